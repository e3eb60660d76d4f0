#pragma once
// One-call uniformization (docs/method.md §2.2-2.5): system of
// loops -> discrete Ricci flow on the (refined) mesh -> isometric layout of
// the cut disk with its deck group. Genus 0 goes to the unit sphere
// (spherical.h), genus 1 to a flat torus (lattice, modulus τ), genus >= 2 to
// a hyperbolic surface (Fuchsian group in SU(1,1)).
#include <complex>
#include <functional>
#include <string>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/layout.h"
#include "surfmap/uniformize/ricci_flow.h"
#include "surfmap/uniformize/spherical.h"

namespace surfmap {

/// How the flat / hyperbolic metric of genus >= 1 is found.
///  * IntrinsicDelaunay (default): Newton on the convex energy with Ptolemy
///    flips that keep the intrinsic triangulation Delaunay (a metric exists
///    for every mesh); the loops are cut on that triangulation
///    (uniformize/intrinsic_loops.h). Needs vertex scaling and Newton; with
///    another scheme or method the fixed-connectivity path runs.
///  * FixedConnectivity: the metric on the loops' mesh itself, refined by
///    altitude-foot splits when it does not exist (fixed_connectivity_refinement).
///  * Automatic (SurfaceMapOptions::uniformization.target_metric's
///    default): the intrinsic Delaunay metric; the fixed-connectivity one
///    (exactly refined when needed) only when the flip path throws.
///    uniformize() treats it as IntrinsicDelaunay (which already falls back
///    to the fixed connectivity, exactly refined when needed, when the loops
///    of T' fail: T' with two edges between one pair of vertices).
///  * FixedFirst: the fixed-connectivity metric (surface_map: refined exactly
///    when needed) when it can be delivered, the flip-based one only when
///    that throws UniformizationError; the order `auto` had before the flip
///    path became the default, kept for callers measured on the fixed metric.
/// Names (CLI, Python, reports): "flips", "fixed", "auto", "fixed-first"
/// (map/map_option_names.h; docs/uniformization.md "Which target metric runs").
enum class UniformizationMetric { IntrinsicDelaunay, FixedConnectivity, Automatic, FixedFirst };

/// Which lengths the loops of the flip path (intrinsic_loops) are shortest in.
///  * Embedding: the 3D lengths (the input's geometry), base vertex near the
///    centroid.
///  * Metric: the uniformization metric itself, base vertex its centre,
///    shallow cut tree (SystemOfLoopsOptions::edge_weights): a compact
///    domain (issue 13: the raw genus-24 wheel's 3D loops cut a domain
///    reaching 32 from the centre, 1 − |z| ~ 1e-14; the metric's 14). CAD
///    plates of genus 13+ are too long in their metric for either.
///  * Automatic (default): Embedding; for genus >= 2, Metric when that layout
///    fails its checks or crowds |z| = 1 (coordinate_roundoff above
///    UniformizeOptions::crowded_roundoff), kept when it passes the checks and
///    is more compact. Genus 1 and the fixed-connectivity path (loops before
///    the metric) always use Embedding.
/// Names (CLI): "embedding", "metric", "auto".
enum class LoopMetric { Embedding, Metric, Automatic };

struct UniformizeOptions {
  UniformizationMetric metric = UniformizationMetric::IntrinsicDelaunay;
  /// FixedConnectivity only: refine exactly when the metric does not exist
  /// (uniformize/feasible_metric.h; default false: the altitude-foot
  /// refinement is no longer needed by default).
  bool fixed_connectivity_refinement = false;
  /// Discrete conformal scheme (default vertex scaling / discrete Yamabe).
  RicciScheme scheme = RicciScheme::VertexScaling;
  /// Newton (default) or the paper's explicit flow.
  RicciMethod method = RicciMethod::Newton;
  /// Max curvature error of the metric (default 1e-10).
  double tolerance = 1e-10;
  /// Accepted residual when Newton stops at the floating-point floor above
  /// `tolerance` (RicciFlowOptions::floor_tolerance; default 1e-7).
  double floor_tolerance = 1e-7;
  /// 0 (default): the solver's own limit.
  int max_iterations = 0;
  /// Base vertex of the loops (genus >= 1) / vertex sent to the pole
  /// (genus 0); -1 (default): chosen automatically.
  int base_vertex = -1;
  /// Called per flow iteration with the max curvature error; return false to
  /// cancel (throws Cancelled).
  std::function<bool(int iteration, double residual)> progress;
  LayoutOptions layout;
  /// Lengths the loops are shortest in (LoopMetric; default Automatic).
  LoopMetric loops = LoopMetric::Automatic;
  /// Automatic: a layout whose coordinate round-off (DiskLayout::
  /// coordinate_roundoff, ε · 2/(1 − |z|²) at the farthest corner) exceeds
  /// this is laid out again on loops in the metric (default 1e-9: corners
  /// within 5e-7 of |z| = 1, about 15 from the centre).
  double crowded_roundoff = 1e-9;
};

struct UniformizeResult {
  int genus = 0;
  /// "spherical" (genus 0), "flat" (genus 1) or "hyperbolic" (genus >= 2).
  std::string kind;
  bool converged = false;
  int iterations = 0;
  double max_curvature_error = 0;
  /// The metric stopped at the floating-point floor (residual above
  /// `tolerance`, within `floor_tolerance`), and the a priori floor estimate
  /// (RicciFlowResult). Still converged.
  bool stopped_at_floor = false;
  double floor_estimate = 0;
  /// Gap allowed between glued copies (gluing_tolerance below).
  double gluing_tolerance = 0;
  std::vector<double> residual_history;
  /// Area in the uniformization metric before any normalisation: flat, the
  /// area of the fundamental domain; hyperbolic, 4π(g−1) up to the
  /// tolerance; spherical, 4π.
  double area = 0;
  double time_s = 0;
  /// Genus 1: lattice vectors (loop generators a, b), τ = ω2/ω1 with Im τ > 0
  /// and τ reduced to the modular fundamental domain (modulus.sl2z).
  TorusModulus modulus;
  Complex tau, tau_reduced;
  /// Genus >= 2: the 2g loop generators (layout.h conventions) and the
  /// distance of the boundary-word product from ±identity.
  std::vector<hyperbolic::Mobius> generators;
  double product_relation_error = 0;
  DiskLayout layout;
  /// Whether the layout's coordinates in the one Poincaré chart passed the
  /// gluing checks (interior, deck, corner, relation; uniformize.cpp
  /// check_layout). False when only the per-face checks hold (DiskLayout::
  /// max_vertex_holonomy, num_flipped_local) because the domain reaches
  /// beyond what double coordinates resolve (CAD plates of genus 13 .. 24,
  /// 37 .. 73 from the centre): the metric, the area, the cut and the
  /// per-face charts are valid, the corners, side pairings and generators
  /// in the layout frame are not to the coordinates' digits, and everything
  /// that reads them (surface_map's location and harmonic map, `uniformize
  /// --layout`) refuses such a layout with an error naming it.
  bool single_chart = true;
  /// "single chart", or "per-face charts (...)" with the single chart's
  /// failure.
  std::string layout_checks;
  /// "intrinsic Delaunay" or "fixed connectivity" (with the reason when the
  /// intrinsic path fell back), and the Ptolemy flips of the metric.
  std::string metric;
  int edge_flips = 0;
  /// Which loops were laid out (LoopMetric): "embedding", "metric", or
  /// "metric (embedding loops: <why not>)" when Automatic switched.
  std::string loop_metric;
  /// The metric laid out: #E lengths of Connectivity(loops.mesh.F) (with the
  /// fixed connectivity equal to ricci.edge_lengths; intrinsic: the flow's
  /// metric restricted to the loops' refinement of the flipped triangulation).
  Eigen::VectorXd edge_lengths;
  /// The loops' mesh (intrinsic Delaunay: the flipped triangulation, refined
  /// by the loops; its vertex positions interpolate the input's in 3D and
  /// only serve the loop construction) (refined further when the fixed-connectivity metric did
  /// not exist: refinement_splits exact splits, uniformize/feasible_metric.h).
  SystemOfLoops loops;
  int refinement_splits = 0;
  RicciFlowResult ricci;
  /// Genus 0: #V positions on the unit sphere (input vertex order).
  SphericalUniformization sphere;
};

/// The gap allowed between the copies of a glued point in `layout` for a
/// metric with max curvature error `residual`: max(1e-6, 1e4 residual) ×
/// sqrt(area) (relative to the layout's scale) + 1e3 × coordinate_roundoff.
double gluing_tolerance(const DiskLayout& layout, double residual);

/// The largest holonomy of the transitions around a vertex (DiskLayout::
/// max_vertex_holonomy) accepted for a metric with max curvature error
/// `residual`: 1e-8 + 1e2 residual (an angle defect θ gives about θ / 2;
/// the products' rounding reaches 3e-11 on the genus-24 plate).
double vertex_holonomy_tolerance(double residual);

/// The checks every delivered layout passes (a SolveError naming the first
/// that fails). Always the per-face charts' checks (DiskLayout::
/// num_flipped_local, max_vertex_holonomy within vertex_holonomy_tolerance);
/// then the single chart's: no flipped triangle, interior and deck gaps and
/// the base corner within gluing_tolerance beyond their round-off, the
/// boundary-word relation within its condition. A hyperbolic layout whose
/// single chart fails them with faces its coordinates cannot resolve
/// (DiskLayout::num_unresolved) and no flipped triangle taller than its
/// round-off passes on the per-face checks: returns false with `why` set to
/// the single chart's failure; true when the single chart passed.
/// `residual`: the metric's max curvature error.
bool check_layout(const DiskLayout& layout, double residual, std::string* why = nullptr);

/// The flip path's loops with their layout (uniformize, and the map's target
/// in map/map_support.cpp, so both lay out the same domain).
struct LoopsLayout {
  SystemOfLoops loops;
  Eigen::VectorXd lengths;  ///< the metric on Connectivity(loops.mesh.F)
  DiskLayout layout;
  std::string loop_metric;  ///< as UniformizeResult::loop_metric
  bool single_chart = true;          ///< as UniformizeResult::single_chart
  std::string single_chart_failure;  ///< the single chart's failure when !single_chart
};

/// Lays out `loops` (the metric `lengths` on them; `loop_metric` names them)
/// and checks the layout (check_layout). `may_switch` (LoopMetric::Automatic,
/// genus >= 2, loops shortest in 3D): when that layout fails its checks, is
/// checked in per-face charts only, or its coordinate_roundoff exceeds
/// `crowded_roundoff`, lays out again on the loops shortest in the metric
/// (intrinsic_loops(mesh, flow, ..., true)) and keeps those when they pass
/// and are better (held by the single chart first, then more compact).
/// Throws SolveError when the kept layout fails its checks.
LoopsLayout lay_out_loops(const TriMesh& mesh, const RicciFlowResult& flow, Background background,
                          const SystemOfLoopsOptions& loop_options, SystemOfLoops loops, Eigen::VectorXd lengths,
                          std::string loop_metric, bool may_switch, const LayoutOptions& layout_options,
                          double crowded_roundoff);

/// mesh: closed, manifold, outward-oriented (after intake). Throws
/// UniformizationError (a SolveError, with the solver's message) when the
/// metric does not converge or the layout is inconsistent; never reports an
/// unconverged result as a success. With FixedFirst, `metric` in the result
/// says when the fixed connectivity failed first.
UniformizeResult uniformize(const TriMesh& mesh, const UniformizeOptions& options = {});

}  // namespace surfmap
