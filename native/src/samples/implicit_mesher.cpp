#include "implicit_mesher.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Geometry>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"

namespace surfmap::samples::detail {

using Eigen::Vector3d;

namespace {

// The surface functions used by the samples are distance-like; their
// gradients stay below this bound, which lets whole blocks of the grid be
// classified from one value at the block centre.
constexpr double kLipschitz = 2.0;
// Crossing parameters are kept this far from the grid vertices so no marching
// triangle collapses to zero area (the raw output still has slivers).
constexpr double kClampT = 1e-3;

}  // namespace

TriMesh marching_tetrahedra(const Implicit& f, const Vector3d& lo, const Vector3d& hi,
                            int resolution) {
  if (resolution < 4)
    throw InputError("marching tetrahedra: resolution " + std::to_string(resolution) +
                     " is too low (need >= 4)");
  const Vector3d ext = hi - lo;
  const double h = ext.maxCoeff() / resolution;
  const int pad = 2;
  const Vector3d origin = lo - Vector3d::Constant(pad * h);
  std::array<int, 3> n;  // cells per axis
  for (int a = 0; a < 3; ++a) n[a] = static_cast<int>(std::ceil(ext[a] / h)) + 2 * pad;
  const int64_t NX = n[0] + 1, NY = n[1] + 1;
  auto pos = [&](int64_t i, int64_t j, int64_t k) {
    return Vector3d(origin.x() + i * h, origin.y() + j * h, origin.z() + k * h);
  };

  // Coarse classification: blocks of B^3 cells whose centre value exceeds the
  // Lipschitz bound over the block cannot contain the surface; their grid
  // values only need a sign. This makes the cost proportional to the surface.
  const int B = 8;
  std::array<int, 3> nb;
  for (int a = 0; a < 3; ++a) nb[a] = (n[a] + B - 1) / B;
  std::vector<signed char> far(static_cast<size_t>(nb[0]) * nb[1] * nb[2], 0);
  const double reach = kLipschitz * B * h * std::sqrt(3.0) * 0.5 * 1.05;
  for (int bk = 0; bk < nb[2]; ++bk)
    for (int bj = 0; bj < nb[1]; ++bj)
      for (int bi = 0; bi < nb[0]; ++bi) {
        const Vector3d c = origin + h * B * Vector3d(bi + 0.5, bj + 0.5, bk + 0.5);
        const double v = f(c);
        if (std::abs(v) > reach)
          far[(static_cast<size_t>(bk) * nb[1] + bj) * nb[0] + bi] = v > 0 ? 1 : -1;
      }
  auto block_sign = [&](int64_t i, int64_t j, int64_t k) -> int {
    const int bi = static_cast<int>(std::min<int64_t>(i, n[0] - 1) / B);
    const int bj = static_cast<int>(std::min<int64_t>(j, n[1] - 1) / B);
    const int bk = static_cast<int>(std::min<int64_t>(k, n[2] - 1) / B);
    return far[(static_cast<size_t>(bk) * nb[1] + bj) * nb[0] + bi];
  };

  std::vector<double> layer[2];
  layer[0].resize(NX * NY);
  layer[1].resize(NX * NY);
  auto fill_layer = [&](int64_t k, std::vector<double>& out) {
    for (int64_t j = 0; j < NY; ++j)
      for (int64_t i = 0; i < NX; ++i) {
        const int s = block_sign(i, j, k);
        double v;
        if (s != 0) {
          v = s * reach;  // only the sign is ever used far from the surface
        } else {
          v = f(pos(i, j, k));
          // Level value perturbation: no grid vertex lies exactly on the
          // surface, so every crossing is transversal and the output manifold.
          if (v == 0.0) v = 1e-12 * h;
        }
        const bool boundary =
            i == 0 || j == 0 || k == 0 || i == NX - 1 || j == NY - 1 || k == n[2];
        if (boundary && v < 0)
          throw Error("marching tetrahedra: the implicit surface leaves the grid at (" +
                      std::to_string(pos(i, j, k).x()) + ", " + std::to_string(pos(i, j, k).y()) +
                      ", " + std::to_string(pos(i, j, k).z()) + ")");
        out[j * NX + i] = v;
      }
  };

  std::vector<Vector3d> verts;
  std::vector<std::array<int, 3>> faces;
  std::unordered_map<int64_t, int> edge_vertex;
  edge_vertex.reserve(1 << 16);

  // Kuhn split: tet (0, e_p0, e_p0 + e_p1, 111) for each permutation p; all
  // tet edges go from a componentwise-smaller corner to a larger one, so an
  // edge is identified by its lower corner and a direction code 0..6.
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  std::array<std::array<std::array<int, 3>, 4>, 6> tets;
  for (int t = 0; t < 6; ++t) {
    std::array<int, 3> c{0, 0, 0};
    tets[t][0] = c;
    c[perms[t][0]] = 1;
    tets[t][1] = c;
    c[perms[t][1]] = 1;
    tets[t][2] = c;
    tets[t][3] = {1, 1, 1};
  }

  fill_layer(0, layer[0]);
  for (int64_t k = 0; k < n[2]; ++k) {
    fill_layer(k + 1, layer[1]);
    for (int64_t j = 0; j < n[1]; ++j)
      for (int64_t i = 0; i < n[0]; ++i) {
        double cv[2][2][2];
        int inside = 0;
        for (int dz = 0; dz < 2; ++dz)
          for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx) {
              cv[dx][dy][dz] = layer[dz][(j + dy) * NX + i + dx];
              inside += cv[dx][dy][dz] < 0;
            }
        if (inside == 0 || inside == 8) continue;
        for (const auto& tet : tets) {
          double val[4];
          int in_count = 0;
          for (int q = 0; q < 4; ++q) {
            val[q] = cv[tet[q][0]][tet[q][1]][tet[q][2]];
            in_count += val[q] < 0;
          }
          if (in_count == 0 || in_count == 4) continue;
          auto corner_pos = [&](int q) { return pos(i + tet[q][0], j + tet[q][1], k + tet[q][2]); };
          auto vertex_on = [&](int a, int b) {
            if (tet[b][0] < tet[a][0] || tet[b][1] < tet[a][1] || tet[b][2] < tet[a][2])
              std::swap(a, b);
            const int64_t gid = ((k + tet[a][2]) * NY + (j + tet[a][1])) * NX + (i + tet[a][0]);
            const int code =
                (tet[b][0] - tet[a][0]) + 2 * (tet[b][1] - tet[a][1]) + 4 * (tet[b][2] - tet[a][2]) - 1;
            const int64_t key = gid * 7 + code;
            auto it = edge_vertex.find(key);
            if (it != edge_vertex.end()) return it->second;
            double t = val[a] / (val[a] - val[b]);
            t = std::clamp(t, kClampT, 1.0 - kClampT);
            const int id = static_cast<int>(verts.size());
            verts.push_back(corner_pos(a) + t * (corner_pos(b) - corner_pos(a)));
            edge_vertex.emplace(key, id);
            return id;
          };
          // Orient (p, q, r) so its normal points from corner `in` to `out`
          // (from f < 0 to f > 0); the triangle's plane strictly separates
          // the two corners, so the test is robust.
          auto emit = [&](int p, int q, int r, int in, int out) {
            const Vector3d nrm = (verts[q] - verts[p]).cross(verts[r] - verts[p]);
            if (nrm.dot(corner_pos(out) - corner_pos(in)) < 0) std::swap(q, r);
            faces.push_back({p, q, r});
          };
          if (in_count == 1 || in_count == 3) {
            const bool lone_in = in_count == 1;
            int lone = 0;
            for (int q = 0; q < 4; ++q)
              if ((val[q] < 0) == lone_in) lone = q;
            int o[3], m = 0;
            for (int q = 0; q < 4; ++q)
              if (q != lone) o[m++] = q;
            const int a = vertex_on(lone, o[0]), b = vertex_on(lone, o[1]),
                      c = vertex_on(lone, o[2]);
            if (lone_in) emit(a, b, c, lone, o[0]);
            else emit(a, b, c, o[0], lone);
          } else {
            int ins[2], outs[2], mi = 0, mo = 0;
            for (int q = 0; q < 4; ++q) (val[q] < 0 ? ins[mi++] : outs[mo++]) = q;
            const int ac = vertex_on(ins[0], outs[0]), ad = vertex_on(ins[0], outs[1]),
                      bd = vertex_on(ins[1], outs[1]), bc = vertex_on(ins[1], outs[0]);
            // Quad ac-ad-bd-bc (consecutive points share a corner); split along
            // the shorter diagonal.
            if ((verts[ac] - verts[bd]).squaredNorm() <= (verts[ad] - verts[bc]).squaredNorm()) {
              emit(ac, ad, bd, ins[0], outs[0]);
              emit(ac, bd, bc, ins[0], outs[0]);
            } else {
              emit(ad, bd, bc, ins[0], outs[1]);
              emit(ad, bc, ac, ins[0], outs[1]);
            }
          }
        }
      }
    std::swap(layer[0], layer[1]);
  }

  TriMesh mesh;
  mesh.V.resize(static_cast<int>(verts.size()), 3);
  for (size_t v = 0; v < verts.size(); ++v) mesh.V.row(static_cast<int>(v)) = verts[v].transpose();
  mesh.F.resize(static_cast<int>(faces.size()), 3);
  for (size_t t = 0; t < faces.size(); ++t)
    for (int c = 0; c < 3; ++c) mesh.F(static_cast<int>(t), c) = faces[t][c];
  return mesh;
}

namespace {

// sin of the smallest angle (opposite the shortest edge; it is <= 60 degrees,
// so the sine orders triangles like the angle does), without trigonometry.
double min_angle(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const double l0 = (b - a).norm(), l1 = (c - b).norm(), l2 = (a - c).norm();
  const double prod = l0 * l1 * l2;
  if (prod == 0) return 0;
  return (b - a).cross(c - a).norm() * std::min({l0, l1, l2}) / prod;
}

}  // namespace

void improve_on_level_set(TriMesh& mesh, const Implicit& f, double h, int rounds) {
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  std::vector<Vector3d> P(nv);
  for (int v = 0; v < nv; ++v) P[v] = mesh.V.row(v).transpose();
  std::vector<std::array<int, 3>> F(nf);
  for (int t = 0; t < nf; ++t) F[t] = {mesh.F(t, 0), mesh.F(t, 1), mesh.F(t, 2)};
  std::vector<int> twin(3 * nf), val(nv, 0);
  {
    const Connectivity conn(mesh.F, nv);
    for (int hh = 0; hh < 3 * nf; ++hh) twin[hh] = conn.twin(hh);
    for (int t = 0; t < nf; ++t)
      for (int c = 0; c < 3; ++c) ++val[F[t][c]];
  }
  std::vector<int> vout(nv);
  for (int t = 0; t < nf; ++t)
    for (int c = 0; c < 3; ++c) vout[F[t][c]] = 3 * t + c;
  auto tail = [&](int e) { return F[e / 3][e % 3]; };
  auto head = [&](int e) { return F[e / 3][(e % 3 + 1) % 3]; };
  auto nxt = [](int e) { return 3 * (e / 3) + (e % 3 + 1) % 3; };
  auto prv = [](int e) { return 3 * (e / 3) + (e % 3 + 2) % 3; };

  const double eps = 1e-4 * h;
  auto grad = [&](const Vector3d& p, double fp) {
    return Vector3d((f(p + Vector3d(eps, 0, 0)) - fp) / eps, (f(p + Vector3d(0, eps, 0)) - fp) / eps,
                    (f(p + Vector3d(0, 0, eps)) - fp) / eps);
  };
  auto project = [&](Vector3d p) {
    for (int it = 0; it < 4; ++it) {
      const double v = f(p);
      if (std::abs(v) < 1e-9 * h) break;
      const Vector3d g = grad(p, v);
      const double g2 = g.squaredNorm();
      if (g2 < 1e-12) break;
      p -= v * g / g2;
    }
    return p;
  };
  const double tiny_area2 = 1e-6 * h * h;  // |cross| floor, far below any sane triangle

  auto has_edge = [&](int a, int b) {
    const int start = vout[a];
    int e = start;
    do {
      if (head(e) == b) return true;
      e = twin[prv(e)];
    } while (e != start);
    return false;
  };

  auto flip_pass = [&]() {
    int flips = 0;
    for (int e = 0; e < 3 * nf; ++e) {
      const int et = twin[e];
      if (et < e) continue;
      const int a = tail(e), b = head(e), c = F[e / 3][(e % 3 + 2) % 3],
                d = F[et / 3][(et % 3 + 2) % 3];
      if (c == d || val[a] <= 3 || val[b] <= 3) continue;
      const double old_min = std::min(min_angle(P[a], P[b], P[c]), min_angle(P[b], P[a], P[d]));
      const double new_min = std::min(min_angle(P[a], P[d], P[c]), min_angle(P[d], P[b], P[c]));
      if (new_min <= old_min * 1.05 + 1e-9) continue;
      const Vector3d n1 = (P[d] - P[a]).cross(P[c] - P[a]), n2 = (P[b] - P[d]).cross(P[c] - P[d]);
      if (n1.norm() < tiny_area2 || n2.norm() < tiny_area2) continue;
      const Vector3d mid = 0.5 * (P[c] + P[d]);
      const Vector3d g = grad(mid, f(mid));
      // Both new triangles must face the outside (nearly tangent to the level
      // set), or the flip could fold the surface over.
      if (n1.dot(g) < 0.5 * n1.norm() * g.norm() || n2.dot(g) < 0.5 * n2.norm() * g.norm()) continue;
      if (has_edge(c, d)) continue;
      const int f0 = e / 3, f1 = et / 3;
      const int t_bc = twin[nxt(e)], t_ca = twin[prv(e)], t_ad = twin[nxt(et)], t_db = twin[prv(et)];
      F[f0] = {a, d, c};
      F[f1] = {d, b, c};
      auto link = [&](int x, int y) { twin[x] = y; twin[y] = x; };
      link(3 * f0 + 0, t_ad);
      link(3 * f0 + 1, 3 * f1 + 2);
      link(3 * f0 + 2, t_ca);
      link(3 * f1 + 0, t_db);
      link(3 * f1 + 1, t_bc);
      vout[a] = 3 * f0 + 0;
      vout[d] = 3 * f0 + 1;
      vout[c] = 3 * f0 + 2;
      vout[b] = 3 * f1 + 1;
      --val[a]; --val[b]; ++val[c]; ++val[d];
      ++flips;
    }
    return flips;
  };

  // Unit surface normals at the vertices (gradient of f), kept in step with P.
  std::vector<Vector3d> G(nv), Gold(nv);
  auto unit_grad = [&](const Vector3d& p) {
    const Vector3d g = grad(p, f(p));
    const double gn = g.norm();
    return gn > 1e-12 ? Vector3d(g / gn) : Vector3d::Zero();
  };
  for (int v = 0; v < nv; ++v) G[v] = unit_grad(P[v]);
  // How well face t agrees with the outward surface normal (cosine), and its
  // doubled area.
  auto facing = [&](int t, double& area2) {
    const auto& q = F[t];
    const Vector3d nn = (P[q[1]] - P[q[0]]).cross(P[q[2]] - P[q[0]]);
    const Vector3d g = G[q[0]] + G[q[1]] + G[q[2]];
    area2 = nn.norm();
    const double gn = g.norm();
    return area2 > 0 && gn > 0 ? nn.dot(g) / (area2 * gn) : -1.0;
  };
  std::vector<Vector3d> Pold(nv), target(nv);
  std::vector<double> cos_old(nf), area_old(nf);
  std::vector<char> bad_v(nv);
  for (int round = 0; round < rounds; ++round) {
    flip_pass();
    for (int t = 0; t < nf; ++t) cos_old[t] = facing(t, area_old[t]);
    // Tangential umbrella step: move towards the neighbours' average, minus
    // the normal part, then back onto the level set.
    for (int v = 0; v < nv; ++v) target[v].setZero();
    for (int e = 0; e < 3 * nf; ++e) target[tail(e)] += P[head(e)];
    Pold = P;
    Gold = G;
    for (int v = 0; v < nv; ++v) {
      const Vector3d avg = target[v] / val[v];
      const Vector3d& g = G[v];
      Vector3d step = avg - P[v];
      step -= step.dot(g) * g;
      // One Newton step back to the level set: the move is tangential, so f
      // is only second-order off; the gradient there is the new normal.
      Vector3d p = P[v] + 0.8 * step;
      const double fp = f(p);
      const Vector3d gp = grad(p, fp);
      const double g2 = gp.squaredNorm();
      if (g2 > 1e-12) {
        P[v] = p - fp * gp / g2;
        G[v] = gp / std::sqrt(g2);
      }
    }
    // A face is spoiled if it turns away from the outward normal (cosine
    // below 0.1, and lower than before) or collapses; revert the vertices of
    // spoiled faces and repeat until clean (the previous state passes, so this
    // terminates).
    for (int pass = 0; pass < 100; ++pass) {
      std::fill(bad_v.begin(), bad_v.end(), 0);
      int bad = 0;
      for (int t = 0; t < nf; ++t) {
        double area2;
        const double cs = facing(t, area2);
        const bool turned = cs < 0.1 && cs < cos_old[t];
        const bool collapsed = area2 < tiny_area2 && area2 < area_old[t];
        if (turned || collapsed)
          for (int c = 0; c < 3; ++c)
            if (P[F[t][c]] != Pold[F[t][c]]) { bad_v[F[t][c]] = 1; ++bad; }
      }
      if (!bad) break;
      for (int v = 0; v < nv; ++v)
        if (bad_v[v]) { P[v] = Pold[v]; G[v] = Gold[v]; }
    }
  }
  flip_pass();
  for (int v = 0; v < nv; ++v) {
    // Final exact projection (the per-round single Newton step leaves a
    // second-order residual); a long jump would mean a wrong branch, skip it.
    const Vector3d q = project(P[v]);
    if ((q - P[v]).norm() < 0.05 * h) P[v] = q;
  }

  for (int v = 0; v < nv; ++v) mesh.V.row(v) = P[v].transpose();
  for (int t = 0; t < nf; ++t)
    for (int c = 0; c < 3; ++c) mesh.F(t, c) = F[t][c];
}

void check_closed_surface(const TriMesh& mesh, int genus, const std::string& what) {
  if (!mesh.V.allFinite()) throw Error(what + ": non-finite vertex coordinates");
  Connectivity conn = [&]() {
    try {
      return Connectivity(mesh.F, mesh.num_vertices());
    } catch (const Error& e) {
      throw Error(what + ": not a closed manifold surface: " + e.what());
    }
  }();
  // One component: union-find over edges.
  std::vector<int> parent(mesh.num_vertices());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (int e = 0; e < conn.num_edges(); ++e) parent[find(conn.edge_vertex(e, 0))] = find(conn.edge_vertex(e, 1));
  for (int v = 1; v < mesh.num_vertices(); ++v)
    if (find(v) != find(0))
      throw Error(what + ": more than one component (vertex " + std::to_string(v) +
                  " is not connected to vertex 0); raise the resolution");
  if (conn.genus() != genus)
    throw Error(what + ": got genus " + std::to_string(conn.genus()) + " instead of " +
                std::to_string(genus) + "; raise the resolution");
  double vol = 0;
  const double scale2 = (mesh.V.colwise().maxCoeff() - mesh.V.colwise().minCoeff()).squaredNorm();
  for (int t = 0; t < mesh.num_faces(); ++t) {
    const Vector3d a = mesh.V.row(mesh.F(t, 0)), b = mesh.V.row(mesh.F(t, 1)), c = mesh.V.row(mesh.F(t, 2));
    vol += a.dot(b.cross(c)) / 6.0;
    if ((b - a).cross(c - a).norm() <= 1e-14 * scale2)
      throw Error(what + ": face " + std::to_string(t) + " has zero area");
  }
  if (!(vol > 0)) throw Error(what + ": not outward oriented (signed volume " + std::to_string(vol) + ")");
}

}  // namespace surfmap::samples::detail
