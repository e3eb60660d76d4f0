#pragma once
// A test shape shared by the tests and the benchmarks: the boundary of a
// plate of unit cubes with g square holes, a closed genus-g surface.
#include <array>
#include <map>
#include <vector>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::testing_support {

/// The boundary of a 1-voxel-thick plate of (2g+1) x 3 unit cubes with the
/// cubes (2k+1, 1) removed: a closed genus-g surface. Every unit square is
/// split into s x s cells, two triangles each.
inline TriMesh holed_plate(int g, int s) {
  const int W = 2 * g + 1, H = 3;
  auto solid = [&](int x, int y) { return x >= 0 && y >= 0 && x < W && y < H && !(y == 1 && x % 2 == 1); };
  std::map<std::array<int, 3>, int> index;
  std::vector<std::array<double, 3>> pts;
  std::vector<std::array<int, 3>> tris;
  auto vid = [&](int x, int y, int z) {
    auto [it, inserted] = index.emplace(std::array<int, 3>{x, y, z}, static_cast<int>(pts.size()));
    if (inserted) pts.push_back({double(x) / s, double(y) / s, double(z) / s});
    return it->second;
  };
  auto square = [&](int cx, int cy, int axis, int sign) {
    int o[3] = {cx * s, cy * s, 0};
    if (sign > 0) o[axis] += s;
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int i = 0; i < s; ++i)
      for (int j = 0; j < s; ++j) {
        int id[4];
        const int du[4] = {i, i + 1, i + 1, i}, dv[4] = {j, j, j + 1, j + 1};
        for (int q = 0; q < 4; ++q) {
          int p[3];
          p[axis] = o[axis];
          p[u] = o[u] + du[q];
          p[v] = o[v] + dv[q];
          id[q] = vid(p[0], p[1], p[2]);
        }
        if (sign > 0) {
          tris.push_back({id[0], id[1], id[2]});
          tris.push_back({id[0], id[2], id[3]});
        } else {
          tris.push_back({id[0], id[2], id[1]});
          tris.push_back({id[0], id[3], id[2]});
        }
      }
  };
  for (int x = 0; x < W; ++x)
    for (int y = 0; y < H; ++y) {
      if (!solid(x, y)) continue;
      square(x, y, 2, -1);
      square(x, y, 2, +1);
      if (!solid(x - 1, y)) square(x, y, 0, -1);
      if (!solid(x + 1, y)) square(x, y, 0, +1);
      if (!solid(x, y - 1)) square(x, y, 1, -1);
      if (!solid(x, y + 1)) square(x, y, 1, +1);
    }
  TriMesh t;
  t.V.resize(static_cast<int>(pts.size()), 3);
  for (size_t i = 0; i < pts.size(); ++i) t.V.row(i) << pts[i][0], pts[i][1], pts[i][2];
  t.F.resize(static_cast<int>(tris.size()), 3);
  for (size_t i = 0; i < tris.size(); ++i) t.F.row(i) << tris[i][0], tris[i][1], tris[i][2];
  return t;
}

}  // namespace surfmap::testing_support
