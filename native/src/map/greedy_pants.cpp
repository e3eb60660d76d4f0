// The greedy short pants decomposition (map/greedy_pants.h;
// docs/handle_classes.md "Greedy pants decomposition").
#include "surfmap/map/greedy_pants.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <unordered_map>
#include <utility>

#include "../seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/topology/mapping_class_search.h"

namespace surfmap {

namespace {

using hyperbolic::Complex;
using hyperbolic::Mobius;

/// Ends of axes closer than this to the axis of U (in its chart) count as
/// its ends: a lift ending there crosses it, if at all, some 14 units away
/// along it, where a U-translate of a nearer lift is counted instead.
constexpr double kEndTolerance = 1e-6;

/// The two fixed points on the unit circle of a hyperbolic element; false
/// when it is not hyperbolic (|Re a| <= 1 after normalisation).
bool axis_ends(Mobius m, Complex* e1, Complex* e2) {
  const double det = m.determinant();
  if (!(det > 0)) return false;
  m.a /= std::sqrt(det), m.b /= std::sqrt(det);
  const double re = m.a.real();
  if (!(std::abs(re) > 1 + 1e-12) || std::abs(m.b) == 0) return false;
  const double root = std::sqrt(re * re - 1);
  const Complex bb = std::conj(m.b), im(0, m.a.imag());
  *e1 = (im + root) / bb, *e2 = (im - root) / bb;
  *e1 /= std::abs(*e1), *e2 /= std::abs(*e2);
  return true;
}

/// The map K of the disk taking the axis with ends r, t onto the real
/// diameter (t -> 1, r -> -1) and the axis point nearest the origin to 0.
Mobius axis_chart(Complex r, Complex t) {
  const Complex bis = r + t;
  Complex foot(0, 0);
  if (std::abs(bis) > 1e-12) {
    // Half the angle 2α between r and t seen from 0: the orthogonal circle
    // has its centre at sec α on the bisector and radius tan α.
    const double cos_alpha = std::abs(bis) / 2, alpha = std::acos(std::min(1.0, cos_alpha));
    foot = (bis / std::abs(bis)) * (1 / std::cos(alpha) - std::tan(alpha));
  }
  const Mobius c = Mobius::centring(foot);
  const Complex tc = c(t);
  return Mobius::rotation(-std::arg(tc)) * c;
}

/// Position along the real diameter (signed distance from 0) where the
/// geodesic with ends p, q (on the unit circle) crosses it; false when it
/// does not cross (both ends on one side) or shares an end with it.
bool crossing_on_diameter(Complex p, Complex q, double* tau) {
  if (!(p.imag() * q.imag() < 0)) return false;
  if (std::abs(p.imag()) < kEndTolerance || std::abs(q.imag()) < kEndTolerance) return false;
  // Upper half-plane w = i (1 + z) / (1 − z): the diameter is the imaginary
  // axis (0 -> i), an end e^{iα} goes to −cot(α/2); the crossing is at
  // height sqrt(−u1 u2), at distance log of it from i.
  const double u1 = -1 / std::tan(std::arg(p) / 2), u2 = -1 / std::tan(std::arg(q) / 2);
  if (!(u1 * u2 < 0)) return false;
  *tau = 0.5 * std::log(-u1 * u2);
  return true;
}

bool is_proper_power(const Word& w) {
  const size_t n = w.size();
  for (size_t p = 1; p < n; ++p) {
    if (n % p) continue;
    bool periodic = true;
    for (size_t i = p; i < n && periodic; ++i) periodic = w[i] == w[i - p];
    if (periodic) return true;
  }
  return false;
}

/// The least of the cyclic rotations of w and of w^-1 (one name per
/// unoriented cyclic word).
Word cyclic_name(const Word& w) {
  Word best = w;
  for (const Word& x : {w, inverse(w)})
    for (size_t r = 0; r < x.size(); ++r) {
      Word y(x.begin() + r, x.end());
      y.insert(y.end(), x.begin(), x.begin() + r);
      best = std::min(best, y);
    }
  return best;
}

/// Cyclically reduced words of 1..max_letters letters, one per unoriented
/// cyclic word, no proper powers.
std::vector<Word> candidate_words(int genus, int max_letters) {
  std::set<Word> names;
  for (const Word& v : reduced_words_up_to(genus, max_letters))
    if (!v.empty() && v.front() != -v.back() && !is_proper_power(v)) names.insert(cyclic_name(v));
  return {names.begin(), names.end()};
}

Word prefix(const Word& w, size_t k) { return Word(w.begin(), w.begin() + k); }

/// A short cyclic word for the conjugacy class of w: free cyclic reduction
/// and Dehn reduction of the word and of its half-turned rotations (as
/// SurfaceGroupLengths does for side words), so that a curve given by a far
/// conjugate (the caterpillar's words in the marking's letters) gets a word
/// whose lifts the conjugator ball reaches.
Word short_cyclic_word(Word w, const DehnReducer& reduce) {
  w = cyclic_reduce(reduce(w));
  for (int guard = 0; guard < 64 && w.size() >= 2; ++guard) {
    const size_t h = w.size() / 2;
    Word turned(w.begin() + static_cast<long>(h), w.end());
    turned.insert(turned.end(), w.begin(), w.begin() + static_cast<long>(h));
    turned = cyclic_reduce(reduce(turned));
    if (turned.size() >= w.size()) break;
    w = std::move(turned);
  }
  return w;
}

}  // namespace

namespace {

/// curve_intersection with what every call of one surface and marking
/// shares made once: the relator's reducer and the conjugator balls.
class IntersectionCounter {
 public:
  IntersectionCounter(const SurfaceGroupLengths& lengths, const SurfaceAutomorphism& marking)
      : lengths_(lengths), marking_(marking), reduce_(canonical_relator(lengths.genus())) {}

  const DehnReducer& reduce() const { return reduce_; }

  CurveIntersection operator()(const Word& u, const Word& v, const CurveIntersectionOptions& options) {
    CurveIntersection out;
    if (u.empty() || v.empty()) return out;
    auto caller = [&](const Word& w) { return reduce_(substitute(w, marking_.map)); };
    // Every lift is a word of its own, evaluated with U in the frame of u
    // (SurfaceGroupLengths::elements_in_frame_of_first): products of the
    // marking's generators as matrices lose every digit (the handles'
    // generators are loops at one base joined by tails of 15 units and more).
    const Word uc = caller(u), vc = caller(v);
    std::vector<Mobius> m;
    if (!lengths_.elements_in_frame_of_first({uc}, &m)) return out;
    const Mobius U = m[0];
    Complex r, t;
    if (!axis_ends(U, &r, &t)) return out;
    const double ell = 2 * std::acosh(std::abs(U.a.real()) / std::sqrt(U.determinant()));
    if (!(ell > 1e-9)) return out;
    const Mobius K = axis_chart(r, t);
    int radius = options.radius;
    while (radius > 0 && u.size() * v.size() * ball(radius).size() > options.max_lifts) --radius;
    const std::vector<Word>& conjugators = ball(radius);
    const bool self = u == v;
    std::set<Word> seen;
    std::vector<double> points;
    for (size_t i = 0; i < u.size(); ++i)
      for (const Word& h : conjugators)
        for (size_t k = 0; k < v.size(); ++k) {
          const Word c = caller(concat({prefix(u, i), h, prefix(v, k)}));
          const Word lift = reduce_(concat({c, vc, inverse(c)}));
          if (!seen.insert(lift).second) continue;
          if (!lengths_.elements_in_frame_of_first({uc, lift}, &m)) continue;
          Complex e1, e2;
          if (!axis_ends(m[1], &e1, &e2)) continue;
          e1 = K(e1), e2 = K(e2);
          // The axis of U itself (ends ±1, to round-off: a lift there with
          // ends off by round-off would otherwise count as crossing).
          const bool on_axis = std::abs(e1.imag()) < kEndTolerance && std::abs(e2.imag()) < kEndTolerance &&
                               e1.real() * e2.real() < 0;
          if (on_axis) {
            if (!self) out.same_curve = true;
            continue;
          }
          double tau;
          if (!crossing_on_diameter(e1, e2, &tau)) continue;
          if (options.stop_at_first_crossing) {
            out.crossings = 1;
            return out;
          }
          double s = std::fmod(tau, ell);
          if (s < 0) s += ell;
          points.push_back(s);
        }
    // Crossing points modulo U: the same point reached by several lifts
    // comes out within round-off, so points are merged within 1e-5 of the
    // period (at least 1e-5), across the period's end too.
    std::sort(points.begin(), points.end());
    const double tol = 1e-5 * std::max(1.0, ell);
    int clusters = 0;
    for (size_t k = 0; k < points.size(); ++k)
      if (k == 0 || points[k] - points[k - 1] > tol) ++clusters;
    if (clusters > 1 && points.back() - points.front() > ell - tol) --clusters;
    out.crossings = clusters;
    return out;
  }

 private:
  const std::vector<Word>& ball(int radius) {
    if (static_cast<int>(balls_.size()) <= radius) balls_.resize(radius + 1);
    if (balls_[radius].empty()) balls_[radius] = reduced_words_up_to(lengths_.genus(), radius);
    return balls_[radius];
  }

  const SurfaceGroupLengths& lengths_;
  const SurfaceAutomorphism& marking_;
  DehnReducer reduce_;
  std::vector<std::vector<Word>> balls_;
};

}  // namespace

CurveIntersection curve_intersection(const SurfaceGroupLengths& lengths, const SurfaceAutomorphism& marking,
                                     const Word& u, const Word& v, const CurveIntersectionOptions& options) {
  IntersectionCounter count(lengths, marking);
  return count(u, v, options);
}

namespace {

/// Curves of equal length (1e-7 relative) that no lift shows to be one: the
/// same curve when they also meet every marking generator equally often. A
/// word of the marking and the caterpillar's word for one curve can be far
/// conjugates whose lifts the conjugator ball does not bring together; two
/// curves exchanged by a symmetry (the fertility's two handles of length
/// 1.04) meet the generators differently.
bool same_by_length_and_generators(IntersectionCounter& count, int genus, const GreedyPantsCurve& x,
                                   const GreedyPantsCurve& y, CurveIntersectionOptions options) {
  if (!(std::abs(x.length - y.length) <= 1e-7 * y.length)) return false;
  options.stop_at_first_crossing = false;  // (counts compared, not verdicts)
  for (int j = 1; j <= 2 * genus; ++j) {
    const int ix = count({j}, x.marking_word, options).crossings;
    const int iy = count({j}, y.marking_word, options).crossings;
    if (ix < 0 || ix != iy) return false;
  }
  return true;
}

/// Every closed geodesic shorter than 4 arcsinh(1) = 2 log(3 + 2√2) ≈ 3.5255
/// on a hyperbolic surface is simple (the shortest closed geodesic with a
/// self-intersection is at least that long, a known bound, attained by the
/// figure eight of the thrice-punctured sphere).
const double kShortestNonSimple = 4 * std::asinh(1.0);

/// Collar lemma: two crossing simple closed geodesics of lengths ℓ1, ℓ2 each
/// cross the other's collar, so sinh(ℓ1/2) sinh(ℓ2/2) >= 1; below that
/// they are disjoint.
bool disjoint_by_collar_lemma(double l1, double l2) { return std::sinh(l1 / 2) * std::sinh(l2 / 2) < 1 - 1e-9; }

}  // namespace

GreedyPantsDecomposition greedy_pants_decomposition(const SurfaceGroupLengths& lengths, const ShortMarking& marking,
                                                    const std::vector<Word>& extra_curves,
                                                    const GreedyPantsOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  GreedyPantsDecomposition out;
  const int genus = lengths.genus(), wanted = 3 * genus - 3;
  if (genus < 2) throw InputError("greedy_pants_decomposition: genus " + std::to_string(genus) + " < 2");
  const int letters = options.max_letters > 0 ? options.max_letters : genus == 2 ? 4 : genus <= 4 ? 3 : 2;
  IntersectionCounter count(lengths, marking.marking);
  const DehnReducer& reduce = count.reduce();
  std::vector<Word> words = candidate_words(genus, letters);
  for (const Word& c : extra_curves) {
    const Word w = short_cyclic_word(substitute(c, marking.marking.inverse), reduce);
    if (!w.empty()) words.push_back(w);
  }
  std::vector<GreedyPantsCurve> listed;
  for (const Word& w : words) {
    GreedyPantsCurve c{w, reduce(substitute(w, marking.marking.map)), 0};
    c.length = lengths.length(c.word);
    if (!std::isfinite(c.length)) {
      ++out.not_evaluable;
      continue;
    }
    if (c.length > 1e-9) listed.push_back(std::move(c));
  }
  std::stable_sort(listed.begin(), listed.end(),
                   [](const GreedyPantsCurve& x, const GreedyPantsCurve& y) { return x.length < y.length; });
  out.candidates = listed.size();
  CurveIntersectionOptions verdict = options.intersection;
  verdict.stop_at_first_crossing = verdict.stop_at_first_crossing || options.shortcuts;
  for (const GreedyPantsCurve& c : listed) {
    if (static_cast<int>(out.curves.size()) == wanted || out.examined == options.max_examined) break;
    ++out.examined;
    // Against the chosen curves first (short words: cheaper than the
    // candidate against itself, and most candidates fail here).
    bool ok = true;
    for (const GreedyPantsCurve& s : out.curves) {
      const bool may_be_same = std::abs(s.length - c.length) <= 1e-7 * c.length;
      if (options.shortcuts && !may_be_same && disjoint_by_collar_lemma(s.length, c.length)) continue;
      ++out.intersection_tests;
      const CurveIntersection x = count(s.marking_word, c.marking_word, verdict);
      const bool same =
          x.same_curve || (x.crossings == 0 && may_be_same && same_by_length_and_generators(count, genus, s, c, verdict));
      if (same) {
        ++out.duplicates, ok = false;
      } else if (x.crossings != 0) {
        ++(x.crossings < 0 ? out.not_evaluable : out.crossing), ok = false;
      }
      if (!ok) break;
    }
    if (!ok) continue;
    if (!(options.shortcuts && c.length < kShortestNonSimple)) {
      ++out.intersection_tests;
      const CurveIntersection self = count(c.marking_word, c.marking_word, verdict);
      if (self.crossings != 0) {
        ++(self.crossings < 0 ? out.not_evaluable : out.self_crossing);
        continue;
      }
    }
    out.curves.push_back(c);
    out.total += c.length;
  }
  out.complete = static_cast<int>(out.curves.size()) == wanted;
  out.time_s = detail::seconds_since(t0);
  return out;
}

namespace {

double squared_log_gap(double x, double y) {
  if (!(x > 0) || !(y > 0) || !std::isfinite(x) || !std::isfinite(y)) return 1e6;
  const double d = std::log(x) - std::log(y);
  return d * d;
}

/// A surface's lengths remembered by word (the descent meets the same
/// images again and again), with the count of evaluations for the budget.
class LengthMemo {
 public:
  explicit LengthMemo(const SurfaceGroupLengths& lengths) : lengths_(lengths) {}
  double operator()(const Word& w) {
    auto it = memo_.find(w);
    if (it != memo_.end()) return it->second;
    ++evaluations;
    const double l = lengths_.length(w);
    if (memo_.size() > 2000000) memo_.clear();
    return memo_.emplace(w, l).first->second;
  }
  size_t evaluations = 0;

 private:
  const SurfaceGroupLengths& lengths_;
  std::unordered_map<Word, double, WordHash> memo_;
};

struct ClassState {
  GroupMap theta, inverse;
  double pants = 0, twist = 0, cost = 0;
};

}  // namespace

std::vector<GreedyPantsClass> greedy_pants_classes(const SurfaceGroupLengths& source, const ShortMarking& source_marking,
                                                   const GreedyPantsDecomposition& source_pants,
                                                   const SurfaceGroupLengths& target, const ShortMarking& target_marking,
                                                   const GreedyPantsDecomposition& target_pants,
                                                   const GreedyPantsClassOptions& options) {
  const int g = source.genus();
  if (target.genus() != g)
    throw InputError("greedy_pants_classes: genus " + std::to_string(g) + " against " + std::to_string(target.genus()));
  std::vector<GreedyPantsClass> out;
  if (source_pants.curves.empty() && target_pants.curves.empty()) return out;
  const DehnReducer reduce(canonical_relator(g));
  LengthMemo length_x(source), length_y(target);
  // The twist term's probes, in X's canonical letters, and their lengths
  // (those not evaluable in X left out: evaluable_probes; one not evaluable
  // in Y under a class still penalises it, squared_log_gap).
  const EvaluableProbes source_probes =
      evaluable_probes(source_marking.marking.map, reduce, [&](const Word& w) { return length_x(w); });
  const std::vector<Word>& probes = source_probes.words;
  const std::vector<double>& probe_x = source_probes.lengths;
  const double curves = static_cast<double>(source_pants.curves.size() + target_pants.curves.size());
  auto evaluate = [&](ClassState& s) {
    double pants = 0;
    for (const GreedyPantsCurve& c : source_pants.curves)
      pants += squared_log_gap(c.length, length_y(reduce(substitute(c.word, s.theta))));
    for (const GreedyPantsCurve& d : target_pants.curves)
      pants += squared_log_gap(d.length, length_x(reduce(substitute(d.word, s.inverse))));
    double twist = 0;
    for (size_t k = 0; k < probes.size(); ++k)
      twist += squared_log_gap(probe_x[k], length_y(reduce(substitute(probes[k], s.theta))));
    s.pants = curves > 0 ? pants / curves : 0;
    s.twist = probes.empty() ? 0 : twist / static_cast<double>(probes.size());
    s.cost = s.pants + options.twist_weight * s.twist;
  };
  // 1. Starts: the signed handle pairings of the markings, lifted exactly,
  // θ0 = M_Y ∘ P ∘ M_X^-1 and θ0^-1 = M_X ∘ P^-1 ∘ M_Y^-1.
  GeometricClassOptions go;
  go.descents = 0;
  go.max_classes = 1 << 30;
  std::vector<std::pair<ClassState, std::string>> starts;
  for (const GeometricClass& gc : geometric_classes(source, source_marking, target, target_marking, go)) {
    const SurfaceAutomorphism P = lift_symplectic(pairing_homology(gc.permutation, gc.rotation));
    ClassState s;
    s.theta = compose(target_marking.marking.map, compose(P.map, source_marking.marking.inverse));
    s.inverse = compose(source_marking.marking.map, compose(P.inverse, target_marking.marking.inverse));
    s.theta = reduce.each(std::move(s.theta));
    s.inverse = reduce.each(std::move(s.inverse));
    evaluate(s);
    starts.emplace_back(std::move(s), gc.description);
  }
  std::stable_sort(starts.begin(), starts.end(), [](const auto& x, const auto& y) { return x.first.cost < y.first.cost; });
  starts.resize(std::min<size_t>(starts.size(), static_cast<size_t>(std::max(1, options.starts))));
  // 2. Each start descends by single twists on either side: θ ∘ m (X side,
  // inverse m^-1 ∘ θ^-1) or m ∘ θ (Y side, inverse θ^-1 ∘ m^-1).
  const std::vector<MappingClassMove> moves = twist_moves(g, false, false);
  auto spent = [&] { return length_x.evaluations + length_y.evaluations; };
  auto apply = [&](const ClassState& s, const MappingClassMove& m, bool left) {
    ClassState n;
    n.theta = left ? compose(m.automorphism.map, s.theta) : compose(s.theta, m.automorphism.map);
    n.inverse = left ? compose(s.inverse, m.automorphism.inverse) : compose(m.automorphism.inverse, s.inverse);
    n.theta = reduce.each(std::move(n.theta));
    n.inverse = reduce.each(std::move(n.inverse));
    evaluate(n);
    return n;
  };
  // (The budget is shared out equally: every start descends.)
  const size_t per_start = options.length_budget / std::max<size_t>(1, starts.size());
  for (auto& [state, text] : starts) {
    ClassState s = state;
    int steps = 0;
    const size_t stop_at = spent() + per_start;
    for (; steps < options.max_steps && spent() < stop_at; ++steps) {
      ClassState best;
      best.cost = s.cost * (1 - 1e-9);
      bool found = false;
      for (const MappingClassMove& m : moves)
        for (bool left : {false, true}) {
          ClassState n = apply(s, m, left);
          if (n.cost < best.cost) best = std::move(n), found = true;
        }
      // None: pairs of moves, when there are at most max_pairs (a twist
      // that pays only together with another; genus 2).
      const size_t singles = 2 * moves.size();
      for (size_t i = 0; i < singles && !found && singles * singles <= options.max_pairs; ++i) {
        const ClassState first = apply(s, moves[i / 2], i % 2);
        for (size_t j = 0; j < singles; ++j) {
          ClassState n = apply(first, moves[j / 2], j % 2);
          if (n.cost < best.cost) best = std::move(n), found = true;
        }
      }
      if (!found) break;
      s = std::move(best);
    }
    GreedyPantsClass c;
    c.theta = std::move(s.theta);
    c.inverse = std::move(s.inverse);
    c.pants_mismatch = s.pants, c.twist_mismatch = s.twist, c.cost = s.cost;
    for (const GreedyPantsCurve& x : source_pants.curves) {
      const double ly = length_y(reduce(substitute(x.word, c.theta)));
      if (std::isfinite(ly)) c.collar_bound += collar_modulus(x.length) * ly * ly;
    }
    c.description = "greedy pants from " + text + (steps ? ", then " + std::to_string(steps) + " twists" : "");
    out.push_back(std::move(c));
  }
  std::stable_sort(out.begin(), out.end(), [](const GreedyPantsClass& x, const GreedyPantsClass& y) { return x.cost < y.cost; });
  std::vector<GreedyPantsClass> distinct;
  for (GreedyPantsClass& c : out) {
    bool seen = false;
    for (const GreedyPantsClass& d : distinct) seen = seen || d.theta == c.theta;
    if (!seen) distinct.push_back(std::move(c));
    if (static_cast<int>(distinct.size()) >= options.max_classes) break;
  }
  return distinct;
}

int shared_pants_curves(const SurfaceGroupLengths& lengths, const ShortMarking& marking,
                        const GreedyPantsDecomposition& greedy, const std::vector<Word>& curves) {
  IntersectionCounter count(lengths, marking.marking);
  const DehnReducer& reduce = count.reduce();
  int shared = 0;
  for (const Word& c : curves) {
    GreedyPantsCurve x{short_cyclic_word(substitute(c, marking.marking.inverse), reduce), c, lengths.length(c)};
    for (const GreedyPantsCurve& g : greedy.curves) {
      if (!(std::abs(g.length - x.length) <= 1e-7 * x.length)) continue;
      if (count(g.marking_word, x.marking_word, {}).same_curve ||
          same_by_length_and_generators(count, lengths.genus(), g, x, {})) {
        ++shared;
        break;
      }
    }
  }
  return shared;
}

}  // namespace surfmap
