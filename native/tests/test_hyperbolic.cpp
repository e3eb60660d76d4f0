// Properties of the Poincaré-disk helpers (geometry/hyperbolic.h): isometry
// invariance, exp/log inverse pair, midpoints, Klein model straightness, the
// law of cosines against an independent construction.
#include <gtest/gtest.h>

#include <random>

#include "surfmap/geometry/hyperbolic.h"

using namespace surfmap::hyperbolic;

namespace {

struct Rng {
  std::mt19937 gen{12345};
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(gen); }
  /// A random point of the disk, with |z| up to rmax.
  Complex point(double rmax = 0.95) {
    return std::polar(rmax * std::sqrt(uniform(0, 1)), uniform(-M_PI, M_PI));
  }
  Mobius mobius() { return Mobius::rotation(uniform(-M_PI, M_PI)) * Mobius::centring(point(0.9)); }
};

}  // namespace

TEST(Hyperbolic, MobiusIsSU11AndGroupOperationsAgree) {
  Rng rng;
  for (int t = 0; t < 200; ++t) {
    const Mobius m = rng.mobius(), n = rng.mobius();
    EXPECT_NEAR(m.determinant(), 1.0, 1e-12);
    EXPECT_NEAR((m * n).determinant(), 1.0, 1e-10);
    const Complex z = rng.point();
    // Composition applies the right factor first.
    const Complex mn = (m * n).apply(z), direct = m.apply(n.apply(z));
    EXPECT_LT(std::abs(mn - direct), 1e-12);
    EXPECT_LT(std::abs(m.inverse().apply(m.apply(z)) - z), 1e-12);
    EXPECT_LT(distance_from_identity(m * m.inverse()), 1e-12);
    // Maps the disk into itself.
    EXPECT_LT(std::abs(m.apply(z)), 1.0);
  }
  // A non-identity is detected as such.
  EXPECT_GT(distance_from_identity(Mobius::rotation(0.1)), 0.01);
  EXPECT_LT(distance_from_identity(Mobius::rotation(2 * M_PI)), 1e-14);  // = −identity
}

TEST(Hyperbolic, CentringChartSendsPointToOriginAndInverseIsMinusP) {
  Rng rng;
  for (int t = 0; t < 100; ++t) {
    const Complex p = rng.point(0.99), z = rng.point();
    EXPECT_LT(std::abs(Mobius::centring(p).apply(p)), 1e-12);
    const Complex tz = Mobius::centring(p).apply(z);
    EXPECT_LT(std::abs(Mobius::centring(-p).apply(tz) - z), 1e-10);
    // Formula of docs/method.md §7.
    EXPECT_LT(std::abs(tz - (z - p) / (1.0 - std::conj(p) * z)), 1e-12);
  }
}

TEST(Hyperbolic, DistanceIsInvariantUnderIsometries) {
  Rng rng;
  for (int t = 0; t < 300; ++t) {
    const Mobius m = rng.mobius();
    const Complex z = rng.point(0.98), w = rng.point(0.98);
    const double d = distance(z, w);
    EXPECT_NEAR(distance(m.apply(z), m.apply(w)), d, 1e-9 * (1 + d));
    // Agrees with the artanh form of docs/method.md §7.
    const double d2 = 2 * std::atanh(std::abs(z - w) / std::abs(1.0 - std::conj(w) * z));
    EXPECT_NEAR(d, d2, 1e-9 * (1 + d));
    EXPECT_NEAR(distance(z, w), distance(w, z), 1e-12);
  }
  EXPECT_EQ(distance(Complex(0.3, 0.2), Complex(0.3, 0.2)), 0.0);
  EXPECT_NEAR(distance_from_origin(Complex(0.5, 0)), 2 * std::atanh(0.5), 1e-15);
}

TEST(Hyperbolic, TriangleInequality) {
  Rng rng;
  for (int t = 0; t < 500; ++t) {
    const Complex a = rng.point(0.99), b = rng.point(0.99), c = rng.point(0.99);
    EXPECT_LE(distance(a, c), distance(a, b) + distance(b, c) + 1e-9);
  }
}

TEST(Hyperbolic, ExpAndLogAreInverse) {
  Rng rng;
  for (int t = 0; t < 300; ++t) {
    const Complex p = rng.point(0.95), w = rng.point(0.95);
    const Complex xi = log_map(p, w);
    EXPECT_NEAR(std::abs(xi), distance(p, w), 1e-9 * (1 + std::abs(xi)));
    EXPECT_LT(std::abs(exp_map(p, xi) - w), 1e-10);
    const Complex v(rng.uniform(-3, 3), rng.uniform(-3, 3));
    EXPECT_LT(std::abs(log_map(p, exp_map(p, v)) - v), 1e-8);
    EXPECT_NEAR(distance(p, exp_map(p, v)), std::abs(v), 1e-8);
  }
  // At the origin the metric is 2|dz|: a short step ξ moves by about ξ/2.
  const Complex small(1e-6, 2e-6);
  EXPECT_LT(std::abs(exp_map(0.0, small) - small / 2.0), 1e-15);
}

TEST(Hyperbolic, ExpMapCommutesWithIsometriesUpToTheDerivativeRotation) {
  // m(exp_p(ξ)) = exp_{m(p)}(ξ · m'(p)/|m'(p)|): isometries carry geodesics to geodesics.
  Rng rng;
  for (int t = 0; t < 100; ++t) {
    const Mobius m = rng.mobius();
    const Complex p = rng.point(0.9), xi(rng.uniform(-2, 2), rng.uniform(-2, 2));
    const Complex d = m.derivative(p);
    const Complex lhs = m.apply(exp_map(p, xi)), rhs = exp_map(m.apply(p), xi * d / std::abs(d));
    EXPECT_LT(std::abs(lhs - rhs), 1e-9);
  }
}

TEST(Hyperbolic, MidpointIsEquidistantAndOnTheGeodesic) {
  Rng rng;
  for (int t = 0; t < 300; ++t) {
    const Complex z = rng.point(0.97), w = rng.point(0.97);
    const Complex m = midpoint(z, w);
    const double d = distance(z, w);
    EXPECT_NEAR(distance(z, m), d / 2, 1e-8 * (1 + d));
    EXPECT_NEAR(distance(w, m), d / 2, 1e-8 * (1 + d));
    const Complex q = geodesic_point(z, w, 0.25);
    EXPECT_NEAR(distance(z, q) + distance(q, w), d, 1e-8 * (1 + d));
  }
}

TEST(Hyperbolic, KleinRoundTripAndGeodesicsAreStraightInKlein) {
  Rng rng;
  for (int t = 0; t < 300; ++t) {
    const Complex z = rng.point(0.99);
    EXPECT_LT(std::abs(klein_to_poincare(poincare_to_klein(z)) - z), 1e-12);
    const Complex a = rng.point(0.95), b = rng.point(0.95);
    const Complex ka = poincare_to_klein(a), kb = poincare_to_klein(b);
    for (double s : {0.1, 0.37, 0.5, 0.81}) {
      const Complex kq = poincare_to_klein(geodesic_point(a, b, s));
      // Collinear: the cross product of (kb−ka) and (kq−ka) vanishes, and kq lies between.
      const double cross = std::imag(std::conj(kb - ka) * (kq - ka));
      EXPECT_NEAR(cross, 0.0, 1e-10);
      const double along = std::real(std::conj(kb - ka) * (kq - ka)) / std::norm(kb - ka);
      EXPECT_GT(along, 0.0);
      EXPECT_LT(along, 1.0);
    }
    // A Poincaré geodesic that is not a diameter is a circular arc: its
    // Poincaré-model points are NOT collinear in general (the test above
    // would fail in the wrong model).
  }
  const Complex a(0.5, 0.1), b(-0.2, 0.6), q = midpoint(a, b);
  EXPECT_GT(std::abs(std::imag(std::conj(b - a) * (q - a))), 1e-3);
}

TEST(Hyperbolic, LawOfCosinesMatchesConstructedTriangles) {
  // Build a triangle from two sides and the angle between them in the disk,
  // then compare side and angles against the formulas.
  Rng rng;
  for (int t = 0; t < 300; ++t) {
    const double a = std::exp(rng.uniform(std::log(1e-4), std::log(4.0)));
    const double b = std::exp(rng.uniform(std::log(1e-4), std::log(4.0)));
    const double gamma = rng.uniform(0.01, M_PI - 0.01);
    const Complex C = 0.0, A = std::tanh(b / 2), B = std::polar(std::tanh(a / 2), gamma);
    const double c = distance(A, B);
    EXPECT_NEAR(law_of_cosines_side(a, b, gamma), c, 1e-9 * c + 1e-13);
    EXPECT_NEAR(law_of_cosines_angle(a, b, c), gamma, 1e-6);
    // Angles sum to less than π, by the area.
    const double alpha = law_of_cosines_angle(b, c, a), beta = law_of_cosines_angle(c, a, b);
    EXPECT_LT(alpha + beta + gamma, M_PI);
    const double gamma_c = law_of_cosines_angle(a, b, c);
    EXPECT_NEAR(triangle_area(a, b, c), M_PI - alpha - beta - gamma_c, 1e-10);
    // Area is isometry invariant and agrees with the point version.
    EXPECT_NEAR(triangle_area(A, B, C), triangle_area(a, b, c), 1e-9);
    // Plain law of cosines, where it is well conditioned.
    if (a > 0.1 && b > 0.1 && c > 0.1) {
      const double cg = (std::cosh(a) * std::cosh(b) - std::cosh(c)) / (std::sinh(a) * std::sinh(b));
      EXPECT_NEAR(std::cos(gamma), cg, 1e-7);
    }
  }
  // Small triangles are nearly Euclidean.
  EXPECT_NEAR(law_of_cosines_angle(3e-5, 4e-5, 5e-5), M_PI / 2, 1e-8);
  EXPECT_NEAR(euclidean_angle(3, 4, 5), M_PI / 2, 1e-14);
  EXPECT_NEAR(euclidean_angle(1, 1, 1), M_PI / 3, 1e-14);
  // Degenerate inputs clamp instead of producing NaN.
  EXPECT_EQ(law_of_cosines_angle(1, 1, 2.5), M_PI);
  EXPECT_EQ(law_of_cosines_angle(1, 3, 1), 0.0);
}

TEST(Hyperbolic, IsometryFromPairs) {
  Rng rng;
  for (int t = 0; t < 100; ++t) {
    const Mobius m = rng.mobius();
    const Complex p0 = rng.point(0.8), p1 = rng.point(0.8);
    const Mobius r = isometry_from_pairs(p0, p1, m.apply(p0), m.apply(p1));
    EXPECT_LT(mobius_distance(r, m), 1e-9);
  }
}
