#include "surfmap/map/hyperbolic_harmonic.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/CholmodSupport>
#include <Eigen/Dense>
#include <Eigen/SparseCore>

#include "surfmap/error.h"

namespace surfmap {
namespace {

using hyperbolic::Mobius;
using Complex = std::complex<double>;

Mobius effective(const WeightedEdge& e, const std::vector<Mobius>& deck) {
  return deck[e.i] * e.rho * deck[e.j].inverse();
}

// Moves z towards the origin with generators while that helps; returns the
// accumulated element.
Mobius reduce_towards_origin(Complex& z, const std::vector<Mobius>& moves) {
  Mobius acc;
  for (int guard = 0; guard < 64; ++guard) {
    double best = std::abs(z);
    int arg = -1;
    for (size_t k = 0; k < moves.size(); ++k) {
      const double r = std::abs(moves[k].apply(z));
      if (r < best - 1e-12) best = r, arg = static_cast<int>(k);
    }
    if (arg < 0) break;
    z = moves[arg].apply(z);
    acc = (moves[arg] * acc).normalized();
  }
  return acc;
}

}  // namespace

double hyperbolic_energy(const std::vector<WeightedEdge>& edges, const std::vector<Complex>& z,
                         const std::vector<Mobius>& deck) {
  double E = 0;
  for (const auto& e : edges) {
    const double d = hyperbolic::distance(z[e.i], effective(e, deck).apply(z[e.j]));
    E += e.w * d * d;
  }
  return E;
}

HyperbolicHarmonicResult hyperbolic_harmonic_map(int n, const std::vector<WeightedEdge>& edges,
                                                 const std::vector<Mobius>& generators, std::vector<Complex> z0,
                                                 const HyperbolicHarmonicOptions& options) {
  if (static_cast<int>(z0.size()) != n) throw InputError("hyperbolic_harmonic_map: one start point per vertex needed");
  for (int i = 0; i < n; ++i)
    if (!(std::abs(z0[i]) < 1)) throw InputError("hyperbolic_harmonic_map: start point of vertex " + std::to_string(i) + " is outside the disk");
  if (!options.fixed.empty() && static_cast<int>(options.fixed.size()) != n)
    throw InputError("hyperbolic_harmonic_map: the fixed mask needs one entry per vertex");
  std::vector<Mobius> moves;
  for (const auto& g : generators) moves.push_back(g), moves.push_back(g.inverse());

  HyperbolicHarmonicResult r;
  r.z = std::move(z0);
  r.vertex_deck.assign(n, Mobius());
  for (int i = 0; i < n; ++i) r.vertex_deck[i] = reduce_towards_origin(r.z[i], moves);

  double max_w = 0;
  for (const auto& e : edges) max_w = std::max(max_w, e.w);
  auto energy = [&](const std::vector<Complex>& z) { return hyperbolic_energy(edges, z, r.vertex_deck); };
  double E = energy(r.z);
  r.energy_history.push_back(E);
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> solver;
  solver.cholmod().print = 0;  // indefinite tries are expected and handled below
  bool analysed = false;
  for (int it = 0; it < options.max_iterations; ++it) {
    // Riemannian Newton (DESIGN.md §7). Unknowns: a tangent vector per
    // vertex in the orthonormal frame of the chart centring it (2 reals).
    // For the term w d(x, y)^2 seen from the chart centring x, y sits at t
    // on the diameter with direction u; the Hessian of ½d² is [1 -1; -1 1]
    // along u and [a -b; -b a] across it (a = d coth d, b = d / sinh d), and
    // y's own frame is rotated by theta = arg((T_x ∘ ρ ∘ T_{-y})'(0)).
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(edges.size() * 16 + 2 * n);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(2 * n);
    for (const auto& e : edges) {
      if (e.w <= 0) continue;
      const Mobius rho = effective(e, r.vertex_deck);
      const Mobius M = Mobius::centring(r.z[e.i]) * rho * Mobius::translation_to(r.z[e.j]);
      const Complex t = M.apply(Complex(0.0));
      const Complex li = hyperbolic::log_map(r.z[e.i], rho.apply(r.z[e.j]));
      const Complex lj = hyperbolic::log_map(r.z[e.j], rho.inverse().apply(r.z[e.i]));
      const double d = std::abs(li);
      g[2 * e.i] -= 2 * e.w * li.real(), g[2 * e.i + 1] -= 2 * e.w * li.imag();
      g[2 * e.j] -= 2 * e.w * lj.real(), g[2 * e.j + 1] -= 2 * e.w * lj.imag();
      const Complex u = std::abs(t) > 0 ? t / std::abs(t) : Complex(1.0, 0.0);
      const double a = d > 1e-8 ? d / std::tanh(d) : 1 + d * d / 3;
      const double b = d > 1e-8 ? d / std::sinh(d) : 1 - d * d / 6;
      Eigen::Vector2d uu(u.real(), u.imag()), un(-u.imag(), u.real());
      const Eigen::Matrix2d P = uu * uu.transpose() + a * un * un.transpose();
      const Eigen::Matrix2d Q = uu * uu.transpose() + b * un * un.transpose();
      const Complex rot = M.derivative(Complex(0.0));
      const double th = std::arg(rot);
      Eigen::Matrix2d R;
      R << std::cos(th), -std::sin(th), std::sin(th), std::cos(th);
      const Eigen::Matrix2d Hii = 2 * e.w * P, Hjj = 2 * e.w * R.transpose() * P * R, Hij = -2 * e.w * Q * R;
      for (int p = 0; p < 2; ++p)
        for (int q = 0; q < 2; ++q) {
          trip.emplace_back(2 * e.i + p, 2 * e.i + q, Hii(p, q));
          trip.emplace_back(2 * e.j + p, 2 * e.j + q, Hjj(p, q));
          trip.emplace_back(2 * e.i + p, 2 * e.j + q, Hij(p, q));
          trip.emplace_back(2 * e.j + q, 2 * e.i + p, Hij(p, q));
        }
    }
    // Held vertices (landmarks): no gradient and identity rows/columns, so
    // their Newton step is 0 and the other vertices see them as fixed.
    if (!options.fixed.empty()) {
      std::vector<Eigen::Triplet<double>> kept;
      kept.reserve(trip.size());
      for (const auto& t : trip)
        if (!options.fixed[t.row() / 2] && !options.fixed[t.col() / 2]) kept.push_back(t);
      for (int i = 0; i < n; ++i)
        if (options.fixed[i]) {
          g[2 * i] = g[2 * i + 1] = 0;
          kept.emplace_back(2 * i, 2 * i, max_w), kept.emplace_back(2 * i + 1, 2 * i + 1, max_w);
        }
      trip.swap(kept);
    }
    double gnorm = 0;
    for (int i = 0; i < n; ++i) gnorm = std::max(gnorm, std::hypot(g[2 * i], g[2 * i + 1]));
    r.gradient_history.push_back(gnorm);
    if (options.progress && !options.progress(it, E, gnorm)) throw Cancelled("harmonic map solve cancelled");
    if (gnorm <= options.tolerance * std::max(max_w, 1e-300)) {
      r.converged = true;
      r.iterations = it;
      break;
    }
    // A Levenberg shift keeps the factorisation definite: tiny where the
    // model is exact (the normal surplus d coth d − 1 is O(d²)), raised when
    // far from the optimum the frame bookkeeping leaves it indefinite.
    Eigen::SparseMatrix<double> H0(2 * n, 2 * n);
    H0.setFromTriplets(trip.begin(), trip.end());
    Eigen::SparseMatrix<double> H;
    for (double shift = 1e-9 * max_w;; shift *= 100) {
      Eigen::SparseMatrix<double> I(2 * n, 2 * n);
      I.setIdentity();
      H = H0 + shift * I;
      if (!analysed) solver.analyzePattern(H), analysed = true;
      solver.factorize(H);
      if (solver.info() == Eigen::Success) break;
      if (shift > 1e6 * max_w) throw SolveError("hyperbolic harmonic map: Hessian factorisation failed");
    }
    Eigen::VectorXd step = solver.solve(-g);
    // Far from the optimum the frame bookkeeping makes the model Hessian
    // inexact; fall back to the diagonally scaled gradient when the Newton
    // direction is not a descent direction.
    if (!(g.dot(step) < 0) || !step.allFinite()) {
      for (int k = 0; k < 2 * n; ++k) step[k] = -g[k] / std::max(H.coeff(k, k), 1e-300);
    }
    // Backtracking line search on E along the exponential map; the chart
    // centring z_i has its frame aligned with the disk's axes.
    double alpha = 1.0;
    std::vector<Complex> trial(n);
    bool accepted = false;
    double slope = g.dot(step);
    for (int ls = 0; ls < 40; ++ls) {
      for (int i = 0; i < n; ++i) trial[i] = hyperbolic::exp_map(r.z[i], alpha * Complex(step[2 * i], step[2 * i + 1]));
      const double Et = energy(trial);
      if (Et <= E + 1e-4 * alpha * slope || (Et < E && alpha < 1e-3)) {
        r.z.swap(trial);
        E = Et;
        accepted = true;
        break;
      }
      alpha *= 0.5;
    }
    r.iterations = it + 1;
    if (!accepted) {
      // No decrease along the Newton direction. Try the scaled gradient once
      // before concluding that round-off has been reached.
      Eigen::VectorXd gs(2 * n);
      for (int k = 0; k < 2 * n; ++k) gs[k] = -g[k] / std::max(H.coeff(k, k), 1e-300);
      for (double beta = 1.0; beta > 1e-8 && !accepted; beta *= 0.25) {
        for (int i = 0; i < n; ++i) trial[i] = hyperbolic::exp_map(r.z[i], beta * Complex(gs[2 * i], gs[2 * i + 1]));
        const double Et = energy(trial);
        if (Et < E) r.z.swap(trial), E = Et, accepted = true;
      }
      if (!accepted) {
        // Converged if the gradient is tiny, or if the decrease Newton still
        // predicts (−g·step/2) is below what E can resolve in floating point
        // (points near |z| = 1 make each distance carry ~1e-12 relative noise).
        r.converged = gnorm <= 1e4 * options.tolerance * std::max(max_w, 1e-300) || -0.5 * slope <= 1e-9 * E;
        break;
      }
    }
    r.energy_history.push_back(E);
    // Dynamic charts: bring far-out vertices back towards the origin.
    for (int i = 0; i < n; ++i)
      if (std::abs(r.z[i]) > 0.6) {
        const Mobius gk = reduce_towards_origin(r.z[i], moves);
        r.vertex_deck[i] = (gk * r.vertex_deck[i]).normalized();
      }
  }
  r.energy = E;
  return r;
}

}  // namespace surfmap
