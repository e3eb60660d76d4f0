#pragma once
// Poincaré-disk helpers (docs/method.md §7): orientation-preserving isometries of
// the disk as SU(1,1) matrices, distance, geodesic midpoint, exp/log maps,
// Klein <-> Poincaré conversion and the hyperbolic law of cosines
// (curvature −1). Used by the layout (uniformize/layout.h), the homotopy data
// and the hyperbolic harmonic-map solver.
//
// Model: the open unit disk with metric ds = 2|dz| / (1 − |z|²).
// All functions are inline; they are small and sit in inner loops.
#include <algorithm>
#include <cmath>
#include <complex>

namespace surfmap::hyperbolic {

using Complex = std::complex<double>;

/// z ↦ (a z + b) / (b̄ z + ā) with |a|² − |b|² = 1, i.e. the SU(1,1) matrix
/// [[a, b], [b̄, ā]]. Every orientation-preserving isometry of the Poincaré
/// disk has exactly two such representations, (a, b) and (−a, −b).
struct Mobius {
  Complex a{1.0, 0.0};
  Complex b{0.0, 0.0};

  static Mobius identity() { return {}; }
  /// z ↦ e^{iθ} z.
  static Mobius rotation(double theta) { return {std::polar(1.0, theta / 2), Complex(0.0)}; }
  /// The chart centring p: T_p(z) = (z − p) / (1 − p̄ z); T_p(p) = 0, and its
  /// inverse is T_{−p}. Requires |p| < 1.
  static Mobius centring(Complex p) {
    const double s = 1.0 / std::sqrt((1.0 - std::abs(p)) * (1.0 + std::abs(p)));
    return {Complex(s, 0.0), -p * s};
  }
  /// The hyperbolic translation along the geodesic through 0 and p taking 0
  /// to p: T_{−p}.
  static Mobius translation_to(Complex p) { return centring(-p); }
  /// The translation by the tangent vector ξ at 0 (orthonormal coordinates):
  /// takes 0 to exp_0(ξ), a = cosh(|ξ|/2), b = sinh(|ξ|/2) ξ/|ξ|. Exact for
  /// long ξ too, where translation_to(exp_0(ξ)) would divide by 1 − |p|² ≈ 0.
  static Mobius translation(Complex xi) {
    const double n = std::abs(xi);
    if (n == 0.0) return {};
    return {Complex(std::cosh(n / 2), 0.0), std::sinh(n / 2) * (xi / n)};
  }

  Complex apply(Complex z) const { return (a * z + b) / (std::conj(b) * z + std::conj(a)); }
  Complex operator()(Complex z) const { return apply(z); }
  /// Inverse: [[ā, −b], [−b̄, a]].
  Mobius inverse() const { return {std::conj(a), -b}; }
  /// Composition (*this) ∘ o: apply o first.
  Mobius operator*(const Mobius& o) const {
    return {a * o.a + b * std::conj(o.b), a * o.b + b * std::conj(o.a)};
  }
  /// |a|² − |b|², 1 for an exact SU(1,1) element.
  double determinant() const { return std::norm(a) - std::norm(b); }
  /// Rescales to determinant 1 (removes round-off drift after many products).
  /// The determinant |a|² − |b|² carries an error of round-off times
  /// |a|² + |b|², so rescaling by it injects that much noise into every
  /// entry (beyond entries of ~1e8 it can even come out negative). Matrices
  /// with |a|² + |b|² >= 1e4 are therefore returned unchanged: a product of
  /// determinant-1 factors keeps every entry to a relative round-off per
  /// factor, which is all that the distance 2 asinh|b|, the direction b/ā
  /// and the derivative need.
  Mobius normalized() const {
    const double big = std::norm(a) + std::norm(b);
    if (!(big < 1e4)) return *this;
    const double det = determinant();
    if (!(det > 0)) return *this;
    const double s = 1.0 / std::sqrt(det);
    return {a * s, b * s};
  }
  /// |a| + |b|: bounds how much the map amplifies round-off.
  double size() const { return std::abs(a) + std::abs(b); }
  /// Distance d(0, m(0)) = 2 asinh|b| (for determinant 1): exact for near
  /// and far images alike, unlike distances between points near |z| = 1.
  double displacement_of_origin() const { return 2.0 * std::asinh(std::abs(b)); }
  /// Derivative at z: 1 / (b̄ z + ā)².
  Complex derivative(Complex z) const {
    const Complex d = std::conj(b) * z + std::conj(a);
    return 1.0 / (d * d);
  }
};

/// Distance of a Möbius map from ±identity as matrices: min over the sign of
/// max(|a ∓ 1|, |b|) (both representations of the identity count).
inline double distance_from_identity(const Mobius& m) {
  const double plus = std::max(std::abs(m.a - 1.0), std::abs(m.b));
  const double minus = std::max(std::abs(m.a + 1.0), std::abs(m.b));
  return std::min(plus, minus);
}

/// Matrix distance between two Möbius maps, up to the sign ambiguity.
inline double mobius_distance(const Mobius& m, const Mobius& n) {
  const double plus = std::max(std::abs(m.a - n.a), std::abs(m.b - n.b));
  const double minus = std::max(std::abs(m.a + n.a), std::abs(m.b + n.b));
  return std::min(plus, minus);
}

/// 1 − |z|², computed as (1 − |z|)(1 + |z|) to keep digits near the boundary.
inline double conformal_denominator(Complex z) {
  const double r = std::abs(z);
  return (1.0 - r) * (1.0 + r);
}

/// T_p(z) = (z − p) / (1 − p̄ z), the point z in the chart centring p,
/// evaluated as (z − p) / ((1 − |p|²) − p̄ (z − p)): for p near |z| = 1 and
/// z close to p, 1 − p̄ z cancels to a few digits while this form keeps
/// them (z − p is exact for nearby floats).
inline Complex centred(Complex p, Complex z) {
  const Complex d = z - p;
  const double r = std::abs(p);
  return d / ((1.0 - r) * (1.0 + r) - std::conj(p) * d);
}

/// Barycentric coordinates (λ0, λ1, λ2), Σλ = 1, of q in the geodesic
/// triangle c0 c1 c2, in the hyperboloid model: q ∝ Σ λ_k X_k with X_k the
/// corners on the hyperboloid. Unlike Klein-model barycentrics they do not
/// depend on the chart (isometries act linearly on the hyperboloid), and all
/// are >= 0 exactly when q is in the triangle. Computed in the chart centring
/// q (Klein barycentrics μ of the origin there, λ_k ∝ μ_k / cosh d(q, c_k)),
/// so tiny triangles near |z| = 1 keep their digits.
inline void triangle_barycentric(Complex q, Complex c0, Complex c1, Complex c2, double lambda[3]) {
  const Complex w[3] = {centred(q, c0), centred(q, c1), centred(q, c2)};
  Complex k[3];
  double inv_cosh[3];
  for (int i = 0; i < 3; ++i) {
    const double n = std::norm(w[i]);
    k[i] = 2.0 * w[i] / (1.0 + n);
    inv_cosh[i] = (1.0 - n) / (1.0 + n);
  }
  auto cross = [](Complex a, Complex b) { return a.real() * b.imag() - a.imag() * b.real(); };
  // Affine barycentrics of the origin: μ_i ∝ cross(k_{i+1}, k_{i+2}).
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    lambda[i] = cross(k[(i + 1) % 3], k[(i + 2) % 3]) * inv_cosh[i];
    sum += lambda[i];
  }
  for (int i = 0; i < 3; ++i) lambda[i] /= sum;
}

/// Hyperbolic distance d(z, w) = 2 artanh(|z − w| / |1 − w̄ z|), evaluated as
/// 2 asinh(|z − w| / sqrt((1 − |z|²)(1 − |w|²))), which does not lose digits
/// when the ratio is close to 1 (points near the boundary).
inline double distance(Complex z, Complex w) {
  return 2.0 * std::asinh(std::abs(z - w) /
                          std::sqrt(conformal_denominator(z) * conformal_denominator(w)));
}

/// Distance from the origin: 2 artanh|z|.
inline double distance_from_origin(Complex z) { return 2.0 * std::atanh(std::abs(z)); }

/// Exponential map at p: the point at distance |ξ| from p in direction ξ,
/// with ξ a tangent vector at p in orthonormal coordinates (unit length =
/// unit hyperbolic length): exp_p(ξ) = T_{−p}(tanh(|ξ|/2) ξ/|ξ|).
inline Complex exp_map(Complex p, Complex xi) {
  const double n = std::abs(xi);
  if (n == 0.0) return p;
  return Mobius::translation_to(p).apply(std::tanh(n / 2) * (xi / n));
}

/// Logarithm at p: log_p(w) = 2 artanh|T_p(w)| · T_p(w)/|T_p(w)|; the inverse
/// of exp_map(p, ·). Its length is d(p, w).
inline Complex log_map(Complex p, Complex w) {
  const Complex t = Mobius::centring(p).apply(w);
  const double n = std::abs(t);
  if (n == 0.0) return Complex(0.0);
  return 2.0 * std::atanh(n) * (t / n);
}

/// The point halfway between z and w along the geodesic.
inline Complex midpoint(Complex z, Complex w) { return exp_map(z, 0.5 * log_map(z, w)); }

/// The point at fraction t ∈ [0, 1] along the geodesic from z to w.
inline Complex geodesic_point(Complex z, Complex w, double t) {
  return exp_map(z, t * log_map(z, w));
}

/// Poincaré → Klein: k = 2z / (1 + |z|²). Geodesics are straight chords in
/// the Klein model, so barycentric point-in-triangle tests are exact there.
inline Complex poincare_to_klein(Complex z) { return 2.0 * z / (1.0 + std::norm(z)); }

/// Klein → Poincaré: z = k / (1 + sqrt(1 − |k|²)).
inline Complex klein_to_poincare(Complex k) {
  const double r = std::abs(k);
  return k / (1.0 + std::sqrt(std::max(0.0, (1.0 - r) * (1.0 + r))));
}

/// Hyperbolic law of cosines (curvature −1): the side c opposite the angle
/// γ between sides a and b: cosh c = cosh a cosh b − sinh a sinh b cos γ.
/// Evaluated through cosh c − 1 = cosh(a−b) − 1 + sinh a sinh b (1 − cos γ)
/// so that short sides do not cancel to zero.
inline double law_of_cosines_side(double a, double b, double gamma) {
  const double s = std::sinh((a - b) / 2), h = std::sin(gamma / 2);
  // cosh x − 1 = 2 sinh²(x/2); 1 − cos γ = 2 sin²(γ/2).
  const double coshc_minus_1 = 2 * s * s + 2 * std::sinh(a) * std::sinh(b) * h * h;
  // c = 2 asinh(sqrt((cosh c − 1)/2)).
  return 2.0 * std::asinh(std::sqrt(coshc_minus_1 / 2));
}

/// The angle opposite side c in a hyperbolic triangle with sides a, b, c,
/// from the half-angle formula
///   tan²(γ/2) = sinh(s−a) sinh(s−b) / (sinh s · sinh(s−c)),  s = (a+b+c)/2,
/// which stays accurate for small and for needle triangles (the plain law of
/// cosines loses all digits when the sides are short). Violations of the
/// triangle inequality are clamped: γ = π if c >= a + b, 0 if a or b is too
/// long.
inline double law_of_cosines_angle(double a, double b, double c) {
  const double s = (a + b + c) / 2;
  const double sa = s - a, sb = s - b, sc = s - c;
  if (sc <= 0) return M_PI;
  if (sa <= 0 || sb <= 0) return 0.0;
  return 2.0 * std::atan(std::sqrt(std::sinh(sa) * std::sinh(sb) / (std::sinh(s) * std::sinh(sc))));
}

/// Euclidean counterpart of law_of_cosines_angle (tan²(γ/2) = (s−a)(s−b) /
/// (s(s−c))), with the same clamping.
inline double euclidean_angle(double a, double b, double c) {
  const double s = (a + b + c) / 2;
  const double sa = s - a, sb = s - b, sc = s - c;
  if (sc <= 0) return M_PI;
  if (sa <= 0 || sb <= 0) return 0.0;
  return 2.0 * std::atan(std::sqrt(sa * sb / (s * sc)));
}

/// Area of a hyperbolic triangle with sides a, b, c (= π − angle sum), by the
/// hyperbolic l'Huilier formula
///   tan(A/4) = sqrt(tanh(s/2) tanh((s−a)/2) tanh((s−b)/2) tanh((s−c)/2)),
/// which keeps its digits for tiny triangles where π − Σangles cancels.
inline double triangle_area(double a, double b, double c) {
  const double s = (a + b + c) / 2;
  const double p = std::tanh(s / 2) * std::tanh(std::max(0.0, s - a) / 2) *
                   std::tanh(std::max(0.0, s - b) / 2) * std::tanh(std::max(0.0, s - c) / 2);
  return 4.0 * std::atan(std::sqrt(p));
}

/// Area of the geodesic triangle with vertices p, q, r in the disk.
inline double triangle_area(Complex p, Complex q, Complex r) {
  return triangle_area(distance(q, r), distance(r, p), distance(p, q));
}

/// The isometry taking the ordered pair (p0, p1) to (q0, q1). The two pairs
/// must be (nearly) equally far apart; the result maps p0 to q0 exactly and
/// p1 onto the geodesic ray from q0 through q1.
inline Mobius isometry_from_pairs(Complex p0, Complex p1, Complex q0, Complex q1) {
  const Mobius tp = Mobius::centring(p0), tq = Mobius::centring(q0);
  const Complex u = tp.apply(p1), v = tq.apply(q1);
  const double angle = std::arg(v) - std::arg(u);
  return tq.inverse() * Mobius::rotation(angle) * tp;
}

}  // namespace surfmap::hyperbolic
