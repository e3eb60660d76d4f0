// Boundary vertices sliding along geodesics in the hyperbolic harmonic map
// (HyperbolicHarmonicOptions::boundary_slide, issue 16: the half of an open
// surface's double with its boundary on the target's geodesic boundary).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <complex>
#include <random>
#include <utility>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/map/hyperbolic_harmonic.h"

namespace surfmap {
namespace {

using Complex = std::complex<double>;
using hyperbolic::Mobius;

// An N x N grid of the unit square (two triangles per cell, counter-clockwise)
// put into the hyperbolic strip between the real diameter (bottom row) and
// its translate by `height` along the imaginary axis (top row): vertex (a, b)
// at T_{i height b/(N-1)}(tanh(x_a / 2)), x_a from -width/2 to width/2.
// The left and right columns are held; the bottom and top rows (corners
// excepted) slide on their row's geodesic. Weights 1 on every edge.
struct Strip {
  int N = 9;
  double width = 1.6, height = 0.9;
  std::vector<WeightedEdge> edges;
  std::vector<std::array<int, 3>> faces;
  std::vector<Complex> rest;  // the grid's placement
  Mobius bottom, top;         // the rows' geodesics: G(real diameter)
  HyperbolicHarmonicOptions options;

  int id(int a, int b) const { return b * N + a; }
  Strip() {
    bottom = Mobius();
    top = Mobius::translation(Complex(0.0, height));
    rest.resize(N * N);
    for (int b = 0; b < N; ++b)
      for (int a = 0; a < N; ++a) {
        const double x = width * (static_cast<double>(a) / (N - 1) - 0.5);
        rest[id(a, b)] = Mobius::translation(Complex(0.0, height * b / (N - 1))).apply(Complex(std::tanh(x / 2), 0.0));
      }
    auto edge = [&](int i, int j) {
      WeightedEdge e;
      e.i = i, e.j = j, e.w = 1.0;
      edges.push_back(e);
    };
    for (int b = 0; b < N; ++b)
      for (int a = 0; a < N; ++a) {
        if (a + 1 < N) edge(id(a, b), id(a + 1, b));
        if (b + 1 < N) edge(id(a, b), id(a, b + 1));
        if (a + 1 < N && b + 1 < N) {
          edge(id(a, b), id(a + 1, b + 1));
          faces.push_back({id(a, b), id(a + 1, b), id(a + 1, b + 1)});
          faces.push_back({id(a, b), id(a + 1, b + 1), id(a, b + 1)});
        }
      }
    options.fixed.assign(N * N, 0);
    for (int b = 0; b < N; ++b) options.fixed[id(0, b)] = options.fixed[id(N - 1, b)] = 1;
  }
  // Sliding rows on: bottom and top rows but their corners.
  void slide() {
    options.boundary_slide.slides.assign(N * N, 0);
    options.boundary_slide.geodesic.assign(N * N, Mobius());
    for (int a = 1; a + 1 < N; ++a) {
      options.boundary_slide.slides[id(a, 0)] = options.boundary_slide.slides[id(a, N - 1)] = 1;
      options.boundary_slide.geodesic[id(a, N - 1)] = top;
    }
  }
  // The edges between consecutive sliding vertices of a row, ordered.
  void order() {
    for (size_t e = 0; e < edges.size(); ++e) {
      const int i = edges[e].i, j = edges[e].j;
      const bool row = j == i + 1 && (i / N == 0 || i / N == N - 1) && i % N >= 1 && j % N <= N - 2;
      if (row) options.boundary_slide.ordered_edges.push_back(static_cast<int>(e));
    }
  }
  // A start: the grid's placement with the free and sliding vertices moved
  // at random (up to `amount` in the disk's coordinates, off the geodesics too).
  std::vector<Complex> start(double amount, unsigned seed) const {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-amount, amount);
    std::vector<Complex> z = rest;
    for (int v = 0; v < N * N; ++v)
      if (!options.fixed[v]) z[v] += Complex(u(rng), u(rng));
    return z;
  }
  double off_geodesic(const std::vector<Complex>& z, int v) const {
    const Complex x = (v / N == 0 ? bottom : top).inverse().apply(z[v]);
    return std::asinh(2 * std::abs(x.imag()) / (1 - std::norm(x)));
  }
  // Faces whose image (Klein model: straight sides) turns over.
  int flipped(const std::vector<Complex>& z) const {
    int count = 0;
    for (const auto& f : faces) {
      Complex k[3];
      for (int c = 0; c < 3; ++c) k[c] = 2.0 * z[f[c]] / (1.0 + std::norm(z[f[c]]));
      count += ((k[1] - k[0]) * std::conj(k[2] - k[0])).imag() >= 0;  // counter-clockwise is negative here
    }
    return count;
  }
  // The point of the row's geodesic nearest z (straight perpendicular in the Klein model).
  Complex projected(Complex z, int v) const {
    const Mobius& G = v / N == 0 ? bottom : top;
    const Complex x = G.inverse().apply(z);
    const double k = (2.0 * x / (1.0 + std::norm(x))).real();
    return G.apply(Complex(k / (1 + std::sqrt(1 - k * k)), 0.0));
  }
};

TEST(HyperbolicBoundarySlide, SlidingVerticesEndOnTheirGeodesicsAtNoMoreEnergyThanTheProjectedMap) {
  Strip s;
  const std::vector<Complex> z0 = s.start(0.05, 7);
  // Unconstrained: the rows move off their geodesics (towards each other).
  const HyperbolicHarmonicResult free = hyperbolic_harmonic_map(s.N * s.N, s.edges, {}, z0, s.options);
  ASSERT_TRUE(free.converged);
  double free_off = 0;
  for (int a = 1; a + 1 < s.N; ++a) free_off = std::max(free_off, s.off_geodesic(free.z, s.id(a, s.N - 1)));
  EXPECT_GT(free_off, 1e-3);
  std::vector<Complex> projected = free.z;
  for (int a = 1; a + 1 < s.N; ++a)
    for (int b : {0, s.N - 1}) projected[s.id(a, b)] = s.projected(free.z[s.id(a, b)], s.id(a, b));
  const std::vector<Mobius> identity(s.N * s.N);
  const double E_projected = hyperbolic_energy(s.edges, projected, identity);

  s.slide();
  s.order();
  const HyperbolicHarmonicResult r = hyperbolic_harmonic_map(s.N * s.N, s.edges, {}, z0, s.options);
  ASSERT_TRUE(r.converged);
  EXPECT_LT(r.slide_off_geodesic, 1e-12);
  for (int a = 1; a + 1 < s.N; ++a)
    for (int b : {0, s.N - 1}) EXPECT_LT(s.off_geodesic(r.z, s.id(a, b)), 1e-12) << a << ", " << b;
  EXPECT_NEAR(r.energy, hyperbolic_energy(s.edges, r.z, identity), 1e-12 * r.energy);
  EXPECT_LE(r.energy, E_projected);
  EXPECT_GE(r.energy, free.energy - 1e-12 * free.energy);  // a constrained minimum
  EXPECT_LT(r.energy, E_projected - 1e-6 * E_projected);   // the projection is not the optimum
  EXPECT_EQ(s.flipped(r.z), 0);
  EXPECT_EQ(s.flipped(s.rest), 0);
  EXPECT_EQ(r.order_rejections, 0);
  // The same optimum from another start (the restricted energy is convex; a start that keeps
  // the rows in order: larger moves would swap neighbours, which the order check keeps).
  const HyperbolicHarmonicResult other = hyperbolic_harmonic_map(s.N * s.N, s.edges, {}, s.start(0.03, 11), s.options);
  ASSERT_TRUE(other.converged);
  for (int v = 0; v < s.N * s.N; ++v) EXPECT_LT(hyperbolic::distance(other.z[v], r.z[v]), 1e-7) << v;
  // Tangential balance at the sliding vertices: moving one along its geodesic
  // by +-1e-4 raises the energy.
  for (int a : {2, 5})
    for (double t : {-1e-4, 1e-4}) {
      std::vector<Complex> moved = r.z;
      const int v = s.id(a, 0);
      const Complex x = s.bottom.inverse().apply(moved[v]);
      moved[v] = s.bottom.apply(Mobius::translation(Complex(t, 0.0)).apply(x));
      EXPECT_GT(hyperbolic_energy(s.edges, moved, identity), r.energy);
    }
}

TEST(HyperbolicBoundarySlide, OrderedEdgesKeepConsecutiveImagesFromPassingEachOther) {
  // Two bottom-row vertices start swapped along their geodesic: unordered,
  // the solve uncrosses them (the optimum); with the row's edges ordered, the
  // line search never lets a head pass its tail, so they stay in the start's
  // order (and the trials that would have swapped them are counted).
  Strip s;
  s.slide();
  std::vector<Complex> z0 = s.rest;
  std::swap(z0[s.id(3, 0)], z0[s.id(4, 0)]);
  auto side = [&](const std::vector<Complex>& z) {
    return s.bottom.inverse().apply(z[s.id(4, 0)]).real() - s.bottom.inverse().apply(z[s.id(3, 0)]).real();
  };
  ASSERT_LT(side(z0), 0);
  const HyperbolicHarmonicResult unordered = hyperbolic_harmonic_map(s.N * s.N, s.edges, {}, z0, s.options);
  ASSERT_TRUE(unordered.converged);
  EXPECT_GT(side(unordered.z), 0);
  EXPECT_EQ(s.flipped(unordered.z), 0);
  s.order();
  const HyperbolicHarmonicResult ordered = hyperbolic_harmonic_map(s.N * s.N, s.edges, {}, z0, s.options);
  EXPECT_LT(side(ordered.z), 0);
  EXPECT_GT(ordered.order_rejections, 0);
  for (int a = 1; a + 2 < s.N; ++a) {
    const double d = s.bottom.inverse().apply(ordered.z[s.id(a + 1, 0)]).real() -
                     s.bottom.inverse().apply(ordered.z[s.id(a, 0)]).real();
    EXPECT_EQ(d > 0, a != 3) << a;  // only the swapped pair 3, 4 out of order
  }
  EXPECT_GT(ordered.energy, unordered.energy);
}

TEST(HyperbolicBoundarySlide, PullsTowardAGeodesicAreMinimisedWithTheEdges) {
  // A pull 3 dist(z_v, bottom)^2 on the centre vertex (the half's share of a double's edge from
  // v to its mirror image): the solve converges, its energy is the edges' plus the pull's at the
  // result, the centre ends nearer the bottom geodesic than without the pull, and moving the
  // centre a little in any direction raises the energy (a minimum, the pull's gradient included).
  Strip s;
  s.slide();
  s.order();
  const int centre = s.id(s.N / 2, s.N / 2);
  const HyperbolicHarmonicResult plain = hyperbolic_harmonic_map(s.N * s.N, s.edges, {}, s.rest, s.options);
  ASSERT_TRUE(plain.converged);
  s.options.boundary_slide.pulls.push_back({centre, 3.0, s.bottom});
  const HyperbolicHarmonicResult r = hyperbolic_harmonic_map(s.N * s.N, s.edges, {}, s.rest, s.options);
  ASSERT_TRUE(r.converged);
  const std::vector<Mobius> identity(s.N * s.N);
  auto total = [&](const std::vector<Complex>& z) {
    const Complex x = s.bottom.inverse().apply(z[centre]);
    const double delta = std::asinh(2 * std::abs(x.imag()) / (1 - std::norm(x)));
    return hyperbolic_energy(s.edges, z, identity) + 3.0 * delta * delta;
  };
  EXPECT_NEAR(r.energy, total(r.z), 1e-10 * r.energy);
  EXPECT_LT(std::abs(r.z[centre].imag()), std::abs(plain.z[centre].imag()) - 1e-3);
  for (Complex step : {Complex(1e-4, 0), Complex(-1e-4, 0), Complex(0, 1e-4), Complex(0, -1e-4)}) {
    std::vector<Complex> moved = r.z;
    moved[centre] = Mobius::translation_to(r.z[centre]).apply(step);
    EXPECT_GT(total(moved), r.energy);
  }
  // (No flip count here: a pull towards a geodesic beyond the vertex's star, as this one, may
  // fold the star; in the doubles a pull is a Delaunay edge to the vertex's own mirror image.)
}

TEST(HyperbolicBoundarySlide, BadInputIsRefused) {
  Strip s;
  s.slide();
  s.options.boundary_slide.geodesic.pop_back();
  EXPECT_THROW(hyperbolic_harmonic_map(s.N * s.N, s.edges, {}, s.rest, s.options), InputError);
  Strip t;
  t.slide();
  t.options.boundary_slide.slides[t.id(0, 0)] = 1;  // held and sliding
  EXPECT_THROW(hyperbolic_harmonic_map(t.N * t.N, t.edges, {}, t.rest, t.options), InputError);
  Strip u;
  u.slide();
  u.options.boundary_slide.ordered_edges = {static_cast<int>(u.edges.size())};
  EXPECT_THROW(hyperbolic_harmonic_map(u.N * u.N, u.edges, {}, u.rest, u.options), InputError);
}

}  // namespace
}  // namespace surfmap
