#pragma once
// Exact refinement of a triangle mesh for the uniformization metric
// (docs/method.md §2.4: the fixed-connectivity flow must converge on badly shaped
// CAD and scan meshes). With fixed connectivity, the vertex-scaling metric of
// a mesh with caps (angles near 180°) often does not exist: the minimiser of
// the extended energy has degenerate triangles. Splitting the edge opposite
// every large angle at the foot of the altitude (a cap becomes two right
// triangles; the neighbour across gets two pieces meeting at that point)
// makes the flow feasible on such meshes in practice (no theorem: the
// intrinsic-Delaunay flow of ricci_flow.h is the one with a guarantee, but
// it lives on another triangulation). Every split is on the current mesh's
// own edge, in 3D, so the refined mesh is the same polyhedral surface:
// each refined face lies inside one input face and every refined vertex is an
// input vertex or a point of an input face with exact barycentrics. Points
// located on the refined mesh therefore convert exactly back to the input.
#include <vector>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

struct ExactRefinementOptions {
  /// Split the edge opposite every angle above this (degrees, > 90; default
  /// 150). Lower values give fewer obtuse triangles and more vertices.
  double max_angle_deg = 150;
  /// The split point is the foot of the altitude from the large angle,
  /// clamped to [foot_clamp, 1 − foot_clamp] along the edge (default 0.01).
  /// A coarse clamp (0.1) leaves the halves of a cap whose apex is near an
  /// end still capped and cascades into vanishing edges (seen on g3_block).
  double foot_clamp = 0.01;
  /// Stop after this many splits (0 = 2 × #F of the input; default 0).
  int max_splits = 0;
};

struct ExactRefinementResult {
  /// The refined mesh. Its first #V(input) vertices are the input vertices
  /// (same order, same positions); new vertices lie on input edges or inside
  /// input faces. Orientation as the input.
  TriMesh mesh;
  /// #F(refined): the input face that contains each refined face.
  std::vector<int> face_origin;
  /// #V(refined): an input face containing each vertex and its barycentrics
  /// there (#V x 3; input vertices get a face around them and a unit vector).
  std::vector<int> origin_face;
  RowMatrixX3d origin_barycentric;
  int splits = 0;
  /// The splits in order: edge (a, b) of the mesh at that time, the new
  /// vertex m = a + t (b − a). Callers carrying edge paths (loops) insert m.
  struct Split {
    int a, b, m;
    double t;
  };
  std::vector<Split> split_log;
  /// Largest angle (degrees) before and after; obtuse_after counts the
  /// faces still above max_angle_deg (non-zero when max_splits was hit).
  double max_angle_before = 0, max_angle_after = 0;
  int obtuse_after = 0;
};

/// mesh: closed, manifold, oriented (after intake). O(#splits log #F).
ExactRefinementResult refine_obtuse_triangles(const TriMesh& mesh, const ExactRefinementOptions& options = {});

/// Barycentrics (#3, clamped to >= 0, summing to 1) of p projected into the
/// input face `input_face` (also what map/ uses to turn a located 3D point
/// into face coordinates); for checks and for callers converting located points: refined face rf, barycentrics b ->
/// input face face_origin[rf], Σ_k b_k · bary(corner k).
Eigen::Vector3d barycentric_in_input_face(const TriMesh& input, int input_face, const Eigen::Vector3d& p);

}  // namespace surfmap
