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

/// The sampling grid of marching_tetrahedra: [lo, hi] padded by two cells,
/// n[a] cells of size h along axis a from `origin`; grid vertices are
/// (i, j, k) with 0 <= i < NX = n[0] + 1, 0 <= j < NY = n[1] + 1, 0 <= k <= n[2].
struct Grid {
  Vector3d origin;
  double h = 0.0;
  std::array<int, 3> n;  // cells per axis
  int64_t NX = 0, NY = 0;

  Grid(const Vector3d& lo, const Vector3d& hi, int resolution) {
    const Vector3d ext = hi - lo;
    h = ext.maxCoeff() / resolution;
    const int pad = 2;
    origin = lo - Vector3d::Constant(pad * h);
    for (int a = 0; a < 3; ++a) n[a] = static_cast<int>(std::ceil(ext[a] / h)) + 2 * pad;
    NX = n[0] + 1;
    NY = n[1] + 1;
  }
  Vector3d pos(int64_t i, int64_t j, int64_t k) const {
    return Vector3d(origin.x() + i * h, origin.y() + j * h, origin.z() + k * h);
  }
};

/// Coarse classification: blocks of B^3 cells whose centre value exceeds the
/// Lipschitz bound over the block cannot contain the surface; their grid
/// values only need a sign. This makes the cost proportional to the surface.
struct FarBlocks {
  static constexpr int B = 8;
  std::array<int, 3> nb;
  std::vector<signed char> far;  // per block: +1 / -1 far outside / inside, 0 near the surface
  double reach = 0.0;

  FarBlocks(const Implicit& f, const Grid& g) {
    const std::array<int, 3>& n = g.n;
    const double h = g.h;
    for (int a = 0; a < 3; ++a) nb[a] = (n[a] + B - 1) / B;
    far.assign(static_cast<size_t>(nb[0]) * nb[1] * nb[2], 0);
    reach = kLipschitz * B * h * std::sqrt(3.0) * 0.5 * 1.05;
    for (int bk = 0; bk < nb[2]; ++bk)
      for (int bj = 0; bj < nb[1]; ++bj)
        for (int bi = 0; bi < nb[0]; ++bi) {
          const Vector3d c = g.origin + h * B * Vector3d(bi + 0.5, bj + 0.5, bk + 0.5);
          const double v = f(c);
          if (std::abs(v) > reach)
            far[(static_cast<size_t>(bk) * nb[1] + bj) * nb[0] + bi] = v > 0 ? 1 : -1;
        }
  }
  /// The sign of the block holding grid vertex (i, j, k), 0 near the surface.
  int sign(const Grid& g, int64_t i, int64_t j, int64_t k) const {
    const int bi = static_cast<int>(std::min<int64_t>(i, g.n[0] - 1) / B);
    const int bj = static_cast<int>(std::min<int64_t>(j, g.n[1] - 1) / B);
    const int bk = static_cast<int>(std::min<int64_t>(k, g.n[2] - 1) / B);
    return far[(static_cast<size_t>(bk) * nb[1] + bj) * nb[0] + bi];
  }
};

/// The values of f at the grid vertices of layer k (NX * NY, x fastest).
/// Throws Error where f < 0 on the grid boundary.
void fill_layer(const Implicit& f, const Grid& g, const FarBlocks& blocks, int64_t k,
                std::vector<double>& out) {
  const int64_t NX = g.NX, NY = g.NY;
  for (int64_t j = 0; j < NY; ++j)
    for (int64_t i = 0; i < NX; ++i) {
      const int s = blocks.sign(g, i, j, k);
      double v;
      if (s != 0) {
        v = s * blocks.reach;  // only the sign is ever used far from the surface
      } else {
        v = f(g.pos(i, j, k));
        // Level value perturbation: no grid vertex lies exactly on the
        // surface, so every crossing is transversal and the output manifold.
        if (v == 0.0) v = 1e-12 * g.h;
      }
      const bool boundary =
          i == 0 || j == 0 || k == 0 || i == NX - 1 || j == NY - 1 || k == g.n[2];
      if (boundary && v < 0)
        throw Error("marching tetrahedra: the implicit surface leaves the grid at (" +
                    std::to_string(g.pos(i, j, k).x()) + ", " + std::to_string(g.pos(i, j, k).y()) +
                    ", " + std::to_string(g.pos(i, j, k).z()) + ")");
      out[j * NX + i] = v;
    }
}

/// A tetrahedron of a cube by its 4 corners' offsets (0/1 per axis).
using Tet = std::array<std::array<int, 3>, 4>;

/// Kuhn split: tet (0, e_p0, e_p0 + e_p1, 111) for each permutation p; all
/// tet edges go from a componentwise-smaller corner to a larger one, so an
/// edge is identified by its lower corner and a direction code 0..6.
std::array<Tet, 6> kuhn_tets() {
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  std::array<Tet, 6> tets;
  for (int t = 0; t < 6; ++t) {
    std::array<int, 3> c{0, 0, 0};
    tets[t][0] = c;
    c[perms[t][0]] = 1;
    tets[t][1] = c;
    c[perms[t][1]] = 1;
    tets[t][2] = c;
    tets[t][3] = {1, 1, 1};
  }
  return tets;
}

/// The growing output of marching_tetrahedra: one vertex per crossed grid
/// edge (welded through `edge_vertex`) and faces oriented towards f > 0.
struct TetSurface {
  const Grid& g;
  std::vector<Vector3d> verts;
  std::vector<std::array<int, 3>> faces;
  std::unordered_map<int64_t, int> edge_vertex;

  explicit TetSurface(const Grid& grid) : g(grid) { edge_vertex.reserve(1 << 16); }

  /// The triangles (one, or two for a quad) of tetrahedron `tet` of cell
  /// (i, j, k) whose corner values cv straddle 0.
  void add_tet(const Tet& tet, const double (&cv)[2][2][2], int64_t i, int64_t j, int64_t k) {
    const int64_t NX = g.NX, NY = g.NY;
    double val[4];
    int in_count = 0;
    for (int q = 0; q < 4; ++q) {
      val[q] = cv[tet[q][0]][tet[q][1]][tet[q][2]];
      in_count += val[q] < 0;
    }
    if (in_count == 0 || in_count == 4) return;
    auto corner_pos = [&](int q) { return g.pos(i + tet[q][0], j + tet[q][1], k + tet[q][2]); };
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

  TriMesh mesh() const {
    TriMesh mesh;
    mesh.V.resize(static_cast<int>(verts.size()), 3);
    for (size_t v = 0; v < verts.size(); ++v) mesh.V.row(static_cast<int>(v)) = verts[v].transpose();
    mesh.F.resize(static_cast<int>(faces.size()), 3);
    for (size_t t = 0; t < faces.size(); ++t)
      for (int c = 0; c < 3; ++c) mesh.F(static_cast<int>(t), c) = faces[t][c];
    return mesh;
  }
};

}  // namespace

TriMesh marching_tetrahedra(const Implicit& f, const Vector3d& lo, const Vector3d& hi,
                            int resolution) {
  if (resolution < 4)
    throw InputError("marching tetrahedra: resolution " + std::to_string(resolution) +
                     " is too low (need >= 4)");
  const Grid g(lo, hi, resolution);
  const FarBlocks blocks(f, g);
  std::vector<double> layer[2];
  layer[0].resize(g.NX * g.NY);
  layer[1].resize(g.NX * g.NY);
  TetSurface surface(g);
  const std::array<Tet, 6> tets = kuhn_tets();

  fill_layer(f, g, blocks, 0, layer[0]);
  for (int64_t k = 0; k < g.n[2]; ++k) {
    fill_layer(f, g, blocks, k + 1, layer[1]);
    for (int64_t j = 0; j < g.n[1]; ++j)
      for (int64_t i = 0; i < g.n[0]; ++i) {
        double cv[2][2][2];
        int inside = 0;
        for (int dz = 0; dz < 2; ++dz)
          for (int dy = 0; dy < 2; ++dy)
            for (int dx = 0; dx < 2; ++dx) {
              cv[dx][dy][dz] = layer[dz][(j + dy) * g.NX + i + dx];
              inside += cv[dx][dy][dz] < 0;
            }
        if (inside == 0 || inside == 8) continue;
        for (const Tet& tet : tets) surface.add_tet(tet, cv, i, j, k);
      }
    std::swap(layer[0], layer[1]);
  }
  return surface.mesh();
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

/// The state of improve_on_level_set: positions P (#V), faces F (#F, flipped
/// in place) with their half-edge twins (3#F; half-edge 3t + c runs from
/// corner c of face t to corner c + 1), valences and one outgoing half-edge
/// per vertex, and the unit surface normals G (gradient of f) kept in step
/// with P.
struct LevelSetMesh {
  const Implicit& f;
  const double h;
  const int nv, nf;
  std::vector<Vector3d> P;
  std::vector<std::array<int, 3>> F;
  std::vector<int> twin, val, vout;
  const double eps;         // finite-difference step of grad
  const double tiny_area2;  // |cross| floor, far below any sane triangle
  std::vector<Vector3d> G, Gold;
  std::vector<Vector3d> Pold, target;
  std::vector<double> cos_old, area_old;
  std::vector<char> bad_v;

  LevelSetMesh(const TriMesh& mesh, const Implicit& fn, double spacing)
      : f(fn),
        h(spacing),
        nv(mesh.num_vertices()),
        nf(mesh.num_faces()),
        P(nv),
        F(nf),
        twin(3 * nf),
        val(nv, 0),
        vout(nv),
        eps(1e-4 * spacing),
        tiny_area2(1e-6 * spacing * spacing),
        G(nv),
        Gold(nv),
        Pold(nv),
        target(nv),
        cos_old(nf),
        area_old(nf),
        bad_v(nv) {
    for (int v = 0; v < nv; ++v) P[v] = mesh.V.row(v).transpose();
    for (int t = 0; t < nf; ++t) F[t] = {mesh.F(t, 0), mesh.F(t, 1), mesh.F(t, 2)};
    {
      const Connectivity conn(mesh.F, nv);
      for (int hh = 0; hh < 3 * nf; ++hh) twin[hh] = conn.twin(hh);
      for (int t = 0; t < nf; ++t)
        for (int c = 0; c < 3; ++c) ++val[F[t][c]];
    }
    for (int t = 0; t < nf; ++t)
      for (int c = 0; c < 3; ++c) vout[F[t][c]] = 3 * t + c;
    for (int v = 0; v < nv; ++v) G[v] = unit_grad(P[v]);
  }

  int tail(int e) const { return F[e / 3][e % 3]; }
  int head(int e) const { return F[e / 3][(e % 3 + 1) % 3]; }
  static int nxt(int e) { return 3 * (e / 3) + (e % 3 + 1) % 3; }
  static int prv(int e) { return 3 * (e / 3) + (e % 3 + 2) % 3; }

  Vector3d grad(const Vector3d& p, double fp) const {
    return Vector3d((f(p + Vector3d(eps, 0, 0)) - fp) / eps, (f(p + Vector3d(0, eps, 0)) - fp) / eps,
                    (f(p + Vector3d(0, 0, eps)) - fp) / eps);
  }
  Vector3d project(Vector3d p) const {
    for (int it = 0; it < 4; ++it) {
      const double v = f(p);
      if (std::abs(v) < 1e-9 * h) break;
      const Vector3d g = grad(p, v);
      const double g2 = g.squaredNorm();
      if (g2 < 1e-12) break;
      p -= v * g / g2;
    }
    return p;
  }
  Vector3d unit_grad(const Vector3d& p) const {
    const Vector3d g = grad(p, f(p));
    const double gn = g.norm();
    return gn > 1e-12 ? Vector3d(g / gn) : Vector3d::Zero();
  }

  bool has_edge(int a, int b) const {
    const int start = vout[a];
    int e = start;
    do {
      if (head(e) == b) return true;
      e = twin[prv(e)];
    } while (e != start);
    return false;
  }

  /// One sweep of angle-improving flips (only where both new faces face the
  /// outside); returns the number of flips.
  int flip_pass() {
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
  }

  // How well face t agrees with the outward surface normal (cosine), and its
  // doubled area.
  double facing(int t, double& area2) const {
    const auto& q = F[t];
    const Vector3d nn = (P[q[1]] - P[q[0]]).cross(P[q[2]] - P[q[0]]);
    const Vector3d g = G[q[0]] + G[q[1]] + G[q[2]];
    area2 = nn.norm();
    const double gn = g.norm();
    return area2 > 0 && gn > 0 ? nn.dot(g) / (area2 * gn) : -1.0;
  }

  /// Tangential umbrella step: move towards the neighbours' average, minus
  /// the normal part, then back onto the level set. Records the faces'
  /// facing before it and P, G in Pold, Gold.
  void umbrella_step() {
    for (int t = 0; t < nf; ++t) cos_old[t] = facing(t, area_old[t]);
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
  }

  /// A face is spoiled if it turns away from the outward normal (cosine
  /// below 0.1, and lower than before) or collapses; revert the vertices of
  /// spoiled faces and repeat until clean (the previous state passes, so this
  /// terminates).
  void revert_spoiled() {
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

  /// Final exact projection (the per-round single Newton step leaves a
  /// second-order residual); a long jump would mean a wrong branch, skip it.
  void project_vertices() {
    for (int v = 0; v < nv; ++v) {
      const Vector3d q = project(P[v]);
      if ((q - P[v]).norm() < 0.05 * h) P[v] = q;
    }
  }

  void write_to(TriMesh& mesh) const {
    for (int v = 0; v < nv; ++v) mesh.V.row(v) = P[v].transpose();
    for (int t = 0; t < nf; ++t)
      for (int c = 0; c < 3; ++c) mesh.F(t, c) = F[t][c];
  }
};

}  // namespace

void improve_on_level_set(TriMesh& mesh, const Implicit& f, double h, int rounds) {
  LevelSetMesh m(mesh, f, h);
  for (int round = 0; round < rounds; ++round) {
    m.flip_pass();
    m.umbrella_step();
    m.revert_spoiled();
  }
  m.flip_pass();
  m.project_vertices();
  m.write_to(mesh);
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
