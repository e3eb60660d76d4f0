// Conformal maps of disks and annuli (docs/open_surfaces.md): a harmonic
// function and its harmonic conjugate, both P1 with cotangent weights.
#include "surfmap/map/open_conformal.h"

#include <algorithm>
#include <cmath>
#include <queue>
#include <unordered_map>

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>

#include "surfmap/error.h"

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

// Harmonic function with Neumann boundary conditions and a jump `period`
// across the cut (the energy Σ w (θ_j − θ_i + c_ij)², c = ±period on the
// crossed edges), vertices with free[v] = 0 held at 0. Returns θ and the energy.
std::pair<Eigen::VectorXd, double> conjugate(const WeightedEdges& e, const std::vector<Crossing>& cut, double period,
                                             const std::vector<char>& free) {
  std::vector<double> jump(e.ends.size(), 0.0);  // c for smaller -> larger
  for (const Crossing& c : cut) jump[c.edge] += c.sign * period;
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
double signed_area_sum(const OpenConformalResult& r, const TriMesh& mesh, int* flipped, int* degenerate = nullptr) {
  double total = 0;
  int count = 0, zero = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const auto z = face_image(r, mesh, f);
    const double a = 0.5 * std::imag(std::conj(z[1] - z[0]) * (z[2] - z[0]));
    total += a;
    if (std::abs(a) <= 1e-12 * (std::norm(z[1] - z[0]) + std::norm(z[2] - z[0])))
      ++zero;
    else if (a < 0)
      ++count;
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
  std::vector<double> dist(e.nv, std::numeric_limits<double>::infinity());
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
  for (int v : loop) dist[v] = 0, heap.emplace(0.0, v);
  while (!heap.empty()) {
    const auto [d, v] = heap.top();
    heap.pop();
    if (d > dist[v]) continue;
    for (const auto& [w, l] : adj[v])
      if (d + l < dist[w]) dist[w] = d + l, heap.emplace(d + l, w);
  }
  return static_cast<int>(std::max_element(dist.begin(), dist.end()) - dist.begin());
}

}  // namespace

std::array<cd, 3> face_image(const OpenConformalResult& map, const TriMesh& mesh, int f) {
  std::array<cd, 3> z = {map.uv[mesh.F(f, 0)], map.uv[mesh.F(f, 1)], map.uv[mesh.F(f, 2)]};
  if (map.cylinder)
    for (int k = 1; k < 3; ++k) z[k] += std::round(z[0].real() - z[k].real());
  return z;
}

OpenConformalResult disk_conformal_map(const TriMesh& mesh, const OpenSurfaceTopology& topology,
                                       const OpenConformalOptions& options) {
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
  const Eigen::VectorXd u = solve_laplace(full, interior, Eigen::VectorXd::Zero(nv), source, "disk Green's function");

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
  const Eigen::VectorXd theta = conjugate(annulus, cut, 2 * M_PI, free).first;

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

OpenConformalResult annulus_conformal_map(const TriMesh& mesh, const OpenSurfaceTopology& topology,
                                          const OpenConformalOptions& options) {
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
  const Eigen::VectorXd u = solve_laplace(e, interior, held, Eigen::VectorXd::Zero(nv), "annulus harmonic");
  double energy_u = 0;
  for (size_t k = 0; k < e.ends.size(); ++k) {
    const double d = u[e.ends[k].first] - u[e.ends[k].second];
    energy_u += e.weight[k] * d * d;
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
  const auto [theta, energy_theta] = conjugate(e, cut, 1.0, free);

  OpenConformalResult r;
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

}  // namespace surfmap
