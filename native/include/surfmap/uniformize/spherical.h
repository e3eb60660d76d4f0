#pragma once
// Genus-0 uniformization (docs/method.md §2.4): a map of a closed genus-0
// mesh onto the unit sphere.
//
// Method: send one vertex v0 to infinity. Remove its star and flatten the
// remaining disk with the Euclidean discrete Ricci flow (vertex scaling,
// Newton, intrinsic Delaunay flips by default): curvature 0 at the interior
// vertices and the Dirichlet condition u_j = −2 log l(v0, j) on the ring of
// v0's neighbours — the limit of vertex scaling with u_{v0} -> ∞, which keeps
// every length cross ratio, edges to v0 included. Lay the disk out in the
// plane, project stereographically (v0 -> the pole): the chord lengths on the
// sphere are then again a vertex scaling of the input lengths, i.e. the
// result is a discrete conformal map onto a polyhedron inscribed in the unit
// sphere (docs/uniformization.md). With flips (default) the start is the intrinsic Delaunay
// triangulation of the whole sphere, and the removed vertex's ring and star
// edges flip between rounds of the flow (ring flips at degenerate
// triangles, star flips at reflex ring vertices; docs/uniformization.md
// "Genus 0"), so the chordal polyhedron of `intrinsic_faces` is convex: an
// embedding. Finally Möbius-centre: Newton steps of the ball automorphism
// that moves the area-weighted centre of mass (vertex areas of the input
// mesh) to the origin.
#include <array>
#include <string>
#include <vector>

#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {

struct SphericalUniformizationOptions {
  /// Vertex sent to the pole before centring; -1 (default): the vertex of
  /// highest valence, then a few others spread over the vertex order and the
  /// 12 vertices with the best-shaped neighbourhoods if that one fails.
  /// A pole fails by a non-converged result or by an InputError or
  /// SolveError of its own attempt (e.g. its flow's Ptolemy flips cycle):
  /// the next pole is tried, and when all fail the result is not converged
  /// and its message lists every pole's reason. Cancelled, and errors of the
  /// whole mesh (genus, the whole sphere's Delaunay start), end the run.
  int removed_vertex = -1;
  /// Options of the inner Euclidean flow (scheme/method/tolerance/progress).
  RicciFlowOptions flow;
  /// Overrides flow.intrinsic_delaunay (default true): flatten with Ptolemy
  /// flips so that badly shaped meshes have a solution; the flattened
  /// intrinsic triangulation is laid out, and its faces (intrinsic_faces)
  /// are then checked on the sphere (flipped_faces; any -> not converged).
  bool intrinsic_delaunay = true;
  /// Rounds of the flattening with ring flips between them (intrinsic
  /// Delaunay only): a disk triangle degenerating against the removed
  /// vertex's ring flips that ring edge and the flow runs again (default 64).
  int max_ring_flip_rounds = 64;
  /// Stop centring (Newton on the Möbius parameter) when |centre of mass|
  /// <= max(centring_tolerance, the rounding floor centring_floor).
  double centring_tolerance = 1e-10;
  /// When no Möbius step decreases |centre of mass| any more, a residual
  /// at or below this is the floating-point floor of this mesh: success,
  /// with centring_stopped_at_floor set (issue 13 item 4). Set it <=
  /// centring_tolerance to demand the tolerance strictly.
  double centring_floor_tolerance = 1e-7;
  int max_centring_iterations = 500;
};

/// One edge flip of the genus-0 uniformization in the global face ids (a
/// face keeps the id of the input face it replaced; flips reuse their two
/// ids), enough to carry points back through it
/// (uniformize/spherical_correspondence.h). Slots 0..3 = k, s, m, t as in
/// EdgeFlip; the rows of face0 and face1 before and after are given as the
/// slot of each column.
struct SphereFlip {
  int face0 = -1, face1 = -1;
  std::array<int, 4> quad{};  ///< input vertex ids of the slots k, s, m, t
  std::array<int, 3> before0{}, before1{}, after0{}, after1{};
  /// Lengths (EdgeFlip::base_lengths order) in the frame current at the
  /// flip; exact: a metric-preserving Euclidean flip (planar unfolding),
  /// otherwise a Ptolemy flip (light-cone Gram matrix).
  std::array<double, 6> lengths{};
  bool exact = false;
};

/// A change of frame between flips: every vertex's vector in the light-cone
/// picture is multiplied by e^{log_scale[v]} (a vertex scaling of all
/// lengths by e^{(g_i + g_j)/2}); `time`: the number of flips before it.
struct SphereFrameChange {
  int time = 0;
  Eigen::VectorXd log_scale;  ///< #V, input vertex ids
};

struct SphericalUniformization {
  /// #V positions on the unit sphere (same vertex order as the input).
  RowMatrixX3d positions;
  /// True when the flow converged, the centre of mass reached the tolerance
  /// (or its floor) and no intrinsic triangle is flipped on the sphere.
  bool converged = false;
  int removed_vertex = -1;
  int flow_iterations = 0;             ///< Newton iterations of the flattening
  double max_curvature_error = 0;      ///< at the interior vertices of the disk
  /// The flattening stopped at the floating-point floor (RicciFlowResult).
  bool stopped_at_floor = false;
  /// Always 0: the former circular-boundary iteration was replaced by the
  /// exact vertex-at-infinity condition (field kept for the CLI's JSON).
  double circle_error = 0;
  double centre_of_mass_norm = 0;      ///< after centring (the achieved residual)
  /// Rounding floor of |centre of mass| (≈ ε (4 + log2 #V) √3): the
  /// centring stops at max(centring_tolerance, centring_floor).
  double centring_floor = 0;
  int centring_iterations = 0;         ///< Newton steps of the Möbius centring
  /// The centring stalled above the tolerance but within
  /// options.centring_floor_tolerance: converged, at the floor.
  bool centring_stopped_at_floor = false;
  /// A Möbius step off the axis would have inverted faces (a long shape's
  /// ends crowded at the poles below double precision, e.g. a bent 40:1
  /// sphere): the centring went on along the axis only and converged when
  /// the axial component of the centre of mass reached the stop;
  /// centre_of_mass_norm is then the whole (tangential) residual.
  bool centring_axial_only = false;
  /// Intrinsic faces (intrinsic_faces) whose chordal triangle points inward
  /// on the sphere: 0 when converged.
  int flipped_faces = 0;
  /// Input faces whose chordal triangle (between their vertices' images)
  /// points inward. Not a failure: with flips the image of an input face is
  /// a union of pieces of intrinsic triangles; equal to flipped_faces when
  /// no edge flipped.
  int input_flipped_faces = 0;
  /// The triangulation whose chordal triangles embed in the sphere (#F' x 3,
  /// input vertex ids; #F' = #F): the flow's intrinsic Delaunay faces of the
  /// punctured disk and the star of removed_vertex, row f taking the place
  /// of input face f through the flips (flip_log). The input faces without flips.
  RowMatrixX3i intrinsic_faces;
  /// The whole way from the input faces to intrinsic_faces (with flips,
  /// when converged): the flips of the sphere's Delaunay start, of every
  /// round of the flattening, the ring and star flips, and the frame
  /// changes between them (the rounds' conformal factors, star flips'
  /// vertex scalings, and last the projection to the sphere with the
  /// Möbius centring). Row f of intrinsic_faces is global face f.
  /// Empty without flips. See uniformize/spherical_correspondence.h.
  std::vector<SphereFlip> flip_log;
  std::vector<SphereFrameChange> frame_log;
  int ring_flips = 0;                  ///< flips of the removed vertex's ring edges and of its star edges (star flips)
  int edge_flips = 0;                  ///< intrinsic flips: the whole sphere's Delaunay start and the flattening (all rounds)
  int simplicial_flips = 0;            ///< of edge_flips: exact flips making the Delaunay start simplicial (no two edges with the same ends)
  double time_s = 0;
  std::string message;                 ///< why it failed (names the element), empty on success
};

/// mesh: closed, manifold, oriented outward, genus 0 (InputError otherwise).
/// Throws SolveError when the whole sphere's intrinsic Delaunay start cannot
/// be made simplicial, Cancelled when options.flow.progress asks to stop;
/// with a given removed_vertex, that pole's InputError / SolveError too.
SphericalUniformization spherical_uniformization(const TriMesh& mesh,
                                                 const SphericalUniformizationOptions& options = {});

}  // namespace surfmap
