// Conformal maps of disks and annuli (docs/open_surfaces.md): a harmonic
// function and its harmonic conjugate, both P1 with cotangent weights.
#include "surfmap/map/open_conformal.h"

#include <algorithm>
#include <array>
#include <deque>
#include <cmath>
#include <queue>
#include <unordered_map>

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>

#include "surfmap/error.h"

#include "../mesh/dijkstra.h"

namespace surfmap {
namespace {

using cd = std::complex<double>;

// Undirected edges with cotangent weights (cot α + cot β)/2, optionally
// leaving out the faces at one vertex (the disk's pole).
struct WeightedEdges {
  std::vector<std::pair<int, int>> ends;  // smaller index first
  std::vector<double> weight;
  std::unordered_map<long long, int> index;
  std::vector<std::vector<int>> faces;  // per edge, its faces (1 or 2)
  int nv = 0;
  long long key(int a, int b) const { return static_cast<long long>(std::min(a, b)) * nv + std::max(a, b); }
  int find(int a, int b) const {
    auto it = index.find(key(a, b));
    return it == index.end() ? -1 : it->second;
  }
};

WeightedEdges weighted_edges(const TriMesh& mesh, int skip_vertex = -1) {
  WeightedEdges e;
  e.nv = mesh.num_vertices();
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const bool skip = mesh.F(f, 0) == skip_vertex || mesh.F(f, 1) == skip_vertex || mesh.F(f, 2) == skip_vertex;
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.F(f, (k + 1) % 3), b = mesh.F(f, (k + 2) % 3);
      auto [it, inserted] = e.index.emplace(e.key(a, b), static_cast<int>(e.ends.size()));
      if (inserted) {
        e.ends.emplace_back(std::min(a, b), std::max(a, b));
        e.weight.push_back(0.0);
        e.faces.emplace_back();
      }
      e.faces[it->second].push_back(f);
      if (skip) continue;
      const Eigen::Vector3d c = mesh.V.row(mesh.F(f, k)), pa = mesh.V.row(a), pb = mesh.V.row(b);
      const Eigen::Vector3d u = pa - c, v = pb - c;
      e.weight[it->second] += 0.5 * u.dot(v) / std::max(u.cross(v).norm(), 1e-300);
    }
  }
  return e;
}

// Intrinsic Delaunay triangulation of an open mesh by edge flips on edge
// lengths (Bobenko–Springborn; docs/method.md §2.8): its cotangent weights
// are >= 0 on interior edges and still reproduce affine functions, so the
// solves below keep their exact results on Delaunay meshes (no flip) while
// obtuse triangles (scans, decimated meshes) no longer bring negative
// weights that fold the map. Boundary edges are never flipped; edges of
// `frozen` faces neither (the disk's pole star, which the conjugate leaves
// out: keeping it the original star keeps the dual cut's period exact).
// Each intrinsic halfedge carries the path of original directed edges it
// was made from, so the cut's jumps on original edges carry over (a flip
// replaces an edge by a homotopic path inside the two triangles).
struct IntrinsicOpen {
  std::vector<std::array<int, 3>> F;
  std::vector<int> twin;                              // per halfedge 3f + k (F[f][k] -> F[f][k+1]); -1 on the boundary
  std::vector<double> len;                            // per halfedge
  std::vector<std::vector<std::pair<int, int>>> path;  // per halfedge: original directed edges, tail to head
  std::vector<char> frozen;  // per face: 1 the disk pole's star, 2 kept unflipped because the map folded it
  int flips = 0;
  static int next(int h) { return 3 * (h / 3) + (h % 3 + 1) % 3; }
  static int prev(int h) { return 3 * (h / 3) + (h % 3 + 2) % 3; }
  int tail(int h) const { return F[h / 3][h % 3]; }
  int head(int h) const { return F[h / 3][(h % 3 + 1) % 3]; }
  // cot of the angle opposite h in its face.
  double cot_at(int h) const {
    const double a = len[h], b = len[next(h)], c = len[prev(h)];
    const double s = (a + b + c) / 2;
    const double area = std::sqrt(std::max(s * (s - a) * (s - b) * (s - c), 0.0));
    return (b * b + c * c - a * a) / std::max(4 * area, 1e-300);
  }
  double angle_at_tail(int h) const {  // angle at tail(h) between h and prev(h)
    const double a = len[next(h)], b = len[h], c = len[prev(h)];
    return std::acos(std::clamp((b * b + c * c - a * a) / (2 * b * c), -1.0, 1.0));
  }
};

// `kept` (empty or #F): faces whose edges are not flipped either (frozen 2).
IntrinsicOpen intrinsic_open(const TriMesh& mesh, int frozen_vertex, bool flip, const std::vector<char>& kept = {}) {
  IntrinsicOpen m;
  const int nf = mesh.num_faces();
  m.F.resize(nf);
  m.twin.assign(3 * nf, -1);
  m.len.resize(3 * nf);
  m.path.resize(3 * nf);
  m.frozen.assign(nf, 0);
  std::unordered_map<long long, int> directed;
  const long long nv = mesh.num_vertices();
  for (int f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      m.F[f][k] = mesh.F(f, k);
      if (mesh.F(f, k) == frozen_vertex) m.frozen[f] = 1;
    }
    if (!kept.empty() && kept[f]) m.frozen[f] = 2;
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * f + k, a = mesh.F(f, k), b = mesh.F(f, (k + 1) % 3);
      m.len[h] = (mesh.V.row(a) - mesh.V.row(b)).norm();
      m.path[h] = {{a, b}};
      directed[a * nv + b] = h;
    }
  }
  for (const auto& [key, h] : directed) {
    auto it = directed.find(m.head(h) * nv + m.tail(h));
    if (it != directed.end()) m.twin[h] = it->second;
  }
  if (!flip) return m;
  std::vector<int> degree(nv, 0);  // edge ends (a boundary edge counted from its one halfedge)
  for (int h = 0; h < 3 * nf; ++h)
    if (m.twin[h] < 0 || h < m.twin[h]) ++degree[m.tail(h)], ++degree[m.head(h)];
  std::deque<int> queue;
  std::vector<char> queued(3 * nf, 0);
  for (int h = 0; h < 3 * nf; ++h)
    if (m.twin[h] > h) queue.push_back(h), queued[h] = 1;
  const int max_flips = 100 * 3 * nf;
  while (!queue.empty() && m.flips < max_flips) {
    int h = queue.front();
    queue.pop_front();
    queued[h] = 0;
    const int t = m.twin[h];
    if (t < 0) continue;
    if (m.cot_at(h) + m.cot_at(t) >= -1e-12) continue;
    const int f0 = h / 3, f1 = t / 3;
    if (f0 == f1 || m.frozen[f0] || m.frozen[f1]) continue;
    const int hn = IntrinsicOpen::next(h), hp = IntrinsicOpen::prev(h), tn = IntrinsicOpen::next(t),
              tp = IntrinsicOpen::prev(t);
    const std::array<int, 4> outer_he = {hp, tn, tp, hn};  // k->i, i->l, l->j, j->k
    bool inner_twin = false;
    for (int o : outer_he) inner_twin |= m.twin[o] >= 0 && (m.twin[o] / 3 == f0 || m.twin[o] / 3 == f1);
    const int i = m.tail(h), j = m.head(h), k = m.head(hn), l = m.head(tn);
    // Keep every vertex with two or more edges (a degree-1 vertex would sit
    // inside one face and collapse onto its neighbour).
    if (inner_twin || degree[i] - 1 < 2 || degree[j] - 1 < 2) continue;
    // New edge k-l: unfold the two triangles around i.
    const double angle_i = m.angle_at_tail(h) + m.angle_at_tail(tn);
    const double a = m.len[hp], b = m.len[tn];
    const double kl = std::sqrt(std::max(a * a + b * b - 2 * a * b * std::cos(angle_i), 0.0));
    if (!(kl > 0)) continue;
    std::array<int, 4> outer_twin;
    std::array<double, 4> outer_len;
    std::array<std::vector<std::pair<int, int>>, 4> outer_path;
    for (int q = 0; q < 4; ++q)
      outer_twin[q] = m.twin[outer_he[q]], outer_len[q] = m.len[outer_he[q]], outer_path[q] = m.path[outer_he[q]];
    std::vector<std::pair<int, int>> kl_path = outer_path[0];
    kl_path.insert(kl_path.end(), outer_path[1].begin(), outer_path[1].end());
    std::vector<std::pair<int, int>> lk_path;
    for (auto it = kl_path.rbegin(); it != kl_path.rend(); ++it) lk_path.emplace_back(it->second, it->first);
    // New faces f0 = (k, i, l), f1 = (l, j, k): slots 0, 1 the outer sides, 2 the new edge.
    m.F[f0] = {k, i, l};
    m.F[f1] = {l, j, k};
    const std::array<int, 4> new_he = {3 * f0, 3 * f0 + 1, 3 * f1, 3 * f1 + 1};
    for (int q = 0; q < 4; ++q) {
      m.twin[new_he[q]] = outer_twin[q];
      if (outer_twin[q] >= 0) m.twin[outer_twin[q]] = new_he[q];
      m.len[new_he[q]] = outer_len[q];
      m.path[new_he[q]] = std::move(outer_path[q]);
    }
    const int e0 = 3 * f0 + 2, e1 = 3 * f1 + 2;  // l->k and k->l
    m.twin[e0] = e1, m.twin[e1] = e0;
    m.len[e0] = m.len[e1] = kl;
    m.path[e0] = std::move(lk_path);
    m.path[e1] = std::move(kl_path);
    --degree[i], --degree[j], ++degree[k], ++degree[l];
    ++m.flips;
    for (int q = 0; q < 4; ++q) {
      const int o = new_he[q], ot = m.twin[o];
      if (ot < 0) continue;
      const int rep = std::min(o, ot);
      if (!queued[rep]) queue.push_back(rep), queued[rep] = 1;
    }
  }
  return m;
}

// The intrinsic triangulation's edges with their cotangent weights, faces
// at `skip_vertex` left out (as weighted_edges), and each edge's path.
struct IntrinsicEdges {
  WeightedEdges edges;  // ends tail -> head (not sorted: multi-edges and loops allowed); no index or faces
  std::vector<std::vector<std::pair<int, int>>> path;
  std::vector<char> kept;  // per edge: a side of a face kept unflipped (frozen 2)
};

IntrinsicEdges intrinsic_edges(const IntrinsicOpen& m, int nv, int skip_vertex = -1) {
  IntrinsicEdges out;
  out.edges.nv = nv;
  const int nh = static_cast<int>(m.twin.size());
  std::vector<int> edge_of(nh, -1);
  for (int h = 0; h < nh; ++h) {
    if (m.twin[h] >= 0 && m.twin[h] < h) continue;
    edge_of[h] = static_cast<int>(out.edges.ends.size());
    if (m.twin[h] >= 0) edge_of[m.twin[h]] = edge_of[h];
    out.edges.ends.emplace_back(m.tail(h), m.head(h));
    out.edges.weight.push_back(0.0);
    out.path.push_back(m.path[h]);
    out.kept.push_back(0);
  }
  for (int h = 0; h < nh; ++h)
    if (m.frozen[h / 3] == 2) out.kept[edge_of[h]] = 1;
  for (int h = 0; h < nh; ++h) {
    const auto& f = m.F[h / 3];
    if (f[0] == skip_vertex || f[1] == skip_vertex || f[2] == skip_vertex) continue;
    out.edges.weight[edge_of[h]] += 0.5 * m.cot_at(h);
  }
  return out;
}

// The cut's jumps (on original edges, smaller -> larger vertex) summed along
// each intrinsic edge's path, tail -> head.
std::vector<double> path_jumps(const IntrinsicEdges& ie, const WeightedEdges& original,
                               const std::vector<double>& original_jump) {
  std::vector<double> jump(ie.path.size(), 0.0);
  for (size_t k = 0; k < ie.path.size(); ++k)
    for (const auto& [a, b] : ie.path[k]) jump[k] += (a < b ? 1 : -1) * original_jump[original.find(a, b)];
  return jump;
}

// Positive weights on the mesh's own edges (as positive_edge_weights for
// closed sources): each cotangent weight raised to at least `floor` times
// the mean positive weight of `reference`. They no longer reproduce affine
// maps, but no edge pulls its ends across the other's faces.
void raise_to_floor(WeightedEdges& e, const WeightedEdges& reference, double floor) {
  double sum = 0;
  int count = 0;
  for (double w : reference.weight)
    if (w > 0) sum += w, ++count;
  const double least = floor * (count > 0 ? sum / count : 1.0);
  for (double& w : e.weight)
    if (!(w >= least)) w = least;
}

// Negative weights left on edges of kept faces raised to the floor (as
// delaunay_energy_weights does for the edges its flips cannot reach).
void raise_kept(IntrinsicEdges& ie, const WeightedEdges& reference, double floor) {
  double sum = 0;
  int count = 0;
  for (double w : reference.weight)
    if (w > 0) sum += w, ++count;
  const double least = floor * (count > 0 ? sum / count : 1.0);
  for (size_t k = 0; k < ie.kept.size(); ++k)
    if (ie.kept[k] && ie.edges.weight[k] < 0) ie.edges.weight[k] = least;
}

int negative_weights(const WeightedEdges& e) {
  int n = 0;
  for (double w : e.weight) n += w < 0;
  return n;
}

// Solves the weighted Laplace equation for the vertices with free[v] set,
// the others held at `values`; rhs adds a source term per vertex (the
// gradient of the energy's linear part). Returns all values.
Eigen::VectorXd solve_laplace(const WeightedEdges& e, const std::vector<char>& free, Eigen::VectorXd values,
                              const Eigen::VectorXd& rhs, const char* what) {
  const int nv = e.nv;
  std::vector<int> slot(nv, -1);
  int n = 0;
  for (int v = 0; v < nv; ++v)
    if (free[v]) slot[v] = n++;
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  for (int v = 0; v < nv; ++v)
    if (free[v]) b[slot[v]] = rhs[v];
  for (size_t k = 0; k < e.ends.size(); ++k) {
    const auto [i, j] = e.ends[k];
    const double w = e.weight[k];
    if (w == 0.0) continue;
    for (const auto& [p, q] : {std::make_pair(i, j), std::make_pair(j, i)}) {
      if (!free[p]) continue;
      trip.emplace_back(slot[p], slot[p], w);
      if (free[q])
        trip.emplace_back(slot[p], slot[q], -w);
      else
        b[slot[p]] += w * values[q];
    }
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(trip.begin(), trip.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
  if (solver.info() != Eigen::Success) throw SolveError(std::string("the ") + what + " solve failed (factorisation)");
  const Eigen::VectorXd x = solver.solve(b);
  if (solver.info() != Eigen::Success || !x.allFinite())
    throw SolveError(std::string("the ") + what + " solve failed");
  for (int v = 0; v < nv; ++v)
    if (free[v]) values[v] = x[slot[v]];
  return values;
}

// A dual path of faces from `sources` to the nearest face with an edge in
// `goal_edges` (breadth-first over faces sharing an edge; `blocked` faces
// are not entered). Returns the crossed edges with the direction of the
// crossing (+1: the halfedge of the face crossed from runs smaller -> larger
// vertex): the first is the source face's `entry` edge when given.
struct Crossing {
  int edge;
  int sign;
};

int orientation_in_face(const TriMesh& mesh, int f, int a, int b) {
  for (int k = 0; k < 3; ++k)
    if (mesh.F(f, k) == a && mesh.F(f, (k + 1) % 3) == b) return 1;
  return -1;
}

std::vector<Crossing> dual_cut(const TriMesh& mesh, const WeightedEdges& e, const std::vector<int>& sources,
                               const std::vector<int>& source_entry, const std::vector<char>& goal_edge,
                               const std::vector<char>& blocked) {
  const int nf = mesh.num_faces();
  std::vector<int> parent(nf, -2), entry(nf, -1);
  std::queue<int> queue;
  for (size_t s = 0; s < sources.size(); ++s) {
    if (parent[sources[s]] != -2) continue;
    parent[sources[s]] = -1;
    entry[sources[s]] = source_entry[s];
    queue.push(sources[s]);
  }
  int goal = -1, goal_out = -1;
  while (!queue.empty() && goal < 0) {
    const int f = queue.front();
    queue.pop();
    for (int k = 0; k < 3 && goal < 0; ++k) {
      const int edge = e.find(mesh.F(f, k), mesh.F(f, (k + 1) % 3));
      if (goal_edge[edge] && edge != entry[f]) {
        goal = f, goal_out = edge;
        break;
      }
      for (int g : e.faces[edge])
        if (g != f && parent[g] == -2 && !blocked[g]) {
          parent[g] = f, entry[g] = edge;
          queue.push(g);
        }
    }
  }
  if (goal < 0) throw SolveError("no dual path joins the boundaries (the mesh is not connected as expected)");
  // Out-edge of each face on the path, crossed from that face.
  std::vector<Crossing> cut;
  auto crossing_from = [&](int f, int edge) {
    const auto [a, b] = e.ends[edge];
    return Crossing{edge, orientation_in_face(mesh, f, a, b)};
  };
  cut.push_back(crossing_from(goal, goal_out));
  for (int f = goal; parent[f] >= 0; f = parent[f]) cut.push_back(crossing_from(parent[f], entry[f]));
  // The source face's entry edge (a boundary edge) is crossed into it.
  int first = goal;
  while (parent[first] >= 0) first = parent[first];
  if (entry[first] >= 0) {
    Crossing c = crossing_from(first, entry[first]);
    c.sign = -c.sign;
    cut.push_back(c);
  }
  return cut;
}

// The jumps of a dual cut on the original edges (smaller -> larger vertex):
// ±period on each crossed edge.
std::vector<double> cut_jumps(const WeightedEdges& e, const std::vector<Crossing>& cut, double period) {
  std::vector<double> jump(e.ends.size(), 0.0);
  for (const Crossing& c : cut) jump[c.edge] += c.sign * period;
  return jump;
}

// Harmonic function with Neumann boundary conditions and the given jumps
// (the energy Σ w (θ_j − θ_i + c_ij)², c from ends.first to ends.second),
// vertices with free[v] = 0 held at 0. Returns θ and the energy.
std::pair<Eigen::VectorXd, double> conjugate(const WeightedEdges& e, const std::vector<double>& jump,
                                             const std::vector<char>& free) {
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(e.nv);
  for (size_t k = 0; k < e.ends.size(); ++k) {
    const auto [i, j] = e.ends[k];
    // d/dθ_i of w (θ_j − θ_i + c)² = 2 w (θ_i − θ_j − c): (L θ)_i gets + w c, (L θ)_j gets − w c.
    rhs[i] += e.weight[k] * jump[k];
    rhs[j] -= e.weight[k] * jump[k];
  }
  const Eigen::VectorXd theta = solve_laplace(e, free, Eigen::VectorXd::Zero(e.nv), rhs, "harmonic conjugate");
  double energy = 0;
  for (size_t k = 0; k < e.ends.size(); ++k) {
    const auto [i, j] = e.ends[k];
    if (!free[i] && !free[j] && e.weight[k] == 0.0) continue;
    const double d = theta[j] - theta[i] + jump[k];
    energy += e.weight[k] * d * d;
  }
  return {theta, energy};
}

// Σ signed image areas; counts the flipped images and the degenerate ones
// (|area| <= 1e-12 of the squared edge lengths: the annulus's ears).
double signed_area_sum(const OpenConformalResult& r, const TriMesh& mesh, int* flipped, int* degenerate = nullptr,
                       std::vector<char>* flipped_mask = nullptr) {
  double total = 0;
  int count = 0, zero = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const auto z = face_image(r, mesh, f);
    const double a = 0.5 * std::imag(std::conj(z[1] - z[0]) * (z[2] - z[0]));
    total += a;
    if (std::abs(a) <= 1e-12 * (std::norm(z[1] - z[0]) + std::norm(z[2] - z[0])))
      ++zero;
    else if (a < 0) {
      ++count;
      if (flipped_mask) (*flipped_mask)[f] = 1;
    }
  }
  if (flipped) *flipped = count;
  if (degenerate) *degenerate = zero;
  return total;
}

std::vector<char> boundary_edge_mask(const WeightedEdges& e, const std::vector<int>& loop) {
  std::vector<char> mask(e.ends.size(), 0);
  for (size_t k = 0; k < loop.size(); ++k) mask[e.find(loop[k], loop[(k + 1) % loop.size()])] = 1;
  return mask;
}

// Vertex farthest (edge-length distance) from the boundary: the disk's pole.
int farthest_from_boundary(const TriMesh& mesh, const WeightedEdges& e, const std::vector<int>& loop) {
  std::vector<std::vector<std::pair<int, double>>> adj(e.nv);
  for (const auto& [a, b] : e.ends) {
    const double l = (mesh.V.row(a) - mesh.V.row(b)).norm();
    adj[a].emplace_back(b, l), adj[b].emplace_back(a, l);
  }
  auto neighbours = [&](int v, auto&& visit) {
    for (const auto& [w, l] : adj[v]) visit(-1, w, l);
  };
  detail::DijkstraOptions options;
  options.want_parents = false;
  detail::DijkstraResult from_boundary;
  detail::dijkstra(e.nv, neighbours, loop, options, from_boundary);
  const std::vector<double>& dist = from_boundary.distance;
  return static_cast<int>(std::max_element(dist.begin(), dist.end()) - dist.begin());
}

}  // namespace

const char* open_conformal_weights_name(OpenConformalWeights weights) {
  switch (weights) {
    case OpenConformalWeights::automatic: return "automatic";
    case OpenConformalWeights::intrinsic: return "intrinsic";
    case OpenConformalWeights::own: return "own";
    case OpenConformalWeights::positive_own: return "positive_own";
  }
  return "?";
}

std::array<cd, 3> face_image(const OpenConformalResult& map, const TriMesh& mesh, int f) {
  std::array<cd, 3> z = {map.uv[mesh.F(f, 0)], map.uv[mesh.F(f, 1)], map.uv[mesh.F(f, 2)]};
  if (map.cylinder)
    for (int k = 1; k < 3; ++k) z[k] += std::round(z[0].real() - z[k].real());
  return z;
}

namespace {

OpenConformalResult disk_map_with(const TriMesh& mesh, const OpenSurfaceTopology& topology,
                                  const OpenConformalOptions& options, OpenConformalWeights weights,
                                  const std::vector<char>& kept) {
  if (topology.genus != 0 || topology.num_boundary_loops() != 1)
    throw InputError("the disk map needs genus 0 with 1 boundary loop, got " + topology.describe());
  const int nv = mesh.num_vertices();
  const std::vector<int>& loop = topology.boundary_loops[0];
  const WeightedEdges full = weighted_edges(mesh);
  OpenConformalResult r;
  r.pole = farthest_from_boundary(mesh, full, loop);
  const int p = r.pole;
  if (std::find(loop.begin(), loop.end(), p) != loop.end())
    throw InputError("the disk has no interior vertex (every vertex is on its boundary); refine it first");

  // u = log|z|: the Green's function, L u = −2π δ_p, u = 0 on the boundary.
  std::vector<char> interior(nv, 1);
  for (int v : loop) interior[v] = 0;
  Eigen::VectorXd source = Eigen::VectorXd::Zero(nv);
  source[p] = -2 * M_PI;
  // Both solves on the intrinsic Delaunay triangulation (the pole's star kept).
  const IntrinsicOpen tri = intrinsic_open(mesh, p, weights == OpenConformalWeights::intrinsic, kept);
  r.weights = weights;
  r.intrinsic_flips = tri.flips;
  r.own_negative_weights = negative_weights(full);
  IntrinsicEdges full_intrinsic = intrinsic_edges(tri, nv);
  if (weights == OpenConformalWeights::positive_own)
    raise_to_floor(full_intrinsic.edges, full_intrinsic.edges, options.own_weights_floor);
  const WeightedEdges full_reference = full_intrinsic.edges;
  raise_kept(full_intrinsic, full_reference, options.own_weights_floor);
  r.negative_weights = negative_weights(full_intrinsic.edges);
  const Eigen::VectorXd u =
      solve_laplace(full_intrinsic.edges, interior, Eigen::VectorXd::Zero(nv), source, "disk Green's function");

  // θ = arg z: harmonic on the mesh minus the pole's star (Neumann on both
  // boundaries), jump 2π across a dual cut from the star to the boundary.
  const WeightedEdges annulus = weighted_edges(mesh, p);
  std::vector<char> star(mesh.num_faces(), 0);
  std::vector<int> sources, entries;
  for (int f = 0; f < mesh.num_faces(); ++f)
    if (mesh.F(f, 0) == p || mesh.F(f, 1) == p || mesh.F(f, 2) == p) star[f] = 1, sources.push_back(f), entries.push_back(-1);
  const std::vector<Crossing> cut =
      dual_cut(mesh, annulus, sources, entries, boundary_edge_mask(annulus, loop), star);
  std::vector<char> free(nv, 1);
  free[p] = 0;         // not in the energy
  free[loop[0]] = 0;   // θ's additive constant
  IntrinsicEdges annulus_intrinsic = intrinsic_edges(tri, nv, p);
  raise_kept(annulus_intrinsic, full_reference, options.own_weights_floor);
  if (weights == OpenConformalWeights::positive_own)  // the pole's star keeps weight 0: it is not in this energy
    for (size_t k = 0; k < annulus_intrinsic.edges.weight.size(); ++k)
      if (annulus_intrinsic.edges.weight[k] != 0.0 || (annulus_intrinsic.edges.ends[k].first != p &&
                                                       annulus_intrinsic.edges.ends[k].second != p))
        annulus_intrinsic.edges.weight[k] = std::max(annulus_intrinsic.edges.weight[k], full_intrinsic.edges.weight[k]);
  const Eigen::VectorXd theta =
      conjugate(annulus_intrinsic.edges, path_jumps(annulus_intrinsic, annulus, cut_jumps(annulus, cut, 2 * M_PI)), free)
          .first;

  r.uv.resize(nv);
  for (int v = 0; v < nv; ++v) r.uv[v] = v == p ? cd(0) : std::exp(cd(u[v], theta[v]));
  if (signed_area_sum(r, mesh, nullptr) < 0)
    for (auto& z : r.uv) z = std::conj(z);

  // Möbius normalisation: z -> (z − c)/(1 − c̄ z) with c the area-weighted
  // centroid of the images, repeated until the centroid is at the origin.
  std::vector<double> vertex_area(nv, 0.0);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) vertex_area[mesh.F(f, k)] += area / 3;
  }
  cd total_map_centre = 0;
  bool first = true;
  for (; r.centring_iterations < options.max_centring_iterations; ++r.centring_iterations) {
    cd c = 0;
    double total = 0;
    for (int v = 0; v < nv; ++v) c += vertex_area[v] * r.uv[v], total += vertex_area[v];
    c /= total;
    if (first) total_map_centre = c, first = false;
    if (std::abs(c) < options.centring_tolerance) break;
    for (auto& z : r.uv) z = (z - c) / (1.0 - std::conj(c) * z);
  }
  r.centring = total_map_centre;
  for (int v : loop) r.uv[v] /= std::abs(r.uv[v]);  // exactly on the circle
  signed_area_sum(r, mesh, &r.flipped_faces, &r.degenerate_faces);
  return r;
}

OpenConformalResult annulus_map_with(const TriMesh& mesh, const OpenSurfaceTopology& topology,
                                     const OpenConformalOptions& options, OpenConformalWeights weights,
                                  const std::vector<char>& kept) {
  if (topology.genus != 0 || topology.num_boundary_loops() != 2)
    throw InputError("the annulus map needs genus 0 with 2 boundary loops, got " + topology.describe());
  const int nv = mesh.num_vertices();
  const auto& loop0 = topology.boundary_loops[0];
  const auto& loop1 = topology.boundary_loops[1];
  const WeightedEdges e = weighted_edges(mesh);

  // u: 0 on loop 0, 1 on loop 1, harmonic inside; E(u) = Σ w (u_i − u_j)².
  std::vector<char> interior(nv, 1);
  Eigen::VectorXd held = Eigen::VectorXd::Zero(nv);
  for (int v : loop0) interior[v] = 0;
  for (int v : loop1) interior[v] = 0, held[v] = 1;
  const IntrinsicOpen tri = intrinsic_open(mesh, -1, weights == OpenConformalWeights::intrinsic, kept);
  IntrinsicEdges ie = intrinsic_edges(tri, nv);
  if (weights == OpenConformalWeights::positive_own) raise_to_floor(ie.edges, ie.edges, options.own_weights_floor);
  const WeightedEdges reference = ie.edges;
  raise_kept(ie, reference, options.own_weights_floor);
  const Eigen::VectorXd u = solve_laplace(ie.edges, interior, held, Eigen::VectorXd::Zero(nv), "annulus harmonic");
  double energy_u = 0;
  for (size_t k = 0; k < ie.edges.ends.size(); ++k) {
    const double d = u[ie.edges.ends[k].first] - u[ie.edges.ends[k].second];
    energy_u += ie.edges.weight[k] * d * d;
  }

  // θ: period 1 across a dual cut from loop 0 to loop 1, Neumann on both.
  const std::vector<char> mask0 = boundary_edge_mask(e, loop0), mask1 = boundary_edge_mask(e, loop1);
  std::vector<int> sources, entries;
  for (size_t k = 0; k < e.ends.size(); ++k)
    if (mask0[k]) sources.push_back(e.faces[k][0]), entries.push_back(static_cast<int>(k));
  const std::vector<Crossing> cut =
      dual_cut(mesh, e, sources, entries, mask1, std::vector<char>(mesh.num_faces(), 0));
  std::vector<char> free(nv, 1);
  free[loop0[0]] = 0;
  const auto [theta, energy_theta] = conjugate(ie.edges, path_jumps(ie, e, cut_jumps(e, cut, 1.0)), free);

  OpenConformalResult r;
  r.weights = weights;
  r.intrinsic_flips = tri.flips;
  r.own_negative_weights = negative_weights(e);
  r.negative_weights = negative_weights(ie.edges);
  r.cylinder = true;
  r.modulus_from_u = 1.0 / energy_u;
  r.modulus_from_theta = energy_theta;
  r.modulus = std::sqrt(r.modulus_from_u * r.modulus_from_theta);
  r.uv.resize(nv);
  for (int v = 0; v < nv; ++v) r.uv[v] = cd(theta[v] - std::floor(theta[v]), r.modulus * u[v]);
  if (signed_area_sum(r, mesh, nullptr) < 0)
    for (int v = 0; v < nv; ++v) r.uv[v] = cd(-theta[v] - std::floor(-theta[v]), r.modulus * u[v]);
  signed_area_sum(r, mesh, &r.flipped_faces, &r.degenerate_faces);
  return r;
}

// automatic: the intrinsic Delaunay weights. The intrinsic map embeds the
// intrinsic triangulation, not the user's: a sliver whose long edge was
// flipped can still fold (its middle vertex lands across the long edge's
// image). Then the folded faces keep their own edges (from the second
// round their neighbours too: keeping them at once cost more D' on the
// decimated face, max 110 against 40), with negative weights raised to
// own_weights_floor, and the solve is repeated, at most `max_kept_rounds`
// times; if faces still fold, the
// positive own-edge weights are tried too and the map with fewer flipped
// faces is kept (the intrinsic one on a tie: it reproduces affine maps).
template <class Solve>
OpenConformalResult choose_weights(const TriMesh& mesh, const OpenConformalOptions& options, Solve solve) {
  if (options.weights != OpenConformalWeights::automatic) return solve(options.weights, std::vector<char>{});
  std::vector<char> kept(mesh.num_faces(), 0);
  OpenConformalResult r = solve(OpenConformalWeights::intrinsic, kept);
  const int first_flipped = r.flipped_faces;
  int rounds = 0;
  for (; r.flipped_faces > 0 && rounds < options.max_kept_rounds; ++rounds) {
    std::vector<char> folded(mesh.num_faces(), 0);
    signed_area_sum(r, mesh, nullptr, nullptr, &folded);
    // First the folded faces alone; when faces still fold, their
    // neighbours too (they move the folded face's corners).
    std::vector<char> touched(mesh.num_vertices(), 0);
    for (int f = 0; f < mesh.num_faces(); ++f)
      if (folded[f]) {
        kept[f] = 1;
        if (rounds > 0)
          for (int k = 0; k < 3; ++k) touched[mesh.F(f, k)] = 1;
      }
    for (int f = 0; f < mesh.num_faces(); ++f)
      if (touched[mesh.F(f, 0)] || touched[mesh.F(f, 1)] || touched[mesh.F(f, 2)]) kept[f] = 1;
    r = solve(OpenConformalWeights::intrinsic, kept);
  }
  r.intrinsic_flipped_faces = first_flipped;
  r.kept_rounds = rounds;
  for (char c : kept) r.kept_faces += c;
  if (r.flipped_faces == 0) return r;
  OpenConformalResult fallback = solve(OpenConformalWeights::positive_own, std::vector<char>{});
  if (fallback.flipped_faces < r.flipped_faces) {
    fallback.intrinsic_flips = r.intrinsic_flips;
    fallback.intrinsic_flipped_faces = first_flipped;
    fallback.kept_rounds = r.kept_rounds, fallback.kept_faces = r.kept_faces;
    return fallback;
  }
  return r;
}

}  // namespace

OpenConformalResult disk_conformal_map(const TriMesh& mesh, const OpenSurfaceTopology& topology,
                                       const OpenConformalOptions& options) {
  return choose_weights(mesh, options, [&](OpenConformalWeights w, const std::vector<char>& kept) {
    return disk_map_with(mesh, topology, options, w, kept);
  });
}

OpenConformalResult annulus_conformal_map(const TriMesh& mesh, const OpenSurfaceTopology& topology,
                                          const OpenConformalOptions& options) {
  return choose_weights(mesh, options, [&](OpenConformalWeights w, const std::vector<char>& kept) {
    return annulus_map_with(mesh, topology, options, w, kept);
  });
}

}  // namespace surfmap
