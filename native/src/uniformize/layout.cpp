// Isometric disk layout and deck transformations (layout.h; docs/method.md §2.5).
#include "surfmap/uniformize/layout.h"

#include <algorithm>
#include <limits>
#include <array>
#include <chrono>
#include <cmath>
#include <future>
#include <queue>
#include <string>
#include <type_traits>

#include "../seconds_since.h"
#include "surfmap/error.h"

namespace surfmap {
namespace {

using hyperbolic::Mobius;

/// z ↦ r z + t with |r| = 1: orientation-preserving isometry of the plane.
struct Rigid {
  Complex r{1.0, 0.0}, t{0.0, 0.0};
  Complex apply(Complex z) const { return r * z + t; }
  Rigid operator*(const Rigid& o) const { return {r * o.r, r * o.t + t}; }
  Rigid inverse() const { return {std::conj(r), -std::conj(r) * t}; }
  Rigid normalized() const { return {r / std::abs(r), t}; }
};

// The two geometries share the layout code; each supplies its charts.
struct Flat {
  using Chart = Rigid;
  /// Coordinate on the positive real axis of the point at distance l from 0.
  static double coord(double l) { return l; }
  static double angle(double a, double b, double c) { return hyperbolic::euclidean_angle(a, b, c); }
  static double distance(Complex z, Complex w) { return std::abs(z - w); }
  /// Round-off bound (in the metric) of chart.apply(z) in double precision.
  static double apply_roundoff(const Chart& m, Complex z) {
    return std::numeric_limits<double>::epsilon() * (std::abs(z) + std::abs(m.t) + std::abs(m.apply(z)));
  }
  /// Twice the signed area of the triangle a, b, d (positive: counter-clockwise).
  static double orientation(Complex a, Complex b, Complex d) { return std::imag(std::conj(b - a) * (d - a)); }
  /// The chart taking 0 to p and the positive real axis towards q.
  static Chart frame(Complex p, Complex q) {
    const Complex d = q - p;
    return {d / std::abs(d), p};
  }
  /// Half-turn about the midpoint of the standard segment [0, l]: swaps its ends.
  static Chart flip(double l) { return {Complex(-1.0, 0.0), Complex(l, 0.0)}; }
  static double area(double a, double b, double c) {
    // Heron in the stable (Kahan) ordering.
    double x[3] = {a, b, c};
    std::sort(x, x + 3);
    const double C = x[0], B = x[1], A = x[2];
    const double p = (A + (B + C)) * (C - (A - B)) * (C + (A - B)) * (A + (B - C));
    return 0.25 * std::sqrt(std::max(0.0, p));
  }
};

struct Hyper {
  using Chart = Mobius;
  static double coord(double l) { return std::tanh(l / 2); }
  static double angle(double a, double b, double c) { return hyperbolic::law_of_cosines_angle(a, b, c); }
  static double distance(Complex z, Complex w) { return hyperbolic::distance(z, w); }
  /// Klein model: geodesics are straight chords, so the sign of the cross
  /// product is the orientation of the geodesic triangle (in the Poincaré
  /// model three nearly collinear points lie on a circular arc instead).
  static Complex straight(Complex z) { return hyperbolic::poincare_to_klein(z); }
  /// Round-off bound (in the metric) of m.apply(z) = (a z + b) / (b̄ z + ā)
  /// in double precision, entries rounded too: first-order error of the
  /// quotient, ε (|a||z| + |b| + |w| (|b||z| + |a|)) / |b̄ z + ā|, times the
  /// metric's scale 2 / (1 − |w|²) at the image w. A side pairing of a long
  /// fundamental domain (|a| ~ 1e5) applied to a point at 1 − |z| ~ 1e-7
  /// gives 1e-4: the gaps of the genus-11 wheel's deck maps were exactly this.
  static double apply_roundoff(const Chart& m, Complex z) {
    const Complex w = m.apply(z);
    const double az = std::abs(m.a) * std::abs(z), bz = std::abs(m.b) * std::abs(z);
    const double den = std::abs(std::conj(m.b) * z + std::conj(m.a));
    const double dw = std::numeric_limits<double>::epsilon() * (az + std::abs(m.b) + std::abs(w) * (bz + std::abs(m.a))) / den;
    return 2.0 * dw / std::max(1e-300, hyperbolic::conformal_denominator(w));
  }
  /// Sign of the geodesic triangle a, b, d (positive: counter-clockwise),
  /// tested in the Klein model of the chart centring a. In the layout's own
  /// Klein coordinates a triangle near |z| = 1 is squeezed radially by
  /// 1 − |k|² (1e-12 at |z| = 1 − 2e-6), so their round-off alone turned a
  /// sliver of the genus-11 CAD block (height 2.6e-5 in the metric, corner
  /// round-off 1e-10) over; centred, the corners keep their digits.
  static double orientation(Complex a, Complex b, Complex d) {
    const Complex kb = straight(hyperbolic::centred(a, b)), kd = straight(hyperbolic::centred(a, d));
    return std::imag(std::conj(kb) * kd);
  }
  static Chart frame(Complex p, Complex q) {
    const Mobius tp = Mobius::centring(p);
    return tp.inverse() * Mobius::rotation(std::arg(tp.apply(q)));
  }
  static Chart flip(double l) {
    // z ↦ −z, then the translation taking 0 to tanh(l/2).
    return Mobius::translation_to(Complex(std::tanh(l / 2), 0.0)) * Mobius{Complex(0.0, 1.0), Complex(0.0)};
  }
  static double area(double a, double b, double c) { return hyperbolic::triangle_area(a, b, c); }
};

using detail::seconds_since;

/// Breadth-first distances on the cut tree (adjacency lists); returns the
/// farthest face and fills parent.
int tree_bfs(const std::vector<std::vector<int>>& adj, int start, std::vector<int>& parent,
             std::vector<int>& order) {
  const int n = static_cast<int>(adj.size());
  parent.assign(n, -2);
  order.clear();
  std::queue<int> q;
  q.push(start);
  parent[start] = -1;
  int last = start;
  while (!q.empty()) {
    const int f = q.front();
    q.pop();
    order.push_back(f);
    last = f;
    for (int g : adj[f])
      if (parent[g] == -2) {
        parent[g] = f;
        q.push(g);
      }
  }
  return last;
}

/// Canonical triangle of every face: corner 0 at 0, corner 1 on the positive
/// real axis, corner 2 above it (counter-clockwise). InputError on a face
/// whose lengths are not a triangle.
template <class G>
std::vector<std::array<Complex, 3>> canonical_triangles(const Connectivity& conn, const Eigen::VectorXd& L) {
  const int nF = conn.num_faces();
  std::vector<std::array<Complex, 3>> canon(nF);
  for (int f = 0; f < nF; ++f) {
    const double l0 = L[conn.edge(3 * f)], l1 = L[conn.edge(3 * f + 1)], l2 = L[conn.edge(3 * f + 2)];
    if (!(l0 > 0 && l1 > 0 && l2 > 0) || !std::isfinite(l0 + l1 + l2))
      throw InputError("layout: face " + std::to_string(f) + " has a non-positive or non-finite edge length");
    if (l0 > l1 + l2 || l1 > l2 + l0 || l2 > l0 + l1)
      throw InputError("layout: face " + std::to_string(f) + " violates the triangle inequality (lengths " +
                       std::to_string(l0) + ", " + std::to_string(l1) + ", " + std::to_string(l2) + ")");
    const double alpha0 = G::angle(l0, l2, l1);
    canon[f] = {Complex(0.0), Complex(G::coord(l0), 0.0), std::polar(G::coord(l2), alpha0)};
  }
  return canon;
}

/// The gluing of neighbouring canonical triangles.
template <class G>
struct Gluing {
  using Chart = typename G::Chart;
  const Connectivity& conn;
  const Eigen::VectorXd& L;
  const std::vector<std::array<Complex, 3>>& canon;
  /// Frame of halfedge h inside its face's canonical triangle.
  Chart frame(int h) const {
    const int f = h / 3, k = h % 3;
    if (k == 0) return Chart{};
    return G::frame(canon[f][k], canon[f][(k + 1) % 3]);
  }
  /// Transition across halfedge h: maps the canonical coordinates of
  /// face(twin(h)) to those of face(h), gluing the two copies of the edge.
  Chart transition(int h) const {
    const int t = conn.twin(h);
    return (frame(h) * G::flip(L[conn.edge(h)]) * frame(t).inverse()).normalized();
  }
};

/// Loop membership of every edge (-1 off the loops) with the halfedge
/// running along the loop; the cut edges are exactly the loop edges.
struct LoopEdges {
  std::vector<int> loop, forward;
};

/// The loop edges of `loops` (SolveError when they are not 2g closed loops
/// through the base vertex on distinct edges), and out.cut_edge; checks that
/// the cut tree T* never crosses a loop (a wrong system of loops would
/// otherwise be laid out silently wrong).
LoopEdges loop_edges(const Connectivity& conn, const SystemOfLoops& loops, DiskLayout& out) {
  const int nF = conn.num_faces(), nE = conn.num_edges(), nV = conn.num_vertices();
  const int genus = conn.genus();
  const int nloops = static_cast<int>(loops.loops.size());
  if (nloops != 2 * genus)
    throw SolveError("layout: " + std::to_string(nloops) + " loops for genus " + std::to_string(genus));
  LoopEdges le;
  le.loop.assign(nE, -1), le.forward.assign(nE, -1);
  for (int k = 0; k < nloops; ++k) {
    const auto& path = loops.loops[k];
    if (path.size() < 2 || path.front() != loops.base_vertex || path.back() != loops.base_vertex)
      throw SolveError("layout: loop " + std::to_string(k) + " does not start and end at the base vertex");
    for (size_t i = 0; i + 1 < path.size(); ++i) {
      if (path[i] < 0 || path[i] >= nV || path[i + 1] < 0 || path[i + 1] >= nV)
        throw InputError("layout: loop " + std::to_string(k) + " has a vertex index out of range");
      const int h = conn.find_halfedge(path[i], path[i + 1]);
      if (h < 0)
        throw SolveError("layout: loop " + std::to_string(k) + " steps between non-adjacent vertices " +
                         std::to_string(path[i]) + " and " + std::to_string(path[i + 1]));
      const int e = conn.edge(h);
      if (le.loop[e] >= 0)
        throw SolveError("layout: edge " + std::to_string(e) + " lies on loops " + std::to_string(le.loop[e]) +
                         " and " + std::to_string(k));
      le.loop[e] = k;
      le.forward[e] = h;
    }
  }
  out.cut_edge.assign(nE, false);
  for (int e = 0; e < nE; ++e) out.cut_edge[e] = le.loop[e] >= 0;
  if (static_cast<int>(loops.dual_tree_parent_halfedge.size()) != nF)
    throw InputError("layout: dual_tree_parent_halfedge has " +
                     std::to_string(loops.dual_tree_parent_halfedge.size()) + " entries for " +
                     std::to_string(nF) + " faces");
  for (int f = 0; f < nF; ++f) {
    const int h = loops.dual_tree_parent_halfedge[f];
    if (h < 0) continue;
    if (h >= 3 * nF || Connectivity::face(h) != f)
      throw InputError("layout: dual tree parent halfedge of face " + std::to_string(f) + " is not in that face");
    if (out.cut_edge[conn.edge(h)])
      throw SolveError("layout: the cut tree crosses loop " + std::to_string(le.loop[conn.edge(h)]) + " at edge " +
                       std::to_string(conn.edge(h)));
  }
  return le;
}

/// Faces of the disk adjacent across every uncut edge (with the halfedge
/// crossed). The layout walks this graph breadth-first (a spanning tree of
/// it, like T*, but of the least depth from the root, so that the fewest
/// chart products pile up).
struct DiskAdjacency {
  std::vector<std::vector<int>> face, halfedge;
};

DiskAdjacency disk_adjacency(const Connectivity& conn, const std::vector<bool>& cut_edge) {
  const int nF = conn.num_faces();
  DiskAdjacency adj;
  adj.face.resize(nF), adj.halfedge.resize(nF);
  for (int h = 0; h < 3 * nF; ++h) {
    if (cut_edge[conn.edge(h)]) continue;
    adj.face[Connectivity::face(h)].push_back(Connectivity::face(conn.twin(h)));
    adj.halfedge[Connectivity::face(h)].push_back(h);
  }
  return adj;
}

/// The root face: `requested` when >= 0, else the tree centre (middle of a
/// longest path, two sweeps). SolveError when the loops disconnect the disk.
int root_face(const DiskAdjacency& adj, int requested) {
  const int nF = static_cast<int>(adj.face.size());
  std::vector<int> parent, order;
  int root = requested;
  const int a = tree_bfs(adj.face, 0, parent, order);
  if (static_cast<int>(order.size()) != nF)
    throw SolveError("layout: the cut tree reaches " + std::to_string(order.size()) + " of " + std::to_string(nF) +
                     " faces; the loops disconnect the surface");
  const int b = tree_bfs(adj.face, a, parent, order);
  std::vector<int> path;
  for (int f = b; f != -1; f = parent[f]) path.push_back(f);
  if (root < 0) root = path[path.size() / 2];
  if (root >= nF) throw InputError("layout: root face " + std::to_string(root) + " out of range");
  return root;
}

/// Charts of every face in breadth-first order from the root (`bfs`: that
/// order); products[f] counts the rounded chart products behind chart[f]
/// (its depth in the breadth-first tree): each rounds the entries by about
/// ε relative, so the chart's entries carry products[f] × ε (first order).
template <class G>
std::vector<typename G::Chart> face_charts(const Gluing<G>& glue, const DiskAdjacency& adj, int root,
                                           std::vector<int>& bfs, std::vector<int>& products) {
  const int nF = static_cast<int>(adj.face.size());
  std::vector<typename G::Chart> chart(nF);
  products.assign(nF, 0);
  std::vector<char> done(nF, 0);
  bfs.clear();
  bfs.reserve(nF);
  std::queue<int> q;
  q.push(root);
  done[root] = 1;
  while (!q.empty()) {
    const int f = q.front();
    q.pop();
    bfs.push_back(f);
    for (size_t i = 0; i < adj.face[f].size(); ++i) {
      const int g = adj.face[f][i];
      if (done[g]) continue;
      done[g] = 1;
      chart[g] = (chart[f] * glue.transition(adj.halfedge[f][i])).normalized();
      products[g] = products[f] + 1;
      q.push(g);
    }
  }
  return chart;
}

/// Round-off (in the metric) of every corner as its chart places it: the
/// chart's evaluation bound G::apply_roundoff times (products[f] + 1), the
/// rounded products behind the chart plus the evaluation itself. Gluing
/// checks compare each gap with the bounds of the corners involved.
template <class G>
std::vector<std::array<double, 3>> corner_roundoffs(const std::vector<typename G::Chart>& chart,
                                                    const std::vector<std::array<Complex, 3>>& canon,
                                                    const std::vector<int>& products) {
  std::vector<std::array<double, 3>> r(chart.size());
  for (size_t f = 0; f < chart.size(); ++f)
    for (int k = 0; k < 3; ++k) r[f][k] = (products[f] + 1) * G::apply_roundoff(chart[f], canon[f][k]);
  return r;
}

/// out.corners from the charts and canonical triangles.
template <class Chart>
void compute_corners(const std::vector<Chart>& chart, const std::vector<std::array<Complex, 3>>& canon,
                     DiskLayout& out) {
  const int nF = static_cast<int>(chart.size());
  out.corners.resize(nF, 3);
  for (int f = 0; f < nF; ++f)
    for (int k = 0; k < 3; ++k) out.corners(f, k) = chart[f].apply(canon[f][k]);
}

/// The Karcher objective ½Σ d(c, z)² (times 2) over the corners, with its
/// gradient Σ log_c(z) and exact Hessian (docs/method.md §7: 1 along each
/// geodesic, d coth d across it), from one pass of logarithms: d(c, z) is
/// |log_c(z)|, so the line search's objective needs no pass of its own
/// (issue 19: the recentring was a third of a 50k layout). Per corner one
/// Möbius map, one square root and one artanh: with t = T_c(z), d = 2 artanh|t|
/// and coth d = (1 + |t|²) / (2|t|), so d coth d = artanh|t| (1 + |t|²) / |t|
/// needs no tanh, and |t| ≤ 1 needs no overflow-safe hypot.
struct KarcherTerms {
  double objective = 0;
  Complex g{0.0};
  double hxx = 0, hxy = 0, hyy = 0;
};
KarcherTerms karcher_terms(const DiskLayout& out, Complex c) {
  const int nF = static_cast<int>(out.corners.rows());
  const Mobius centring = Mobius::centring(c);
  const Complex a = centring.a, b = centring.b;
  KarcherTerms r;
  double gx = 0, gy = 0;
  for (int f = 0; f < nF; ++f)
    for (int k = 0; k < 3; ++k) {
      // t = T_c(z) = (a z + b) / (b̄ z + ā), by one reciprocal of |b̄ z + ā|².
      const Complex z = out.corners(f, k);
      const Complex num = a * z + b, den = std::conj(b) * z + std::conj(a);
      const double inv = 1.0 / std::norm(den);
      const double tx = (num.real() * den.real() + num.imag() * den.imag()) * inv;
      const double ty = (num.imag() * den.real() - num.real() * den.imag()) * inv;
      const double tn2 = tx * tx + ty * ty;
      if (tn2 == 0.0) {  // the corner is the centre: no gradient, Hessian I
        r.hxx += 1, r.hyy += 1;
        continue;
      }
      const double tn = std::sqrt(tn2);
      const double half_d = std::atanh(tn);
      const double d = 2.0 * half_d;
      const double ux = tx / tn, uy = ty / tn;
      gx += d * ux, gy += d * uy;
      r.objective += d * d;
      const double normal = half_d * (1.0 + tn2) / tn;  // d coth d
      // H = u uᵀ + normal (I − u uᵀ)
      r.hxx += normal + (1 - normal) * ux * ux;
      r.hxy += (1 - normal) * ux * uy;
      r.hyy += normal + (1 - normal) * uy * uy;
    }
  r.g = Complex(gx, gy);
  return r;
}

/// Karcher mean of the corner positions: minimise ½Σ d(c, z)² by Riemannian
/// Newton steps c ← exp_c(H⁻¹ Σ log_c(z)) from 0 (the root face's chart),
/// with backtracking on the objective (it is geodesically convex). The
/// terms at an accepted trial point are the next step's. Near the mean the
/// Newton step's predicted decrease ½ gᵀH⁻¹g falls below the objective's
/// round-off (a sum of 3F terms), so the objective cannot confirm it: there a
/// step is accepted when it lowers the gradient instead (issue 19: on the
/// ranking's 1220-vertex copy the gradient stalled at 1.6e-3 above its
/// tolerance and the backtracking spent 34 of 38 evaluations confirming
/// steps of 1e-7). `evaluations` counts the passes over the corners. (A
/// start at the corners' centre of mass on the hyperboloid saved one of the
/// bench copy's 4 passes and none of the target's, and moved the centre of the raw genus-11 wheel's layout
/// enough to fold one triangle of its map: not kept.)
Complex karcher_mean_of_corners(const DiskLayout& out, int* evaluations) {
  const int nF = static_cast<int>(out.corners.rows());
  Complex c(0.0);
  KarcherTerms at = karcher_terms(out, c);
  int passes = 1;
  const double tolerance = 1e-10 * 3.0 * nF;  // far below any use of the centre
  for (int it = 0; it < 100; ++it) {
    const Complex g = at.g;
    if (std::abs(g) < tolerance) break;
    const double det = at.hxx * at.hyy - at.hxy * at.hxy;
    const Complex step((at.hyy * g.real() - at.hxy * g.imag()) / det, (at.hxx * g.imag() - at.hxy * g.real()) / det);
    // The sum's round-off: each of its 3F terms rounds to a relative ε.
    const double objective_roundoff = 3.0 * nF * std::numeric_limits<double>::epsilon() * at.objective;
    const bool below_roundoff = 0.5 * (g.real() * step.real() + g.imag() * step.imag()) <= objective_roundoff;
    bool moved = false;
    for (double t = 1.0; t > 1e-6; t *= 0.5) {
      const Complex cn = hyperbolic::exp_map(c, t * step);
      KarcherTerms trial = karcher_terms(out, cn);
      ++passes;
      if (trial.objective < at.objective || (below_roundoff && std::abs(trial.g) < std::abs(g))) {
        c = cn, at = trial, moved = true;
        break;
      }
      if (below_roundoff) break;  // shorter steps cannot be confirmed either
    }
    if (!moved) break;
  }
  if (evaluations) *evaluations = passes;
  return c;
}

/// The isometry T (T(0) = c) whose centre c approximately minimises the
/// largest distance to a corner (the domain's 1-centre), by shrinking
/// steps: move c towards the farthest corner by 1/(i + 2) of its distance
/// (the farthest corner's distance converges to the least radius; the
/// method needs only a geodesically convex distance, which the disk's is).
/// Every distance and direction is read off the matrix T⁻¹ ∘ chart[f] ∘
/// T_{−p} (2 asinh|b|, the direction of b/ā), never off the corners'
/// coordinates, which round to |z| = 1 beyond about 37 from 0 (issue 13:
/// the long CAD plates, whose Karcher mean sits far from the middle of the
/// domain).
Mobius minimax_centre(const std::vector<Mobius>& chart, const std::vector<std::array<Complex, 3>>& canon,
                      int iterations) {
  const int nF = static_cast<int>(chart.size());
  std::vector<Mobius> corner(3 * nF);  // chart[f] ∘ T_{−p}: takes 0 to the corner
  for (int f = 0; f < nF; ++f)
    for (int k = 0; k < 3; ++k) corner[3 * f + k] = chart[f] * Mobius::translation_to(canon[f][k]);
  Mobius T;
  for (int it = 0; it < iterations; ++it) {
    const Mobius Ti = T.inverse();
    double far = -1;
    Complex towards(0.0);
    for (const Mobius& c : corner) {
      const Mobius m = Ti * c;
      const double d = m.displacement_of_origin();
      if (d > far) far = d, towards = m.b / std::conj(m.a);
    }
    if (far <= 0 || std::abs(towards) == 0.0) break;
    T = (T * Mobius::translation(far / (it + 2) * towards / std::abs(towards))).normalized();
  }
  return T;
}

/// Re-centres the charts (hyperbolic: on the Karcher mean of the corners,
/// then when `minimax` on the domain's 1-centre (minimax_centre); flat: on
/// their area-weighted centroid) and recomputes the corners.
template <class G>
void recentre(std::vector<typename G::Chart>& chart, const std::vector<std::array<Complex, 3>>& canon,
              DiskLayout& out, bool minimax) {
  const int nF = static_cast<int>(chart.size());
  if constexpr (std::is_same_v<G, Hyper>) {
    const Mobius tc = Mobius::centring(karcher_mean_of_corners(out, &out.centre_evaluations));
    for (int f = 0; f < nF; ++f) chart[f] = (tc * chart[f]).normalized();
    if (minimax) {
      const Mobius ti = minimax_centre(chart, canon, 400).inverse();
      for (int f = 0; f < nF; ++f) chart[f] = (ti * chart[f]).normalized();
    }
  } else {
    Complex c(0.0);
    double total = 0;
    for (int f = 0; f < nF; ++f) {
      const Complex a = out.corners(f, 0), b = out.corners(f, 1), d = out.corners(f, 2);
      const double w = 0.5 * std::imag(std::conj(b - a) * (d - a));
      c += w * (a + b + d) / 3.0;
      total += w;
    }
    c /= total;
    for (int f = 0; f < nF; ++f) chart[f].t -= c;
  }
  compute_corners(chart, canon, out);
}

/// Round-off of the coordinates in the metric: ε times the metric's scale
/// factor at a corner (hyperbolic 2/(1−|z|²), which reaches 10¹² on long
/// fundamental domains; flat |z|). Gluing checks are judged against its
/// maximum (uniformize.cpp); a triangle whose sides are all below 100 times
/// the round-off at its corners cannot be resolved by the coordinates at
/// all (flat metrics of long thin limbs shrink triangles to 1e-13 at
/// |z| = 5000): it is counted as unresolved, not as flipped. Fills
/// out.coordinate_roundoff, num_flipped, num_unresolved and area.
template <class G>
void count_flipped_faces(const Connectivity& conn, const Eigen::VectorXd& L,
                         const std::vector<std::array<double, 3>>& reach, DiskLayout& out) {
  const int nF = conn.num_faces();
  // The scale factor from the corner's distance d to 0 read off its chart
  // (hyperbolic 2/(1 − |z|²) = 1 + cosh d), not from the coordinates: where
  // |z| rounds to 1 (the CAD plates of genus 13+, d up to 70) the
  // coordinates' own 1 − |z|² is 0 or negative, and the round-off with it.
  auto roundoff_at = [&](int f, int k) {
    const double factor = std::is_same_v<G, Hyper> ? 1.0 + std::cosh(reach[f][k]) : reach[f][k];
    return std::numeric_limits<double>::epsilon() * std::max(factor, 1.0);
  };
  out.coordinate_roundoff = 0;
  out.num_flipped = 0;
  out.num_flipped_above_roundoff = 0;
  out.num_unresolved = 0;
  out.area = 0;
  for (int f = 0; f < nF; ++f) {
    double rho = 0;
    for (int k = 0; k < 3; ++k) rho = std::max(rho, roundoff_at(f, k));
    out.coordinate_roundoff = std::max(out.coordinate_roundoff, rho);
    const double lmax = std::max({L[conn.edge(3 * f)], L[conn.edge(3 * f + 1)], L[conn.edge(3 * f + 2)]});
    const double area = G::area(L[conn.edge(3 * f)], L[conn.edge(3 * f + 1)], L[conn.edge(3 * f + 2)]);
    if (lmax < 100 * rho) {
      ++out.num_unresolved;
    } else if (!(G::orientation(out.corners(f, 0), out.corners(f, 1), out.corners(f, 2)) > 0)) {
      ++out.num_flipped;
      // A sliver whose height is below 100 times the round-off of its
      // corners can turn over by rounding alone; a taller one cannot.
      if (2 * area / lmax >= 100 * rho) ++out.num_flipped_above_roundoff;
    }
    out.area += area;
  }
}

/// Distance of every corner from 0 in the metric, read off its chart rather
/// than its coordinates (hyperbolic: the displacement of 0 by chart[f] ∘
/// T_{−p} for the canonical corner p, 2 asinh|b|, exact however close the
/// corner is to |z| = 1; flat: |z|). out.layout_radius is the largest.
template <class G>
std::vector<std::array<double, 3>> corner_reach(const std::vector<typename G::Chart>& chart,
                                                const std::vector<std::array<Complex, 3>>& canon, DiskLayout& out) {
  std::vector<std::array<double, 3>> reach(chart.size());
  out.layout_radius = 0;
  for (size_t f = 0; f < chart.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      if constexpr (std::is_same_v<G, Hyper>)
        reach[f][k] = (chart[f] * Mobius::translation_to(canon[f][k])).displacement_of_origin();
      else
        reach[f][k] = std::abs(chart[f].apply(canon[f][k]));
      out.layout_radius = std::max(out.layout_radius, reach[f][k]);
    }
  return reach;
}

/// Distance of a chart from the identity (up to the sign of an SU(1,1)
/// matrix); flat: max(|r − 1|, |t| / scale).
double chart_defect(const Mobius& m, double) { return hyperbolic::distance_from_identity(m); }
double chart_defect(const Rigid& m, double scale) { return std::max(std::abs(m.r - 1.0), std::abs(m.t) / scale); }

/// The layout's checks in per-face charts (DiskLayout::max_vertex_holonomy,
/// num_flipped_local): nothing here uses a position in the layout's frame,
/// only the canonical triangles and the transitions between neighbours,
/// whose entries are of the size of a triangle wherever the face lies.
///  * Holonomy: around every vertex of the closed surface (cut or not), the
///    product of the transitions across the edges of its star, from one face
///    back to it, must be the identity: it is the rotation about the vertex
///    by its angle defect. On the disk this is what makes the two copies of
///    an interior edge's endpoint coincide (the disk is simply connected,
///    and its cycles are generated by vertex stars), the deck maps of two
///    consecutive edges of a loop agree (the star of their common vertex
///    crosses the loop twice) and the 4g corners close up (the star of the
///    base vertex): exactly the single chart's gluing checks, without
///    products along breadth-first paths of hundreds of faces.
///  * Orientation: every face carried into each neighbour's chart by their
///    transition must be counter-clockwise there, with its far corner on the
///    other side of the common edge from the neighbour's far corner (no fold).
struct LocalChecks {
  double max_vertex_holonomy = 0;
  int num_flipped_local = 0;
};
template <class G>
LocalChecks local_checks(const Gluing<G>& glue) {
  using Chart = typename G::Chart;
  const Connectivity& conn = glue.conn;
  const int nF = conn.num_faces(), nV = conn.num_vertices();
  const auto& canon = glue.canon;
  std::vector<Chart> transition(3 * nF);
  for (int h = 0; h < 3 * nF; ++h) transition[h] = glue.transition(h);
  LocalChecks out;
  for (int v = 0; v < nV; ++v) {
    // From face(h) to the next face around v: across prev(h), whose twin is
    // the next outgoing halfedge; transition(prev(h)) maps that face's
    // canonical coordinates into face(h)'s.
    const int h0 = conn.vertex_halfedge(v);
    if (h0 < 0) continue;
    Chart product{};
    double scale = 0;
    int h = h0, steps = 0;
    do {
      const int p = Connectivity::prev(h);
      product = (product * transition[p]).normalized();
      scale = std::max(scale, glue.L[conn.edge(p)]);
      h = conn.twin(p);
      if (++steps > 3 * nF) throw SolveError("layout: the star of vertex " + std::to_string(v) + " does not close");
    } while (h != h0);
    out.max_vertex_holonomy = std::max(out.max_vertex_holonomy, chart_defect(product, scale));
  }
  std::vector<char> flipped(nF, 0);
  for (int h = 0; h < 3 * nF; ++h) {
    const int f = Connectivity::face(h), t = conn.twin(h), g = Connectivity::face(t);
    const Chart& T = transition[h];  // g's canonical coordinates -> f's
    const int k = h % 3;
    const Complex a = canon[f][k], b = canon[f][(k + 1) % 3], c = canon[f][(k + 2) % 3];
    const Complex p = T.apply(canon[g][0]), q = T.apply(canon[g][1]), r = T.apply(canon[g][2]);
    const Complex far = T.apply(canon[g][(t % 3 + 2) % 3]);
    if (!(G::orientation(p, q, r) > 0) || !(G::orientation(a, b, c) > 0) || !(G::orientation(b, a, far) > 0))
      flipped[g] = 1;
  }
  for (char x : flipped) out.num_flipped_local += x;
  return out;
}

/// A gluing gap up to this many times its own evaluation round-off
/// (G::apply_roundoff, times the chart's product count for face charts) is
/// rounding, not a gluing error.
constexpr double kRoundoffFactor = 10.0;

/// Deck map of every cut edge (identity elsewhere): the copy of face g glued
/// to face f along e is chart[f] ∘ E, and the deck map carries it onto the
/// laid-out copy chart[g]. Interior edges: the two copies of each endpoint
/// must coincide (out.max_interior_mismatch), up to the round-off of the
/// two charts that place them: (products + 1) × apply_roundoff of each
/// (issue 13: the genus-11 CAD plate's gaps of 0.02 at 1 − |z| = 1.5e-11
/// are 1.5 times that bound, and do not change when the curvature residual
/// drops from 5e-5 to 1e-13, so they are rounding; out.max_interior_excess
/// is the gap beyond kRoundoffFactor times it). Also fills the flat or
/// hyperbolic edge deck fields and the flat holonomy check.
template <class G>
std::vector<typename G::Chart> edge_decks(const Gluing<G>& glue, const std::vector<typename G::Chart>& chart,
                                          const std::vector<std::array<double, 3>>& rounding, DiskLayout& out) {
  using Chart = typename G::Chart;
  const Connectivity& conn = glue.conn;
  const RowMatrixX3i& F = conn.faces();
  const int nE = conn.num_edges();
  auto corner_of = [&](int f, int v) {
    for (int k = 0; k < 3; ++k)
      if (F(f, k) == v) return out.corners(f, k);
    return Complex(NAN, NAN);
  };
  auto corner_roundoff = [&](int f, int v) {
    for (int k = 0; k < 3; ++k)
      if (F(f, k) == v) return rounding[f][k];
    return 0.0;
  };
  std::vector<Chart> deck(nE);
  out.max_interior_mismatch = 0;
  out.interior_roundoff = 0;
  out.max_interior_excess = 0;
  for (int e = 0; e < nE; ++e) {
    const int h = conn.edge_halfedge(e), t = conn.twin(h);
    const int f = Connectivity::face(h), g = Connectivity::face(t);
    if (!out.cut_edge[e]) {
      for (int v : {conn.tail(h), conn.head(h)}) {
        const double d = G::distance(corner_of(f, v), corner_of(g, v));
        const double r = corner_roundoff(f, v) + corner_roundoff(g, v);
        out.max_interior_mismatch = std::max(out.max_interior_mismatch, d);
        out.interior_roundoff = std::max(out.interior_roundoff, r);
        out.max_interior_excess = std::max(out.max_interior_excess, d - kRoundoffFactor * r);
      }
      continue;
    }
    deck[e] = (chart[g] * (chart[f] * glue.transition(h)).inverse()).normalized();
  }
  out.max_holonomy_rotation = 0;
  if constexpr (std::is_same_v<G, Hyper>) {
    out.edge_deck_mobius = deck;
  } else {
    out.edge_deck_translation.assign(nE, Complex(0.0));
    for (int e = 0; e < nE; ++e) {
      out.edge_deck_translation[e] = deck[e].t;
      out.max_holonomy_rotation = std::max(out.max_holonomy_rotation, std::abs(deck[e].r - 1.0));
    }
  }
  return deck;
}

/// The sides of the cut disk: its boundary walked counter-clockwise (disk on
/// the left of each halfedge: after h, turn clockwise around head(h) inside
/// the disk until the next cut edge), split into maximal runs between copies
/// of the base vertex, each labelled with its loop letter; rotated so that
/// the word starts with +1 (loop 0 forward). Fills out.word, side_start and
/// boundary_halfedges; plus_side[k] / minus_side[k] are the sides of +k / −k.
struct DiskSides {
  std::vector<int> plus_side, minus_side;
};

DiskSides disk_sides(const Connectivity& conn, const SystemOfLoops& loops, const LoopEdges& le, DiskLayout& out) {
  const int nF = conn.num_faces(), nE = conn.num_edges(), nV = conn.num_vertices();
  const int genus = conn.genus();
  const int nloops = static_cast<int>(loops.loops.size());
  const int x = loops.base_vertex;
  if (x < 0 || x >= nV) throw InputError("layout: base vertex " + std::to_string(x) + " out of range");
  int num_cut = 0;
  for (int e = 0; e < nE; ++e) num_cut += out.cut_edge[e];
  int start = -1;
  for (int h : conn.outgoing(x))
    if (out.cut_edge[conn.edge(h)]) {
      start = h;
      break;
    }
  if (start < 0) throw SolveError("layout: no loop passes through the base vertex " + std::to_string(x));
  std::vector<int> boundary;
  for (int h = start;;) {
    boundary.push_back(h);
    if (static_cast<int>(boundary.size()) > 2 * num_cut) break;
    int c = Connectivity::next(h);
    for (int guard = 0; !out.cut_edge[conn.edge(c)]; ++guard) {
      c = Connectivity::next(conn.twin(c));
      if (guard > 3 * nF) throw SolveError("layout: boundary walk lost around vertex " + std::to_string(conn.head(h)));
    }
    h = c;
    if (h == start) break;
  }
  if (static_cast<int>(boundary.size()) != 2 * num_cut)
    throw SolveError("layout: the cut disk boundary has " + std::to_string(boundary.size()) + " halfedges, expected " +
                     std::to_string(2 * num_cut) + " (the cut is not a disk)");
  // Sides: maximal runs between copies of x.
  std::vector<int> starts;
  for (int i = 0; i < static_cast<int>(boundary.size()); ++i)
    if (conn.tail(boundary[i]) == x) starts.push_back(i);
  const int n = static_cast<int>(starts.size());
  if (n != 4 * genus)
    throw SolveError("layout: the disk boundary passes the base vertex " + std::to_string(n) + " times, expected " +
                     std::to_string(4 * genus));
  std::vector<int> letters(n);
  for (int s = 0; s < n; ++s) {
    const int b = starts[s], e_ = (s + 1 < n) ? starts[s + 1] : static_cast<int>(boundary.size());
    int letter = 0;
    for (int i = b; i < e_; ++i) {
      const int h = boundary[i], e = conn.edge(h);
      const int l = (le.forward[e] == h) ? le.loop[e] + 1 : -(le.loop[e] + 1);
      if (i == b) letter = l;
      if (l != letter)
        throw SolveError("layout: a side of the cut disk switches from loop letter " + std::to_string(letter) +
                         " to " + std::to_string(l) + " at edge " + std::to_string(e) +
                         " (loops touch away from the base vertex)");
    }
    const int k = std::abs(letter) - 1;
    if (e_ - b != static_cast<int>(loops.loops[k].size()) - 1)
      throw SolveError("layout: a side of the cut disk covers " + std::to_string(e_ - b) + " of the " +
                       std::to_string(loops.loops[k].size() - 1) + " edges of loop " + std::to_string(k));
    letters[s] = letter;
  }
  // Rotate so that the word starts with +1 (loop 0 forward).
  int rot = 0;
  for (int s = 0; s < n; ++s)
    if (letters[s] == 1) rot = s;
  out.word.resize(n);
  out.side_start.resize(n);
  out.boundary_halfedges.resize(boundary.size());
  const int off = starts[rot];
  for (size_t i = 0; i < boundary.size(); ++i) out.boundary_halfedges[i] = boundary[(i + off) % boundary.size()];
  for (int s = 0; s < n; ++s) {
    out.word[s] = letters[(s + rot) % n];
    out.side_start[s] =
        (starts[(s + rot) % n] - off + static_cast<int>(boundary.size())) % static_cast<int>(boundary.size());
  }
  DiskSides sides;
  sides.plus_side.assign(nloops, -1), sides.minus_side.assign(nloops, -1);
  for (int s = 0; s < n; ++s) {
    const int k = std::abs(out.word[s]) - 1;
    int& slot = out.word[s] > 0 ? sides.plus_side[k] : sides.minus_side[k];
    if (slot >= 0) throw SolveError("layout: loop letter " + std::to_string(out.word[s]) + " occurs twice");
    slot = s;
  }
  return sides;
}

/// Side pairings D_k: deck maps of the loop's edges oriented along the loop,
/// read off the loop's longest edge: the refined loops fan out of the base
/// vertex through tiny edges, and a deck map read off a tiny edge has a
/// rotation error of (round-off / edge length), which the far end of a long
/// loop multiplies (1e-4 gaps on raw genus-8 meshes). Every loop edge's left
/// copy must land on its right copy under the one side pairing of its loop:
/// out.max_deck_inconsistency, measured as a distance between points (in the
/// metric), not between matrices: hyperbolic deck matrices of a long
/// fundamental domain have large entries whose rounding is no error.
/// A deck gap up to kRoundoffFactor times its evaluation round-off
/// (G::apply_roundoff) is rounding, not a gluing error.

template <class G>
std::vector<typename G::Chart> side_pairings(const Connectivity& conn, const Eigen::VectorXd& L,
                                             const std::vector<typename G::Chart>& deck, const LoopEdges& le,
                                             const DiskSides& sides, const std::vector<std::array<double, 3>>& rounding,
                                             DiskLayout& out) {
  using Chart = typename G::Chart;
  const int nE = conn.num_edges();
  const int nloops = static_cast<int>(sides.plus_side.size());
  const int n = static_cast<int>(out.word.size());
  auto oriented_deck = [&](int h) {
    const int e = conn.edge(h);
    return conn.edge_halfedge(e) == h ? deck[e] : deck[e].inverse();
  };
  // The two copies (corner in the left face, corner in the right face) of
  // both endpoints of every edge of each loop.
  struct CornerPair { int f, kf, g, kg; };
  std::vector<std::vector<CornerPair>> copies(nloops);
  for (int e = 0; e < nE; ++e) {
    if (le.loop[e] < 0) continue;
    const int hf = le.forward[e], t = conn.twin(hf);
    const int f = Connectivity::face(hf), g = Connectivity::face(t);
    copies[le.loop[e]].push_back({f, hf % 3, g, (t % 3 + 1) % 3});
    copies[le.loop[e]].push_back({f, (hf % 3 + 1) % 3, g, t % 3});
  }
  auto largest_gap = [&](const Chart& Dk, const std::vector<CornerPair>& pairs) {
    double gap = 0;
    for (const CornerPair& c : pairs)
      gap = std::max(gap, G::distance(Dk.apply(out.corners(c.f, c.kf)), out.corners(c.g, c.kg)));
    return gap;
  };
  std::vector<Chart> D(nloops);
  const int nb = static_cast<int>(out.boundary_halfedges.size());
  for (int k = 0; k < nloops; ++k) {
    const int s0 = out.side_start[sides.plus_side[k]];
    const int s1 = out.side_start[(sides.plus_side[k] + 1) % n];
    int best = out.boundary_halfedges[s0];
    for (int i = s0; i != s1; i = (i + 1) % nb) {
      const int h = out.boundary_halfedges[i];
      if (L[conn.edge(h)] > L[conn.edge(best)]) best = h;
    }
    // Hyperbolic: a pairing read off one edge is off by that edge's chart
    // round-off, which grows like cosh of the distance along the loop
    // (genus 11: 1e-9 at the edge, 3 at the loop's far end); the edge whose
    // pairing glues the whole loop best is used instead when it does better.
    // (Flat round-off grows only linearly along the loop: longest edge.)
    if constexpr (std::is_same_v<G, Hyper>) {
      double best_gap = largest_gap(oriented_deck(best), copies[k]);
      for (int i = s0; i != s1; i = (i + 1) % nb) {
        const int h = out.boundary_halfedges[i];
        const double gap = largest_gap(oriented_deck(h), copies[k]);
        if (gap < best_gap) best = h, best_gap = gap;
      }
    }
    D[k] = oriented_deck(best);
  }
  out.max_deck_inconsistency = 0;
  out.deck_roundoff = 0;
  out.max_deck_excess = 0;
  for (int e = 0; e < nE; ++e) {
    if (le.loop[e] < 0) continue;
    const int hf = le.forward[e], t = conn.twin(hf);
    const Chart& Dk = D[le.loop[e]];
    const int f = Connectivity::face(hf), g = Connectivity::face(t);
    const int kf[2] = {hf % 3, (hf % 3 + 1) % 3}, kg[2] = {(t % 3 + 1) % 3, t % 3};
    for (int i = 0; i < 2; ++i) {
      const Complex from = out.corners(f, kf[i]), to = out.corners(g, kg[i]);
      // Besides the evaluation, the two corners carry their own charts'
      // round-off (an isometry carries a point's error unchanged in the metric).
      const double r = G::apply_roundoff(Dk, from) + rounding[f][kf[i]] + rounding[g][kg[i]];
      const double d = G::distance(Dk.apply(from), to);
      out.max_deck_inconsistency = std::max(out.max_deck_inconsistency, d);
      out.deck_roundoff = std::max(out.deck_roundoff, r);
      out.max_deck_excess = std::max(out.max_deck_excess, d - kRoundoffFactor * r);
    }
  }
  return D;
}

/// Corner elements Ψ_m (c_m = Ψ_m(c_0)) through the vertex cycle:
/// D_k Ψ_i = Ψ_{j+1} and D_k Ψ_{i+1} = Ψ_j for sides i = +k, j = −k; from
/// them the vertex-cycle relator (out.side_relator), the generators as side
/// words and as charts, the corner check and the product relation's error.
template <class G>
void corner_elements(const std::vector<typename G::Chart>& D, const DiskSides& sides, DiskLayout& out) {
  using Chart = typename G::Chart;
  const int nloops = static_cast<int>(D.size());
  const int n = static_cast<int>(out.word.size());
  struct Rel { int from, to, k; };
  std::vector<Rel> rels;
  for (int k = 0; k < nloops; ++k) {
    const int i = sides.plus_side[k], j = sides.minus_side[k];
    rels.push_back({i, (j + 1) % n, k});
    rels.push_back({(i + 1) % n, j, k});
  }
  std::vector<Chart> psi(n);
  std::vector<Word> psi_word(n);  // Ψ_m as a side word (DiskLayout::side_relator)
  std::vector<char> known(n, 0);
  known[0] = 1;
  std::vector<char> used(rels.size(), 0);
  for (bool progress = true; progress;) {
    progress = false;
    for (size_t r = 0; r < rels.size(); ++r) {
      if (used[r]) continue;
      const Rel& rel = rels[r];
      if (known[rel.from] && !known[rel.to]) {
        psi[rel.to] = (D[rel.k] * psi[rel.from]).normalized();
        psi_word[rel.to] = concat(Word{rel.k + 1}, psi_word[rel.from]);
        known[rel.to] = 1;
      } else if (known[rel.to] && !known[rel.from]) {
        psi[rel.from] = (D[rel.k].inverse() * psi[rel.to]).normalized();
        psi_word[rel.from] = concat(Word{-(rel.k + 1)}, psi_word[rel.to]);
        known[rel.from] = 1;
      } else {
        continue;
      }
      used[r] = 1;
      progress = true;
    }
  }
  for (int m = 0; m < n; ++m)
    if (!known[m]) throw SolveError("layout: the corners of the cut disk do not form one vertex cycle");
  // The corner relations form one cycle through the 4g corners; the one not
  // used above closes it: D_k Ψ_from Ψ_to⁻¹ = id is the vertex-cycle relator.
  out.side_relator.clear();
  for (size_t r = 0; r < rels.size(); ++r)
    if (!used[r]) {
      const Rel& rel = rels[r];
      out.side_relator = cyclic_reduce(concat({Word{rel.k + 1}, psi_word[rel.from], inverse(psi_word[rel.to])}));
    }
  {
    std::vector<int> plus(nloops, 0), minus(nloops, 0);
    for (int x : out.side_relator) ++(x > 0 ? plus : minus)[std::abs(x) - 1];
    bool ok = static_cast<int>(out.side_relator.size()) == n;
    for (int k = 0; k < nloops; ++k) ok = ok && plus[k] == 1 && minus[k] == 1;
    if (!ok)
      throw SolveError("layout: the vertex cycle of the side pairings is not a one-vertex relation of length " +
                       std::to_string(n));
  }
  out.generator_side_words.assign(nloops, Word{});
  for (int k = 0; k < nloops; ++k) {
    const int i = sides.plus_side[k];
    out.generator_side_words[k] = dehn_reduce(concat(inverse(psi_word[i]), psi_word[(i + 1) % n]), out.side_relator);
  }
  const Complex c0 = out.corners(Connectivity::face(out.boundary_halfedges[0]), out.boundary_halfedges[0] % 3);
  // The corners through the products Ψ_m of up to 4g side pairings: each
  // factor's round-off is multiplied by the size of the partial products
  // ((|a| + |b|)² for SU(1,1) maps), so this check has its own condition.
  out.max_corner_inconsistency = 0;
  out.corner_condition = 1;
  for (int m = 0; m < n; ++m) {
    const int h = out.boundary_halfedges[out.side_start[m]];
    const Complex cm = out.corners(Connectivity::face(h), h % 3);
    out.max_corner_inconsistency = std::max(out.max_corner_inconsistency, G::distance(psi[m].apply(c0), cm));
    if constexpr (std::is_same_v<G, Hyper>) {
      const double size = std::abs(psi[m].a) + std::abs(psi[m].b);
      out.corner_condition = std::max(out.corner_condition, n * size * size);
    }
  }
  std::vector<Chart> gen(nloops);
  for (int k = 0; k < nloops; ++k) {
    const int i = sides.plus_side[k];
    gen[k] = (psi[i].inverse() * psi[(i + 1) % n]).normalized();
  }
  // The word relation, multiplied out in the chart centring the base corner
  // c_0: there each generator's entries are about cosh(loop length / 2),
  // while in the layout's own frame they grow with the distance of c_0 from
  // the centre and the product would drown in rounding.
  Chart to_base{};
  if constexpr (std::is_same_v<G, Hyper>) to_base = Mobius::centring(c0);
  Chart prod{};
  for (int s = 0; s < n; ++s) {
    const int k = std::abs(out.word[s]) - 1;
    const Chart gk = (to_base * gen[k] * to_base.inverse()).normalized();
    prod = prod * (out.word[s] > 0 ? gk : gk.inverse());
    if constexpr (std::is_same_v<G, Hyper>)
      out.relation_condition = std::max(out.relation_condition, std::norm(std::abs(prod.a) + std::abs(prod.b)));
  }
  if constexpr (std::is_same_v<G, Hyper>) {
    out.side_pairings = D;
    out.generators = gen;
    out.product_relation_error = hyperbolic::distance_from_identity(prod);
  } else {
    out.side_translations.resize(nloops);
    out.generator_translations.resize(nloops);
    double scale = 0;
    for (int k = 0; k < nloops; ++k) {
      out.side_translations[k] = D[k].t;
      out.generator_translations[k] = gen[k].t;
      scale = std::max(scale, std::abs(gen[k].t));
    }
    out.product_relation_error = std::max(std::abs(prod.r - 1.0), std::abs(prod.t) / scale);
  }
}

/// Copies of vertices on the disk: wedges around each vertex separated by
/// cut edges (out.disk_faces, disk_positions, disk_vertex_origin,
/// vertex_copies), and each vertex's position from the first face of the
/// breadth-first order that holds it (out.vertex_positions).
void vertex_copies(const Connectivity& conn, const std::vector<int>& bfs, DiskLayout& out) {
  const int nF = conn.num_faces(), nV = conn.num_vertices();
  const RowMatrixX3i& F = conn.faces();
  out.disk_faces.resize(nF, 3);
  out.disk_positions.clear();
  out.disk_vertex_origin.clear();
  out.vertex_copies.assign(nV, 0);
  for (int v = 0; v < nV; ++v) {
    const std::vector<int> hs = conn.outgoing(v);
    const int m = static_cast<int>(hs.size());
    int s = -1;
    for (int i = 0; i < m; ++i)
      if (out.cut_edge[conn.edge(Connectivity::prev(hs[i]))]) {
        s = i;
        break;
      }
    int id = -1;
    for (int t = 1; t <= m; ++t) {
      const int h = hs[((s < 0 ? 0 : s) + t) % m];
      if (id < 0) {
        id = static_cast<int>(out.disk_positions.size());
        out.disk_positions.push_back(out.corners(Connectivity::face(h), h % 3));
        out.disk_vertex_origin.push_back(v);
        ++out.vertex_copies[v];
      }
      out.disk_faces(Connectivity::face(h), h % 3) = id;
      if (out.cut_edge[conn.edge(Connectivity::prev(h))]) id = -1;
    }
  }
  out.vertex_positions.assign(nV, Complex(NAN, NAN));
  std::vector<char> placed(nV, 0);
  for (int f : bfs)
    for (int k = 0; k < 3; ++k)
      if (!placed[F(f, k)]) {
        placed[F(f, k)] = 1;
        out.vertex_positions[F(f, k)] = out.corners(f, k);
      }
}

/// The layout in its steps (docs/method.md §2.5): canonical triangles, the
/// cut along the loops, face charts breadth-first from the tree centre,
/// re-centring, checks, deck maps, the disk's sides, side pairings, corner
/// elements and relation, vertex copies.
template <class G>
void layout_impl(const Connectivity& conn, const Eigen::VectorXd& L, const SystemOfLoops& loops,
                 const LayoutOptions& options, DiskLayout& out) {
  out.genus = conn.genus();
  const std::vector<std::array<Complex, 3>> canon = canonical_triangles<G>(conn, L);
  const Gluing<G> glue{conn, L, canon};
  // The per-face checks read only the canonical triangles and their
  // gluing, none of the charts below: with a second thread they run next to
  // the charts and their re-centring (issue 19: a quarter of a 50k layout).
  // Declared after `glue`, so that an exception below waits for the task
  // before `glue` goes.
  std::future<LocalChecks> local;
  if (options.threads > 1) local = std::async(std::launch::async, [&glue] { return local_checks<G>(glue); });
  const LoopEdges le = loop_edges(conn, loops, out);
  const DiskAdjacency adj = disk_adjacency(conn, out.cut_edge);
  const int root = root_face(adj, options.root_face);
  out.root_face = root;

  std::vector<int> bfs, products;
  std::vector<typename G::Chart> chart = face_charts(glue, adj, root, bfs, products);
  compute_corners(chart, canon, out);
  if (options.recentre) {
    recentre<G>(chart, canon, out, options.minimax_centre);
    for (int& p : products) p += options.minimax_centre ? 2 : 1;
  }
  // The corners' reach and the flipped faces read the charts and corners
  // and write only their own fields of `out`: with a second thread they run
  // next to the round-off bounds and the edge decks (issue 19; the same
  // numbers either way). Declared after everything it reads.
  auto reach_and_flips = [&] {
    const std::vector<std::array<double, 3>> reach = corner_reach<G>(chart, canon, out);
    count_flipped_faces<G>(conn, L, reach, out);
  };
  std::future<void> flips;
  if (options.threads > 1) flips = std::async(std::launch::async, reach_and_flips);
  const std::vector<std::array<double, 3>> rounding = corner_roundoffs<G>(chart, canon, products);
  if constexpr (std::is_same_v<G, Hyper>) {
    out.face_charts = chart;
  } else {
    const int nF = conn.num_faces();
    out.face_rotation.resize(nF);
    out.face_translation.resize(nF);
    for (int f = 0; f < nF; ++f) {
      out.face_rotation[f] = chart[f].r;
      out.face_translation[f] = chart[f].t;
    }
  }
  if (!flips.valid()) reach_and_flips();
  const LocalChecks checks = local.valid() ? local.get() : local_checks<G>(glue);
  out.max_vertex_holonomy = checks.max_vertex_holonomy;
  out.num_flipped_local = checks.num_flipped_local;

  const std::vector<typename G::Chart> deck = edge_decks(glue, chart, rounding, out);
  if (flips.valid()) flips.get();
  const DiskSides sides = disk_sides(conn, loops, le, out);
  const std::vector<typename G::Chart> D = side_pairings<G>(conn, L, deck, le, sides, rounding, out);
  corner_elements<G>(D, sides, out);
  vertex_copies(conn, bfs, out);
}

}  // namespace

DiskLayout layout_disk(const Connectivity& conn, const Eigen::VectorXd& edge_lengths, Background background,
                       const SystemOfLoops& loops, const LayoutOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  if (edge_lengths.size() != conn.num_edges())
    throw InputError("layout: " + std::to_string(edge_lengths.size()) + " edge lengths for " +
                     std::to_string(conn.num_edges()) + " edges");
  if (loops.mesh.num_faces() != conn.num_faces())
    throw InputError("layout: the system of loops refers to a mesh with " + std::to_string(loops.mesh.num_faces()) +
                     " faces, the connectivity has " + std::to_string(conn.num_faces()));
  if (conn.genus() < 1) throw InputError("layout: genus 0 has no loops to cut along (use the spherical layout)");
  DiskLayout out;
  out.background = background;
  if (background == Background::Hyperbolic)
    layout_impl<Hyper>(conn, edge_lengths, loops, options, out);
  else
    layout_impl<Flat>(conn, edge_lengths, loops, options, out);
  out.time_s = seconds_since(t0);
  return out;
}

FaceAtlas hyperbolic_face_atlas(const Connectivity& conn, const Eigen::VectorXd& edge_lengths) {
  if (edge_lengths.size() != conn.num_edges())
    throw InputError("face atlas: " + std::to_string(edge_lengths.size()) + " edge lengths for " +
                     std::to_string(conn.num_edges()) + " edges");
  FaceAtlas atlas;
  atlas.corners = canonical_triangles<Hyper>(conn, edge_lengths);
  const Gluing<Hyper> glue{conn, edge_lengths, atlas.corners};
  const int nH = conn.num_halfedges();
  atlas.transition.resize(nH);
  atlas.twin.resize(nH);
  for (int h = 0; h < nH; ++h) atlas.transition[h] = glue.transition(h), atlas.twin[h] = conn.twin(h);
  return atlas;
}

Complex reduce_modulus(Complex tau, int* matrix) {
  if (!(std::imag(tau) > 0)) throw InputError("reduce_modulus: Im tau must be positive");
  long a = 1, b = 0, c = 0, d = 1;  // tau_current = (a tau0 + b) / (c tau0 + d)
  const Complex tau0 = tau;
  for (int it = 0; it < 1000; ++it) {
    const double n = std::round(std::real(tau));
    if (n != 0) {
      // τ − n: [[1, −n], [0, 1]] · M
      tau -= n;
      a -= static_cast<long>(n) * c;
      b -= static_cast<long>(n) * d;
    }
    if (std::norm(tau) < 1.0 - 1e-15) {
      // −1/τ: [[0, −1], [1, 0]] · M
      tau = -1.0 / tau;
      const long na = -c, nb = -d, nc = a, nd = b;
      a = na, b = nb, c = nc, d = nd;
    } else {
      break;
    }
  }
  // Recompute from the integer matrix to avoid drift.
  tau = (static_cast<double>(a) * tau0 + static_cast<double>(b)) / (static_cast<double>(c) * tau0 + static_cast<double>(d));
  if (matrix) {
    matrix[0] = static_cast<int>(a), matrix[1] = static_cast<int>(b);
    matrix[2] = static_cast<int>(c), matrix[3] = static_cast<int>(d);
  }
  return tau;
}

TorusModulus torus_modulus(Complex omega1, Complex omega2) {
  TorusModulus m;
  m.omega1 = omega1;
  m.omega2 = omega2;
  if (std::abs(omega1) == 0 || std::abs(omega2) == 0) throw SolveError("torus_modulus: zero lattice vector");
  m.tau = omega2 / omega1;
  if (std::imag(m.tau) < 0) {
    m.tau = -m.tau;
    m.omega2 = -omega2;
    m.omega2_negated = true;
  }
  if (!(std::imag(m.tau) > 0)) throw SolveError("torus_modulus: the lattice vectors are parallel");
  m.tau_reduced = reduce_modulus(m.tau, m.sl2z);
  return m;
}

}  // namespace surfmap
