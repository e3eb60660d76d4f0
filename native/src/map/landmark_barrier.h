// The pieces the flat and hyperbolic barrier continuations share
// (flat_barrier_landmarks in landmarks.cpp, hyperbolic_barrier_landmarks in
// hyperbolic_landmarks.cpp; landmarks.h): free unknowns, reference areas,
// the barrier, the Hessian's pattern, the line search and the continuation
// in s itself. Internal to src/map.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/SparseCore>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::detail {

// One backtracking (Armijo) step of the barrier Newton solves: z
// (#V) moves along `step` (x and y of each free vertex v at 2 index[v]) to
// the first halving that decreases `objective` by 1e-4 of the predicted
// slope; the barrier makes every infeasible trial +inf. Returns false when
// no halving does; `tiny` is set when the decrease was at round-off
// (<= rel_tiny |F|), which the callers take as converged.
template <class Objective>
bool armijo_step(std::vector<Complex>& z, double& Fz, const Eigen::VectorXd& step, double slope,
                 const std::vector<int>& index, const Objective& objective, double rel_tiny, bool& tiny) {
  std::vector<Complex> trial(z);
  double alpha = 1;
  for (int ls = 0; ls < 40; ++ls, alpha *= 0.5) {
    for (size_t v = 0; v < z.size(); ++v)
      if (index[v] >= 0) trial[v] = z[v] + alpha * Complex(step[2 * index[v]], step[2 * index[v] + 1]);
    const double Ft = objective(trial);
    if (Ft <= Fz + 1e-4 * alpha * slope) {
      tiny = Fz - Ft <= rel_tiny * std::abs(Fz);
      z.swap(trial), Fz = Ft;
      return true;
    }
  }
  return false;
}

// The barrier continuations' shared pieces (flat_barrier_landmarks,
// hyperbolic_barrier_landmarks; landmarks.h).

// Free unknowns: every vertex but the held landmarks `source`, numbered in
// order (index[v] = -1 for held vertices); returns their count.
inline int number_free_vertices(int n, const std::vector<int>& source, std::vector<int>& index) {
  index.assign(n, -1);
  std::vector<char> held(n, 0);
  for (int s : source) held[s] = 1;
  int m = 0;
  for (int v = 0; v < n; ++v)
    if (!held[v]) index[v] = m++;
  return m;
}

// Reference areas c_f = A_f(free) / 4 of the `nf` faces (area(f): the free
// map's face area); false when the free map itself is not embedded (nothing
// to continue from).
template <class Area>
bool barrier_reference_areas(int nf, const Area& area, std::vector<double>& c) {
  c.assign(nf, 0.0);
  for (int f = 0; f < nf; ++f) {
    c[f] = 0.25 * area(f);
    if (!(c[f] > 0)) return false;
  }
  return true;
}

// Σ_f φ(A_f / c_f), φ(x) = x − 1 − log x below 1 (C¹, convex), for the
// face areas area(f); +inf when a face is not positively oriented.
template <class Area>
double face_barrier(const std::vector<double>& c, const Area& area) {
  double B = 0;
  for (size_t f = 0; f < c.size(); ++f) {
    const double x = area(static_cast<int>(f)) / c[f];
    if (!(x > 0)) return std::numeric_limits<double>::infinity();
    if (x < 1) B += x - 1 - std::log(x);
  }
  return B;
}

// Fixed sparsity of the continuation's Hessian in the free unknowns (x, y
// of each, `index` from number_free_vertices): Laplacian couplings of
// `edges` and every face's corners; zero-valued triplets.
template <class Edge>
std::vector<Eigen::Triplet<double>> barrier_hessian_pattern(const std::vector<Edge>& edges, const RowMatrixX3i& F,
                                                            const std::vector<int>& index) {
  std::vector<Eigen::Triplet<double>> pattern;
  auto couple = [&](int a, int b) {
    if (index[a] < 0 || index[b] < 0) return;
    for (int u = 0; u < 2; ++u)
      for (int w = 0; w < 2; ++w) pattern.emplace_back(2 * index[a] + u, 2 * index[b] + w, 0.0);
  };
  for (const auto& e : edges) couple(e.i, e.i), couple(e.j, e.j), couple(e.i, e.j), couple(e.j, e.i);
  for (int f = 0; f < static_cast<int>(F.rows()); ++f)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) couple(F(f, a), F(f, b));
  return pattern;
}

// The continuation in s shared by both barrier solves: from the free map
// (s = 0, in z) towards the landmarks on their lifts (s = 1). Each step
// predicts the free points at s + ds (predict(z, s, next) returns the
// trial), puts the landmarks at `next` (place(trial, next)) and corrects
// by Newton at fixed landmarks (newton(trial, max_it): 8 iterations, 60 at
// s = 1); a step whose prediction is infeasible or whose correction stalls
// is halved, success doubles the next. Returns the s reached (z the map
// there); `steps` counts the steps taken.
template <class Predict, class Place, class Objective, class Newton>
double barrier_continuation(std::vector<Complex>& z, const Predict& predict, const Place& place,
                            const Objective& objective, const Newton& newton, int& steps) {
  double s = 0, ds = 1;
  while (s < 1 && ds > 1e-3) {
    const double next = std::min(1.0, s + ds);
    std::vector<Complex> trial = predict(z, s, next);
    place(trial, next);
    const bool good = std::isfinite(objective(trial)) && newton(trial, next < 1 ? 8 : 60);
    if (good) {
      z.swap(trial), s = next, ++steps;
      ds *= 2;
    } else {
      ds *= 0.5;
    }
  }
  return s;
}

}  // namespace surfmap::detail
