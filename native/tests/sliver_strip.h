#pragma once
// A test shape: the same closed surface with a thin strip of long slivers
// put in along a path of its edges, as a CAD tessellation leaves along a
// fillet (the teapot's handle strip, docs/handle_classes.md "Flat images, folds and the own-edge retry").
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "surfmap/mesh/tri_mesh.h"
#include "sliver_caps.h"

namespace surfmap::testing_support {

/// The path: from vertex `start`, the shortest path in edges (breadth-first,
/// neighbours in index order) to the lowest-numbered vertex `hops` edges away. Its
/// inner vertices are cut apart: the faces on the path's left get a copy of
/// each, `width` (a length) towards those faces' other corners, and the
/// crack is closed by a strip of triangles whose left row lags the right
/// one by up to `lag` vertices, so each reaches `lag` edges along the path
/// and is `width` wide: long slivers. Same genus; #V + hops - 1 vertices,
/// #F + 2 (hops - 1) faces.
inline TriMesh with_strip(const TriMesh& m, int start, int hops, double width, int lag) {
  const int nv = m.num_vertices();
  std::vector<std::set<int>> neighbours(nv);
  std::map<std::pair<int, int>, int> face_of;  // directed edge (a, b) -> its face
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = m.F(f, k), b = m.F(f, (k + 1) % 3);
      neighbours[a].insert(b);
      face_of[{a, b}] = f;
    }
  std::vector<int> parent(nv, -1), distance(nv, -1);
  std::deque<int> queue = {start};
  distance[start] = 0;
  while (!queue.empty()) {
    const int v = queue.front();
    queue.pop_front();
    for (int u : neighbours[v])
      if (distance[u] < 0) distance[u] = distance[v] + 1, parent[u] = v, queue.push_back(u);
  }
  const int end = static_cast<int>(std::find(distance.begin(), distance.end(), hops) - distance.begin());
  std::vector<int> path = {end};
  while (path.back() != start) path.push_back(parent[path.back()]);
  std::reverse(path.begin(), path.end());

  std::vector<Eigen::RowVector3d> V;
  for (int i = 0; i < nv; ++i) V.push_back(m.V.row(i));
  std::vector<Eigen::RowVector3i> F;
  for (int f = 0; f < m.num_faces(); ++f) F.push_back(m.F.row(f));
  std::vector<int> copy(path.begin(), path.end());  // the left row (the ends are shared)
  for (size_t i = 1; i + 1 < path.size(); ++i) {
    const int p = path[i], next = path[i + 1], previous = path[i - 1];
    // The faces left of p -> next, turning around p until the edge to previous.
    std::vector<int> left;
    for (int a = next, guard = 0; guard < 100; ++guard) {
      const int f = face_of.at({p, a});
      left.push_back(f);
      int k = 0;
      while (m.F(f, k) != p) ++k;
      const int b = m.F(f, (k + 2) % 3);
      if (b == previous) break;
      a = b;
    }
    Eigen::RowVector3d centre = Eigen::RowVector3d::Zero();
    int corners = 0;
    for (int f : left)
      for (int k = 0; k < 3; ++k)
        if (m.F(f, k) != p) centre += m.V.row(m.F(f, k)), ++corners;
    const Eigen::RowVector3d towards = (centre / corners - m.V.row(p)).normalized();
    copy[i] = static_cast<int>(V.size());
    V.push_back(m.V.row(p) + width * towards);
    for (int f : left)
      for (int k = 0; k < 3; ++k)
        if (F[f][k] == p) F[f][k] = copy[i];
  }
  // The strip: a ladder from (1, 1) to (k - 1, k - 1), the right row (i)
  // ahead of the left (j) by up to `lag`.
  const int k = static_cast<int>(path.size()) - 1;
  F.push_back({path[0], path[1], copy[1]});
  for (int i = 1, j = 1; i < k - 1 || j < k - 1;) {
    if ((i < k - 1 && i - j < lag) || j == k - 1) {
      F.push_back({path[i], path[i + 1], copy[j]});
      ++i;
    } else {
      F.push_back({path[i], copy[j + 1], copy[j]});
      ++j;
    }
  }
  F.push_back({path[k - 1], path[k], copy[k - 1]});
  return mesh_from_rows(V, F);
}

}  // namespace surfmap::testing_support
