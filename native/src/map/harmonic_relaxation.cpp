#include "surfmap/map/harmonic_relaxation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "../seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/geometry/dynamic_charts.h"
#include "surfmap/topology/words.h"

namespace surfmap {
namespace {

using hyperbolic::Mobius;
using Complex = std::complex<double>;
using Clock = std::chrono::steady_clock;

using detail::seconds_since;

// Complex division without the C99 inf/nan special cases (__divdc3) that
// dominate the sweep otherwise; the denominators here are never zero (they
// are b̄z + ā and 1 − p̄y with |z|, |p|, |y| < 1).
inline Complex quick_div(Complex num, Complex den) { return num * std::conj(den) / std::norm(den); }

// exp_p(ξ) = T_{−p}(tanh(|ξ|/2) ξ/|ξ|), T_{−p}(u) = (u + p) / (1 + p̄ u).
inline Complex quick_exp(Complex p, Complex xi) {
  const double n = std::sqrt(std::norm(xi));
  if (n == 0.0) return p;
  const Complex u = (std::tanh(n / 2) / n) * xi;
  return quick_div(u + p, 1.0 + std::conj(p) * u);
}

// m(z) for an SU(1,1) element.
inline Complex quick_apply(const Mobius& m, Complex z) { return quick_div(m.a * z + m.b, std::conj(m.b) * z + std::conj(m.a)); }

// Moves z towards the origin (geometry/dynamic_charts.h, the same rule as
// the Newton solver's dynamic charts); returns the element applied, and in
// `moved` whether any move was.
// `word` (optional): the element as a word in the generators' letters
// (move 2k is generator k, letter k + 1; move 2k + 1 its inverse, -(k + 1)),
// product order as written, as HyperbolicHarmonicResult::vertex_deck_word.
Mobius move_towards_origin(Complex& z, const std::vector<Mobius>& moves, bool* moved = nullptr, Word* word = nullptr) {
  Mobius acc;
  const std::vector<int> applied = reduce_towards_origin(Mobius::translation_to(z), moves);
  for (int k : applied) {
    z = moves[k].apply(z);
    acc = (moves[k] * acc).normalized();
  }
  if (word) {
    word->clear();
    for (auto it = applied.rbegin(); it != applied.rend(); ++it) word->push_back(*it % 2 == 0 ? *it / 2 + 1 : -(*it / 2 + 1));
    *word = reduce(*word);
  }
  if (moved) *moved = !applied.empty();
  return acc;
}

// Incident edges per vertex (CSR): edge index and whether the vertex is the
// edge's tail i (the neighbour's image is then ρ z_j) or its head j (ρ⁻¹ z_i).
struct Incidence {
  std::vector<int> start, edge;
  std::vector<char> is_tail;
};

template <class EdgeEnds>
Incidence incidence(int n, size_t m, EdgeEnds ends) {
  Incidence inc;
  inc.start.assign(n + 1, 0);
  for (size_t e = 0; e < m; ++e) {
    const auto [i, j] = ends(e);
    ++inc.start[i + 1], ++inc.start[j + 1];
  }
  for (int v = 0; v < n; ++v) inc.start[v + 1] += inc.start[v];
  inc.edge.resize(inc.start[n]);
  inc.is_tail.resize(inc.start[n]);
  std::vector<int> fill(inc.start.begin(), inc.start.end() - 1);
  for (size_t e = 0; e < m; ++e) {
    const auto [i, j] = ends(e);
    inc.edge[fill[i]] = static_cast<int>(e), inc.is_tail[fill[i]++] = 1;
    inc.edge[fill[j]] = static_cast<int>(e), inc.is_tail[fill[j]++] = 0;
  }
  return inc;
}

// Weights must be >= 0; cotangents of an intrinsic Delaunay triangulation
// can come out as −1e-17 from round-off, which is accepted (and used as 0).
void check_edges(int n, const std::vector<int>& ei, const std::vector<int>& ej, const std::vector<double>& w,
                 const char* who) {
  double max_w = 0;
  for (double x : w) max_w = std::max(max_w, std::abs(x));
  for (size_t e = 0; e < ei.size(); ++e) {
    if (ei[e] < 0 || ei[e] >= n || ej[e] < 0 || ej[e] >= n || ei[e] == ej[e])
      throw InputError(std::string(who) + ": edge " + std::to_string(e) + " has invalid endpoints " +
                       std::to_string(ei[e]) + ", " + std::to_string(ej[e]));
    if (!(w[e] >= -1e-12 * max_w) || !std::isfinite(w[e]))
      throw InputError(std::string(who) + ": edge " + std::to_string(e) + " has weight " + std::to_string(w[e]) +
                       "; weights must be finite and >= 0");
  }
}

void check_options(const HarmonicRelaxationOptions& o, int n, const char* who) {
  if (!(o.step > 0 && o.step <= 1)) throw InputError(std::string(who) + ": step must lie in (0, 1]");
  if (o.max_iterations < 0) throw InputError(std::string(who) + ": max_iterations must be >= 0");
  if (o.check_every < 1) throw InputError(std::string(who) + ": check_every must be >= 1");
  if (!o.fixed.empty() && static_cast<int>(o.fixed.size()) != n)
    throw InputError(std::string(who) + ": the fixed mask needs one entry per vertex");
}

// The sweep / evaluate / stop loop shared by the flat and the hyperbolic
// versions. `sweep()` relaxes every vertex once; `evaluate(E, g)` computes the
// energy and the largest per-vertex gradient length.
template <class Sweep, class Evaluate>
void relax_loop(HarmonicRelaxationResult& r, double max_w, const HarmonicRelaxationOptions& options, Sweep sweep,
                Evaluate evaluate) {
  const auto t0 = Clock::now();
  double sweep_time = 0;
  auto record = [&](int s) {
    double E = 0, g = 0;
    evaluate(E, g);
    r.energy_history.push_back(E), r.gradient_history.push_back(g);
    r.time_history.push_back(sweep_time), r.sweep_history.push_back(s);
    r.energy = E;
    if (options.progress && !options.progress(s, E, g)) throw Cancelled("harmonic relaxation cancelled");
    return g <= options.tolerance * std::max(max_w, 1e-300);
  };
  if (record(0)) {
    r.converged = true, r.stop_reason = "tolerance";
  } else {
    r.stop_reason = "iteration cap";
    for (int s = 1; s <= options.max_iterations; ++s) {
      const auto ts = Clock::now();
      sweep();
      sweep_time += seconds_since(ts);
      r.iterations = s;
      const bool last = s == options.max_iterations;
      const bool over_budget = options.time_budget_s > 0 && sweep_time >= options.time_budget_s;
      if (s % options.check_every == 0 || last || over_budget) {
        if (record(s)) {
          r.converged = true, r.stop_reason = "tolerance";
          break;
        }
      }
      if (over_budget) {
        r.stop_reason = "time budget";
        break;
      }
    }
  }
  r.time_s = seconds_since(t0);
}

}  // namespace

HarmonicRelaxationResult harmonic_relaxation(int n, const std::vector<WeightedEdge>& edges,
                                             const std::vector<Mobius>& generators, std::vector<Complex> z0,
                                             const HarmonicRelaxationOptions& options) {
  const char* who = "harmonic_relaxation";
  check_options(options, n, who);
  if (static_cast<int>(z0.size()) != n) throw InputError("harmonic_relaxation: one start point per vertex needed");
  for (int i = 0; i < n; ++i)
    if (!(std::abs(z0[i]) < 1))
      throw InputError("harmonic_relaxation: start point of vertex " + std::to_string(i) + " is outside the disk");
  {
    std::vector<int> ei(edges.size()), ej(edges.size());
    std::vector<double> w(edges.size());
    for (size_t e = 0; e < edges.size(); ++e) ei[e] = edges[e].i, ej[e] = edges[e].j, w[e] = edges[e].w;
    check_edges(n, ei, ej, w, who);
  }
  std::vector<Mobius> moves;
  for (const auto& g : generators) moves.push_back(g), moves.push_back(g.inverse());

  HarmonicRelaxationResult r;
  r.z = std::move(z0);
  r.vertex_deck.assign(n, Mobius());
  r.vertex_deck_word.assign(n, Word{});
  for (int i = 0; i < n; ++i) r.vertex_deck[i] = move_towards_origin(r.z[i], moves, nullptr, &r.vertex_deck_word[i]);
  // Effective element per edge (i -> j) and its inverse, kept up to date
  // when a vertex changes chart.
  std::vector<Mobius> eff(edges.size()), eff_inv(edges.size());
  auto refresh = [&](size_t e) {
    eff[e] = (r.vertex_deck[edges[e].i] * edges[e].rho * r.vertex_deck[edges[e].j].inverse()).normalized();
    eff_inv[e] = eff[e].inverse();
  };
  for (size_t e = 0; e < edges.size(); ++e) refresh(e);
  const Incidence inc = incidence(n, edges.size(), [&](size_t e) { return std::make_pair(edges[e].i, edges[e].j); });
  double max_w = 0;
  for (const auto& e : edges) max_w = std::max(max_w, e.w);

  // Image of vertex v's k-th neighbour in the current charts.
  auto neighbour_image = [&](int k) {
    const int e = inc.edge[k];
    return inc.is_tail[k] ? quick_apply(eff[e], r.z[edges[e].j]) : quick_apply(eff_inv[e], r.z[edges[e].i]);
  };
  // Local energy Σ w d(p, y_k)² of vertex v at p.
  auto local_energy = [&](int v, Complex p) {
    double s = 0;
    for (int k = inc.start[v]; k < inc.start[v + 1]; ++k) {
      if (edges[inc.edge[k]].w <= 0) continue;
      const double d = hyperbolic::distance(p, neighbour_image(k));
      s += edges[inc.edge[k]].w * d * d;
    }
    return s;
  };
  std::vector<double> settled(n, 0.0);  // |z|² below which the chart test is skipped
  const bool any_fixed = !options.fixed.empty();
  auto sweep = [&]() {
    for (int v = 0; v < n; ++v) {
      if (any_fixed && options.fixed[v]) continue;
      // The chart centring p = z_v: T(y) = (y − p) / (1 − p̄ y) (SU(1,1) scale cancels).
      const Complex p = r.z[v], pc = std::conj(p);
      Complex sum(0.0);
      double W = 0, e_old = 0, d_max = 0;
      for (int k = inc.start[v]; k < inc.start[v + 1]; ++k) {
        const double w = edges[inc.edge[k]].w;
        if (w <= 0) continue;
        // log_{z_v}(y) in the chart centring z_v.
        const Complex y = neighbour_image(k);
        const Complex t = quick_div(y - p, 1.0 - pc * y);
        const double a = std::sqrt(std::norm(t));
        if (a == 0) {
          W += w;
          continue;
        }
        const double d = 2.0 * std::atanh(a);
        sum += w * d * (t / a);
        W += w;
        e_old += w * d * d;
        d_max = std::max(d_max, d);
      }
      if (W <= 0) continue;
      Complex xi = options.step * sum / W;
      Complex next = quick_exp(p, xi);
      // Step ½ is a decrease for image edges shorter than ~3.8 (file
      // comment); longer ones are checked and the step halved if needed.
      if (d_max > 1.5) {
        for (int bt = 0; bt < 30 && local_energy(v, next) > e_old; ++bt) {
          xi *= 0.5;
          next = quick_exp(p, xi);
        }
        if (local_energy(v, next) > e_old) continue;
      }
      r.z[v] = next;
    }
    // Dynamic charts: bring far-out vertices back towards the origin. A
    // vertex that no generator brings closer is re-tried only once it has
    // drifted further out (the fundamental domain reaches beyond 0.6).
    // The vertex's edges are conjugated by the element applied (ρ' ← γ ρ'
    // where v is the tail, ρ' ← ρ' γ⁻¹ where it is the head), not rebuilt
    // from the accumulated decks, whose matrices grow without bound on a far
    // start and whose product then keeps no digits.
    for (int v = 0; v < n; ++v) {
      const double r2 = std::norm(r.z[v]);
      if (r2 <= 0.36 || r2 <= settled[v]) continue;
      bool moved = false;
      Word wk;
      const Mobius gk = move_towards_origin(r.z[v], moves, &moved, &wk);
      const double after = std::norm(r.z[v]);
      settled[v] = std::min(1.0, std::sqrt(after) + 0.02) * std::min(1.0, std::sqrt(after) + 0.02);
      if (!moved) continue;
      r.vertex_deck[v] = (gk * r.vertex_deck[v]).normalized();
      r.vertex_deck_word[v] = concat(wk, r.vertex_deck_word[v]);
      for (int k = inc.start[v]; k < inc.start[v + 1]; ++k) {
        const size_t e = inc.edge[k];
        if (edges[e].i == v) eff[e] = (gk * eff[e]).normalized();
        if (edges[e].j == v) eff[e] = (eff[e] * gk.inverse()).normalized();
        eff_inv[e] = eff[e].inverse();
      }
    }
  };
  std::vector<Complex> grad(n);
  auto evaluate = [&](double& E, double& g) {
    E = 0;
    std::fill(grad.begin(), grad.end(), Complex(0.0));
    for (size_t e = 0; e < edges.size(); ++e) {
      if (edges[e].w <= 0) continue;
      const int i = edges[e].i, j = edges[e].j;
      const Complex li = hyperbolic::log_map(r.z[i], eff[e].apply(r.z[j]));
      const Complex lj = hyperbolic::log_map(r.z[j], eff_inv[e].apply(r.z[i]));
      E += edges[e].w * std::norm(li);
      grad[i] -= 2 * edges[e].w * li, grad[j] -= 2 * edges[e].w * lj;
    }
    g = 0;
    for (int v = 0; v < n; ++v)
      if (!any_fixed || !options.fixed[v]) g = std::max(g, std::abs(grad[v]));
  };
  relax_loop(r, max_w, options, sweep, evaluate);
  r.edge_effective = std::move(eff);
  return r;
}

HarmonicRelaxationResult flat_harmonic_relaxation(int n, const std::vector<int>& ei, const std::vector<int>& ej,
                                                  const std::vector<double>& w, const std::vector<Complex>& t,
                                                  std::vector<Complex> z0, const HarmonicRelaxationOptions& options) {
  const char* who = "flat_harmonic_relaxation";
  check_options(options, n, who);
  if (static_cast<int>(z0.size()) != n) throw InputError("flat_harmonic_relaxation: one start point per vertex needed");
  if (ej.size() != ei.size() || w.size() != ei.size() || t.size() != ei.size())
    throw InputError("flat_harmonic_relaxation: edge_i, edge_j, weight and translation must have the same size");
  check_edges(n, ei, ej, w, who);
  HarmonicRelaxationResult r;
  r.z = std::move(z0);
  r.vertex_deck.assign(n, Mobius());
  const Incidence inc = incidence(n, ei.size(), [&](size_t e) { return std::make_pair(ei[e], ej[e]); });
  double max_w = 0;
  for (double x : w) max_w = std::max(max_w, x);
  const bool any_fixed = !options.fixed.empty();
  auto sweep = [&]() {
    for (int v = 0; v < n; ++v) {
      if (any_fixed && options.fixed[v]) continue;
      Complex sum(0.0);
      double W = 0;
      for (int k = inc.start[v]; k < inc.start[v + 1]; ++k) {
        const int e = inc.edge[k];
        if (w[e] <= 0) continue;
        // Image of the neighbour: z_j + t from the tail, z_i − t from the head.
        const Complex y = inc.is_tail[k] ? r.z[ej[e]] + t[e] : r.z[ei[e]] - t[e];
        sum += w[e] * (y - r.z[v]);
        W += w[e];
      }
      if (W > 0) r.z[v] += options.step * sum / W;
    }
  };
  std::vector<Complex> grad(n);
  auto evaluate = [&](double& E, double& g) {
    E = 0;
    std::fill(grad.begin(), grad.end(), Complex(0.0));
    for (size_t e = 0; e < ei.size(); ++e) {
      if (w[e] <= 0) continue;
      const Complex d = r.z[ej[e]] + t[e] - r.z[ei[e]];
      E += w[e] * std::norm(d);
      grad[ei[e]] -= 2 * w[e] * d, grad[ej[e]] += 2 * w[e] * d;
    }
    g = 0;
    for (int v = 0; v < n; ++v)
      if (!any_fixed || !options.fixed[v]) g = std::max(g, std::abs(grad[v]));
  };
  relax_loop(r, max_w, options, sweep, evaluate);
  return r;
}

HyperbolicHarmonicResult as_harmonic_result(HarmonicRelaxationResult r) {
  HyperbolicHarmonicResult h;
  h.converged = r.converged;
  h.iterations = r.iterations;
  h.energy_history = std::move(r.energy_history);
  h.gradient_history = std::move(r.gradient_history);
  h.z = std::move(r.z);
  h.vertex_deck = std::move(r.vertex_deck);
  h.vertex_deck_word = std::move(r.vertex_deck_word);
  h.edge_effective = std::move(r.edge_effective);
  h.energy = r.energy;
  return h;
}

}  // namespace surfmap
