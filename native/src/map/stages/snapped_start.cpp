#include "snapped_start.h"

#include <algorithm>
#include <cmath>
#include <functional>
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

SnappedStartBuilder::Tree SnappedStartBuilder::tree(const std::vector<WeightedEdge>& edges) const {
  const int n = static_cast<int>(nearest_.size());
  Tree s;
  s.z.assign(n, Complex(0.0));
  s.T.assign(n, Word{});
  s.R.assign(n, Word{});
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
  std::vector<char> seen(n, 0);
  std::vector<char>& tree_edge = s.tree_edge;
  tree_edge.assign(edges.size(), 0);
  std::vector<Word>& T = s.T;  // D_v = T_v D_root R_v: target-side and class-side products along the tree
  std::vector<Word>& R = s.R;
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
  return s;
}

SnappedStart SnappedStartBuilder::operator()(const std::vector<WeightedEdge>& edges) const {
  const int n = static_cast<int>(nearest_.size());
  Tree t = tree(edges);
  SnappedStart s;
  s.z = std::move(t.z);
  s.deck.assign(n, Word{});
  const std::vector<char>& tree_edge = t.tree_edge;
  const std::vector<Word>& T = t.T;
  const std::vector<Word>& R = t.R;
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
    c.M = group_.reduce(concat({inverse(T[ed.i]), short_words_[nearest_lift(s.z[ed.i], s.z[ed.j])], T[ed.j]}));
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
  // How far the class is from the snapped map: edges whose start element is
  // not their nearest lift (0 in the snapped overlay's own class when the
  // overlay is consistent).
  for (const WeightedEdge& ed : edges) {
    const Word w = group_.reduce(concat({T[ed.i], root_deck, R[ed.i], ed.rho_word, inverse(R[ed.j]),
                                         inverse(root_deck), inverse(T[ed.j])}));
    if (w != short_words_[nearest_lift(s.z[ed.i], s.z[ed.j])]) ++s.disagreeing_edges;
  }
  for (const WeightedEdge& ed : edges) {
    const double d0 = ed.rho.displacement_of_origin();
    s.origin_energy += ed.w * d0 * d0;
    s.origin_longest_edge = std::max(s.origin_longest_edge, d0);
  }
  if (!std::isfinite(s.energy)) s.energy = std::numeric_limits<double>::infinity();
  return s;
}

size_t SnappedStartBuilder::nearest_lift(Complex zi, Complex zj) const {
  double best = std::numeric_limits<double>::infinity();
  size_t bq = 0;
  for (size_t q = 0; q < short_elements_.size(); ++q) {
    const double d = distance_to_image(zi, short_elements_[q], zj);
    if (d < best) best = d, bq = q;
  }
  return bq;
}

SnappedLoops SnappedStartBuilder::loop_images(const std::vector<WeightedEdge>& edges, const Connectivity& sc,
                                              const std::vector<std::vector<int>>& loops,
                                              const std::vector<Word>& edge_word, const Word& loop_relator) const {
  SnappedLoops out;
  const Tree t = tree(edges);
  // Each source edge's element under the snapped map, in the tree's gauge:
  // M = T_i^-1 s T_j with s its nearest lift (the empty word on tree edges).
  const int ne = sc.num_edges(), nf = sc.num_faces();
  std::vector<Word> edge_element(ne);
  std::vector<double> ambiguity(ne, 0.0);  // nearest lift's distance over the next nearest's
  for (int e = 0; e < ne; ++e) {
    const int h = sc.edge_halfedge(e), i = sc.tail(h), j = sc.head(h);
    const size_t q = nearest_lift(t.z[i], t.z[j]);
    edge_element[e] = group_.reduce(concat({inverse(t.T[i]), short_words_[q], t.T[j]}));
    const double best = distance_to_image(t.z[i], short_elements_[q], t.z[j]);
    const Complex image = short_elements_[q].apply(t.z[j]);
    double second = std::numeric_limits<double>::infinity();
    for (size_t r = 0; r < short_elements_.size(); ++r) {
      if (distance_to_image(image, short_elements_[r], t.z[j]) < 1e-6) continue;  // the same lift
      second = std::min(second, distance_to_image(t.z[i], short_elements_[r], t.z[j]));
    }
    ambiguity[e] = best / std::max(second, 1e-300);
    if (!std::isfinite(ambiguity[e])) ambiguity[e] = std::numeric_limits<double>::max();
  }
  auto element_of = [&](int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? edge_element[e] : inverse(edge_element[e]);
  };
  // The snapped map is a map of the surfaces (one homomorphism of the
  // groups) exactly when these elements close up around every face.
  for (int f = 0; f < nf; ++f)
    if (!group_.reduce(concat({element_of(3 * f), element_of(3 * f + 1), element_of(3 * f + 2)})).empty())
      ++out.inconsistent_faces;
  // Made consistent: the most ambiguous edges (a spanning tree of the dual
  // graph, Kruskal by ambiguity, most ambiguous first) are derived from the
  // others by closing the faces, leaves of that tree first; the rest (#V - 1
  // + 2g edges, the least ambiguous) keep their nearest lifts. On the
  // genus-11 plate onto itself 43 faces did not close (long image edges
  // across the short collars), and the loops read through them did not
  // give an isomorphism.
  std::vector<int> by_ambiguity(ne);
  for (int e = 0; e < ne; ++e) by_ambiguity[e] = e;
  std::stable_sort(by_ambiguity.begin(), by_ambiguity.end(), [&](int x, int y) { return ambiguity[x] > ambiguity[y]; });
  std::vector<int> component(nf);
  for (int f = 0; f < nf; ++f) component[f] = f;
  std::function<int(int)> find = [&](int f) { return component[f] == f ? f : component[f] = find(component[f]); };
  std::vector<std::vector<int>> dual_tree(nf);  // per face: its dual tree halfedges
  for (int e : by_ambiguity) {
    const int h = sc.edge_halfedge(e), g = sc.twin(h);
    if (g < 0) continue;
    const int a = find(h / 3), b = find(g / 3);
    if (a == b) continue;
    component[a] = b;
    dual_tree[h / 3].push_back(h);
    dual_tree[g / 3].push_back(g);
  }
  std::vector<int> order{0}, parent_halfedge(nf, -1);
  std::vector<char> reached(nf, 0);
  reached[0] = 1;
  for (size_t q = 0; q < order.size(); ++q)
    for (int h : dual_tree[order[q]]) {
      const int g = sc.twin(h), f = g / 3;
      if (reached[f]) continue;
      reached[f] = 1;
      parent_halfedge[f] = g;  // f's halfedge towards its parent
      order.push_back(f);
    }
  for (size_t q = order.size(); q-- > 1;) {
    const int f = order[q], hd = parent_halfedge[f];
    const int hb = 3 * f + (hd % 3 + 1) % 3, hc = 3 * f + (hd % 3 + 2) % 3;
    Word derived = group_.reduce(inverse(concat(element_of(hb), element_of(hc))));
    const int e = sc.edge(hd);
    edge_element[e] = sc.edge_halfedge(e) == hd ? derived : inverse(derived);
  }
  const int letters = static_cast<int>(loops.size());
  out.letter_side_words.assign(letters, Word{});
  std::vector<char> have(letters, 0);
  const DehnReducer source_reduce(loop_relator);
  for (const std::vector<int>& loop : loops) {
    Word source_word, image;
    for (size_t q = 0; q + 1 < loop.size(); ++q) {
      const int h = sc.find_halfedge(loop[q], loop[q + 1]);
      if (h < 0) {
        out.why = "a source loop is not an edge path of the source";
        return out;
      }
      const int e = sc.edge(h);
      source_word = concat(source_word, sc.edge_halfedge(e) == h ? edge_word[e] : inverse(edge_word[e]));
      image = group_.reduce(concat(image, element_of(h)));
    }
    source_word = source_reduce(source_word);
    // Each loop crosses the cut once (its generator edge): its word is its
    // own letter, the image of that letter its snapped element.
    if (source_word.size() != 1) {
      out.why = "a source loop's word has " + std::to_string(source_word.size()) + " letters, not 1";
      return out;
    }
    const int k = std::abs(source_word[0]) - 1;
    out.letter_side_words[k] = source_word[0] > 0 ? image : inverse(image);
    have[k] = 1;
  }
  for (int k = 0; k < letters; ++k)
    if (!have[k]) {
      out.why = "source loop letter " + std::to_string(k + 1) + " is not the word of any loop";
      return out;
    }
  out.ok = true;
  return out;
}

bool snapped_class_map(const SnappedLoops& loops, const DiskLayout& layout, const DeckGroup& group,
                       const std::vector<Word>& canonical_of_loop_letter, const std::vector<Word>& source_generators,
                       GroupMap* theta, std::string* why) {
  const Word& word = layout.word;
  const int n = static_cast<int>(word.size());
  const int letters = n / 2;
  if (!loops.ok) {
    *why = loops.why;
    return false;
  }
  // Side letter k+1 in loop letters: D_k Psi_i = Psi_{j+1} for the sides
  // i (+k) and j (-k) (uniformize/layout.cpp corner_elements), and
  // Psi_{m+1} = Psi_m g_{word[m]}, so Psi_m is the boundary word's prefix.
  auto prefix = [&](int m) { return Word(word.begin(), word.begin() + m); };
  std::vector<Word> side_in_loops(letters);
  const DehnReducer reduce_loops(word);
  for (int k = 0; k < letters; ++k) {
    int i = -1, j = -1;
    for (int m = 0; m < n; ++m) {
      if (word[m] == k + 1) i = m;
      if (word[m] == -(k + 1)) j = m;
    }
    if (i < 0 || j < 0) {
      *why = "the target's boundary word lacks loop letter " + std::to_string(k + 1);
      return false;
    }
    side_in_loops[k] = reduce_loops(concat(prefix(j + 1), inverse(prefix(i))));
    if (group.side_word(side_in_loops[k]) != Word{k + 1}) {
      *why = "side letter " + std::to_string(k + 1) + " does not rewrite in loop letters";
      return false;
    }
  }
  std::vector<Word> loop_images;
  for (const Word& w : loops.letter_side_words) loop_images.push_back(reduce_loops(substitute(w, side_in_loops)));
  const DehnReducer reduce_canonical(canonical_relator(letters / 2));
  theta->assign(source_generators.size(), Word{});
  for (size_t j = 0; j < source_generators.size(); ++j)
    (*theta)[j] = reduce_canonical(substitute(substitute(source_generators[j], loop_images), canonical_of_loop_letter));
  return true;
}

bool invert_canonical_generators(const std::vector<Word>& canonical_generators, const Word& layout_word,
                                 const std::vector<Word>& hint, std::vector<Word>* loop_letters, std::string* why) {
  const int n = static_cast<int>(canonical_generators.size());
  const DehnReducer reduce_exactly(layout_word);
  // A cap on the work (Dehn reductions) of the moves: the two-generator
  // products cost (2g)^3 reductions per stuck step, so a high-genus target
  // whose generators do not reduce gives up instead of running for minutes.
  constexpr long kMaxReductions = 20000000;
  long reductions = 0;
  auto reduce_loops = [&](const Word& w) {
    ++reductions;
    return reduce_exactly(w);
  };
  const DehnReducer reduce_canonical(canonical_relator(n / 2));
  auto inverts = [&](const std::vector<Word>& inv) {
    if (static_cast<int>(inv.size()) != n) return false;
    for (int k = 0; k < n; ++k)
      if (reduce_loops(substitute(inv[k], canonical_generators)) != Word{k + 1}) return false;
    return true;
  };
  if (inverts(hint)) {
    *loop_letters = hint;
    return true;
  }
  // u[i]: a loop word, p[i]: the canonical word it is the image of.
  std::vector<Word> u(n), p(n);
  for (int i = 0; i < n; ++i) u[i] = reduce_loops(canonical_generators[i]), p[i] = Word{i + 1};
  auto total = [&] {
    size_t t = 0;
    for (const Word& w : u) t += w.size();
    return t;
  };
  const size_t start_letters = total();
  Word conjugator;  // the original u_i = conjugator u_i conjugator^-1
  constexpr int kPlateauMoves = 2000;
  int plateau_moves = 0;
  std::set<std::vector<Word>> seen;
  for (int round = 0; round < 100000; ++round) {
    if (reductions > kMaxReductions) {
      *why = "Nielsen moves gave up after " + std::to_string(reductions) + " reductions at " + std::to_string(total()) +
             " letters (from " + std::to_string(start_letters) + ")";
      return false;
    }
    bool done = true;
    for (const Word& w : u) done = done && w.size() == 1;
    if (done) break;
    size_t best = 0;
    int bi = -1;
    Word bu, bp;
    for (int i = 0; i < n; ++i)
      for (int k = 0; k < n; ++k) {
        if (k == i) continue;
        for (int sign : {1, -1})
          for (int right : {1, 0}) {
            const Word uk = sign > 0 ? u[k] : inverse(u[k]);
            const Word pk = sign > 0 ? p[k] : inverse(p[k]);
            Word cu = reduce_loops(right ? concat(u[i], uk) : concat(uk, u[i]));
            if (cu.size() >= u[i].size()) continue;
            const size_t gain = u[i].size() - cu.size();
            if (gain > best) best = gain, bi = i, bu = std::move(cu), bp = right ? concat(p[i], pk) : concat(pk, p[i]);
          }
      }
    // The generators seen from another base point (the carried loops start
    // at the target's own base vertex): all conjugated by one letter x,
    // u_i -> x^-1 u_i x (an inner automorphism: the inverse up to the one
    // conjugation c, which names the same class).
    // The conjugators tried: every letter and every prefix of a generator
    // up to half its length (u_i = c x c^-1 starts with c).
    if (bi < 0) {
      size_t best_total = total();
      Word bx;
      std::set<Word> tried;
      auto try_conjugator = [&](const Word& x) {
        if (x.empty() || !tried.insert(x).second) return;
        size_t t = 0;
        for (const Word& w : u) t += reduce_loops(concat({inverse(x), w, x})).size();
        if (t < best_total) best_total = t, bx = x;
      };
      for (int x = -n; x <= n; ++x)
        if (x != 0) try_conjugator(Word{x});
      for (const Word& w : u)
        for (size_t m = 1; 2 * m < w.size(); ++m) try_conjugator(Word(w.begin(), w.begin() + m));
      if (!bx.empty()) {
        for (Word& w : u) w = reduce_loops(concat({inverse(bx), w, bx}));
        conjugator = reduce_loops(concat(conjugator, bx));
        continue;
      }
    }
    // Stuck on single moves: conjugations u_k^e u_i u_k^-e, then products
    // with two generators (a one-relator group's bases need not shorten
    // one multiplication at a time).
    for (int i = 0; i < n && bi < 0; ++i)
      for (int k = 0; k < n; ++k) {
        if (k == i) continue;
        for (int sign : {1, -1}) {
          const Word uk = sign > 0 ? u[k] : inverse(u[k]);
          const Word pk = sign > 0 ? p[k] : inverse(p[k]);
          Word cu = reduce_loops(concat({uk, u[i], inverse(uk)}));
          if (cu.size() >= u[i].size()) continue;
          const size_t gain = u[i].size() - cu.size();
          if (gain > best) best = gain, bi = i, bu = std::move(cu), bp = concat({pk, p[i], inverse(pk)});
        }
      }
    for (int i = 0; i < n && bi < 0; ++i)
      for (int k = 0; k < n; ++k)
        for (int l = 0; l < n; ++l) {
          if (k == i || l == i) continue;
          for (int sk : {1, -1})
            for (int sl : {1, -1})
              for (int right : {1, 0}) {
                const Word uk = sk > 0 ? u[k] : inverse(u[k]), ul = sl > 0 ? u[l] : inverse(u[l]);
                const Word pk = sk > 0 ? p[k] : inverse(p[k]), pl = sl > 0 ? p[l] : inverse(p[l]);
                Word cu = reduce_loops(right ? concat({u[i], uk, ul}) : concat({uk, ul, u[i]}));
                if (cu.size() >= u[i].size()) continue;
                const size_t gain = u[i].size() - cu.size();
                if (gain > best)
                  best = gain, bi = i, bu = std::move(cu), bp = right ? concat({p[i], pk, pl}) : concat({pk, pl, p[i]});
              }
        }
    // Still stuck: a move that keeps the length, to a configuration not
    // seen before (a plateau walk, at most kPlateauMoves in all).
    for (int i = 0; i < n && bi < 0 && plateau_moves < kPlateauMoves; ++i)
      for (int k = 0; k < n && bi < 0; ++k) {
        if (k == i) continue;
        for (int sign : {1, -1})
          for (int right : {1, 0}) {
            if (bi >= 0) break;
            const Word uk = sign > 0 ? u[k] : inverse(u[k]);
            Word cu = reduce_loops(right ? concat(u[i], uk) : concat(uk, u[i]));
            if (cu.size() != u[i].size()) continue;
            std::vector<Word> next = u;
            next[i] = cu;
            if (!seen.insert(next).second) continue;
            const Word pk = sign > 0 ? p[k] : inverse(p[k]);
            bi = i, bu = std::move(cu), bp = right ? concat(p[i], pk) : concat(pk, p[i]);
            ++plateau_moves;
          }
      }
    if (bi < 0) {
      *why = "Nielsen moves stuck at " + std::to_string(total()) + " letters (from " + std::to_string(start_letters) +
             ", " + std::to_string(n) + " generators)";
      return false;
    }
    u[bi] = std::move(bu);
    p[bi] = reduce_canonical(bp);
  }
  std::vector<Word> inv(n);
  std::vector<char> have(n, 0);
  for (int i = 0; i < n; ++i) {
    if (u[i].size() != 1) return (*why = "Nielsen moves did not finish"), false;
    const int k = std::abs(u[i][0]) - 1;
    if (have[k]) return (*why = "Nielsen moves ended on a repeated letter"), false;
    have[k] = 1;
    inv[k] = u[i][0] > 0 ? p[i] : inverse(p[i]);
  }
  for (int k = 0; k < n; ++k)
    if (reduce_loops(substitute(inv[k], canonical_generators)) !=
        reduce_loops(concat({conjugator, Word{k + 1}, inverse(conjugator)})))
      return (*why = "the inverse found does not check out"), false;
  *loop_letters = std::move(inv);
  return true;
}

}  // namespace surfmap::detail
