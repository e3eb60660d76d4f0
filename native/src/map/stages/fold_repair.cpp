#include "fold_repair.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <Eigen/Sparse>
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
  void set_points(const std::vector<Complex>& z) { z_ = z; }

  // Halfedge h's element: it carries the head's point into the tail's sheet
  // (as chart_distortion reads it).
  Mobius element(int h) const {
    const int e = sc_.edge(h);
    const Mobius& A = eff_[index_.solver_edge[e]];
    return (sc_.edge_halfedge(e) == h) == static_cast<bool>(index_.forward[e]) ? A : A.inverse();
  }

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
// sees the ones before), for a few rounds, from the points `start` in the
// sheets of hr. Whether no face folds at the end; `z` gets the points either
// way (the folds the projection could undo stay undone for the next stage),
// `moved_list` the vertices moved.
bool project_folds(const TriMesh& source, const Connectivity& sc, const SolverEdgeIndex& index,
                   const HyperbolicHarmonicResult& hr, const std::vector<Complex>& start, const std::vector<char>& held,
                   std::vector<Complex>& z, std::vector<int>& moved_list, int rounds) {
  KernelProjection kp(source, sc, index, hr);
  kp.set_points(start);
  std::vector<char> moved(source.num_vertices(), 0);
  moved_list.clear();
  bool clean = false;
  for (int round = 0; round < rounds && !clean; ++round) {
    bool any = false;
    for (int f = 0; f < source.num_faces(); ++f) {
      if (kp.positive(f)) continue;
      any = true;
      int v = -1;
      if (!kp.unfold(f, held, v)) continue;
      if (!moved[v]) moved[v] = 1, moved_list.push_back(v);
    }
    clean = !any;
  }
  if (!clean) {
    clean = true;
    for (int f = 0; f < source.num_faces() && clean; ++f) clean = kp.positive(f);
  }
  z = kp.points();
  return clean;
}

Complex to_klein(Complex z) { return 2.0 * z / (1.0 + std::norm(z)); }
Complex from_klein(Complex x) { return x / (1.0 + std::sqrt(std::max(0.0, 1.0 - std::norm(x)))); }
double cross2(Complex a, Complex b) { return a.real() * b.imag() - a.imag() * b.real(); }

// The joint embedding of fold clusters (second stage). Folded slivers that
// share vertices cannot be unfolded one corner at a time (no corner's
// kernel is open), so all free vertices near a cluster move together: the
// region R (free vertices within `rings` rings of the folded faces' corners;
// each connected part of it separately) is laid out in one flat chart of
// the target, the Klein model centred at one of its points, where geodesic
// triangles are straight and keep their orientation. Its faces (those with
// a corner in R) must form a disk. The rim (held) stays; the interior gets
// the embedding with positive weights (the source's own-edge weights,
// floored positive) and the rim fixed: a Tutte embedding, injective by
// Floater's theorem when the rim is convex in the chart, which for a small
// region of a smooth map it nearly is (checked: any folded face fails the
// try and the caller grows the region). Then each vertex walks back
// towards the intrinsic map's point (Gauss-Seidel, halving the step) as far
// as its star stays positive and no face gets flatter than
// `shape_fraction` of its source shape or than it already is, so only the
// faces that must change keep the embedding's shape.
class ClusterEmbedding {
 public:
  ClusterEmbedding(const TriMesh& source, const Connectivity& sc, const KernelProjection& sheets,
                   const IntrinsicDelaunayResult& own, const std::vector<char>& held, const FoldRepairOptions& options)
      : source_(source), sc_(sc), sheets_(sheets), own_(own), held_(held), options_(options) {
    const double shape_fraction = options.cluster_shape_fraction;
    // Each face's source shape: twice its area over its longest side squared.
    source_shape_.resize(source.num_faces());
    for (int f = 0; f < source.num_faces(); ++f) {
      const Eigen::Vector3d p0 = source.V.row(source.F(f, 0)), p1 = source.V.row(source.F(f, 1)),
                            p2 = source.V.row(source.F(f, 2));
      const double l2 = std::max({(p1 - p0).squaredNorm(), (p2 - p1).squaredNorm(), (p0 - p2).squaredNorm()});
      source_shape_[f] = l2 > 0 ? shape_fraction * (p1 - p0).cross(p2 - p0).norm() / l2 : 0.0;
    }
  }

  // Embeds each part of `free` (vertices) in its own chart, moving `z`
  // (points in the sheets of the solve) and marking `changed` where it
  // succeeds. The parts that fail (not a disk, chart not usable, or the
  // embedding folds a face) are left as they were; how many, with the last
  // reason in `why`. `parts`: how many parts there were.
  int embed(const std::vector<char>& free, const std::vector<Complex>& intrinsic_z, std::vector<Complex>& z,
            std::vector<char>& changed, int relax_rounds, int max_vertices, int& parts, std::string& why) {
    const int nv = source_.num_vertices();
    std::vector<int> part(nv, -1);
    parts = 0;
    int failed = 0;
    for (int seed = 0; seed < nv; ++seed) {
      if (!free[seed] || part[seed] >= 0) continue;
      std::vector<int> members = {seed};
      part[seed] = parts;
      for (size_t q = 0; q < members.size(); ++q)
        for (int h : sc_.outgoing(members[q]))
          if (const int u = sc_.head(h); free[u] && part[u] < 0) part[u] = parts, members.push_back(u);
      if (!embed_part(members, intrinsic_z, z, changed, relax_rounds, max_vertices, why)) {
        ++failed;
      }
      ++parts;
    }
    return failed;
  }

 private:
  // Faces flatter than this (shape below) count as folded: the solver's
  // charts would call them flat or could read them either way.
  static constexpr double kFlat = 1e-7;

  // A face's shape in the chart (twice its signed area over its longest side
  // squared): > 0 when positively oriented.
  static double shape(Complex a, Complex b, Complex c) {
    const double l2 = std::max({std::norm(b - a), std::norm(c - b), std::norm(a - c)});
    return l2 > 0 ? cross2(b - a, c - a) / l2 : 0.0;
  }

  // The region's layout: its faces (those with a corner in the part), its
  // vertices (part and rim), each vertex's element into the root's sheet,
  // the points x (now) and goal (the intrinsic map's) in the chart, and the
  // rim loop in order (counter-clockwise: the region on its left).
  struct Region {
    std::vector<int> faces, verts, rim;
    std::vector<Mobius> to_root;
    std::vector<Complex> x, goal;
    Mobius centre;
  };

  // Lays out the region of `members` (`in`: membership); false with the
  // reason when it is not a disk or leaves the chart.
  bool lay_out(const std::vector<int>& members, const std::vector<char>& in, const std::vector<Complex>& intrinsic_z,
               const std::vector<Complex>& z, std::vector<int>& local, std::vector<char>& face_in, Region& g,
               std::string& why) const {
    for (int f : g.faces) face_in[f] = 0;
    for (int v : g.verts) local[v] = -1;
    g = Region();
    for (int v : members)
      for (int h : sc_.outgoing(v))
        if (const int f = Connectivity::face(h); !face_in[f]) face_in[f] = 1, g.faces.push_back(f);
    for (int f : g.faces)
      for (int k = 0; k < 3; ++k)
        if (const int v = source_.F(f, k); local[v] < 0) local[v] = static_cast<int>(g.verts.size()), g.verts.push_back(v);
    // A disk: Euler characteristic 1 and one rim loop.
    int edges2 = 0, rim_halfedges = 0;
    for (int f : g.faces)
      for (int k = 0; k < 3; ++k) {
        const bool rim = !face_in[Connectivity::face(sc_.twin(3 * f + k))];
        edges2 += rim ? 2 : 1;
        rim_halfedges += rim;
      }
    const int euler = static_cast<int>(g.verts.size()) - edges2 / 2 + static_cast<int>(g.faces.size());
    int first = -1;
    for (int f : g.faces)
      for (int k = 0; k < 3 && first < 0; ++k)
        if (!face_in[Connectivity::face(sc_.twin(3 * f + k))]) first = 3 * f + k;
    // Walk the rim from `first`: the next rim halfedge leaves this one's head.
    for (int h = first, guard = 0; h >= 0 && guard < rim_halfedges; ++guard) {
      g.rim.push_back(sc_.tail(h));
      int n = Connectivity::next(h);
      while (face_in[Connectivity::face(sc_.twin(n))]) n = Connectivity::next(sc_.twin(n));
      h = n;
      if (h == first) break;
    }
    if (euler != 1 || static_cast<int>(g.rim.size()) != rim_halfedges) {
      why = "a region of " + std::to_string(members.size()) + " vertices is not a disk (Euler characteristic " +
            std::to_string(euler) + ", " + std::to_string(g.rim.size()) + " of " + std::to_string(rim_halfedges) +
            " rim edges in one loop)";
      return false;
    }
    // The chart: every region vertex's point carried into the root's sheet
    // along a spanning tree of the region's faces (the elements around each
    // face compose to the identity, so any tree gives the same points on a
    // disk), then centred at the root's point, in the Klein model.
    const int root = members[0];
    g.to_root.assign(g.verts.size(), Mobius());
    std::vector<char> placed(g.verts.size(), 0);
    placed[local[root]] = 1;
    std::vector<int> queue = {root};
    for (size_t q = 0; q < queue.size(); ++q) {
      const int v = queue[q];
      for (int h : sc_.outgoing(v)) {
        if (!face_in[Connectivity::face(h)] && !face_in[Connectivity::face(sc_.twin(h))]) continue;
        const int u = sc_.head(h);
        if (local[u] < 0 || placed[local[u]]) continue;
        placed[local[u]] = 1;
        g.to_root[local[u]] = (g.to_root[local[v]] * sheets_.element(h)).normalized();
        queue.push_back(u);
      }
    }
    g.centre = Mobius::centring(z[root]);
    g.x.resize(g.verts.size());
    g.goal.resize(g.verts.size());
    for (size_t i = 0; i < g.verts.size(); ++i) {
      g.x[i] = to_klein(g.centre.apply(g.to_root[i].apply(z[g.verts[i]])));
      g.goal[i] = to_klein(g.centre.apply(g.to_root[i].apply(intrinsic_z[g.verts[i]])));
      if (!(std::abs(g.x[i]) < 0.99) || !(std::abs(g.goal[i]) < 0.99)) {
        why = "a region of " + std::to_string(members.size()) + " vertices reaches the chart's edge";
        return false;
      }
    }
    (void)in;
    return true;
  }

  bool embed_part(std::vector<int> members, const std::vector<Complex>& intrinsic_z, std::vector<Complex>& z,
                  std::vector<char>& changed, int relax_rounds, int max_vertices, std::string& why) {
    const int nv = source_.num_vertices();
    std::vector<char> in(nv, 0);
    for (int v : members) in[v] = 1;
    std::vector<int> local(nv, -1);
    std::vector<char> face_in(source_.num_faces(), 0);
    Region g;
    if (!lay_out(members, in, intrinsic_z, z, local, face_in, g, why)) return false;
    (void)max_vertices;
    const int n = static_cast<int>(members.size());
    const std::vector<int>& faces = g.faces;
    std::vector<Complex>& x = g.x;
    const std::vector<Complex>& goal = g.goal;
    std::vector<int> unknown(g.verts.size(), -1);
    for (int i = 0; i < n; ++i) unknown[local[members[i]]] = i;
    auto face_shape = [&](int f) {
      return shape(x[local[source_.F(f, 0)]], x[local[source_.F(f, 1)]], x[local[source_.F(f, 2)]]);
    };
    // The joint untangling: Levenberg-Marquardt on
    //   Σ_f min(0, (s_f − ε_f) / L_f²)² + λ Σ_ij |(x_i − x_j) − (g_i − g_j)|² / L_ij²
    // over the part's points (the rim fixed), from where they are: s_f is the
    // face's signed double area in the chart, L_f its longest side in the
    // intrinsic map (g) and ε_f = shape_fraction x its source shape x L_f²,
    // so every face is asked to be positive and no flatter than that; the
    // second term keeps the edges as the intrinsic map has them. Each face
    // area is affine in each corner, so the Jacobian is exact and small.
    std::vector<double> L2(faces.size()), eps(faces.size());
    double typical = 0;
    for (size_t k = 0; k < faces.size(); ++k) {
      const int f = faces[k];
      const Complex a = goal[local[source_.F(f, 0)]], b = goal[local[source_.F(f, 1)]], c = goal[local[source_.F(f, 2)]];
      L2[k] = std::max({std::norm(b - a), std::norm(c - b), std::norm(a - c)});
      typical += L2[k];
    }
    typical /= std::max<size_t>(1, faces.size());
    for (size_t k = 0; k < faces.size(); ++k) {
      L2[k] = std::max(L2[k], 1e-4 * typical);
      const double scale = std::max(source_shape_[faces[k]], 1e-9) * L2[k];
      eps[k] = options_.cluster_floor * scale;
      L2[k] = scale;  // residuals relative to the face's source shape
    }
    struct Edge { int i, j; double scale; };
    std::vector<Edge> springs;
    for (int v : members)
      for (int h : sc_.outgoing(v)) {
        const int u = sc_.head(h);
        if (unknown[local[u]] >= 0 && u < v) continue;  // once per edge
        const double l2 = std::max(std::norm(goal[local[v]] - goal[local[u]]), 1e-4 * typical);
        springs.push_back({local[v], local[u], 1.0 / std::sqrt(l2)});
      }
    const double lambda = options_.cluster_spring;
    auto objective = [&](const std::vector<Complex>& p, int& negative) {
      double F = 0;
      negative = 0;
      for (size_t k = 0; k < faces.size(); ++k) {
        const int f = faces[k];
        const Complex a = p[local[source_.F(f, 0)]], b = p[local[source_.F(f, 1)]], c = p[local[source_.F(f, 2)]];
        const double sa = cross2(b - a, c - a);
        negative += !(shape(a, b, c) > kFlat);
        if (sa < eps[k]) F += std::pow((sa - eps[k]) / L2[k], 2);
      }
      for (const Edge& e : springs) F += lambda * std::norm(((p[e.i] - p[e.j]) - (goal[e.i] - goal[e.j])) * e.scale);
      return F;
    };
    // Two starts: where the points are (a few faces fold), then, when
    // folds stay (a twisted strip of slivers needs a move no local descent
    // finds), the embedding with positive weights (the source's own-edge
    // weights) and the rim fixed, Tutte's: it has no twist, only folds where
    // the rim is not convex in the chart, which the descent then removes.
    const std::vector<Complex> start = x;
    auto tutte = [&]() {
      std::vector<Eigen::Triplet<double>> trip;
      Eigen::VectorXcd rhs = Eigen::VectorXcd::Zero(n);
      for (int i = 0; i < n; ++i) {
        double diag = 0;
        for (int h : sc_.outgoing(members[i])) {
          const double w = std::max(own_.edges[sc_.edge(h)].cot_weight, 1e-12);
          const int u = sc_.head(h);
          diag += w;
          if (const int j = unknown[local[u]]; j >= 0) trip.emplace_back(i, j, -w);
          else rhs[i] += w * start[local[u]];
        }
        trip.emplace_back(i, i, diag);
      }
      Eigen::SparseMatrix<double> Lap(n, n);
      Lap.setFromTriplets(trip.begin(), trip.end());
      Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(Lap);
      if (solver.info() != Eigen::Success) return false;
      const Eigen::VectorXd re = solver.solve(rhs.real()), im = solver.solve(rhs.imag());
      for (int i = 0; i < n; ++i) x[local[members[i]]] = Complex(re[i], im[i]);
      return true;
    };
    // The descent: Levenberg-Marquardt steps that lower the objective,
    // until nothing folds or `iterations`.
    double F = 0;
    int negative = 0;
    auto descend = [&](int iterations) {
      F = objective(x, negative);
    double mu = 1e-3;
    for (int it = 0; it < iterations && negative > 0; ++it) {
      // Normal equations JᵀJ δ = −Jᵀr, over 2n reals (re, im per point).
      std::vector<Eigen::Triplet<double>> trip;
      Eigen::VectorXd grad = Eigen::VectorXd::Zero(2 * n);
      auto add_row = [&](const std::vector<std::pair<int, double>>& row, double r) {
        for (const auto& [ci, cv] : row) {
          grad[ci] += cv * r;
          for (const auto& [cj, cw] : row) trip.emplace_back(ci, cj, cv * cw);
        }
      };
      for (size_t k = 0; k < faces.size(); ++k) {
        const int f = faces[k];
        int id[3];
        Complex q[3];
        for (int c = 0; c < 3; ++c) id[c] = local[source_.F(f, c)], q[c] = x[id[c]];
        const double sa = cross2(q[1] - q[0], q[2] - q[0]);
        if (!(sa < eps[k])) continue;
        std::vector<std::pair<int, double>> row;
        for (int c = 0; c < 3; ++c) {
          const int j = unknown[id[c]];
          if (j < 0) continue;
          const Complex b = q[(c + 1) % 3], d = q[(c + 2) % 3];
          row.push_back({2 * j, (b.imag() - d.imag()) / L2[k]});
          row.push_back({2 * j + 1, (d.real() - b.real()) / L2[k]});
        }
        add_row(row, (sa - eps[k]) / L2[k]);
      }
      const double sl = std::sqrt(lambda);
      for (const Edge& e : springs) {
        const Complex r = ((x[e.i] - x[e.j]) - (goal[e.i] - goal[e.j])) * e.scale * sl;
        for (int part = 0; part < 2; ++part) {
          std::vector<std::pair<int, double>> row;
          if (const int j = unknown[e.i]; j >= 0) row.push_back({2 * j + part, e.scale * sl});
          if (const int j = unknown[e.j]; j >= 0) row.push_back({2 * j + part, -e.scale * sl});
          add_row(row, part ? r.imag() : r.real());
        }
      }
      Eigen::SparseMatrix<double> H(2 * n, 2 * n);
      H.setFromTriplets(trip.begin(), trip.end());
      Eigen::VectorXd diag = H.diagonal();
      bool stepped = false;
      for (int attempt = 0; attempt < 12 && !stepped; ++attempt) {
        Eigen::SparseMatrix<double> A = H;
        for (int r = 0; r < 2 * n; ++r) A.coeffRef(r, r) += mu * (diag[r] + 1e-12);
        Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
        if (solver.info() != Eigen::Success) {
          mu *= 10;
          continue;
        }
        const Eigen::VectorXd delta = solver.solve(-grad);
        std::vector<Complex> trial = x;
        for (int i = 0; i < n; ++i) trial[local[members[i]]] += Complex(delta[2 * i], delta[2 * i + 1]);
        int trial_negative = 0;
        const double trial_F = objective(trial, trial_negative);
        if (trial_F < F) {
          x.swap(trial), F = trial_F, negative = trial_negative, stepped = true;
          mu = std::max(mu / 3, 1e-9);
        } else {
          mu *= 4;
        }
      }
      if (!stepped) break;
    }
    };
    for (int attempt = 0; attempt < 2; ++attempt) {
      if (attempt == 1 && !tutte()) break;
      descend(options_.cluster_iterations);
      if (negative == 0) break;
    }
    int folded = 0;
    for (int f : faces) folded += !(face_shape(f) > kFlat);
    for (int i = 0; i < static_cast<int>(g.verts.size()); ++i)
      if (!(std::abs(x[i]) < 0.995)) ++folded;
    if (folded) {
      why = "the untangling of a region of " + std::to_string(n) + " vertices leaves " + std::to_string(folded) +
            " of its " + std::to_string(faces.size()) + " faces folded";
      return false;
    }
    // Back towards the intrinsic map, each vertex as far as its star allows.
    for (int round = 0; round < relax_rounds; ++round) {
      double moved = 0;
      for (int v : members) {
        if (!held_.empty() && held_[v]) continue;
        const int i = local[v];
        const Complex from = x[i];
        std::vector<int> star;
        std::vector<double> floor;
        for (int h : sc_.outgoing(v)) {
          const int f = Connectivity::face(h);
          star.push_back(f);
          floor.push_back(std::min(face_shape(f), source_shape_[f]));
        }
        for (double t = 1.0; t > 1.0 / 64; t *= 0.5) {
          x[i] = from + t * (goal[i] - from);
          bool ok = true;
          for (size_t s = 0; s < star.size() && ok; ++s) ok = face_shape(star[s]) >= floor[s] && face_shape(star[s]) > kFlat;
          if (ok) break;
          x[i] = from;
        }
        moved = std::max(moved, std::abs(x[i] - from));
      }
      if (moved < 1e-14) break;
    }
    // Back into each vertex's own sheet.
    const Mobius uncentre = g.centre.inverse();
    for (int v : members) {
      z[v] = g.to_root[local[v]].inverse().apply(uncentre.apply(from_klein(x[local[v]])));
      changed[v] = 1;
    }
    return true;
  }

  const TriMesh& source_;
  const Connectivity& sc_;
  const KernelProjection& sheets_;
  const IntrinsicDelaunayResult& own_;
  const std::vector<char>& held_;
  std::vector<double> source_shape_;
  const FoldRepairOptions& options_;
};

// Vertices within `rings` edges of a corner of a face not positive under
// `kp`, held ones excepted (and not walked through). `count`: how many.
std::vector<char> fold_neighbourhood(const TriMesh& source, const Connectivity& sc, const KernelProjection& kp,
                                     const std::vector<char>& held, int rings, int& count) {
  std::vector<double> per_face(source.num_faces(), 0.0);
  for (int f = 0; f < source.num_faces(); ++f)
    if (!kp.positive(f)) per_face[f] = std::numeric_limits<double>::infinity();
  const std::vector<char> none(source.num_faces(), 0);
  return free_region(source, sc, per_face, held, rings, none, count);
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
                    const std::string& method, int rings, double max_mean_rise = -1) {
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
    if (max_mean_rise >= 0) {
      // The quality guard: the map's area-weighted mean D' against that of
      // the faces it did not change (the intrinsic map's).
      double all = 0, all_area = 0, kept = 0, kept_area = 0;
      for (int f = 0; f < source.num_faces(); ++f) {
        if (!std::isfinite(q.per_face[f])) continue;
        const Eigen::Vector3d p0 = source.V.row(source.F(f, 0)), p1 = source.V.row(source.F(f, 1)),
                              p2 = source.V.row(source.F(f, 2));
        const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
        all += area * q.per_face[f], all_area += area;
        if (!changed[source.F(f, 0)] && !changed[source.F(f, 1)] && !changed[source.F(f, 2)])
          kept += area * q.per_face[f], kept_area += area;
      }
      const double mean = all / all_area, kept_mean = kept / kept_area;
      if (!(mean <= (1 + max_mean_rise) * kept_mean)) {
        char text[200];
        std::snprintf(text, sizeof text, "mean D' %.3g, more than %.0f%% above the unchanged faces' %.3g", mean,
                      100 * max_mean_rise, kept_mean);
        last += "; " + method + ": " + text;
        return false;
      }
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
  std::vector<Complex> projected;
  std::vector<char> changed(nv, 0);
  {
    std::vector<int> moved;
    const bool clean = project_folds(source, sc, index, hr, hr.z, held, projected, moved, options.projection_rounds);
    for (int v : moved) changed[v] = 1;
    if (!clean)
      last = "projection: " + std::string(moved.empty() ? "some fold has no corner whose neighbours' kernel is open"
                                                        : "folds left where no corner's kernel is open");
    else if (accept(projected, hr.vertex_deck_word, changed, "projection", 0))
      return out;
  }
  // 2. The joint embedding of the clusters the projection left, on growing
  // rings (each part that embeds stays; the folds left grow their region).
  if (options.cluster_max_rings > 0) {
    KernelProjection sheets(source, sc, index, hr);
    sheets.set_points(projected);
    ClusterEmbedding ce(source, sc, sheets, own, held, options);
    std::vector<Complex> z = projected;
    std::string why;
    int rings = 1, parts = 0, tries = 0, used_rings = 0;
    for (; rings <= options.cluster_max_rings; rings = std::max(rings + 1, rings * 3 / 2)) {
      int count = 0;
      const std::vector<char> free = fold_neighbourhood(source, sc, sheets, held, rings, count);
      if (count == 0) break;  // no fold left
      if (count > options.max_free_fraction * nv) {
        why = std::to_string(rings) + " rings free " + std::to_string(count) + " of " + std::to_string(nv) +
              " vertices (not local)";
        break;
      }
      ++tries;
      used_rings = rings;
      const int failed = ce.embed(free, hr.z, z, changed, options.cluster_relax_rounds, static_cast<int>(options.max_free_fraction * nv), parts, why);
      sheets.set_points(z);
      if (failed) why = std::to_string(failed) + " of " + std::to_string(parts) + " regions at " + std::to_string(rings) +
                        " rings: " + why;
    }
    int folded = 0;
    for (int f = 0; f < source.num_faces(); ++f) folded += !sheets.positive(f);
    if (tries > 0 && folded == 0) {
      if (accept(z, hr.vertex_deck_word, changed, "joint untangling of the fold clusters",
                 used_rings, options.cluster_max_mean_rise)) {
        info.tries = tries;
        return out;
      }
    } else if (tries > 0) {
      last += "; joint embedding: " + std::to_string(folded) + " faces left folded (" + why + ")";
    }
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
    std::vector<int> moved;
    if (!project_folds(source, sc, index, r, r.z, held, z, moved, options.projection_rounds)) {
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
