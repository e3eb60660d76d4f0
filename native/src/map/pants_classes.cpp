// Handle classes from short pants decompositions with Fenchel–Nielsen
// coordinates (map/pants_classes.h; docs/handle_classes.md "Pants
// decompositions").
#include "surfmap/map/pants_classes.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <unordered_map>
#include <utility>

#include "surfmap/error.h"
#include "surfmap/topology/mapping_class_search.h"

namespace surfmap {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

int letter_a(int j) { return 2 * j - 1; }  // handle j = 1..g
int letter_b(int j) { return 2 * j; }

Word commutator_of_handle(int j) { return {letter_a(j), letter_b(j), -letter_a(j), -letter_b(j)}; }

// s_j = k_1 ... k_j.
Word separating_word(int j) {
  Word w;
  for (int i = 1; i <= j; ++i) {
    const Word k = commutator_of_handle(i);
    w.insert(w.end(), k.begin(), k.end());
  }
  return w;
}

Word conjugated(const Word& u, const Word& w) { return concat({u, w, inverse(u)}); }

// The automorphism conjugating the letters of handles first..last by u (u a
// word in those handles' letters whose conjugation fixes their product of
// commutators: u = that product, a Dehn twist along the curve it is).
SurfaceAutomorphism conjugate_handles(int genus, int first, int last, const Word& u) {
  SurfaceAutomorphism t{identity_map(2 * genus), identity_map(2 * genus), 1};
  for (int j = first; j <= last; ++j)
    for (int x : {letter_a(j), letter_b(j)}) {
      t.map[x - 1] = conjugated(u, {x});
      t.inverse[x - 1] = conjugated(inverse(u), {x});
    }
  return t;
}

void reduce_all(GroupMap& m, const DehnReducer& reduce) {
  for (Word& w : m) w = reduce(w);
}

double log_gap(double x, double y) {
  if (!(x > 0) || !(y > 0) || !std::isfinite(x) || !std::isfinite(y)) return 1e6;
  const double d = std::log(x) - std::log(y);
  return d * d;
}

// Fixed points of a hyperbolic SU(1,1) element: repelling r, attracting t.
bool axis_endpoints(hyperbolic::Mobius m, Complex* r, Complex* t) {
  const double det = m.determinant();
  if (det > 0.5 && det < 2) m.a /= std::sqrt(det), m.b /= std::sqrt(det);
  const double re = m.a.real(), im = m.a.imag();
  if (!(std::abs(re) > 1 + 1e-12) || std::abs(m.b) == 0) return false;
  // |b|² − Im(a)² = Re(a)² − 1 for determinant 1 (the latter without the
  // cancellation of two large squares).
  const double root = std::sqrt(re * re - 1);
  const Complex bb = std::conj(m.b);
  const Complex z1 = (Complex(0, im) + root) / bb, z2 = (Complex(0, im) - root) / bb;
  // |derivative| = 1 / |b̄ z + ā|²: attracting where |b̄ z + ā| > 1.
  const bool z1_attracts = std::abs(bb * z1 + std::conj(m.a)) > std::abs(bb * z2 + std::conj(m.a));
  *t = z1_attracts ? z1 : z2;
  *r = z1_attracts ? z2 : z1;
  return true;
}

// Handle permutation of an automorphism that maps handles to handles in
// homology (row block of the image of handle i's a); -1 when it mixes.
std::vector<int> handle_permutation(const GroupMap& map, int genus) {
  const IntMatrix H = homology_matrix(map, 2 * genus);
  std::vector<int> perm(genus, -1);
  for (int i = 0; i < genus; ++i)
    for (int t = 0; t < genus; ++t)
      if (H(2 * t, 2 * i) != 0 || H(2 * t + 1, 2 * i) != 0) perm[i] = (perm[i] == -1) ? t : -2;
  return perm;
}

// The transposition of adjacent handles i, i + 1 (1-based), c = k_i:
// (a_i, b_i, a_i+1, b_i+1) -> (c a_i+1 c^-1, c b_i+1 c^-1, a_i, b_i); it
// fixes k_i k_i+1 and so the relator exactly.
GroupMap adjacent_transposition(int genus, int i) {
  GroupMap m = identity_map(2 * genus);
  const Word c = commutator_of_handle(i);
  m[letter_a(i) - 1] = conjugated(c, {letter_a(i + 1)});
  m[letter_b(i) - 1] = conjugated(c, {letter_b(i + 1)});
  m[letter_a(i + 1) - 1] = {letter_a(i)};
  m[letter_b(i + 1) - 1] = {letter_b(i)};
  return m;
}

// Genus 4: handles 1, 2 -> 3, 4 and 3, 4 -> 1, 2 conjugated by
// u = (k_3 k_4)^-1, which maps k1 k2 k3 k4 to itself exactly.
GroupMap half_rotation_genus4() {
  GroupMap m = identity_map(8);
  const Word u = inverse(concat(commutator_of_handle(3), commutator_of_handle(4)));
  for (int j = 1; j <= 2; ++j) {
    m[letter_a(j) - 1] = {letter_a(j + 2)};
    m[letter_b(j) - 1] = {letter_b(j + 2)};
    m[letter_a(j + 2) - 1] = conjugated(u, {letter_a(j)});
    m[letter_b(j + 2) - 1] = conjugated(u, {letter_b(j)});
  }
  return m;
}

// The half turn of handle j: (a, b) -> (ab) (a^-1, b^-1) (ab)^-1, fixing
// [a, b] exactly.
GroupMap half_turn(int genus, int j) {
  GroupMap m = identity_map(2 * genus);
  const Word ab = {letter_a(j), letter_b(j)};
  m[letter_a(j) - 1] = conjugated(ab, {-letter_a(j)});
  m[letter_b(j) - 1] = conjugated(ab, {-letter_b(j)});
  return m;
}

GroupMap power(const SurfaceAutomorphism& t, int n, const DehnReducer& reduce) {
  GroupMap m = identity_map(static_cast<int>(t.map.size()));
  for (int k = 0; k < std::abs(n); ++k) {
    m = compose(m, n > 0 ? t.map : t.inverse);
    reduce_all(m, reduce);
  }
  return m;
}

// Height of the foot of e's axis on the axis r -> t (signed distance along
// it up to a constant: log|z - r| - log|z - t| at the midpoint of the
// endpoints' heights); NaN when e is not hyperbolic.
double axis_foot(Complex r, Complex t, const hyperbolic::Mobius& e) {
  Complex p, q;
  if (!axis_endpoints(e, &p, &q)) return kNaN;
  auto height = [&](Complex z) { return std::log(std::abs(z - r)) - std::log(std::abs(z - t)); };
  return 0.5 * (height(p) + height(q));
}

// Foot of `side`'s axis on `curve`'s axis (twist_coordinate's frame of the
// curve), measured on c^n side c^-n for the first n of 0, ±1, ..., ±8 whose
// matrix there has the trace of side's short conjugate (within 1e-6
// relative: its entries are accurate), and moved back by n ℓ
// (c^n translates its own axis by n ℓ towards the attracting end, where the
// height grows, so foot(side) = foot(c^n side c^-n) - n ℓ exactly); NaN
// when none does.
double side_foot(const SurfaceGroupLengths& lengths, const Word& curve, const Word& side) {
  const double ell = lengths.length(curve);
  if (!std::isfinite(ell) || !(ell > 0)) return kNaN;
  const double side_length = lengths.length(side);
  if (!std::isfinite(side_length) || !(side_length > 0)) return kNaN;
  const double side_half_trace = std::cosh(side_length / 2);
  const DehnReducer reduce(canonical_relator(lengths.genus()));
  for (int k = 0; k <= 16; ++k) {
    const int n = (k % 2 == 1) ? (k + 1) / 2 : -(k / 2);
    Word cn;
    for (int i = 0; i < std::abs(n); ++i) cn.insert(cn.end(), curve.begin(), curve.end());
    if (n < 0) cn = inverse(cn);
    const Word w = reduce(conjugated(cn, side));
    std::vector<hyperbolic::Mobius> m;
    if (!lengths.elements_in_frame_of_first({curve, w}, &m)) continue;
    // (The determinant is round-off for entries beyond 1e8; the trace,
    // compared with the short conjugate's, tells a usable matrix.)
    if (!(std::abs(std::abs(m[1].a.real()) - side_half_trace) <= 1e-6 * side_half_trace)) continue;
    Complex r, t;
    if (!axis_endpoints(m[0], &r, &t)) return kNaN;
    const double foot = axis_foot(r, t, m[1]);
    if (std::isfinite(foot)) return foot - n * ell;
  }
  return kNaN;
}

}  // namespace

std::vector<StandardPantsCurve> standard_pants_curves(int genus) {
  if (genus < 2) throw InputError("standard_pants_curves: genus " + std::to_string(genus) + " < 2");
  const int g = genus;
  const DehnReducer reduce(canonical_relator(g));
  std::vector<StandardPantsCurve> out;
  for (int j = 1; j <= g; ++j) {
    StandardPantsCurve c;
    c.name = "a" + std::to_string(j);
    c.curve = {letter_a(j)};
    c.side1 = commutator_of_handle(j);
    c.side2 = reduce(conjugated({-letter_b(j)}, commutator_of_handle(j)));  // the pants across a_j
    c.twist = {identity_map(2 * g), identity_map(2 * g), 1};
    c.twist.map[letter_b(j) - 1] = {letter_b(j), letter_a(j)};  // T(a_j): b_j -> b_j a_j
    c.twist.inverse[letter_b(j) - 1] = {letter_b(j), -letter_a(j)};
    out.push_back(std::move(c));
  }
  for (int j = 1; j < g; ++j) {
    StandardPantsCurve c;
    c.name = "s" + std::to_string(j);
    c.curve = separating_word(j);
    c.side1 = j == 1 ? Word{letter_a(1)} : commutator_of_handle(j);
    c.side2 = j + 1 < g ? commutator_of_handle(j + 1) : Word{letter_a(g)};
    c.twist = conjugate_handles(g, 1, j, c.curve);
    out.push_back(std::move(c));
  }
  for (int j = 2; j < g; ++j) {
    StandardPantsCurve c;
    c.name = "k" + std::to_string(j);
    c.curve = commutator_of_handle(j);
    c.side1 = {letter_a(j)};
    c.side2 = separating_word(j - 1);
    c.twist = conjugate_handles(g, j, j, c.curve);
    out.push_back(std::move(c));
  }
  return out;
}

std::vector<PantsSymmetry> pants_symmetries(int genus) {
  const int g = genus;
  const DehnReducer reduce(canonical_relator(g));
  std::vector<GroupMap> generators{adjacent_transposition(g, 1)};
  if (g >= 3) generators.push_back(adjacent_transposition(g, g - 1));
  if (g == 4) generators.push_back(half_rotation_genus4());
  // Closure under composition, one automorphism per handle permutation.
  std::map<std::vector<int>, GroupMap> found;
  std::vector<GroupMap> frontier{identity_map(2 * g)};
  found[handle_permutation(frontier[0], g)] = frontier[0];
  while (!frontier.empty()) {
    std::vector<GroupMap> next;
    for (const GroupMap& m : frontier)
      for (const GroupMap& s : generators) {
        GroupMap c = compose(m, s);
        reduce_all(c, reduce);
        const std::vector<int> perm = handle_permutation(c, g);
        if (found.count(perm)) continue;
        found[perm] = c;
        next.push_back(std::move(c));
      }
    frontier = std::move(next);
  }
  std::vector<PantsSymmetry> out;
  for (const auto& [perm, m] : found)
    for (int bits = 0; bits < (1 << g); ++bits) {
      PantsSymmetry s;
      s.permutation = perm;
      GroupMap turns = identity_map(2 * g);
      for (int j = 1; j <= g; ++j) {
        s.half_turn.push_back((bits >> (j - 1)) & 1);
        if (s.half_turn.back()) turns = compose(turns, half_turn(g, j));
      }
      s.map = compose(m, turns);
      reduce_all(s.map, reduce);
      out.push_back(std::move(s));
    }
  return out;
}

double twist_coordinate(const SurfaceGroupLengths& lengths, const Word& curve, const Word& side1, const Word& side2) {
  std::vector<hyperbolic::Mobius> m;
  if (!lengths.elements_in_frame_of_first({curve, side1, side2}, &m)) {
    // A side element whose axis lies far along the curve's axis (its word a
    // long conjugate) has entries beyond double precision in the curve's
    // frame. The feet are then measured per side (the frame depends on the
    // curve alone, so it is the same), through conjugates by curve powers.
    const double f1 = side_foot(lengths, curve, side1), f2 = side_foot(lengths, curve, side2);
    return f2 - f1;
  }
  const hyperbolic::Mobius &c = m[0], &e1 = m[1], &e2 = m[2];
  Complex r, t;
  if (!axis_endpoints(c, &r, &t)) return kNaN;
  return axis_foot(r, t, e2) - axis_foot(r, t, e1);
}

std::vector<PantsCurve> pants_coordinates(const SurfaceGroupLengths& lengths, const GroupMap& marking) {
  const DehnReducer reduce(canonical_relator(lengths.genus()));
  std::vector<PantsCurve> out;
  for (const StandardPantsCurve& s : standard_pants_curves(lengths.genus())) {
    PantsCurve c;
    c.name = s.name;
    c.word = reduce(substitute(s.curve, marking));
    c.length = lengths.length(c.word);
    c.twist = twist_coordinate(lengths, c.word, reduce(substitute(s.side1, marking)), reduce(substitute(s.side2, marking)));
    out.push_back(std::move(c));
  }
  return out;
}

namespace {

// The shift of curve c's twist coordinate under one Dehn twist along it
// (±ℓ), measured for `outer` ∘ T_c against `outer`; NaN when not evaluable.
double twist_shift(const SurfaceGroupLengths& lengths, const GroupMap& outer, const StandardPantsCurve& s,
                   const DehnReducer& reduce, double* at_outer) {
  auto tw = [&](const GroupMap& m) {
    return twist_coordinate(lengths, reduce(substitute(s.curve, m)), reduce(substitute(s.side1, m)),
                            reduce(substitute(s.side2, m)));
  };
  *at_outer = tw(outer);
  GroupMap twisted = compose(outer, s.twist.map);
  reduce_all(twisted, reduce);
  return tw(twisted) - *at_outer;
}

}  // namespace

namespace {

// Handle j's curve that becomes its pants curve: a (choice 0), b (1: the
// quarter turn a -> a b a^-1, b -> a^-1), a b (2: a -> a b), a b^-1 (3:
// a -> a b^-1); each fixes [a, b] exactly, so the other curves stay.
SurfaceAutomorphism handle_curve_choice(int genus, int j, int choice) {
  SurfaceAutomorphism m{identity_map(2 * genus), identity_map(2 * genus), 1};
  const int a = letter_a(j), b = letter_b(j);
  switch (choice) {
    case 1:
      m.map[a - 1] = {a, b, -a}, m.map[b - 1] = {-a};
      m.inverse[a - 1] = {-b}, m.inverse[b - 1] = {b, a, -b};
      break;
    case 2: m.map[a - 1] = {a, b}, m.inverse[a - 1] = {a, -b}; break;
    case 3: m.map[a - 1] = {a, -b}, m.inverse[a - 1] = {a, b}; break;
    default: break;
  }
  return m;
}

}  // namespace

namespace {

PantsDecomposition descend_pants(const SurfaceGroupLengths& lengths, const SurfaceAutomorphism& start,
                                 const std::function<double(const GroupMap&)>& total_of,
                                 const std::vector<StandardPantsCurve>& standard,
                                 const PantsDecompositionOptions& options, const DehnReducer& reduce) {
  const int g = lengths.genus();
  PantsDecomposition out;
  out.marking = start;
  out.start_total = out.total = total_of(out.marking.map);
  out.stop_reason = "step budget";
  if (!std::isfinite(out.total)) {
    out.stop_reason = "not evaluable";
    out.curves = pants_coordinates(lengths, out.marking.map);
    return out;
  }
  // Descent: the best single twist (right side: a change of marking) while
  // it shortens the curves.
  const std::vector<MappingClassMove> moves = twist_moves(g, false, false);
  // (Depth d: sequences of d moves without a move followed by its inverse,
  // tried when no shorter sequence shortens: every sequence while there are
  // at most options.max_neighbourhood, else the `beam` lowest sequences of
  // depth d − 1 extended by every move.)
  struct Sequence {
    std::vector<int> moves;
    GroupMap map;
    double total;
  };
  for (int step = 0; step < options.max_steps; ++step) {
    double best = out.total * (1 - options.tolerance);
    std::vector<int> best_seq;
    GroupMap best_map;
    std::vector<Sequence> level{{{}, out.marking.map, out.total}};
    for (int depth = 1; depth <= options.max_depth && best_seq.empty(); ++depth) {
      if (level.size() * moves.size() > options.max_neighbourhood) {
        std::partial_sort(level.begin(), level.begin() + std::min<size_t>(level.size(), options.beam), level.end(),
                          [](const Sequence& x, const Sequence& y) { return x.total < y.total; });
        level.resize(std::min<size_t>(level.size(), options.beam));
      }
      std::vector<Sequence> next_level;
      for (const Sequence& q : level)
        for (size_t k = 0; k < moves.size(); ++k) {
          if (!q.moves.empty() && static_cast<int>(k) == (q.moves.back() ^ 1)) continue;  // (back)
          Sequence n{q.moves, compose(q.map, moves[k].automorphism.map), 0};
          reduce_all(n.map, reduce);
          n.moves.push_back(static_cast<int>(k));
          n.total = total_of(n.map);
          if (n.total < best) best = n.total, best_seq = n.moves, best_map = n.map;
          next_level.push_back(std::move(n));
        }
      level = std::move(next_level);
    }
    if (best_seq.empty()) {
      out.stop_reason = "no shortening move";
      break;
    }
    out.marking.map = std::move(best_map);
    for (int m : best_seq) {
      out.marking.inverse = compose(moves[m].automorphism.inverse, out.marking.inverse);
      reduce_all(out.marking.inverse, reduce);
      out.moves.push_back(moves[m].name);
    }
    out.total = best;
  }
  // Twist normalisation: T_c^n with n = −round(τ / shift) brings τ(c) into
  // [−ℓ/2, ℓ/2] (the twists along disjoint curves commute and leave the
  // other curves' coordinates alone).
  for (const StandardPantsCurve& s : standard) {
    double tau = 0;
    const double shift = twist_shift(lengths, out.marking.map, s, reduce, &tau);
    if (!std::isfinite(shift) || !std::isfinite(tau) || std::abs(shift) < 1e-9) continue;
    const int n = -static_cast<int>(std::lround(std::clamp(tau / shift, -50.0, 50.0)));
    if (n == 0) continue;
    SurfaceAutomorphism tn{power(s.twist, n, reduce), power(s.twist, -n, reduce), std::abs(n)};
    out.marking.map = compose(out.marking.map, tn.map);
    out.marking.inverse = compose(tn.inverse, out.marking.inverse);
    reduce_all(out.marking.map, reduce);
    reduce_all(out.marking.inverse, reduce);
    out.normalising_twists += std::abs(n);
  }
  out.curves = pants_coordinates(lengths, out.marking.map);
  return out;
}

}  // namespace

std::vector<CurveTwist> short_curve_twists(const SurfaceGroupLengths& lengths, const ShortMarking& marking,
                                           const PantsDecomposition* pants) {
  const int g = lengths.genus();
  const DehnReducer reduce(canonical_relator(g));
  std::vector<CurveTwist> out;
  // M T M^-1 for a marking M (standard letter -> caller word, both ways) and
  // a twist T in the standard letters.
  auto add = [&](const std::string& name, const SurfaceAutomorphism& m, const Word& curve,
                 const SurfaceAutomorphism& twist) {
    CurveTwist c;
    c.name = name;
    c.curve = reduce(substitute(curve, m.map));
    c.twist.map = compose(m.map, compose(twist.map, m.inverse));
    c.twist.inverse = compose(m.map, compose(twist.inverse, m.inverse));
    reduce_all(c.twist.map, reduce), reduce_all(c.twist.inverse, reduce);
    c.twist.moves = 1;
    for (const CurveTwist& e : out)
      if (e.twist.map == c.twist.map || e.twist.map == c.twist.inverse) return;  // (the same curve, either way round)
    c.length = lengths.length(c.curve);
    out.push_back(std::move(c));
  };
  const std::vector<StandardPantsCurve> standard = standard_pants_curves(g);
  for (int j = 1; j <= g; ++j) {
    add("marking a" + std::to_string(j), marking.marking, {letter_a(j)}, standard[j - 1].twist);
    // T(b_j): a_j -> a_j b_j^-1 (the handedness of twist_moves' T(b_j)).
    SurfaceAutomorphism tb{identity_map(2 * g), identity_map(2 * g), 1};
    tb.map[letter_a(j) - 1] = {letter_a(j), -letter_b(j)};
    tb.inverse[letter_a(j) - 1] = {letter_a(j), letter_b(j)};
    add("marking b" + std::to_string(j), marking.marking, {letter_b(j)}, tb);
  }
  if (pants)
    for (const StandardPantsCurve& s : standard) add("pants " + s.name, pants->marking, s.curve, s.twist);
  std::stable_sort(out.begin(), out.end(), [](const CurveTwist& x, const CurveTwist& y) {
    const bool fx = std::isfinite(x.length), fy = std::isfinite(y.length);
    return fx != fy ? fx : fx && x.length < y.length;
  });
  return out;
}

PantsDecomposition short_pants_decomposition(const SurfaceGroupLengths& lengths, const ShortMarking& start,
                                             const PantsDecompositionOptions& options) {
  const int g = lengths.genus();
  const DehnReducer reduce(canonical_relator(g));
  const std::vector<StandardPantsCurve> standard = standard_pants_curves(g);
  // Curve lengths remembered by word (exact: the length computed for that
  // very word). A twist leaves the curves without its letters alone, and the
  // descent's sequences and starts share most curves; at most 2^22 letters
  // of keys are kept (then it starts afresh).
  std::unordered_map<Word, double, WordHash> length_of;
  size_t memo_letters = 0;
  auto curve_length = [&](const Word& w) {
    const auto it = length_of.find(w);
    if (it != length_of.end()) return it->second;
    const double l = lengths.length(w);
    if (memo_letters + w.size() > (size_t{1} << 22)) length_of.clear(), memo_letters = 0;
    length_of.emplace(w, l);
    memo_letters += w.size();
    return l;
  };
  auto total_of = [&](const GroupMap& m) {
    double total = 0;
    for (const StandardPantsCurve& s : standard) {
      const double l = curve_length(reduce(substitute(s.curve, m)));
      if (!std::isfinite(l)) return std::numeric_limits<double>::infinity();
      total += l;
    }
    return total;
  };
  // Starts: the short marking with every choice of each handle's pants
  // curve among its probe curves a, b, ab, ab^-1 (4^g, up to 4^4), ranked
  // by their total; the `starts` lowest descend.
  std::vector<std::pair<double, SurfaceAutomorphism>> starts;
  const int choices = g <= 4 ? 1 << (2 * g) : 1;
  for (int code = 0; code < choices; ++code) {
    SurfaceAutomorphism m = start.marking;
    for (int j = 1; j <= g; ++j) {
      const SurfaceAutomorphism c = handle_curve_choice(g, j, (code >> (2 * (j - 1))) & 3);
      m.map = compose(m.map, c.map);
      m.inverse = compose(c.inverse, m.inverse);
    }
    reduce_all(m.map, reduce), reduce_all(m.inverse, reduce);
    starts.push_back({total_of(m.map), std::move(m)});
  }
  std::stable_sort(starts.begin(), starts.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  starts.resize(std::min<size_t>(starts.size(), static_cast<size_t>(std::max(1, options.starts))));
  PantsDecomposition best;
  for (const auto& [total, marking] : starts) {
    PantsDecomposition d = descend_pants(lengths, marking, total_of, standard, options, reduce);
    d.start_total = total_of(start.marking.map);
    if (best.curves.empty() || d.total < best.total) best = std::move(d);
  }
  return best;
}

std::vector<PantsClass> pants_classes(const SurfaceGroupLengths& source, const PantsDecomposition& source_pants,
                                      const SurfaceGroupLengths& target, const PantsDecomposition& target_pants,
                                      const PantsClassOptions& options) {
  const int g = source.genus();
  if (target.genus() != g)
    throw InputError("pants_classes: genus " + std::to_string(g) + " against " + std::to_string(target.genus()));
  const DehnReducer reduce(canonical_relator(g));
  const std::vector<StandardPantsCurve> standard = standard_pants_curves(g);
  const std::vector<PantsSymmetry> symmetries = pants_symmetries(g);
  const GroupMap& mx = source_pants.marking.map;
  const GroupMap& mx_inv = source_pants.marking.inverse;
  const GroupMap& my = target_pants.marking.map;
  // 1. Handle permutations ranked by the pants curves' lengths (half turns
  // do not change them).
  std::vector<std::pair<double, std::vector<int>>> ranked;
  for (const PantsSymmetry& s : symmetries) {
    if (std::any_of(s.half_turn.begin(), s.half_turn.end(), [](int h) { return h != 0; })) continue;
    double score = 0;
    for (size_t c = 0; c < standard.size(); ++c)
      score += log_gap(source_pants.curves[c].length,
                       target.length(reduce(substitute(substitute(standard[c].curve, s.map), my))));
    ranked.push_back({score, s.permutation});
  }
  std::stable_sort(ranked.begin(), ranked.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  ranked.resize(std::min<size_t>(ranked.size(), static_cast<size_t>(std::max(1, options.permutations))));
  // Probes of the source decomposition's marking, for the final ranking
  // (those not evaluable in X left out: evaluable_probes).
  const EvaluableProbes probes = evaluable_probes(mx, reduce, [&](const Word& w) { return source.length(w); });
  const std::vector<Word>& probe_words = probes.words;
  const std::vector<double>& probe_x = probes.lengths;
  std::vector<PantsClass> out;
  for (const auto& [score, perm] : ranked)
    for (const PantsSymmetry& s : symmetries) {
      if (s.permutation != perm) continue;
      PantsClass pc;
      pc.symmetry = s;
      // 2. Twists matching the twist coordinates, curve by curve.
      GroupMap twists = identity_map(2 * g);
      for (size_t c = 0; c < standard.size(); ++c) {
        GroupMap outer = compose(my, compose(s.map, twists));
        reduce_all(outer, reduce);
        double tau_y = 0;
        const double shift = twist_shift(target, outer, standard[c], reduce, &tau_y);
        const double tau_x = source_pants.curves[c].twist;
        int n = 0;
        if (std::isfinite(shift) && std::isfinite(tau_y) && std::isfinite(tau_x) && std::abs(shift) > 1e-9)
          n = static_cast<int>(std::lround(std::clamp((tau_x - tau_y) / shift, -50.0, 50.0)));
        pc.twists.push_back(n);
        if (n != 0) {
          twists = compose(twists, power(standard[c].twist, n, reduce));
          reduce_all(twists, reduce);
        }
      }
      GroupMap outer = compose(my, compose(s.map, twists));
      reduce_all(outer, reduce);
      const std::vector<PantsCurve> images = pants_coordinates(target, outer);
      for (size_t c = 0; c < standard.size(); ++c) {
        pc.length_mismatch += log_gap(source_pants.curves[c].length, images[c].length);
        const double d = (source_pants.curves[c].twist - images[c].twist) / source_pants.curves[c].length;
        pc.twist_mismatch += std::isfinite(d) ? d * d : 1e6;
      }
      pc.theta = compose(outer, mx_inv);
      reduce_all(pc.theta, reduce);
      for (size_t k = 0; k < probe_words.size(); ++k)
        pc.mismatch += log_gap(probe_x[k], target.length(reduce(substitute(probe_words[k], pc.theta))));
      static const char* turn[2] = {"", " (half turn)"};
      pc.description = "pants handles ";
      for (int i = 0; i < g; ++i)
        pc.description += (i ? ", " : "") + std::to_string(i + 1) + "->" + std::to_string(s.permutation[i] + 1) +
                          turn[s.half_turn[i]];
      std::string tw;
      for (size_t c = 0; c < standard.size(); ++c)
        if (pc.twists[c] != 0)
          tw += (tw.empty() ? "" : ", ") + standard[c].name + (pc.twists[c] > 0 ? " +" : " ") + std::to_string(pc.twists[c]);
      if (!tw.empty()) pc.description += "; twists " + tw;
      out.push_back(std::move(pc));
    }
  std::stable_sort(out.begin(), out.end(), [](const PantsClass& x, const PantsClass& y) { return x.mismatch < y.mismatch; });
  out.resize(std::min<size_t>(out.size(), static_cast<size_t>(std::max(1, options.max_classes))));
  return out;
}

}  // namespace surfmap
