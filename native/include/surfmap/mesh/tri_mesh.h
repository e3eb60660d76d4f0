#pragma once
#include <Eigen/Core>

namespace surfmap {

using RowMatrixX3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using RowMatrixX3i = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// A triangle mesh: V is #V x 3 positions, F is #F x 3 vertex indices,
/// counter-clockwise seen from outside. Meshes handed to algorithms have
/// passed `intake` (closed, manifold, one component, oriented outward).
struct TriMesh {
  RowMatrixX3d V;
  RowMatrixX3i F;
  int num_vertices() const { return static_cast<int>(V.rows()); }
  int num_faces() const { return static_cast<int>(F.rows()); }
};

}  // namespace surfmap
