// The greedy short pants decomposition (map/greedy_pants.h;
// docs/handle_classes.md "Greedy pants decomposition").
#include "surfmap/map/greedy_pants.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <utility>

#include "surfmap/error.h"

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
Word cyclic_dehn_reduce(Word w, const DehnReducer& reduce) {
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

CurveIntersection curve_intersection(const SurfaceGroupLengths& lengths, const SurfaceAutomorphism& marking,
                                     const Word& u, const Word& v, const CurveIntersectionOptions& options) {
  CurveIntersection out;
  const int genus = lengths.genus();
  if (u.empty() || v.empty()) return out;
  const DehnReducer reduce(canonical_relator(genus));
  auto caller = [&](const Word& w) { return reduce(substitute(w, marking.map)); };
  // Every lift is a word of its own, evaluated with U in the frame of u
  // (SurfaceGroupLengths::elements_in_frame_of_first): products of the
  // marking's generators as matrices lose every digit (the handles'
  // generators are loops at one base joined by tails of 15 units and more).
  const Word uc = caller(u), vc = caller(v);
  std::vector<Mobius> m;
  if (!lengths.elements_in_frame_of_first({uc}, &m)) return out;
  const Mobius U = m[0];
  Complex r, t;
  if (!axis_ends(U, &r, &t)) return out;
  const double ell = 2 * std::acosh(std::abs(U.a.real()) / std::sqrt(U.determinant()));
  if (!(ell > 1e-9)) return out;
  const Mobius K = axis_chart(r, t);
  int radius = options.radius;
  while (radius > 0 && u.size() * v.size() * reduced_words_up_to(genus, radius).size() > options.max_lifts) --radius;
  const std::vector<Word> ball = reduced_words_up_to(genus, radius);
  const bool self = u == v;
  std::set<Word> seen;
  std::vector<double> points;
  for (size_t i = 0; i < u.size(); ++i)
    for (const Word& h : ball)
      for (size_t k = 0; k < v.size(); ++k) {
        const Word c = caller(concat({prefix(u, i), h, prefix(v, k)}));
        const Word lift = reduce(concat({c, vc, inverse(c)}));
        if (!seen.insert(lift).second) continue;
        if (!lengths.elements_in_frame_of_first({uc, lift}, &m)) continue;
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

/// Curves of equal length (1e-7 relative) that no lift shows to be one: the
/// same curve when they also meet every marking generator equally often. A
/// word of the marking and the caterpillar's word for one curve can be far
/// conjugates whose lifts the conjugator ball does not bring together; two
/// curves exchanged by a symmetry (the fertility's two handles of length
/// 1.04) meet the generators differently.
bool same_by_length_and_generators(const SurfaceGroupLengths& lengths, const SurfaceAutomorphism& marking,
                                   const GreedyPantsCurve& x, const GreedyPantsCurve& y,
                                   const CurveIntersectionOptions& options) {
  if (!(std::abs(x.length - y.length) <= 1e-7 * y.length)) return false;
  for (int j = 1; j <= 2 * lengths.genus(); ++j) {
    const int ix = curve_intersection(lengths, marking, {j}, x.marking_word, options).crossings;
    const int iy = curve_intersection(lengths, marking, {j}, y.marking_word, options).crossings;
    if (ix < 0 || ix != iy) return false;
  }
  return true;
}

GreedyPantsDecomposition greedy_pants_decomposition(const SurfaceGroupLengths& lengths, const ShortMarking& marking,
                                                    const std::vector<Word>& extra_curves,
                                                    const GreedyPantsOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  GreedyPantsDecomposition out;
  const int genus = lengths.genus(), wanted = 3 * genus - 3;
  if (genus < 2) throw InputError("greedy_pants_decomposition: genus " + std::to_string(genus) + " < 2");
  const int letters = options.max_letters > 0 ? options.max_letters : genus == 2 ? 4 : genus <= 4 ? 3 : 2;
  const DehnReducer reduce(canonical_relator(genus));
  std::vector<Word> words = candidate_words(genus, letters);
  for (const Word& c : extra_curves) {
    const Word w = cyclic_dehn_reduce(substitute(c, marking.marking.inverse), reduce);
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
  for (const GreedyPantsCurve& c : listed) {
    if (static_cast<int>(out.curves.size()) == wanted || out.examined == options.max_examined) break;
    ++out.examined;
    const CurveIntersection self = curve_intersection(lengths, marking.marking, c.marking_word, c.marking_word, options.intersection);
    if (self.crossings != 0) {
      ++(self.crossings < 0 ? out.not_evaluable : out.self_crossing);
      continue;
    }
    bool ok = true;
    for (const GreedyPantsCurve& s : out.curves) {
      const CurveIntersection x = curve_intersection(lengths, marking.marking, s.marking_word, c.marking_word,
                                                     options.intersection);
      const bool same = x.same_curve || (x.crossings == 0 && same_by_length_and_generators(lengths, marking.marking, s, c,
                                                                                             options.intersection));
      if (same) {
        ++out.duplicates, ok = false;
      } else if (x.crossings != 0) {
        ++(x.crossings < 0 ? out.not_evaluable : out.crossing), ok = false;
      }
      if (!ok) break;
    }
    if (!ok) continue;
    out.curves.push_back(c);
    out.total += c.length;
  }
  out.complete = static_cast<int>(out.curves.size()) == wanted;
  out.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

int shared_pants_curves(const SurfaceGroupLengths& lengths, const ShortMarking& marking,
                        const GreedyPantsDecomposition& greedy, const std::vector<Word>& curves) {
  const DehnReducer reduce(canonical_relator(lengths.genus()));
  int shared = 0;
  for (const Word& c : curves) {
    GreedyPantsCurve x{cyclic_dehn_reduce(substitute(c, marking.marking.inverse), reduce), c, lengths.length(c)};
    for (const GreedyPantsCurve& g : greedy.curves) {
      if (!(std::abs(g.length - x.length) <= 1e-7 * x.length)) continue;
      if (curve_intersection(lengths, marking.marking, g.marking_word, x.marking_word).same_curve ||
          same_by_length_and_generators(lengths, marking.marking, g, x, {})) {
        ++shared;
        break;
      }
    }
  }
  return shared;
}

}  // namespace surfmap
