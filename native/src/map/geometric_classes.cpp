// Handle classes from short markings of the two surfaces' hyperbolic metrics
// (map/geometric_classes.h; docs/handle_classes.md "Geometric candidates").
#include "surfmap/map/geometric_classes.h"

#include <algorithm>
#include <array>
#include <functional>
#include <cmath>
#include <limits>
#include <numeric>
#include <utility>

#include "surfmap/error.h"
#include "surfmap/topology/mapping_class_search.h"

namespace surfmap {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Σ ℓ(marking(p)) over the probes; +inf when one is not evaluable.
double total_probe_length(const SurfaceGroupLengths& lengths, const GroupMap& marking, const std::vector<Word>& probes,
                          const DehnReducer& reduce) {
  double total = 0;
  for (const Word& p : probes) {
    const double l = lengths.length(reduce(substitute(p, marking)));
    if (!std::isfinite(l)) return kInf;
    total += l;
  }
  return total;
}

// Per marking handle: ℓ(a), ℓ(b), ℓ(ab), ℓ(ab^-1).
std::vector<std::array<double, 4>> handle_lengths(const SurfaceGroupLengths& lengths, const GroupMap& marking,
                                                  const DehnReducer& reduce) {
  std::vector<std::array<double, 4>> out;
  for (int i = 0; i < lengths.genus(); ++i) {
    const int a = 2 * i + 1, b = 2 * i + 2;
    std::array<double, 4> h{};
    const Word words[4] = {{a}, {b}, {a, b}, {a, -b}};
    for (int k = 0; k < 4; ++k) h[k] = lengths.length(reduce(substitute(words[k], marking)));
    out.push_back(h);
  }
  return out;
}

double log_gap(double x, double y) {
  if (!(x > 0) || !(y > 0) || !std::isfinite(x) || !std::isfinite(y)) return 1e6;
  const double d = std::log(x) - std::log(y);
  return d * d;
}

// A mismatch at or below this is a match: every probe keeps its length up
// to the metrics' round-off (the descents stop there; below it the
// mismatch is noise and says nothing about which class is better).
constexpr double kMatched = 1e-12;
// Costs (probe length totals, mismatches) within this fraction of each
// other are equal up to round-off: the lengths come from traces of long
// words and from metrics converged to ~1e-10, and a round-off change of the
// metric moves them by ~1e-11 relative (the sinh / cosh form of the Ricci
// flow's dl/du reordered GeometricClasses.RecoverAKnownMappingClass's
// 4th and 5th classes, 2.29917325847 and ..849, and with them which was
// descended).
constexpr double kTieRelative = 1e-9;

bool tied(double x, double y) {
  if (x <= kMatched && y <= kMatched) return true;
  return std::abs(x - y) <= kTieRelative * std::max(std::abs(x), std::abs(y));
}

// x lower than `best` by more than round-off (a near-tie keeps `best`, the
// earlier one in the caller's fixed order).
bool lower(double x, double best) { return x < best && !tied(x, best); }

// The order of `values` ascending, where values equal up to round-off
// (tied with the first of their run) stay in index order: a round-off
// change of the inputs does not reorder a tie. #values.
std::vector<size_t> order_with_ties(const std::vector<double>& values) {
  std::vector<size_t> order(values.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return values[a] < values[b]; });
  for (size_t begin = 0; begin < order.size();) {
    size_t end = begin + 1;
    while (end < order.size() && tied(values[order[end]], values[order[begin]])) ++end;
    std::sort(order.begin() + begin, order.begin() + end);
    begin = end;
  }
  return order;
}

// `items` permuted into `order` (a permutation of their indices).
template <class T>
void permute(std::vector<T>& items, const std::vector<size_t>& order) {
  std::vector<T> out;
  out.reserve(order.size());
  for (size_t k : order) out.push_back(std::move(items[k]));
  items = std::move(out);
}

}  // namespace

IntMatrix pairing_homology(const std::vector<int>& perm, const std::vector<int>& rot) {
  const int g = static_cast<int>(perm.size());
  IntMatrix P = IntMatrix::Zero(2 * g, 2 * g);
  for (int i = 0; i < g; ++i) {
    const int ta = 2 * perm[i], tb = ta + 1;
    switch (rot[i] % 4) {
      case 0: P(ta, 2 * i) = 1, P(tb, 2 * i + 1) = 1; break;    // a -> a', b -> b'
      case 1: P(tb, 2 * i) = 1, P(ta, 2 * i + 1) = -1; break;   // a -> b', b -> a'^-1
      case 2: P(ta, 2 * i) = -1, P(tb, 2 * i + 1) = -1; break;  // a -> a'^-1, b -> b'^-1
      default: P(tb, 2 * i) = -1, P(ta, 2 * i + 1) = 1; break;  // a -> b'^-1, b -> a'
    }
  }
  return P;
}

std::string pairing_text(const std::vector<int>& perm, const std::vector<int>& rot) {
  static const char* turn[4] = {"", " (quarter turn)", " (half turn)", " (three quarter turns)"};
  std::string s = "marking handles ";
  for (size_t i = 0; i < perm.size(); ++i)
    s += (i ? ", " : "") + std::to_string(i + 1) + "->" + std::to_string(perm[i] + 1) + turn[rot[i] % 4];
  return s;
}

std::vector<Word> marking_probes(int genus) {
  const int n = 2 * genus;
  std::vector<Word> probes;
  for (int j = 1; j <= n; ++j) probes.push_back({j});
  for (int i = 1; i <= n; ++i)
    for (int j = i + 1; j <= n; ++j) probes.push_back({i, j}), probes.push_back({i, -j});
  return probes;
}

std::vector<Word> longer_probes(int genus) {
  const int n = 2 * genus;
  std::vector<Word> probes;
  for (int i = 1; i <= n; ++i)
    for (int j = i + 1; j <= n; ++j)
      for (int k = j + 1; k <= n; ++k)
        for (int sj : {1, -1})
          for (int sk : {1, -1}) probes.push_back({i, sj * j, sk * k});
  return probes;
}

EvaluableProbes evaluable_probes(const GroupMap& marking_map, const DehnReducer& reduce,
                                 const std::function<double(const Word&)>& length_in_x,
                                 const std::vector<Word>& words) {
  EvaluableProbes out;
  for (const Word& p : words.empty() ? marking_probes(static_cast<int>(marking_map.size()) / 2) : words) {
    Word w = reduce(substitute(p, marking_map));
    const double x = length_in_x(w);
    if (!std::isfinite(x) || !(x > 0)) continue;
    out.words.push_back(std::move(w));
    out.lengths.push_back(x);
  }
  return out;
}

namespace {

// One move of a descent: moves[move] composed on the right (map ∘ m: a
// change of the marking / of the source side) or on the left (m ∘ map: the
// target side).
struct DescentStep {
  int move = -1;
  bool left = false;
};

struct Descent {
  GroupMap map;
  double cost = 0;
  std::vector<DescentStep> steps;
  bool stalled = false;  ///< ended at a minimum of single moves and pairs
};

// Greedy descent of `cost` over the moves (right side, and the left side
// when `left_too`): the best single move while one lowers the cost by more
// than `tolerance` relative, else the best pair of moves (when `pairs` and
// the pair neighbourhood has at most `max_pairs` members), at most
// `max_steps` steps, none once the cost is a match (kMatched). Of moves
// whose costs tie up to round-off the first in the moves' order is taken.
Descent descend(GroupMap map, const std::function<double(const GroupMap&)>& cost,
                const std::vector<MappingClassMove>& moves, bool left_too, int max_steps, bool pairs, size_t max_pairs,
                double tolerance, const DehnReducer& reduce) {
  Descent d;
  d.map = std::move(map);
  d.cost = cost(d.map);
  if (!std::isfinite(d.cost)) return d;
  std::vector<DescentStep> singles;
  for (int k = 0; k < static_cast<int>(moves.size()); ++k) {
    singles.push_back({k, false});
    if (left_too) singles.push_back({k, true});
  }
  auto apply = [&](const GroupMap& m, const DescentStep& s) {
    GroupMap next = s.left ? compose(moves[s.move].automorphism.map, m) : compose(m, moves[s.move].automorphism.map);
    next = reduce.each(std::move(next));
    return next;
  };
  pairs = pairs && singles.size() * singles.size() <= max_pairs;
  for (int step = 0; step < max_steps; ++step) {
    if (d.cost <= kMatched) {
      d.stalled = true;
      break;
    }
    const double bar = d.cost * (1 - tolerance);
    double best = bar;
    std::vector<DescentStep> best_steps;
    GroupMap best_map;
    for (const DescentStep& s : singles) {
      GroupMap next = apply(d.map, s);
      const double c = cost(next);
      if (c < bar && (best_steps.empty() || lower(c, best))) best = c, best_steps = {s}, best_map = std::move(next);
    }
    // None: pairs of moves (a minimum of single moves often is not one of
    // pairs: a twist that only pays together with another).
    for (size_t i = 0; i < singles.size() && best_steps.empty() && pairs; ++i) {
      const GroupMap first = apply(d.map, singles[i]);
      for (const DescentStep& s : singles) {
        if (s.left == singles[i].left && s.move == (singles[i].move ^ 1)) continue;  // (its inverse: back)
        GroupMap next = apply(first, s);
        const double c = cost(next);
        if (c < bar && (best_steps.empty() || lower(c, best))) best = c, best_steps = {singles[i], s}, best_map = std::move(next);
      }
      if (i + 1 == singles.size() && !best_steps.empty()) break;
    }
    if (best_steps.empty()) {
      d.stalled = true;
      break;
    }
    d.map = std::move(best_map);
    d.cost = best;
    d.steps.insert(d.steps.end(), best_steps.begin(), best_steps.end());
  }
  return d;
}

}  // namespace

std::vector<Word> handle_probes(int genus) {
  std::vector<Word> probes;
  for (int i = 0; i < genus; ++i) {
    const int a = 2 * i + 1, b = 2 * i + 2;
    probes.insert(probes.end(), {{a}, {b}, {a, b}, {a, -b}});
  }
  return probes;
}

ShortMarking short_marking(const SurfaceGroupLengths& lengths, const ShortMarkingOptions& options) {
  const int g = lengths.genus();
  const DehnReducer reduce(canonical_relator(g));
  const std::vector<Word> probes = handle_probes(g);
  // Twists along each handle's own a_i, b_i: the moves a signed handle
  // permutation maps to each other, so two isometric surfaces whose
  // markings differ by one descend alike (the chain and separating twists,
  // which mix handles, are left to the classes' own descent).
  std::vector<MappingClassMove> moves;
  for (MappingClassMove& m : twist_moves(g, false, false))
    if (m.name.rfind("T(a", 0) == 0 || m.name.rfind("T(b", 0) == 0) moves.push_back(std::move(m));
  ShortMarking out;
  const GroupMap id = identity_map(2 * g);
  out.start_total = total_probe_length(lengths, id, probes, reduce);
  // (phi -> phi ∘ m changes the marking by the mapping class m; the inverse
  // follows as m^-1 ∘ phi^-1.)
  const Descent d = descend(
      id, [&](const GroupMap& m) { return total_probe_length(lengths, m, probes, reduce); }, moves, false,
      options.max_steps, options.pair_moves, options.max_pairs, options.tolerance, reduce);
  out.marking.map = d.map;
  out.marking.inverse = id;
  for (const DescentStep& s : d.steps) {
    out.marking.inverse = compose(moves[s.move].automorphism.inverse, out.marking.inverse);
    out.marking.inverse = reduce.each(std::move(out.marking.inverse));
    out.moves.push_back(moves[s.move].name);
  }
  out.total = d.cost;
  out.stop_reason = !std::isfinite(out.start_total) ? "not evaluable" : d.stalled ? "no shortening move" : "step budget";
  for (int j = 1; j <= 2 * g; ++j) out.generator_lengths.push_back(lengths.length(out.marking.map[j - 1]));
  return out;
}

std::vector<ShortGeodesic> short_geodesics(const SurfaceGroupLengths& lengths, const ShortMarking& marking,
                                           int max_letters, int count) {
  const int n = 2 * lengths.genus();
  const DehnReducer reduce(canonical_relator(lengths.genus()));
  max_letters = std::clamp(max_letters, 1, 3);
  std::vector<Word> words;
  std::vector<int> letters;
  for (int k = 1; k <= n; ++k) letters.push_back(k), letters.push_back(-k);
  // Cyclically reduced words of 1..max_letters letters.
  std::vector<Word> frontier{{}};
  for (int len = 1; len <= max_letters; ++len) {
    std::vector<Word> next;
    for (const Word& w : frontier)
      for (int x : letters) {
        if (!w.empty() && w.back() == -x) continue;
        Word v = w;
        v.push_back(x);
        next.push_back(v);
        const bool power = std::all_of(v.begin(), v.end(), [&](int y) { return y == v.front(); }) && v.size() > 1;
        if ((v.front() != -v.back() || v.size() == 1) && !power) words.push_back(v);  // (not x^k: not primitive)
      }
    frontier = std::move(next);
  }
  std::vector<ShortGeodesic> all;
  for (const Word& w : words) {
    const Word c = cyclic_reduce(reduce(substitute(w, marking.marking.map)));
    if (c.empty()) continue;
    const double l = lengths.length(c);
    if (std::isfinite(l) && l > 0) all.push_back({c, l});
  }
  std::sort(all.begin(), all.end(), [](const ShortGeodesic& x, const ShortGeodesic& y) { return x.length < y.length; });
  std::vector<ShortGeodesic> out;
  for (ShortGeodesic& s : all) {
    if (!out.empty() && std::abs(out.back().length - s.length) <= 1e-6 * s.length) continue;
    out.push_back(std::move(s));
    if (static_cast<int>(out.size()) >= count) break;
  }
  return out;
}

std::vector<GeometricClass> geometric_classes(const SurfaceGroupLengths& source, const ShortMarking& source_marking,
                                              const SurfaceGroupLengths& target, const ShortMarking& target_marking,
                                              const GeometricClassOptions& options) {
  const int g = source.genus();
  if (target.genus() != g)
    throw InputError("geometric_classes: genus " + std::to_string(g) + " against " + std::to_string(target.genus()));
  const DehnReducer reduce(canonical_relator(g));
  const auto hx = handle_lengths(source, source_marking.marking.map, reduce);
  const auto hy = handle_lengths(target, target_marking.marking.map, reduce);
  // 1. Handle pairings (permutation, a/b swapped or not) by the handles' own
  // lengths; a half turn does not change them.
  struct Pairing {
    double cost;
    std::vector<int> perm, swap;
  };
  std::vector<Pairing> pairings;
  const int keep = std::max(1, options.pairings);
  auto pair_cost = [&](int i, int j, bool s) {
    const auto& x = hx[i];
    const auto& y = hy[j];
    return s ? log_gap(x[0], y[1]) + log_gap(x[1], y[0]) + log_gap(x[2], y[3]) + log_gap(x[3], y[2])
             : log_gap(x[0], y[0]) + log_gap(x[1], y[1]) + log_gap(x[2], y[2]) + log_gap(x[3], y[3]);
  };
  if (g > options.enumerated_genus) {
    // Issue 13: all g! 2^g pairings are 8e10 at genus 11 (16 GB before the
    // map was stopped); the `keep` best come from Murty's k-best
    // assignments instead (exact, ties in another order).
    std::vector<std::array<double, 2>> score(static_cast<size_t>(g) * g);
    for (int i = 0; i < g; ++i)
      for (int j = 0; j < g; ++j) score[i * g + j] = {pair_cost(i, j, false), pair_cost(i, j, true)};
    for (const SignedPermutation& sp : best_signed_permutations(g, score, keep)) {
      Pairing p{sp.score, sp.perm, std::vector<int>(g)};
      for (int i = 0; i < g; ++i) p.swap[i] = sp.sign[i] < 0;
      pairings.push_back(std::move(p));
    }
  } else {
    std::vector<int> perm(g);
    std::iota(perm.begin(), perm.end(), 0);
    do {
      for (int bits = 0; bits < (1 << g); ++bits) {
        Pairing p{0, perm, std::vector<int>(g)};
        for (int i = 0; i < g; ++i) {
          p.swap[i] = (bits >> i) & 1;
          p.cost += pair_cost(i, perm[i], p.swap[i]);
        }
        pairings.push_back(std::move(p));
      }
    } while (std::next_permutation(perm.begin(), perm.end()));
  }
  {
    // (Ties up to round-off in enumeration order, so that which pairings
    // are kept does not hang on round-off.)
    std::vector<double> cost;
    for (const Pairing& p : pairings) cost.push_back(p.cost);
    permute(pairings, order_with_ties(cost));
  }
  pairings.resize(std::min<size_t>(pairings.size(), static_cast<size_t>(keep)));
  // 2. Every half-turn pattern of the kept pairings, lifted exactly and
  // ranked by all probes.
  // (Probes not evaluable in X are left out: evaluable_probes.)
  const EvaluableProbes probes =
      evaluable_probes(source_marking.marking.map, reduce, [&](const Word& w) { return source.length(w); });
  const std::vector<Word>& probe_words = probes.words;
  const std::vector<double>& probe_x = probes.lengths;
  // Length evaluations spent (the descents stop at options.length_budget:
  // genus 6 has 144 probes and 88 one-sided twists per step).
  size_t spent = 0;
  auto mismatch = [&](const GroupMap& theta) {
    spent += probe_words.size();
    double m = 0;
    for (size_t k = 0; k < probe_words.size(); ++k) m += log_gap(probe_x[k], target.length(reduce(substitute(probe_words[k], theta))));
    return m;
  };
  std::vector<GeometricClass> out;
  auto class_of = [&](const Pairing& p, const std::vector<int>& half) {
    GeometricClass c;
    c.permutation = p.perm;
    for (int i = 0; i < g; ++i) c.rotation.push_back(p.swap[i] + 2 * half[i]);
    const SurfaceAutomorphism P = lift_symplectic(pairing_homology(c.permutation, c.rotation));
    c.theta = compose(target_marking.marking.map, compose(P.map, source_marking.marking.inverse));
    c.theta = reduce.each(std::move(c.theta));
    c.mismatch = mismatch(c.theta);
    c.description = pairing_text(c.permutation, c.rotation);
    return c;
  };
  for (const Pairing& p : pairings) {
    if (g <= options.enumerated_genus) {
      for (int bits = 0; bits < (1 << g); ++bits) {
        std::vector<int> half(g);
        for (int i = 0; i < g; ++i) half[i] = (bits >> i) & 1;
        out.push_back(class_of(p, half));
      }
      continue;
    }
    // Issue 13: 2^g patterns per pairing (2048 at genus 11, each lifted and
    // measured on 2g(2g-1) + 2g probes) are too many: one handle's half turn
    // at a time while it lowers the mismatch (rounds over the handles).
    std::vector<int> half(g, 0);
    GeometricClass best = class_of(p, half);
    for (bool improved = true; improved;) {
      improved = false;
      for (int i = 0; i < g; ++i) {
        half[i] ^= 1;
        GeometricClass c = class_of(p, half);
        if (lower(c.mismatch, best.mismatch)) best = std::move(c), improved = true;
        else half[i] ^= 1;
      }
    }
    out.push_back(std::move(best));
  }
  // Lowest mismatch first, ties up to round-off in enumeration order (which
  // classes are kept and descend must not hang on round-off).
  auto mismatches = [&] {
    std::vector<double> m;
    for (const GeometricClass& c : out) m.push_back(c.mismatch);
    return m;
  };
  permute(out, order_with_ties(mismatches()));
  out.resize(std::min<size_t>(out.size(), static_cast<size_t>(std::max(1, options.max_classes))));
  // 3. The markings are local minima, not always the same ones on two
  // isometric surfaces, and the lift fixes each class only up to Torelli
  // elements: each class descends on the mismatch itself, by moves on
  // either side (singles, then pairs), towards a class under which every
  // probe keeps its length.
  // The `descents` lowest descend, and every class tied up to round-off with
  // the last of them: which of two tied classes descends must not hang on
  // round-off (RecoverAKnownMappingClass: the 4th and 5th classes tie at
  // 2.2991732585, and only one of them descends to the isometry).
  const std::vector<MappingClassMove> moves = twist_moves(g, false, false);
  size_t descending = std::min(out.size(), static_cast<size_t>(std::max(0, options.descents)));
  while (descending > 0 && descending < out.size() && tied(out[descending].mismatch, out[descending - 1].mismatch))
    ++descending;
  // (A step costs about 2 #moves evaluations of the cost: the budget caps the steps.)
  auto budget_steps = [&](size_t lengths_per_cost) {
    const size_t per_step = 2 * moves.size() * std::max<size_t>(1, lengths_per_cost);
    return static_cast<int>(std::min<size_t>(options.max_steps, (options.length_budget - spent) / per_step + 1));
  };
  for (size_t k = 0; k < descending; ++k) {
    GeometricClass& c = out[k];
    if (c.mismatch <= kMatched) continue;
    if (spent >= options.length_budget) break;
    const Descent d =
        descend(c.theta, mismatch, moves, true, budget_steps(probe_words.size()), true, options.max_pairs, 1e-9, reduce);
    c.theta = d.map;
    c.mismatch = d.cost;
    if (!d.steps.empty()) c.description += ", then " + std::to_string(d.steps.size()) + " twists matching lengths";
  }
  // 4. Classes that match every probe are not told apart by them: on the
  // lopsided genus-2 surface against itself (RecoverAKnownMappingClass) four
  // classes match every probe to 4e-17, and only one is an isometry (the
  // others change longer curves by up to 4e-3 relative); which one a descent
  // reached was decided by its steps below kMatched, i.e. by round-off. Such
  // classes descend again on the probes and the three-letter probes
  // (longer_probes), and come first, ordered by that mismatch.
  const EvaluableProbes longer =
      evaluable_probes(source_marking.marking.map, reduce, [&](const Word& w) { return source.length(w); },
                       longer_probes(g));
  auto refined = [&](const GroupMap& theta) {
    spent += longer.words.size();
    double m = mismatch(theta);
    for (size_t k = 0; k < longer.words.size(); ++k)
      m += log_gap(longer.lengths[k], target.length(reduce(substitute(longer.words[k], theta))));
    return m;
  };
  std::vector<size_t> matched, rest;
  std::vector<double> matched_by, rest_by;
  for (size_t k = 0; k < out.size(); ++k) {
    GeometricClass& c = out[k];
    if (c.mismatch > kMatched || k >= descending) {
      rest.push_back(k), rest_by.push_back(c.mismatch);
      continue;
    }
    double m = refined(c.theta);
    if (m > kMatched && spent < options.length_budget) {
      const Descent d = descend(c.theta, refined, moves, true, budget_steps(probe_words.size() + longer.words.size()),
                                true, options.max_pairs, 1e-9, reduce);
      if (!d.steps.empty())
        c.description += ", then " + std::to_string(d.steps.size()) + " twists matching longer curves";
      c.theta = d.map;
      c.mismatch = mismatch(c.theta);
      m = d.cost;
    }
    matched.push_back(k), matched_by.push_back(m);
  }
  std::vector<size_t> order;
  for (size_t k : order_with_ties(matched_by)) order.push_back(matched[k]);
  for (size_t k : order_with_ties(rest_by)) order.push_back(rest[k]);
  permute(out, order);
  return out;
}

}  // namespace surfmap
