// Discrete Ricci flow (docs/method.md §2.4). See ricci_flow.h.
//
// Everything is written as "lengths as functions of u" (per scheme) composed
// with "angles as functions of lengths" (per background), so that one
// chain rule gives the Jacobian dK/du for all four combinations:
//   dθ_i/dl_i = l_i / (2A)                         (Euclidean, A = area)
//             = sinh l_i / (sinh l_j sinh l_k sin θ_i)   (hyperbolic)
//   dθ_i/dl_j = −dθ_i/dl_i · cos θ_k               (both; k the third corner)
// (differentiate the law of cosines). K_i = full_i − Σθ_i, so dK/du = −Σ dθ/du;
// for vertex scaling this is the Hessian of the vertex-scaling flow's
// convex energy (Euclidean: the cotangent Laplacian / 2).
#include "surfmap/uniformize/ricci_flow.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <future>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string>

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "../cholmod_vector_solve.h"
#include "../seconds_since.h"
#include "ricci_core.h"
#include "surfmap/error.h"
#include "surfmap/work_counters.h"
#include "surfmap/geometry/mollify.h"

namespace surfmap {
namespace detail {
namespace {


/// Edges / faces from which an evaluation with RicciFlowOptions::threads > 1
/// is split over two threads (below, a thread costs more than it saves).
constexpr int kSplitEvaluation = 20000;

/// part(half, begin, end) over [0, n): with threads > 1 and n >=
/// kSplitEvaluation in two halves, part(0, 0, n / 2) here and
/// part(1, n / 2, n) on another thread; else part(0, 0, n) alone. Each part
/// must write only its own slots, so the numbers are the same either way.
template <class Part>
void in_two_halves(int n, int threads, const Part& part) {
  if (threads > 1 && n >= kSplitEvaluation) {
    const int mid = n / 2;
    auto second = std::async(std::launch::async, [&] { part(1, mid, n); });
    part(0, 0, mid);
    second.get();
  } else {
    part(0, 0, n);
  }
}

/// Lengths of the metric at u and their derivatives dl_e/du at both endpoints.
class SchemeMetric {
 public:
  SchemeMetric(const RicciDomain& dom, const Eigen::VectorXd& l0, Background bg, RicciScheme scheme)
      : dom_(dom), bg_(bg), scheme_(scheme), l0_(l0) {
    const int ne = static_cast<int>(dom.EV.rows()), nv = dom.num_vertices;
    if (scheme == RicciScheme::InversiveDistance) {
      // Initial metric in the background geometry.
      Eigen::VectorXd lb = l0;
      if (bg == Background::Hyperbolic)
        for (int e = 0; e < ne; ++e) lb[e] = 2.0 * std::asinh(l0[e] / 2.0);
      r0_ = Eigen::VectorXd::Constant(nv, std::numeric_limits<double>::infinity());
      for (int e = 0; e < ne; ++e)
        for (int k = 0; k < 2; ++k) r0_[dom.EV(e, k)] = std::min(r0_[dom.EV(e, k)], lb[e] / 3.0);
      inv_.resize(ne);
      for (int e = 0; e < ne; ++e) {
        const double ri = r0_[dom.EV(e, 0)], rj = r0_[dom.EV(e, 1)];
        if (bg == Background::Euclidean)
          inv_[e] = (lb[e] * lb[e] - ri * ri - rj * rj) / (2.0 * ri * rj);
        else
          inv_[e] = (std::cosh(lb[e]) - std::cosh(ri) * std::cosh(rj)) /
                    (std::sinh(ri) * std::sinh(rj));
      }
      if (bg == Background::Hyperbolic) {
        tanh_half_r0_.resize(nv);
        for (int v = 0; v < nv; ++v) tanh_half_r0_[v] = std::tanh(r0_[v] / 2.0);
      }
    }
  }

  /// Fills l (#E) and dldu (#E x 2: d l_e / d u_{EV(e,0)}, d l_e / d u_{EV(e,1)}).
  /// Returns the first edge whose length is not a finite positive number, or -1.
  /// threads > 1: the edges in two halves, the second on another thread
  /// (each edge's length is its own: the same numbers).
  int lengths(const Eigen::VectorXd& u, Eigen::VectorXd& l, Eigen::MatrixX2d* dldu, int threads = 1) const {
    const int ne = static_cast<int>(dom_.EV.rows());
    l.resize(ne);
    if (dldu) dldu->resize(ne, 2);
    Eigen::VectorXd r;
    if (scheme_ == RicciScheme::InversiveDistance) {
      r.resize(dom_.num_vertices);
      for (int v = 0; v < dom_.num_vertices; ++v) {
        if (bg_ == Background::Euclidean) {
          r[v] = r0_[v] * std::exp(u[v]);
        } else {
          const double t = tanh_half_r0_[v] * std::exp(u[v]);
          r[v] = t < 1.0 ? 2.0 * std::atanh(t) : std::numeric_limits<double>::infinity();
        }
      }
    }
    int bad[2] = {-1, -1};
    in_two_halves(ne, threads,
                  [&](int half, int begin, int end) { bad[half] = edge_range(u, r, begin, end, l, dldu); });
    return bad[0] >= 0 ? bad[0] : bad[1];
  }

 private:
  /// Lengths of edges [begin, end) (l, dldu sized); the first bad one or -1.
  int edge_range(const Eigen::VectorXd& u, const Eigen::VectorXd& r, int begin, int end, Eigen::VectorXd& l,
                 Eigen::MatrixX2d* dldu) const {
    int bad = -1;
    for (int e = begin; e < end; ++e) {
      const int i = dom_.EV(e, 0), j = dom_.EV(e, 1);
      double le, di, dj;
      if (scheme_ == RicciScheme::VertexScaling) {
        const double s = std::exp(0.5 * (u[i] + u[j]));
        if (bg_ == Background::Euclidean) {
          le = s * l0_[e];
          di = dj = 0.5 * le;
        } else {
          // sinh(l/2) = e^{(ui+uj)/2} l0/2  =>  dl/du_i = tanh(l/2) =
          // sinh(l/2) / cosh(l/2), without a tanh (ch = sh once sh² would
          // overflow: l > 700).
          const double sh = 0.5 * s * l0_[e], ch = sh < 1e150 ? std::sqrt(1.0 + sh * sh) : sh;
          le = 2.0 * std::asinh(sh);
          di = dj = sh / ch;
        }
      } else {
        const double ri = r[i], rj = r[j], I = inv_[e];
        if (bg_ == Background::Euclidean) {
          le = std::sqrt(std::max(0.0, ri * ri + rj * rj + 2.0 * ri * rj * I));
          di = (ri * ri + ri * rj * I) / le;
          dj = (rj * rj + ri * rj * I) / le;
        } else {
          const double ci = std::cosh(ri), cj = std::cosh(rj), si = std::sinh(ri),
                       sj = std::sinh(rj);
          const double ch = ci * cj + I * si * sj;
          le = ch > 1.0 ? std::acosh(ch) : 0.0;
          const double sl = std::sinh(le);
          // dr/du = sinh r for tanh(r/2) = c e^u.
          di = si * (si * cj + I * ci * sj) / sl;
          dj = sj * (sj * ci + I * cj * si) / sl;
        }
      }
      l[e] = le;
      if (dldu) {
        (*dldu)(e, 0) = di;
        (*dldu)(e, 1) = dj;
      }
      if (!(std::isfinite(le) && le > 0.0 && std::isfinite(di) && std::isfinite(dj)) && bad < 0)
        bad = e;
    }
    return bad;
  }

  const RicciDomain& dom_;
  Background bg_;
  RicciScheme scheme_;
  const Eigen::VectorXd& l0_;  // Penner coordinates when flipping (updated in place)
  Eigen::VectorXd r0_, inv_, tanh_half_r0_;
};

/// Half-perimeter above which the hyperbolic half-angle formulas use
/// logarithms: sinh(s) sinh(s_k) overflows near s = 355, and the quotients
/// then gave NaN angles (extreme cone targets, e.g. every vertex a cone of
/// angle 0.1, whose Newton steps pass through triangles of sides ~10^3).
constexpr double kLongTriangle = 200.0;

/// Largest change of any u_i in one hyperbolic Newton step (newton_step).
constexpr double kMaxHyperbolicStep = 10.0;

/// log sinh(a) for a > 0 without overflow, accurate also for small a.
double log_sinh(double a) { return a - std::log(2.0) + std::log(-std::expm1(-2.0 * a)); }

/// The hyperbolic branch of triangle_angles for long triangles (s >
/// kLongTriangle): the same half-angle formulas with every sinh product
/// taken through its logarithm; tan²(θ_k/2) = sinh s_{k+1} sinh s_{k+2} /
/// (sinh s sinh s_k), and dθ_i/dl_i = sinh l_i / (2 sqrt(sinh s Π sinh s_k)).
/// s_k: the three slacks (all > 0).
void hyperbolic_angles_of_long_triangle(const double l[3], double s, const double sk[3], double theta[3],
                                        double D[3][3]) {
  const double log_fs = log_sinh(s);
  double log_f[3];
  for (int k = 0; k < 3; ++k) log_f[k] = log_sinh(sk[k]);
  double cos_theta[3];
  for (int k = 0; k < 3; ++k) {
    const double log_x = log_fs + log_f[k], log_y = log_f[(k + 1) % 3] + log_f[(k + 2) % 3];
    const double top = std::max(log_x, log_y);
    const double x = std::exp(log_x - top), y = std::exp(log_y - top);
    theta[k] = 2.0 * std::atan2(std::sqrt(y), std::sqrt(x));
    cos_theta[k] = (x - y) / (x + y);
  }
  const double log_twice = std::log(2.0) + 0.5 * (log_fs + log_f[0] + log_f[1] + log_f[2]);
  for (int i = 0; i < 3; ++i) {
    const double dii = std::exp(log_sinh(l[i]) - log_twice);
    D[i][i] = dii;
    for (int m = 0; m < 3; ++m)
      if (m != i) D[i][m] = -dii * cos_theta[3 - i - m];
  }
}

/// Angles of a triangle with sides l[k] opposite corner k, and D(i,m) =
/// dθ_i/dl_m. Returns false (angles π,0,0 opposite the too-long side, D = 0)
/// when the triangle inequality fails: the convex energy extended past
/// degenerate triangles.
bool triangle_angles(const double l[3], Background bg, double theta[3], double D[3][3],
                     double* slack) {
  const double s = 0.5 * (l[0] + l[1] + l[2]);
  double sk[3];
  for (int k = 0; k < 3; ++k) sk[k] = 0.5 * (l[(k + 1) % 3] + l[(k + 2) % 3] - l[k]);
  int worst = 0;
  for (int k = 1; k < 3; ++k)
    if (sk[k] < sk[worst]) worst = k;
  if (slack) *slack = sk[worst] / s;
  if (!(sk[worst] > 0.0)) {
    for (int k = 0; k < 3; ++k) {
      theta[k] = (k == worst) ? kPi : 0.0;
      for (int m = 0; m < 3; ++m) D[k][m] = 0.0;
    }
    return false;
  }
  if (bg == Background::Hyperbolic && s > kLongTriangle) {
    hyperbolic_angles_of_long_triangle(l, s, sk, theta, D);
    return true;
  }
  double f[3], fs, twice;  // "half-perimeter" quantities of the half-angle formulas
  if (bg == Background::Euclidean) {
    for (int k = 0; k < 3; ++k) f[k] = sk[k];
    fs = s;
    twice = 2.0 * std::sqrt(s * sk[0] * sk[1] * sk[2]);  // 2A = l_j l_k sin θ_i
  } else {
    for (int k = 0; k < 3; ++k) f[k] = std::sinh(sk[k]);
    fs = std::sinh(s);
    twice = 2.0 * std::sqrt(fs * f[0] * f[1] * f[2]);  // = sinh l_j sinh l_k sin θ_i
  }
  // θ_k = 2 atan2(√y, √x) with x = fs f_k, y = f_{k+1} f_{k+2}, so
  // cos θ_k = (x − y) / (x + y) without a cosine (issue 19: the Jacobian
  // is assembled at every Newton step; 6 cosines per face were a fifth of it).
  double cos_theta[3];
  for (int k = 0; k < 3; ++k) {
    const double x = fs * f[k], y = f[(k + 1) % 3] * f[(k + 2) % 3];
    theta[k] = 2.0 * std::atan2(std::sqrt(y), std::sqrt(x));
    cos_theta[k] = (x - y) / (x + y);
  }
  for (int i = 0; i < 3; ++i) {
    const double dii = (bg == Background::Euclidean ? l[i] : std::sinh(l[i])) / twice;
    D[i][i] = dii;
    for (int m = 0; m < 3; ++m)
      if (m != i) D[i][m] = -dii * cos_theta[3 - i - m];
  }
  return true;
}


/// Extended angles (see triangle_angles) of face f for lengths L.
template <class LengthOf>
void face_angles(const RicciDomain& d, int f, Background bg, const LengthOf& L, double th[3]) {
  double l[3], D[3][3];
  for (int q = 0; q < 3; ++q) l[q] = L(d.FE(f, q));
  triangle_angles(l, bg, th, D, nullptr);
}

/// Mutable intrinsic triangulation for the Delaunay-flip variant of the
/// vertex-scaling flow (Euclidean and hyperbolic; docs/uniformization.md):
/// the domain's
/// faces/edges change by flips; `pen` holds the base lengths l⁰ of the
/// current edges, so that l = e^{(u_i+u_j)/2} l⁰ (Euclidean) or
/// sinh(l/2) = e^{(u_i+u_j)/2} l⁰/2 (hyperbolic). Both Ptolemy relations —
/// Euclidean l, hyperbolic sinh(l/2) for a cyclic quadrilateral — then read
/// l⁰_new l⁰_e = l⁰_a l⁰_c + l⁰_b l⁰_d, which commutes with vertex scaling.
struct FlipContext {
  RicciDomain* dom = nullptr;
  RowMatrixX2i EF;  // faces on both sides of every edge, -1 on the boundary
  Eigen::VectorXd* pen = nullptr;
  long long flips = 0;
  long long version = 0;
  long long max_flips = 0;
  /// Flips allowed in one make_delaunay pass (0: no limit but max_flips).
  /// Set for the Newton line search's trial points (RicciRun::line_search),
  /// which roll a pass that hits it back (pass_exhausted).
  long long pass_limit = 0;
  bool pass_exhausted = false;
  Background bg = Background::Euclidean;
  std::vector<EdgeFlip> history;  // every flip made, in order (RicciFlowResult::flip_history)

  void init(RicciDomain& d, Eigen::VectorXd& p, Background background) {
    bg = background;
    dom = &d;
    pen = &p;
    EF = RowMatrixX2i::Constant(d.EV.rows(), 2, -1);
    for (int f = 0; f < d.F.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int e = d.FE(f, k);
        EF(e, EF(e, 0) < 0 ? 0 : 1) = f;
      }
    // The whole run's budget (every flip is kept in `history`, 72 bytes
    // each): the flips of real meshes stay near #E in all (genus-3 CAD
    // plate: 2,010 for 2,364 edges), and the old 1000 #E per pass let a
    // cycling pass on the artery's double grow past 10 GB (issue 13).
    max_flips = 50LL * (d.EV.rows() + 10);
  }

  /// Flips towards the Delaunay triangulation of the metric at u (u == null:
  /// the input metric, flipped exactly with Euclidean flips; otherwise
  /// Ptolemy flips of the Penner coordinates). Returns false when the flip
  /// budget ran out.
  bool make_delaunay(const Eigen::VectorXd* u) {
    RicciDomain& d = *dom;
    Eigen::VectorXd& P = *pen;
    auto pen = [&](int e) { return u ? std::exp(0.5 * ((*u)[d.EV(e, 0)] + (*u)[d.EV(e, 1)])) * P[e] : P[e]; };
    auto len = [&](int e) {
      const double x = pen(e);
      return bg == Background::Euclidean ? x : 2.0 * std::asinh(0.5 * x);
    };
    const int ne = static_cast<int>(d.EV.rows());
    const long long flips_at_start = flips;
    pass_exhausted = false;
    // The Delaunay test's conformal factors, once per pass (issue 19: five
    // exp per tested edge were 0.21 G instructions of the 50k target's flow):
    // w_v = e^{(u_v − max u)/2}, so a Penner coordinate at u relative to the
    // largest factor is w_i w_j l⁰. Empty when u is not finite everywhere.
    std::vector<double> w;
    if (u && u->size() > 0 && u->allFinite()) {
      const double top = u->maxCoeff();
      w.resize(u->size());
      for (int v = 0; v < u->size(); ++v) w[v] = std::exp(0.5 * ((*u)[v] - top));
    }
    std::vector<int> stack(ne);
    std::vector<char> queued(ne, 1);
    for (int e = 0; e < ne; ++e) stack[e] = ne - 1 - e;
    while (!stack.empty()) {
      const int e = stack.back();
      stack.pop_back();
      queued[e] = 0;
      const int f0 = EF(e, 0), f1 = EF(e, 1);
      if (f0 < 0 || f1 < 0 || f0 == f1) continue;
      int a0 = 0, a1 = 0;
      while (d.FE(f0, a0) != e) ++a0;
      while (d.FE(f1, a1) != e) ++a1;
      // Delaunay test on the Penner coordinates x (Euclidean: the lengths;
      // hyperbolic: 2 sinh(l/2)) through the horocyclic arcs x_opp/(x_a x_b)
      // of the corners (the decorated-triangle criterion): e is Delaunay
      // when the arcs at the two opposite corners sum to at most the arcs at
      // its ends. For triangles this equals the circumcircle condition
      // (Euclidean α + β <= π; hyperbolic: opposite angles <= angles at the
      // ends; checked numerically on random quadrilaterals of both kinds),
      // and it stays right where the coordinates violate the triangle
      // inequality, where an angle test with extended angles (π, 0, 0) ties
      // and leaves degenerate pairs unflipped. A Delaunay triangulation in
      // Penner coordinates satisfies the triangle inequality.
      //
      // Both sides are homogeneous of degree −1 in x, so the coordinates are
      // taken relative to the quad's largest conformal factor: a trial u of
      // a Newton step may be large enough for e^{u/2} to overflow, and the
      // NaN tests of infinite coordinates used to flip two edges of a quad
      // back and forth until the history exhausted memory (issue 13, the
      // artery's double). A test that is not a number flips nothing.
      // The factors w (above) serve unless one of the quad's is below 1e-100
      // (a quad far below the largest factor: its own shift then).
      {
        const int quad[4] = {d.F(f0, 0), d.F(f0, 1), d.F(f0, 2), d.F(f1, a1)};
        bool by_factors = !w.empty();
        for (int v : quad) by_factors = by_factors && w[v] > 1e-100;
        double shift = 0.0;
        if (u && !by_factors) {
          shift = -std::numeric_limits<double>::infinity();
          for (int v : quad) shift = std::max(shift, (*u)[v]);
        }
        auto x = [&](int edge) {
          if (by_factors) return w[d.EV(edge, 0)] * w[d.EV(edge, 1)] * P[edge];
          return u ? std::exp(0.5 * ((*u)[d.EV(edge, 0)] + (*u)[d.EV(edge, 1)]) - shift) * P[edge] : P[edge];
        };
        const double xe = x(e), xks = x(d.FE(f0, (a0 + 2) % 3)), xkt = x(d.FE(f0, (a0 + 1) % 3)),
                     xms = x(d.FE(f1, (a1 + 1) % 3)), xmt = x(d.FE(f1, (a1 + 2) % 3));
        const double opposite = xe / (xks * xkt) + xe / (xms * xmt);
        const double at_ends = (xkt / xks + xmt / xms + xks / xkt + xms / xmt) / xe;
        if (!(opposite > at_ends * (1.0 + 1e-12))) continue;
      }
      // Quad v_k, s, v_m, t (counter-clockwise); e = s–t becomes v_k–v_m.
      const int vk = d.F(f0, a0), s = d.F(f0, (a0 + 1) % 3), t = d.F(f0, (a0 + 2) % 3);
      const int vm = d.F(f1, a1);
      if (d.F(f1, (a1 + 1) % 3) != t || d.F(f1, (a1 + 2) % 3) != s) continue;  // not a plain quad
      const int e_tk = d.FE(f0, (a0 + 1) % 3), e_ks = d.FE(f0, (a0 + 2) % 3);
      const int e_sm = d.FE(f1, (a1 + 1) % 3), e_mt = d.FE(f1, (a1 + 2) % 3);
      if (e_tk == e || e_ks == e || e_sm == e || e_mt == e) continue;
      double lnew;
      if (!u) {
        // Exact (metric-preserving) flip: unfold the quad at s.
        double th0[3], th1[3];
        face_angles(d, f0, bg, len, th0);
        face_angles(d, f1, bg, len, th1);
        const double th = th0[(a0 + 1) % 3] + th1[(a1 + 2) % 3];
        const double x = len(e_ks), y = len(e_sm);
        if (bg == Background::Euclidean) {
          lnew = std::sqrt(std::max(0.0, x * x + y * y - 2.0 * x * y * std::cos(th)));
        } else {
          const double c = std::cosh(x) * std::cosh(y) - std::sinh(x) * std::sinh(y) * std::cos(th);
          lnew = 2.0 * std::sinh(0.5 * std::acosh(std::max(1.0, c)));  // back to l⁰
        }
      } else {
        // Ptolemy: commutes with vertex scaling, so it acts on the base lengths.
        lnew = (P[e_tk] * P[e_sm] + P[e_ks] * P[e_mt]) / P[e];
      }
      if (!(lnew > 0.0) || !std::isfinite(lnew)) continue;
      EdgeFlip rec;
      rec.face0 = f0, rec.face1 = f1, rec.corner0 = a0, rec.corner1 = a1;
      rec.base_lengths = {P[e_ks], P[e_sm], P[e_mt], P[e_tk], P[e], lnew};
      rec.exact = !u;
      history.push_back(rec);
      P[e] = lnew;
      d.F.row(f0) << vk, s, vm;
      d.FE.row(f0) << e_sm, e, e_ks;
      d.F.row(f1) << vm, t, vk;
      d.FE.row(f1) << e_tk, e, e_mt;
      d.EV(e, 0) = std::min(vk, vm);
      d.EV(e, 1) = std::max(vk, vm);
      refresh_edge_faces(f0, f1, {e, e_tk, e_ks, e_sm, e_mt});
      ++flips;
      ++version;
      if (pass_limit > 0 && flips - flips_at_start > pass_limit) {
        pass_exhausted = true;
        return false;
      }
      if (flips > max_flips) return false;
      for (int x : {e_tk, e_ks, e_sm, e_mt})
        if (!queued[x]) {
          queued[x] = 1;
          stack.push_back(x);
        }
    }
    return true;
  }

  /// Faces of the quad's edges `quad` (the flipped edge and its four
  /// sides), recomputed from the two faces f0, f1 as they are now (after a
  /// flip or its undoing): after earlier flips the triangulation need not be
  /// simplicial (a vertex may be both ends of the quad, an edge may be two of
  /// its sides), and an in-place swap of face ids gets those cases wrong.
  void refresh_edge_faces(int f0, int f1, std::initializer_list<int> quad) {
    const RicciDomain& d = *dom;
    for (int x : quad)
      for (int q = 0; q < 2; ++q)
        if (EF(x, q) == f0 || EF(x, q) == f1) EF(x, q) = -2;
    for (int f : {f0, f1})
      for (int q = 0; q < 3; ++q) {
        const int x = d.FE(f, q);
        EF(x, EF(x, 0) == -2 ? 0 : 1) = f;
      }
  }

  /// Undoes the newest flips until `keep` are left (the inverse of the flip
  /// above, read off its history record): the triangulation, its base
  /// lengths and edge-face table return to their state after flip keep − 1.
  void roll_back(long long keep) {
    RicciDomain& d = *dom;
    Eigen::VectorXd& P = *pen;
    while (static_cast<long long>(history.size()) > keep) {
      const EdgeFlip rec = history.back();
      history.pop_back();
      const int f0 = rec.face0, f1 = rec.face1, a0 = rec.corner0, a1 = rec.corner1;
      // After the flip: F(f0) = (k, s, m), FE(f0) = (e_sm, e, e_ks);
      // F(f1) = (m, t, k), FE(f1) = (e_tk, e, e_mt).
      const int vk = d.F(f0, 0), s = d.F(f0, 1), vm = d.F(f0, 2), t = d.F(f1, 1);
      const int e_sm = d.FE(f0, 0), e = d.FE(f0, 1), e_ks = d.FE(f0, 2), e_tk = d.FE(f1, 0), e_mt = d.FE(f1, 2);
      d.F(f0, a0) = vk, d.F(f0, (a0 + 1) % 3) = s, d.F(f0, (a0 + 2) % 3) = t;
      d.FE(f0, a0) = e, d.FE(f0, (a0 + 1) % 3) = e_tk, d.FE(f0, (a0 + 2) % 3) = e_ks;
      d.F(f1, a1) = vm, d.F(f1, (a1 + 1) % 3) = t, d.F(f1, (a1 + 2) % 3) = s;
      d.FE(f1, a1) = e, d.FE(f1, (a1 + 1) % 3) = e_sm, d.FE(f1, (a1 + 2) % 3) = e_mt;
      d.EV(e, 0) = std::min(s, t);
      d.EV(e, 1) = std::max(s, t);
      P[e] = rec.base_lengths[4];
      refresh_edge_faces(f0, f1, {e, e_tk, e_ks, e_sm, e_mt});
      --flips;
      ++version;
    }
  }
};

struct Evaluation {
  Eigen::VectorXd l, K;
  int bad_edge = -1;
  /// The flips of this evaluation ran past FlipContext::pass_limit (a line
  /// search trial): nothing else was evaluated.
  bool flips_exhausted = false;
  int first_degenerate = -1;
  int degenerate = 0;
  double min_slack = 1.0;
  int min_slack_face = -1;
  std::vector<Eigen::Triplet<double>> triplets;
  /// Scratch: the angles of face f's corners at 3f + k.
  std::vector<double> angles;
  /// FlipContext::version of the triangulation evaluated on (0 without flips).
  long long version = 0;
};

/// The per-face part of an evaluation over faces [begin, end): each face's
/// angles into angles[3f + k] and its 9 Jacobian entries into
/// triplets[9f ..] (sized by the caller), the degeneracy counts into `part`.
struct FaceScan {
  int degenerate = 0;
  int first_degenerate = -1;
  double min_slack = 1.0;
  int min_slack_face = -1;
};

void scan_faces(const RicciDomain& dom, Background bg, const Eigen::VectorXd& l_all, const Eigen::MatrixX2d* dldu,
                int begin, int end, double* angles, Eigen::Triplet<double>* triplets, FaceScan& part) {
  for (int f = begin; f < end; ++f) {
    double l[3], th[3], D[3][3], slack;
    for (int k = 0; k < 3; ++k) l[k] = l_all[dom.FE(f, k)];
    if (!triangle_angles(l, bg, th, D, &slack)) {
      ++part.degenerate;
      if (part.first_degenerate < 0) part.first_degenerate = f;
    }
    if (slack < part.min_slack) {
      part.min_slack = slack;
      part.min_slack_face = f;
    }
    for (int k = 0; k < 3; ++k) angles[3 * static_cast<size_t>(f) + k] = th[k];
    if (!dldu) continue;
    // dl_m/du at the corners: side m joins corners m+1 and m+2.
    double J[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};  // J(m, corner w) = dl_m/du_w
    for (int m = 0; m < 3; ++m) {
      const int e = dom.FE(f, m);
      for (int q = 1; q <= 2; ++q) {
        const int w = (m + q) % 3;
        J[m][w] = dom.EV(e, 0) == dom.F(f, w) ? (*dldu)(e, 0) : (*dldu)(e, 1);
      }
    }
    Eigen::Triplet<double>* out = triplets + 9 * static_cast<size_t>(f);
    for (int i = 0; i < 3; ++i)
      for (int w = 0; w < 3; ++w) {
        double d = 0.0;
        for (int m = 0; m < 3; ++m) d += D[i][m] * J[m][w];
        *out++ = Eigen::Triplet<double>(dom.F(f, i), dom.F(f, w), -d);  // dK = −dθ
      }
  }
}

/// threads > 1 (RicciFlowOptions::threads): the lengths and the per-face
/// part in two halves, the second half on another thread. Every face writes
/// its own slots and the angle sums are then taken in face order, as with
/// one thread: the same bits either way.
void evaluate(const RicciDomain& dom, const SchemeMetric& metric, Background bg,
              const Eigen::VectorXd& u, bool jacobian, Evaluation& ev,
              FlipContext* flips = nullptr, int threads = 1) {
  // A pass that runs out of its flip budget is cycling: a clear error in
  // bounded memory (the flip history grows with every flip) instead of
  // carrying on with a non-Delaunay triangulation.
  ev.flips_exhausted = false;
  if (flips && !flips->make_delaunay(&u) && flips->pass_exhausted) {
    ev.flips_exhausted = true;
    return;
  }
  if (flips && flips->flips > flips->max_flips)
    throw SolveError("ricci_flow: the intrinsic Delaunay flips did not terminate (" +
                     std::to_string(flips->flips) + " flips, the budget of 50 per edge)");
  ev.version = flips ? flips->version : 0;
  Eigen::MatrixX2d dldu;
  ev.bad_edge = metric.lengths(u, ev.l, jacobian ? &dldu : nullptr, threads);
  ev.K = dom.full_angle;
  ev.degenerate = 0;
  ev.first_degenerate = -1;
  ev.min_slack = 1.0;
  ev.min_slack_face = -1;
  if (!jacobian) ev.triplets.clear();
  if (ev.bad_edge >= 0) {
    ev.triplets.clear();
    return;
  }
  const int nf = static_cast<int>(dom.F.rows());
  if (jacobian) ev.triplets.resize(9 * static_cast<size_t>(nf));
  ev.angles.resize(3 * static_cast<size_t>(nf));
  const Eigen::MatrixX2d* d = jacobian ? &dldu : nullptr;
  FaceScan parts[2];
  in_two_halves(nf, threads, [&](int half, int begin, int end) {
    scan_faces(dom, bg, ev.l, d, begin, end, ev.angles.data(), ev.triplets.data(), parts[half]);
  });
  // The halves combined as one pass in face order would have found them.
  for (const FaceScan& p : parts) {
    ev.degenerate += p.degenerate;
    if (ev.first_degenerate < 0) ev.first_degenerate = p.first_degenerate;
    if (p.min_slack < ev.min_slack) {
      ev.min_slack = p.min_slack;
      ev.min_slack_face = p.min_slack_face;
    }
  }
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) ev.K[dom.F(f, k)] -= ev.angles[3 * static_cast<size_t>(f) + k];
}

/// RicciFlowResult::floor_estimate: max over vertices of ε Σ_corners
/// (Σ l²)/(2A) (Euclidean; hyperbolic: the same with sinh l and the
/// hyperbolic "2A" of triangle_angles), the angle error caused by relative
/// length errors of ε.
double angle_sum_roundoff(const RicciDomain& dom, const Eigen::VectorXd& lengths, Background bg) {
  Eigen::VectorXd per_vertex = Eigen::VectorXd::Zero(dom.num_vertices);
  for (int f = 0; f < dom.F.rows(); ++f) {
    double l[3], th[3], D[3][3];
    for (int k = 0; k < 3; ++k) l[k] = lengths[dom.FE(f, k)];
    if (!triangle_angles(l, bg, th, D, nullptr)) continue;
    // D[i][i] = l_i / (2A): Σ_m D[m][m] l_m = (Σ l²)/(2A).
    double c = 0;
    for (int m = 0; m < 3; ++m) c += D[m][m] * l[m];
    for (int k = 0; k < 3; ++k) per_vertex[dom.F(f, k)] += c;
  }
  return std::numeric_limits<double>::epsilon() * (per_vertex.size() ? per_vertex.maxCoeff() : 0.0);
}

int argmax_abs(const Eigen::VectorXd& x) {
  int best = 0;
  for (int i = 1; i < x.size(); ++i)
    if (std::abs(x[i]) > std::abs(x[best])) best = i;
  return best;
}

}  // namespace

RicciDomain domain_from_connectivity(const Connectivity& conn) {
  RicciDomain d;
  d.num_vertices = conn.num_vertices();
  d.F = conn.faces();
  d.EV = conn.edge_vertices();
  d.FE.resize(conn.num_faces(), 3);
  for (int f = 0; f < conn.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) d.FE(f, k) = conn.edge(3 * f + (k + 1) % 3);
  d.full_angle = Eigen::VectorXd::Constant(d.num_vertices, 2.0 * kPi);
  return d;
}

RicciDomain domain_from_faces(int num_vertices, const RowMatrixX3i& F) {
  RicciDomain d;
  d.num_vertices = num_vertices;
  d.F = F;
  const int nf = static_cast<int>(F.rows());
  std::vector<std::pair<long long, int>> keys(3 * static_cast<size_t>(nf));
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, (k + 1) % 3), b = F(f, (k + 2) % 3);
      keys[3 * f + k] = {static_cast<long long>(std::min(a, b)) * num_vertices + std::max(a, b),
                         3 * f + k};
    }
  std::sort(keys.begin(), keys.end());
  d.FE.resize(nf, 3);
  std::vector<std::array<int, 2>> ev;
  d.full_angle = Eigen::VectorXd::Constant(num_vertices, 2.0 * kPi);
  for (size_t i = 0; i < keys.size();) {
    size_t j = i;
    while (j < keys.size() && keys[j].first == keys[i].first) ++j;
    if (j - i > 2) throw InputError("non-manifold edge in face " + std::to_string(keys[i].second / 3));
    const int e = static_cast<int>(ev.size());
    const long long key = keys[i].first;
    ev.push_back({static_cast<int>(key / num_vertices), static_cast<int>(key % num_vertices)});
    for (size_t q = i; q < j; ++q) d.FE(keys[q].second / 3, keys[q].second % 3) = e;
    if (j - i == 1) d.full_angle[ev.back()[0]] = d.full_angle[ev.back()[1]] = kPi;
    i = j;
  }
  d.EV.resize(static_cast<int>(ev.size()), 2);
  for (int e = 0; e < static_cast<int>(ev.size()); ++e) {
    d.EV(e, 0) = ev[e][0];
    d.EV(e, 1) = ev[e][1];
  }
  return d;
}

RicciLinearization ricci_linearize(const RicciDomain& dom, const Eigen::VectorXd& lengths,
                                   Background background, RicciScheme scheme,
                                   const Eigen::VectorXd& u) {
  SchemeMetric metric(dom, lengths, background, scheme);
  Evaluation ev;
  evaluate(dom, metric, background, u, true, ev);
  if (ev.bad_edge >= 0)
    throw SolveError("edge " + std::to_string(ev.bad_edge) + " has no valid length at this u");
  RicciLinearization out;
  out.curvature = ev.K;
  out.edge_lengths = ev.l;
  out.degenerate_faces = ev.degenerate;
  out.jacobian.resize(dom.num_vertices, dom.num_vertices);
  out.jacobian.setFromTriplets(ev.triplets.begin(), ev.triplets.end());
  return out;
}

namespace {

#ifndef SURFMAP_RICCI_SOLVER
// CHOLMOD picks AMD or METIS by fill; Eigen's AMD-only SimplicialLLT fills in
// badly beyond ~200k vertices (16 s vs 4 s per factorization at 250k).
// Supernodal: with an optimised BLAS (scripts/bootstrap.sh) its factorisation
// takes a third of the simplicial one's time (72848-vertex vase, one BLAS
// thread: 0.32 s against 0.9 s), for preconditioner solves ~30% slower.
#define SURFMAP_RICCI_SOLVER SupernodalFactorSimplicialSolves
#endif

/// Issue 19 (session 24): the supernodal factorisation (a third of the
/// simplicial one's time on large meshes), its solves from a simplicial copy
/// of the factor. CHOLMOD's supernodal solve makes two BLAS calls per
/// supernode, which on these Laplacians' many small supernodes cost more
/// than the arithmetic: the same factor's solves took 0.21 ms simplicial
/// against 0.36 ms supernodal at 6.9k vertices, 3.5 against 5.1 ms at 69k
/// (one BLAS thread), and the preconditioned CG steps solve with one factor
/// tens of times (41 solves for the 6.9k bench target's 6 Newton steps). The
/// copy costs one pass over the factor per factorisation; hyperbolic flows
/// on small meshes only (up to kSimplicialSolveVertices: the 55.9k bench target, whose flow
/// starts from a coarse copy's solution and solves little, held 34 MiB more
/// for it). The solves' sums run in another order than the supernodal ones:
/// the same step up to round-off.
constexpr Eigen::Index kSimplicialSolveVertices = 20000;
class SupernodalFactorSimplicialSolves
    : public Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> {
  using Base = Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower>;

 public:
  /// Off: the supernodal solves (flat flows). Chosen in session 24 because
  /// SurfaceMap.CrowdedFingerImagesKeepTheirOrientation certified with the
  /// supernodal solves' round-off and not with the simplicial one's; session
  /// 25 found that a draw of round-off (the supernodal solves fail it too
  /// with the target scaled by 1 + 1e-15, docs/history/code_map.md "Session 25") and
  /// moved the test off the double-resolution edge. Flat flows could take
  /// the simplicial solves now; not switched, since that moves every genus-1
  /// and annulus result by round-off and wants their suites rerun.
  bool simplicial_solves = true;
  SupernodalFactorSimplicialSolves() = default;
  SupernodalFactorSimplicialSolves(const SupernodalFactorSimplicialSolves&) = delete;
  SupernodalFactorSimplicialSolves& operator=(const SupernodalFactorSimplicialSolves&) = delete;
  ~SupernodalFactorSimplicialSolves() { free_copy(); }

  void analyzePattern(const Eigen::SparseMatrix<double>& A) {
    free_copy();
    Base::analyzePattern(A);
  }
  void factorize(const Eigen::SparseMatrix<double>& A) {
    free_copy();
    Base::factorize(A);
    if (!simplicial_solves || Base::info() != Eigen::Success || !m_cholmodFactor || A.rows() > kSimplicialSolveVertices)
      return;
    copy_ = simplicial_copy(m_cholmodFactor, &cholmod());
  }
  Eigen::VectorXd solve(const Eigen::VectorXd& b) {
    if (!copy_) return Base::solve(b);
    return cholmod_vector_solve(copy_, b, &cholmod());
  }

 private:
  void free_copy() {
    if (copy_) cholmod_free_factor(&copy_, &cholmod());
    copy_ = nullptr;
  }
  cholmod_factor* copy_ = nullptr;
};

/// Checks ricci_solve's inputs (one InputError naming the edge, face or
/// count at fault): #E finite positive lengths satisfying the triangle
/// inequality, a #V target (empty: zeros) and a #V fixed mask, and
/// Gauss–Bonnet for the target unless a fixed vertex absorbs the balance.
/// Returns the #V target; *has_fixed tells whether any vertex is fixed.
Eigen::VectorXd checked_target(const RicciDomain& dom, const Eigen::VectorXd& lengths,
                               Background background, const Eigen::VectorXd& target_in,
                               const std::vector<char>* fixed_in, bool* has_fixed_out) {
  const int nv = dom.num_vertices, ne = static_cast<int>(dom.EV.rows()),
            nf = static_cast<int>(dom.F.rows());
  if (lengths.size() != ne)
    throw InputError("ricci_flow: expected " + std::to_string(ne) + " edge lengths, got " +
                     std::to_string(lengths.size()));
  for (int e = 0; e < ne; ++e)
    if (!(std::isfinite(lengths[e]) && lengths[e] > 0.0))
      throw InputError("ricci_flow: edge " + std::to_string(e) + " (" +
                       std::to_string(dom.EV(e, 0)) + ", " + std::to_string(dom.EV(e, 1)) +
                       ") has length " + fmt(lengths[e]));
  for (int f = 0; f < nf; ++f) {
    double l[3];
    for (int k = 0; k < 3; ++k) l[k] = lengths[dom.FE(f, k)];
    for (int k = 0; k < 3; ++k)
      if (!(l[k] < l[(k + 1) % 3] + l[(k + 2) % 3]))
        throw InputError("ricci_flow: face " + std::to_string(f) +
                         " violates the triangle inequality in the input lengths (zero area)");
  }
  Eigen::VectorXd target = target_in.size() == 0 ? Eigen::VectorXd::Zero(nv) : target_in;
  if (target.size() != nv)
    throw InputError("ricci_flow: expected " + std::to_string(nv) + " target curvatures, got " +
                     std::to_string(target.size()));
  if (fixed_in && static_cast<int>(fixed_in->size()) != nv)
    throw InputError("ricci_flow: fixed mask must have #V entries");
  // Gauss–Bonnet: Σ K_i = Σ full_i − π #F (+ area in the hyperbolic case).
  // (computed as an integer multiple of π: summing 2π over 10⁵ vertices in
  // floating point would itself be off by more than a tight tolerance)
  long long gb_pi = -static_cast<long long>(nf);
  for (int v = 0; v < nv; ++v) gb_pi += std::llround(dom.full_angle[v] / kPi);
  const double gb = kPi * static_cast<double>(gb_pi);
  const bool has_fixed =
      fixed_in && std::find(fixed_in->begin(), fixed_in->end(), 1) != fixed_in->end();
  if (has_fixed) {
    // Dirichlet problem: the fixed vertices absorb the Gauss–Bonnet balance.
  } else if (background == Background::Euclidean) {
    if (std::abs(target.sum() - gb) > 1e-8 * (1.0 + std::abs(gb) + target.cwiseAbs().sum()))
      throw InputError("ricci_flow: flat target curvatures sum to " + fmt(target.sum()) +
                       " but Gauss–Bonnet requires " + fmt(gb) + " (2π χ)");
  } else if (!(target.sum() - gb > 0.0)) {
    throw InputError("ricci_flow: hyperbolic target curvatures sum to " + fmt(target.sum()) +
                     ", which leaves no positive area (need more than 2π χ = " + fmt(gb) + ")");
  }
  *has_fixed_out = has_fixed;
  return target;
}

/// One run of ricci_solve after its input checks, one method a phase: the
/// flip pass of the input, an explicit flow step, a Newton step (Hessian
/// assembly, step solve, line search), the stopping test at the
/// floating-point floor, and the result assembly. Holds pointers into
/// itself (metric, flip_ctx): not copyable.
struct RicciRun {
  const RicciFlowOptions& options;
  const Background background;
  const Eigen::VectorXd target;
  const std::vector<char>* fixed_in;
  // Dirichlet vertices keep their start u; their curvature is not a target.
  const bool any_fixed;
  const bool newton, flat;
  RicciDomain dom;       // mutable: edge flips change it
  const int nv;
  Eigen::VectorXd base;  // Penner coordinates of the current edges
  SchemeMetric metric;
  FlipContext flip_ctx;
  FlipContext* flips = nullptr;
  int rolled_back_trials = 0;  // RicciFlowResult::rolled_back_trials

  RicciFlowResult res;
  Evaluation ev, trial;
  Eigen::VectorXd g;
  double err = 0.0;

  Eigen::SparseMatrix<double> H;
  std::vector<int> slot;
  long long slot_version = -1;
  SURFMAP_RICCI_SOLVER llt;
  bool analyzed = false, factor_valid = false;
  long long analyzed_version = 0;
  double mu = 0.0;  // Levenberg shift, only used when a plain Newton step fails
  std::string failure;
  // Residuals in (tolerance, floor_tol] where Newton can make no progress are
  // the floating-point floor of this mesh: success (RicciFlowOptions).
  const double floor_tol;
  bool at_floor = false;
  StartCheck* check = nullptr;  // ricci_flow_from_checked

  RicciRun(const RicciDomain& dom_in, const Eigen::VectorXd& lengths, Background background_in,
           const RicciFlowOptions& options_in, Eigen::VectorXd target_checked,
           const std::vector<char>* fixed, bool has_fixed, StartCheck* start_check)
      : options(options_in),
        background(background_in),
        target(std::move(target_checked)),
        fixed_in(fixed),
        any_fixed(has_fixed),
        newton(options_in.method == RicciMethod::Newton),
        flat(background_in == Background::Euclidean),
        dom(dom_in),
        nv(dom_in.num_vertices),
        base(lengths),
        metric(dom, base, background_in, options_in.scheme),
        H(dom_in.num_vertices, dom_in.num_vertices),
        floor_tol(std::max(options_in.tolerance, options_in.floor_tolerance)),
        check(start_check) {
    llt.simplicial_solves = background_in == Background::Hyperbolic;
  }
  RicciRun(const RicciRun&) = delete;
  RicciRun& operator=(const RicciRun&) = delete;

  Eigen::VectorXd residual(const Eigen::VectorXd& K) const {
    Eigen::VectorXd r = K - target;
    if (any_fixed)
      for (int v = 0; v < nv; ++v)
        if ((*fixed_in)[v]) r[v] = 0.0;
    return r;
  }

  /// Flip pass: the input metric made intrinsically Delaunay by exact flips
  /// (vertex scaling with options.intrinsic_delaunay only).
  void flip_input_to_delaunay() {
    if (options.intrinsic_delaunay && options.scheme == RicciScheme::VertexScaling) {
      flip_ctx.init(dom, base, background);
      if (!flip_ctx.make_delaunay(nullptr))
        throw SolveError("ricci_flow: intrinsic Delaunay flips of the input did not terminate");
      flips = &flip_ctx;
    }
  }

  /// ricci_flow_from_checked: whether u_start beats u = 0 by the energy's
  /// slopes along the segment between them (see there), filling check->account.
  /// u = 0 is evaluated first, with the Jacobian a Newton step needs, and the
  /// triangulation it leaves is kept in a copy. When the start does not beat
  /// it, every flip towards u_start is undone from that copy and the
  /// evaluation at u = 0 becomes the run's start (evaluate_start evaluates
  /// nothing again), so the run from u = 0 is the one ricci_flow makes, bit
  /// for bit (FlipContext::roll_back would restore the faces but not the
  /// order of EF's two faces, which orients later flips).
  bool start_beats_zero(const Eigen::VectorXd& u_start) {
    CheckedStart& a = check->account;
    Evaluation at_zero;
    evaluate(dom, metric, background, Eigen::VectorXd::Zero(nv), newton, at_zero, flips, options.threads);
    const RicciDomain dom_at_zero = dom;
    const Eigen::VectorXd base_at_zero = base;
    const RowMatrixX2i ef_at_zero = flip_ctx.EF;
    const long long flips_at_zero = flip_ctx.flips;
    const size_t history_at_zero = flip_ctx.history.size();
    bool better = at_zero.bad_edge < 0;
    if (better) {
      const Eigen::VectorXd g0 = residual(at_zero.K);
      a.residual_at_zero = g0.cwiseAbs().maxCoeff();
      a.slope_at_zero = g0.dot(u_start);
      evaluate(dom, metric, background, u_start, newton, ev, flips, options.threads);
      better = ev.bad_edge < 0;
      if (better) {
        a.slope_at_start = residual(ev.K).dot(u_start);
        better = a.slope_at_zero < 0.0 && a.slope_at_start <= check->overshoot * -a.slope_at_zero;
      }
    }
    if (!better) {
      dom = dom_at_zero;
      base = base_at_zero;
      flip_ctx.EF = ef_at_zero;
      flip_ctx.flips = flips_at_zero;
      flip_ctx.history.resize(history_at_zero);
      ++flip_ctx.version;
      at_zero.version = flips ? flip_ctx.version : 0;
      ev = std::move(at_zero);
    }
    return better;
  }

  /// The metric at the start u (u_start or zero), its residual and the
  /// first residual_history entry.
  void evaluate_start(const Eigen::VectorXd* u_start) {
    res.background = background;
    bool evaluated = false;
    if (u_start && check && newton && !any_fixed) {
      check->account.start_used = start_beats_zero(*u_start);
      evaluated = true;  // at u_start, or at u = 0 when it was declined
      if (!check->account.start_used) u_start = nullptr;
    }
    res.u = u_start ? *u_start : Eigen::VectorXd::Zero(nv);
    if (!evaluated) evaluate(dom, metric, background, res.u, newton, ev, flips, options.threads);
    if (ev.bad_edge >= 0)
      throw InputError("ricci_flow: edge " + std::to_string(ev.bad_edge) +
                       " has no valid length in the initial metric");
    g = residual(ev.K);
    err = g.cwiseAbs().maxCoeff();
    res.residual_history.push_back(err);
  }

  /// One step of the explicit flow (RicciMethod::Flow). False (with
  /// `failure` set) when the flow broke down.
  bool flow_step() {
    res.u -= options.flow_step * g;
    evaluate(dom, metric, background, res.u, false, ev, flips, options.threads);
    if (ev.bad_edge >= 0) {
      failure = "the flow produced an invalid length at edge " + std::to_string(ev.bad_edge) +
                " (step too large?)";
      return false;
    }
    g = residual(ev.K);
    err = g.cwiseAbs().maxCoeff();
    if (!std::isfinite(err)) {
      failure = "the flow diverged (non-finite curvature)";
      return false;
    }
    res.residual_history.push_back(err);
    return true;
  }

  // Issue 19: the Jacobian's triplets come in the same order at every
  // iteration while the triangulation is unchanged (flips change it), so
  // after one setFromTriplets their slots in H are known and later
  // iterations only add the values (in the same order: the same sums).
  void assemble(const std::vector<Eigen::Triplet<double>>& t, long long version, Eigen::SparseMatrix<double>& M) {
    if (slot_version != version || slot.size() != t.size()) {
      M.setFromTriplets(t.begin(), t.end());
      slot.resize(t.size());
      for (size_t q = 0; q < t.size(); ++q) {
        const int c = t[q].col();
        const int* begin = M.innerIndexPtr() + M.outerIndexPtr()[c];
        const int* end = M.innerIndexPtr() + M.outerIndexPtr()[c + 1];
        slot[q] = static_cast<int>(std::lower_bound(begin, end, t[q].row()) - M.innerIndexPtr());
      }
      slot_version = version;
      return;
    }
    double* v = M.valuePtr();
    std::fill(v, v + M.nonZeros(), 0.0);
    for (size_t q = 0; q < t.size(); ++q) v[slot[q]] += t[q].value();
  }

  /// H from the Jacobian of the current evaluation. Newton: H δ = −g, gauge
  /// fixed by pinning vertex 0 (adding e0 e0ᵀ makes H definite; since Σg = 0
  /// the solution then has δ_0 = 0 and solves H δ = −g).
  void assemble_hessian() {
    if (any_fixed) {
      // Identity rows/columns for the fixed vertices (their step is 0).
      std::vector<Eigen::Triplet<double>> kept;
      kept.reserve(ev.triplets.size() + nv);
      for (const auto& t : ev.triplets)
        if (!(*fixed_in)[t.row()] && !(*fixed_in)[t.col()]) kept.push_back(t);
      for (int v = 0; v < nv; ++v)
        if ((*fixed_in)[v]) kept.emplace_back(v, v, 1.0);
      H.setFromTriplets(kept.begin(), kept.end());
    } else {
      assemble(ev.triplets, flip_ctx.version, H);
      if (flat) H.coeffRef(0, 0) += 1.0;
    }
  }

  /// Cheap path: the factor of an earlier Hessian as a preconditioner for
  /// conjugate gradients on the current one (H changes little between
  /// Newton steps); empty when that does not converge quickly (the caller
  /// then refactorizes).
  /// Inexact Newton: the step is solved to a relative residual of the
  /// current curvature error (at most 1e-3), which keeps the convergence
  /// superlinear; solving every step to 1e-12 took twice the iterations
  /// for the same Newton steps and final error (72848-vertex vase: 43
  /// against 88 preconditioned iterations over 5 steps, 0.4 s of 1.9 s).
  Eigen::VectorXd preconditioned_step(const Eigen::VectorXd& rhs) {
    Eigen::VectorXd delta = Eigen::VectorXd::Zero(nv);
    Eigen::VectorXd r = rhs, z = llt.solve(r), p = z;
    double rz = r.dot(z);
    const double stop = std::max(1e-12, std::min(1e-3, err)) * rhs.norm();
    bool ok = false;
    for (int k = 0; k < 40; ++k) {
      ++res.cg_iterations;
      const Eigen::VectorXd Hp = H * p;
      const double pHp = p.dot(Hp);
      if (!(pHp > 0.0)) break;
      const double a = rz / pHp;
      delta += a * p;
      r -= a * Hp;
      if (r.norm() <= stop) {
        ok = true;
        break;
      }
      z = llt.solve(r);
      const double rz_new = r.dot(z);
      p = z + (rz_new / rz) * p;
      rz = rz_new;
    }
    if (!ok || !delta.allFinite()) delta.resize(0);
    return delta;
  }

  /// The step from a fresh factorization of H + mu I (the pattern analysed
  /// again when flips changed it). False, with mu raised, when the
  /// factorization or solve failed.
  bool factorized_step(const Eigen::VectorXd& rhs, Eigen::VectorXd& delta) {
    Eigen::SparseMatrix<double> A = H;
    if (mu > 0.0)
      for (int v = 0; v < nv; ++v) A.coeffRef(v, v) += mu;
    if (!analyzed || analyzed_version != flip_ctx.version) {
      llt.analyzePattern(A);  // again when flips changed the sparsity pattern
      ++work::analyses;
      analyzed = true;
      analyzed_version = flip_ctx.version;
    }
    llt.factorize(A);
    ++work::factorisations;
    ++res.factorisations;
    factor_valid = llt.info() == Eigen::Success && mu == 0.0;
    if (llt.info() == Eigen::Success) delta = llt.solve(rhs);
    if (llt.info() != Eigen::Success || !delta.allFinite()) {
      mu = std::max(mu * 10.0, 1e-10 * (1.0 + H.diagonal().cwiseAbs().maxCoeff()));
      return false;
    }
    return true;
  }

  /// Backtracking on the residual norm (the Newton direction decreases
  /// |g|² at rate −2|g|²); K is continuous across degenerate triangles
  /// thanks to the extended angles. On success u, ev and g move to the
  /// accepted point.
  bool line_search(const Eigen::VectorXd& delta, double g2) {
    for (double t = 1.0; t > 1e-6; t *= 0.5) {
      Eigen::VectorXd ut = res.u + t * delta;
      if (flat && !any_fixed) ut.array() -= ut[0];
      // A trial point far from u (a full Newton step on a long, tapered
      // shape: conformal factors e^-70 at one end) can be a metric whose
      // Delaunay triangulation is reached only after a huge number of
      // Ptolemy flips: edges wind around a vertex whose cone angle the step
      // made enormous, their base lengths grow geometrically (1e13 after
      // 65000 flips on a 480-vertex bent 40:1 sphere) and the whole run's
      // flip budget was spent on one rejected trial. Such a trial is
      // rejected like an invalid one: its flips are rolled back and the
      // step halved (issue 13 item 5).
      const long long mark = flips ? static_cast<long long>(flip_ctx.history.size()) : 0;
      if (flips) flip_ctx.pass_limit = 2LL * static_cast<long long>(dom.EV.rows()) + 100;
      evaluate(dom, metric, background, ut, true, trial, flips, options.threads);
      if (flips) flip_ctx.pass_limit = 0;
      if (trial.flips_exhausted) {
        flip_ctx.roll_back(mark);
        ++rolled_back_trials;
        continue;
      }
      if (trial.bad_edge >= 0) continue;
      const Eigen::VectorXd gt = residual(trial.K);
      if (gt.allFinite() && gt.squaredNorm() <= (1.0 - 1e-4 * t) * g2) {
        res.u = ut;
        std::swap(ev, trial);
        g = gt;
        return true;
      }
    }
    return false;
  }

  /// One Newton iteration: up to 12 attempts (step solve, line search),
  /// raising the Levenberg shift mu after each failure. False (with
  /// `failure` and at_floor set) when no attempt decreased the residual.
  bool newton_step() {
    ++work::newton_iterations;
    assemble_hessian();
    const double g2 = g.squaredNorm();
    bool accepted = false;
    // Flat, no Dirichlet vertex: the constant part of g cannot be removed by
    // any u (Σ K = 2πχ); it is only round-off of the angle sums (~1e-10 at
    // 500k vertices). Solving with it would pile it onto the pinned vertex
    // 0, so drop it and let it stay spread evenly (~1e-16 per vertex).
    Eigen::VectorXd rhs = -g;
    if (flat && !any_fixed) rhs.array() += g.mean();
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      Eigen::VectorXd delta;
      if (factor_valid && mu == 0.0) delta = preconditioned_step(rhs);
      if (delta.size() == 0 && !factorized_step(rhs, delta)) continue;
      // Hyperbolic: at most kMaxHyperbolicStep in any u per step. Why: far
      // out every angle underflows to 0, where the residual is the target's
      // cone angles, small for near-cusp targets (all cones 0.1 or 1e-3), so
      // a residual line search accepted a first step into that region, whose
      // Hessian is 0, and stalled there.
      if (!flat) {
        const double largest = delta.cwiseAbs().maxCoeff();
        if (largest > kMaxHyperbolicStep) delta *= kMaxHyperbolicStep / largest;
      }
      accepted = line_search(delta, g2);
      if (accepted) {
        mu *= 0.1;
        if (mu < 1e-14) mu = 0.0;
      } else {
        mu = std::max(mu * 100.0, 1e-8 * (1.0 + H.diagonal().cwiseAbs().maxCoeff()));
      }
    }
    if (!accepted) {
      at_floor = err <= floor_tol;
      failure = err < std::max(1e3 * options.tolerance, floor_tol)
                    ? "Newton stalled at the floating-point floor of the angle sums"
                    : "Newton line search failed to decrease the curvature residual";
      return false;
    }
    err = g.cwiseAbs().maxCoeff();
    res.residual_history.push_back(err);
    return true;
  }

  /// Stopping test: eight iterations without 10% progress just above the
  /// tolerance are the floating-point floor of this mesh (seen at 500k
  /// vertices, ~1.2e-10). True (with `failure` and at_floor set) to stop.
  bool stalled_at_floor() {
    const size_t nh = res.residual_history.size();
    if (nh >= 9 && err > options.tolerance && err < std::max(1e3 * options.tolerance, floor_tol) &&
        err > 0.9 * res.residual_history[nh - 9]) {
      at_floor = err <= floor_tol;
      failure = "Newton stalled at the floating-point floor of the angle sums";
      return true;
    }
    return false;
  }

  /// Result assembly after `it` iterations: the final metric validated
  /// again (never report success with an invalid metric), the final
  /// triangulation, and converged / stopped_at_floor / message.
  void assemble_result(int it, int max_it) {
    res.iterations = it;
    // Newton out of iterations within the floor band: also the floor.
    if (newton && it >= max_it && err > options.tolerance && err <= floor_tol) at_floor = true;

    // Final validation: never report success with an invalid metric. ev
    // already holds the evaluation at res.u (evaluate_start, the accepted
    // line-search trial or the last flow step) unless a rejected trial's
    // flips changed the triangulation since; evaluate is deterministic and
    // its lengths and angles do not depend on the Jacobian flag, so only
    // then is it evaluated again (issue 19: 0.1 s of the 72848-vertex vase's
    // 2 s flow).
    if (ev.version != (flips ? flips->version : 0)) evaluate(dom, metric, background, res.u, false, ev, flips, options.threads);
    res.edge_lengths = ev.l;
    res.flips = static_cast<int>(flip_ctx.flips);
    res.flip_history = std::move(flip_ctx.history);
    res.rolled_back_trials = rolled_back_trials;

    res.faces = dom.F;
    res.face_edges = dom.FE;
    res.edge_vertices = dom.EV;
    if (ev.bad_edge >= 0) {
      res.converged = false;
      res.message = "edge " + std::to_string(ev.bad_edge) + " has no valid length in the final metric";
      res.max_curvature_error = std::numeric_limits<double>::infinity();
    } else {
      g = residual(ev.K);
      res.max_curvature_error = g.cwiseAbs().maxCoeff();
      res.floor_estimate = angle_sum_roundoff(dom, ev.l, background);
      const int worst = argmax_abs(g);
      if (ev.degenerate > 0) {
        res.converged = false;
        res.message = "face " + std::to_string(ev.first_degenerate) +
                      " violates the triangle inequality in the final metric (" +
                      std::to_string(ev.degenerate) + " degenerate faces)";
      } else if (ev.min_slack < 1e-13) {
        res.converged = false;
        res.message = "face " + std::to_string(ev.min_slack_face) +
                      " is numerically degenerate in the final metric";
      } else if (at_floor && res.max_curvature_error <= floor_tol) {
        res.converged = true;
        res.stopped_at_floor = true;
      } else if (!(res.max_curvature_error <= options.tolerance)) {
        res.converged = false;
        res.message = (failure.empty() ? std::string("did not reach the tolerance") : failure) +
                      " after " + std::to_string(it) + " iterations: max curvature error " +
                      fmt(res.max_curvature_error) + " at vertex " + std::to_string(worst);
      } else {
        res.converged = true;
      }
    }
  }
};

}  // namespace

RicciFlowResult ricci_solve(const RicciDomain& dom_in, const Eigen::VectorXd& lengths,
                            Background background, const RicciFlowOptions& options,
                            const Eigen::VectorXd& target_in, const Eigen::VectorXd* u_start,
                            const std::vector<char>* fixed_in, StartCheck* check) {
  const auto t0 = std::chrono::steady_clock::now();
  bool has_fixed = false;
  Eigen::VectorXd target =
      checked_target(dom_in, lengths, background, target_in, fixed_in, &has_fixed);
  RicciRun run(dom_in, lengths, background, options, std::move(target), fixed_in, has_fixed, check);
  run.flip_input_to_delaunay();
  run.evaluate_start(u_start);
  const int max_it =
      options.max_iterations > 0 ? options.max_iterations : (run.newton ? 100 : 200000);
  int it = 0;
  for (; it < max_it && run.err > options.tolerance; ++it) {
    if (options.progress && !options.progress(it, run.err))
      throw Cancelled("ricci_flow cancelled at iteration " + std::to_string(it));
    if (!run.newton) {
      if (!run.flow_step()) break;
      continue;
    }
    if (!run.newton_step()) break;
    if (run.stalled_at_floor()) {
      ++it;
      break;
    }
  }
  run.assemble_result(it, max_it);
  run.res.time_s = seconds_since(t0);
  return std::move(run.res);
}

}  // namespace detail

RicciFlowResult ricci_flow(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                           Background background, const RicciFlowOptions& options,
                           const Eigen::VectorXd& target_curvature) {
  const detail::RicciDomain dom = detail::domain_from_connectivity(mesh);
  return detail::ricci_solve(dom, edge_lengths, background, options, target_curvature, nullptr);
}

namespace {

/// ricci_flow_from's start, checked (#V finite values) and in the flat gauge
/// of the Newton solve (u_0 = 0), which its steps keep.
Eigen::VectorXd gauged_start(const detail::RicciDomain& dom, Background background, const Eigen::VectorXd& u_start) {
  if (u_start.size() != dom.num_vertices)
    throw InputError("ricci_flow: expected " + std::to_string(dom.num_vertices) + " start conformal factors, got " +
                     std::to_string(u_start.size()));
  if (!u_start.allFinite()) throw InputError("ricci_flow: the start conformal factors are not all finite");
  Eigen::VectorXd u = u_start;
  if (background == Background::Euclidean) u.array() -= u[0];
  return u;
}

}  // namespace

RicciFlowResult ricci_flow_from(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                Background background, const RicciFlowOptions& options,
                                const Eigen::VectorXd& u_start, const Eigen::VectorXd& target_curvature) {
  const detail::RicciDomain dom = detail::domain_from_connectivity(mesh);
  const Eigen::VectorXd u = gauged_start(dom, background, u_start);
  return detail::ricci_solve(dom, edge_lengths, background, options, target_curvature, &u);
}

CheckedFlow ricci_flow_from_checked(const Connectivity& mesh, const Eigen::VectorXd& edge_lengths,
                                    Background background, const RicciFlowOptions& options,
                                    const Eigen::VectorXd& u_start, double overshoot) {
  const detail::RicciDomain dom = detail::domain_from_connectivity(mesh);
  const Eigen::VectorXd u = gauged_start(dom, background, u_start);
  detail::StartCheck check;
  check.overshoot = overshoot;
  CheckedFlow r;
  r.flow = detail::ricci_solve(dom, edge_lengths, background, options, {}, &u, nullptr, &check);
  r.start = check.account;
  return r;
}

RicciLinearization ricci_linearization(const Connectivity& mesh,
                                       const Eigen::VectorXd& edge_lengths,
                                       Background background, RicciScheme scheme,
                                       const Eigen::VectorXd& u) {
  const detail::RicciDomain dom = detail::domain_from_connectivity(mesh);
  if (u.size() != dom.num_vertices || edge_lengths.size() != dom.EV.rows())
    throw InputError("ricci_linearization: u must have #V entries and edge_lengths #E");
  return detail::ricci_linearize(dom, edge_lengths, background, scheme, u);
}

Eigen::VectorXd edge_lengths(const TriMesh& mesh, const Connectivity& conn) {
  Eigen::VectorXd l(conn.num_edges());
  for (int e = 0; e < conn.num_edges(); ++e)
    l[e] = (mesh.V.row(conn.edge_vertex(e, 0)) - mesh.V.row(conn.edge_vertex(e, 1))).norm();
  return mollify_edge_lengths(l, conn).lengths;
}

}  // namespace surfmap
