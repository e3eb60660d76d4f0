#include "landmarks.h"

#include <algorithm>
#include <cmath>
#include <deque>

#include <Eigen/Eigenvalues>
#include <set>
#include <limits>
#include <string>

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

// One backtracking (Armijo) step of the barrier Newton solves below: z
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

std::string landmark_name(const std::vector<std::pair<int, int>>& landmarks, int a) {
  return "landmark " + std::to_string(a) + " (" + std::to_string(landmarks[a].first) + " -> " +
         std::to_string(landmarks[a].second) + ")";
}

// The barrier continuations' shared pieces (flat_barrier_landmarks,
// hyperbolic_barrier_landmarks; landmarks.h).

// Free unknowns: every vertex but the held landmarks `source`, numbered in
// order (index[v] = -1 for held vertices); returns their count.
int number_free_vertices(int n, const std::vector<int>& source, std::vector<int>& index) {
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
// lifts at s >= 1).
struct LandmarkGeodesics {
  const std::vector<Complex>& free;
  const std::vector<int>& source;
  const std::vector<Complex>& lifts;
  std::vector<hyperbolic::Mobius> back;
  std::vector<Complex> far;

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
      z[source[a]] = s >= 1 ? lifts[a]
                     : r == 0 ? free[source[a]]
                              : back[a].apply(std::tanh(s * std::atanh(r)) * (far[a] / r));
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
  const LandmarkGeodesics paths(free, source, lifts);
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
  const double s = barrier_continuation(z, predict, place, objective, newton, out.steps);
  out.reached = s;
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
// optimum's charts and decks with the continuation's points.
HyperbolicHarmonicResult barrier_as_held(const HyperbolicHarmonicResult& free, const HyperbolicBarrierResult& br) {
  HyperbolicHarmonicResult held = free;  // same charts and decks, new points
  held.z = br.z;
  held.energy = br.energy;
  held.iterations = br.newton_iterations;
  held.energy_history = {br.energy};
  held.gradient_history.clear();
  held.edge_local.clear();  // not kept by the continuation (rebuilt from the points)
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
      HyperbolicHarmonicResult held = barrier_as_held(free, br);
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
