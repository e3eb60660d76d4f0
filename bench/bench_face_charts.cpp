// bench_face_charts: the harmonic map in per-face charts (issue 13) on
// surfaces whose layout one Poincaré chart cannot hold (CAD plates of genus
// 13 .. 24). The target is uniformized and its metric turned into a
// FaceAtlas. Without a source, the target's own triangulation is mapped
// onto it: every vertex starts at its corner of one of its faces, jittered
// by a fifth of its shortest edge, weights 1 (the optimum is then not the
// identity), every edge's start element composed of the transitions around
// its two ends. With a source (another meshing of the same shape, e.g. a
// jittered or re-segmented plate), every source vertex starts at the
// target's vertex of the same index when both have as many vertices (a
// jittered copy), else at its nearest point of the target in 3D, and every
// source edge's element is composed of the transitions along the shortest
// path of faces between its ends' faces (by the metric; the class of that start; weights 1). This is the
// solve alone, not surfmap map's pipeline (no class search, location or
// distortion). Prints one row per target: layout radius, whether the
// single chart holds, the solve's convergence, iterations, energy, last
// largest per-vertex gradient, the largest edge element |a| + |b| at the
// end (1 = a point; large = a global chart's entries), the images flipped
// at the start and at the optimum (each source face's image tested in the
// chart of its first corner, in the Klein model), and the seconds; then a
// line with the same problem solved in the layout's one chart.
//
//   bench_face_charts TARGET.obj [TARGET.obj ...]
//   bench_face_charts --source SOURCE.obj TARGET.obj
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <queue>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "../native/src/map/face_chart_elements.h"
#include "../native/src/seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/uniformize/layout.h"
#include "surfmap/uniformize/uniformize.h"

using namespace surfmap;
using detail::around_vertex;
using detail::close_faces;
using detail::OpenFaceRepair;
using detail::rederive_open_faces;
using detail::seconds_since;
using detail::shortest_edge_path_back;
using hyperbolic::Mobius;
using Complex = std::complex<double>;

namespace {

// Closest point of triangle abc to p, as barycentrics (Ericson, Real-Time
// Collision Detection 5.1.5).
Eigen::Vector3d closest_barycentric(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return {1 - d1 / (d1 - d3), d1 / (d1 - d3), 0};
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return {1 - d2 / (d2 - d6), 0, d2 / (d2 - d6)};
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - t, t};
  }
  const double den = 1 / (va + vb + vc);
  return {1 - (vb + vc) * den, vb * den, vc * den};
}

// The point of a canonical triangle with hyperboloid barycentrics b.
Complex hyperboloid_point(const std::array<Complex, 3>& corners, const Eigen::Vector3d& b) {
  double X = 0, Y = 0, T = 0;
  for (int k = 0; k < 3; ++k) {
    const Complex c = corners[k];
    const double n = 1 - std::norm(c);
    X += b[k] * 2 * c.real() / n, Y += b[k] * 2 * c.imag() / n, T += b[k] * (1 + std::norm(c)) / n;
  }
  const double m = std::sqrt(T * T - X * X - Y * Y);
  return Complex(X / m, Y / m) / (1 + T / m);
}

// Where a source edge's end may leave or enter the target: a face, the
// point in its canonical chart, and the element between that face's
// coordinates and those of the face the end's vertex starts in (source
// end: start face -> this face; target end: this face -> start face).
struct EdgeEnd {
  int face;
  Complex point;
  Mobius element;
};

// The element of a source edge j -> i: face0[j]'s canonical coordinates ->
// face0[i]'s along the shortest path of faces from one of j's ends to one
// of i's, measured point -> centroids -> point in the metric (Dijkstra;
// counting faces instead picks paths around a hole across long thin faces).
Mobius along_shortest_path(const Connectivity& conn, const FaceAtlas& atlas, const std::vector<EdgeEnd>& from,
                           const std::vector<EdgeEnd>& to) {
  auto centroid = [&](int f) {
    const auto& c = atlas.corners[f];
    return hyperbolic::geodesic_point(c[0], hyperbolic::midpoint(c[1], c[2]), 2.0 / 3.0);
  };
  const int nF = conn.num_faces();
  std::vector<double> dist(nF, 1e300);
  std::vector<int> parent_h(nF, -1), from_end(nF, -1), to_end(nF, -1);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  for (size_t k = 0; k < from.size(); ++k) {
    const int f = from[k].face;
    const double d = hyperbolic::distance(from[k].point, centroid(f));
    if (d < dist[f]) dist[f] = d, from_end[f] = static_cast<int>(k), queue.push({d, f});
  }
  for (size_t k = 0; k < to.size(); ++k) to_end[to[k].face] = static_cast<int>(k);
  double best = 1e300;
  int best_face = -1;
  while (!queue.empty()) {
    const auto [d, f] = queue.top();
    queue.pop();
    if (d > dist[f]) continue;
    if (d >= best) break;
    const Complex cf = centroid(f);
    if (to_end[f] >= 0) {
      const double total = d + hyperbolic::distance(cf, to[to_end[f]].point);
      if (total < best) best = total, best_face = f;
    }
    for (int s = 0; s < 3; ++s) {
      const int t = conn.twin(3 * f + s), g = Connectivity::face(t);
      const double step = hyperbolic::distance(atlas.transition[t].apply(cf), centroid(g));
      if (d + step < dist[g]) dist[g] = d + step, parent_h[g] = t, from_end[g] = -1, queue.push({d + step, g});
    }
  }
  if (best_face < 0) throw SolveError("no path of faces between the ends of a source edge");
  Mobius T = to[to_end[best_face]].element;
  int g = best_face;
  for (; parent_h[g] >= 0; g = Connectivity::face(conn.twin(parent_h[g]))) T = (T * atlas.transition[parent_h[g]]).normalized();
  return (T * from[from_end[g]].element).normalized();
}

// Source edge i -> j whose ends sit at target vertices i and j: face(j's
// first outgoing halfedge)'s coordinates -> face(i's)'s, composed of the
// elements of the target edges along the shortest edge path from i to j in
// the metric (Dijkstra), each composed around the stars of its ends.
Mobius along_shortest_edge_path(const Connectivity& conn, const FaceAtlas& atlas, const Eigen::VectorXd& lengths, int i,
                                int j) {
  auto first_out = [&](int v) { return conn.outgoing(v).front(); };
  Mobius T;  // face0[j] -> face0[v], built from j back to i
  for (int g : shortest_edge_path_back(conn, lengths, i, j, "the target")) {
    const int a = conn.tail(g), v = conn.head(g);
    // head's start face -> tail's start face for target halfedge g.
    const Mobius rho_g = (around_vertex(conn, atlas, first_out(a), g) *
                          around_vertex(conn, atlas, first_out(v), Connectivity::next(g)).inverse())
                             .normalized();
    T = (rho_g * T).normalized();
  }
  return T;
}

// A vertex's ends: every face of its star at its corner (start face out0[v]).
std::vector<EdgeEnd> vertex_ends(const Connectivity& conn, const FaceAtlas& atlas, int out0, int v, bool source) {
  std::vector<EdgeEnd> ends;
  for (int a : conn.outgoing(v)) {
    const Mobius to_start = around_vertex(conn, atlas, out0, a);  // face(a) -> face(out0)
    ends.push_back({Connectivity::face(a), atlas.corners[Connectivity::face(a)][a % 3],
                    source ? to_start.inverse() : to_start});
  }
  return ends;
}

void run(const char* path, const char* source_path) {
  const TriMesh mesh = load_mesh(path).mesh;
  const auto t0 = std::chrono::steady_clock::now();
  const UniformizeResult u = uniformize(mesh);
  const double t_uniformize = seconds_since(t0);
  const Connectivity conn(u.loops.mesh.F, u.loops.mesh.num_vertices());
  const FaceAtlas atlas = hyperbolic_face_atlas(conn, u.edge_lengths);
  const TriMesh source = source_path ? load_mesh(source_path).mesh : u.loops.mesh;
  const Connectivity sc(source.F, source.num_vertices());
  const int n = sc.num_vertices();
  std::vector<int> face0(n), out0(n);
  std::vector<Complex> w0(n);
  std::vector<WeightedEdge> edges;
  // Same vertices: edges not in the intrinsic triangulation, and the
  // source faces whose elements do not close before / after the repair.
  int along_paths = 0, by_faces = 0, repaired = 0, open_faces_before = 0, open_faces_after = 0;
  if (!source_path) {
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    for (int v = 0; v < n; ++v) {
      const std::vector<int> out = conn.outgoing(v);
      double shortest = 1e300;
      for (int h : out) shortest = std::min(shortest, u.edge_lengths[conn.edge(h)]);
      out0[v] = out.front();
      face0[v] = Connectivity::face(out0[v]);
      w0[v] = hyperbolic::exp_map(atlas.corners[face0[v]][out0[v] % 3],
                                  0.2 * shortest * Complex(U(rng), U(rng)) / std::sqrt(2.0));
    }
    for (int e = 0; e < conn.num_edges(); ++e) {
      const int h = conn.edge_halfedge(e), i = conn.tail(h), j = conn.head(h);
      WeightedEdge ed;
      ed.i = i, ed.j = j, ed.w = 1.0;
      ed.rho = (around_vertex(conn, atlas, out0[i], h) *
                around_vertex(conn, atlas, out0[j], Connectivity::next(h)).inverse())
                   .normalized();
      edges.push_back(ed);
    }
  } else if (source.num_vertices() == mesh.num_vertices()) {
    // The same vertices (a jittered copy): vertex v starts at the target's
    // vertex v (the loops' mesh keeps the input's vertices first), at its
    // corner of one of its faces.
    for (int v = 0; v < n; ++v) {
      out0[v] = conn.outgoing(v).front();
      face0[v] = Connectivity::face(out0[v]);
      w0[v] = atlas.corners[face0[v]][out0[v] % 3];
    }
    // An edge the intrinsic triangulation kept: composed around the stars
    // of its ends (its own class). The others, while some source face has
    // one of them and two known edges: from the face's closing relation
    // ρ_ab ρ_bc ρ_ca = id (the class is a cocycle); the rest along the
    // shortest path of faces.
    std::vector<char> known(sc.num_edges(), 0);
    edges.resize(sc.num_edges());
    for (int e = 0; e < sc.num_edges(); ++e) {
      const int h = sc.edge_halfedge(e), i = sc.tail(h), j = sc.head(h);
      WeightedEdge& ed = edges[e];
      ed.i = i, ed.j = j, ed.w = 1.0;
      const int kept = conn.find_halfedge(i, j);
      if (kept >= 0) {
        ed.rho = (around_vertex(conn, atlas, out0[i], kept) *
                  around_vertex(conn, atlas, out0[j], Connectivity::next(kept)).inverse())
                     .normalized();
        known[e] = 1;
      }
    }
    by_faces = close_faces(sc, known, [&](int e) -> Mobius& { return edges[e].rho; });
    std::vector<char> exact = known;
    for (int e = 0; e < sc.num_edges(); ++e)
      if (!known[e]) {
        edges[e].rho = along_shortest_edge_path(conn, atlas, u.edge_lengths, edges[e].i, edges[e].j);
        ++along_paths;
      }
    // Edges in the wrong class (their faces do not close) re-derived from a
    // face (face_chart_elements.h).
    const OpenFaceRepair repair = rederive_open_faces(sc, exact, edges);
    open_faces_before = repair.open_before, repaired = repair.repaired, open_faces_after = repair.open_after;
  } else {
    const TriMesh& T = u.loops.mesh;
    for (int v = 0; v < n; ++v) {
      const Eigen::Vector3d p = source.V.row(v).transpose();
      double best = 1e300;
      Eigen::Vector3d best_b;
      for (int f = 0; f < T.num_faces(); ++f) {
        const Eigen::Vector3d a = T.V.row(T.F(f, 0)), b = T.V.row(T.F(f, 1)), c = T.V.row(T.F(f, 2));
        const Eigen::Vector3d l = closest_barycentric(p, a, b, c);
        const double d = (l[0] * a + l[1] * b + l[2] * c - p).squaredNorm();
        if (d < best) best = d, best_b = l, face0[v] = f;
      }
      w0[v] = hyperboloid_point(atlas.corners[face0[v]], best_b);
    }
    for (int e = 0; e < sc.num_edges(); ++e) {
      const int h = sc.edge_halfedge(e), i = sc.tail(h), j = sc.head(h);
      WeightedEdge ed;
      ed.i = i, ed.j = j, ed.w = 1.0;
      ed.rho = along_shortest_path(conn, atlas, {{face0[j], w0[j], Mobius()}}, {{face0[i], w0[i], Mobius()}});
      edges.push_back(ed);
    }
  }
  HyperbolicHarmonicOptions o;
  o.max_iterations = 500;
  const auto t1 = std::chrono::steady_clock::now();
  const HyperbolicHarmonicResult r = hyperbolic_harmonic_map_in_face_charts(n, edges, atlas, face0, w0, o);
  const double t_solve = seconds_since(t1);
  double largest = 0;
  for (const Mobius& m : r.edge_effective) largest = std::max(largest, m.size());
  // Head of halfedge h in the chart of its tail.
  auto head_in_tail_chart = [&](int h) {
    const int e = sc.edge(h);
    const Mobius& A = r.edge_local[e];
    return (sc.edge_halfedge(e) == h ? A : A.inverse()).apply(Complex(0.0));
  };
  const int flipped = detail::count_flipped(sc, head_in_tail_chart);
  // The start's images the same way (its edges in the start points' charts).
  const int start_flipped = detail::count_flipped(sc, [&](int h) {
    const int e = sc.edge(h);
    const WeightedEdge& ed = edges[e];
    const Mobius A = (Mobius::translation_to(w0[ed.i]).inverse() * ed.rho * Mobius::translation_to(w0[ed.j])).normalized();
    return (sc.edge_halfedge(e) == h ? A : A.inverse()).apply(Complex(0.0));
  });
  const char* start = !source_path                                 ? "itself, jittered"
                      : source.num_vertices() == mesh.num_vertices() ? "start: same vertices"
                                                                     : "start: nearest points";
  std::printf("| %s | %s (%s) | %d | %d | %.1f | %s | %s | %d | %.6f | %.1e | %.3g | %d | %d | %.1f | %.1f |\n", path,
              source_path ? source_path : "-", start, u.genus, n, u.layout.layout_radius,
              u.single_chart ? "yes" : "no", r.converged ? "yes" : "no", r.iterations, r.energy,
              r.gradient_history.empty() ? 0.0 : r.gradient_history.back(), largest, start_flipped, flipped, t_uniformize,
              t_solve);
  // The same problem posed in the layout's one chart (what surfmap map
  // would solve): start points and edge elements through the layout's
  // global face charts, moves by the side pairings.
  {
    std::vector<Complex> z0(n);
    std::vector<WeightedEdge> single = edges;
    for (int v = 0; v < n; ++v) z0[v] = u.layout.face_charts[face0[v]].apply(w0[v]);
    for (WeightedEdge& ed : single)
      ed.rho = (u.layout.face_charts[face0[ed.i]] * ed.rho * u.layout.face_charts[face0[ed.j]].inverse()).normalized();
    try {
      const HyperbolicHarmonicResult one = hyperbolic_harmonic_map(n, single, u.layout.side_pairings, z0, o);
      const int one_flipped = detail::count_flipped(sc, [&](int h) {
        const int e = sc.edge(h);
        const Mobius& A = one.edge_local[e];
        return (sc.edge_halfedge(e) == h ? A : A.inverse()).apply(Complex(0.0));
      });
      std::printf("(the same problem in the layout's one chart: %s, %d iterations, energy %.6f, %d flipped)\n",
                  one.converged ? "converged" : "not converged", one.iterations, one.energy, one_flipped);
    } catch (const std::exception& e) {
      std::printf("(the same problem in the layout's one chart: %s)\n", e.what());
    }
  }
  if (along_paths + by_faces > 0)
    std::printf("(source edges not in the intrinsic triangulation: %d closed by faces, %d along edge paths; faces not "
                "closing %d, %d edges re-derived from a face, then %d)\n",
                by_faces, along_paths, open_faces_before, repaired, open_faces_after);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  const char* source = nullptr;
  std::vector<const char*> targets;
  for (int k = 1; k < argc; ++k) {
    if (std::string(argv[k]) == "--source" && k + 1 < argc)
      source = argv[++k];
    else
      targets.push_back(argv[k]);
  }
  if (targets.empty()) {
    std::fprintf(stderr, "usage: bench_face_charts [--source SOURCE.obj] TARGET.obj [TARGET.obj ...]\n");
    return 2;
  }
  std::printf("| target | source | genus | source vertices | layout radius | single chart | converged | iterations | "
              "energy | last gradient | largest edge element | start flipped | flipped | uniformize s | solve s |\n"
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  int failures = 0;
  for (const char* t : targets) {
    try {
      run(t, source);
    } catch (const std::exception& e) {
      std::printf("| %s | error: %s |\n", t, e.what());
      ++failures;
    }
  }
  return failures == 0 ? 0 : 1;
}
