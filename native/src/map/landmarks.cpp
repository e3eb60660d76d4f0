// Landmarks (docs/method.md §2.10; landmarks.h): genus-1 lifts and the pinned flat
// solve, carried neighbourhoods (grow_landmark_patches) and the flat barrier
// continuation. Genus >= 2 is in hyperbolic_landmarks.cpp; the pieces both
// continuations share in landmark_barrier.h.
#include "landmarks.h"

#include <algorithm>
#include <cmath>
#include <deque>

#include <Eigen/Eigenvalues>
#include <set>
#include <limits>
#include <string>

#include "landmark_barrier.h"
#include "surfmap/error.h"
#include "surfmap/work_counters.h"
#include "surfmap/geometry/hyperbolic.h"

namespace surfmap::detail {

Complex nearest_lattice_translate(Complex z, Complex p, Complex w1, Complex w2) {
  const double det = w1.real() * w2.imag() - w1.imag() * w2.real();
  const Complex d = z - p;
  const double alpha = (d.real() * w2.imag() - d.imag() * w2.real()) / det;
  const double beta = (w1.real() * d.imag() - w1.imag() * d.real()) / det;
  // Rounding lattice coordinates is nearest only for orthogonal bases: look
  // at the neighbours of the rounded point too.
  Complex best = p;
  double best_d = std::numeric_limits<double>::infinity();
  for (int dm = -1; dm <= 1; ++dm)
    for (int dn = -1; dn <= 1; ++dn) {
      const Complex q = p + (std::round(alpha) + dm) * w1 + (std::round(beta) + dn) * w2;
      if (std::abs(q - z) < best_d) best_d = std::abs(q - z), best = q;
    }
  return best;
}

std::vector<Complex> flat_landmark_lifts(const std::vector<Complex>& z, const std::vector<int>& source,
                                         const std::vector<Complex>& target_position, Complex w1, Complex w2) {
  const size_t k = source.size();
  std::vector<Complex> lift(k);
  Complex shift = target_position[0] - z[source[0]];
  for (int it = 0; it < 20; ++it) {
    Complex mean = 0;
    bool changed = false;
    for (size_t a = 0; a < k; ++a) {
      const Complex q = nearest_lattice_translate(z[source[a]] + shift, target_position[a], w1, w2);
      changed = changed || it == 0 || std::abs(q - lift[a]) > 1e-12 * (std::abs(w1) + std::abs(w2));
      lift[a] = q;
      mean += q - z[source[a]];
    }
    shift = mean / double(k);
    if (!changed) break;
  }
  return lift;
}

PinnedFlatHarmonic::PinnedFlatHarmonic(int num_vertices, const std::vector<IntrinsicEdge>& edges,
                                       const std::vector<int>& pinned, bool uniform)
    : n_(num_vertices), edges_(edges), pinned_(pinned), free_index_(num_vertices, -1), uniform_(uniform) {
  if (pinned.empty()) throw InputError("PinnedFlatHarmonic: at least one pinned vertex is needed");
  std::vector<int> pinned_index(n_, -1);
  for (size_t k = 0; k < pinned.size(); ++k) pinned_index[pinned[k]] = static_cast<int>(k);
  int nf = 0;
  for (int v = 0; v < n_; ++v)
    if (pinned_index[v] < 0) free_index_[v] = nf++;
  std::vector<Eigen::Triplet<double>> ff, fp;
  for (const auto& e : edges_) {
    const double w = uniform_ ? 1.0 : e.cot_weight;
    if (w == 0) continue;
    const int a = free_index_[e.i], b = free_index_[e.j];
    if (a >= 0) ff.emplace_back(a, a, w);
    if (b >= 0) ff.emplace_back(b, b, w);
    if (a >= 0 && b >= 0) ff.emplace_back(a, b, -w), ff.emplace_back(b, a, -w);
    if (a >= 0 && b < 0) fp.emplace_back(a, pinned_index[e.j], -w);
    if (b >= 0 && a < 0) fp.emplace_back(b, pinned_index[e.i], -w);
  }
  Eigen::SparseMatrix<double> L(nf, nf);
  L.setFromTriplets(ff.begin(), ff.end());
  coupling_.resize(nf, static_cast<int>(pinned.size()));
  coupling_.setFromTriplets(fp.begin(), fp.end());
  llt_ = std::make_unique<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>>();
  llt_->compute(L);
  ++work::analyses, ++work::factorisations;
  if (llt_->info() != Eigen::Success)
    throw SolveError("the source Laplacian with the landmarks pinned could not be factorised");
}

std::pair<std::vector<Complex>, double> PinnedFlatHarmonic::solve(const std::vector<Complex>& t,
                                                                  const std::vector<Complex>& values) const {
  const int nf = static_cast<int>(coupling_.rows()), np = static_cast<int>(pinned_.size());
  Eigen::VectorXd bx = Eigen::VectorXd::Zero(nf), by = Eigen::VectorXd::Zero(nf);
  for (size_t e = 0; e < edges_.size(); ++e) {
    const auto& ie = edges_[e];
    const double w = uniform_ ? 1.0 : ie.cot_weight;
    if (free_index_[ie.i] >= 0) bx[free_index_[ie.i]] += w * t[e].real(), by[free_index_[ie.i]] += w * t[e].imag();
    if (free_index_[ie.j] >= 0) bx[free_index_[ie.j]] -= w * t[e].real(), by[free_index_[ie.j]] -= w * t[e].imag();
  }
  Eigen::VectorXd px(np), py(np);
  for (int k = 0; k < np; ++k) px[k] = values[k].real(), py[k] = values[k].imag();
  bx -= coupling_ * px;
  by -= coupling_ * py;
  const Eigen::VectorXd x = llt_->solve(bx), y = llt_->solve(by);
  std::vector<Complex> z(n_);
  for (int v = 0; v < n_; ++v)
    if (free_index_[v] >= 0) z[v] = Complex(x[free_index_[v]], y[free_index_[v]]);
  for (int k = 0; k < np; ++k) z[pinned_[k]] = values[k];
  double energy = 0;
  for (size_t e = 0; e < edges_.size(); ++e) {
    const auto& ie = edges_[e];
    energy += ie.cot_weight * std::norm(z[ie.j] + t[e] - z[ie.i]);
  }
  return {z, energy};
}

namespace {

std::string landmark_name(const std::vector<std::pair<int, int>>& landmarks, int a) {
  return "landmark " + std::to_string(a) + " (" + std::to_string(landmarks[a].first) + " -> " +
         std::to_string(landmarks[a].second) + ")";
}

using CornerOffsets = Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>;

// flat_barrier_landmarks' objective at fixed landmark positions,
// F(z) = E(z) + μ Σ_f φ(A_f(z) / c_f) (E: the cotangent Dirichlet energy
// of `edges` with translations t; A_f: the signed area of face f's image,
// corners z[F(f,k)] + off(f,k); c from barrier_reference_areas, μ set by
// the caller), and its derivatives in the free unknowns.
struct FlatBarrierProblem {
  const std::vector<IntrinsicEdge>& edges;
  const std::vector<Complex>& t;
  const RowMatrixX3i& F;
  const CornerOffsets& off;
  const std::vector<int>& index;  // number_free_vertices
  int m = 0;                      // free unknowns
  std::vector<double> c;
  double mu = 0;

  double area(const std::vector<Complex>& z, int f) const {
    const Complex p0 = z[F(f, 0)] + off(f, 0), p1 = z[F(f, 1)] + off(f, 1), p2 = z[F(f, 2)] + off(f, 2);
    const Complex e1 = p1 - p0, e2 = p2 - p0;
    return 0.5 * (e1.real() * e2.imag() - e1.imag() * e2.real());
  }
  double dirichlet(const std::vector<Complex>& z) const {
    double E = 0;
    for (size_t e = 0; e < edges.size(); ++e) E += edges[e].cot_weight * std::norm(z[edges[e].j] + t[e] - z[edges[e].i]);
    return E;
  }
  // F(z); +inf when a face is not positively oriented.
  double objective(const std::vector<Complex>& z) const {
    const double B = face_barrier(c, [&](int f) { return area(z, f); });
    if (!(B < std::numeric_limits<double>::infinity())) return B;
    return dirichlet(z) + mu * B;
  }
  // Gradient g (2m) at z and, with H, the Hessian (sparsity `pattern`) with
  // each face's barrier block projected onto PSD.
  void assemble(const std::vector<Complex>& z, Eigen::VectorXd& g, const std::vector<Eigen::Triplet<double>>& pattern,
                Eigen::SparseMatrix<double>* H) const {
    const int nf = static_cast<int>(F.rows());
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(pattern.size());
    for (const auto& p : pattern) trip.emplace_back(p.row(), p.col(), 0.0);
    g = Eigen::VectorXd::Zero(2 * m);
    auto add = [&](int a, int b, double hxx, double hxy, double hyx, double hyy) {
      if (index[a] < 0 || index[b] < 0) return;
      trip.emplace_back(2 * index[a], 2 * index[b], hxx), trip.emplace_back(2 * index[a], 2 * index[b] + 1, hxy);
      trip.emplace_back(2 * index[a] + 1, 2 * index[b], hyx), trip.emplace_back(2 * index[a] + 1, 2 * index[b] + 1, hyy);
    };
    for (size_t e = 0; e < edges.size(); ++e) {
      const int i = edges[e].i, j = edges[e].j;
      const double w = edges[e].cot_weight;
      if (i == j) continue;
      const Complex d = z[j] + t[e] - z[i];
      if (index[i] >= 0) g[2 * index[i]] -= 2 * w * d.real(), g[2 * index[i] + 1] -= 2 * w * d.imag();
      if (index[j] >= 0) g[2 * index[j]] += 2 * w * d.real(), g[2 * index[j] + 1] += 2 * w * d.imag();
      add(i, i, 2 * w, 0, 0, 2 * w), add(j, j, 2 * w, 0, 0, 2 * w);
      add(i, j, -2 * w, 0, 0, -2 * w), add(j, i, -2 * w, 0, 0, -2 * w);
    }
    for (int f = 0; f < nf; ++f) {
      const double x = area(z, f) / c[f];
      if (x >= 1) continue;
      Complex p[3];
      for (int k = 0; k < 3; ++k) p[k] = z[F(f, k)] + off(f, k);
      // ∂A/∂(x_k, y_k) = ½ (y_{k+1} − y_{k+2}, x_{k+2} − x_{k+1}).
      double gA[3][2];
      for (int k = 0; k < 3; ++k) {
        const Complex a = p[(k + 1) % 3], b = p[(k + 2) % 3];
        gA[k][0] = 0.5 * (a.imag() - b.imag()), gA[k][1] = 0.5 * (b.real() - a.real());
      }
      const double d1 = mu * (1 - 1 / x) / c[f], d2 = mu / (x * x * c[f] * c[f]);
      // Face Hessian d2 ∇A∇Aᵀ + d1 ∇²A (∇²A: the shoelace's constant
      // ∂²A/∂x_a∂y_b = ½(δ_{b,a+1} − δ_{b,a+2})), projected onto PSD.
      Eigen::Matrix<double, 6, 1> ga;
      Eigen::Matrix<double, 6, 6> K = Eigen::Matrix<double, 6, 6>::Zero();
      for (int a = 0; a < 3; ++a) ga[2 * a] = gA[a][0], ga[2 * a + 1] = gA[a][1];
      for (int a = 0; a < 3; ++a) {
        K(2 * a, 2 * ((a + 1) % 3) + 1) += 0.5 * d1, K(2 * ((a + 1) % 3) + 1, 2 * a) += 0.5 * d1;
        K(2 * a, 2 * ((a + 2) % 3) + 1) -= 0.5 * d1, K(2 * ((a + 2) % 3) + 1, 2 * a) -= 0.5 * d1;
      }
      K += d2 * ga * ga.transpose();
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(K);
      const Eigen::Matrix<double, 6, 1> lam = es.eigenvalues().cwiseMax(0.0);
      K = es.eigenvectors() * lam.asDiagonal() * es.eigenvectors().transpose();
      for (int a = 0; a < 3; ++a) {
        const int va = F(f, a);
        if (index[va] >= 0) g[2 * index[va]] += d1 * gA[a][0], g[2 * index[va] + 1] += d1 * gA[a][1];
        for (int b = 0; b < 3; ++b)
          add(va, F(f, b), K(2 * a, 2 * b), K(2 * a, 2 * b + 1), K(2 * a + 1, 2 * b), K(2 * a + 1, 2 * b + 1));
      }
    }
    if (H) H->setFromTriplets(trip.begin(), trip.end());
  }
};

}  // namespace

LandmarkPatchSearch grow_landmark_patches(
    int n, const std::vector<std::pair<int, int>>& edge_ends, const RowMatrixX3i& faces,
    const std::vector<std::pair<int, int>>& landmarks,
    const std::function<std::vector<int>(const std::vector<LandmarkPatch>&)>& solve) {
  const int k = static_cast<int>(landmarks.size());
  // Incident edges per vertex (self-loops of the intrinsic triangulation skipped).
  std::vector<std::vector<std::pair<int, int>>> nb(n);  // (edge, other end)
  for (size_t e = 0; e < edge_ends.size(); ++e) {
    const auto [i, j] = edge_ends[e];
    if (i == j) continue;
    nb[i].emplace_back(static_cast<int>(e), j), nb[j].emplace_back(static_cast<int>(e), i);
  }
  // Which landmark each vertex is nearest to (multi-source breadth first):
  // a folded face is charged to the landmark nearest to it.
  std::vector<int> owner(n, -1);
  {
    std::deque<int> queue;
    for (int a = 0; a < k; ++a) owner[landmarks[a].first] = a, queue.push_back(landmarks[a].first);
    while (!queue.empty()) {
      const int u = queue.front();
      queue.pop_front();
      for (const auto& [e, v] : nb[u])
        if (owner[v] < 0) owner[v] = owner[u], queue.push_back(v);
    }
  }
  LandmarkPatchSearch search;
  search.rings.assign(k, 0);
  std::vector<int> member(n, -1);
  int last_bad = std::numeric_limits<int>::max(), worse = 0;
  for (int round = 0; round < 40; ++round) {
    std::vector<LandmarkPatch> patches(k);
    std::fill(member.begin(), member.end(), -1);
    int held = 0;
    for (int a = 0; a < k; ++a) {
      LandmarkPatch& P = patches[a];
      std::vector<int> depth{0};
      P.vertex.push_back(landmarks[a].first), P.parent.push_back(-1), P.edge.push_back(-1), P.head.push_back(0);
      member[landmarks[a].first] = a;
      for (size_t q = 0; q < P.vertex.size(); ++q) {
        if (depth[q] >= search.rings[a]) continue;
        for (const auto& [e, v] : nb[P.vertex[q]]) {
          if (member[v] == a) continue;
          if (member[v] >= 0)
            throw SolveError(landmark_name(landmarks, a) + " and " + landmark_name(landmarks, member[v]) +
                             " cannot be held without folding the map in this homotopy class: the neighbourhoods "
                             "they must carry to keep it bijective (" + std::to_string(search.rings[a]) + " and " +
                             std::to_string(search.rings[member[v]]) +
                             " rings) meet. Their targets are too far from where the map without landmarks puts them "
                             "for landmarks this close together; move them nearer or drop one");
          member[v] = a;
          P.vertex.push_back(v), P.parent.push_back(static_cast<int>(q)), P.edge.push_back(e);
          P.head.push_back(edge_ends[e].second == v && edge_ends[e].first == P.vertex[q]);
          depth.push_back(depth[q] + 1);
        }
      }
      held += static_cast<int>(P.vertex.size());
    }
    if (2 * held > n) {
      std::string names;
      for (int a = 0; a < k; ++a)
        if (search.rings[a] > 0) names += (names.empty() ? "" : ", ") + landmark_name(landmarks, a);
      throw SolveError("the landmarks cannot be held without folding the map in this homotopy class: keeping it "
                       "bijective would hold more than half of the source rigidly (" + names +
                       "; their targets are far from where the map without landmarks puts them)");
    }
    const std::vector<int> bad = solve(patches);
    ++search.solves;
    search.held_vertices = held;
    if (bad.empty()) return search;
    // Carrying more usually cuts the folds (not monotonically: 7, 14, 6, 1,
    // 2, 0 seen); when it adds folds round after round, the surround has no
    // room to absorb the move (g2_double-torus -> g2_eight at 5.5 edges:
    // 13, 41, 75, 123, ... up to half the source held) and it is given up.
    worse = static_cast<int>(bad.size()) > last_bad ? worse + 1 : 0;
    last_bad = static_cast<int>(bad.size());
    if (worse >= 3) {
      std::string names;
      for (int a = 0; a < k; ++a)
        if (search.rings[a] > 0) names += (names.empty() ? "" : ", ") + landmark_name(landmarks, a);
      throw SolveError("the landmarks cannot be held without folding the map in this homotopy class: carrying "
                       "larger neighbourhoods with them folds more of it (" + std::to_string(bad.size()) +
                       " faces with " + std::to_string(held) + " vertices held; " + names +
                       "; their targets are far from where the map without landmarks puts them)");
    }
    std::vector<char> grow(k, 0);
    for (int f : bad)
      for (int c = 0; c < 3; ++c)
        if (owner[faces(f, c)] >= 0) grow[owner[faces(f, c)]] = 1;
    for (int a = 0; a < k; ++a)
      if (grow[a]) search.rings[a] = std::max(search.rings[a] + 1, (3 * search.rings[a] + 1) / 2);
  }
  std::string names;
  for (int a = 0; a < k; ++a) names += (names.empty() ? "" : ", ") + landmark_name(landmarks, a);
  throw SolveError("the landmarks could not be held without folding the map (" + names + ")");
}

FlatBarrierResult flat_barrier_landmarks(int n, const std::vector<IntrinsicEdge>& edges,
                                         const std::vector<Complex>& t, const RowMatrixX3i& F,
                                         const Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>& off,
                                         const std::vector<Complex>& free, const std::vector<int>& source,
                                         const std::vector<Complex>& lifts) {
  FlatBarrierResult out;
  const int nf = static_cast<int>(F.rows());
  // Free unknowns: every vertex but the landmarks, x and y interleaved.
  std::vector<int> index;
  const int m = number_free_vertices(n, source, index);
  FlatBarrierProblem problem{edges, t, F, off, index, m, {}, 0.0};
  if (!barrier_reference_areas(nf, [&](int f) { return problem.area(free, f); }, problem.c)) return out;
  const double mu = problem.mu = problem.dirichlet(free) / nf;
  auto objective = [&](const std::vector<Complex>& z) { return problem.objective(z); };
  const std::vector<Eigen::Triplet<double>> pattern = barrier_hessian_pattern(edges, F, index);
  Eigen::SparseMatrix<double> H(2 * m, 2 * m);
  H.setFromTriplets(pattern.begin(), pattern.end());
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> llt;
  llt.analyzePattern(H);
  ++work::analyses;
  // Gradient of the objective in the free unknowns at z and (with
  // `hessian`) its Hessian in H (the barrier's per-face blocks projected).
  auto assemble = [&](const std::vector<Complex>& z, Eigen::VectorXd& g, bool hessian) {
    problem.assemble(z, g, pattern, hessian ? &H : nullptr);
  };
  double wmax = 0;
  for (const auto& e : edges) wmax = std::max(wmax, e.cot_weight);
  // Newton corrections at fixed landmark positions; false when the line
  // search cannot make progress.
  auto newton = [&](std::vector<Complex>& z, int max_it) {
    double Fz = objective(z);
    for (int it = 0; it < max_it; ++it) {
      Eigen::VectorXd g;
      assemble(z, g, true);
      double gmax = g.lpNorm<Eigen::Infinity>();
      if (gmax <= 1e-10 * std::max(1.0, mu / std::max(wmax, 1e-300)) * wmax) return true;
      llt.factorize(H);
      ++work::factorisations;
      if (llt.info() != Eigen::Success) return false;
      const Eigen::VectorXd step = llt.solve(-g);
      const double slope = g.dot(step);
      bool tiny = false;  // converged when the decrease is at round-off
      if (!armijo_step(z, Fz, step, slope, index, objective, 1e-12, tiny)) return false;
      ++out.newton_iterations;
      if (tiny) return true;
    }
    return true;
  };
  // The landmarks' move extended harmonically (the predictor direction).
  std::vector<Complex> move(source.size());
  for (size_t a = 0; a < source.size(); ++a) move[a] = lifts[a] - free[source[a]];
  const std::vector<Complex> zero_t(edges.size(), Complex(0.0));
  const std::vector<Complex> direction = PinnedFlatHarmonic(n, edges, source, false).solve(zero_t, move).first;
  // Euler predictor along the path of optima: the free unknowns' response
  // −H⁻¹ ∂g/∂s to the landmarks' move (∂g/∂s by a difference); the
  // harmonic extension of the move from the free map at the start.
  auto predict = [&](const std::vector<Complex>& z, double s, double next) {
    std::vector<Complex> dir = direction;
    if (s > 0) {
      Eigen::VectorXd g0, g1;
      assemble(z, g0, true);
      llt.factorize(H);
      ++work::factorisations;
      std::vector<Complex> zh = z;
      const double h = 1e-6;
      for (size_t a = 0; a < source.size(); ++a) zh[source[a]] += h * move[a];
      assemble(zh, g1, false);
      if (llt.info() == Eigen::Success) {
        const Eigen::VectorXd d = llt.solve(-(g1 - g0) / h);
        for (int v = 0; v < n; ++v)
          dir[v] = index[v] >= 0 ? Complex(d[2 * index[v]], d[2 * index[v] + 1]) : Complex(0.0);
      }
    }
    std::vector<Complex> trial = z;
    for (int v = 0; v < n; ++v) trial[v] += (next - s) * dir[v];
    return trial;
  };
  auto place = [&](std::vector<Complex>& z, double s) {
    for (size_t a = 0; a < source.size(); ++a) z[source[a]] = free[source[a]] + s * move[a];
  };
  std::vector<Complex> z = free;
  const double s = barrier_continuation(z, predict, place, objective, newton, out.steps);
  out.reached = s;
  if (s < 1) return out;
  // Polish at the final positions (the landmarks exactly on their lifts).
  for (size_t a = 0; a < source.size(); ++a) z[source[a]] = lifts[a];
  newton(z, 40);
  out.ok = true;
  out.energy = problem.dirichlet(z);
  out.z = std::move(z);
  return out;
}

}  // namespace surfmap::detail
