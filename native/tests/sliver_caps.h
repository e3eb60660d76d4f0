#pragma once
// A test shape: the same closed surface with CAD-like caps (slivers) put in.
#include <Eigen/Core>
#include <vector>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::testing_support {

/// Every `stride`-th face (a, b, c) of `m` is split at a point p just above
/// the midpoint of ab (height `eps` of the way to c), which leaves the cap
/// (a, b, p) with an angle near 180 degrees at p. Same surface, same genus;
/// #V + #F/stride vertices, #F + 2 #F/stride faces.
/// A TriMesh from lists of vertex and face rows (the fixtures build them by push_back).
inline TriMesh mesh_from_rows(const std::vector<Eigen::RowVector3d>& V, const std::vector<Eigen::RowVector3i>& F) {
  TriMesh r;
  r.V.resize(static_cast<int>(V.size()), 3);
  for (size_t i = 0; i < V.size(); ++i) r.V.row(static_cast<int>(i)) = V[i];
  r.F.resize(static_cast<int>(F.size()), 3);
  for (size_t i = 0; i < F.size(); ++i) r.F.row(static_cast<int>(i)) = F[i];
  return r;
}

inline TriMesh with_caps(const TriMesh& m, int stride, double eps) {
  std::vector<Eigen::RowVector3d> V;
  for (int i = 0; i < m.num_vertices(); ++i) V.push_back(m.V.row(i));
  std::vector<Eigen::RowVector3i> F;
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::RowVector3i t = m.F.row(f);
    if (f % stride) {
      F.push_back(t);
      continue;
    }
    const Eigen::RowVector3d mid = 0.5 * (V[t[0]] + V[t[1]]);
    const int p = static_cast<int>(V.size());
    V.push_back(mid + eps * (V[t[2]] - mid));
    F.push_back({t[0], t[1], p});
    F.push_back({t[1], t[2], p});
    F.push_back({t[2], t[0], p});
  }
  return mesh_from_rows(V, F);
}

}  // namespace surfmap::testing_support
