#include "snapped_start.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
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

Word rotated(const Word& u, size_t r) {
  Word out(u.begin() + static_cast<long>(r), u.end());
  out.insert(out.end(), u.begin(), u.begin() + static_cast<long>(r));
  return out;
}

// w = a u a^-1 with u cyclically Dehn-reduced: matching ends are peeled off
// into a, and a rotation p^-1 u p that Dehn's algorithm shortens moves p
// into a.
void peel(const Word& w, const std::function<Word(const Word&)>& reduce, Word* a, Word* u) {
  a->clear();
  *u = reduce(w);
  for (size_t guard = 0; guard < 4 * w.size() + 8; ++guard) {
    if (u->size() >= 2 && u->front() == -u->back()) {
      a->push_back(u->front());
      *u = Word(u->begin() + 1, u->end() - 1);
      continue;
    }
    bool shorter = false;
    for (size_t r = 1; r < u->size() && !shorter; ++r) {
      Word d = reduce(rotated(*u, r));
      if (d.size() < u->size()) {
        *a = concat(*a, Word(u->begin(), u->begin() + static_cast<long>(r)));
        *u = std::move(d);
        shorter = true;
      }
    }
    if (!shorter) break;
  }
  *a = reduce(*a);
}

}  // namespace

bool conjugator_from_words(const std::vector<std::pair<Word, Word>>& pairs,
                           const std::function<Word(const Word&)>& reduce, int letters, Word* D, std::string* why) {
  auto equal = [&](const Word& x, const Word& y) { return reduce(concat(x, inverse(y))).empty(); };
  size_t first = 0;
  while (first < pairs.size() && reduce(pairs[first].first).empty()) ++first;
  if (first == pairs.size()) return (*why = "no pair with a non-trivial element"), false;
  const Word& L = pairs[first].first;
  const Word& M = pairs[first].second;
  Word a, l, b, m;
  peel(L, reduce, &a, &l);
  peel(M, reduce, &b, &m);
  // x with x l x^-1 = m: a rotation p^-1 l p of l equal to m (x = p^-1),
  // else one letter y away from it (x = y p^-1).
  Word x;
  bool found = false;
  for (size_t r = 0; r < l.size() && !found; ++r)
    if (equal(rotated(l, r), m)) x = inverse(Word(l.begin(), l.begin() + static_cast<long>(r))), found = true;
  for (size_t r = 0; r < l.size() && !found; ++r) {
    const Word rot = rotated(l, r);
    for (int y = -letters; y <= letters && !found; ++y)
      if (y != 0 && equal(concat({Word{y}, rot, Word{-y}}), m))
        x = concat(Word{y}, inverse(Word(l.begin(), l.begin() + static_cast<long>(r)))), found = true;
  }
  if (!found) {
    *why = "the first loop's elements (" + std::to_string(l.size()) + " and " + std::to_string(m.size()) +
           " letters cyclically reduced) are not conjugate by a rotation";
    return false;
  }
  // D = b x l^k a^-1; k from the first pair whose L does not commute with L.
  auto candidate = [&](long k) {
    Word power;
    for (long q = 0; q < std::abs(k); ++q) power = concat(power, k > 0 ? l : inverse(l));
    return reduce(concat({b, x, power, inverse(a)}));
  };
  auto conjugates = [&](const Word& d, const std::pair<Word, Word>& p) {
    return reduce(concat({d, p.first, inverse(d), inverse(p.second)})).empty();
  };
  Word best = candidate(0);
  for (size_t q = first + 1; q < pairs.size(); ++q) {
    const Word& L2 = pairs[q].first;
    if (reduce(concat({L, L2, inverse(L), inverse(L2)})).empty()) continue;
    const long range = static_cast<long>((L2.size() + pairs[q].second.size()) / std::max<size_t>(l.size(), 1)) + 2;
    bool pinned = false;
    for (long k = 0; k <= range && !pinned; ++k)
      for (long s : {k, -k}) {
        const Word d = candidate(s);
        if (conjugates(d, pairs[q])) {
          best = d, pinned = true;
          break;
        }
      }
    if (!pinned) {
      *why = "no power of the first loop's element conjugates pair " + std::to_string(q) + " as well";
      return false;
    }
    break;
  }
  for (size_t q = 0; q < pairs.size(); ++q)
    if (!conjugates(best, pairs[q])) {
      *why = "pair " + std::to_string(q) + " is not conjugated by the conjugator of the others";
      return false;
    }
  *D = std::move(best);
  return true;
}

SnappedStartBuilder::SnappedStartBuilder(const TriMesh& source, const TriMesh& target, const TriMesh& layout_mesh,
                                         const DiskLayout& layout, const DeckGroup& group,
                                         const FundamentalPolygon& polygon)
    : group_(group), polygon_(polygon), layout_conn_(layout_mesh.F, layout_mesh.num_vertices()) {
  const int nt = target.num_vertices();
  if (layout_mesh.num_vertices() < nt || layout.disk_faces.rows() != layout_mesh.num_faces())
    layout_mismatch_ = "the layout's mesh has " + std::to_string(layout_mesh.num_faces()) + " faces, the layout " +
                       std::to_string(layout.disk_faces.rows());
  layout_points_.resize(layout_mesh.num_vertices());
  for (int v = 0; v < layout_mesh.num_vertices(); ++v) layout_points_[v] = layout_mesh.V.row(v).transpose();
  source_points_.resize(source.num_vertices());
  for (int v = 0; v < source.num_vertices(); ++v) source_points_[v] = source.V.row(v).transpose();
  std::vector<Eigen::Vector3d> points(nt);
  for (int v = 0; v < nt; ++v) points[v] = target.V.row(v).transpose();
  const NearestPointIndex index(std::move(points));
  nearest_.resize(source.num_vertices());
  for (int v = 0; v < source.num_vertices(); ++v) nearest_[v] = index.nearest(source.V.row(v).transpose());
  // Every cut halfedge lies on one side of the disk's boundary (the disk on
  // its left); the side's letter is the deck map taking this copy of the
  // edge onto the other (uniformize/layout.h), so crossing the edge out of
  // the face of this halfedge moves to the sheet times that letter's inverse.
  halfedge_letter_.assign(layout_conn_.num_halfedges(), 0);
  const int sides = static_cast<int>(layout.side_start.size());
  const int nb = static_cast<int>(layout.boundary_halfedges.size());
  for (int s = 0; s < sides; ++s) {
    const int end = s + 1 < sides ? layout.side_start[s + 1] : layout.side_start[0] + nb;
    for (int i = layout.side_start[s]; i < end; ++i) halfedge_letter_[layout.boundary_halfedges[i % nb]] = layout.word[s];
  }
  // Each source vertex's home: a layout face around its target vertex, and
  // that vertex's copy in the face (its point in the cut disk).
  home_face_.resize(nearest_.size());
  home_point_.resize(nearest_.size());
  if (!layout_mismatch_.empty()) return;
  for (size_t v = 0; v < nearest_.size(); ++v) {
    const int h = layout_conn_.vertex_halfedge(nearest_[v]), f = Connectivity::face(h);
    home_face_[v] = f;
    home_point_[v] = layout.disk_positions[layout.disk_faces(f, h % 3)];
  }
}

SnappedStartBuilder::Tree SnappedStartBuilder::tree(const std::vector<WeightedEdge>& edges,
                                                     bool through_source_edges) const {
  const int n = static_cast<int>(nearest_.size());
  Tree s;
  s.z = home_point_;
  s.T.assign(n, Word{});
  s.R.assign(n, Word{});
  s.tree_edge.assign(edges.size(), 0);
  s.element.assign(edges.size(), Word{});
  PathScratch scratch;
  for (size_t e = 0; e < edges.size(); ++e) {
    double length = 0;
    int on_path = 0;
    if (through_source_edges) {
      const WeightedEdge& ed = edges[e];
      const auto& ie = e < source_paths_->edges.size() ? source_paths_->edges[e] : IntrinsicEdge{};
      if (ie.i == ed.i && ie.j == ed.j && !ie.path.empty()) {
        Word w;
        for (int h : ie.path) w = concat(w, source_halfedge_element(h));
        s.element[e] = group_.reduce(w);
        continue;
      }
      const int h = source_conn_->find_halfedge(ed.i, ed.j);
      if (h >= 0) {
        s.element[e] = source_halfedge_element(h);
        continue;
      }
    }
    if (!path_element(edges[e].i, edges[e].j, scratch, &s.element[e], &length, &on_path, &s.why)) return s;
  }
  std::vector<std::vector<int>> incident(n);
  for (size_t e = 0; e < edges.size(); ++e) {
    incident[edges[e].i].push_back(static_cast<int>(e));
    incident[edges[e].j].push_back(static_cast<int>(e));
  }
  // A breadth-first tree of the solver's edges: v reached from u across e
  // has D_v = T_v D_root R_v with T_v = g T_u, g the element of (v, u) (the
  // lift of u next to v's home copy is g of u's), and R the class's
  // elements along the tree; e's element (solve_with_decks: D_i rho D_j^-1)
  // is then the snapped map's once D_root is the conjugator below.
  std::vector<char> seen(n, 0);
  for (int root = 0; root < n; ++root) {
    if (seen[root]) continue;
    seen[root] = 1;
    std::vector<int> queue{root};
    for (size_t q = 0; q < queue.size(); ++q) {
      const int u = queue[q];
      for (int e : incident[u]) {
        const WeightedEdge& ed = edges[e];
        const int v = ed.i == u ? ed.j : ed.i;
        if (seen[v]) continue;
        seen[v] = 1;
        s.tree_edge[e] = 1;
        // u is the tail (ed.i): D_v = g D_u rho with g = element(i, j)^-1; u is the head: g = element(i, j), rho^-1.
        const Word g = ed.i == u ? inverse(s.element[e]) : s.element[e];
        const Word rho = ed.i == u ? ed.rho_word : inverse(ed.rho_word);
        s.T[v] = group_.reduce(concat(g, s.T[u]));
        s.R[v] = group_.reduce(concat(s.R[u], rho));
        queue.push_back(v);
      }
    }
  }
  s.ok = true;
  return s;
}

SnappedStart SnappedStartBuilder::operator()(const std::vector<WeightedEdge>& edges) const {
  SnappedStart s = start_from(tree(edges, false), edges);
  // No conjugator with each solver edge's own image path: the loops the
  // tree closes through intrinsic edges (or input edges flipped away) need
  // not be the snapped map's, so read every solver edge through the
  // source's own edges instead (use_source_paths), where the elements close
  // around every face; kept when it gives a conjugator. Only then, so that a
  // start found today keeps its very words.
  if (!s.conjugator_found && !source_element_.empty()) {
    SnappedStart t = start_from(tree(edges, true), edges);
    if (t.conjugator_found) {
      t.through_source_edges = true;
      return t;
    }
    if (s.conjugator_why.empty()) s.conjugator_why = t.conjugator_why;
    else s.conjugator_why += "; through the source's edges: " + t.conjugator_why;
  }
  return s;
}

Word SnappedStartBuilder::source_halfedge_element(int h) const {
  const int e = source_conn_->edge(h);
  return source_conn_->edge_halfedge(e) == h ? source_element_[e] : inverse(source_element_[e]);
}

void SnappedStartBuilder::use_source_paths(const Connectivity& sc, const IntrinsicDelaunayResult& idt) {
  const ConsistentElements c = consistent_edge_elements(sc);
  if (!c.ok) return;
  source_conn_ = &sc;
  source_paths_ = &idt;
  source_element_ = c.element;
}

SnappedStart SnappedStartBuilder::start_from(const Tree& t, const std::vector<WeightedEdge>& edges) const {
  const int n = static_cast<int>(nearest_.size());
  SnappedStart s;
  for (const WeightedEdge& ed : edges) {
    const double d0 = ed.rho.displacement_of_origin();
    s.origin_energy += ed.w * d0 * d0;
    s.origin_longest_edge = std::max(s.origin_longest_edge, d0);
  }
  if (!t.ok) {  // no exact elements: never better than the origin
    s.energy = s.longest_edge = std::numeric_limits<double>::infinity();
    return s;
  }
  s.z = t.z;
  s.deck.assign(n, Word{});
  const std::vector<char>& tree_edge = t.tree_edge;
  const std::vector<Word>& T = t.T;
  const std::vector<Word>& R = t.R;
  // The root's deck: the conjugator D with D L_e D^-1 = M_e for the loops
  // closed by the edges off the tree (L_e = R_i rho R_j^-1 the class's
  // element of the loop, M_e = T_i^-1 s_e T_j the snapped map's, s_e the
  // edge's exact element); D maps the axes of two such L onto those of their
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
    c.M = group_.reduce(concat({inverse(T[ed.i]), t.element[e], T[ed.j]}));
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
  bool conjugator_found = false;
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
      conjugator_found = s.conjugator_found = true;
      double cl = 0;
      const double E = energy_with(candidate, &cl);
      if (E < s.energy) s.energy = E, s.longest_edge = cl, root_deck = candidate;
      break;
    }
  }
  // No conjugator from the fixed points (genus 11: they lie at round-off
  // from |z| = 1, and D(0) comes out at |z| >= 0.997 in every try): the
  // conjugator from the words (conjugator_from_words), checked exactly on
  // every closing loop. Only then, so that a start the fixed points give
  // keeps its very words (genus-2 maps byte-identical).
  if (!conjugator_found && !closing.empty()) {
    std::vector<std::pair<Word, Word>> pairs;
    pairs.reserve(closing.size());
    for (const Closing& c : closing) pairs.emplace_back(c.L, c.M);
    Word candidate;
    std::string why;
    const int letters = static_cast<int>(group_.side_pairings().size());
    if (conjugator_from_words(pairs, [&](const Word& w) { return group_.reduce(w); }, letters, &candidate, &why)) {
      s.conjugator_from_words = s.conjugator_found = true;
      double cl = 0;
      const double E = energy_with(candidate, &cl);
      if (E < s.energy) s.energy = E, s.longest_edge = cl, root_deck = candidate;
    } else {
      s.conjugator_why = why;
    }
  }
  for (int v = 0; v < n; ++v) s.deck[v] = group_.reduce(concat({T[v], root_deck, R[v]}));
  // How far the class is from the snapped map: edges whose start element is
  // not their exact element (0 in the snapped overlay's own class when the
  // overlay is consistent).
  for (size_t e = 0; e < edges.size(); ++e) {
    const WeightedEdge& ed = edges[e];
    const Word w = group_.reduce(concat({T[ed.i], root_deck, R[ed.i], ed.rho_word, inverse(R[ed.j]),
                                         inverse(root_deck), inverse(T[ed.j])}));
    if (w != t.element[e]) ++s.disagreeing_edges;
  }
  if (!std::isfinite(s.energy)) s.energy = std::numeric_limits<double>::infinity();
  return s;
}

bool SnappedStartBuilder::walk_around(int p, int from, int to, Word& sheet) const {
  int h0 = -1;
  for (int k = 0; k < 3; ++k)
    if (layout_conn_.tail(3 * from + k) == p) h0 = 3 * from + k;
  if (h0 < 0) return false;
  // Counter-clockwise: out of face(h) across prev(h); clockwise: across h.
  Word ccw, cw;
  const int valence = layout_conn_.valence(p);
  int h = h0, steps_ccw = 0;
  for (; Connectivity::face(h) != to; ++steps_ccw) {
    if (steps_ccw > valence) return false;
    const int out = Connectivity::prev(h);
    if (halfedge_letter_[out] != 0) ccw.push_back(-halfedge_letter_[out]);
    h = layout_conn_.rotate_ccw(h);
  }
  h = h0;
  int steps_cw = 0;
  for (; Connectivity::face(h) != to && steps_cw < steps_ccw; ++steps_cw) {
    if (halfedge_letter_[h] != 0) cw.push_back(-halfedge_letter_[h]);
    h = Connectivity::next(layout_conn_.twin(h));
  }
  const Word& walk = Connectivity::face(h) == to && steps_cw < steps_ccw ? cw : ccw;
  sheet.insert(sheet.end(), walk.begin(), walk.end());
  return true;
}

// Dijkstra on the layout's edges (3D chord lengths) from a to b, for the
// source edges whose ends snap to target vertices that are not adjacent;
// the search's arrays are kept in `s` (reset in the time of what the last
// search reached).
void SnappedStartBuilder::shortest_path(int a, int b, PathScratch& s) const {
  detail::DijkstraOptions to_b;
  to_b.target = b;
  auto chords = detail::rotation_arcs(layout_conn_, [&](int h) {
    return (layout_points_[layout_conn_.head(h)] - layout_points_[layout_conn_.tail(h)]).norm();
  });
  detail::dijkstra(layout_conn_.num_vertices(), chords, {a}, to_b, s.search);
  s.path.clear();
  if (std::isfinite(s.search.distance[b]))
    for (int v = b; v != a; v = layout_conn_.tail(s.search.parent_arc[v])) s.path.push_back(v);
  s.path.push_back(a);
  std::reverse(s.path.begin(), s.path.end());
}

bool SnappedStartBuilder::path_element(int i, int j, PathScratch& scratch, Word* element, double* length,
                                       int* edges_on_path, std::string* why) const {
  if (!layout_mismatch_.empty()) return (*why = layout_mismatch_), false;
  const int a = nearest_[i], b = nearest_[j];
  std::vector<int>& path = scratch.path;
  if (a == b) path.assign(1, a);
  else if (layout_conn_.find_halfedge(a, b) >= 0) path = {a, b};
  else shortest_path(a, b, scratch);
  if (path.back() != b)
    return (*why = "target vertices " + std::to_string(a) + " and " + std::to_string(b) + " are not connected"), false;
  Word sheet;
  int face = home_face_[i];
  *length = 0;
  for (size_t q = 0; q + 1 < path.size(); ++q) {
    const int h = layout_conn_.find_halfedge(path[q], path[q + 1]);
    if (!walk_around(path[q], face, Connectivity::face(h), sheet))
      return (*why = "the walk around target vertex " + std::to_string(path[q]) + " lost its way"), false;
    face = Connectivity::face(h);
    *length += (layout_points_[path[q + 1]] - layout_points_[path[q]]).norm();
  }
  if (!walk_around(b, face, home_face_[j], sheet))
    return (*why = "the walk around target vertex " + std::to_string(b) + " lost its way"), false;
  *element = group_.reduce(sheet);
  *edges_on_path = static_cast<int>(path.size()) - 1;
  return true;
}

ExactEdgeElements SnappedStartBuilder::exact_edge_elements(const Connectivity& sc) const {
  ExactEdgeElements out;
  const int ne = sc.num_edges();
  out.element.assign(ne, Word{});
  out.doubt.assign(ne, 0.0);
  PathScratch scratch;
  for (int e = 0; e < ne; ++e) {
    const int hs = sc.edge_halfedge(e), i = sc.tail(hs), j = sc.head(hs);
    double length = 0;
    int on_path = 0;
    if (!path_element(i, j, scratch, &out.element[e], &length, &on_path, &out.why)) return out;
    out.longest_path = std::max(out.longest_path, on_path);
    out.long_paths += on_path >= 2;
    out.doubt[e] = length / std::max((source_points_[j] - source_points_[i]).norm(), 1e-300);
  }
  out.ok = true;
  return out;
}

SnappedStartBuilder::ConsistentElements SnappedStartBuilder::consistent_edge_elements(const Connectivity& sc) const {
  ConsistentElements out;
  ExactEdgeElements exact = exact_edge_elements(sc);
  if (!exact.ok) {
    out.why = exact.why;
    return out;
  }
  out.longest_path = exact.longest_path;
  out.long_paths = exact.long_paths;
  const int ne = sc.num_edges(), nf = sc.num_faces();
  std::vector<Word>& edge_element = exact.element;
  const std::vector<double>& doubt = exact.doubt;
  auto element_of = [&](int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? edge_element[e] : inverse(edge_element[e]);
  };
  // The snapped map is a map of the surfaces (one homomorphism of the
  // groups) exactly when these elements close up around every face.
  for (int f = 0; f < nf; ++f)
    if (!group_.reduce(concat({element_of(3 * f), element_of(3 * f + 1), element_of(3 * f + 2)})).empty())
      ++out.inconsistent_faces;
  // Made consistent when some face does not close: the most doubtful edges
  // (a spanning tree of the dual graph, Kruskal by doubt, most doubtful
  // first) are derived from the others by closing the faces, leaves of that
  // tree first; the rest (#V - 1 + 2g edges, the least doubtful) keep their
  // paths' elements.
  if (out.inconsistent_faces > 0) {
    std::vector<int> by_doubt(ne);
    for (int e = 0; e < ne; ++e) by_doubt[e] = e;
    std::stable_sort(by_doubt.begin(), by_doubt.end(), [&](int x, int y) { return doubt[x] > doubt[y]; });
    std::vector<int> component(nf);
    for (int f = 0; f < nf; ++f) component[f] = f;
    std::function<int(int)> find = [&](int f) { return component[f] == f ? f : component[f] = find(component[f]); };
    std::vector<std::vector<int>> dual_tree(nf);  // per face: its dual tree halfedges
    for (int e : by_doubt) {
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
  }
  out.element = std::move(edge_element);
  out.ok = true;
  return out;
}

SnappedLoops SnappedStartBuilder::loop_images(const Connectivity& sc, const std::vector<std::vector<int>>& loops,
                                              const std::vector<Word>& edge_word, const Word& loop_relator) const {
  SnappedLoops out;
  const ConsistentElements consistent = consistent_edge_elements(sc);
  if (!consistent.ok) {
    out.why = consistent.why;
    return out;
  }
  out.longest_path = consistent.longest_path;
  out.long_paths = consistent.long_paths;
  out.inconsistent_faces = consistent.inconsistent_faces;
  const std::vector<Word>& edge_element = consistent.element;
  auto element_of = [&](int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? edge_element[e] : inverse(edge_element[e]);
  };
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
