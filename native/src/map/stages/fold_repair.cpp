#include "fold_repair.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "surfmap/error.h"

namespace surfmap::detail {

using hyperbolic::Mobius;

double energy_in_charts(const std::vector<WeightedEdge>& edges, const std::vector<Mobius>& edge_local) {
  double E = 0;
  for (size_t e = 0; e < edges.size() && e < edge_local.size(); ++e) {
    if (edges[e].w <= 0) continue;
    const double d = edge_local[e].displacement_of_origin();
    E += edges[e].w * d * d;
  }
  return E;
}

namespace {

// Vertices within `rings` edges of a corner of a folded face (BFS on the
// source's own edges), then closed over slivers: a face whose smallest
// angle is below `sliver` (radians) with a free corner frees its other
// corners, so the region's rim cuts no sliver (a sliver with held and free
// corners folds under the smallest move of the free ones). Held vertices
// are never freed (nor walked through: a landmark stays a wall, as in the
// landmark holds).
std::vector<char> free_region(const TriMesh& source, const Connectivity& sc, const std::vector<double>& per_face,
                              const std::vector<char>& held, int rings, const std::vector<char>& is_sliver,
                              int& count) {
  const int nv = source.num_vertices();
  std::vector<int> ring(nv, -1), queue;
  auto is_held = [&](int v) { return !held.empty() && held[v]; };
  for (int f = 0; f < source.num_faces(); ++f)
    if (!std::isfinite(per_face[f]))
      for (int k = 0; k < 3; ++k)
        if (const int v = source.F(f, k); ring[v] < 0 && !is_held(v)) ring[v] = 0, queue.push_back(v);
  for (size_t q = 0; q < queue.size(); ++q) {
    const int v = queue[q];
    if (ring[v] == rings) continue;
    for (int h : sc.outgoing(v))
      if (const int u = sc.head(h); ring[u] < 0 && !is_held(u)) ring[u] = ring[v] + 1, queue.push_back(u);
  }
  // (Sliver closure: a flood over the slivers, from the ring region.)
  for (size_t q = 0; q < queue.size(); ++q)
    for (int h : sc.outgoing(queue[q])) {
      if (!is_sliver[Connectivity::face(h)]) continue;
      const int f = Connectivity::face(h);
      for (int k = 0; k < 3; ++k)
        if (const int u = source.F(f, k); ring[u] < 0 && !is_held(u)) ring[u] = rings, queue.push_back(u);
    }
  std::vector<char> free(nv, 0);
  for (int v : queue) free[v] = 1;
  count = static_cast<int>(queue.size());
  return free;
}

// The projection (first stage): the vertices of each folded face are moved,
// one at a time, into the kernel of the polygon formed by their neighbours,
// where every face of their star is positively oriented. Seen from the
// vertex's point (centred at 0) in the Klein model, geodesics are straight
// lines and orientation is kept, so the kernel is an intersection of
// half-planes: the big square clipped by each face's far side (convex
// polygon clipping). The vertex goes from where it is towards the kernel's
// centroid, only as far as it must to clear every face by a quarter of the
// centroid's margin; among the corners of a folded face the one that moves
// least goes. Neighbours are read in the vertex's sheet through the solve's
// effective edge elements, which no move changes (no vertex leaves its sheet).
class KernelProjection {
 public:
  KernelProjection(const TriMesh& source, const Connectivity& sc, const SolverEdgeIndex& index,
                   const HyperbolicHarmonicResult& hr)
      : source_(source), sc_(sc), index_(index), eff_(hr.edge_effective), z_(hr.z) {}

  const std::vector<Complex>& points() const { return z_; }

  // Whether face f is positively oriented (Klein model centred at its corner 0).
  bool positive(int f) const {
    const Mobius c = Mobius::centring(z_[source_.F(f, 0)]);
    const Complex a = klein(c.apply(element(3 * f).apply(z_[source_.F(f, 1)])));
    const Complex b = klein(c.apply(element(3 * f + 2).inverse().apply(z_[source_.F(f, 2)])));
    return cross(a, b) > 0;
  }

  // Moves one corner of face f so that its whole star is positive; false
  // when no corner's kernel is open. `moved` gets the vertex.
  bool unfold(int f, const std::vector<char>& held, int& moved) {
    double best_move = std::numeric_limits<double>::infinity();
    Complex best_point;
    int best_v = -1;
    for (int k = 0; k < 3; ++k) {
      const int v = source_.F(f, k);
      if (!held.empty() && held[v]) continue;
      Complex x;
      const double move = kernel_move(v, x);
      if (move < best_move) best_move = move, best_point = x, best_v = v;
    }
    if (best_v < 0) return false;
    const double r2 = std::norm(best_point);
    const Complex poincare = best_point / (1.0 + std::sqrt(std::max(0.0, 1.0 - r2)));
    z_[best_v] = Mobius::translation_to(z_[best_v]).apply(poincare);
    moved = best_v;
    return true;
  }

 private:
  static double cross(Complex a, Complex b) { return a.real() * b.imag() - a.imag() * b.real(); }
  static Complex klein(Complex z) { return 2.0 * z / (1.0 + std::norm(z)); }

  // Halfedge h's element (tail's sheet -> head's), as chart_distortion reads it.
  Mobius element(int h) const {
    const int e = sc_.edge(h);
    const Mobius& A = eff_[index_.solver_edge[e]];
    return (sc_.edge_halfedge(e) == h) == static_cast<bool>(index_.forward[e]) ? A : A.inverse();
  }

  // The Klein point (centred at v's point) v should move to, and how far
  // (its Klein norm); +inf when the kernel is empty or too thin.
  double kernel_move(int v, Complex& target) const {
    const Mobius c = Mobius::centring(z_[v]);
    std::vector<std::pair<Complex, Complex>> sides;  // (a, b): x must lie left of a -> b
    for (int h : sc_.outgoing(v)) {
      const int hn = Connectivity::next(h), hp = Connectivity::next(hn);  // v->a, a->b, b->v
      const Complex a = klein(c.apply(element(h).apply(z_[sc_.head(h)])));
      const Complex b = klein(c.apply(element(hp).inverse().apply(z_[sc_.tail(hp)])));
      sides.push_back({a, b});
    }
    // Kernel: a square larger than the star, clipped by every side.
    double extent = 0;
    for (const auto& [a, b] : sides) extent = std::max({extent, std::abs(a), std::abs(b)});
    if (!(extent > 0) || !std::isfinite(extent)) return std::numeric_limits<double>::infinity();
    std::vector<Complex> poly = {{-2 * extent, -2 * extent}, {2 * extent, -2 * extent}, {2 * extent, 2 * extent},
                                 {-2 * extent, 2 * extent}};
    for (const auto& [a, b] : sides) {
      const Complex d = b - a;
      auto side = [&](Complex x) { return cross(d, x - a); };
      std::vector<Complex> next;
      for (size_t i = 0; i < poly.size(); ++i) {
        const Complex p = poly[i], q = poly[(i + 1) % poly.size()];
        const double sp = side(p), sq = side(q);
        if (sp >= 0) next.push_back(p);
        if ((sp >= 0) != (sq >= 0)) next.push_back(p + (q - p) * (sp / (sp - sq)));
      }
      poly.swap(next);
      if (poly.size() < 3) return std::numeric_limits<double>::infinity();
    }
    // Area centroid of the convex kernel (interior when its area is positive).
    double area = 0;
    Complex centroid = 0;
    for (size_t i = 0; i < poly.size(); ++i) {
      const Complex p = poly[i], q = poly[(i + 1) % poly.size()];
      const double w = cross(p, q);
      area += w;
      centroid += w * (p + q);
    }
    if (!(area > 0)) return std::numeric_limits<double>::infinity();
    centroid /= 3.0 * area;
    auto margin = [&](Complex x) {
      double m = std::numeric_limits<double>::infinity();
      for (const auto& [a, b] : sides) m = std::min(m, cross(b - a, x - a) / std::abs(b - a));
      return m;
    };
    const double full = margin(centroid);
    if (!(full > 1e-12 * extent) || std::abs(centroid) >= 0.999) return std::numeric_limits<double>::infinity();
    for (double lambda : {1.0 / 64, 1.0 / 32, 1.0 / 16, 1.0 / 8, 1.0 / 4, 1.0 / 2, 3.0 / 4, 1.0}) {
      const Complex x = lambda * centroid;
      if (margin(x) >= 0.25 * full) {
        target = x;
        return std::abs(x);
      }
    }
    target = centroid;
    return std::abs(centroid);
  }

  const TriMesh& source_;
  const Connectivity& sc_;
  const SolverEdgeIndex& index_;
  const std::vector<Mobius>& eff_;
  std::vector<Complex> z_;
};

// Every face is checked, the folded ones unfolded (Gauss-Seidel: each move
// sees the ones before), for a few rounds. The moved vertices, or empty when
// some fold stays.
std::vector<int> project_folds(const TriMesh& source, const Connectivity& sc, const SolverEdgeIndex& index,
                               const HyperbolicHarmonicResult& hr, const std::vector<char>& held,
                               std::vector<Complex>& z, int rounds) {
  KernelProjection kp(source, sc, index, hr);
  std::vector<char> moved(source.num_vertices(), 0);
  std::vector<int> moved_list;
  for (int round = 0; round < rounds; ++round) {
    bool any = false, stuck = false;
    for (int f = 0; f < source.num_faces(); ++f) {
      if (kp.positive(f)) continue;
      any = true;
      int v = -1;
      if (!kp.unfold(f, held, v)) {
        stuck = true;
        continue;
      }
      if (!moved[v]) moved[v] = 1, moved_list.push_back(v);
    }
    if (!any) {
      z = kp.points();
      return moved_list;
    }
    if (stuck && round + 1 == rounds) break;
  }
  return {};
}

}  // namespace

FoldRepairResult repair_folds_locally(const TriMesh& source, const Connectivity& sc,
                                      const std::vector<WeightedEdge>& edges, const SolverEdgeIndex& index,
                                      const IntrinsicDelaunayResult& own, const HyperbolicHarmonicResult& hr,
                                      const std::vector<double>& per_face, const std::vector<char>& held,
                                      const DeckGroup& group, const FundamentalPolygon& polygon,
                                      const FoldRepairOptions& options,
                                      const std::function<bool(int, double, double)>& progress) {
  FoldRepairResult out;
  SurfaceMapResult::FoldRepair& info = out.info;
  const int nv = source.num_vertices();
  for (double d : per_face) info.folded_faces += !std::isfinite(d);
  info.energy_before = energy_in_charts(edges, hr.edge_local);
  if (static_cast<int>(hr.vertex_deck_word.size()) != nv || hr.z.size() != static_cast<size_t>(nv) ||
      hr.edge_local.size() != edges.size()) {
    // The relaxation keeps no deck words: its chart moves cannot be composed exactly.
    info.status = "not repaired: the solve kept no vertex deck words (relaxation)";
    return out;
  }
  // Which source edge each solver edge is (-1: an edge of the intrinsic
  // triangulation only, which the own-edge problem does not have).
  std::vector<int> source_edge(edges.size(), -1);
  for (int e = 0; e < sc.num_edges(); ++e) source_edge[index.solver_edge[e]] = e;
  std::string last;
  HyperbolicHarmonicOptions ho;
  ho.tolerance = options.tolerance;
  ho.max_iterations = options.max_iterations;
  ho.relator = group.side_relator();
  ho.reduce_point = [&](Complex& p) { return polygon.reduce(p); };
  // The repaired map: points `z` in the sheets of `decks` (the edges'
  // elements unchanged) read back through a solve with every vertex held,
  // which gives its charts and its intrinsic energy; accepted when no face
  // folds there. `changed`: the vertices moved.
  auto accept = [&](const std::vector<Complex>& z, const std::vector<Word>& decks, const std::vector<char>& changed,
                    const std::string& method, int rings) {
    HyperbolicHarmonicOptions fixed = ho;
    fixed.fixed.assign(nv, 1);
    HyperbolicHarmonicResult r;
    try {
      r = solve_with_decks(nv, edges, z, decks, group, fixed);
    } catch (const Cancelled&) {
      throw;
    } catch (const Error& e) {
      last += "; " + method + ": " + e.what();
      return false;
    }
    const DistortionStats q = chart_distortion(source, sc, r.edge_local, index);
    if (q.flipped || q.degenerate) {
      last += "; " + method + ": " + std::to_string(q.flipped) + " flipped and " + std::to_string(q.degenerate) +
              " flat faces left in the solver's charts";
      return false;
    }
    info.method = method;
    info.rings = rings;
    info.free_vertices = static_cast<int>(std::count(changed.begin(), changed.end(), 1));
    for (int f = 0; f < source.num_faces(); ++f)
      info.changed_faces += changed[source.F(f, 0)] || changed[source.F(f, 1)] || changed[source.F(f, 2)];
    r.energy = energy_in_charts(edges, r.edge_local);
    info.energy_after = r.energy;
    info.status = "repaired";
    out.map = std::move(r);
    return true;
  };
  // 1. The projection alone (few vertices, each within its own star).
  {
    std::vector<Complex> z;
    const std::vector<int> moved = project_folds(source, sc, index, hr, held, z, options.projection_rounds);
    std::vector<char> changed(nv, 0);
    for (int v : moved) changed[v] = 1;
    if (moved.empty())
      last = "projection: some fold has no corner whose neighbours' kernel is open";
    else if (accept(z, hr.vertex_deck_word, changed, "projection", 0))
      return out;
  }
  // 2. Held re-solves with own-edge weights on growing rings, each followed
  // by the projection where its region's rim still folds (the rim's faces
  // have held corners, and slivers there fold under the smallest move).
  std::vector<char> is_sliver(source.num_faces(), 0);
  for (int f = 0; f < source.num_faces(); ++f) {
    double smallest = M_PI;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d a = source.V.row(source.F(f, (k + 1) % 3)) - source.V.row(source.F(f, k));
      const Eigen::Vector3d b = source.V.row(source.F(f, (k + 2) % 3)) - source.V.row(source.F(f, k));
      smallest = std::min(smallest, std::atan2(a.cross(b).norm(), a.dot(b)));
    }
    is_sliver[f] = smallest < options.sliver_degrees * M_PI / 180;
  }
  int rings = options.first_rings;
  for (int t = 0; t < options.max_tries; ++t, rings *= 2) {
    int count = 0;
    std::vector<char> free = free_region(source, sc, per_face, held, rings, is_sliver, count);
    if (count == 0) {
      last += "; every corner of the folded faces is held";
      break;
    }
    if (count > options.max_free_fraction * nv) {
      last += "; " + std::to_string(rings) + " rings free " + std::to_string(count) + " of " + std::to_string(nv) +
              " vertices (more than " + std::to_string(static_cast<int>(100 * options.max_free_fraction + 0.5)) +
              "%: not local)";
      break;
    }
    ++info.tries;
    // The held solve: own-edge weights on the edges with a free end, none
    // elsewhere (the held vertices' terms are constant), the rest held.
    std::vector<WeightedEdge> local = edges;
    for (size_t e = 0; e < local.size(); ++e) {
      const bool touches = free[local[e].i] || free[local[e].j];
      local[e].w = touches && source_edge[e] >= 0 ? own.edges[source_edge[e]].cot_weight : 0.0;
    }
    HyperbolicHarmonicOptions hs = ho;
    hs.progress = progress;
    hs.fixed.assign(nv, 1);
    for (int v = 0; v < nv; ++v) hs.fixed[v] = !free[v];
    HyperbolicHarmonicResult r;
    try {
      r = solve_with_decks(nv, local, hr.z, hr.vertex_deck_word, group, hs);
    } catch (const Cancelled&) {
      throw;
    } catch (const Error& e) {
      last += "; " + std::to_string(rings) + " rings: the held solve failed (" + e.what() + ")";
      continue;
    }
    if (!r.converged) {
      last += "; " + std::to_string(rings) + " rings: the held solve did not converge";
      continue;
    }
    const std::string method = "held re-solve of " + std::to_string(rings) + " rings";
    if (accept(r.z, r.vertex_deck_word, free, method, rings)) return out;
    std::vector<Complex> z;
    const std::vector<int> moved = project_folds(source, sc, index, r, held, z, options.projection_rounds);
    if (moved.empty()) {
      last += "; " + method + ": the projection after it is stuck";
      continue;
    }
    for (int v : moved) free[v] = 1;
    if (accept(z, r.vertex_deck_word, free, method + " and projection", rings)) return out;
  }
  info.status = "not repaired: " + last;
  return out;
}

}  // namespace surfmap::detail
