#pragma once
// The system of loops and the uniformization metric on an intrinsic
// triangulation (docs/uniformization.md). The flip-based flow
// (RicciFlowOptions::intrinsic_delaunay; docs/uniformization.md) returns a flat or hyperbolic metric on a flipped
// triangulation T' of the input's vertices. This computes a system of loops
// on T' (combinatorially: T' with the input's vertex positions as a mesh) and
// the metric's exact lengths on the loops' refined mesh: every refined vertex
// lies on a face of T' (origin face, barycentric coordinates), every refined
// edge inside one face of T' or along one of its edges, so its length is
// the distance of two points of one flat / hyperbolic triangle. The result
// is laid out by layout_disk like the fixed-connectivity metric.
//
// Points are placed in a triangle by their barycentric coordinates:
// Euclidean, the affine combination of the corners; hyperbolic, the
// normalised combination of the corners' hyperboloid vectors (invariant
// under isometries, so a point on an edge is the same point seen from both
// faces; in the Klein model it is a projective image of the barycentric
// triangle, so refined faces keep their orientation).
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {

struct IntrinsicLoops {
  /// System of loops of the intrinsic triangulation (its mesh: the refined
  /// T', vertex positions = input positions / 3D barycentric interpolation,
  /// only used for the loops' construction). origin_face refers to the faces
  /// of flow.faces.
  SystemOfLoops loops;
  /// #E(loops.mesh) lengths of the flow's metric, edge order of
  /// Connectivity(loops.mesh.F).
  Eigen::VectorXd lengths;
  /// Connectivity(loops.mesh.F), built here for the lengths: the layout
  /// reads the same (issue 19: not built again).
  std::shared_ptr<const Connectivity> conn;
};

/// A point of a face of T' (flow.faces): face and barycentric weights in the
/// face's corner order.
struct FacePoint {
  int face = -1;
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();
};

/// The point with weights b on the corners of face rf of loops.mesh (an
/// IntrinsicLoops' refined T'), as a point of a face of T': the face of T'
/// holding all three corners (T' faces: F, their Connectivity tc) and the
/// b-weighted sum of the corners' weights there (exact for a flat metric; for
/// a hyperbolic one, a continuous reparametrisation inside the refined face).
/// num_input_vertices: T' vertices come first in loops.mesh. Throws
/// SolveError when no face of T' holds the refined face.
FacePoint intrinsic_face_point(const SystemOfLoops& loops, const RowMatrixX3i& F, const Connectivity& tc,
                               int num_input_vertices, int rf, const Eigen::Vector3d& b);

/// input: the mesh the flow ran on (vertex positions); flow: a converged
/// RicciFlowResult (faces, face_edges, edge_lengths). Throws SolveError when
/// T' is not a simplicial surface (two edges with the same ends, or a loop
/// edge: Connectivity cannot represent it) or the loops fail their checks.
/// loops_in_metric (default false): the loops are the shortest ones in the
/// flow's metric (SystemOfLoopsOptions::edge_weights = flow.edge_lengths,
/// base vertex the metric's centre unless options.base_vertex is set), not
/// in 3D: a compact fundamental domain for high genus (issue 13).
IntrinsicLoops intrinsic_loops(const TriMesh& input, const RicciFlowResult& flow, Background background,
                               const SystemOfLoopsOptions& options = {}, bool loops_in_metric = false);

/// The flow's edge lengths (flow.edge_lengths) in the edge order of tc =
/// Connectivity(flow.faces): #E(tc).
std::vector<double> metric_edge_weights(const RicciFlowResult& flow, const Connectivity& tc);

}  // namespace surfmap
