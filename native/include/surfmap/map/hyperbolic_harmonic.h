#pragma once
// Discrete harmonic map into a hyperbolic surface (paper §VI-B; DESIGN.md
// §2.8 and §7): minimises E(z) = Σ_e w_e d(z_i, ρ_e z_j)² over one point z_i
// per vertex in the Poincaré disk, with a deck element ρ_e per edge i->j and
// weights w_e >= 0. E is geodesically convex (the disk is a Hadamard space),
// so the minimiser in the homotopy class fixed by ρ is unique.
//
// Method: Laplacian-preconditioned Riemannian descent. The gradient at z_i is
// −2 Σ w log_{z_i}(ρ z_j) in the orthonormal frame of the chart centring z_i
// (where frames of neighbours agree up to a rotation of order the edge
// length); the step solves (L + D) ξ = Σ w log(...) with the weight
// Laplacian L and the diagonal D of the normal-block surplus d·coth d − 1
// (DESIGN.md §7), factorised once, then z_i ← exp_{z_i}(α ξ_i) with a
// backtracking line search on E. Vertices that wander far from the origin are
// moved back by deck elements (the algebraic form of the paper's dynamic
// charts, §VI-A): z_i ← γ z_i and, implicitly, ρ_e ← γ_i ρ_e γ_j⁻¹.
#include <complex>
#include <functional>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"

namespace surfmap {

struct HyperbolicHarmonicOptions {
  /// Stop when the largest per-vertex gradient length is below this times
  /// the largest weight-scaled edge length (default 1e-10).
  double tolerance = 1e-10;
  int max_iterations = 300;
  /// Called every iteration with (iteration, energy, gradient norm); return
  /// false to cancel (throws Cancelled).
  std::function<bool(int, double, double)> progress;
  /// #V or empty (default): vertices held at their start point (landmarks,
  /// paper §VII-C). Their Newton step is zero; the chart moves may still
  /// re-express them by a deck element, which is the same point of the surface.
  std::vector<char> fixed;
};

struct WeightedEdge {
  int i = -1, j = -1;
  double w = 0;
  hyperbolic::Mobius rho;  ///< image of the edge runs from z_i to rho(z_j)
};

struct HyperbolicHarmonicResult {
  bool converged = false;
  int iterations = 0;
  std::vector<double> energy_history, gradient_history;
  /// #V points in the Poincaré disk and the deck element applied to each
  /// vertex while solving: the effective element of edge i->j is
  /// vertex_deck[i] * rho * vertex_deck[j]^-1.
  std::vector<std::complex<double>> z;
  std::vector<hyperbolic::Mobius> vertex_deck;
  double energy = 0;
};

/// `generators`: the deck group's generators (their inverses are used too)
/// for moving vertices back towards the origin. `z0`: #V start points.
HyperbolicHarmonicResult hyperbolic_harmonic_map(int num_vertices, const std::vector<WeightedEdge>& edges,
                                                 const std::vector<hyperbolic::Mobius>& generators,
                                                 std::vector<std::complex<double>> z0,
                                                 const HyperbolicHarmonicOptions& options = {});

/// E(z) for the given effective deck elements (for independent checks).
double hyperbolic_energy(const std::vector<WeightedEdge>& edges, const std::vector<std::complex<double>>& z,
                         const std::vector<hyperbolic::Mobius>& vertex_deck);

}  // namespace surfmap
