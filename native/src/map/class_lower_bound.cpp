// Energy lower bound of a homotopy class from hyperbolic lengths
// (docs/handle_classes.md).
#include "surfmap/map/class_lower_bound.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <utility>

#include "surfmap/error.h"
#include "surfmap/topology/mapping_class_search.h"

namespace surfmap {

namespace {
// Relative agreement of the double and extended-precision *lengths* for a
// word whose matrix entries exceed 1e12. Callers compare logarithms of
// lengths (mismatches of 1e-8 and less count as equal), so a length right to
// 1e-6 relative is all they need, and the extended value (11 more bits) is
// then right to about 1e-9. Issue 13: the former bar, 1e-9 relative on the
// half trace (1e-11 on the length of a 150-unit curve), left 136 of the 256
// marking probes of a genus-8 wheel not evaluable: curves of 80-210 units
// whose double traces were right to 1e-10..1e-7 (checked against binary128).
constexpr long double kLengthAgreement = 1e-6L;
}  // namespace

SurfaceGroupLengths::SurfaceGroupLengths(DeckGroup group, GroupMap canonical_to_loops, Word loop_relator,
                                         GroupMap caller_to_canonical)
    : group_(std::move(group)),
      canonical_to_loops_(std::move(canonical_to_loops)),
      caller_to_canonical_(std::move(caller_to_canonical)),
      reduce_canonical_(canonical_relator(std::max<int>(1, static_cast<int>(canonical_to_loops_.size()) / 2))),
      reduce_loops_(loop_relator),
      genus_(static_cast<int>(canonical_to_loops_.size()) / 2) {
  if (genus_ < 2 || canonical_to_loops_.size() % 2 != 0)
    throw InputError("SurfaceGroupLengths: expected 2g >= 4 canonical generators, got " +
                     std::to_string(canonical_to_loops_.size()));
  if (!caller_to_canonical_.empty() && caller_to_canonical_.size() != canonical_to_loops_.size())
    throw InputError("SurfaceGroupLengths: caller_to_canonical has " + std::to_string(caller_to_canonical_.size()) +
                     " words, expected " + std::to_string(canonical_to_loops_.size()));
}

double SurfaceGroupLengths::length(const Word& w, size_t max_letters) const {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Word canonical = caller_to_canonical_.empty() ? w : substitute(w, caller_to_canonical_);
  canonical = reduce_canonical_(canonical);
  if (canonical.empty()) return 0.0;
  if (canonical.size() > max_letters) return nan;
  const Word loops = reduce_loops_(substitute(canonical, canonical_to_loops_));
  if (loops.empty()) return 0.0;
  if (loops.size() > max_letters) return nan;
  // The trace is a class function: the side word is cyclically reduced (and
  // Dehn-reduced again) before it is multiplied out, so the matrix is that of
  // a short conjugate, whose axis passes near the fundamental polygon. A
  // far conjugate has entries of 1e8 and more for a translation length of 6
  // (the determinant then comes out as -32 from round-off, though the
  // trace is still right to 1e-7).
  Word side = group_.side_word(loops);
  for (int guard = 0; guard < 64; ++guard) {
    Word next = group_.reduce(cyclic_reduce(side));
    // (a relator piece across the word's ends: reduce a half-turned rotation too)
    Word turned(next.begin() + static_cast<long>(next.size() / 2), next.end());
    turned.insert(turned.end(), next.begin(), next.begin() + static_cast<long>(next.size() / 2));
    turned = group_.reduce(cyclic_reduce(turned));
    if (turned.size() < next.size()) next = std::move(turned);
    if (next == side) break;
    side = std::move(next);
  }
  if (side.empty()) return 0.0;
  const hyperbolic::Mobius m = group_.evaluate_side_word(side);
  // SU(1,1): tr = 2 Re(a); normalised by the determinant (1 up to round-off)
  // only where that is meaningful.
  const double det = m.determinant();
  double half_trace = std::abs(m.a.real());
  if (det > 0.5 && det < 2) half_trace /= std::sqrt(det);
  if (!std::isfinite(half_trace)) return nan;
  if (std::abs(m.a) > 1e12) {
    // Entries this large come from long curves (ℓ of 50 and more: the
    // entries of even the shortest conjugate are about e^{ℓ/2}), not only
    // from far conjugates. The determinant is then round-off, but the trace
    // usually keeps a relative error of a few round-offs per letter. That is
    // checked, not assumed: the same product in extended precision must give
    // the same length to kLengthAgreement, else it is not evaluable. (A bare cap on
    // the entries made such curves NaN on one machine and finite on another,
    // a probe of the same surface then looked like a mismatch.)
    const long double ld_half_trace = half_trace_extended(side);
    if (!std::isfinite(ld_half_trace) || !(ld_half_trace >= 1)) return nan;
    const long double ld_length = 2 * std::acosh(ld_half_trace);
    const long double d_length = 2 * std::acosh(std::max<long double>(1, half_trace));
    if (!(std::abs(d_length - ld_length) <= kLengthAgreement * ld_length)) return nan;
    half_trace = static_cast<double>(ld_half_trace);
  }
  return 2 * std::acosh(std::max(1.0, half_trace));
}

long double SurfaceGroupLengths::half_trace_extended(const Word& side) const {
  using ComplexL = std::complex<long double>;
  ComplexL a(1), b(0);
  for (int x : side) {
    const hyperbolic::Mobius f = group_.evaluate_side_word(Word{x});
    const ComplexL fa(f.a.real(), f.a.imag()), fb(f.b.real(), f.b.imag());
    const ComplexL na = a * fa + b * std::conj(fb), nb = a * fb + b * std::conj(fa);
    a = na, b = nb;
  }
  const long double det = std::norm(a) - std::norm(b);
  long double h = std::abs(a.real());
  if (det > 0.5L && det < 2.0L) h /= std::sqrt(det);
  return h;
}

bool SurfaceGroupLengths::element(const Word& w, hyperbolic::Mobius* m, size_t max_letters) const {
  Word canonical = caller_to_canonical_.empty() ? w : substitute(w, caller_to_canonical_);
  canonical = reduce_canonical_(canonical);
  if (canonical.size() > max_letters) return false;
  const Word loops = reduce_loops_(substitute(canonical, canonical_to_loops_));
  if (loops.size() > max_letters) return false;
  *m = group_.evaluate(loops);
  return std::isfinite(std::abs(m->a)) && std::isfinite(std::abs(m->b)) && std::abs(m->a) < 1e12;
}

bool SurfaceGroupLengths::elements_in_frame_of_first(const std::vector<Word>& words,
                                                     std::vector<hyperbolic::Mobius>* out, size_t max_letters) const {
  std::vector<Word> side;
  for (const Word& w : words) {
    Word canonical = caller_to_canonical_.empty() ? w : substitute(w, caller_to_canonical_);
    canonical = reduce_canonical_(canonical);
    if (canonical.size() > max_letters) return false;
    const Word loops = reduce_loops_(substitute(canonical, canonical_to_loops_));
    if (loops.size() > max_letters) return false;
    side.push_back(group_.reduce(group_.side_word(loops)));
  }
  if (side.empty()) return false;
  // first = u w u^-1: strip conjugating letters and half-turn rotations
  // (as in length()), keeping u.
  Word u, w = side[0];
  for (int guard = 0; guard < 64; ++guard) {
    const Word before = w;
    while (w.size() >= 2 && w.front() == -w.back()) {
      u.push_back(w.front());
      w = Word(w.begin() + 1, w.end() - 1);
    }
    w = group_.reduce(w);
    const size_t h = w.size() / 2;
    Word turned(w.begin() + static_cast<long>(h), w.end());
    turned.insert(turned.end(), w.begin(), w.begin() + static_cast<long>(h));
    turned = group_.reduce(cyclic_reduce(turned));
    if (turned.size() < w.size()) {  // w = half turned half^-1
      u.insert(u.end(), w.begin(), w.begin() + static_cast<long>(h));
      u = surfmap::reduce(u);
      w = std::move(turned);
    }
    if (w == before) break;
  }
  out->clear();
  const Word ui = inverse(u);
  for (const Word& sw : side) {
    const Word v = group_.reduce(concat({ui, sw, u}));
    if (v.size() > max_letters) return false;
    out->push_back(group_.evaluate_side_word(v));
    if (!std::isfinite(std::abs(out->back().a)) || std::abs(out->back().a) > 1e12) return false;
  }
  return true;
}

double collar_modulus(double length) {
  if (!(length > 0)) return std::numeric_limits<double>::infinity();
  return 2 * std::atan(1 / std::sinh(length / 2)) / length;
}

std::vector<CurveFamily> disjoint_curve_families(int genus, bool move_images) {
  if (genus < 2) throw InputError("disjoint_curve_families: genus " + std::to_string(genus) + " < 2");
  std::vector<Word> separating;
  for (int j = 1; j < genus; ++j) {
    std::vector<Word> handles;
    for (int k = 1; k <= 2 * j; ++k) handles.push_back({k});
    separating.push_back(commutator_product(handles));
  }
  auto family = [&](const std::string& name, auto handle_curve) {
    CurveFamily f{name, {}};
    for (int i = 0; i < genus; ++i) f.curves.push_back(handle_curve(2 * i + 1, 2 * i + 2));
    for (const Word& s : separating) f.curves.push_back(s);
    return f;
  };
  std::vector<CurveFamily> base{
      family("a_i, s_j", [](int a, int) { return Word{a}; }),
      family("b_i, s_j", [](int, int b) { return Word{b}; }),
      family("a_i b_i, s_j", [](int a, int b) { return Word{a, b}; }),
      family("a_i b_i^-1, s_j", [](int a, int b) { return Word{a, -b}; }),
  };
  std::vector<CurveFamily> out = base;
  if (!move_images) return out;
  const Word R = canonical_relator(genus);
  for (const MappingClassMove& m : twist_moves(genus, false, false))
    for (const CurveFamily& f : base) {
      CurveFamily g{m.name + "(" + f.name + ")", {}};
      for (const Word& c : f.curves) g.curves.push_back(dehn_reduce(substitute(c, m.automorphism.map), R));
      out.push_back(std::move(g));
    }
  return out;
}

ClassBoundEvaluator::ClassBoundEvaluator(const SurfaceGroupLengths& source, std::vector<CurveFamily> families)
    : families_(std::move(families)), genus_(source.genus()) {
  std::map<Word, double> memo;
  for (const CurveFamily& f : families_) {
    std::vector<double> lengths;
    for (const Word& c : f.curves) {
      auto it = memo.find(c);
      if (it == memo.end()) it = memo.emplace(c, source.length(c)).first;
      lengths.push_back(it->second);
    }
    source_lengths_.push_back(std::move(lengths));
  }
}

ClassLowerBound ClassBoundEvaluator::operator()(const SurfaceGroupLengths& target, const GroupMap& theta) const {
  ClassLowerBound r;
  r.conformal_bound = conformal_bound(genus_);
  if (target.genus() != genus_ || static_cast<int>(theta.size()) != 2 * genus_)
    throw InputError("class_lower_bound: the class has " + std::to_string(theta.size()) + " generator images, the surfaces genus " +
                     std::to_string(genus_) + " and " + std::to_string(target.genus()));
  std::map<Word, double> memo;  // image lengths by source curve
  for (size_t f = 0; f < families_.size(); ++f) {
    double sum = 0;
    std::vector<double> image_lengths;
    for (size_t c = 0; c < families_[f].curves.size(); ++c) {
      const Word& curve = families_[f].curves[c];
      auto it = memo.find(curve);
      if (it == memo.end()) it = memo.emplace(curve, target.length(substitute(curve, theta))).first;
      image_lengths.push_back(it->second);
      const double lx = source_lengths_[f][c], ly = it->second;
      // Not evaluable (NaN) or degenerate: the curve's collar is left out,
      // which keeps the sum a lower bound.
      if (!std::isfinite(lx) || !(lx > 0) || !std::isfinite(ly)) continue;
      sum += collar_modulus(lx) * ly * ly;
    }
    if (sum > r.curve_bound) {
      r.curve_bound = sum;
      r.family = static_cast<int>(f);
      r.family_name = families_[f].name;
      r.source_lengths = source_lengths_[f];
      r.target_lengths = std::move(image_lengths);
    }
  }
  r.bound = std::max(r.curve_bound, r.conformal_bound);
  return r;
}

}  // namespace surfmap
