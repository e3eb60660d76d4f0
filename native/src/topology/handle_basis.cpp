#include "surfmap/topology/handle_basis.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <numeric>
#include <optional>
#include <queue>
#include <array>
#include <string>

#include <Eigen/Geometry>
#include <Eigen/LU>

#include "surfmap/error.h"

namespace surfmap {
namespace {

using IntVector = Eigen::Matrix<long long, Eigen::Dynamic, 1>;

// Letters of handle i (0-based).
int A(int i) { return 2 * i + 1; }
int B(int i) { return 2 * i + 2; }
Word power(int letter, long long q) {
  Word w;
  for (long long k = 0; k < std::abs(q); ++k) w.push_back(q > 0 ? letter : -letter);
  return w;
}

struct Move {
  GroupMap fwd, inv;
};

Move then(const Move& outer, const Move& inner) {  // outer ∘ inner
  return {compose(outer.fwd, inner.fwd), compose(inner.inv, outer.inv)};
}

void dehn_all(GroupMap& m, const Word& R) {
  for (Word& w : m) w = dehn_reduce(w, R);
}

// a_i -> a_i b_i^q (homology a_i += q b_i); its inverse uses -q.
Move twist_a(int g, int i, long long q) {
  Move m{identity_map(2 * g), identity_map(2 * g)};
  m.fwd[A(i) - 1] = concat({A(i)}, power(B(i), q));
  m.inv[A(i) - 1] = concat({A(i)}, power(B(i), -q));
  return m;
}
// b_i -> b_i a_i^q (homology b_i += q a_i).
Move twist_b(int g, int i, long long q) {
  Move m{identity_map(2 * g), identity_map(2 * g)};
  m.fwd[B(i) - 1] = concat({B(i)}, power(A(i), q));
  m.inv[B(i) - 1] = concat({B(i)}, power(A(i), -q));
  return m;
}

// Half turn of handle i: (a, b) -> (ab) (a^-1, b^-1) (ab)^-1, which fixes
// [a, b] exactly; homology -I on the handle. Inverse found by a word search
// and checked: a -> b a^-1 b^-1, b -> b a b^-1 a^-1 b^-1.
Move half_turn(int g, int i) {
  Move m{identity_map(2 * g), identity_map(2 * g)};
  const int a = A(i), b = B(i);
  m.fwd[a - 1] = {a, b, -a, -b, -a};
  m.fwd[b - 1] = {a, -b, -a};
  m.inv[a - 1] = {b, -a, -b};
  m.inv[b - 1] = {b, a, -b, -a, -b};
  return m;
}

// Rewrites a genus-2 pattern (letters 1..4 for handles i, i+1) in genus g.
GroupMap embed_pair(int g, int i, const std::vector<Word>& pattern) {
  GroupMap m = identity_map(2 * g);
  for (int k = 0; k < 4; ++k) {
    Word w;
    for (int x : pattern[k]) w.push_back((x > 0 ? 1 : -1) * (2 * i + std::abs(x)));
    m[2 * i + k] = w;
  }
  return m;
}

// Swap of handles i and i+1: (H_i, H_i+1) -> (c_i H_i+1 c_i^-1, H_i) with
// c_i = [a_i, b_i]; fixes c_i c_i+1 exactly. Inverse: (H_i+1, c_i+1^-1 H_i c_i+1).
Move swap(int g, int i) {
  const Word c1{1, 2, -1, -2}, c2{3, 4, -3, -4};
  const std::vector<Word> fwd{concat({c1, {3}, inverse(c1)}), concat({c1, {4}, inverse(c1)}), {1}, {2}};
  const std::vector<Word> inv{{3}, {4}, concat({inverse(c2), {1}, c2}), concat({inverse(c2), {2}, c2})};
  return {embed_pair(g, i, fwd), embed_pair(g, i, inv)};
}

// Mixing of handles i, i+1: homology a_i += a_i+1, b_i+1 -= b_i (coordinates:
// v[a_i+1] += v[a_i], v[b_i] -= v[b_i+1]). Found by a search over short words
// and made to fix [a1,b1][a2,b2] exactly (not only up to conjugation) by an
// inner automorphism; its inverse was checked to compose to the identity.
Move mix_adjacent(int g, int i) {
  const std::vector<Word> fwd{{1, 3}, {-3, 2, 3}, {-3, 2, 3, -2, 3}, {4, -3, -2, 3}};
  const std::vector<Word> inv{{1, -2, -3, 2}, {-2, 3, 2, -3, 2}, {-2, 3, 2}, {4, 2}};
  return {embed_pair(g, i, fwd), embed_pair(g, i, inv)};
}

// v[a_to] += v[a_from], v[b_from] -= v[b_to] for any two handles: the
// adjacent mixing conjugated by swaps that carry positions (h0, h0+1) to
// (from, to).
Move mix(int g, int from, int to) {
  Move C{identity_map(2 * g), identity_map(2 * g)};
  int h0;
  if (from < to) {
    h0 = from;
    for (int j = from + 1; j <= to - 1; ++j) C = then(swap(g, j), C);
  } else {
    h0 = to;
    C = swap(g, to);
    for (int j = to + 1; j <= from - 1; ++j) C = then(swap(g, j), C);
  }
  const Move U = mix_adjacent(g, h0);
  Move m{compose(C.fwd, compose(U.fwd, C.inv)), compose(C.fwd, compose(U.inv, C.inv))};
  return m;
}

IntMatrix integer_inverse(const IntMatrix& M) {
  const Eigen::MatrixXd inv = M.cast<double>().inverse();
  IntMatrix r = inv.array().round().cast<long long>().matrix();
  if (M * r != IntMatrix::Identity(M.rows(), M.cols()))
    throw SolveError("handle basis: an integer matrix that should be unimodular is not");
  return r;
}

// Basis (columns) of the integer kernel {x : A x = 0} by unimodular column
// operations (A V = [H | 0]), size-reduced afterwards.
IntMatrix integer_kernel(const IntMatrix& A_in) {
  IntMatrix A = A_in;
  const int n = static_cast<int>(A.cols());
  IntMatrix V = IntMatrix::Identity(n, n);
  int col = 0;
  for (int r = 0; r < A.rows() && col < n; ++r) {
    // Euclid on row r among columns col..n-1.
    for (;;) {
      int piv = -1;
      for (int c = col; c < n; ++c)
        if (A(r, c) != 0 && (piv < 0 || std::abs(A(r, c)) < std::abs(A(r, piv)))) piv = c;
      if (piv < 0) break;
      A.col(piv).swap(A.col(col));
      V.col(piv).swap(V.col(col));
      bool done = true;
      for (int c = col + 1; c < n; ++c) {
        if (A(r, c) == 0) continue;
        const long long q = A(r, c) / A(r, col);
        A.col(c) -= q * A.col(col);
        V.col(c) -= q * V.col(col);
        if (A(r, c) != 0) done = false;
      }
      if (done) {
        ++col;
        break;
      }
    }
  }
  IntMatrix K = V.rightCols(n - col);
  // Size reduction: pairwise x_i -= q x_j while it shortens (L1).
  for (bool changed = true; changed;) {
    changed = false;
    for (int i = 0; i < K.cols(); ++i)
      for (int j = 0; j < K.cols(); ++j) {
        if (i == j) continue;
        for (int s : {1, -1}) {
          const IntVector t = K.col(i) - s * K.col(j);
          if (t.cwiseAbs().sum() < K.col(i).cwiseAbs().sum()) K.col(i) = t, changed = true;
        }
      }
  }
  return K;
}

}  // namespace

Word substitute(const Word& w, const GroupMap& images) {
  Word r;
  for (int x : w) {
    const Word& e = images.at(std::abs(x) - 1);
    if (x > 0)
      r.insert(r.end(), e.begin(), e.end());
    else
      for (auto it = e.rbegin(); it != e.rend(); ++it) r.push_back(-*it);
  }
  return reduce(r);
}

GroupMap identity_map(int n) {
  GroupMap m(n);
  for (int j = 0; j < n; ++j) m[j] = {j + 1};
  return m;
}

GroupMap compose(const GroupMap& outer, const GroupMap& inner) {
  GroupMap m(inner.size());
  for (size_t j = 0; j < inner.size(); ++j) m[j] = substitute(inner[j], outer);
  return m;
}

Eigen::Matrix<long long, Eigen::Dynamic, 1> abelianize(const Word& w, int n) {
  IntVector v = IntVector::Zero(n);
  for (int x : w) {
    if (std::abs(x) > n) throw InputError("abelianize: letter " + std::to_string(x) + " out of range");
    v[std::abs(x) - 1] += x > 0 ? 1 : -1;
  }
  return v;
}

IntMatrix homology_matrix(const GroupMap& map, int n) {
  IntMatrix M(n, n);
  for (int j = 0; j < n; ++j) M.col(j) = abelianize(map[j], n);
  return M;
}

IntMatrix symplectic_form(int genus) {
  IntMatrix J = IntMatrix::Zero(2 * genus, 2 * genus);
  for (int i = 0; i < genus; ++i) J(2 * i, 2 * i + 1) = 1, J(2 * i + 1, 2 * i) = -1;
  return J;
}

Word canonical_relator(int genus) {
  Word R;
  for (int i = 0; i < genus; ++i) R.insert(R.end(), {A(i), B(i), -A(i), -B(i)});
  return R;
}

SurfaceAutomorphism lift_symplectic(const IntMatrix& P) {
  const int n = static_cast<int>(P.rows());
  if (n % 2 != 0 || P.cols() != n || n == 0) throw InputError("lift_symplectic: P must be 2g x 2g");
  const int g = n / 2;
  const IntMatrix J = symplectic_form(g);
  if (P.transpose() * J * P != J) throw InputError("lift_symplectic: P does not preserve the intersection form");
  const Word R = canonical_relator(g);
  // Reduce Q = P^-1 to I by left multiplications T_k ... T_1 Q = I; then
  // T_k ... T_1 = P and the automorphism is tau_k ∘ ... ∘ tau_1.
  IntMatrix Q = -J * P.transpose() * J;  // P^-1 for symplectic P
  SurfaceAutomorphism out{identity_map(n), identity_map(n), 0};
  auto apply = [&](const Move& m) {
    Q = homology_matrix(m.fwd, n) * Q;
    out.map = compose(m.fwd, out.map);
    out.inverse = compose(out.inverse, m.inv);
    dehn_all(out.map, R);
    dehn_all(out.inverse, R);
    if (++out.moves > 2000) throw SolveError("lift_symplectic: too many moves (entries of P too large)");
    // Word lengths can grow exponentially with the entries of P; realistic
    // changes of basis (signed permutations, a few twists) stay short.
    for (const GroupMap* gm : {&out.map, &out.inverse})
      for (const Word& w : *gm)
        if (w.size() > 3000) throw SolveError("lift_symplectic: words too long (entries of P too large)");
  };
  auto apply_power = [&](const Move& m, long long q) {
    for (long long k = 0; k < std::abs(q); ++k) apply(q > 0 ? m : Move{m.inv, m.fwd});
  };
  auto ra = [](int i) { return 2 * i; };
  auto rb = [](int i) { return 2 * i + 1; };
  for (int h = 0; h < g; ++h) {
    const int ca = ra(h), cb = rb(h);
    // Column a_h -> e_{a_h}. When handle h holds none of it, bring a handle
    // that does to position h by adjacent swaps (short words; mixing would
    // also do it, with longer ones).
    if (Q(ra(h), ca) == 0 && Q(rb(h), ca) == 0) {
      int k = h + 1;
      while (k < g && Q(ra(k), ca) == 0 && Q(rb(k), ca) == 0) ++k;
      if (k == g) throw SolveError("lift_symplectic: zero column");
      for (int j = k - 1; j >= h; --j) apply(swap(g, j));
    }
    // Clear the b-rows handle by handle.
    for (int k = h; k < g; ++k)
      while (Q(rb(k), ca) != 0) {
        if (Q(ra(k), ca) == 0) {
          apply(twist_b(g, k, 1));  // v_a += v_b
          continue;
        }
        apply(twist_a(g, k, -(Q(rb(k), ca) / Q(ra(k), ca))));  // v_b -= q v_a
        if (Q(rb(k), ca) != 0) apply(twist_b(g, k, -(Q(ra(k), ca) / Q(rb(k), ca))));
      }
    // Then Euclid across handles on the a-rows (mixing keeps b-rows zero).
    for (int k = h + 1; k < g; ++k)
      while (Q(ra(k), ca) != 0) {
        if (Q(ra(h), ca) == 0) {
          apply(mix(g, k, h));  // v[a_h] += v[a_k]
          continue;
        }
        apply_power(mix(g, h, k), -(Q(ra(k), ca) / Q(ra(h), ca)));
        if (Q(ra(k), ca) != 0) apply_power(mix(g, k, h), -(Q(ra(h), ca) / Q(ra(k), ca)));
      }
    if (Q(ra(h), ca) == -1) apply(half_turn(g, h));
    if (Q(ra(h), ca) != 1) throw SolveError("lift_symplectic: column of a_" + std::to_string(h + 1) + " is not primitive");
    // Column b_h -> e_{b_h}, keeping column a_h.
    if (Q(rb(h), cb) != 1) throw SolveError("lift_symplectic: reduction lost the symplectic pairing");
    for (int k = h + 1; k < g; ++k) {
      // mix(k, h): v[a_h] += v[a_k], v[b_k] -= v[b_h] (= 1 here).
      if (Q(ra(k), cb) != 0) {
        apply_power(mix(g, k, h), Q(rb(k), cb) + Q(ra(k), cb));  // b_k -> -a_k
        apply(twist_b(g, k, 1));                                  // a_k += b_k -> 0
      }
      apply_power(mix(g, k, h), Q(rb(k), cb));
    }
    if (Q(ra(h), cb) != 0) apply(twist_b(g, h, -Q(ra(h), cb)));
  }
  if (Q != IntMatrix::Identity(n, n)) throw SolveError("lift_symplectic: reduction did not reach the identity");
  if (homology_matrix(out.map, n) != P) throw SolveError("lift_symplectic: lifted map has the wrong homology");
  return out;
}

SurfaceAutomorphism adjacent_handle_mixing(int genus, int i) {
  if (i < 0 || i + 1 >= genus) throw InputError("adjacent_handle_mixing: handle " + std::to_string(i) + " has no next handle");
  const Move m = mix_adjacent(genus, i);
  return {m.fwd, m.inv, 1};
}

bool is_surface_automorphism(const SurfaceAutomorphism& a, int genus) {
  const int n = 2 * genus;
  if (static_cast<int>(a.map.size()) != n || static_cast<int>(a.inverse.size()) != n) return false;
  const Word R = canonical_relator(genus);
  if (!dehn_reduce(substitute(R, a.map), R).empty()) return false;
  if (!dehn_reduce(substitute(R, a.inverse), R).empty()) return false;
  const GroupMap fi = compose(a.map, a.inverse), iff = compose(a.inverse, a.map);
  for (int j = 0; j < n; ++j) {
    if (!dehn_reduce(concat(fi[j], {-(j + 1)}), R).empty()) return false;
    if (!dehn_reduce(concat(iff[j], {-(j + 1)}), R).empty()) return false;
  }
  const IntMatrix M = homology_matrix(a.map, n), J = symplectic_form(genus);
  return M.transpose() * J * M == J;
}

namespace {

// The signed solid angle of a triangle (x, y, z) seen from the origin, with
// |x|, |y|, |z| given, is 2 atan2(num, den), num = x . (y x z), den = |x||y||z|
// + (x . y)|z| + (x . z)|y| + (y . z)|x| (the triangle's solid angle formula);
// 0 when the three directions are coplanar (num = 0).
// The running product of the solid angles' complex numbers (den + i num,
// whose arguments are the atan2 terms) and the number of whole turns its
// argument made: sum of the terms = arg(product) + 2 pi turns.
struct AngleSum {
  double re = 1, im = 0;
  long long turns = 0;
  int since_scale = 0;
  // Adds atan2(num, den) (num != 0: the argument is strictly inside the
  // upper or the lower half plane).
  void add(double num, double den) {
    const double r = re * den - im * num, i = re * num + im * den;
    // Both arguments in (0, pi] (z on the negative real axis counts as pi):
    // their sum is in (0, 2 pi) and left (-pi, pi] when the product turned
    // into the lower half plane. Both in (-pi, 0): the sum is in (-2 pi, 0)
    // and left it when the product is in the upper half plane or at -pi.
    // Mixed halves (or z at 0) never leave (-pi, pi]. The tests read the
    // computed product, so the count agrees with the argument kept.
    const bool z_upper = im > 0 || (im == 0 && re < 0), z_lower = im < 0;
    if (z_upper && num > 0 && i < 0) ++turns;
    else if (z_lower && num < 0 && (i > 0 || (i == 0 && r < 0))) --turns;
    re = r, im = i;
    // Exact power-of-two rescaling now and then (no over- or underflow; the
    // factors' magnitudes are within ~1e-12..1e1).
    if (++since_scale == 8) {
      since_scale = 0;
      const double m = std::max(std::abs(re), std::abs(im));
      if (m > 0 && std::isfinite(m)) {
        const int e = std::ilogb(m);
        re = std::scalbn(re, -e), im = std::scalbn(im, -e);
      }
    }
  }
  double total() const { return std::atan2(im, re) + 2 * M_PI * static_cast<double>(turns); }
};

// The linking number of two closed polygons from their signed crossings in
// one parallel projection (exact: an integer count), or nullopt when that
// projection is not generic to a safe margin: a vertex of one polygon within
// 1e-9 (relative) of the other's segment line where the two may cross, or
// a crossing whose two heights along the view are within 1e-9 of the
// polygons' size (polygons touching or nearly), or the two ways of counting
// disagree. Issue 19: the Gauss sum's solid angles for every segment pair
// were 0.49 G instructions of the 50k pair's calling thread; the crossings
// need a box test for most pairs. Lk = Σ over crossings of a over b of the
// crossing's sign = the same over b over a (both are counted, as a check;
// the sign convention is the Gauss sum's of linking_number, below).
std::optional<int> linking_by_crossings(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  // A fixed direction of no special alignment with meshes' axes.
  const Eigen::Vector3d view = Eigen::Vector3d(0.3141592653589793, 0.5772156649015329, 0.7071067811865476).normalized();
  const Eigen::Vector3d e1 = view.unitOrthogonal(), e2 = view.cross(e1);
  struct Point {
    double x, y, z;
  };
  auto project = [&](const std::vector<Eigen::Vector3d>& p) {
    std::vector<Point> q(p.size());
    for (size_t i = 0; i < p.size(); ++i) q[i] = {p[i].dot(e1), p[i].dot(e2), p[i].dot(view)};
    return q;
  };
  const std::vector<Point> pa = project(a), pb = project(b);
  double size = 0;
  for (const auto* q : {&pa, &pb})
    for (const Point& p : *q) size = std::max({size, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  const double height_margin = 1e-9 * size;
  constexpr double kMargin = 1e-9;
  // Segment boxes of b (x and y ranges), so most pairs cost a box test.
  const size_t na = pa.size(), nb = pb.size();
  std::vector<std::array<double, 4>> box(nb);
  for (size_t j = 0; j < nb; ++j) {
    const Point &p = pb[j], &q = pb[(j + 1) % nb];
    box[j] = {std::min(p.x, q.x), std::max(p.x, q.x), std::min(p.y, q.y), std::max(p.y, q.y)};
  }
  // Signed area test of r against the line p -> q: the sign, 0 when within
  // the margin of the line (relative to |q - p| |r - p|).
  auto side = [](const Point& p, const Point& q, const Point& r) {
    const double ux = q.x - p.x, uy = q.y - p.y, vx = r.x - p.x, vy = r.y - p.y;
    const double d = ux * vy - uy * vx;
    const double scale = std::sqrt((ux * ux + uy * uy) * (vx * vx + vy * vy));
    return d > kMargin * scale ? 1 : d < -kMargin * scale ? -1 : 0;
  };
  int a_over = 0, b_over = 0;
  for (size_t i = 0; i < na; ++i) {
    const Point &p1 = pa[i], &p2 = pa[(i + 1) % na];
    const double x0 = std::min(p1.x, p2.x), x1 = std::max(p1.x, p2.x), y0 = std::min(p1.y, p2.y),
                 y1 = std::max(p1.y, p2.y);
    for (size_t j = 0; j < nb; ++j) {
      const std::array<double, 4>& bx = box[j];
      if (bx[1] < x0 || bx[0] > x1 || bx[3] < y0 || bx[2] > y1) continue;
      const Point &p3 = pb[j], &p4 = pb[(j + 1) % nb];
      const int s1 = side(p3, p4, p1), s2 = side(p3, p4, p2);
      if (s1 * s2 > 0) continue;  // a's segment on one side of b's line
      const int s3 = side(p1, p2, p3), s4 = side(p1, p2, p4);
      if (s3 * s4 > 0) continue;
      if (s1 == 0 || s2 == 0 || s3 == 0 || s4 == 0) return std::nullopt;  // not generic
      // A proper crossing at p1 + t (p2 - p1) = p3 + s (p4 - p3).
      const double ux = p2.x - p1.x, uy = p2.y - p1.y, vx = p4.x - p3.x, vy = p4.y - p3.y;
      const double wx = p3.x - p1.x, wy = p3.y - p1.y, den = ux * vy - uy * vx;
      const double t = (wx * vy - wy * vx) / den, s = (wx * uy - wy * ux) / den;
      const double za = p1.z + t * (p2.z - p1.z), zb = p3.z + s * (p4.z - p3.z);
      if (!(std::abs(za - zb) > height_margin)) return std::nullopt;
      // The crossing's sign: the over strand's direction turned onto the
      // under one's (den = u x v with u along a), counter-clockwise positive.
      const int sign = den > 0 ? 1 : -1;
      if (za > zb)
        a_over += sign;
      else
        b_over -= sign;
    }
  }
  if (a_over != b_over) return std::nullopt;
  return a_over;
}

}  // namespace

double linking_number(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  // The segment pair (p1 p2, p3 p4) subtends the spherical quadrilateral of
  // the directions r13, r14, r24, r23 (Klenin & Langowski, Biopolymers
  // 2000); its signed area is that of the triangles (r13, r14, r24) and
  // (r13, r24, r23), each 2 atan2(num, den) (Van Oosterom & Strackee), on
  // the differences of one vertex of `a` to every vertex of `b` (computed
  // once per vertex of `a`, with their lengths). Issue 19: the atan2 terms
  // are summed as the argument of the product of their complex numbers
  // (den + i num) plus its whole turns, one atan2 in all instead of two per
  // segment pair (which were most of a source cut's handle basis); the sum
  // agrees with the term-by-term one to ~1e-12 and the linking numbers are
  // integers.
  const size_t na = a.size(), nb = b.size();
  if (na == 0 || nb == 0) return 0;
  // Exact from a generic projection's crossings where it is one (the sign
  // convention of the Gauss sum below: HandleBasis.LinkingNumber*).
  if (const std::optional<int> crossings = linking_by_crossings(a, b)) return *crossings;
  std::vector<Eigen::Vector3d> from1(nb), from2(nb);
  std::vector<double> len1(nb), len2(nb);
  auto differences = [&](const Eigen::Vector3d& p, std::vector<Eigen::Vector3d>& d, std::vector<double>& l) {
    for (size_t j = 0; j < nb; ++j) d[j] = b[j] - p, l[j] = d[j].norm();
  };
  AngleSum sum;
  auto add = [&](const Eigen::Vector3d& x, const Eigen::Vector3d& y, const Eigen::Vector3d& z, double lx, double ly,
                 double lz) {
    const double num = x.dot(y.cross(z));
    if (num == 0) return;  // coplanar directions: no solid angle
    sum.add(num, lx * ly * lz + x.dot(y) * lz + x.dot(z) * ly + y.dot(z) * lx);
  };
  differences(a[0], from1, len1);
  for (size_t i = 0; i < na; ++i) {
    differences(a[(i + 1) % na], from2, len2);
    for (size_t j = 0; j < nb; ++j) {
      const size_t k = (j + 1) % nb;
      const Eigen::Vector3d &r13 = from1[j], &r14 = from1[k], &r23 = from2[j], &r24 = from2[k];
      const double l13 = len1[j], l14 = len1[k], l23 = len2[j], l24 = len2[k];
      if (!(l13 * l14 * l23 * l24 > 0)) continue;  // touching polygons: no solid angle
      add(r13, r14, r24, l13, l14, l24);
      add(r13, r24, r23, l13, l24, l23);
    }
    from1.swap(from2);
    len1.swap(len2);
  }
  // Each triangle's solid angle is 2 atan2; the total is minus their sum.
  return -2 * sum.total() / (4.0 * M_PI);
}

namespace {

// handle_basis' loops as 3D polygons in a frame centred on the mesh and
// scaled by its bounding box diagonal: `on` the surface, `inside` pushed
// along the vertex normals by 0.2 x the shortest incident edge (the
// linking numbers pair one with the other), with each loop's centroid,
// vector area and length.
struct LoopGeometry {
  std::vector<std::vector<Eigen::Vector3d>> on, inside;
  std::vector<Eigen::Vector3d> centroid, area;
  std::vector<double> length;
};

LoopGeometry loop_geometry(const TriMesh& mesh, const std::vector<std::vector<int>>& loops) {
  const int n = static_cast<int>(loops.size());
  // Normal frame: vertex normals, push distance 0.2 x shortest incident edge.
  const int nv = mesh.num_vertices();
  std::vector<Eigen::Vector3d> normal(nv, Eigen::Vector3d::Zero());
  std::vector<double> shortest(nv, std::numeric_limits<double>::infinity());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d p0 = mesh.V.row(mesh.F(f, 0)), p1 = mesh.V.row(mesh.F(f, 1)), p2 = mesh.V.row(mesh.F(f, 2));
    const Eigen::Vector3d nf = (p1 - p0).cross(p2 - p0);
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.F(f, k), w = mesh.F(f, (k + 1) % 3);
      normal[v] += nf;
      const double l = (mesh.V.row(v) - mesh.V.row(w)).norm();
      shortest[v] = std::min(shortest[v], l);
      shortest[w] = std::min(shortest[w], l);
    }
  }
  const Eigen::Vector3d lo = mesh.V.colwise().minCoeff(), hi = mesh.V.colwise().maxCoeff();
  const double diag = (hi - lo).norm();
  const Eigen::Vector3d centre = mesh.V.colwise().mean();
  LoopGeometry lg;
  auto& on = lg.on;
  auto& inside = lg.inside;
  on.resize(n), inside.resize(n), lg.centroid.resize(n), lg.area.resize(n);
  lg.length.assign(n, 0);
  for (int k = 0; k < n; ++k) {
    const auto& path = loops[k];
    const size_t m = path.size() >= 2 && path.front() == path.back() ? path.size() - 1 : path.size();
    Eigen::Vector3d c = Eigen::Vector3d::Zero(), area = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < m; ++i) {
      const int v = path[i];
      const Eigen::Vector3d p = (mesh.V.row(v).transpose() - centre) / diag;
      on[k].push_back(p);
      const double nn = normal[v].norm();
      const Eigen::Vector3d nrm = nn > 0 ? Eigen::Vector3d(normal[v] / nn) : Eigen::Vector3d::Zero();
      inside[k].push_back(p - 0.2 * shortest[v] / diag * nrm);
    }
    for (size_t i = 0; i < m; ++i) {
      const Eigen::Vector3d &p = on[k][i], &q = on[k][(i + 1) % m];
      const double l = (q - p).norm();
      c += 0.5 * l * (p + q);
      lg.length[k] += l;
      area += 0.5 * p.cross(q);
    }
    lg.centroid[k] = lg.length[k] > 0 ? Eigen::Vector3d(c / lg.length[k]) : on[k].front();
    lg.area[k] = area;
  }
  return lg;
}

// Meridians M and dual longitudes Lg (canonical coordinates, n x g each;
// m_i . l_j = δ_ij) from the loops' linking matrix hb.loop_linking (H: loop
// classes in canonical coordinates, Ginv its inverse). Sets hb.geometric,
// hb.message and hb.meridian_loops; when the linking numbers do not give a
// geometric basis, the canonical handles (a_i, b_i).
void meridians_and_longitudes(const IntMatrix& H, const IntMatrix& Ginv, HandleBasis& hb, IntMatrix& M,
                              IntMatrix& Lg) {
  const int g = hb.genus, n = 2 * g;
  const IntMatrix J = symplectic_form(g);
  const IntMatrix Lc = Ginv.transpose() * hb.loop_linking * Ginv;
  const IntMatrix anti = Lc - Lc.transpose();
  M.resize(n, g), Lg.resize(n, g);
  hb.geometric = hb.linking_roundoff < 0.2 && (anti == J || anti == -J);
  if (!hb.geometric) {
    hb.message = hb.linking_roundoff >= 0.2 ? "linking numbers are not integral (round-off " +
                                                  std::to_string(hb.linking_roundoff) + "): loops too close to the surface?"
                                            : "linking form is inconsistent with the intersection form";
  } else {
    for (int k = 0; k < n; ++k)
      if (hb.loop_linking.row(k).isZero()) hb.meridian_loops.push_back(k);
    IntMatrix merid;
    if (static_cast<int>(hb.meridian_loops.size()) == g) {
      merid.resize(n, g);
      for (int i = 0; i < g; ++i) merid.col(i) = H.col(hb.meridian_loops[i]);
    } else {
      // Meridians in loop coordinates: u with u^T Ll = 0; reduced there, so
      // they are short combinations of loops.
      merid = H * integer_kernel(hb.loop_linking.transpose());
    }
    const IntMatrix longi = integer_kernel(Lc);
    if (merid.cols() != g || longi.cols() != g) {
      hb.geometric = false;
      hb.message = "meridian or longitude lattice does not have rank g";
    } else {
      const IntMatrix pairing = merid.transpose() * J * longi;
      const long long det = std::llround(pairing.cast<double>().determinant());
      if (std::abs(det) != 1) {
        hb.geometric = false;
        hb.message = "meridians and longitudes are not dual under intersection";
      } else {
        M = merid;
        Lg = longi * integer_inverse(pairing);  // m_i . l_j = delta_ij
      }
    }
  }
  if (!hb.geometric) {
    for (int i = 0; i < g; ++i) M.col(i) = IntMatrix::Identity(n, n).col(2 * i), Lg.col(i) = IntMatrix::Identity(n, n).col(2 * i + 1);
  }
}

// One handle: meridian and longitude (canonical coordinates), position
// (where its longitude's loops lie) and the vector areas of both.
struct Handle {
  IntVector m, l;
  Eigen::Vector3d pos, am, al;
};

// The g handles, ordered along the longest axis of the mesh's bounding box
// (ties: the others), each oriented so that its longitude turns positively
// about the shortest axis (the normal of a flat shape's plane; next axis
// when nearly perpendicular): "half turn" then means something geometric.
std::vector<Handle> ordered_handles(const TriMesh& mesh, const LoopGeometry& lg, const IntMatrix& Ginv,
                                    const IntMatrix& M, const IntMatrix& Lg) {
  const int g = static_cast<int>(M.cols()), n = 2 * g;
  std::vector<Handle> handles(g);
  for (int i = 0; i < g; ++i) {
    Handle& h = handles[i];
    h.m = M.col(i), h.l = Lg.col(i);
    const IntVector um = Ginv * h.m, ul = Ginv * h.l;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    double wsum = 0;
    h.am.setZero(), h.al.setZero();
    // The handle sits where its longitude runs round the hole: meridians
    // are less telling (the meridian lattice of a double torus holds both
    // outer arms and the middle bar).
    for (int k = 0; k < n; ++k) {
      const double w = std::abs(static_cast<double>(ul[k])) * lg.length[k];
      c += w * lg.centroid[k], wsum += w;
      h.am += static_cast<double>(um[k]) * lg.area[k];
      h.al += static_cast<double>(ul[k]) * lg.area[k];
    }
    h.pos = wsum > 0 ? Eigen::Vector3d(c / wsum) : Eigen::Vector3d::Zero();
  }
  const Eigen::Vector3d lo = mesh.V.colwise().minCoeff(), hi = mesh.V.colwise().maxCoeff();
  int axis = 0, thin = 0;
  for (int d = 1; d < 3; ++d) {
    if (hi[d] - lo[d] > hi[axis] - lo[axis]) axis = d;
    if (hi[d] - lo[d] < hi[thin] - lo[thin]) thin = d;
  }
  for (Handle& h : handles) {
    const double len = h.al.norm();
    int d = thin;
    for (int t = 0; t < 3 && std::abs(h.al[d]) < 0.2 * len; ++t) d = (d + 1) % 3;
    if (h.al[d] < 0) h.m = -h.m, h.l = -h.l, h.am = -h.am, h.al = -h.al;
  }
  std::stable_sort(handles.begin(), handles.end(), [&](const Handle& x, const Handle& y) {
    for (int d = 0; d < 3; ++d) {
      const int e = (axis + d) % 3;
      if (std::abs(x.pos[e] - y.pos[e]) > 1e-6) return x.pos[e] < y.pos[e];
    }
    return false;
  });
  return handles;
}

}  // namespace

HandleBasis handle_basis(const TriMesh& mesh, const std::vector<std::vector<int>>& loops,
                         const CanonicalSchema& schema) {
  const int g = schema.genus, n = 2 * g;
  if (static_cast<int>(loops.size()) != n || static_cast<int>(schema.letters.size()) != n)
    throw InputError("handle_basis: need 2g loops and the canonical schema of their word");
  HandleBasis hb;
  hb.genus = g;
  const IntMatrix J = symplectic_form(g);
  // Loop k's class in canonical coordinates (H, columns) and canonical
  // generators in loop coordinates (Ginv = H^-1).
  IntMatrix H(n, n), Ginv(n, n);
  for (int k = 0; k < n; ++k) H.col(k) = abelianize(schema.letters[k], n);
  for (int j = 0; j < n; ++j) Ginv.col(j) = abelianize(schema.generators[j], n);
  if (H * Ginv != IntMatrix::Identity(n, n)) throw SolveError("handle_basis: schema substitutions are not inverse in homology");

  const LoopGeometry lg = loop_geometry(mesh, loops);
  hb.loop_linking = IntMatrix::Zero(n, n);
  for (int k = 0; k < n; ++k)
    for (int l = 0; l < n; ++l) {
      const double lk = linking_number(lg.inside[k], lg.on[l]);
      const double r = std::round(lk);
      hb.linking_roundoff = std::max(hb.linking_roundoff, std::abs(lk - r));
      hb.loop_linking(k, l) = static_cast<long long>(r);
    }

  // Handles: meridian m_i (canonical coordinates), its loop-coordinate
  // vector, and the dual longitude l_i; positioned, oriented and ordered.
  IntMatrix M, Lg;
  meridians_and_longitudes(H, Ginv, hb, M, Lg);
  const std::vector<Handle> handles = ordered_handles(mesh, lg, Ginv, M, Lg);
  hb.P.resize(n, n);
  for (int i = 0; i < g; ++i) {
    hb.P.col(2 * i) = handles[i].m;
    hb.P.col(2 * i + 1) = handles[i].l;
    hb.position.push_back(handles[i].pos);
    hb.meridian_area.push_back(handles[i].am);
    hb.longitude_area.push_back(handles[i].al);
  }
  if (hb.P.transpose() * J * hb.P != J) throw SolveError("handle_basis: meridian/longitude basis is not symplectic");
  try {
    hb.to_canonical = lift_symplectic(hb.P);
  } catch (const SolveError& e) {
    // Geometric basis too far from the canonical one to lift with short
    // words: fall back to the canonical handles.
    hb.geometric = false;
    hb.message = std::string("meridian basis not used: ") + e.what();
    hb.P = IntMatrix::Identity(n, n);
    hb.to_canonical = lift_symplectic(hb.P);
  }
  return hb;
}

namespace {
std::string describe(const std::vector<int>& perm, const std::vector<int>& sign) {
  std::string d;
  for (size_t i = 0; i < perm.size(); ++i) {
    if (i) d += ", ";
    d += "handle " + std::to_string(i + 1) + " -> handle " + std::to_string(perm[i] + 1);
    if (sign[i] < 0) d += " (half turn)";
  }
  return d;
}
}  // namespace

GroupMap reduce_separating_twists(const GroupMap& map, int genus, const std::function<double(const GroupMap&)>& cost,
                                  int max_steps) {
  const int n = 2 * genus;
  const Word R = canonical_relator(genus);
  std::vector<GroupMap> twists;  // T_j and T_j^-1
  for (int j = 1; j < genus; ++j)
    for (int s : {1, -1}) {
      Word C;
      for (int i = 0; i < j; ++i) C = concat({C, {A(i), B(i), -A(i), -B(i)}});
      if (s < 0) C = inverse(C);
      GroupMap t = identity_map(n);
      for (int i = 0; i < j; ++i)
        for (int x : {A(i), B(i)}) t[x - 1] = concat({C, {x}, inverse(C)});
      twists.push_back(t);
    }
  const DehnReducer dehn(R);  // one set of rotations for the 4 (g − 1) 2g reductions per step
  GroupMap cur = map;
  double best = cost(cur);
  for (int step = 0; step < max_steps; ++step) {
    GroupMap next;
    double next_cost = best;
    for (const GroupMap& t : twists)
      for (const GroupMap& cand : {compose(cur, t), compose(t, cur)}) {
        GroupMap c = cand;
        for (Word& w : c) w = dehn(w);
        const double v = cost(c);
        if (v < next_cost) next_cost = v, next = std::move(c);
      }
    if (next.empty()) break;
    cur = std::move(next);
    best = next_cost;
  }
  return cur;
}

bool handle_correspondence_of(const HandleBasis& source, const HandleBasis& target, const IntMatrix& homology,
                              std::vector<int>* permutation, std::vector<int>* sign, std::string* description) {
  const int g = source.genus;
  const IntMatrix S = integer_inverse(target.P) * homology * source.P;
  std::vector<int> perm(g, -1), sg(g, 0);
  bool ok = true;
  for (int i = 0; i < g && ok; ++i) {
    for (int j = 0; j < g; ++j) {
      const auto blk = S.block(2 * j, 2 * i, 2, 2);
      if (blk.isZero()) continue;
      if (perm[i] >= 0) ok = false;
      if (blk == IntMatrix::Identity(2, 2)) perm[i] = j, sg[i] = 1;
      else if (blk == -IntMatrix::Identity(2, 2)) perm[i] = j, sg[i] = -1;
      else ok = false;
    }
    if (perm[i] < 0) ok = false;
  }
  if (permutation) *permutation = perm;
  if (sign) *sign = sg;
  if (description) *description = ok ? describe(perm, sg) : "mixes handles";
  return ok;
}

namespace {

using Choice = SignedPermutation;

/// Up to this genus every signed permutation is scored (7! 2^7 = 645,120);
/// beyond, the g! 2^g grow past memory (genus 8: 1e7, genus 11: 8e10), and
/// the best ones are searched for instead (best_signed_permutations).
constexpr int kEnumeratedGenus = 7;
/// max_candidates <= 0 asks for all; above kEnumeratedGenus, for this many.
constexpr int kUnboundedCandidateCap = 1000;

/// All g! 2^g signed permutations ranked by score (stable: ties keep the
/// order permutations-then-sign-masks), the first max_candidates (> 0) kept.
std::vector<Choice> all_choices_ranked(int g, const std::vector<std::array<double, 2>>& pair_score,
                                       int max_candidates) {
  std::vector<Choice> choices;
  std::vector<int> perm(g);
  std::iota(perm.begin(), perm.end(), 0);
  do {
    for (int mask = 0; mask < (1 << g); ++mask) {
      Choice c{perm, std::vector<int>(g, 1), 0.0};
      for (int i = 0; i < g; ++i) {
        if (mask & (1 << i)) c.sign[i] = -1;
        c.score += pair_score[i * g + perm[i]][c.sign[i] > 0 ? 0 : 1];
      }
      choices.push_back(c);
    }
  } while (std::next_permutation(perm.begin(), perm.end()));
  std::stable_sort(choices.begin(), choices.end(), [](const Choice& x, const Choice& y) { return x.score < y.score; });
  if (max_candidates > 0 && static_cast<int>(choices.size()) > max_candidates) choices.resize(max_candidates);
  return choices;
}

/// Minimum-cost assignment of rows to columns of the n x n matrix `cost`
/// (entries >= kForbidden are not allowed): the Hungarian method with
/// potentials, O(n³). Returns the column of every row, empty when no
/// allowed assignment exists.
constexpr double kForbidden = 1e300;
std::vector<int> min_cost_assignment(const std::vector<double>& cost, int n) {
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> u(n + 1, 0.0), v(n + 1, 0.0);
  std::vector<int> p(n + 1, 0), way(n + 1, 0);  // p[col] = row (1-based), 0 = free
  for (int i = 1; i <= n; ++i) {
    p[0] = i;
    int j0 = 0;
    std::vector<double> minv(n + 1, inf);
    std::vector<char> used(n + 1, 0);
    do {
      used[j0] = 1;
      const int i0 = p[j0];
      double delta = inf;
      int j1 = -1;
      for (int j = 1; j <= n; ++j) {
        if (used[j]) continue;
        const double c = cost[(i0 - 1) * n + (j - 1)];
        const double cur = c >= kForbidden ? inf : c - u[i0] - v[j];
        if (cur < minv[j]) {
          minv[j] = cur;
          way[j] = j0;
        }
        if (minv[j] < delta) {
          delta = minv[j];
          j1 = j;
        }
      }
      if (j1 < 0 || delta == inf) return {};
      for (int j = 0; j <= n; ++j) {
        if (used[j]) {
          u[p[j]] += delta;
          v[j] -= delta;
        } else {
          minv[j] -= delta;
        }
      }
      j0 = j1;
    } while (p[j0] != 0);
    do {
      const int j1 = way[j0];
      p[j0] = p[j1];
      j0 = j1;
    } while (j0);
  }
  std::vector<int> col(n);
  for (int j = 1; j <= n; ++j) col[p[j] - 1] = j - 1;
  return col;
}

}  // namespace

std::vector<SignedPermutation> best_signed_permutations(int g, const std::vector<std::array<double, 2>>& pair_score,
                                                        int count) {
  if (g < 1 || g > 64 || static_cast<int>(pair_score.size()) != g * g)
    throw InputError("best_signed_permutations: need 1 <= g <= 64 and g² pair scores");
  std::vector<double> base(static_cast<size_t>(g) * g);
  for (int k = 0; k < g * g; ++k) base[k] = std::min(pair_score[k][0], pair_score[k][1]);
  auto total = [&](const std::vector<double>& cost, const std::vector<int>& col) {
    double t = 0;
    for (int i = 0; i < g; ++i) t += cost[i * g + col[i]];
    return t;
  };
  // Murty: each subproblem is the base matrix with some pairs forced (their
  // row and column closed to everything else) and some forbidden.
  struct Sub {
    double score;
    long long order;
    std::vector<double> cost;
    std::vector<int> col;
    int fixed_rows;  // rows 0..fixed_rows-1 are forced to col[]
  };
  auto worse = [](const Sub& x, const Sub& y) { return x.score != y.score ? x.score > y.score : x.order > y.order; };
  std::priority_queue<Sub, std::vector<Sub>, decltype(worse)> queue(worse);
  long long order = 0;
  {
    std::vector<int> col = min_cost_assignment(base, g);
    if (!col.empty()) queue.push({total(base, col), order++, base, col, 0});
  }
  std::vector<std::vector<int>> perms;
  while (!queue.empty() && static_cast<int>(perms.size()) < count) {
    Sub best = queue.top();
    queue.pop();
    perms.push_back(best.col);
    std::vector<double> cost = best.cost;
    for (int r = best.fixed_rows; r < g; ++r) {
      // Partition r: rows before r keep best's columns, row r avoids its own.
      std::vector<double> child = cost;
      child[r * g + best.col[r]] = kForbidden;
      std::vector<int> col = min_cost_assignment(child, g);
      if (!col.empty()) queue.push({total(base, col), order++, child, col, r});
      // Force (r, best.col[r]) for the next partitions.
      for (int j = 0; j < g; ++j)
        if (j != best.col[r]) cost[r * g + j] = kForbidden;
      for (int i = 0; i < g; ++i)
        if (i != r) cost[i * g + best.col[r]] = kForbidden;
    }
  }
  std::vector<Choice> out;
  for (const std::vector<int>& perm : perms) {
    // Sign patterns: penalties of leaving each pair's best sign, flipped in
    // sets of increasing sum (each set grown by its next penalty, or its
    // last penalty swapped for the next one).
    std::vector<int> best_sign(g), by_penalty(g);
    std::vector<double> penalty(g);
    for (int i = 0; i < g; ++i) {
      const auto& ps = pair_score[i * g + perm[i]];
      best_sign[i] = ps[0] <= ps[1] ? 1 : -1;
      penalty[i] = std::abs(ps[0] - ps[1]);
    }
    std::iota(by_penalty.begin(), by_penalty.end(), 0);
    std::stable_sort(by_penalty.begin(), by_penalty.end(), [&](int a, int b) { return penalty[a] < penalty[b]; });
    struct Flips {
      double extra;
      std::vector<int> set;  // indices into by_penalty, increasing
    };
    auto more = [](const Flips& x, const Flips& y) { return x.extra > y.extra; };
    std::priority_queue<Flips, std::vector<Flips>, decltype(more)> flips(more);
    flips.push({0.0, {}});
    for (int made = 0; made < count && !flips.empty(); ++made) {
      const Flips f = flips.top();
      flips.pop();
      Choice c{perm, best_sign, 0.0};
      for (int q : f.set) c.sign[by_penalty[q]] = -c.sign[by_penalty[q]];
      for (int i = 0; i < g; ++i) c.score += pair_score[i * g + perm[i]][c.sign[i] > 0 ? 0 : 1];
      out.push_back(std::move(c));
      const int last = f.set.empty() ? -1 : f.set.back();
      if (last + 1 < g) {
        Flips grown = f;
        grown.set.push_back(last + 1);
        grown.extra += penalty[by_penalty[last + 1]];
        flips.push(grown);
        if (last >= 0) {
          Flips swapped = f;
          swapped.set.back() = last + 1;
          swapped.extra += penalty[by_penalty[last + 1]] - penalty[by_penalty[last]];
          flips.push(swapped);
        }
      }
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const Choice& x, const Choice& y) { return x.score < y.score; });
  if (static_cast<int>(out.size()) > count) out.resize(count);
  return out;
}

std::vector<HandleCandidate> handle_candidates(const HandleBasis& source, const HandleBasis& target,
                                               int max_candidates) {
  constexpr size_t kMaxCandidateLetters = 200000;
  const int g = source.genus, n = 2 * g;
  if (target.genus != g) throw InputError("handle_candidates: the surfaces have different genus");
  const IntMatrix J = symplectic_form(g);
  const Word R = canonical_relator(g);
  auto unit = [](const Eigen::Vector3d& v) {
    const double l = v.norm();
    return l > 1e-12 ? Eigen::Vector3d(v / l) : Eigen::Vector3d::Zero();
  };
  // Score of source handle i on target handle j with sign s (index 0: +1, 1: −1).
  std::vector<std::array<double, 2>> pair_score(static_cast<size_t>(g) * g);
  for (int i = 0; i < g; ++i)
    for (int j = 0; j < g; ++j) {
      const double d = 0.5 * (unit(source.meridian_area[i]).dot(unit(target.meridian_area[j])) +
                              unit(source.longitude_area[i]).dot(unit(target.longitude_area[j])));
      const double dist2 = (source.position[i] - target.position[j]).squaredNorm();
      pair_score[i * g + j] = {dist2 + 0.05 * (1.0 - d), dist2 + 0.05 * (1.0 + d)};
    }
  std::vector<Choice> choices = g <= kEnumeratedGenus ? all_choices_ranked(g, pair_score, max_candidates)
                                                      : best_signed_permutations(g, pair_score, max_candidates > 0 ? max_candidates
                                                                                                       : kUnboundedCandidateCap);

  const IntMatrix Ps_inv = integer_inverse(source.P);
  const DehnReducer dehn(R);
  std::vector<HandleCandidate> out;
  for (size_t q = 0; q < choices.size(); ++q) {
    const Choice& c = choices[q];
    IntMatrix S = IntMatrix::Zero(n, n);
    for (int i = 0; i < g; ++i) {
      S(2 * c.perm[i], 2 * i) = c.sign[i];
      S(2 * c.perm[i] + 1, 2 * i + 1) = c.sign[i];
    }
    const SurfaceAutomorphism sigma = lift_symplectic(S);
    HandleCandidate hc;
    hc.permutation = c.perm;
    hc.sign = c.sign;
    hc.geometric_score = c.score;
    // Source canonical -> source geometric -> (signed permutation) target
    // geometric -> target canonical.
    // Composed as (target ∘ sigma) ∘ source^-1, reducing in the target's
    // canonical letters after each step: the unreduced triple composition
    // grows like the product of the three lengths (minutes for genus 5).
    GroupMap target_sigma = compose(target.to_canonical.map, sigma.map);
    for (Word& w : target_sigma) w = dehn(w);
    // Classes whose words would be this long are left out: the map needs
    // their deck elements, which at this length are far beyond double
    // precision (surface_map refuses loop images beyond 500 letters), and
    // building them alone took minutes (a genus-5 target whose meridian
    // basis is 9e4 letters in its canonical generators: 1.7e7 per class).
    size_t predicted = 0;
    for (const Word& w : source.to_canonical.inverse)
      for (int x : w) predicted += target_sigma[std::abs(x) - 1].size();
    if (predicted > kMaxCandidateLetters) continue;
    hc.map = compose(target_sigma, source.to_canonical.inverse);
    for (Word& w : hc.map) w = dehn(w);
    hc.homology = homology_matrix(hc.map, n);
    if (hc.homology != target.P * S * Ps_inv) throw SolveError("handle_candidates: composed map has the wrong homology");
    if (hc.homology.transpose() * J * hc.homology != J)
      throw SolveError("handle_candidates: candidate does not preserve the intersection form");
    if (!dehn_reduce(substitute(R, hc.map), R).empty())
      throw SolveError("handle_candidates: candidate does not respect the surface relation");
    std::string d = describe(c.perm, c.sign);
    if (q == 0) d += source.geometric && target.geometric ? "  [closest handle positions]" : "";
    if (!source.geometric || !target.geometric) d += "  [canonical handles: meridians unknown]";
    hc.description = d;
    out.push_back(std::move(hc));
  }
  return out;
}

}  // namespace surfmap
