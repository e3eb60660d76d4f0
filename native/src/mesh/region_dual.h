#pragma once
// The dual of a partition of a closed mesh's vertices into regions: a vertex
// per region, a face for every fine triangle whose corners lie in three
// different regions. The coarse copies of a mesh are such duals: the
// ranking's (map/coarse_source.h: farthest-point seeds, geodesic Voronoi
// regions) and the Ricci flow's multilevel start (uniformize/coarse_start.h:
// breadth-first seeds, nearest-seed regions). Both use it only when it is a
// closed oriented manifold of the fine mesh's Euler characteristic, which is
// checked here, never assumed. Internal to the core (native/src).
#include <algorithm>
#include <array>
#include <exception>
#include <memory>
#include <unordered_set>
#include <vector>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::detail {

/// The dual's faces of the partition `region` (#V: each fine vertex's region
/// 0..num_regions-1) of the fine faces F (#F x 3): one per distinct triple,
/// smallest region first with the orientation kept, in the order of the
/// first fine face that has it (a triple met again the same way round is the
/// same face). False when a vertex is in no region (-1) or a triple is also
/// met the other way round: the dual is then no oriented surface.
inline bool region_dual_faces(const RowMatrixX3i& F, const std::vector<int>& region, int num_regions,
                              std::vector<std::array<int, 3>>& faces) {
  faces.clear();
  std::unordered_set<long long> seen;
  const long long n = num_regions;
  for (int f = 0; f < F.rows(); ++f) {
    std::array<int, 3> t{region[F(f, 0)], region[F(f, 1)], region[F(f, 2)]};
    if (t[0] < 0 || t[1] < 0 || t[2] < 0) return false;
    if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) continue;
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());  // smallest first, orientation kept
    if (seen.count((t[0] * n + t[2]) * n + t[1])) return false;
    if (seen.insert((t[0] * n + t[1]) * n + t[2]).second) faces.push_back(t);
  }
  return true;
}

/// The connectivity of `faces` over num_regions vertices; null unless it is
/// a closed manifold with Euler characteristic `euler` (the fine mesh's).
inline std::unique_ptr<Connectivity> region_dual_surface(const std::vector<std::array<int, 3>>& faces,
                                                         int num_regions, int euler) {
  RowMatrixX3i F(static_cast<int>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f)
    for (int k = 0; k < 3; ++k) F(static_cast<int>(f), k) = faces[f][k];
  std::unique_ptr<Connectivity> cc;
  try {
    cc = std::make_unique<Connectivity>(F, num_regions);
    if (cc->euler_characteristic() != euler) cc.reset();
  } catch (const std::exception&) {
    cc.reset();  // not a closed manifold (Connectivity names why)
  }
  return cc;
}

/// The dual as a mesh: vertex c at fine vertex seeds[c]'s position (#Vc),
/// the faces of `dual`.
inline TriMesh region_dual_mesh(const TriMesh& fine, const std::vector<int>& seeds, const Connectivity& dual) {
  TriMesh mesh;
  const int nc = static_cast<int>(seeds.size());
  mesh.V.resize(nc, 3);
  for (int c = 0; c < nc; ++c) mesh.V.row(c) = fine.V.row(seeds[c]);
  mesh.F = dual.faces();
  return mesh;
}

}  // namespace surfmap::detail
