#pragma once
// The initial ("before") map of the hyperbolic case (genus >= 2; docs/method.md §2.7,
// docs/method.md §2.7) and the quality of any map given by points and deck
// elements (docs/method.md §2.11).
//
// What is built (hyperbolic_initial_map with the source mesh, the default):
//  0. First, the cut-graph polygon (map/cut_graph_initial_map.h): the source
//     cut along its own edges (the unrefined loops' cut graph) onto the
//     convex polygon of that graph's harmonic map into the target, an
//     embedding by construction with no fold to repair (0 folds on every
//     raw sliver source of genus 2-6 measured, the jittered one, the real
//     genus-2/3 pairs and the 50k bench pair; 0.1-0.4 s at 2-7k vertices).
//     When that polygon is not strictly convex or too large for double
//     precision (very twisted classes), 1 and 2 below.
//  1. The polygon construction (polygon_initial_map). The source is cut along
//     its REFINED loops (topology/system_of_loops.h: split points on input
//     edges, bend points inside input faces, loops simple and meeting only
//     at x; the input vertices keep their indices), a disk D whose boundary
//     is a 4g-gon with the source's word w_S. The class's deck element of
//     every source halfedge (side words of the target's group, DeckGroup) is
//     carried to the refined mesh through the input face holding each
//     refined face, and D is developed face by face: every copy d of a
//     vertex gets the deck element c_d of its tile. The 4g copies of x give
//     the corners Q_s = C_s(p) = θ(prefix_s of w_S)(p): the target's
//     geodesic polygon of the SOURCE's loops; paired sides are deck images
//     of each other (E_s takes the partner side onto side s, reversed). The
//     base point p (the lift of x) minimises the perimeter Σ_s d(p, A_s p),
//     A_s = C_s⁻¹ C_s+1, a convex function (sum of displacement functions).
//     When Q is simple, positively oriented and convex in the Klein model
//     (checked; it is not always), D is flattened onto it there: boundary
//     copies on their side at the fraction of the loop's 3D length (the
//     same on both banks, so the pairing carries one copy onto the other),
//     interior ones by sparse Cholesky solves with two right-hand sides and
//     symmetrised mean-value weights w of the 3D refined mesh (positive, so
//     Floater's theorem gives an embedding of D in every solve); interior
//     edges joining two boundary copies of one side (whose faces would be
//     degenerate) are split first. Solve 0 is the plain Klein-model Tutte
//     map; it is not isometry-invariant (Klein coordinates are anisotropic
//     towards the polygon's far corners), so the two banks of a side, which
//     sit at different places of Q, were treated differently and source
//     faces crossing the side flipped (66 flips on n-hole torus -> polycube
//     genus 2). Rounds 1..hyperboloid_rounds re-weight towards the
//     hyperboloid barycentre condition X_i ∝ Σ_j w_ij X_j, invariant under
//     isometries: in Klein coordinates Σ_j w_ij γ_i γ_j (k_j − k_i) = 0 with
//     γ = 1/sqrt(1 − |k|²) from the previous round (66 -> 3 flips there;
//     clean remeshed pairs: max D' 85 -> 9). The input vertices are read
//     off with their decks c_d. A source face crossed by a loop, straight
//     between its corners' images, can still flip (the flattening's
//     derivative jumps across the fixed sides); then the fallback is used,
//     started from the flattening (a local relaxation of the flipped
//     corners was tried and made more flips than it removed).
//  2. The fallback, and InitialMapMethod::UniformHarmonic: the Tutte-type map
//     in the same class, the discrete harmonic map with uniform weights
//     (every source edge weight 1) into the target's hyperbolic surface,
//     i.e. each vertex at the hyperbolic barycentre of its neighbours'
//     images; with positive weights an embedding (the hyperbolic Tutte
//     theorem; docs/method.md §2.8), the counterpart of the genus-1 initial map
//     (flat_map.cpp: the uniform Tutte embedding of the flat torus). Cost: a
//     Newton solve, about 6-7 iterations from the origin and 4 from a
//     flattening with flips ("uniform harmonic (from the polygon)": the
//     same unique map, reached sooner).
// How often it applies (session-3 measurements, generated pairs at ~5-10k
// vertices in the overlay / canonical class and the real meshes): Q was
// convex in every case that fitted in double precision but one (a genus-6
// sliver source); the flattening was used (no flipped source face) on
// remeshed n-hole-torus pairs of genus 2 and 4, n-hole torus -> cup (genus
// 2), n-hole torus -> vase at 5k (not at 7k: 1 flip), vase -> amphora, and
// the real double-torus <-> eight pair and self-maps (genus 2, 3); it fell
// back with 1-12 flipped faces crossing the loops on sliver sources, the
// genus-3 remeshed pair, cup -> n-hole torus, n-hole torus -> polycube,
// amphora -> vase, vase -> n-hole torus and fertility (genus 4);
// and before flattening when corners reach |k| > 1 − 1e-9 in the polygon's
// own Klein chart (genus 5 pairs, botijo; very twisted classes). The
// polygon start costs the main Newton solve 0-1 extra iteration against the
// uniform start; the fallback started from the flattening needs 3-5 Newton
// steps instead of 5-8.
// Where this differs from the paper (docs/method.md §2.7): the paper cuts
// BOTH surfaces along corresponding canonical loops, flattens both disks
// onto the same canonical 4g-gon and composes the two maps. Here the
// target is never cut along the source's loops (its canonical generators are
// words in its own loops; the mesh is not re-cut, docs/method.md §2.3) and
// the source is not cut along canonical loops: the source's disk goes
// straight onto the target's geodesic polygon of the source's own loops,
// which plays the role of the common polygon (no second flattening and no
// composition through barycentric coordinates; the map is located on the
// target afterwards like the optimum). That polygon is convex only for some
// pairs and base points, hence the fallback. Figures (energy, D' per source
// face, flips) are measured on the image triangles in the Poincaré disk,
// where they are intrinsic to the target's metric.
#include <complex>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/map/cut_graph_initial_map.h"
#include "surfmap/map/distortion.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap {

struct HyperbolicInitialMapOptions {
  /// Gradient tolerance of the uniform-weight solve (default 1e-4; Newton
  /// converges quadratically, so the energy is then exact to ~1e-9 relative
  /// and one factorisation is saved; the map only starts the real solve).
  double tolerance = 1e-4;
  int max_iterations = 100;
  /// Try the cut-graph polygon first (map/cut_graph_initial_map.h: an
  /// embedding by construction; default true), then (when it does not
  /// apply) the polygon construction below.
  bool cut_graph = true;
  /// Try the polygon construction (default true); false with cut_graph
  /// false builds the uniform-weight map directly.
  bool polygon = true;
  /// Passed to polygon_initial_map (PolygonInitialMapOptions) and
  /// cut_graph_initial_map.
  int base_vertex = -1;
  /// Optional: the source's unrefined loops from base_vertex, for
  /// cut_graph_initial_map (CutGraphInitialMapOptions::loops).
  const std::vector<std::vector<int>>* source_loops = nullptr;
  std::function<Word(std::complex<double>&)> reduce_point;
  /// Optional: asked before every Newton iteration of the uniform-weight
  /// solve; false stops it (Cancelled). Lets a caller that builds the map on
  /// another thread abandon it (map/concurrency.h).
  std::function<bool()> keep_going;
  /// Optional (#V each, or empty: the origin): where the uniform-weight solve
  /// starts when the polygon is not used, as points and deck words (e.g. the
  /// class's coarse solution prolonged). The map is the unique minimiser in
  /// the class whatever the start; a good start saves Newton iterations (12
  /// from the origin on the 50k genus-2 bench pair).
  std::vector<std::complex<double>> start_z;
  std::vector<Word> start_word;
};

struct PolygonInitialMapOptions {
  /// Base vertex x of the source's refined loops (-1: automatic, as
  /// system_of_loops); pass the base vertex of the loops `halfedge_word`
  /// was computed from, so that both cuts start at the same vertex.
  int base_vertex = -1;
  /// Iterations of the Riemannian gradient descent choosing the base point p
  /// (minimiser of Σ_s d(p, A_s p) over the side elements A_s; default 200).
  int base_point_iterations = 200;
  /// A corner is convex when its turn, the exterior angle in the Klein model,
  /// exceeds this (radians, default 1e-9): flatter corners make degenerate
  /// boundary triangles.
  double min_turn = 1e-9;
  /// Rounds re-weighting the flattening towards the hyperboloid barycentre
  /// condition X_i ∝ Σ w_ij X_j (isometry-invariant, unlike the plain
  /// Klein-model Tutte map of round 0; default 3, 0: plain Klein Tutte).
  int hyperboloid_rounds = 3;
  /// Optional: moves a point into the target's fundamental domain and
  /// returns the side word applied (as HyperbolicHarmonicOptions::reduce_point).
  std::function<Word(std::complex<double>&)> reduce_point;
};

/// The source's cut disk flattened onto the target's geodesic polygon of the
/// source's loops (file comment).
struct PolygonInitialMapResult {
  /// True when the polygon was simple, positively oriented and convex and
  /// the flattening was computed; otherwise `reason` says why not and the
  /// map fields are empty.
  bool applied = false;
  std::string reason;
  /// The 4g corners Q_s = C_s(p) (Poincaré disk, counter-clockwise along the
  /// disk's boundary), their deck elements C_s as reduced side words, and per
  /// side s (Q_s -> Q_s+1): the side it is glued to and the deck element E_s
  /// (side word) taking that side onto side s, reversed:
  /// E_s(Q_partner) = Q_s+1, E_s(Q_partner+1) = Q_s.
  std::vector<std::complex<double>> corners;
  std::vector<Word> corner_word;
  std::vector<int> side_partner;
  std::vector<Word> side_pairing_word;
  /// The chosen base point p (lift of the base vertex) and Σ_s d(Q_s, Q_s+1).
  std::complex<double> base_point;
  double perimeter = 0;
  /// Smallest and largest exterior angle of Q in the Klein model (radians).
  double min_turn = 0, max_turn = 0;
  bool convex = false;
  /// Size of the refined source mesh and of its disk, and the interior edges
  /// joining two boundary vertices of one side that were split before the
  /// flattening (Floater's theorem needs none).
  int refined_vertices = 0, disk_vertices = 0, chords_split = 0;
  /// #V_source points and deck elements (HyperbolicHarmonicResult contract:
  /// z_i = vertex_deck_i(lift_i); edge i->j has the effective element
  /// vertex_deck[i] * rho * vertex_deck[j]^-1); words are side words.
  std::vector<std::complex<double>> z;
  std::vector<hyperbolic::Mobius> vertex_deck;
  std::vector<Word> vertex_deck_word;
  /// Flipped / degenerate images of the source's own faces (geodesic
  /// triangles between the input vertices' images), when applied.
  int source_flipped = 0, source_degenerate = 0;
  /// Vertices re-solved (uniform weights, the rest held) around those faces
  /// when there were only a few and that cleared them; 0 otherwise.
  int repaired_vertices = 0;
  double time_s = 0;
};

struct HyperbolicInitialMapResult {
  bool converged = false;
  int iterations = 0;
  /// #V points and per-vertex deck elements (as HyperbolicHarmonicResult).
  std::vector<std::complex<double>> z;
  std::vector<hyperbolic::Mobius> vertex_deck;
  /// The same decks as words in the generators' letters (see
  /// HyperbolicHarmonicResult::vertex_deck_word).
  std::vector<Word> vertex_deck_word;
  /// "cut-graph polygon", "polygon" or "uniform harmonic" (or "uniform
  /// harmonic (from the polygon)"): which construction gave the map.
  std::string construction;
  /// The cut-graph attempt (its figures and, when not used, why; its map
  /// fields are emptied); applied = false and empty reason when not tried.
  CutGraphInitialMapResult cut_graph;
  /// Flipped / degenerate source faces of the cut-graph map (round-off on
  /// slivers; the map is not used then).
  int cut_graph_flipped = 0, cut_graph_degenerate = 0;
  /// The polygon attempt (its figures and, when not used, why; its map
  /// fields are emptied); applied = false and empty reason when not tried.
  PolygonInitialMapResult polygon;
  double time_s = 0;
};

/// The paper's polygon construction in the form that applies to one
/// surface's loops (file comment). `source`/`sc`: the source mesh;
/// `halfedge_word` (#3F): the class's deck element of every source halfedge
/// as a side word of `group` (its twin carries the inverse), flat around
/// every face. Throws InputError on size mismatches; a polygon that is not
/// convex is not an error (applied = false).
PolygonInitialMapResult polygon_initial_map(const TriMesh& source, const Connectivity& sc,
                                            const std::vector<Word>& halfedge_word, const DeckGroup& group,
                                            const PolygonInitialMapOptions& options = {});

/// The initial map: polygon_initial_map when options.polygon and it applies
/// and its images of the source's faces are not flipped, otherwise the
/// uniform-weight harmonic map in the class (weight 1 on every source edge,
/// Newton from the flattening when there is one, else from the origin).
/// `halfedge_rho` (#3F: the deck element of source halfedge h = 3f+k, which
/// runs from F(f,k) to F(f,k+1); the twin's element is the inverse) and
/// `halfedge_word` (#3F, the same elements as side words of `group`).
/// Throws SolveError if the uniform-weight solve breaks down.
HyperbolicInitialMapResult hyperbolic_initial_map(const TriMesh& source, const Connectivity& sc,
                                                  const std::vector<hyperbolic::Mobius>& halfedge_rho,
                                                  const std::vector<Word>& halfedge_word, const DeckGroup& group,
                                                  const HyperbolicInitialMapOptions& options = {});

/// What SurfaceMapOptions::inspect_initial_map sees (pointers valid during
/// the call): the class's source halfedge elements (#3F, as matrices and as
/// side words of `group`) and the initial map built from them.
struct InitialMapInspection {
  const std::vector<hyperbolic::Mobius>* halfedge_rho = nullptr;
  const std::vector<Word>* halfedge_word = nullptr;
  const DeckGroup* group = nullptr;
  const HyperbolicInitialMapResult* init = nullptr;
};

/// Quality of the map given by `z` (#V points in the Poincaré disk),
/// `vertex_deck` (#V) and `halfedge_rho` (#3F, as above): the image of face f
/// is the geodesic triangle on z_{F0}, ρ_eff(3f) z_{F1}, ρ_eff(3f+2)⁻¹ z_{F2}
/// with ρ_eff(h) = deck[tail] · ρ(h) · deck[head]⁻¹; D' from the hyperbolic
/// side lengths against the 3D ones (docs/method.md §2.11), orientation tested in
/// the chart centring corner 0. Flipped and degenerate images have D' = +inf
/// and are left out of mean and max. `image` receives the #F x 3 corners.
DistortionStats hyperbolic_distortion(const TriMesh& source, const std::vector<hyperbolic::Mobius>& halfedge_rho,
                                      const std::vector<std::complex<double>>& z,
                                      const std::vector<hyperbolic::Mobius>& vertex_deck,
                                      Eigen::Matrix<std::complex<double>, Eigen::Dynamic, 3, Eigen::RowMajor>* image = nullptr);

/// The same from side words of `group`: `halfedge_word` (#3F) and the
/// vertices' decks `vertex_deck_word` (#V). The effective element of every
/// halfedge is then its reduced word multiplied out (short: a tile next to
/// the fundamental domain), where the matrix products above lose digits when
/// the decks are large, and thin triangles far out come out flipped that are
/// not: 89 of them on a 50k-vertex uniform-weight map in a twisted genus-2
/// class (n_hole_torus(2,103) -> vase) that has none in the solver's own
/// charts, and none by this overload.
DistortionStats hyperbolic_distortion(const TriMesh& source, const DeckGroup& group,
                                      const std::vector<Word>& halfedge_word,
                                      const std::vector<std::complex<double>>& z,
                                      const std::vector<Word>& vertex_deck_word,
                                      Eigen::Matrix<std::complex<double>, Eigen::Dynamic, 3, Eigen::RowMajor>* image = nullptr);

}  // namespace surfmap
