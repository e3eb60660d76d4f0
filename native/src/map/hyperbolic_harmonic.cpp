#include "surfmap/map/hyperbolic_harmonic.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <utility>

#include <cholmod.h>

#include <Eigen/Dense>

#include "../cholmod_vector_solve.h"
#include "../seconds_since.h"
#include "concurrency.h"
#include "surfmap/error.h"
#include "surfmap/work_counters.h"
#include "surfmap/geometry/dynamic_charts.h"
#include "surfmap/map/point_location.h"

namespace surfmap {
namespace {

using hyperbolic::Mobius;
using Complex = std::complex<double>;

Mobius effective(const WeightedEdge& e, const std::vector<Mobius>& deck) {
  return deck[e.i] * e.rho * deck[e.j].inverse();
}

// SU(1,1) arithmetic in long double for the effective elements and the
// edges derived from them (below): about three more digits than double on x86.
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

long double size(const LongMobius& m) { return std::abs(m.a) + std::abs(m.b); }

// A product in long double and the first-order estimate of its round-off,
// in units of the long double epsilon (absolute, on the entries).
struct LongProduct {
  LongMobius value;
  long double error = 0;
};

// X_1 X_2 ... X_n (`factors`, n >= 1) left to right, normalised at the end,
// with the round-off estimate Σ_{m>=2} |X_1..X_{m-1}| |X_m| |X_{m+1}..X_n|:
// each multiplication's error, of the size of its two operands, carried
// through the rest of the product (sizes |a| + |b| of the partial products,
// not of the factors: a product of large factors that cancel, as a word
// circling a far corner of the domain, is only as inexact as its partial
// products are large). `suffix`: scratch.
LongProduct multiply_out(const std::vector<LongMobius>& factors, std::vector<LongMobius>& suffix) {
  const size_t n = factors.size();
  suffix.resize(n + 1);
  suffix[n] = LongMobius();
  for (size_t m = n; m-- > 1;) suffix[m] = factors[m] * suffix[m + 1];
  LongProduct p;
  p.value = factors[0];
  for (size_t m = 1; m < n; ++m) {
    p.error += size(p.value) * size(factors[m]) * size(suffix[m + 1]);
    p.value = p.value * factors[m];
  }
  p.value = p.value.normalized();
  return p;
}

// Move index (2k: generator k, 2k+1: its inverse) as a word letter.
int move_letter(int m) { return m % 2 == 0 ? m / 2 + 1 : -(m / 2 + 1); }

// The Newton system: 2x2 blocks on a fixed pattern (the vertex graph of the
// edges with w > 0), assembled straight into CHOLMOD's upper-triangular
// column storage, and its symbolic factorisation (HessianAnalysis), computed
// once per pattern: per solve, or once for every solve on the same pattern
// (HyperbolicHarmonicSolver). The fill-reducing ordering is computed on the
// vertex graph (a quarter of the size) and expanded to the blocks, which
// keeps each vertex's two unknowns adjacent. AMD, except on large meshes
// with the reference BLAS: there METIS nested dissection pays, as it halves
// the factorisation flops (50k source vertices: 1.7e9 against 3.2e9; 0.7 s
// against 1.2 s per factorisation on netlib BLAS), but with OpenBLAS
// (scripts/bootstrap.sh) both factorise in 0.23-0.3 s (single-threaded) and
// METIS's ordering costs 0.5 s against 0.08 s for AMD, more than it saves
// over the 1-3 factorisations of a solve from a good start.
}  // namespace

struct HessianAnalysis {
  int n = 0;
  std::vector<int> colptr, rows, pair, lower_size;
  /// Per edge: i, j and whether it enters the Hessian (w > 0, i != j): the pattern.
  std::vector<std::array<int, 3>> edge_key;
  cholmod_common c{};
  cholmod_factor* L = nullptr;  ///< symbolic factor (copied by every solve)

  HessianAnalysis(int num_vertices, const std::vector<WeightedEdge>& edges) : n(num_vertices) {
    cholmod_start(&c);
    c.print = 0;
    // Lower neighbours of every vertex (the blocks (I, J), I < J, of column J).
    std::vector<std::vector<int>> lower(n);
    for (const auto& e : edges)
      if (e.w > 0 && e.i != e.j) lower[std::max(e.i, e.j)].push_back(std::min(e.i, e.j));
    for (auto& l : lower) std::sort(l.begin(), l.end()), l.erase(std::unique(l.begin(), l.end()), l.end());
    colptr.assign(2 * n + 1, 0);
    for (int J = 0; J < n; ++J) {
      const int d = static_cast<int>(lower[J].size());
      colptr[2 * J + 1] = colptr[2 * J] + 2 * d + 1;
      colptr[2 * J + 2] = colptr[2 * J + 1] + 2 * d + 2;
    }
    const int nnz = colptr[2 * n];
    rows.resize(nnz);
    for (int J = 0; J < n; ++J) {
      int p = colptr[2 * J], q = colptr[2 * J + 1];
      for (int I : lower[J]) rows[p++] = 2 * I, rows[p++] = 2 * I + 1, rows[q++] = 2 * I, rows[q++] = 2 * I + 1;
      rows[p] = 2 * J, rows[q] = 2 * J, rows[q + 1] = 2 * J + 1;
    }
    // Per edge: position of its off-diagonal block's first entry in column
    // 2·max (the block's k-th lower neighbour sits at colptr + 2k).
    pair.assign(edges.size(), -1);
    edge_key.resize(edges.size());
    for (size_t e = 0; e < edges.size(); ++e) {
      const auto& ed = edges[e];
      edge_key[e] = {ed.i, ed.j, ed.w > 0 && ed.i != ed.j};
      if (!(ed.w > 0) || ed.i == ed.j) continue;
      const int J = std::max(ed.i, ed.j), I = std::min(ed.i, ed.j);
      pair[e] = static_cast<int>(std::lower_bound(lower[J].begin(), lower[J].end(), I) - lower[J].begin());
    }
    lower_size.resize(n);
    for (int J = 0; J < n; ++J) lower_size[J] = static_cast<int>(lower[J].size());
    cholmod_sparse* A = cholmod_allocate_sparse(2 * n, 2 * n, nnz, 1, 1, 1, CHOLMOD_REAL, &c);
    std::copy(colptr.begin(), colptr.end(), static_cast<int*>(A->p));
    std::copy(rows.begin(), rows.end(), static_cast<int*>(A->i));

    // Ordering of the vertex graph, expanded to the 2x2 blocks.
    std::vector<int> vp(n + 1, 0), vi;
    for (int J = 0; J < n; ++J) {
      vp[J + 1] = vp[J] + lower_size[J] + 1;
      for (int I : lower[J]) vi.push_back(I);
      vi.push_back(J);
    }
    cholmod_sparse* G = cholmod_allocate_sparse(n, n, vi.size(), 1, 1, 1, CHOLMOD_PATTERN, &c);
    std::copy(vp.begin(), vp.end(), static_cast<int*>(G->p));
    std::copy(vi.begin(), vi.end(), static_cast<int*>(G->i));
    c.nmethods = 1;
    c.method[0].ordering = n > 20000 && !detail::optimised_blas() ? CHOLMOD_METIS : CHOLMOD_AMD;
    std::vector<int> perm(2 * n);
    {
      std::lock_guard<std::mutex> lock(detail::ordering_mutex());
      cholmod_factor* Lg = cholmod_analyze(G, &c);
      if (!Lg) {
        cholmod_free_sparse(&G, &c);
        cholmod_free_sparse(&A, &c);
        cholmod_finish(&c);
        throw SolveError("hyperbolic harmonic map: ordering of the Hessian failed");
      }
      const int* P = static_cast<const int*>(Lg->Perm);
      for (int k = 0; k < n; ++k) perm[2 * k] = 2 * P[k], perm[2 * k + 1] = 2 * P[k] + 1;
      cholmod_free_factor(&Lg, &c);
    }
    cholmod_free_sparse(&G, &c);
    c.method[0].ordering = CHOLMOD_GIVEN;
    L = cholmod_analyze_p(A, perm.data(), nullptr, 0, &c);
    ++work::analyses;
    cholmod_free_sparse(&A, &c);
    if (!L) {
      cholmod_finish(&c);
      throw SolveError("hyperbolic harmonic map: symbolic factorisation of the Hessian failed");
    }
  }
  ~HessianAnalysis() {
    cholmod_free_factor(&L, &c);
    cholmod_finish(&c);
  }
  HessianAnalysis(const HessianAnalysis&) = delete;
  HessianAnalysis& operator=(const HessianAnalysis&) = delete;
  /// Whether `edges` on `num_vertices` have this pattern.
  bool matches(int num_vertices, const std::vector<WeightedEdge>& edges) const {
    if (num_vertices != n || edges.size() != edge_key.size()) return false;
    for (size_t e = 0; e < edges.size(); ++e) {
      const auto& ed = edges[e];
      if (edge_key[e] != std::array<int, 3>{ed.i, ed.j, ed.w > 0 && ed.i != ed.j}) return false;
    }
    return true;
  }
};

namespace {

// The Newton systems with this many unknowns solve from a simplicial copy
// of the factor (BlockHessian::factorize): those of the preconditioned steps
// (kPreconditionedVertices), where one factor serves many solves, on small
// sources only (the 50k bench pair's source, with the copy: 114 MiB more
// peak memory and no CPU saved).
constexpr int kSimplicialSolveUnknowns = 8000, kSimplicialSolveMaxUnknowns = 40000;

// The numeric side of the Newton system for one solve: values on the
// analysis's pattern and a numeric factor (a copy of the symbolic one, so
// solves on two threads do not share CHOLMOD state).
class BlockHessian {
 public:
  explicit BlockHessian(const HessianAnalysis& analysis)
      : n_(analysis.n), colptr_(analysis.colptr), rows_(analysis.rows), pair_(analysis.pair),
        lower_size_(analysis.lower_size) {
    cholmod_start(&c_);
    c_.print = 0;  // indefinite tries are expected and handled by the caller
    const int nnz = colptr_[2 * n_];
    values_.assign(nnz, 0.0);
    A_ = cholmod_allocate_sparse(2 * n_, 2 * n_, nnz, 1, 1, 1, CHOLMOD_REAL, &c_);
    std::copy(analysis.colptr.begin(), analysis.colptr.end(), static_cast<int*>(A_->p));
    std::copy(analysis.rows.begin(), analysis.rows.end(), static_cast<int*>(A_->i));
    L_ = cholmod_copy_factor(analysis.L, &c_);
    if (!L_) throw SolveError("hyperbolic harmonic map: copying the symbolic factorisation of the Hessian failed");
  }
  ~BlockHessian() {
    if (solves_) cholmod_free_factor(&solves_, &c_);
    cholmod_free_factor(&L_, &c_);
    cholmod_free_sparse(&A_, &c_);
    cholmod_finish(&c_);
  }
  BlockHessian(const BlockHessian&) = delete;
  BlockHessian& operator=(const BlockHessian&) = delete;

  void clear() { std::fill(values_.begin(), values_.end(), 0.0); }
  // Adds the symmetric block D at (J, J).
  void add_diagonal(int J, const Eigen::Matrix2d& D) {
    const int d = lower_size_[J];
    values_[colptr_[2 * J] + 2 * d] += D(0, 0);
    values_[colptr_[2 * J + 1] + 2 * d] += D(0, 1);
    values_[colptr_[2 * J + 1] + 2 * d + 1] += D(1, 1);
  }
  // Adds M at (i, j) (and M^T at (j, i)) for edge e, i != j.
  void add_offdiagonal(size_t e, int i, int j, const Eigen::Matrix2d& M) {
    const int k = pair_[e];
    const Eigen::Matrix2d B = i < j ? M : Eigen::Matrix2d(M.transpose());  // block (min, max)
    const int J = std::max(i, j);
    values_[colptr_[2 * J] + 2 * k] += B(0, 0);
    values_[colptr_[2 * J] + 2 * k + 1] += B(1, 0);
    values_[colptr_[2 * J + 1] + 2 * k] += B(0, 1);
    values_[colptr_[2 * J + 1] + 2 * k + 1] += B(1, 1);
  }
  double diagonal(int k) const {
    const int J = k / 2, d = lower_size_[J];
    return k % 2 == 0 ? values_[colptr_[2 * J] + 2 * d] : values_[colptr_[2 * J + 1] + 2 * d + 1];
  }
  // Numeric factorisation of the assembled matrix plus shift·I; false when
  // it is not positive definite.
  bool factorize(double shift) {
    double* x = static_cast<double*>(A_->x);
    std::copy(values_.begin(), values_.end(), x);
    for (int J = 0; J < n_; ++J) {
      const int d = lower_size_[J];
      x[colptr_[2 * J] + 2 * d] += shift;
      x[colptr_[2 * J + 1] + 2 * d + 1] += shift;
    }
    cholmod_factorize(A_, L_, &c_);
    ++work::factorisations;
    if (solves_) cholmod_free_factor(&solves_, &c_);
    const bool ok = c_.status == CHOLMOD_OK && L_->minor == L_->n;
    // Issue 19 (session 24): the solves from a simplicial copy of a
    // supernodal factor (its solve's two BLAS calls per supernode cost more
    // than the arithmetic; ricci_flow.cpp SupernodalFactorSimplicialSolves),
    // where a factor serves many solves (the preconditioned steps).
    if (ok && L_->is_super && 2 * n_ >= kSimplicialSolveUnknowns && 2 * n_ <= kSimplicialSolveMaxUnknowns)
      solves_ = detail::simplicial_copy(L_, &c_);
    return ok;
  }
  // (assembled matrix + shift·I) x, from the upper triangle it stores (the
  // matrix assembled last, whatever the factor holds).
  Eigen::VectorXd multiply(const Eigen::VectorXd& x, double shift) const {
    Eigen::VectorXd y = shift * x;
    for (int c = 0; c < 2 * n_; ++c) {
      const double xc = x[c];
      double yc = 0;
      for (int p = colptr_[c]; p < colptr_[c + 1]; ++p) {
        const int r = rows_[p];
        const double v = values_[p];
        if (r == c) {
          yc += v * xc;
        } else {
          y[r] += v * xc;
          yc += v * x[r];
        }
      }
      y[c] += yc;
    }
    return y;
  }
  Eigen::VectorXd solve(const Eigen::VectorXd& b) { return detail::cholmod_vector_solve(solves_ ? solves_ : L_, b, &c_); }

 private:
  int n_;
  cholmod_common c_{};
  cholmod_sparse* A_ = nullptr;
  cholmod_factor* L_ = nullptr;
  cholmod_factor* solves_ = nullptr;  // simplicial copy of L_ for the solves, or null
  const std::vector<int>& colptr_;
  const std::vector<int>& rows_;
  const std::vector<int>& pair_;
  const std::vector<int>& lower_size_;
  std::vector<double> values_;
};

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

namespace {

// The checks of newton_solve's input: one start point per vertex inside the
// disk, a full fixed mask when any, edge ends in range and finite weights
// that are not clearly negative (InputError naming the vertex or edge).
void check_newton_input(int n, const std::vector<WeightedEdge>& edges, const std::vector<Complex>& z0,
                        const HyperbolicHarmonicOptions& options) {
  if (static_cast<int>(z0.size()) != n) throw InputError("hyperbolic_harmonic_map: one start point per vertex needed");
  for (int i = 0; i < n; ++i)
    if (!(std::abs(z0[i]) < 1)) throw InputError("hyperbolic_harmonic_map: start point of vertex " + std::to_string(i) + " is outside the disk");
  if (!options.fixed.empty() && static_cast<int>(options.fixed.size()) != n)
    throw InputError("hyperbolic_harmonic_map: the fixed mask needs one entry per vertex");
  const BoundarySlideOptions& slide = options.boundary_slide;
  if (!slide.slides.empty()) {
    if (static_cast<int>(slide.slides.size()) != n || static_cast<int>(slide.geodesic.size()) != n)
      throw InputError("hyperbolic_harmonic_map: boundary_slide needs one slide flag and one geodesic per vertex");
    for (int i = 0; i < n; ++i) {
      if (!slide.slides[i]) continue;
      if (!options.fixed.empty() && options.fixed[i])
        throw InputError("hyperbolic_harmonic_map: vertex " + std::to_string(i) + " is both held and sliding");
      const Mobius& G = slide.geodesic[i];
      if (!std::isfinite(std::abs(G.a)) || !std::isfinite(std::abs(G.b)) || !(G.determinant() > 0))
        throw InputError("hyperbolic_harmonic_map: the geodesic of vertex " + std::to_string(i) +
                         " is not an isometry of the disk");
    }
  } else if (!slide.ordered_edges.empty()) {
    throw InputError("hyperbolic_harmonic_map: ordered_edges without sliding vertices");
  }
  for (const auto& p : slide.pulls)
    if (p.vertex < 0 || p.vertex >= n || !(p.w >= 0) || !std::isfinite(p.w) || !(p.geodesic.determinant() > 0) ||
        (!options.fixed.empty() && options.fixed[p.vertex]) || (!slide.slides.empty() && slide.slides[p.vertex]))
      throw InputError("hyperbolic_harmonic_map: the pull on vertex " + std::to_string(p.vertex) +
                       " needs a free vertex, a weight >= 0 and an isometry");
  for (int e : slide.ordered_edges)
    if (e < 0 || e >= static_cast<int>(edges.size()) || !slide.slides[edges[e].i] || !slide.slides[edges[e].j])
      throw InputError("hyperbolic_harmonic_map: ordered edge " + std::to_string(e) +
                       " is not an edge between two sliding vertices");
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
}

// The solve runs in charts (docs/method.md §2.6, done algebraically): vertex i has
// a chart C_i (an isometry with C_i(0) = z_i, its frame parallel-transported
// along the steps), and every edge its element in the charts of its ends,
// A_e = C_i^-1 ρ'_e C_j, so that the image of the edge runs from 0 to A_e(0)
// in i's chart; ρ'_e = deck_i ρ_e deck_j^-1 is the edge's effective element
// after the chart moves. Energies, gradients and Hessians are read off A_e
// alone: d = 2 asinh|b|, direction b/ā, frame rotation arg A_e'(0) = 2 arg a.
// A step ξ takes C_i to C_i τ(ξ_i) with the exact translations τ, and the
// line search's trial elements are τ(ξ_i)^-1 A_e τ(ξ_j).
//
// The state carried from one iteration to the next is the charts and the
// effective elements (as reduced words when a relator is given, so short
// once the edge is short). Far from the origin (a chart of size 100 or
// more, ChartState::anchor_if_far) each chart is split, C_i = T_i c_i: an anchor
// T_i in long double and the local chart c_i of the steps since, near the
// identity (folded into T_i once it moves beyond kReanchorB); every edge
// keeps K_e = T_i^-1 ρ'_e T_j in long double, and A_e = c_i^-1 K_e c_j is
// derived afresh after every step. Moving a vertex to another sheet
// changes T_i and ρ'_e but not K_e, so that only re-anchoring (rare once
// the steps are short) and a sheet that makes K_e more accurate derive K_e
// from T and ρ' again. Issue 13: deriving A_e from the full charts in
// double after every step (as before) is exact only near the origin. A
// thin CAD plate's domain reaches ~26 units out (charts with entries ~5e5,
// deck elements ~3e7), where a chart in double is known only to
// ~1e-16 |C|^2 ≈ 2.5e-5 in its own frame, and a vertex flipping between
// two sheets every iteration moved its edges by 2.3e-3 each time (the two
// sheets' words evaluate to matrices that disagree that much): E moved by
// ±1e-5 per step while Newton's steps decreased it by 1e-6, and the raw
// genus-8 polycube -> thin genus-8 plate solve wandered at gradient
// 0.03..0.06 (3.5e-5 of the largest weight) for its 300 iterations; with
// the anchors it reaches the tolerance in 3 (docs/robustness.md).
//
// Updating A_e in place instead (A_e ← τ^-1 A_e τ at every step)
// accumulates the absolute round-off of its largest size: a twisted class
// seen from an all-at-origin start has edges of size 1e8..1e14, whose
// in-place updates had drifted by up to 0.75 in length by the end, so the
// solve converged (to its own, wrong, A_e) at a folded point of higher
// energy than the true optimum of the class (n_hole_torus(2,40) -> vase:
// 439.89 where the class's optimum is 443.21 from the coarse start; the
// positions' true energy was 456.41).
class ChartState {
 public:
  /// #V chart C_i (per-face charts: inside face[i]'s chart); once the
  /// anchors are on (anchor_if_far), the local chart c_i: the steps since
  /// vertex i was last anchored, near the identity (re-anchored beyond
  /// kReanchorB), so kept in double.
  std::vector<Mobius> chart;
  std::vector<LongMobius> eff;  ///< #edges effective element ρ'_e
  std::vector<Mobius> A;  ///< #edges A_e, derived by derive_edges()
  std::vector<int> face;  ///< #V per-face charts only: the target face of chart[i]

  // Charts at the start points, every vertex moved to the sheet of the
  // target's domain (r.vertex_deck / vertex_deck_word record the moves).
  //
  // Per-face charts (`atlas` non-null, issue 13): chart[i] is vertex i's
  // chart inside the canonical chart of target face face[i], ρ'_e takes
  // face[j]'s canonical coordinates to face[i]'s, and the moves are the
  // transitions crossed when a vertex is walked to the face containing it;
  // the same bookkeeping, with no element of the deck group and no global chart.
  ChartState(int n, const std::vector<WeightedEdge>& edges, const std::vector<Mobius>& generators,
             const std::vector<Complex>& z0, const HyperbolicHarmonicOptions& options, HyperbolicHarmonicResult& r,
             const FaceAtlas* atlas = nullptr, std::vector<int> face0 = {})
      : face(std::move(face0)), edges_(edges), generators_(generators), options_(options), r_(r),
        words_(!options.relator.empty() && !atlas), reduce_word_(words_ ? options.relator : Word{}), atlas_(atlas) {
    for (const auto& g : generators) moves_.push_back(g), moves_.push_back(g.inverse());
    chart.resize(n);
    for (int i = 0; i < n; ++i) chart[i] = Mobius::translation_to(z0[i]);
    if (words_)
      for (size_t e = 0; e < edges.size(); ++e)
        if (edges[e].rho_word.empty() && hyperbolic::distance_from_identity(edges[e].rho) > 1e-12)
          throw InputError("hyperbolic_harmonic_map: edge " + std::to_string(e) +
                           " has no rho_word although a relator was given");
    // Incident edges of every vertex (CSR), for the conjugations of the chart moves.
    inc_start_.assign(n + 1, 0);
    for (const auto& ed : edges) {
      ++inc_start_[ed.i + 1];
      if (ed.j != ed.i) ++inc_start_[ed.j + 1];
    }
    for (int v = 0; v < n; ++v) inc_start_[v + 1] += inc_start_[v];
    inc_edge_.resize(inc_start_[n]);
    {
      std::vector<int> fill(inc_start_.begin(), inc_start_.end() - 1);
      for (size_t e = 0; e < edges.size(); ++e) {
        inc_edge_[fill[edges[e].i]++] = static_cast<int>(e);
        if (edges[e].j != edges[e].i) inc_edge_[fill[edges[e].j]++] = static_cast<int>(e);
      }
    }
    // Effective elements: with words, evaluated from the reduced word (in
    // long double) whenever it changes; without, conjugated as matrices.
    eff_word_.resize(words_ ? edges.size() : 0);
    eff.resize(edges.size());
    for (size_t e = 0; e < edges.size(); ++e) {
      if (words_) {
        eff_word_[e] = reduce_word_(edges[e].rho_word);
        eff[e] = evaluate_long(eff_word_[e]);
      } else {
        eff[e] = LongMobius::from(edges[e].rho);
      }
    }
    if (words_ && options_.max_start_round_off > 0) refuse_unevaluable_starts(z0);
    anchor_if_far();
    A.resize(edges.size());
    derive_edges();
    // Edges longer than ~70 units at the start (entries beyond 1e15; a class
    // twisted by dozens of tiles, seen from a start at the origin) would take
    // the solve hundreds of capped steps (minutes at genus 5 when the class
    // ranking tries such classes), and no map with such an edge is an
    // embedding of a mesh of this size: refused at once. A cost limit, not a
    // precision one: the elements are words multiplied out in long double,
    // and raised, such starts converge (session 25: the n-hole torus -> vase
    // classes refused at 73.7-132.4 units solve with 0 flipped), so the
    // message says which limit, not "beyond double range" as it did.
    for (size_t e = 0; e < edges.size(); ++e)
      if (!(A[e].size() < options_.max_start_edge_size))
        throw SolveError("hyperbolic harmonic map: edge " + std::to_string(e) + " starts " +
                         std::to_string(A[e].displacement_of_origin()) +
                         " units long (beyond this solve's start-edge limit: such a start costs hundreds of "
                         "capped steps)",
                         SolveFailure::start_edges);
    r.vertex_deck.assign(n, Mobius());
    r.vertex_deck_word.assign(n, Word{});
    for (int i = 0; i < n; ++i) move_vertex(i);
    anchor_if_far();
    derive_edges();
  }

  // Issue 13 (session 24): every edge's start element T_i^-1 ρ'_e T_j
  // multiplied out as A_e will be (the start charts T_i, then the letters of
  // its reduced word), with the round-off estimate of multiply_out; an
  // element that keeps fewer digits than options.max_start_round_off asks
  // (or comes out non-finite) is refused, naming the edge, its letters and
  // how far its partial products went: the class cannot be evaluated in
  // this domain, which is not the same as a class twisted too far.
  void refuse_unevaluable_starts(const std::vector<Complex>& z0) {
    const long double eps = std::numeric_limits<long double>::epsilon();
    std::vector<LongMobius> f, suffix;
    for (size_t e = 0; e < edges_.size(); ++e) {
      const Word& w = eff_word_[e];
      if (w.size() < 2) continue;  // one letter or none: exact up to its own rounding
      const WeightedEdge& ed = edges_[e];
      f.clear();
      f.push_back(LongMobius::from(Mobius::translation_to(z0[ed.i]).inverse()));
      for (int x : w) f.push_back(letter(x));
      f.push_back(LongMobius::from(Mobius::translation_to(z0[ed.j])));
      const LongProduct p = multiply_out(f, suffix);
      const long double s = size(p.value), relative = p.error * eps / s;
      if (std::isfinite(static_cast<double>(s)) && relative <= options_.max_start_round_off) continue;
      long double widest = 1;  // the largest partial product from the left
      LongMobius m;
      for (const LongMobius& x : f) m = m * x, widest = std::max(widest, size(m));
      char text[320];
      std::snprintf(text, sizeof text,
                    "hyperbolic harmonic map: edge %zu's deck element cannot be evaluated in this domain (its "
                    "reduced word of %zu side letters has partial products up to 10^%.1f for an element of size "
                    "10^%.1f, round-off %.2g of it)",
                    e, w.size(), static_cast<double>(std::log10(widest)), static_cast<double>(std::log10(s)),
                    static_cast<double>(relative));
      throw SolveError(text);
    }
  }

  // Every A_e afresh: A_e = c_i^-1 K_e c_j from the local charts and the
  // anchored elements, or A_e = C_i^-1 ρ'_e C_j from the full charts while
  // they are all near the origin.
  void derive_edges() {
    for (size_t e = 0; e < edges_.size(); ++e) {
      const LongMobius ci = LongMobius::from(chart[edges_[e].i]), cj = LongMobius::from(chart[edges_[e].j]);
      const LongMobius& K = anchored_mode_ ? anchored_[e] : eff[e];
      A[e] = (ci.inverse() * K * cj).normalized().to_double().normalized();
    }
  }

  bool in_face_charts() const { return atlas_ != nullptr; }

  /// Whether the charts are split into anchors and local charts (see
  /// kAnchorChartSize).
  bool anchored() const { return anchored_mode_; }

  /// The anchors are needed only far from the origin: A_e derived from full
  /// charts in double is off by ~1e-16 |C_i| |C_j| (sizes |a| + |b|), below
  /// 1e-12 while every chart is below 100 (within ~9 units of the origin),
  /// a hundredth of the default gradient tolerance (1e-10 of the largest
  /// weight). Until a chart reaches that size the solve keeps the full
  /// charts in double, as it did before the anchors, with the same
  /// arithmetic bit for bit; the anchors cost CPU (n_hole_torus(2,32) ->
  /// vase(2,32): 0.86 -> 1.03 s user, 5% of it in hypotl: the full chart
  /// T_i c_i and its |b| in long double for every vertex at every
  /// iteration, and the round-off bounds of every sheet change). The first
  /// chart beyond it (after the start's sheet moves or after a step)
  /// switches the whole solve to the anchors, once, for good.
  static constexpr double kAnchorChartSize = 100.0;
  void anchor_if_far() {
    if (anchored_mode_ || atlas_) return;  // per-face charts stay near their face's chart
    bool far = false;
    for (const Mobius& c : chart) far = far || !(c.size() < kAnchorChartSize);
    if (!far) return;
    anchored_mode_ = true;
    anchor_.resize(chart.size());
    for (size_t v = 0; v < chart.size(); ++v) anchor_[v] = LongMobius::from(chart[v]), chart[v] = Mobius();
    anchored_.resize(edges_.size());
    anchored_error_.resize(edges_.size());
    for (size_t e = 0; e < edges_.size(); ++e) {
      const LongProduct K = fresh_anchored(static_cast<int>(e));
      anchored_[e] = K.value, anchored_error_[e] = K.error;
    }
  }

  /// Vertex v's full chart C_v = T_v c_v (C_v itself before the anchors).
  LongMobius full_chart(int v) const {
    if (!anchored_mode_) return LongMobius::from(chart[v]);
    return (anchor_[v] * LongMobius::from(chart[v])).normalized();
  }

  /// The local chart folded into the anchor once it has moved beyond
  /// kReanchorB (|b| = sinh(d/2): about 1.4 units), so that c_v stays near
  /// the identity: T_v ← T_v c_v, c_v ← 1, and the incident K_e carried
  /// along (K_e ← c_i^-1 K_e c_j, A_e unchanged), or derived afresh when that
  /// is the more accurate (refresh_if_better).
  static constexpr double kReanchorB = 0.75;
  void reanchor_if_moved(int v) {
    if (!anchored_mode_ || !(std::abs(chart[v].b) > kReanchorB)) return;
    const LongMobius c = LongMobius::from(chart[v]);
    anchor_[v] = (anchor_[v] * c).normalized();
    const long double c_size = std::abs(c.a) + std::abs(c.b);
    for (int k = inc_start_[v]; k < inc_start_[v + 1]; ++k) {
      const int e = inc_edge_[k];
      LongMobius K = anchored_[e];
      if (edges_[e].i == v) K = c.inverse() * K;
      if (edges_[e].j == v) K = K * c;
      anchored_[e] = K.normalized();
      anchored_error_[e] += c_size * (std::abs(K.a) + std::abs(K.b));
      refresh_if_better(e);
    }
    chart[v] = Mobius();
  }

  // Dynamic charts: vertex v to the sheet options.reduce_point names, or
  // greedily towards the origin by the generators; in per-face charts, to
  // the face containing it (kept where it is when the walk does not reach
  // it: its chart is still exact, only farther from the face).
  void move_vertex(int v) {
    if (atlas_) {
      Mobius moved;
      Eigen::Vector3d bary;
      const int g = locate_in_face_charts(*atlas_, face[v], chart[v].apply(Complex(0.0)), kMaxWalkFaces, &moved, &bary);
      if (g >= 0 && g != face[v]) change_sheet(v, Word{}, moved, LongMobius::from(moved)), face[v] = g;
      return;
    }
    if (options_.reduce_point) {
      Complex z = position(v);
      const Word w = options_.reduce_point(z);
      if (!w.empty()) {
        const LongMobius g = evaluate_long(w);
        change_sheet(v, w, g.to_double().normalized(), g);
      }
      return;
    }
    const Mobius full = anchored_mode_ ? full_chart(v).to_double().normalized() : chart[v];
    for (int m : reduce_towards_origin(full, moves_))
      change_sheet(v, Word{move_letter(m)}, moves_[m], LongMobius::from(moves_[m]));
  }

  /// z_v = C_v(0) = b / ā of the full chart.
  Complex position(int v) const {
    if (!anchored_mode_) return chart[v].apply(Complex(0.0));
    const LongMobius C = full_chart(v);
    const std::complex<long double> z = C.b / std::conj(C.a);
    return {static_cast<double>(z.real()), static_cast<double>(z.imag())};
  }

 private:
  LongMobius evaluate_long(const Word& w) const {
    LongMobius m;
    for (int x : w) m = (m * letter(x)).normalized();
    return m;
  }

  // K_e = T_i^-1 ρ'_e T_j afresh (fresh_anchored) when its round-off
  // estimate is well below the one K_e carries: a vertex that flips between
  // two sheets from one iteration to the next then does not move its edges'
  // elements by the round-off of the far one, and an element whose product
  // keeps no digits never replaces one that does.
  void refresh_if_better(int e) {
    const LongProduct fresh = fresh_anchored(e);
    if (fresh.error < 0.25L * anchored_error_[e]) anchored_[e] = fresh.value, anchored_error_[e] = fresh.error;
  }

  // K_e = T_i^-1 ρ'_e T_j multiplied out as one product: with words, of T_i^-1,
  // the letters of ρ'_e's reduced word and T_j, so that every partial
  // product is seen from vertex i's anchor; without, of T_i^-1, ρ'_e, T_j.
  // Issue 13 (raw genus-8 polycube -> thin genus-8 plate): the letters are
  // side pairings with entries up to 4e4, and an edge between two vertices
  // 0.17 apart on either side of a far corner of P has a word of 9 of them
  // that circles the corner through tiles whose centres are up to 55 units
  // from the origin. Multiplied out alone, ρ'_e's partial products pass
  // 1e12 (sizes |a| + |b|), where long double keeps no digit, and K_e derived
  // from it was off by up to 6; 146 of the 22,156 intrinsic triangles did not
  // close up (by up to 0.044) and 3 folded. Seen from T_i the partial
  // products are only as large as vertex i is far from those centres, and
  // the triangles close to 5.6e-5, the target's own round-off
  // (docs/robustness.md "Long deck elements").
  LongProduct fresh_anchored(int e) const {
    const WeightedEdge& ed = edges_[e];
    std::vector<LongMobius>& f = factor_scratch_;
    f.clear();
    f.push_back(anchor_[ed.i].inverse());
    if (words_)
      for (int x : eff_word_[e]) f.push_back(letter(x));
    else
      f.push_back(eff[e]);
    f.push_back(anchor_[ed.j]);
    return multiply_out(f, suffix_scratch_);
  }
  LongMobius letter(int x) const {
    const int k = std::abs(x) - 1;
    if (k < 0 || k >= static_cast<int>(generators_.size()))
      throw InputError("hyperbolic_harmonic_map: letter " + std::to_string(x) + " names no generator");
    return LongMobius::from(moves_[x > 0 ? 2 * k : 2 * k + 1]);
  }

  // Vertex v to another sheet by γ (word w when words are kept): T_v ← γ T_v,
  // and its edges conjugated, ρ'_e ← γ ρ'_e where v is the tail and
  // ρ'_e ← ρ'_e γ^-1 where it is the head, so that K_e (and A_e) is
  // unchanged; K_e is derived afresh only when the new sheet makes that the
  // more accurate (fewer or shorter letters).
  // Before the anchors, C_v ← γ C_v in double and ρ'_e conjugated by γ as
  // rounded to double; with them, by g (γ in long double).
  void change_sheet(int v, const Word& w, const Mobius& gamma, const LongMobius& g_long) {
    if (anchored_mode_)
      anchor_[v] = (g_long * anchor_[v]).normalized();
    else
      chart[v] = (gamma * chart[v]).normalized();
    const LongMobius g = anchored_mode_ ? g_long : LongMobius::from(gamma);
    if (!atlas_) {  // per-face charts: gamma is a transition, not a deck element
      r_.vertex_deck[v] = (gamma * r_.vertex_deck[v]).normalized();
      r_.vertex_deck_word[v] = concat(w, r_.vertex_deck_word[v]);
    }
    for (int k = inc_start_[v]; k < inc_start_[v + 1]; ++k) {
      const int e = inc_edge_[k];
      const WeightedEdge& ed = edges_[e];
      if (words_) {
        Word x = eff_word_[e];
        if (ed.i == v) x = concat(w, x);
        if (ed.j == v) x = concat(x, inverse(w));
        eff_word_[e] = reduce_word_(x);
        eff[e] = evaluate_long(eff_word_[e]);
      } else {
        if (ed.i == v) eff[e] = (g * eff[e]).normalized();
        if (ed.j == v) eff[e] = (eff[e] * g.inverse()).normalized();
      }
      if (anchored_mode_) refresh_if_better(e);
    }
  }

  const std::vector<WeightedEdge>& edges_;
  const std::vector<Mobius>& generators_;
  const HyperbolicHarmonicOptions& options_;
  HyperbolicHarmonicResult& r_;
  const bool words_;
  const DehnReducer reduce_word_;
  const FaceAtlas* atlas_;
  // A vertex moves a fraction of an edge per step (kMaxStep caps it), so
  // its walk crosses a few faces; the cap only bounds a lost walk.
  static constexpr int kMaxWalkFaces = 256;
  std::vector<Mobius> moves_;  // generator k at 2k, its inverse at 2k+1
  std::vector<int> inc_start_, inc_edge_;
  std::vector<Word> eff_word_;
  bool anchored_mode_ = false;  // charts split T_i c_i (anchor_if_far)
  std::vector<LongMobius> anchor_;  // #V anchor T_i (the full chart is T_i c_i)
  std::vector<LongMobius> anchored_;  // #edges K_e = T_i^-1 ρ'_e T_j
  std::vector<long double> anchored_error_;  // #edges round-off estimate of K_e (units of epsilon)
  mutable std::vector<LongMobius> factor_scratch_, suffix_scratch_;  // fresh_anchored's
};

// The energy Σ w d² for edge elements `a` (one per edge).
double chart_energy(const std::vector<WeightedEdge>& edges, const std::vector<Mobius>& a) {
  double E = 0;
  for (size_t e = 0; e < edges.size(); ++e) {
    if (edges[e].w <= 0) continue;
    const double d = a[e].displacement_of_origin();
    E += edges[e].w * d * d;
  }
  return E;
}

// Largest per-vertex gradient length for edge elements `a` (free vertices);
// `grad_buf`: #V scratch.
double chart_gradient_norm(const std::vector<WeightedEdge>& edges, const std::vector<Mobius>& a,
                           const std::vector<char>& fixed, const std::vector<Complex>& slide_dir,
                           std::vector<Complex>& grad_buf, const std::vector<Complex>& extra = {}) {
  const int n = static_cast<int>(grad_buf.size());
  std::fill(grad_buf.begin(), grad_buf.end(), Complex(0.0));
  for (size_t e = 0; e < edges.size(); ++e) {
    if (edges[e].w <= 0) continue;
    const Mobius& M = a[e];
    const double d = M.displacement_of_origin(), bn = std::abs(M.b);
    if (!(bn > 0)) continue;
    grad_buf[edges[e].i] -= 2 * edges[e].w * d * (M.b / std::conj(M.a)) * (std::abs(M.a) / bn);
    grad_buf[edges[e].j] -= 2 * edges[e].w * d * (-M.b / M.a) * (std::abs(M.a) / bn);
  }
  for (size_t i = 0; i < extra.size(); ++i) grad_buf[i] += extra[i];
  double gn = 0;
  for (int i = 0; i < n; ++i) {
    if (!fixed.empty() && fixed[i]) continue;
    // A sliding vertex: the gradient's component along its geodesic.
    const bool slides = !slide_dir.empty() && slide_dir[i] != Complex(0.0);
    gn = std::max(gn, slides ? std::abs((grad_buf[i] * std::conj(slide_dir[i])).real()) : std::abs(grad_buf[i]));
  }
  return gn;
}

// Riemannian Newton system (docs/method.md §7) at the edge elements A:
// unknowns are a tangent vector per vertex in the orthonormal frame of its
// chart at 0 (2 reals). For the term w d(x, y)^2 seen from x's chart,
// y = A_e(0) lies on the diameter with direction u; the Hessian of ½d² is
// [1 -1; -1 1] along u and [a -b; -b a] across it (a = d coth d,
// b = d / sinh d), and y's own frame is rotated by theta = arg A_e'(0).
// Held vertices (`fixed`, landmarks): no gradient and identity rows and
// columns (scaled by max_w), so their Newton step is 0 and the other
// vertices see them as fixed. Sliding vertices (`slide_dir`, empty or #V:
// the unit direction of the vertex's geodesic in its chart, 0 for a free
// vertex; BoundarySlideOptions): the unknowns (t, s) stand for the tangent
// vector t u, so their blocks are B^T H B with B = [u 0] and the dead
// unknown s gets an identity row (scaled by max_w) and no gradient, as a held
// vertex's. Fills H and g (2 #V).
void assemble_newton_system(const std::vector<WeightedEdge>& edges, const std::vector<Mobius>& A,
                            const std::vector<char>& fixed, const std::vector<Complex>& slide_dir, double max_w,
                            BlockHessian& H, Eigen::VectorXd& g) {
  const int n = static_cast<int>(g.size() / 2);
  H.clear();
  const bool any_fixed = !fixed.empty();
  auto is_free = [&](int v) { return !any_fixed || !fixed[v]; };
  auto slides = [&](int v) { return !slide_dir.empty() && slide_dir[v] != Complex(0.0); };
  auto basis = [&](int v) {
    Eigen::Matrix2d B = Eigen::Matrix2d::Identity();
    if (slides(v)) B << slide_dir[v].real(), 0, slide_dir[v].imag(), 0;
    return B;
  };
  g.setZero();
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
    Eigen::Matrix2d Hii = 2 * e.w * P, Hjj = 2 * e.w * R.transpose() * P * R, Hij = -2 * e.w * Q * R;
    if (slides(e.i) || slides(e.j)) {
      const Eigen::Matrix2d Bi = basis(e.i), Bj = basis(e.j);
      Hii = Bi.transpose() * Hii * Bi, Hjj = Bj.transpose() * Hjj * Bj, Hij = Bi.transpose() * Hij * Bj;
    }
    // Held vertices: their rows and columns are left out.
    if (e.i == e.j) {
      if (is_free(e.i)) H.add_diagonal(e.i, Hii + Hjj + Hij + Hij.transpose());
      continue;
    }
    if (is_free(e.i)) H.add_diagonal(e.i, Hii);
    if (is_free(e.j)) H.add_diagonal(e.j, Hjj);
    if (is_free(e.i) && is_free(e.j)) H.add_offdiagonal(ei, e.i, e.j, Hij);
  }
  if (any_fixed)
    for (int i = 0; i < n; ++i)
      if (fixed[i]) {
        g[2 * i] = g[2 * i + 1] = 0;
        H.add_diagonal(i, max_w * Eigen::Matrix2d::Identity());
      }
  if (!slide_dir.empty())
    for (int i = 0; i < n; ++i)
      if (slides(i)) {
        g[2 * i] = g[2 * i] * slide_dir[i].real() + g[2 * i + 1] * slide_dir[i].imag();
        g[2 * i + 1] = 0;
        Eigen::Matrix2d dead = Eigen::Matrix2d::Zero();
        dead(1, 1) = max_w;
        H.add_diagonal(i, dead);
      }
}

using Clock = std::chrono::steady_clock;
using detail::seconds_since;

// The first line-search trial moves no vertex by more than this (a bad
// start can ask for steps of 30 units, whose translations have entries
// e^15), which only rescales the Newton step.
constexpr double kMaxStep = 4.0;

// Issue 19: from this many vertices on, the Newton steps after the first
// factorisation are CG on the current Hessian preconditioned by the kept
// factor (HarmonicNewton::preconditioned_step); below it (the ranking's
// coarse copies, at most 3000 vertices by default, where a factorisation
// costs a few solves) the chord steps. Session 24: 4000, was 10000 (the
// 4.9k bench source's full-resolution solve: 1 factorisation and 3 Newton
// steps instead of 2 and 5 with --threads 1, 0.42 G instructions instead of
// 0.48 G, the energy equal to 1e-13 relative). kMaxCgIterations: CG gives up after this
// many (about half a factorisation's worth of solves at 10^5 unknowns).
constexpr int kPreconditionedVertices = 4000;
constexpr int kMaxCgIterations = 15;

/// One newton_solve run: the chart state, the factorisation kept across
/// iterations (chord steps), the Levenberg shift and the last step's
/// bookkeeping, which run through every phase of an iteration; one method a
/// phase (the Newton system, the direction, the step with its line search
/// and fallbacks near round-off, the new charts). Holds references into
/// itself (state -> r): not copyable.
struct HarmonicNewton {
  const int n;
  const std::vector<WeightedEdge>& edges;
  const HyperbolicHarmonicOptions& options;
  const HessianAnalysis* shared;  // the pattern's analysis when given, else built at first use
  HyperbolicHarmonicResult r;
  ChartState state;
  std::vector<Mobius>& A;
  std::vector<Mobius>& chart;
  double max_w = 0;
  double E = 0;
  std::unique_ptr<HessianAnalysis> own_analysis;
  std::unique_ptr<BlockHessian> hessian;  // built at the first iteration that needs it
  // Factorisation state kept across iterations (chord and preconditioned
  // steps, below).
  double shift = 0, last_gnorm = std::numeric_limits<double>::infinity();
  bool factored = false, last_full_step = false, refactor = false;
  std::vector<Mobius> trial_A, step_map;
  std::vector<Complex> grad_buf;
  Eigen::VectorXd g;
  // BoundarySlideOptions: per vertex the unit direction of its geodesic in
  // its chart (0: free), derived afresh at every Newton system, and per
  // ordered edge the side of its head along the geodesic at the start (+1,
  // -1; 0 unchecked).
  std::vector<Complex> slide_dir;
  std::vector<signed char> order_sign;

  HarmonicNewton(int num_vertices, const std::vector<WeightedEdge>& edge_list, const std::vector<Mobius>& generators,
                 const std::vector<Complex>& z0, const HyperbolicHarmonicOptions& opts, const HessianAnalysis* analysis,
                 const FaceAtlas* atlas = nullptr, std::vector<int> face0 = {})
      : n(num_vertices),
        edges(edge_list),
        options(opts),
        shared(analysis),
        state(num_vertices, edge_list, generators, z0, opts, r, atlas, std::move(face0)),
        A(state.A),
        chart(state.chart),
        trial_A(edge_list.size()),
        step_map(num_vertices),
        grad_buf(num_vertices),
        g(2 * num_vertices) {
    for (const auto& e : edges) max_w = std::max(max_w, e.w);
    E = chart_energy(edges, A) + pull_energy(false);
    r.energy_history.push_back(E);
  }
  HarmonicNewton(const HarmonicNewton&) = delete;
  HarmonicNewton& operator=(const HarmonicNewton&) = delete;

  // Trial edge elements for the step alpha * xi (all vertices at once).
  void trial_edges(const Eigen::VectorXd& xi, double alpha) {
    for (int i = 0; i < n; ++i)
      step_map[i] = Mobius::translation(alpha * (!slide_dir.empty() && slide_dir[i] != Complex(0.0)
                                                     ? xi[2 * i] * slide_dir[i]
                                                     : Complex(xi[2 * i], xi[2 * i + 1])));
    for (size_t e = 0; e < edges.size(); ++e)
      trial_A[e] = (step_map[edges[e].i].inverse() * A[e] * step_map[edges[e].j]).normalized();
  }
  void accept(double Et) {
    A.swap(trial_A);
    for (int i = 0; i < n; ++i) chart[i] = (chart[i] * step_map[i]).normalized();
    E = Et;
  }
  // The full Newton step where E cannot resolve its decrease: taken when it
  // at least halves the gradient (quadratic convergence near the optimum
  // does far better), otherwise the gradient is at its round-off floor.
  bool gradient_step(const Eigen::VectorXd& step, double gnorm) {
    trial_edges(step, 1.0);
    ++r.energy_evaluations;
    if (!order_kept(trial_A)) return false;
    if (!(chart_gradient_norm(edges, trial_A, options.fixed, slide_dir, grad_buf, pull_gradient(true)) <= 0.5 * gnorm))
      return false;
    accept(chart_energy(edges, trial_A) + pull_energy(true));
    last_full_step = true;
    return true;
  }

  /// BoundarySlideOptions::pulls: the pull's geodesic seen from its vertex's
  /// chart (times step_map for a trial): its distance δ from the origin and
  /// the unit direction from the origin towards its nearest point (at δ = 0,
  /// across the geodesic).
  std::pair<double, Complex> pull_frame(const BoundarySlideOptions::Pull& p, bool trial) const {
    LongMobius C = state.full_chart(p.vertex);
    if (trial) C = C * LongMobius::from(step_map[p.vertex]);
    const Mobius m =
        (C.inverse() * LongMobius::from(r.vertex_deck[p.vertex]) * LongMobius::from(p.geodesic)).normalized().to_double();
    const Complex y = -m.b / m.a;  // the origin in the geodesic's model (the geodesic: the real diameter)
    const double delta = std::asinh(2 * std::abs(y.imag()) / std::max(1 - std::norm(y), 1e-300));
    const double k = (2.0 * y / (1.0 + std::norm(y))).real();  // the foot: straight perpendicular in Klein
    const Complex foot = m.apply(Complex(k / (1 + std::sqrt(std::max(1 - k * k, 0.0))), 0.0));
    if (std::abs(foot) > 1e-15) return {delta, foot / std::abs(foot)};
    const Complex along = m.derivative(Complex(k, 0.0));
    return {delta, Complex(0.0, 1.0) * along / std::abs(along)};
  }
  double pull_energy(bool trial) const {
    double sum = 0;
    for (const auto& p : options.boundary_slide.pulls) {
      const double delta = pull_frame(p, trial).first;
      sum += p.w * delta * delta;
    }
    return sum;
  }
  /// #V gradients of the pulls (empty without pulls).
  std::vector<Complex> pull_gradient(bool trial) const {
    if (options.boundary_slide.pulls.empty()) return {};
    std::vector<Complex> grad(n, Complex(0.0));
    for (const auto& p : options.boundary_slide.pulls) {
      const auto [delta, toward] = pull_frame(p, trial);
      grad[p.vertex] -= 2 * p.w * delta * toward;
    }
    return grad;
  }
  /// The pulls' gradient and Hessian (docs in BoundarySlideOptions::pulls).
  void add_pulls(BlockHessian& H) {
    for (const auto& p : options.boundary_slide.pulls) {
      const auto [delta, toward] = pull_frame(p, false);
      g[2 * p.vertex] -= 2 * p.w * delta * toward.real();
      g[2 * p.vertex + 1] -= 2 * p.w * delta * toward.imag();
      const Eigen::Vector2d nv(toward.real(), toward.imag()), tv(-toward.imag(), toward.real());
      H.add_diagonal(p.vertex, 2 * p.w * (nv * nv.transpose() + delta * std::tanh(delta) * tv * tv.transpose()));
    }
  }

  /// Vertex i's geodesic seen from its chart: M = C_i^-1 deck_i G_i maps
  /// the real diameter onto it, through the chart's origin up to round-off
  /// (at x = M^-1(0), taken on the diameter); slide_dir[i] = M'(x) / |M'(x)|.
  void derive_slide_directions() {
    const BoundarySlideOptions& slide = options.boundary_slide;
    slide_dir.assign(n, Complex(0.0));
    for (int i = 0; i < n; ++i) {
      if (!slide.slides[i]) continue;
      const LongMobius M = state.full_chart(i).inverse() * LongMobius::from(r.vertex_deck[i]) *
                           LongMobius::from(slide.geodesic[i]);
      const Mobius m = M.normalized().to_double();
      const double x = (-m.b / m.a).real();
      const Complex d = m.derivative(Complex(x, 0.0));
      slide_dir[i] = d / std::abs(d);
    }
  }
  /// The side (sign along the tail's geodesic direction) of every ordered
  /// edge's head, from edge elements `a`.
  double order_side(const std::vector<Mobius>& a, int e) const {
    const Mobius& M = a[e];
    return ((M.b / std::conj(M.a)) * std::conj(slide_dir[edges[e].i])).real();
  }
  void record_order() {
    const auto& ordered = options.boundary_slide.ordered_edges;
    order_sign.assign(ordered.size(), 0);
    for (size_t k = 0; k < ordered.size(); ++k) {
      const double side = order_side(A, ordered[k]);
      order_sign[k] = side > 0 ? 1 : side < 0 ? -1 : 0;
    }
  }
  /// Whether the trial elements keep every ordered edge's head on its start
  /// side (the trial's charts moved along the geodesics, which keeps their
  /// directions, so slide_dir still holds).
  bool order_kept(const std::vector<Mobius>& a) {
    for (size_t k = 0; k < order_sign.size(); ++k)
      if (order_sign[k] != 0 && !(order_sign[k] * order_side(a, options.boundary_slide.ordered_edges[k]) > 0)) {
        ++r.order_rejections;
        return false;
      }
    return true;
  }

  /// The Newton system (H, g) at the current charts; returns the largest
  /// per-vertex gradient, recorded in r.gradient_history. Throws SolveError
  /// on a non-finite energy or gradient, Cancelled from options.progress.
  double newton_system(int it) {
    if (!hessian) {
      const auto t0 = Clock::now();
      if (!shared) own_analysis = std::make_unique<HessianAnalysis>(n, edges);
      hessian = std::make_unique<BlockHessian>(shared ? *shared : *own_analysis);
      r.analysis_seconds += seconds_since(t0);
    }
    BlockHessian& H = *hessian;
    if (!options.boundary_slide.slides.empty()) {
      derive_slide_directions();
      if (order_sign.empty()) record_order();
    }
    assemble_newton_system(edges, A, options.fixed, slide_dir, max_w, H, g);
    add_pulls(H);
    if (!g.allFinite() || !std::isfinite(E))
      throw SolveError("hyperbolic harmonic map: non-finite energy or gradient at iteration " + std::to_string(it));
    double gnorm = 0;
    for (int i = 0; i < n; ++i) gnorm = std::max(gnorm, std::hypot(g[2 * i], g[2 * i + 1]));
    r.gradient_history.push_back(gnorm);
    if (options.progress && !options.progress(it, E, gnorm)) throw Cancelled("harmonic map solve cancelled");
    return gnorm;
  }

  // A Levenberg shift keeps the factorisation definite: tiny where the
  // model is exact (the normal surplus d coth d − 1 is O(d²)), raised when
  // far from the optimum the frame bookkeeping leaves it indefinite.
  void factorize() {
    BlockHessian& H = *hessian;
    for (shift = 1e-9 * max_w;; shift *= 100) {
      const auto t0 = Clock::now();
      const bool ok = H.factorize(shift);
      r.factorization_seconds += seconds_since(t0);
      ++r.factorizations;
      if (ok) break;
      if (shift > 1e6 * max_w) throw SolveError("hyperbolic harmonic map: Hessian factorisation failed");
    }
  }
  double diag(int k) const { return hessian->diagonal(k) + shift; }

  /// Issue 19: the Newton step on the current Hessian by conjugate gradients
  /// preconditioned with the kept factorisation (of an earlier iteration's
  /// Hessian), on sources of kPreconditionedVertices or more. Inexact
  /// Newton with quadratic forcing: the linear residual
  /// |(H + shift_min) x + g| is brought below eta |g| with
  /// eta = min(1e-2, |g|_max / max w), or only until its largest per-vertex
  /// length is a tenth of the stopping tolerance (then the step's gradient
  /// is below the tolerance up to the model's error, quadratic in the step).
  /// From the prolonged coarse solution of the 50k remeshed pair this takes
  /// 3 Newton iterations with 13 CG iterations where the superlinear
  /// eta = min(1e-2, sqrt(|g|_max / max w)) took 4 with 15 (docs/benchmarks.md):
  /// the model is nearly exact there (|g| 0.9 -> 1.9e-3 in the factorised
  /// step), so the solve's own error is what limits each step. Should the
  /// tighter target need more than kMaxCgIterations, a step that already
  /// meets the superlinear target is taken. The outer loop's stopping test
  /// (the gradient against the tolerance) is unchanged, so the optimum is
  /// the same to tolerance. Empty when CG meets non-positive curvature or
  /// meets neither target in kMaxCgIterations (the caller then factorises
  /// afresh).
  Eigen::VectorXd preconditioned_step(double gnorm) {
    BlockHessian& H = *hessian;
    const double min_shift = 1e-9 * max_w;
    const double g2 = g.norm();
    const double scale = std::max(max_w, 1e-300);
    const double quadratic = std::min(1e-2, gnorm / scale);
    const double superlinear = std::min(1e-2, std::sqrt(gnorm / scale));
    const double stop = std::min(0.5, quadratic) * g2;
    const double acceptable = std::min(0.5, superlinear) * g2;
    const double enough = 0.1 * options.tolerance * scale;  // per vertex
    auto largest_vertex = [&](const Eigen::VectorXd& v) {
      double m = 0;
      for (int i = 0; i < n; ++i) m = std::max(m, std::hypot(v[2 * i], v[2 * i + 1]));
      return m;
    };
    Eigen::VectorXd x = Eigen::VectorXd::Zero(2 * n), res = -g;
    Eigen::VectorXd z = H.solve(res), p = z;
    double rz = res.dot(z);
    for (int k = 0; k < kMaxCgIterations; ++k) {
      const Eigen::VectorXd Hp = H.multiply(p, min_shift);
      const double pHp = p.dot(Hp);
      ++r.cg_iterations;
      if (!(pHp > 0) || !(rz > 0)) break;
      const double a = rz / pHp;
      x += a * p;
      res -= a * Hp;
      const double rn = res.norm();
      if (rn <= stop || largest_vertex(res) <= enough || (k + 1 == kMaxCgIterations && rn <= acceptable)) {
        if (!x.allFinite()) break;
        ++r.preconditioned_steps;
        return x;
      }
      z = H.solve(res);
      const double rz_new = res.dot(z);
      p = z + (rz_new / rz) * p;
      rz = rz_new;
    }
    return {};
  }

  /// The step of this iteration: Newton (from the kept factorisation when
  /// *chord is set on return: a chord step on small sources, a
  /// preconditioned CG step on large ones), else the diagonally scaled
  /// gradient.
  Eigen::VectorXd direction(double gnorm, bool* chord_out) {
    BlockHessian& H = *hessian;
    ++work::newton_iterations;
    Eigen::VectorXd step;
    bool chord = false;
    if (n >= kPreconditionedVertices) {
      // A factorisation of the block Hessian costs ~30 solves with it
      // (2·10^5 unknowns: 0.7 s against 0.02 s), and from the prolonged
      // coarse solution the Hessian changes little between iterations: CG
      // on the current Hessian with the first factor as preconditioner
      // takes a handful of solves.
      if (factored && !refactor) step = preconditioned_step(gnorm);
      chord = step.size() > 0;
      refactor = false;
      if (!chord) factorize(), factored = true, step = H.solve(-g);
    } else {
      // Chord steps: near the optimum the Hessian hardly changes between
      // iterations (on a fine mesh the edges are short, d coth d ≈ 1, and the
      // frames turn little), so the last factorisation is kept while it still
      // gives full steps that cut the gradient at least fourfold.
      chord = factored && last_full_step && gnorm <= 0.25 * last_gnorm;
      if (!chord) factorize(), factored = true;
      step = H.solve(-g);
      if (chord && (!(g.dot(step) < 0) || !step.allFinite())) factorize(), step = H.solve(-g);
    }
    *chord_out = chord;
    last_gnorm = gnorm;
    // Far from the optimum the frame bookkeeping makes the model Hessian
    // inexact; fall back to the diagonally scaled gradient when the Newton
    // direction is not a descent direction.
    if (!(g.dot(step) < 0) || !step.allFinite()) {
      for (int k = 0; k < 2 * n; ++k) step[k] = -g[k] / std::max(diag(k), 1e-300);
    }
    return step;
  }

  enum class Outcome { kMoved, kRetry, kStop };

  /// Backtracking line search on E along `step`, with the fallbacks near
  /// round-off: kMoved (charts to update), kRetry (the kept factorisation
  /// gave no decrease: refactorise from the same point) or kStop (with
  /// r.converged set).
  Outcome take_step(int it, const Eigen::VectorXd& step, double gnorm, bool chord) {
    double longest = 0;
    for (int i = 0; i < n; ++i) longest = std::max(longest, std::hypot(step[2 * i], step[2 * i + 1]));
    double alpha = longest > kMaxStep ? kMaxStep / longest : 1.0;
    last_full_step = false;
    bool accepted = false;
    const double slope = g.dot(step);
    // Newton decrement below the round-off of E (a sum of #E terms): E can
    // no longer judge the step, but the gradient still can. Stopping here
    // instead (as before) left gradients of ~1e-7 · max w on a 2.6k-vertex
    // source (decrement ~|g|² / λ_min with λ_min ~ 1e-3), a thousand times
    // the tolerance, and maps 1e-6 apart from different starts.
    if (-0.5 * slope <= 1e-13 * E) {
      r.iterations = it;
      if (!gradient_step(step, gnorm)) {
        r.converged = true;
        return Outcome::kStop;
      }
      accepted = true;
    }
    for (int ls = 0; ls < 40 && !accepted; ++ls) {
      trial_edges(step, alpha);
      if (!order_kept(trial_A)) {
        alpha *= 0.5;
        continue;
      }
      const double Et = chart_energy(edges, trial_A) + pull_energy(true);
      ++r.energy_evaluations;
      if (Et < E && (Et <= E + 1e-4 * alpha * slope || alpha < 1e-3)) {
        accept(Et);
        accepted = true;
        last_full_step = alpha == 1.0;
        break;
      }
      alpha *= 0.5;
    }
    r.iterations = it + 1;
    if (!accepted && chord) {
      // The kept factorisation gave no decrease: the next iteration
      // factorises afresh (last_full_step is false) from the same point.
      last_gnorm = std::numeric_limits<double>::infinity();
      refactor = true;
      return Outcome::kRetry;
    }
    if (!accepted) {
      // No decrease along the Newton direction. Try the scaled gradient once
      // before concluding that round-off has been reached.
      Eigen::VectorXd gs(2 * n);
      for (int k = 0; k < 2 * n; ++k) gs[k] = -g[k] / std::max(diag(k), 1e-300);
      double gl = 0;
      for (int i = 0; i < n; ++i) gl = std::max(gl, std::hypot(gs[2 * i], gs[2 * i + 1]));
      for (double beta = gl > kMaxStep ? kMaxStep / gl : 1.0; beta > 1e-8 && !accepted; beta *= 0.25) {
        trial_edges(gs, beta);
        if (!order_kept(trial_A)) continue;
        const double Et = chart_energy(edges, trial_A) + pull_energy(true);
        ++r.energy_evaluations;
        if (Et < E) accept(Et), accepted = true;
      }
      // The decrease Newton still predicts (−g·step/2) may be below what E
      // resolves: then the full step is judged by the gradient.
      if (!accepted && -0.5 * slope <= 1e-9 * E) accepted = gradient_step(step, gnorm);
      if (!accepted) {
        // Converged if the gradient is tiny, or if the decrease Newton still
        // predicts is below what E can resolve in floating point.
        r.converged = gnorm <= 1e4 * options.tolerance * std::max(max_w, 1e-300) || -0.5 * slope <= 1e-9 * E;
        return Outcome::kStop;
      }
    }
    return Outcome::kMoved;
  }

  /// After a step: the new charts and sheets.
  void recentre_charts() {
    // Local charts that moved far into their anchors; then dynamic charts:
    // far-out vertices back to the domain's sheet (greedy: |C_i(0)| > 0.6),
    // or in per-face charts to the face containing them.
    for (int i = 0; i < n; ++i) {
      if (!state.anchored()) {
        if (state.in_face_charts() || options.reduce_point || std::abs(chart[i].b) > 0.75) state.move_vertex(i);
        continue;
      }
      state.reanchor_if_moved(i);
      if (options.reduce_point || std::abs(state.full_chart(i).b) > 0.75L) state.move_vertex(i);
    }
    state.anchor_if_far();
    // The new charts and sheets: every A_e afresh (ChartState above), and
    // the energy the next iteration starts from.
    state.derive_edges();
    E = chart_energy(edges, A) + pull_energy(false);
    r.energy_history.push_back(E);
  }

  /// The result: energy, positions z (#V), edge elements.
  void finish() {
    r.energy = E;
    r.z.resize(n);
    for (int i = 0; i < n; ++i) r.z[i] = state.position(i);
    if (state.in_face_charts()) r.face = state.face;
    r.edge_local = A;
    r.edge_effective.resize(edges.size());
    for (size_t e = 0; e < edges.size(); ++e) r.edge_effective[e] = state.eff[e].to_double().normalized();
    if (!options.boundary_slide.slides.empty()) {
      // Distance of each sliding vertex (its chart's origin) from its
      // geodesic M(real diameter): that of x = M^-1(0) from the diameter.
      for (int i = 0; i < n; ++i) {
        if (!options.boundary_slide.slides[i]) continue;
        const LongMobius M = state.full_chart(i).inverse() * LongMobius::from(r.vertex_deck[i]) *
                             LongMobius::from(options.boundary_slide.geodesic[i]);
        const Mobius m = M.normalized().to_double();
        const Complex x = -m.b / m.a;
        r.slide_off_geodesic =
            std::max(r.slide_off_geodesic, std::asinh(2 * std::abs(x.imag()) / std::max(1 - std::norm(x), 1e-300)));
      }
    }
  }
};

// Issue 13: a solve whose gradient has reached the round-off floor of its
// charts (a genus-11 coarse copy: E = 257.4074879 +- 4e-8, about #E ulps of
// E, gradient 3e-8 .. 1e-7 against a tolerance of 1e-8) still finds steps
// that "decrease" E by noise, so take_step never stops it and it used to
// run out of iterations and be reported as not converged. It is converged
// when, for kWindow iterations, neither E has dropped by more than its
// round-off (1e-12 E relative, several ulps of a sum of #E terms) nor the
// gradient halved, and the gradient is within the floor take_step's own
// round-off stop accepts (1e4 times the tolerance).
struct RoundoffPlateau {
  static constexpr int kWindow = 30;
  double best_E = std::numeric_limits<double>::infinity();
  double best_g = std::numeric_limits<double>::infinity();
  int since_progress = 0;
  bool reached(double E, double gnorm, double floor) {
    const bool progress = E < best_E - 1e-12 * std::abs(best_E) || gnorm < 0.5 * best_g;
    best_E = std::min(best_E, E);
    best_g = std::min(best_g, gnorm);
    since_progress = progress ? 0 : since_progress + 1;
    return since_progress >= kWindow && gnorm <= floor;
  }
};

// The Newton solve; the pattern's analysis is `shared` when given (the
// caller checked that `edges` have its pattern), else built at the first
// iteration that needs it. Its steps are the helpers above; the state that
// runs through an iteration (shift, chord steps, the last full step) is
// HarmonicNewton's.
HyperbolicHarmonicResult newton_solve(int n, const std::vector<WeightedEdge>& edges, const std::vector<Mobius>& generators,
                                      std::vector<Complex> z0, const HyperbolicHarmonicOptions& options,
                                      const HessianAnalysis* shared, const FaceAtlas* atlas = nullptr,
                                      std::vector<int> face0 = {}) {
  check_newton_input(n, edges, z0, options);
  if (!options.boundary_slide.slides.empty()) {
    if (atlas) throw InputError("hyperbolic_harmonic_map_in_face_charts: boundary_slide is not supported in per-face charts");
    // Sliding vertices start on their geodesics: the orthogonal projection
    // onto G(diameter), a straight perpendicular in the Klein model.
    for (int i = 0; i < n; ++i) {
      if (!options.boundary_slide.slides[i]) continue;
      const Mobius& G = options.boundary_slide.geodesic[i];
      const Complex x = G.inverse().apply(z0[i]);
      const double k = (2.0 * x / (1.0 + std::norm(x))).real();
      z0[i] = G.apply(Complex(k / (1.0 + std::sqrt(std::max(1.0 - k * k, 0.0))), 0.0));
    }
  }
  HarmonicNewton run(n, edges, generators, z0, options, shared, atlas, std::move(face0));
  HyperbolicHarmonicResult& r = run.r;
  RoundoffPlateau plateau;
  for (int it = 0; it < options.max_iterations; ++it) {
    const double gnorm = run.newton_system(it);
    if (gnorm <= options.tolerance * std::max(run.max_w, 1e-300)) {
      r.converged = true;
      r.iterations = it;
      break;
    }
    if (plateau.reached(run.E, gnorm, 1e4 * options.tolerance * std::max(run.max_w, 1e-300))) {
      r.converged = true;
      r.iterations = it;
      break;
    }
    bool chord = false;
    const Eigen::VectorXd step = run.direction(gnorm, &chord);
    const HarmonicNewton::Outcome outcome = run.take_step(it, step, gnorm, chord);
    if (outcome == HarmonicNewton::Outcome::kStop) break;
    if (outcome == HarmonicNewton::Outcome::kRetry) continue;
    run.recentre_charts();
  }
  run.finish();
  return std::move(run.r);
}

}  // namespace

HyperbolicHarmonicResult hyperbolic_harmonic_map(int n, const std::vector<WeightedEdge>& edges,
                                                 const std::vector<Mobius>& generators, std::vector<Complex> z0,
                                                 const HyperbolicHarmonicOptions& options) {
  return newton_solve(n, edges, generators, std::move(z0), options, nullptr);
}

HyperbolicHarmonicResult hyperbolic_harmonic_map_in_face_charts(int n, const std::vector<WeightedEdge>& edges,
                                                                const FaceAtlas& atlas, std::vector<int> face0,
                                                                std::vector<Complex> w0,
                                                                const HyperbolicHarmonicOptions& options) {
  if (!options.relator.empty() || options.reduce_point)
    throw InputError("hyperbolic_harmonic_map_in_face_charts: per-face charts use no relator and no reduce_point");
  if (static_cast<int>(face0.size()) != n)
    throw InputError("hyperbolic_harmonic_map_in_face_charts: one start face per vertex needed");
  for (int i = 0; i < n; ++i)
    if (face0[i] < 0 || face0[i] >= atlas.num_faces())
      throw InputError("hyperbolic_harmonic_map_in_face_charts: start face of vertex " + std::to_string(i) +
                       " is not a face of the atlas");
  return newton_solve(n, edges, {}, std::move(w0), options, nullptr, &atlas, std::move(face0));
}

HyperbolicHarmonicSolver::HyperbolicHarmonicSolver(int num_vertices, const std::vector<WeightedEdge>& edges) {
  for (const auto& ed : edges)
    if (ed.i < 0 || ed.i >= num_vertices || ed.j < 0 || ed.j >= num_vertices)
      throw InputError("HyperbolicHarmonicSolver: an edge has an endpoint out of range");
  analysis_ = std::make_shared<const HessianAnalysis>(num_vertices, edges);
}

HyperbolicHarmonicSolver::~HyperbolicHarmonicSolver() = default;

bool HyperbolicHarmonicSolver::fits(int num_vertices, const std::vector<WeightedEdge>& edges) const {
  return analysis_->matches(num_vertices, edges);
}

HyperbolicHarmonicResult HyperbolicHarmonicSolver::solve(const std::vector<WeightedEdge>& edges,
                                                         const std::vector<Mobius>& generators, std::vector<Complex> z0,
                                                         const HyperbolicHarmonicOptions& options) const {
  const int n = static_cast<int>(z0.size());
  if (!fits(n, edges))
    throw InputError("HyperbolicHarmonicSolver::solve: the edges (endpoints, positive weights) or the vertex count "
                     "differ from those the solver was built for");
  return newton_solve(n, edges, generators, std::move(z0), options, analysis_.get());
}

}  // namespace surfmap
