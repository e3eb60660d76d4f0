// Genus >= 2 landmarks (docs/method.md §2.10; landmarks.h): the hyperbolic barrier
// continuation (hyperbolic_barrier_landmarks) and the held solves
// (hold_hyperbolic_landmarks). The flat case and the carried
// neighbourhoods are in landmarks.cpp.
#include "landmarks.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>

#include <Eigen/Eigenvalues>

#include "landmark_barrier.h"
#include "surfmap/error.h"
#include "surfmap/work_counters.h"
#include "surfmap/geometry/hyperbolic.h"

namespace surfmap::detail {

namespace {

// Second-order forward differentiation in N variables (value, gradient,
// Hessian): the hyperbolic edge and face terms below are compositions of
// Möbius maps, whose derivatives by hand are long and easy to get wrong.
template <int N>
struct Jet {
  double v = 0;
  Eigen::Matrix<double, N, 1> g = Eigen::Matrix<double, N, 1>::Zero();
  Eigen::Matrix<double, N, N> h = Eigen::Matrix<double, N, N>::Zero();
  Jet() = default;
  explicit Jet(double c) : v(c) {}
  static Jet variable(double x, int k) {
    Jet j(x);
    j.g[k] = 1;
    return j;
  }
};
template <int N>
Jet<N> operator+(Jet<N> a, const Jet<N>& b) {
  a.v += b.v, a.g += b.g, a.h += b.h;
  return a;
}
template <int N>
Jet<N> operator-(Jet<N> a, const Jet<N>& b) {
  a.v -= b.v, a.g -= b.g, a.h -= b.h;
  return a;
}
template <int N>
Jet<N> operator*(const Jet<N>& a, const Jet<N>& b) {
  Jet<N> r;
  r.v = a.v * b.v;
  r.g = a.v * b.g + b.v * a.g;
  r.h = a.v * b.h + b.v * a.h + a.g * b.g.transpose() + b.g * a.g.transpose();
  return r;
}
template <int N>
Jet<N> operator*(double c, Jet<N> a) {
  a.v *= c, a.g *= c, a.h *= c;
  return a;
}
template <int N>
Jet<N> operator+(Jet<N> a, double c) {
  a.v += c;
  return a;
}
template <int N>
Jet<N> operator+(double c, Jet<N> a) {
  a.v += c;
  return a;
}
// f(a) from f, f', f'' at a.v.
template <int N>
Jet<N> chain(const Jet<N>& a, double f0, double f1, double f2) {
  Jet<N> r;
  r.v = f0;
  r.g = f1 * a.g;
  r.h = f1 * a.h + f2 * a.g * a.g.transpose();
  return r;
}
template <int N>
Jet<N> reciprocal(const Jet<N>& a) {
  return chain(a, 1 / a.v, -1 / (a.v * a.v), 2 / (a.v * a.v * a.v));
}

template <int N>
struct CJet {
  Jet<N> re, im;
};
template <int N>
CJet<N> operator-(const CJet<N>& a, const CJet<N>& b) {
  return {a.re - b.re, a.im - b.im};
}
template <int N>
CJet<N> operator*(const CJet<N>& a, const CJet<N>& b) {
  return {a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re};
}
template <int N>
CJet<N> conj(const CJet<N>& a) {
  return {a.re, -1.0 * a.im};
}
template <int N>
Jet<N> norm(const CJet<N>& a) {
  return a.re * a.re + a.im * a.im;
}
template <int N>
CJet<N> operator/(const CJet<N>& a, const CJet<N>& b) {
  const Jet<N> inv = reciprocal(norm(b));
  const CJet<N> n = a * conj(b);
  return {n.re * inv, n.im * inv};
}
// c z + d for constants c, d.
template <int N>
CJet<N> affine(Complex c, const CJet<N>& z, Complex d) {
  return {c.real() * z.re - c.imag() * z.im + d.real(), c.real() * z.im + c.imag() * z.re + d.imag()};
}
template <int N>
CJet<N> apply(const hyperbolic::Mobius& m, const CJet<N>& z) {
  return affine(m.a, z, m.b) / affine(std::conj(m.b), z, std::conj(m.a));
}
template <int N>
CJet<N> complex_variable(Complex z, int k) {
  return {Jet<N>::variable(z.real(), k), Jet<N>::variable(z.imag(), k + 1)};
}
template <int N>
CJet<N> complex_constant(Complex z) {
  return {Jet<N>(z.real()), Jet<N>(z.imag())};
}

// asinh(√s)² and its first two derivatives in s (so that d² = 4 of it,
// s = |z−w|² / ((1−|z|²)(1−|w|²)), is smooth where the points meet).
void asinh_sq(double s, double& f0, double& f1, double& f2) {
  if (s < 1e-4) {  // series: cancellation in the closed form
    f0 = s * (1 + s * (-1.0 / 3 + s * (8.0 / 45 - s * 4.0 / 35)));
    f1 = 1 + s * (-2.0 / 3 + s * (8.0 / 15 - s * 16.0 / 35));
    f2 = -2.0 / 3 + s * (16.0 / 15 - s * 48.0 / 35);
    return;
  }
  const double q = std::sqrt(s), r = std::sqrt(1 + s), a = std::asinh(q);
  f0 = a * a;
  f1 = a / (q * r);
  f2 = (q * r - a * (1 + 2 * s)) / (2 * q * r * s * (1 + s));
}

// w d(z_i, ρ z_j)² with (z_i, z_j) the variables (x_i, y_i, x_j, y_j).
Jet<4> edge_term(Complex zi, Complex zj, const hyperbolic::Mobius& rho, double w) {
  const CJet<4> a = complex_variable<4>(zi, 0), b = apply(rho, complex_variable<4>(zj, 2));
  const Jet<4> s = norm(a - b) * reciprocal((1.0 + -1.0 * norm(a)) * (1.0 + -1.0 * norm(b)));
  double f0, f1, f2;
  asinh_sq(s.v, f0, f1, f2);
  return (4 * w) * chain(s, f0, f1, f2);
}
double edge_value(Complex zi, Complex zj, const hyperbolic::Mobius& rho, double w) {
  const double d = hyperbolic::distance(zi, rho.apply(zj));
  return w * d * d;
}

// The orientation measure of an image triangle (corners p0, p1, p2 in the
// Poincaré disk): twice the Euclidean area of its Klein-model triangle seen
// from the chart centring p0. Geodesics are straight in the Klein model, so
// its sign is the geodesic triangle's orientation, and it does not change
// when the whole triangle moves by an isometry fixing the corner's chart
// (unlike the area in one global chart, which shrinks towards |z| = 1).
double klein_area(Complex p0, Complex p1, Complex p2) {
  const Complex b = hyperbolic::centred(p0, p1), c = hyperbolic::centred(p0, p2);
  const Complex kb = 2.0 * b / (1.0 + std::norm(b)), kc = 2.0 * c / (1.0 + std::norm(c));
  return kb.real() * kc.imag() - kb.imag() * kc.real();
}
Jet<6> klein_area(Complex p0, Complex p1, Complex p2, const hyperbolic::Mobius& A1, const hyperbolic::Mobius& A2) {
  const CJet<6> z0 = complex_variable<6>(p0, 0), z1 = apply(A1, complex_variable<6>(p1, 2)),
                z2 = apply(A2, complex_variable<6>(p2, 4));
  const CJet<6> one = complex_constant<6>(Complex(1.0));
  const CJet<6> b = (z1 - z0) / (one - conj(z0) * z1), c = (z2 - z0) / (one - conj(z0) * z2);
  const Jet<6> sb = 2.0 * reciprocal(norm(b) + 1.0), sc = 2.0 * reciprocal(norm(c) + 1.0);
  return sb * sc * (b.re * c.im - b.im * c.re);
}

template <int N>
Eigen::Matrix<double, N, N> psd(const Eigen::Matrix<double, N, N>& K) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> es(K);
  return es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).asDiagonal() * es.eigenvectors().transpose();
}

// hyperbolic_barrier_landmarks' objective at fixed landmark positions,
// F(z) = E(z) + μ Σ_f φ(A_f(z) / c_f) (E = Σ w d(z_i, ρ z_j)²; A_f: the
// Klein area of face f's image with corners 1 and 2 brought into corner
// 0's chart by face_elements; c from barrier_reference_areas, μ set by the
// caller), and its derivatives in the free unknowns.
struct HyperbolicBarrierProblem {
  int n = 0;
  const std::vector<WeightedEdge>& edges;
  const RowMatrixX3i& F;
  const std::vector<hyperbolic::Mobius>& face_elements;  // 3 x #F
  const std::vector<int>& index;                         // number_free_vertices
  int m = 0;                                             // free unknowns
  std::vector<double> c;
  double mu = 0;

  // Corner 1 and 2 of face f into corner 0's chart.
  hyperbolic::Mobius A1(int f) const { return face_elements[3 * f]; }
  hyperbolic::Mobius A2(int f) const { return face_elements[3 * f + 2].inverse(); }
  double area(const std::vector<Complex>& z, int f) const {
    return klein_area(z[F(f, 0)], A1(f).apply(z[F(f, 1)]), A2(f).apply(z[F(f, 2)]));
  }
  double dirichlet(const std::vector<Complex>& z) const {
    double E = 0;
    for (const auto& e : edges) E += edge_value(z[e.i], z[e.j], e.rho, e.w);
    return E;
  }
  // F(z) (face_barrier); +inf when a face is not positively oriented or a
  // point left the disk.
  double objective(const std::vector<Complex>& z) const {
    for (int v = 0; v < n; ++v)
      if (!(std::abs(z[v]) < 1)) return std::numeric_limits<double>::infinity();
    const double B = face_barrier(c, [&](int f) { return area(z, f); });
    if (!(B < std::numeric_limits<double>::infinity())) return B;
    return dirichlet(z) + mu * B;
  }
  // Gradient g (2m: x, y of each free point) and, with H, the Hessian
  // (sparsity `pattern`): exact, or with every edge's and face's block
  // projected onto PSD (`project`; a descent direction always).
  void assemble(const std::vector<Complex>& z, Eigen::VectorXd& g, const std::vector<Eigen::Triplet<double>>& pattern,
                Eigen::SparseMatrix<double>* H, bool project) const {
    const bool hessian = H != nullptr;
    const int nf = static_cast<int>(F.rows());
    std::vector<Eigen::Triplet<double>> trip;
    if (hessian) {
      trip.reserve(2 * pattern.size());
      for (const auto& p : pattern) trip.emplace_back(p.row(), p.col(), 0.0);
    }
    g = Eigen::VectorXd::Zero(2 * m);
    auto scatter = [&](const int* vert, int k, const auto& jet) {
      for (int a = 0; a < k; ++a) {
        if (index[vert[a]] < 0) continue;
        g[2 * index[vert[a]]] += jet.g[2 * a], g[2 * index[vert[a]] + 1] += jet.g[2 * a + 1];
      }
      if (!hessian) return;
      auto K = jet.h;
      if (project) K = psd(K);
      for (int a = 0; a < k; ++a)
        for (int b = 0; b < k; ++b) {
          if (index[vert[a]] < 0 || index[vert[b]] < 0) continue;
          for (int u = 0; u < 2; ++u)
            for (int w = 0; w < 2; ++w) trip.emplace_back(2 * index[vert[a]] + u, 2 * index[vert[b]] + w, K(2 * a + u, 2 * b + w));
        }
    };
    for (const auto& e : edges) {
      if (e.w == 0 || (index[e.i] < 0 && index[e.j] < 0)) continue;
      const int vert[2] = {e.i, e.j};
      scatter(vert, 2, edge_term(z[e.i], z[e.j], e.rho, e.w));
    }
    for (int f = 0; f < nf; ++f) {
      const double x = area(z, f) / c[f];
      if (x >= 1) continue;
      const Jet<6> A = klein_area(z[F(f, 0)], z[F(f, 1)], z[F(f, 2)], A1(f), A2(f));
      // μ φ(A / c): φ' = 1 − 1/x, φ'' = 1/x².
      const Jet<6> B = chain(A, 0.0, mu * (1 - 1 / x) / c[f], mu / (x * x * c[f] * c[f]));
      const int vert[3] = {F(f, 0), F(f, 1), F(f, 2)};
      scatter(vert, 3, B);
    }
    if (hessian) H->setFromTriplets(trip.begin(), trip.end());
  }
};

// The landmarks' paths: each walks the geodesic from its free image to its
// lift; place(z, s) puts them at fraction s of the way (exactly on the
// lifts at s >= 1). With `bend` b != 0 each steps aside to its own left
// (right for b < 0) on the way, by b x its geodesic's length x sin(pi s)
// at fraction s (measured along the perpendicular at the point s of the
// way): two landmarks sent head on towards each other's places then pass
// side by side, a half twist of the pair (b = 1/2: they keep at least 0.87
// of their first distance apart), where on the geodesics they meet
// half-way and the faces between them must vanish.
struct LandmarkGeodesics {
  const std::vector<Complex>& free;
  const std::vector<int>& source;
  const std::vector<Complex>& lifts;
  std::vector<hyperbolic::Mobius> back;
  std::vector<Complex> far;
  double bend = 0;

  LandmarkGeodesics(const std::vector<Complex>& free_points, const std::vector<int>& landmarks,
                    const std::vector<Complex>& lift_points)
      : free(free_points), source(landmarks), lifts(lift_points), back(landmarks.size()), far(landmarks.size()) {
    for (size_t a = 0; a < source.size(); ++a) {
      const hyperbolic::Mobius C = hyperbolic::Mobius::centring(free[source[a]]);
      back[a] = C.inverse(), far[a] = C.apply(lifts[a]);
    }
  }
  void place(std::vector<Complex>& z, double s) const {
    for (size_t a = 0; a < source.size(); ++a) {
      const double r = std::abs(far[a]);
      if (s >= 1 || r == 0) {
        z[source[a]] = s >= 1 ? lifts[a] : free[source[a]];
        continue;
      }
      const Complex u = far[a] / r;
      const Complex p = std::tanh(s * std::atanh(r)) * u;  // s of the way along the geodesic (centred chart)
      if (bend == 0) {
        z[source[a]] = back[a].apply(p);
        continue;
      }
      // Aside by h along the perpendicular at p: the point at distance h on
      // the perpendicular at 0, carried to p by the translation along the
      // geodesic (z + p) / (1 + conj(p) z).
      const double h = bend * 2 * std::atanh(r) * std::sin(M_PI * s);
      const Complex q = std::tanh(h / 2) * Complex(0, 1) * u;
      z[source[a]] = back[a].apply((q + p) / (1.0 + std::conj(p) * q));
    }
  }
};

}  // namespace

HyperbolicBarrierResult hyperbolic_barrier_landmarks(int n, const std::vector<WeightedEdge>& edges,
                                                     const RowMatrixX3i& F,
                                                     const std::vector<hyperbolic::Mobius>& face_elements,
                                                     const std::vector<Complex>& free, const std::vector<int>& source,
                                                     const std::vector<Complex>& lifts,
                                                     const std::function<bool(int, double, double)>& progress) {
  HyperbolicBarrierResult out;
  const int nf = static_cast<int>(F.rows());
  if (static_cast<int>(face_elements.size()) != 3 * nf || static_cast<int>(free.size()) != n)
    throw InputError("hyperbolic_barrier_landmarks: face_elements needs 3 x #F entries and free #V");
  std::vector<int> index;
  const int m = number_free_vertices(n, source, index);
  HyperbolicBarrierProblem problem{n, edges, F, face_elements, index, m, {}, 0.0};
  if (!barrier_reference_areas(nf, [&](int f) { return problem.area(free, f); }, problem.c)) return out;
  problem.mu = problem.dirichlet(free) / nf;
  auto objective = [&](const std::vector<Complex>& z) { return problem.objective(z); };
  const std::vector<Eigen::Triplet<double>> pattern = barrier_hessian_pattern(edges, F, index);
  Eigen::SparseMatrix<double> H(2 * m, 2 * m);
  H.setFromTriplets(pattern.begin(), pattern.end());
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> llt;
  llt.cholmod().print = 0;  // an indefinite exact Hessian is expected (then projected), not worth a warning
  llt.analyzePattern(H);
  ++work::analyses;
  auto assemble = [&](const std::vector<Complex>& z, Eigen::VectorXd& g, bool hessian, bool project) {
    problem.assemble(z, g, pattern, hessian ? &H : nullptr, project);
  };
  // Convergence: the largest per-vertex gradient in the metric (Euclidean
  // gradient times (1 − |z|²)/2) against the free map's largest w d.
  double scale = 0;
  for (const auto& e : edges) scale = std::max(scale, std::abs(e.w) * hyperbolic::distance(free[e.i], e.rho.apply(free[e.j])));
  auto gradient_norm = [&](const std::vector<Complex>& z, const Eigen::VectorXd& g) {
    double r = 0;
    for (int v = 0; v < n; ++v)
      if (index[v] >= 0)
        r = std::max(r, std::hypot(g[2 * index[v]], g[2 * index[v] + 1]) * 0.5 * hyperbolic::conformal_denominator(z[v]));
    return r;
  };
  // Gradient at z and the Newton matrix factorised: the exact Hessian
  // when it is positive definite, else every term's block projected.
  auto factorise_at = [&](const std::vector<Complex>& z, Eigen::VectorXd& g) {
    for (int project = 0; project < 2; ++project) {
      assemble(z, g, true, project);
      llt.factorize(H);
      ++work::factorisations;
      if (llt.info() == Eigen::Success) return true;
    }
    return false;
  };
  auto newton = [&](std::vector<Complex>& z, int max_it) {
    double Fz = objective(z);
    for (int it = 0; it < max_it; ++it) {
      Eigen::VectorXd g, step;
      if (!factorise_at(z, g)) return false;
      const double gn = gradient_norm(z, g);
      if (progress && !progress(out.newton_iterations, Fz, gn)) throw Cancelled("harmonic map solve cancelled");
      if (gn <= 1e-10 * scale) return true;
      step = llt.solve(-g);
      double slope = g.dot(step);
      if (!(slope < 0)) {  // the exact model was not a descent direction
        assemble(z, g, true, true);
        llt.factorize(H);
        ++work::factorisations;
        if (llt.info() != Eigen::Success) return false;
        step = llt.solve(-g), slope = g.dot(step);
      }
      bool tiny = false;
      if (!armijo_step(z, Fz, step, slope, index, objective, 1e-13, tiny)) return false;
      ++out.newton_iterations;
      if (tiny) return true;
    }
    return true;
  };
  LandmarkGeodesics paths(free, source, lifts);
  auto place = [&](std::vector<Complex>& z, double s) { paths.place(z, s); };
  // Euler predictor along the path of optima: the free unknowns' response
  // −H⁻¹ ∂g/∂s to the landmarks' move (∂g/∂s by a difference).
  auto predict = [&](const std::vector<Complex>& z, double s, double next) {
    std::vector<Complex> trial = z;
    const double h = 1e-6;
    Eigen::VectorXd g0, g1;
    std::vector<Complex> zh = z;
    place(zh, s + h);
    assemble(zh, g1, false, false);
    if (factorise_at(z, g0)) {
      const Eigen::VectorXd d = llt.solve(-(g1 - g0) / h);
      for (int v = 0; v < n; ++v)
        if (index[v] >= 0) trial[v] += (next - s) * Complex(d[2 * index[v]], d[2 * index[v] + 1]);
    }
    return trial;
  };
  std::vector<Complex> z = free;
  double s = barrier_continuation(z, predict, place, objective, newton, out.steps);
  out.reached = s;
  // Stalled with more than one landmark: two of them may be meeting head on
  // (sent to each other's places: on their geodesics they meet half-way).
  // Again from the free map, each stepping aside to its left, then to its
  // right (LandmarkGeodesics::bend; docs/history/handle_classes.md "Session 25").
  for (double bend : {0.5, -0.5}) {
    if (s >= 1 || source.size() < 2) break;
    paths.bend = bend;
    z = free;
    s = barrier_continuation(z, predict, place, objective, newton, out.steps);
    out.reached = std::max(out.reached, s);
    out.bend = bend;
  }
  if (s < 1) return out;
  place(z, 1.0);
  newton(z, 40);
  if (!std::isfinite(objective(z))) return out;
  out.ok = true;
  out.energy = problem.dirichlet(z);
  out.z = std::move(z);
  return out;
}

namespace {

// The deck image of `target` nearest to z in hyperbolic distance: breadth
// first over deck images of the target point under words in `moves`,
// keeping only those that stay within reach of z (around a corner of the
// domain the nearest lift can need a word of length ~4g).
Complex nearest_deck_image(Complex z, Complex target, const std::vector<hyperbolic::Mobius>& moves) {
  Complex best = target;
  double best_d = hyperbolic::distance(z, best);
  const double reach = std::max(best_d, 1.0) + 4.0;
  std::set<std::pair<long long, long long>> seen;
  auto key = [](Complex w) { return std::make_pair(std::llround(w.real() * 1e9), std::llround(w.imag() * 1e9)); };
  std::vector<Complex> frontier{best};
  seen.insert(key(best));
  for (int depth = 1; depth <= 2 * static_cast<int>(moves.size()) + 2 && !frontier.empty(); ++depth) {
    std::vector<Complex> next;
    for (const Complex& q : frontier)
      for (const auto& m : moves) {
        const Complex w = m.apply(q);
        const double d = hyperbolic::distance(z, w);
        if (d > reach || !seen.insert(key(w)).second) continue;
        if (d < best_d) best_d = d, best = w;
        next.push_back(w);
      }
    if (seen.size() > 200000) break;
    frontier.swap(next);
  }
  return best;
}

// hold_hyperbolic_landmarks' held solves, all in the free optimum's charts
// (`held_edges`: the edges with the free solve's effective elements).
struct HeldLandmarkSolve {
  int n = 0;
  const std::vector<WeightedEdge>& held_edges;
  const std::vector<hyperbolic::Mobius>& generators;
  const HyperbolicHarmonicResult& free;
  const std::vector<int>& source;
  const std::vector<Complex>& lift;  // per landmark, its target point's nearest deck image
  const HyperbolicHarmonicOptions& options;
  bool relaxation = false;
  const HarmonicRelaxationOptions& relaxation_options;

  // One held solve with the landmarks' neighbourhoods (patches; vertex 0
  // the landmark) held: each patch vertex at the image of its free point
  // under the isometry moving the landmark's free image to its lift along
  // the geodesic (conjugated into the vertex's own chart by the edge
  // elements along the patch's tree), every other vertex starting at its
  // free point (the free optimum's charts). The vertex decks returned are
  // relative to the original edges (the free decks composed back).
  HyperbolicHarmonicResult operator()(const std::vector<LandmarkPatch>& patches) const {
    using hyperbolic::Mobius;
    std::vector<Complex> z0 = free.z;
    HyperbolicHarmonicOptions ho = options;
    ho.fixed.assign(n, 0);
    for (size_t a = 0; a < patches.size(); ++a) {
      const LandmarkPatch& P = patches[a];
      const Complex p = free.z[source[a]], q = lift[a];
      const Mobius C = Mobius::centring(p);
      const Mobius T = (Mobius::translation_to(p) * Mobius::translation_to(C.apply(q)) * C).normalized();
      std::vector<Mobius> to_landmark(P.vertex.size());  // vertex q's chart -> the landmark's
      for (size_t r = 0; r < P.vertex.size(); ++r) {
        const int v = P.vertex[r];
        if (r > 0) {
          const Mobius& rho = held_edges[P.edge[r]].rho;  // j's chart into i's
          to_landmark[r] = (to_landmark[P.parent[r]] * (P.head[r] ? rho : rho.inverse())).normalized();
        }
        z0[v] = r == 0 ? q : to_landmark[r].inverse().apply(T.apply(to_landmark[r].apply(free.z[v])));
        ho.fixed[v] = 1;
      }
    }
    HyperbolicHarmonicResult held;
    if (relaxation) {
      HarmonicRelaxationOptions ro = relaxation_options;
      ro.fixed = ho.fixed;
      held = as_harmonic_result(harmonic_relaxation(n, held_edges, generators, z0, ro));
    } else {
      held = hyperbolic_harmonic_map(n, held_edges, generators, z0, ho);
    }
    for (int i = 0; i < n; ++i) held.vertex_deck[i] = (held.vertex_deck[i] * free.vertex_deck[i]).normalized();
    if (free.vertex_deck_word.size() == static_cast<size_t>(n) && held.vertex_deck_word.size() == static_cast<size_t>(n))
      for (int i = 0; i < n; ++i) held.vertex_deck_word[i] = concat(held.vertex_deck_word[i], free.vertex_deck_word[i]);
    else
      held.vertex_deck_word.clear();
    return held;
  }
};

// The barrier continuation's result as a held harmonic map: the free
// optimum's charts and decks with the continuation's points, and every
// solver edge (`held_edges`, in those charts) in the charts of its ends,
// A_e = C_i^-1 ρ_e C_j (C_i: the translation taking 0 to z[i]), as the
// Newton solve leaves them. (Cleared, the quality stage rebuilt them for the
// source's edges only, leaving the intrinsic Delaunay triangulation's other
// edges at the identity: their triangles were counted flipped.)
HyperbolicHarmonicResult barrier_as_held(const HyperbolicHarmonicResult& free, const HyperbolicBarrierResult& br,
                                         const std::vector<WeightedEdge>& held_edges) {
  using hyperbolic::Mobius;
  HyperbolicHarmonicResult held = free;  // same charts and decks, new points
  held.z = br.z;
  held.energy = br.energy;
  held.iterations = br.newton_iterations;
  held.energy_history = {br.energy};
  held.gradient_history.clear();
  held.edge_local.resize(held_edges.size());
  for (size_t e = 0; e < held_edges.size(); ++e) {
    const WeightedEdge& w = held_edges[e];
    held.edge_local[e] = (Mobius::centring(br.z[w.i]) * w.rho * Mobius::translation_to(br.z[w.j])).normalized();
  }
  held.converged = true;
  return held;
}

}  // namespace

HyperbolicHarmonicResult hold_hyperbolic_landmarks(int n, const std::vector<WeightedEdge>& edges,
                                                   const std::vector<hyperbolic::Mobius>& generators,
                                                   const std::vector<hyperbolic::Mobius>& side_pairings,
                                                   const HyperbolicHarmonicResult& free, const std::vector<int>& source,
                                                   const std::vector<Complex>& target_position,
                                                   const std::vector<int>& target_vertex,
                                                   HyperbolicHarmonicOptions options, bool relaxation,
                                                   HarmonicRelaxationOptions relaxation_options,
                                                   const RowMatrixX3i* faces,
                                                   const std::function<std::vector<int>(const HyperbolicHarmonicResult&)>&
                                                       bad_faces,
                                                   LandmarkHold* hold, const std::vector<hyperbolic::Mobius>* face_elements) {
  using hyperbolic::Mobius;
  // Side pairings move the layout's cut disk to its neighbours (short
  // translations); the loop generators can be long (entries ~1e5 seen in
  // the layout frame), and words that come back near z would be pruned.
  std::vector<Mobius> moves;
  for (const auto& g : side_pairings) moves.push_back(g), moves.push_back(g.inverse());
  // The solve runs in the free optimum's charts: effective edge elements and
  // its points (all near the origin) as the start.
  std::vector<WeightedEdge> held_edges = edges;
  // (The free solve's own effective elements when it has them: well
  // conditioned, unlike products of its vertex decks.)
  const bool have_effective = free.edge_effective.size() == edges.size();
  for (size_t k = 0; k < held_edges.size(); ++k) {
    auto& e = held_edges[k];
    e.rho = have_effective ? free.edge_effective[k]
                           : (free.vertex_deck[e.i] * e.rho * free.vertex_deck[e.j].inverse()).normalized();
    e.rho_word.clear();  // the held solve runs without words (no relator)
  }
  options.relator.clear();
  std::vector<Complex> lift(source.size());
  for (size_t k = 0; k < source.size(); ++k) lift[k] = nearest_deck_image(free.z[source[k]], target_position[k], moves);
  const HeldLandmarkSolve held_solve{n,    held_edges, generators, free, source, lift, options,
                                     relaxation, relaxation_options};
  std::vector<LandmarkPatch> pins(source.size());
  for (size_t a = 0; a < source.size(); ++a)
    pins[a].vertex = {source[a]}, pins[a].parent = {-1}, pins[a].edge = {-1}, pins[a].head = {0};
  LandmarkHold record;
  record.method = "pinned";
  record.rings.assign(source.size(), 0);
  record.solves = 1;
  record.held_vertices = static_cast<int>(source.size());
  if (hold) *hold = record;
  HyperbolicHarmonicResult pinned = held_solve(pins);
  if (!faces || !bad_faces) return pinned;
  if (!pinned.converged)
    throw SolveError("the harmonic map with the landmarks held did not converge in " +
                     std::to_string(pinned.iterations) + " iterations");
  const std::vector<int> pinned_bad = bad_faces(pinned);
  if (pinned_bad.empty()) return pinned;
  // Plain pins fold: the barrier continuation (the bijective held map of
  // least energy up to its barrier), then carried neighbourhoods.
  if (face_elements) {
    const HyperbolicBarrierResult br =
        hyperbolic_barrier_landmarks(n, held_edges, *faces, *face_elements, free.z, source, lift, options.progress);
    record.barrier_steps = br.steps, record.barrier_newton_iterations = br.newton_iterations;
    record.barrier_reached = br.reached;
    record.solves += br.steps;
    if (br.ok) {
      HyperbolicHarmonicResult held = barrier_as_held(free, br, held_edges);
      if (bad_faces(held).empty()) {
        record.method = "barrier continuation";
        if (hold) *hold = record;
        return held;
      }
    }
  }
  std::vector<std::pair<int, int>> ends(held_edges.size()), pairs(source.size());
  for (size_t e = 0; e < held_edges.size(); ++e) ends[e] = {held_edges[e].i, held_edges[e].j};
  for (size_t a = 0; a < source.size(); ++a) pairs[a] = {source[a], target_vertex[a]};
  HyperbolicHarmonicResult accepted;
  LandmarkPatchSearch found;
  try {
    found = grow_landmark_patches(n, ends, *faces, pairs, [&](const std::vector<LandmarkPatch>& patches) {
      bool plain = true;
      for (const auto& P : patches) plain = plain && P.vertex.size() == 1;
      if (plain) {  // the plain pins, solved above
        accepted = pinned;
        return pinned_bad;
      }
      accepted = held_solve(patches);
      if (!accepted.converged)
        throw SolveError("the harmonic map with the landmarks held did not converge in " +
                         std::to_string(accepted.iterations) + " iterations");
      return bad_faces(accepted);
    });
  } catch (const SolveError& e) {
    if (!face_elements) throw;
    throw SolveError("the landmarks cannot be held bijectively: the barrier continuation stalled " +
                     std::to_string(static_cast<int>(100 * record.barrier_reached)) + "% of the way to them, and " +
                     e.what());
  }
  record.method = "carried neighbourhoods";
  record.rings = found.rings;
  record.solves += found.solves - 1;  // its first round is the plain pins
  record.held_vertices = found.held_vertices;
  if (hold) *hold = record;
  return accepted;
}

}  // namespace surfmap::detail
