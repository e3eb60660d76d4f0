#include "snapped_start.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <set>
#include <utility>

#include "surfmap/geometry/nearest_point.h"

namespace surfmap::detail {

using hyperbolic::Mobius;
using Complex = std::complex<double>;

namespace {

// d(z, m(p)) with 1 − |m(p)|² taken from the identity 1 − |m p|² =
// (1 − |p|²) / |b̄ p + ā|² instead of from the rounded image: on the long
// domains of genus 11 and up the copies sit 1e-11 from |z| = 1, where an
// image by a side word rounds onto or past the circle (the plain formula's
// artanh is then infinite), while sinh²(d/2) = |z − w|² / ((1 − |z|²)(1 − |w|²))
// keeps about 1e-5 of relative accuracy there.
double distance_to_image(Complex z, const Mobius& m, Complex p) {
  const Complex w = m.apply(p);
  const double rp = std::abs(p), rz = std::abs(z);
  const double den_p = (1.0 - rp) * (1.0 + rp);
  const double den_w = den_p / std::norm(std::conj(m.b) * p + std::conj(m.a));
  const double den_z = (1.0 - rz) * (1.0 + rz);
  if (!(den_w > 0) || !(den_z > 0)) return std::numeric_limits<double>::infinity();
  return 2.0 * std::asinh(std::sqrt(std::norm(z - w) / (den_z * den_w)));
}

}  // namespace

SnappedStartBuilder::SnappedStartBuilder(const TriMesh& source, const TriMesh& target, const DiskLayout& layout,
                                         const DeckGroup& group, const FundamentalPolygon& polygon)
    : group_(group), polygon_(polygon) {
  const int nt = target.num_vertices();
  std::vector<Eigen::Vector3d> points(nt);
  for (int v = 0; v < nt; ++v) points[v] = target.V.row(v).transpose();
  const NearestPointIndex index(std::move(points));
  nearest_.resize(source.num_vertices());
  for (int v = 0; v < source.num_vertices(); ++v) nearest_[v] = index.nearest(source.V.row(v).transpose());
  copies_.assign(nt, {});
  for (size_t c = 0; c < layout.disk_positions.size(); ++c) {
    const int v = layout.disk_vertex_origin[c];
    if (v >= 0 && v < nt) copies_[v].push_back(layout.disk_positions[c]);
  }
  // The tiles around the polygon: two nearby points of the surface whose
  // copies sit on either side of a side (one letter) or near a corner (the
  // tiles there share only the corner: two letters reach most of them).
  const int letters = static_cast<int>(group.side_pairings().size());
  short_words_.push_back(Word{});
  for (int a = -letters; a <= letters; ++a) {
    if (a == 0) continue;
    short_words_.push_back(Word{a});
    for (int b = -letters; b <= letters; ++b)
      if (b != 0 && b != -a) short_words_.push_back(Word{a, b});
  }
  for (const Word& w : short_words_) short_elements_.push_back(group.evaluate_side_word(w));
}

SnappedStart SnappedStartBuilder::operator()(const std::vector<WeightedEdge>& edges) const {
  const int n = static_cast<int>(nearest_.size());
  SnappedStart s;
  s.z.assign(n, Complex(0.0));
  s.deck.assign(n, Word{});
  std::vector<std::vector<int>> incident(n);
  for (size_t e = 0; e < edges.size(); ++e) {
    incident[edges[e].i].push_back(static_cast<int>(e));
    incident[edges[e].j].push_back(static_cast<int>(e));
  }
  // Prim's tree over the edges, least ambiguous image edge first (its
  // nearest lift's distance over the next nearest lift's: on the plates the
  // collars' closed geodesics, 0.96 units at genus 2, are shorter than the
  // longest image edges, 2.1, so a long edge's nearest lift can be the wrong
  // sheet): vertex v reached from u across e takes the copy c of its nearest
  // target vertex and the short element t minimising d(c, t z_u); with
  // D_v = T_v D_root R_v (T the short elements, R the class's elements along
  // the tree) e's element (solve_with_decks: D_i rho D_j^-1) is that short
  // element once D_root is the conjugator below.
  struct Reach {
    double d;
    int v, u, e;
    size_t t;
    Complex c;
    bool operator<(const Reach& o) const { return d > o.d; }
  };
  std::vector<char> seen(n, 0), tree_edge(edges.size(), 0);
  std::vector<Word> T(n), R(n);  // D_v = T_v D_root R_v: target-side and class-side products along the tree
  std::priority_queue<Reach> heap;
  auto offer = [&](int u) {
    for (int e : incident[u]) {
      const WeightedEdge& ed = edges[e];
      const int v = ed.i == u ? ed.j : ed.i;
      if (seen[v]) continue;
      Reach r{std::numeric_limits<double>::infinity(), v, u, e, 0, Complex(0.0)};
      double second = std::numeric_limits<double>::infinity();
      bool have = false;
      // Whether candidate (c, q) is the same lift of the vertex as the best so
      // far (reached through another copy): not a rival.
      auto same_lift = [&](const Complex& c, size_t q) {
        return have && distance_to_image(r.c, short_elements_[r.t] * short_elements_[q].inverse(), c) < 1e-6;
      };
      for (const Complex& c : copies_[nearest_[v]])
        for (size_t q = 0; q < short_elements_.size(); ++q) {
          const double d = distance_to_image(c, short_elements_[q], s.z[u]);
          if (d < r.d) {
            if (!same_lift(c, q)) second = r.d;
            r.d = d, r.t = q, r.c = c, have = true;
          } else if (d < second && !same_lift(c, q)) {
            second = d;
          }
        }
      // Unambiguous first: the nearest lift against the next nearest one.
      r.d = r.d / std::max(second, 1e-300);
      if (!std::isfinite(r.d)) r.d = std::numeric_limits<double>::max();
      heap.push(r);
    }
  };
  for (int root = 0; root < n; ++root) {
    if (seen[root]) continue;
    seen[root] = 1;
    const auto& rc = copies_[nearest_[root]];
    s.z[root] = rc.empty() ? Complex(0.0) : rc.front();
    offer(root);
    while (!heap.empty()) {
      const Reach r = heap.top();
      heap.pop();
      if (seen[r.v]) continue;
      seen[r.v] = 1;
      tree_edge[r.e] = 1;
      const WeightedEdge& ed = edges[r.e];
      s.z[r.v] = r.c;
      // u is the tail (ed.i): D_v = t D_u rho; u is the head: D_v = t D_u rho^-1.
      const Word rho = ed.i == r.u ? ed.rho_word : inverse(ed.rho_word);
      T[r.v] = group_.reduce(concat(short_words_[r.t], T[r.u]));
      R[r.v] = group_.reduce(concat(R[r.u], rho));
      offer(r.v);
    }
  }
  // The root's deck: the conjugator D with D L_e D^-1 = M_e for the loops
  // closed by the edges off the tree (L_e = R_i rho R_j^-1 the class's
  // element of the loop, M_e = T_i^-1 s_e T_j the snapped map's, s_e the
  // edge's nearest lift); D maps the axes of two such L onto those of their
  // M. Several pairs are tried; the deck of lowest start energy is kept
  // (the empty one included).
  struct Closing {
    Word L, M;
  };
  std::vector<Closing> closing;
  std::set<std::pair<Word, Word>> listed;  // many edges close the same loop
  for (size_t e = 0; e < edges.size(); ++e) {
    if (tree_edge[e]) continue;
    const WeightedEdge& ed = edges[e];
    Closing c;
    c.L = group_.reduce(concat({R[ed.i], ed.rho_word, inverse(R[ed.j])}));
    if (c.L.empty()) continue;
    double best = std::numeric_limits<double>::infinity();
    size_t bq = 0;
    for (size_t q = 0; q < short_elements_.size(); ++q) {
      const double d = distance_to_image(s.z[ed.i], short_elements_[q], s.z[ed.j]);
      if (d < best) best = d, bq = q;
    }
    c.M = group_.reduce(concat({inverse(T[ed.i]), short_words_[bq], T[ed.j]}));
    if (c.M.empty() || !listed.insert({c.L, c.M}).second) continue;
    closing.push_back(std::move(c));
  }
  std::sort(closing.begin(), closing.end(), [](const Closing& a, const Closing& b) {
    return a.L.size() + a.M.size() < b.L.size() + b.M.size();
  });
  auto energy_with = [&](const Word& root, double* longest) {
    double E = 0;
    *longest = 0;
    for (const WeightedEdge& ed : edges) {
      const Word w = group_.reduce(concat({T[ed.i], root, R[ed.i], ed.rho_word, inverse(R[ed.j]), inverse(root),
                                           inverse(T[ed.j])}));
      const double d = distance_to_image(s.z[ed.i], group_.evaluate_side_word(w), s.z[ed.j]);
      E += ed.w * d * d;
      *longest = std::max(*longest, std::isfinite(d) ? d : std::numeric_limits<double>::infinity());
    }
    return std::isfinite(E) ? E : std::numeric_limits<double>::infinity();
  };
  // Fixed points of an SU(1,1) element, attracting first.
  auto fixed_points = [](const Mobius& m, Complex& attract, Complex& repel) {
    const Complex a = m.a, b = m.b;
    const Complex root = std::sqrt((std::conj(a) - a) * (std::conj(a) - a) + 4.0 * std::norm(b));
    const Complex z1 = ((a - std::conj(a)) + root) / (2.0 * std::conj(b));
    const Complex z2 = ((a - std::conj(a)) - root) / (2.0 * std::conj(b));
    const bool first = std::abs(std::conj(b) * z1 + std::conj(a)) > std::abs(std::conj(b) * z2 + std::conj(a));
    attract = first ? z1 : z2;
    repel = first ? z2 : z1;
  };
  // The point y with cross-ratio chart S_m(y) = S_l(x) (S maps p1, p2, p3 to 0, 1, inf).
  auto transfer = [](Complex x, const Complex l[3], const Complex m[3]) {
    const Complex w = (x - l[0]) * (l[1] - l[2]) / ((x - l[2]) * (l[1] - l[0]));
    const Complex k = (m[1] - m[2]) / (m[1] - m[0]);
    return (k * m[0] - w * m[2]) / (k - w);
  };
  Word root_deck;
  double longest = 0;
  s.energy = energy_with(root_deck, &longest);
  s.longest_edge = longest;
  int tried = 0;
  for (size_t p = 0; p < closing.size() && tried < 6; ++p) {
    Complex l1a, l1r, m1a, m1r;
    fixed_points(group_.evaluate_side_word(closing[p].L), l1a, l1r);
    fixed_points(group_.evaluate_side_word(closing[p].M), m1a, m1r);
    for (size_t q = p + 1; q < closing.size(); ++q) {
      Complex l2a, l2r, m2a, m2r;
      fixed_points(group_.evaluate_side_word(closing[q].L), l2a, l2r);
      if (std::abs(l2a - l1a) < 1e-3 || std::abs(l2a - l1r) < 1e-3) continue;
      fixed_points(group_.evaluate_side_word(closing[q].M), m2a, m2r);
      const Complex l[3] = {l1a, l1r, l2a}, m[3] = {m1a, m1r, m2a};
      Complex image = transfer(Complex(0.0), l, m);  // D(0)
      if (!(std::abs(image) < 1.0)) break;
      const Word back = polygon_.reduce(image);  // image <- back(image), near 0 when D is a deck element
      ++tried;
      if (!(std::abs(image) < 1e-6)) break;
      const Word candidate = group_.reduce(inverse(back));
      double cl = 0;
      const double E = energy_with(candidate, &cl);
      if (E < s.energy) s.energy = E, s.longest_edge = cl, root_deck = candidate;
      break;
    }
  }
  for (int v = 0; v < n; ++v) s.deck[v] = group_.reduce(concat({T[v], root_deck, R[v]}));
  for (const WeightedEdge& ed : edges) {
    const double d0 = ed.rho.displacement_of_origin();
    s.origin_energy += ed.w * d0 * d0;
    s.origin_longest_edge = std::max(s.origin_longest_edge, d0);
  }
  if (!std::isfinite(s.energy)) s.energy = std::numeric_limits<double>::infinity();
  return s;
}

}  // namespace surfmap::detail
