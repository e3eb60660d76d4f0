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

// Moves z towards the origin with the moves while that helps; returns the
// indices of the moves applied, in order.
std::vector<int> reduce_towards_origin(Complex& z, const std::vector<Mobius>& moves) {
  std::vector<int> applied;
  for (int guard = 0; guard < 64; ++guard) {
    double best = std::abs(z);
    int arg = -1;
    for (size_t k = 0; k < moves.size(); ++k) {
      const double r = std::abs(moves[k].apply(z));
      if (r < best - 1e-12) best = r, arg = static_cast<int>(k);
    }
    if (arg < 0) break;
    z = moves[arg].apply(z);
    applied.push_back(arg);
  }
  return applied;
}

// SU(1,1) arithmetic in long double for re-deriving long-lived edges
// (below): about three more digits than double on x86.
struct LongMobius {
  using C = std::complex<long double>;
  C a{1.0L, 0.0L}, b{0.0L, 0.0L};
  static LongMobius from(const Mobius& m) { return {C(m.a.real(), m.a.imag()), C(m.b.real(), m.b.imag())}; }
  LongMobius operator*(const LongMobius& o) const { return {a * o.a + b * std::conj(o.b), a * o.b + b * std::conj(o.a)}; }
  LongMobius inverse() const { return {std::conj(a), -b}; }
  LongMobius normalized() const {
    const long double det = std::norm(a) - std::norm(b);
    if (!(det > 0) || !(std::norm(a) + std::norm(b) < 1e7L)) return *this;
    const long double s = 1.0L / std::sqrt(det);
    return {a * s, b * s};
  }
  Mobius to_double() const {
    return {Complex(static_cast<double>(a.real()), static_cast<double>(a.imag())),
            Complex(static_cast<double>(b.real()), static_cast<double>(b.imag()))};
  }
};

// Move index (2k: generator k, 2k+1: its inverse) as a word letter.
int move_letter(int m) { return m % 2 == 0 ? m / 2 + 1 : -(m / 2 + 1); }

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
  double largest_w = 0;
  for (const auto& ed : edges) largest_w = std::max(largest_w, std::abs(ed.w));
  for (size_t e = 0; e < edges.size(); ++e) {
    const auto& ed = edges[e];
    // i == j is allowed: intrinsic triangulations can have loop edges, and
    // w d(z_i, ρ z_i)² is an ordinary term.
    if (ed.i < 0 || ed.i >= n || ed.j < 0 || ed.j >= n)
      throw InputError("hyperbolic_harmonic_map: edge " + std::to_string(e) + " has an endpoint out of range");
    // Intrinsic Delaunay weights are >= -1e-12 (its flip tolerance); they
    // are used as 0. Clearly negative weights would make E non-convex.
    if (!std::isfinite(ed.w) || ed.w < -1e-9 * largest_w)
      throw InputError("hyperbolic_harmonic_map: edge " + std::to_string(e) + " has weight " + std::to_string(ed.w) +
                       " (weights must be finite and >= 0)");
  }

  // The solve runs in charts (paper §VI-A, done algebraically): vertex i has
  // a chart C_i (an isometry with C_i(0) = z_i, its frame parallel-transported
  // along the steps), and every edge its element in the charts of its ends,
  // A_e = C_i^-1 ρ_e C_j, so that the image of the edge runs from 0 to A_e(0)
  // in i's chart. Energies, gradients and Hessians are read off A_e alone:
  // d = 2 asinh|b|, direction b/ā, frame rotation arg A_e'(0) = 2 arg a. A step
  // ξ updates C_i ← C_i τ(ξ_i) and A_e ← τ(ξ_i)^-1 A_e τ(ξ_j) with the exact
  // translations τ, so no quantity is ever formed from points near |z| = 1 or
  // from products with the (possibly huge) deck matrices, and the far edges of
  // a bad start (translation length 30: entries 1e6) cost no digits either.
  // Moving a vertex to another sheet (C_i ← γ C_i, ρ_e ← γ ρ_e) leaves A_e
  // unchanged; it only keeps C_i small and is recorded in the vertex decks.
  HyperbolicHarmonicResult r;
  std::vector<Mobius> chart(n);
  for (int i = 0; i < n; ++i) chart[i] = Mobius::translation_to(z0[i]);
  std::vector<Mobius> A(edges.size());
  for (size_t e = 0; e < edges.size(); ++e)
    A[e] = (chart[edges[e].i].inverse() * edges[e].rho * chart[edges[e].j]).normalized();
  // Edges longer than ~70 units at the start (entries beyond 1e15; a class
  // twisted by dozens of tiles, seen from a start at the origin) would take
  // the solve hundreds of capped steps (minutes at genus 5 when the class
  // ranking tries such classes), and no map with such an edge is an
  // embedding of a mesh of this size: refused at once.
  for (size_t e = 0; e < edges.size(); ++e)
    if (!(A[e].size() < 1e15))
      throw SolveError("hyperbolic harmonic map: edge " + std::to_string(e) + " starts " +
                       std::to_string(A[e].displacement_of_origin()) +
                       " units long (deck element beyond double range for this solve)");
  r.vertex_deck.assign(n, Mobius());
  r.vertex_deck_word.assign(n, Word{});
  auto evaluate_word = [&](const Word& w) {
    Mobius m;
    for (int x : w) {
      const int k = std::abs(x) - 1;
      if (k < 0 || k >= static_cast<int>(generators.size()))
        throw InputError("hyperbolic_harmonic_map: letter " + std::to_string(x) + " names no generator");
      m = (m * moves[x > 0 ? 2 * k : 2 * k + 1]).normalized();
    }
    return m;
  };
  auto move_vertex = [&](int v) {
    Complex z = chart[v].apply(Complex(0.0));
    if (options.reduce_point) {
      const Word w = options.reduce_point(z);
      if (w.empty()) return;
      const Mobius gamma = evaluate_word(w);
      chart[v] = (gamma * chart[v]).normalized();
      r.vertex_deck[v] = (gamma * r.vertex_deck[v]).normalized();
      r.vertex_deck_word[v] = concat(w, r.vertex_deck_word[v]);
      return;
    }
    const std::vector<int> applied = reduce_towards_origin(z, moves);
    for (int m : applied) {
      chart[v] = (moves[m] * chart[v]).normalized();
      r.vertex_deck[v] = (moves[m] * r.vertex_deck[v]).normalized();
      r.vertex_deck_word[v] = concat(Word{move_letter(m)}, r.vertex_deck_word[v]);
    }
  };
  for (int i = 0; i < n; ++i) move_vertex(i);

  double max_w = 0;
  for (const auto& e : edges) max_w = std::max(max_w, e.w);
  auto energy_of = [&](const std::vector<Mobius>& a) {
    double E = 0;
    for (size_t e = 0; e < edges.size(); ++e) {
      if (edges[e].w <= 0) continue;
      const double d = a[e].displacement_of_origin();
      E += edges[e].w * d * d;
    }
    return E;
  };
  double E = energy_of(A);
  r.energy_history.push_back(E);
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> solver;
  solver.cholmod().print = 0;  // indefinite tries are expected and handled below
  bool analysed = false;
  std::vector<Mobius> trial_A(edges.size()), step_map(n);
  // Trial edge elements for the step alpha * xi (all vertices at once).
  auto trial_edges = [&](const Eigen::VectorXd& xi, double alpha) {
    for (int i = 0; i < n; ++i) step_map[i] = Mobius::translation(alpha * Complex(xi[2 * i], xi[2 * i + 1]));
    for (size_t e = 0; e < edges.size(); ++e)
      trial_A[e] = (step_map[edges[e].i].inverse() * A[e] * step_map[edges[e].j]).normalized();
  };
  auto accept = [&](double Et) {
    A.swap(trial_A);
    for (int i = 0; i < n; ++i) chart[i] = (chart[i] * step_map[i]).normalized();
    E = Et;
  };
  // Re-deriving long-lived edges from words. Updating A_e in place keeps
  // an error of round-off times the largest size A_e ever had; evaluating
  // C_i^-1 ρ_eff C_j afresh (ρ_eff = deck_i ρ_e deck_j^-1 as a reduced word,
  // short once the edge is short) costs round-off times |C_i||ρ_eff||C_j|
  // plus the drift of the charts, which are long products themselves. The
  // charts' drift puts re-derived and updated edges in slightly different
  // frames (measured: 1e-5 relative energy differences between starts on a
  // genus-6 self-map when re-deriving from sizes 1e4), so it is used only
  // for edges that were beyond 1e8 (absolute error 1e-8 and worse), where
  // the updated matrix is the worse of the two.
  const bool words = !options.relator.empty();
  if (words)
    for (size_t e = 0; e < edges.size(); ++e)
      if (edges[e].rho_word.empty() && hyperbolic::distance_from_identity(edges[e].rho) > 1e-12)
        throw InputError("hyperbolic_harmonic_map: edge " + std::to_string(e) +
                         " has no rho_word although a relator was given");
  // peak: the error scale A_e carries (its largest size since it was last
  // derived afresh); tried: the iteration at which re-deriving last did not
  // pay (the charts were still far), so that it is retried a few iterations
  // later rather than every iteration; the final pass tries every edge.
  std::vector<double> peak(edges.size());
  std::vector<int> tried(edges.size(), -1000);
  int iteration = 0;
  for (size_t e = 0; e < edges.size(); ++e) peak[e] = A[e].size();
  const DehnReducer reduce_word(words ? options.relator : Word{});
  auto refresh = [&](bool final_pass) {
    if (!words) return;
    for (size_t e = 0; e < edges.size(); ++e) {
      peak[e] = std::max(peak[e], A[e].size());
      if (peak[e] < 1e8 || (!final_pass && (A[e].size() * 100 > peak[e] || iteration - tried[e] < 4))) continue;
      const WeightedEdge& ed = edges[e];
      const Word w = reduce_word(concat({r.vertex_deck_word[ed.i], ed.rho_word, inverse(r.vertex_deck_word[ed.j])}));
      LongMobius rho_eff;
      for (int x : w) {
        const int k = std::abs(x) - 1;
        rho_eff = (rho_eff * LongMobius::from(moves[x > 0 ? 2 * k : 2 * k + 1])).normalized();
      }
      const double rho_size = static_cast<double>(std::abs(rho_eff.a) + std::abs(rho_eff.b));
      const double cost = 1e-3 * chart[ed.i].size() * rho_size * chart[ed.j].size();  // long double: ~3 more digits
      if (cost * 10 < peak[e]) {
        const LongMobius ci = LongMobius::from(chart[ed.i]), cj = LongMobius::from(chart[ed.j]);
        A[e] = (ci.inverse() * rho_eff * cj).normalized().to_double().normalized();
        peak[e] = std::max(cost, A[e].size());
      } else {
        tried[e] = iteration;
      }
    }
  };
  for (int it = 0; it < options.max_iterations; ++it) {
    // Riemannian Newton (DESIGN.md §7). Unknowns: a tangent vector per
    // vertex in the orthonormal frame of its chart at 0 (2 reals). For the
    // term w d(x, y)^2 seen from x's chart, y = A_e(0) lies on the diameter
    // with direction u; the Hessian of ½d² is [1 -1; -1 1] along u and
    // [a -b; -b a] across it (a = d coth d, b = d / sinh d), and y's own
    // frame is rotated by theta = arg A_e'(0).
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(edges.size() * 16 + 2 * n);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(2 * n);
    for (size_t ei = 0; ei < edges.size(); ++ei) {
      const WeightedEdge& e = edges[ei];
      if (e.w <= 0) continue;
      const Mobius& M = A[ei];
      const double d = M.displacement_of_origin();
      const double bn = std::abs(M.b);
      // log_0(A(0)) = d · (b/ā)/|b| in i's chart; log_0(A^-1(0)) = d · (−b/a)/|b| in j's.
      const Complex u = bn > 0 ? (M.b / std::conj(M.a)) * (std::abs(M.a) / bn) : Complex(1.0, 0.0);
      const Complex uj = bn > 0 ? (-M.b / M.a) * (std::abs(M.a) / bn) : Complex(1.0, 0.0);
      const Complex li = d * u, lj = d * uj;
      g[2 * e.i] -= 2 * e.w * li.real(), g[2 * e.i + 1] -= 2 * e.w * li.imag();
      g[2 * e.j] -= 2 * e.w * lj.real(), g[2 * e.j + 1] -= 2 * e.w * lj.imag();
      const double a = d > 1e-8 ? d / std::tanh(d) : 1 + d * d / 3;
      const double b = d > 1e-8 ? d / std::sinh(d) : 1 - d * d / 6;
      Eigen::Vector2d uu(u.real(), u.imag()), un(-u.imag(), u.real());
      const Eigen::Matrix2d P = uu * uu.transpose() + a * un * un.transpose();
      const Eigen::Matrix2d Q = uu * uu.transpose() + b * un * un.transpose();
      const double th = 2.0 * std::arg(M.a);  // arg A'(0) = arg 1/ā²
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
    if (!g.allFinite() || !std::isfinite(E))
      throw SolveError("hyperbolic harmonic map: non-finite energy or gradient at iteration " + std::to_string(it));
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
    // Backtracking line search on E. The first trial moves no vertex by more
    // than kMaxStep (a bad start can ask for steps of 30 units, whose
    // translations have entries e^15), which only rescales the Newton step.
    constexpr double kMaxStep = 4.0;
    double longest = 0;
    for (int i = 0; i < n; ++i) longest = std::max(longest, std::hypot(step[2 * i], step[2 * i + 1]));
    double alpha = longest > kMaxStep ? kMaxStep / longest : 1.0;
    bool accepted = false;
    const double slope = g.dot(step);
    // Newton decrement below the round-off of E (a sum of #E terms): the
    // gradient is at its floating-point floor.
    if (-0.5 * slope <= 1e-13 * E) {
      r.converged = true;
      r.iterations = it;
      break;
    }
    for (int ls = 0; ls < 40; ++ls) {
      trial_edges(step, alpha);
      const double Et = energy_of(trial_A);
      if (Et < E && (Et <= E + 1e-4 * alpha * slope || alpha < 1e-3)) {
        accept(Et);
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
      double gl = 0;
      for (int i = 0; i < n; ++i) gl = std::max(gl, std::hypot(gs[2 * i], gs[2 * i + 1]));
      for (double beta = gl > kMaxStep ? kMaxStep / gl : 1.0; beta > 1e-8 && !accepted; beta *= 0.25) {
        trial_edges(gs, beta);
        const double Et = energy_of(trial_A);
        if (Et < E) accept(Et), accepted = true;
      }
      if (!accepted) {
        // Converged if the gradient is tiny, or if the decrease Newton still
        // predicts (−g·step/2) is below what E can resolve in floating point.
        r.converged = gnorm <= 1e4 * options.tolerance * std::max(max_w, 1e-300) || -0.5 * slope <= 1e-9 * E;
        break;
      }
    }
    r.energy_history.push_back(E);
    // Dynamic charts: bring far-out vertices back towards the origin.
    for (int i = 0; i < n; ++i)
      if (options.reduce_point || std::abs(chart[i].b) > 0.75) move_vertex(i);  // greedy: |C_i(0)| > 0.6
    iteration = it + 1;
    refresh(false);
  }
  refresh(true);
  r.energy = E;
  r.z.resize(n);
  for (int i = 0; i < n; ++i) r.z[i] = chart[i].apply(Complex(0.0));
  r.edge_local = A;
  r.edge_effective.resize(edges.size());
  for (size_t e = 0; e < edges.size(); ++e)
    r.edge_effective[e] = (chart[edges[e].i] * A[e] * chart[edges[e].j].inverse()).normalized();
  return r;
}

}  // namespace surfmap
