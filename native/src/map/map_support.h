#pragma once
// Internal pieces shared by the flat (genus 1) and hyperbolic (genus >= 2)
// surface-map paths: the uniformized target, the source's unrefined loops,
// point location in laid-out triangles and points expressed on the input
// meshes (point location itself: map/point_location.h). Not part of the
// public API.
#include <atomic>
#include <algorithm>
#include <array>
#include <complex>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "surfmap/map/point_location.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/testing/map_hooks.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/intrinsic_correspondence.h"
#include "surfmap/uniformize/layout.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {
struct HyperbolicInitialMapResult;
}

namespace surfmap::detail {

/// Copies the construction and polygon figures of a genus >= 2 initial map.
void set_initial_map_info(const HyperbolicInitialMapResult& init, InitialMapInfo& info);

using Complex = std::complex<double>;
/// Records the end of a stage (name, overall fraction) and may throw Cancelled.
using StageDone = std::function<void(const std::string&, double)>;

/// InputError when `index` (a requested candidate: `what` names the option)
/// is not below `count`, the number of candidates listed.
void check_candidate_index(int index, int count, const std::string& what);

/// The closure account (surface_map.h LayoutClosure) of `num_triangles`
/// triangles whose gaps `gap(t)` gives: counted against the default
/// tolerance, the worst kept.
LayoutClosure layout_closure(int num_triangles, const std::function<double(int)>& gap);

/// The point with (clamped, renormalised) barycentrics b in face f of m.
PointOnSurface point_in_face(const TriMesh& m, int f, Eigen::Vector3d b);

/// The flip-based metric's triangulation T' of the target and the way back
/// from it to the user's faces (uniformize/intrinsic_correspondence.h).
struct TargetIntrinsic {
  explicit TargetIntrinsic(const RicciFlowResult& flow, int num_input_vertices);
  RowMatrixX3i faces;  ///< T' (#F x 3, the input's vertices)
  Connectivity conn;   ///< of faces
  IntrinsicCorrespondence correspondence;
  int num_input_vertices = 0;
};

/// A point given in face rf of the refined mesh s.mesh, expressed on the input
/// mesh (face + barycentrics). intrinsic == null: s is the fixed-connectivity
/// target's refined mesh (origins on input faces), located by a 3D
/// containment test, `cache` (#F refined, initially -1) remembering the input
/// face of each refined face. Otherwise s is the refined T' and the point is
/// carried back through the flips exactly (cache unused).
PointOnSurface point_on_input(const TriMesh& input, const Connectivity& ic, const SystemOfLoops& s,
                              const TargetIntrinsic* intrinsic, std::vector<int>& cache, int rf,
                              const Eigen::Vector3d& b);

/// The target's system of loops on the user's own connectivity (as on the
/// fixed path; loops are combinatorial), for the handle classes of a target
/// uniformized on the flipped triangulation T': candidates, handle basis and
/// overlays are computed on these loops, and evaluated with the deck group
/// of T' through `generators_in_layout_letters` (uniformize/carried_loops.h).
struct ClassLoops {
  SystemOfLoops loops;
  /// loops.word rotated to start with +1 (as DiskLayout::word) and its schema
  /// (generators and letters in the letters of `loops`).
  Word word;
  CanonicalSchema schema;
  /// schema.generators as words in the letters of the layout of T' (2g,
  /// Dehn-reduced): the same canonical generators, on T'.
  std::vector<Word> generators_in_layout_letters;
  /// Flips of the flow that rewrote a loop, and the longest carried loop on T'.
  int flips_on_loops = 0;
  int longest_edge_path = 0;
};

/// The part of ClassLoops that needs no metric (loops, word, schema; the
/// rest is set when the loops are carried onto T'): `mesh`'s own system of
/// loops with options `lo`, refined from `own_loops` (its unrefined loops)
/// when they have lo's base vertex. The flip path builds its class loops with
/// it; class_bound_support.h reads the source's letters as a target from it
/// when the source is not uniformized (issue 19).
ClassLoops own_class_loops(const TriMesh& mesh, const Connectivity& conn, const SystemOfLoopsOptions& lo,
                           const SystemOfLoops* own_loops, const CanonicalSchemaOptions& schema = {});

/// The canonical schema's options SurfaceMapOptions asks for
/// (LoopOptions::short_canonical_generators), for every genus >= 2 schema
/// of the pipeline (both surfaces' loops, the source's other cuts, the
/// uniformized source of the class bounds).
CanonicalSchemaOptions schema_options(const SurfaceMapOptions& options);
/// The other canonical basis's options (classical when the run's are short,
/// and the other way round): the candidates are listed in both
/// (stages/other_basis.h, docs/robustness.md "Canonical generators").
CanonicalSchemaOptions other_schema_options(const SurfaceMapOptions& options);

/// The target laid out in its uniformization metric: system of loops (refined,
/// as the layout needs simple loops), Ricci flow, disk layout, with the metric
/// of SurfaceMapOptions::uniformization.target_metric: the fixed-connectivity one (refined
/// exactly only when asked for, or when the flip path throws) or the
/// flip-based metric on T' with the loops of uniformize/intrinsic_loops.h.
struct UniformizedTarget {
  SystemOfLoops loops;
  DiskLayout layout;
  /// "intrinsic Delaunay" or "fixed connectivity" (with the flip path's
  /// error in parentheses when it was the automatic fallback; with
  /// FixedFirst, "intrinsic Delaunay (fixed connectivity failed: ...)").
  std::string metric;
  /// Why that metric ran (SurfaceMapResult::target_metric_choice).
  std::string metric_choice;
  /// Flip path: which loops were laid out (LoopsLayout::loop_metric).
  std::string loop_metric;
  /// Edge flips of the flip-based flow (0 on the fixed path).
  int flips = 0;
  /// Set on the flip path: T' and the way back to the input faces.
  std::shared_ptr<const TargetIntrinsic> intrinsic;
  /// Set on the flip path of a hyperbolic target: the loops the handle-class
  /// machinery reads (docs/uniformization.md "Handle classes on the flip
  /// path"). Null otherwise, or when carrying them failed (status says why).
  std::shared_ptr<const ClassLoops> class_loops;
  std::string class_loops_status;
  /// Exact splits added so that the metric exists (0: none were needed) and
  /// the max-angle bound used (uniformize/feasible_metric.h).
  int refinement_splits = 0;
  double refinement_max_angle = 0;
};

/// `conn`: Connectivity(target.F) when the caller has it (built once per
/// mesh per run, issue 19), else nullptr. `stop` (nullptr: none): when it
/// is raised, the flip path's flow throws Cancelled at its next iteration
/// (the pipeline leaving while the source's own uniformization runs on the
/// second thread). `mesh` ("target", or "source" when the source is
/// uniformized for its class bounds) names it in a SingleChartError: a
/// hyperbolic layout that is valid but reaches too far for the one chart
/// the map reads ends the run there, without trying the other metric.
/// `own_loops` (nullptr: none): the unrefined system of loops of `target`
/// at the base vertex options.loops.target_base_vertex chooses (the
/// pipeline's source loops when the source is uniformized), whose greedy
/// basis the flip path's class loops then refine instead of computing it
/// again (issue 19; the same loops). `class_loops` false: no handle-class
/// loops (UniformizedTarget::class_loops stays empty; session 24: the
/// source's coarse copy uniformized for the class bounds reads only its
/// layout and loops).
UniformizedTarget uniformized_target(const TriMesh& target, Background background, const SurfaceMapOptions& options,
                                     const Connectivity* conn = nullptr, const std::atomic<bool>* stop = nullptr,
                                     const std::string& mesh = "target", const SystemOfLoops* own_loops = nullptr,
                                     bool class_loops = true);

/// The target metric's account (which metric, why, its flips and exact
/// splits) recorded in the result's target_* fields; one place for every
/// genus that uniformizes the target through uniformized_target.
void record_target_metric(const UniformizedTarget& target, SurfaceMapResult& out);

/// The source's unrefined system of loops: it keeps the source's own
/// connectivity, and contracting its tree gives a one-vertex schema.
SystemOfLoops source_loops(const TriMesh& source, const SurfaceMapOptions& options);
/// The same with `sc` = Connectivity(source.F) and the source's greedy
/// graph when the caller has one (nullptr: built for this call).
SystemOfLoops source_loops(const TriMesh& source, const Connectivity& sc, const SurfaceMapOptions& options,
                           const GreedyGraph* graph = nullptr);

/// Genus 1 (flat target): fills `out` (docs/method.md §2.8, exact sparse solve).
void map_flat(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
              const SurfaceMapOptions& options, const testing::MapHooks& hooks, SurfaceMapResult& out,
              const StageDone& stage_done);

/// Genus 0 (through the unit sphere): fills `out` (map/spherical_map.h).
void map_spherical(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                   const SurfaceMapOptions& options, SurfaceMapResult& out, const StageDone& stage_done);

/// Genus >= 2 (hyperbolic target): fills `out` (Riemannian Newton, docs/method.md §7).
void map_hyperbolic(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                    const SurfaceMapOptions& options, const testing::MapHooks& hooks, SurfaceMapResult& out,
                    const StageDone& stage_done);

}  // namespace surfmap::detail
