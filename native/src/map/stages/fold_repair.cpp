#include "fold_repair.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

#include "surfmap/error.h"
#include "surfmap/map/distortion.h"

namespace surfmap::detail {

using hyperbolic::Mobius;

double energy_in_charts(const std::vector<WeightedEdge>& edges, const std::vector<Mobius>& edge_local) {
  double E = 0;
  for (size_t e = 0; e < edges.size() && e < edge_local.size(); ++e) {
    if (edges[e].w <= 0) continue;
    const double d = edge_local[e].displacement_of_origin();
    E += edges[e].w * d * d;
  }
  return E;
}

namespace {

// Vertices within `rings` edges of a corner of a folded face (BFS on the
// source's own edges), then closed over slivers: a face whose smallest
// angle is below `sliver` (radians) with a free corner frees its other
// corners, so the region's rim cuts no sliver (a sliver with held and free
// corners folds under the smallest move of the free ones). Held vertices
// are never freed (nor walked through: a landmark stays a wall, as in the
// landmark holds).
std::vector<char> free_region(const TriMesh& source, const Connectivity& sc, const std::vector<double>& per_face,
                              const std::vector<char>& held, int rings, const std::vector<char>& is_sliver,
                              int& count) {
  const int nv = source.num_vertices();
  std::vector<int> ring(nv, -1), queue;
  auto is_held = [&](int v) { return !held.empty() && held[v]; };
  for (int f = 0; f < source.num_faces(); ++f)
    if (!std::isfinite(per_face[f]))
      for (int k = 0; k < 3; ++k)
        if (const int v = source.F(f, k); ring[v] < 0 && !is_held(v)) ring[v] = 0, queue.push_back(v);
  for (size_t q = 0; q < queue.size(); ++q) {
    const int v = queue[q];
    if (ring[v] == rings) continue;
    for (int h : sc.outgoing(v))
      if (const int u = sc.head(h); ring[u] < 0 && !is_held(u)) ring[u] = ring[v] + 1, queue.push_back(u);
  }
  // (Sliver closure: a flood over the slivers, from the ring region.)
  for (size_t q = 0; q < queue.size(); ++q)
    for (int h : sc.outgoing(queue[q])) {
      if (!is_sliver[Connectivity::face(h)]) continue;
      const int f = Connectivity::face(h);
      for (int k = 0; k < 3; ++k)
        if (const int u = source.F(f, k); ring[u] < 0 && !is_held(u)) ring[u] = rings, queue.push_back(u);
    }
  std::vector<char> free(nv, 0);
  for (int v : queue) free[v] = 1;
  count = static_cast<int>(queue.size());
  return free;
}

// The projection (first stage): the vertices of each folded face are moved,
// one at a time, into the kernel of the polygon formed by their neighbours,
// where every face of their star is positively oriented. Seen from the
// vertex's point (centred at 0) in the Klein model, geodesics are straight
// lines and orientation is kept, so the kernel is an intersection of
// half-planes: the big square clipped by each face's far side (convex
// polygon clipping). The vertex goes from where it is towards the kernel's
// centroid, only as far as it must to clear every face by a quarter of the
// centroid's margin; among the corners of a folded face the one that moves
// least goes. Neighbours are read in the vertex's sheet through the solve's
// effective edge elements, which no move changes (no vertex leaves its sheet).
class KernelProjection {
 public:
  KernelProjection(const TriMesh& source, const Connectivity& sc, const SolverEdgeIndex& index,
                   const HyperbolicHarmonicResult& hr)
      : source_(source), sc_(sc), index_(index), eff_(hr.edge_effective), z_(hr.z) {}

  const std::vector<Complex>& points() const { return z_; }
  void set_points(const std::vector<Complex>& z) { z_ = z; }

  // Halfedge h's element: it carries the head's point into the tail's sheet
  // (as chart_distortion reads it).
  Mobius element(int h) const {
    const int e = sc_.edge(h);
    const Mobius& A = eff_[index_.solver_edge[e]];
    return (sc_.edge_halfedge(e) == h) == static_cast<bool>(index_.forward[e]) ? A : A.inverse();
  }

  // Whether face f is positively oriented and not flat (Klein model centred
  // at its corner 0; the bound of image_orientation, so that a face the
  // map's distortion counts as flat is unfolded here like a folded one).
  bool positive(int f) const {
    const Mobius c = Mobius::centring(z_[source_.F(f, 0)]);
    const Complex a = klein(c.apply(element(3 * f).apply(z_[source_.F(f, 1)])));
    const Complex b = klein(c.apply(element(3 * f + 2).inverse().apply(z_[source_.F(f, 2)])));
    return cross(a, b) > kFlatImageRelativeCross * std::max(std::norm(a), std::norm(b));
  }

  // Moves one corner of face f so that its whole star is positive; false
  // when no corner's kernel is open. `moved` gets the vertex.
  bool unfold(int f, const std::vector<char>& held, int& moved) {
    double best_move = std::numeric_limits<double>::infinity();
    Complex best_point;
    int best_v = -1;
    for (int k = 0; k < 3; ++k) {
      const int v = source_.F(f, k);
      if (!held.empty() && held[v]) continue;
      Complex x;
      const double move = kernel_move(v, x);
      if (move < best_move) best_move = move, best_point = x, best_v = v;
    }
    if (best_v < 0) return false;
    const double r2 = std::norm(best_point);
    const Complex poincare = best_point / (1.0 + std::sqrt(std::max(0.0, 1.0 - r2)));
    z_[best_v] = Mobius::translation_to(z_[best_v]).apply(poincare);
    moved = best_v;
    return true;
  }

 private:
  static double cross(Complex a, Complex b) { return a.real() * b.imag() - a.imag() * b.real(); }
  static Complex klein(Complex z) { return 2.0 * z / (1.0 + std::norm(z)); }

  // The Klein point (centred at v's point) v should move to, and how far
  // (its Klein norm); +inf when the kernel is empty or too thin.
  double kernel_move(int v, Complex& target) const {
    const Mobius c = Mobius::centring(z_[v]);
    std::vector<std::pair<Complex, Complex>> sides;  // (a, b): x must lie left of a -> b
    for (int h : sc_.outgoing(v)) {
      const int hn = Connectivity::next(h), hp = Connectivity::next(hn);  // v->a, a->b, b->v
      const Complex a = klein(c.apply(element(h).apply(z_[sc_.head(h)])));
      const Complex b = klein(c.apply(element(hp).inverse().apply(z_[sc_.tail(hp)])));
      sides.push_back({a, b});
    }
    // Kernel: a square larger than the star, clipped by every side.
    double extent = 0;
    for (const auto& [a, b] : sides) extent = std::max({extent, std::abs(a), std::abs(b)});
    if (!(extent > 0) || !std::isfinite(extent)) return std::numeric_limits<double>::infinity();
    std::vector<Complex> poly = {{-2 * extent, -2 * extent}, {2 * extent, -2 * extent}, {2 * extent, 2 * extent},
                                 {-2 * extent, 2 * extent}};
    for (const auto& [a, b] : sides) {
      const Complex d = b - a;
      auto side = [&](Complex x) { return cross(d, x - a); };
      std::vector<Complex> next;
      for (size_t i = 0; i < poly.size(); ++i) {
        const Complex p = poly[i], q = poly[(i + 1) % poly.size()];
        const double sp = side(p), sq = side(q);
        if (sp >= 0) next.push_back(p);
        if ((sp >= 0) != (sq >= 0)) next.push_back(p + (q - p) * (sp / (sp - sq)));
      }
      poly.swap(next);
      if (poly.size() < 3) return std::numeric_limits<double>::infinity();
    }
    // Area centroid of the convex kernel (interior when its area is positive).
    double area = 0;
    Complex centroid = 0;
    for (size_t i = 0; i < poly.size(); ++i) {
      const Complex p = poly[i], q = poly[(i + 1) % poly.size()];
      const double w = cross(p, q);
      area += w;
      centroid += w * (p + q);
    }
    if (!(area > 0)) return std::numeric_limits<double>::infinity();
    centroid /= 3.0 * area;
    auto margin = [&](Complex x) {
      double m = std::numeric_limits<double>::infinity();
      for (const auto& [a, b] : sides) m = std::min(m, cross(b - a, x - a) / std::abs(b - a));
      return m;
    };
    const double full = margin(centroid);
    if (!(full > 1e-12 * extent) || std::abs(centroid) >= 0.999) return std::numeric_limits<double>::infinity();
    for (double lambda : {1.0 / 64, 1.0 / 32, 1.0 / 16, 1.0 / 8, 1.0 / 4, 1.0 / 2, 3.0 / 4, 1.0}) {
      const Complex x = lambda * centroid;
      if (margin(x) >= 0.25 * full) {
        target = x;
        return std::abs(x);
      }
    }
    target = centroid;
    return std::abs(centroid);
  }

  const TriMesh& source_;
  const Connectivity& sc_;
  const SolverEdgeIndex& index_;
  const std::vector<Mobius>& eff_;
  std::vector<Complex> z_;
};

// Every face is checked, the folded ones unfolded (Gauss-Seidel: each move
// sees the ones before), for a few rounds. The moved vertices, or empty when
// some fold stays; `partial`, when given, gets the points reached either way
// (the folds the projection undid stay undone for the untangling).
std::vector<int> project_folds(const TriMesh& source, const Connectivity& sc, const SolverEdgeIndex& index,
                               const HyperbolicHarmonicResult& hr, const std::vector<char>& held,
                               std::vector<Complex>& z, int rounds, std::vector<Complex>* partial = nullptr) {
  KernelProjection kp(source, sc, index, hr);
  std::vector<char> moved(source.num_vertices(), 0);
  std::vector<int> moved_list;
  for (int round = 0; round < rounds; ++round) {
    bool any = false, stuck = false;
    for (int f = 0; f < source.num_faces(); ++f) {
      if (kp.positive(f)) continue;
      any = true;
      int v = -1;
      if (!kp.unfold(f, held, v)) {
        stuck = true;
        continue;
      }
      if (!moved[v]) moved[v] = 1, moved_list.push_back(v);
    }
    if (!any) {
      z = kp.points();
      if (partial) *partial = z;
      return moved_list;
    }
    if (stuck && round + 1 == rounds) break;
  }
  if (partial) *partial = kp.points();
  return {};
}

Complex to_klein(Complex z) { return 2.0 * z / (1.0 + std::norm(z)); }
Complex from_klein(Complex x) { return x / (1.0 + std::sqrt(std::max(0.0, 1.0 - std::norm(x)))); }
double cross2(Complex a, Complex b) { return a.real() * b.imag() - a.imag() * b.real(); }

// Vertices within `rings` edges of a corner of a face not positive under
// `kp`, held ones excepted (and not walked through). `count`: how many.
std::vector<char> fold_neighbourhood(const TriMesh& source, const Connectivity& sc, const KernelProjection& kp,
                                     const std::vector<char>& held, int rings, int& count) {
  std::vector<double> per_face(source.num_faces(), 0.0);
  for (int f = 0; f < source.num_faces(); ++f)
    if (!kp.positive(f)) per_face[f] = std::numeric_limits<double>::infinity();
  const std::vector<char> none(source.num_faces(), 0);
  return free_region(source, sc, per_face, held, rings, none, count);
}

// The distortion-aware untangling (second stage). Folded slivers that share
// vertices cannot be unfolded one corner at a time, and asking their images
// only for a positive area crushes them (session 13). Here the free
// vertices near the folds move together to minimise a distortion energy of
// their faces that is also a barrier on their orientation: each connected
// region (its faces must form a disk) is laid out in one flat chart of the
// target, the Klein model centred at one of its points (every point carried
// into that sheet along a tree of the region's edges), where geodesic
// triangles are straight and keep their orientation; its rim is held. Per
// face f with Jacobian J (the affine map from the source face's own shape
// to its image, divided by the square root of the region's mean area scale
// s) and D = det J, the energy is
//   A_f [ (1 − θ) |J|² / (2 χ(D, ε)) + θ (D² + 1) / (2 χ(D, ε)) ],
//   χ(D, ε) = (D + √(ε² + D²)) / 2,
// a regularised conformal (MIPS) term, (K + 1/K)/2 at ε = 0 for the face's
// dilatation K = D', plus a small area term; χ > 0 for every D while ε > 0,
// so a folded start has finite energy, and as ε goes to 0 the energy becomes
// a barrier that keeps every face positive. After each L-BFGS minimisation
// ε shrinks by how much the energy fell, no further than the most folded
// face allows, and once the smallest D is clear of it ε is negligible.
class DistortionUntangler {
 public:
  DistortionUntangler(const TriMesh& source, const Connectivity& sc, const KernelProjection& sheets,
                      const FoldRepairOptions& options)
      : source_(source), sc_(sc), sheets_(sheets), options_(options) {
    const int nf = source.num_faces();
    frame_inverse_.resize(nf);
    area_.resize(nf);
    for (int f = 0; f < nf; ++f) {
      const Eigen::Vector3d p0 = source.V.row(source.F(f, 0)), p1 = source.V.row(source.F(f, 1)),
                            p2 = source.V.row(source.F(f, 2));
      const Eigen::Vector3d e1 = p1 - p0, e2 = p2 - p0;
      const double l1 = e1.norm(), twice = e1.cross(e2).norm();
      const double longest = std::max({l1, e2.norm(), (p2 - p1).norm()});
      area_[f] = 0.5 * twice;
      if (!(l1 > 0) || !(area_[f] > 1e-14 * longest * longest)) {
        area_[f] = 0;  // a degenerate source face has no shape (and counts as neither folded nor flat)
        continue;
      }
      Eigen::Matrix2d S;
      S << l1, e2.dot(e1) / l1, 0, twice / l1;
      frame_inverse_[f] = S.inverse();
    }
  }

  // Untangles each connected part of `free` in its own chart, moving `z` (points in the sheets of `sheets`).
  // Returns how many parts failed (left as they were), the last reason in `why`; `parts`: how many there were.
  int untangle(const std::vector<char>& free, std::vector<Complex>& z, int& parts, std::string& why) {
    const int nv = source_.num_vertices();
    std::vector<int> part(nv, -1);
    parts = 0;
    int failed = 0;
    for (int seed = 0; seed < nv; ++seed) {
      if (!free[seed] || part[seed] >= 0) continue;
      std::vector<int> members = {seed};
      part[seed] = parts;
      for (size_t q = 0; q < members.size(); ++q)
        for (int h : sc_.outgoing(members[q]))
          if (const int u = sc_.head(h); free[u] && part[u] < 0) part[u] = parts, members.push_back(u);
      if (!untangle_part(members, z, why)) ++failed;
      ++parts;
    }
    return failed;
  }

 private:
  struct Face {
    int c[3];
    Eigen::Matrix2d Z;  // the source frame's inverse, over √s
    double w;           // source area over the region's
  };

  static double chi(double D, double eps) {
    const double r = std::sqrt(eps * eps + D * D);
    return D >= 0 ? 0.5 * (D + r) : 0.5 * eps * eps / (r - D);  // (no cancellation for D < 0)
  }

  // Energy of the region at points x (chart), its gradient over every point
  // (the held ones' entries unused), and the smallest D.
  double energy(const std::vector<Face>& faces, const std::vector<Complex>& x, double eps, std::vector<Complex>* grad,
                double& min_det) const {
    const double theta = options_.untangle_area_weight;
    if (grad) grad->assign(x.size(), Complex(0.0));
    double E = 0;
    min_det = std::numeric_limits<double>::infinity();
    for (const Face& f : faces) {
      const Complex t1 = x[f.c[1]] - x[f.c[0]], t2 = x[f.c[2]] - x[f.c[0]];
      Eigen::Matrix2d T;
      T << t1.real(), t2.real(), t1.imag(), t2.imag();
      const Eigen::Matrix2d J = T * f.Z;
      const double D = J.determinant();
      min_det = std::min(min_det, D);
      const double r = std::sqrt(eps * eps + D * D);
      const double c = chi(D, eps), dc = 0.5 * (1 + D / r);
      const double F = J.squaredNorm();
      E += f.w * ((1 - theta) * F + theta * (D * D + 1)) / (2 * c);
      if (!grad) continue;
      Eigen::Matrix2d cof;
      cof << J(1, 1), -J(1, 0), -J(0, 1), J(0, 0);
      const Eigen::Matrix2d dJ = (1 - theta) * (J / c - 0.5 * F * dc / (c * c) * cof) +
                                 theta * (D / c * cof - 0.5 * (D * D + 1) * dc / (c * c) * cof);
      const Eigen::Matrix2d dT = f.w * dJ * f.Z.transpose();
      const Complex g1(dT(0, 0), dT(1, 0)), g2(dT(0, 1), dT(1, 1));
      (*grad)[f.c[1]] += g1;
      (*grad)[f.c[2]] += g2;
      (*grad)[f.c[0]] -= g1 + g2;
    }
    return E;
  }

  // L-BFGS over the free points (`unknown`: their indices in x) at fixed ε.
  void minimise(const std::vector<Face>& faces, const std::vector<int>& unknown, std::vector<Complex>& x, double eps,
                double step_scale) const {
    const int n = static_cast<int>(unknown.size());
    const int memory = 8;
    std::vector<std::vector<Complex>> S, Y;
    std::vector<double> rho;
    std::vector<Complex> g, gn, d(n), xn;
    double min_det = 0;
    double E = energy(faces, x, eps, &g, min_det);
    auto dot = [&](const std::vector<Complex>& a, const std::vector<Complex>& b) {
      double s = 0;
      for (int i = 0; i < n; ++i) s += a[i].real() * b[i].real() + a[i].imag() * b[i].imag();
      return s;
    };
    std::vector<Complex> gf(n);
    for (int i = 0; i < n; ++i) gf[i] = g[unknown[i]];
    for (int it = 0; it < options_.untangle_iterations; ++it) {
      // Two-loop recursion: d = −H g.
      std::vector<Complex> q = gf;
      std::vector<double> alpha(S.size());
      for (int k = static_cast<int>(S.size()) - 1; k >= 0; --k) {
        alpha[k] = rho[k] * dot(S[k], q);
        for (int i = 0; i < n; ++i) q[i] -= alpha[k] * Y[k][i];
      }
      double gamma = 0;
      if (!S.empty()) gamma = dot(S.back(), Y.back()) / dot(Y.back(), Y.back());
      else {
        double gmax = 0;
        for (const Complex& c : gf) gmax = std::max(gmax, std::abs(c));
        gamma = gmax > 0 ? step_scale / gmax : 0;
      }
      for (int i = 0; i < n; ++i) q[i] *= gamma;
      for (size_t k = 0; k < S.size(); ++k) {
        const double beta = rho[k] * dot(Y[k], q);
        for (int i = 0; i < n; ++i) q[i] += (alpha[k] - beta) * S[k][i];
      }
      for (int i = 0; i < n; ++i) d[i] = -q[i];
      double slope = dot(gf, d);
      if (!(slope < 0)) {  // not a descent direction: steepest descent, memory cleared
        S.clear(), Y.clear(), rho.clear();
        double gmax = 0;
        for (const Complex& c : gf) gmax = std::max(gmax, std::abs(c));
        if (!(gmax > 0)) return;
        for (int i = 0; i < n; ++i) d[i] = -gf[i] * (step_scale / gmax);
        slope = dot(gf, d);
      }
      // Backtracking (Armijo).
      double t = 1, En = 0;
      bool stepped = false;
      for (int b = 0; b < 40; ++b, t *= 0.5) {
        xn = x;
        for (int i = 0; i < n; ++i) xn[unknown[i]] += t * d[i];
        En = energy(faces, xn, eps, nullptr, min_det);
        if (std::isfinite(En) && En <= E + 1e-4 * t * slope) {
          stepped = true;
          break;
        }
      }
      if (!stepped) return;
      energy(faces, xn, eps, &gn, min_det);
      std::vector<Complex> s(n), y(n), gnf(n);
      for (int i = 0; i < n; ++i) s[i] = t * d[i], gnf[i] = gn[unknown[i]], y[i] = gnf[i] - gf[i];
      const double sy = dot(s, y);
      if (sy > 1e-300) {
        if (static_cast<int>(S.size()) == memory) S.erase(S.begin()), Y.erase(Y.begin()), rho.erase(rho.begin());
        S.push_back(s), Y.push_back(y), rho.push_back(1 / sy);
      }
      const double drop = E - En;
      x.swap(xn), gf.swap(gnf), E = En;
      if (drop <= 1e-13 * std::abs(E)) return;
    }
  }

  bool untangle_part(const std::vector<int>& members, std::vector<Complex>& z, std::string& why) const {
    const int nv = source_.num_vertices();
    std::vector<char> face_in(source_.num_faces(), 0);
    std::vector<int> local(nv, -1), faces, verts;
    for (int v : members)
      for (int h : sc_.outgoing(v))
        if (const int f = Connectivity::face(h); !face_in[f]) face_in[f] = 1, faces.push_back(f);
    for (int f : faces)
      for (int k = 0; k < 3; ++k)
        if (const int v = source_.F(f, k); local[v] < 0) local[v] = static_cast<int>(verts.size()), verts.push_back(v);
    // A disk: Euler characteristic 1 (the chart's tree then gives every
    // face's corners in one sheet; around each face the elements compose to
    // the identity).
    int edges2 = 0;
    for (int f : faces)
      for (int k = 0; k < 3; ++k) edges2 += face_in[Connectivity::face(sc_.twin(3 * f + k))] ? 1 : 2;
    const int euler = static_cast<int>(verts.size()) - edges2 / 2 + static_cast<int>(faces.size());
    if (euler != 1) {
      why = "a region of " + std::to_string(members.size()) + " vertices is not a disk (Euler characteristic " +
            std::to_string(euler) + ")";
      return false;
    }
    // The chart: every point carried into the root's sheet along a tree of
    // the region's edges, then centred at the root's point, Klein model.
    const int root = members[0];
    std::vector<Mobius> to_root(verts.size());
    std::vector<char> placed(verts.size(), 0);
    placed[local[root]] = 1;
    std::vector<int> queue = {root};
    for (size_t q = 0; q < queue.size(); ++q) {
      const int v = queue[q];
      for (int h : sc_.outgoing(v)) {
        if (!face_in[Connectivity::face(h)]) continue;
        const int u = sc_.head(h);
        if (placed[local[u]]) continue;
        placed[local[u]] = 1;
        to_root[local[u]] = (to_root[local[v]] * sheets_.element(h)).normalized();
        queue.push_back(u);
      }
    }
    const Mobius centre = Mobius::centring(z[root]);
    std::vector<Complex> x(verts.size());
    for (size_t i = 0; i < verts.size(); ++i) {
      if (!placed[i]) {
        why = "a region of " + std::to_string(members.size()) + " vertices is not connected through its faces";
        return false;
      }
      x[i] = to_klein(centre.apply(to_root[i].apply(z[verts[i]])));
      if (!(std::abs(x[i]) < 0.9)) {
        why = "a region of " + std::to_string(members.size()) + " vertices reaches the chart's edge";
        return false;
      }
    }
    // Faces and the region's area scale s (image area over source area).
    double source_area = 0, image_area = 0;
    std::vector<Face> terms;
    for (int f : faces) {
      if (!(area_[f] > 0)) continue;
      Face t;
      for (int k = 0; k < 3; ++k) t.c[k] = local[source_.F(f, k)];
      t.Z = frame_inverse_[f];
      t.w = area_[f];
      source_area += area_[f];
      image_area += 0.5 * std::abs(cross2(x[t.c[1]] - x[t.c[0]], x[t.c[2]] - x[t.c[0]]));
      terms.push_back(t);
    }
    if (!(source_area > 0) || !(image_area > 0)) {
      why = "a region of " + std::to_string(members.size()) + " vertices has no area";
      return false;
    }
    const double root_s = std::sqrt(image_area / source_area);
    double mean_edge = 0;
    for (Face& t : terms) {
      t.Z /= root_s;
      t.w /= source_area;
      mean_edge += std::abs(x[t.c[1]] - x[t.c[0]]);
    }
    mean_edge /= terms.size();
    std::vector<int> unknown;
    for (int v : members) unknown.push_back(local[v]);
    // ε's schedule (the caption above): start at 1 (D is about 1 for a face
    // of its source's shape at the region's scale).
    double eps = 1, min_det = 0;
    for (int round = 0; round < options_.untangle_rounds; ++round) {
      const double before = energy(terms, x, eps, nullptr, min_det);
      minimise(terms, unknown, x, eps, mean_edge);
      const double after = energy(terms, x, eps, nullptr, min_det);
      const double sigma = std::max(1 - after / before, 0.1);
      const double mu = (1 - sigma) * chi(min_det, eps);
      eps = min_det < mu ? 2 * std::sqrt(mu * (mu - min_det)) : 1e-13;
      if (min_det > 0 && std::abs(before - after) <= 1e-5 * after) break;
    }
    // Positive with a margin in the chart, and inside it.
    int folded = 0;
    for (const Face& t : terms) {
      const Complex a = x[t.c[1]] - x[t.c[0]], b = x[t.c[2]] - x[t.c[0]];
      const double l2 = std::max({std::norm(a), std::norm(b), std::norm(b - a)});
      folded += !(cross2(a, b) > kFlatImageRelativeCross * l2);
    }
    for (const Complex& p : x) folded += !(std::abs(p) < 0.95);
    if (folded) {
      why = "the untangling of a region of " + std::to_string(members.size()) + " vertices leaves " +
            std::to_string(folded) + " of its " + std::to_string(terms.size()) + " faces folded or flat";
      return false;
    }
    const Mobius uncentre = centre.inverse();
    for (int v : members) z[v] = to_root[local[v]].inverse().apply(uncentre.apply(from_klein(x[local[v]])));
    return true;
  }

  const TriMesh& source_;
  const Connectivity& sc_;
  const KernelProjection& sheets_;
  const FoldRepairOptions& options_;
  std::vector<Eigen::Matrix2d> frame_inverse_;
  std::vector<double> area_;
};

}  // namespace

FoldRepairResult repair_folds_locally(const TriMesh& source, const Connectivity& sc,
                                      const std::vector<WeightedEdge>& edges, const SolverEdgeIndex& index,
                                      const IntrinsicDelaunayResult& own, const HyperbolicHarmonicResult& hr,
                                      const std::vector<double>& per_face, const std::vector<char>& held,
                                      const DeckGroup& group, const FundamentalPolygon& polygon,
                                      const FoldRepairOptions& options,
                                      const std::function<bool(int, double, double)>& progress) {
  FoldRepairResult out;
  SurfaceMapResult::FoldRepair& info = out.info;
  const int nv = source.num_vertices();
  for (double d : per_face) info.folded_faces += !std::isfinite(d);
  info.energy_before = energy_in_charts(edges, hr.edge_local);
  if (static_cast<int>(hr.vertex_deck_word.size()) != nv || hr.z.size() != static_cast<size_t>(nv) ||
      hr.edge_local.size() != edges.size()) {
    // The relaxation keeps no deck words: its chart moves cannot be composed exactly.
    info.status = "not repaired: the solve kept no vertex deck words (relaxation)";
    return out;
  }
  // The map being repaired: its flat but positive faces (one-to-one, D' ~1e9
  // or more) are tried too, but need not all open: a repair is accepted when
  // nothing folds, no more faces are flat than before, and something was
  // mended (a fold, or a flat face opened).
  const DistortionStats before = chart_distortion(source, sc, hr.edge_local, index);
  const int bad_before = before.flipped + before.degenerate;
  // Which source edge each solver edge is (-1: an edge of the intrinsic
  // triangulation only, which the own-edge problem does not have).
  std::vector<int> source_edge(edges.size(), -1);
  for (int e = 0; e < sc.num_edges(); ++e) source_edge[index.solver_edge[e]] = e;
  std::string last;
  HyperbolicHarmonicOptions ho;
  ho.tolerance = options.tolerance;
  ho.max_iterations = options.max_iterations;
  ho.relator = group.side_relator();
  ho.reduce_point = [&](Complex& p) { return polygon.reduce(p); };
  // The repaired map: points `z` in the sheets of `decks` (the edges'
  // elements unchanged) read back through a solve with every vertex held,
  // which gives its charts and its intrinsic energy; accepted when no face
  // folds there. `changed`: the vertices moved.
  auto accept = [&](const std::vector<Complex>& z, const std::vector<Word>& decks, const std::vector<char>& changed,
                    const std::string& method, int rings, double max_mean_rise = -1) {
    HyperbolicHarmonicOptions fixed = ho;
    fixed.fixed.assign(nv, 1);
    HyperbolicHarmonicResult r;
    try {
      r = solve_with_decks(nv, edges, z, decks, group, fixed);
    } catch (const Cancelled&) {
      throw;
    } catch (const Error& e) {
      last += "; " + method + ": " + e.what();
      return false;
    }
    const DistortionStats q = chart_distortion(source, sc, r.edge_local, index);
    if (q.flipped || q.degenerate > q.flat || q.flat > before.flat || q.flat >= bad_before) {
      last += "; " + method + ": " + std::to_string(q.flipped) + " flipped and " + std::to_string(q.degenerate) +
              " flat faces left in the solver's charts (" + std::to_string(q.flat) + " of them positive; " +
              std::to_string(before.flat) + " before)";
      return false;
    }
    if (max_mean_rise >= 0) {
      // The quality guard: the map's area-weighted mean D' against that of
      // the faces it did not change (the intrinsic map's).
      double all = 0, all_area = 0, kept = 0, kept_area = 0;
      for (int f = 0; f < source.num_faces(); ++f) {
        if (!std::isfinite(q.per_face[f])) continue;
        const Eigen::Vector3d p0 = source.V.row(source.F(f, 0)), p1 = source.V.row(source.F(f, 1)),
                              p2 = source.V.row(source.F(f, 2));
        const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
        all += area * q.per_face[f], all_area += area;
        if (!changed[source.F(f, 0)] && !changed[source.F(f, 1)] && !changed[source.F(f, 2)])
          kept += area * q.per_face[f], kept_area += area;
      }
      const double mean = all / all_area, kept_mean = kept / kept_area;
      if (!(mean <= (1 + max_mean_rise) * kept_mean)) {
        char text[200];
        std::snprintf(text, sizeof text, "mean D' %.3g, more than %.0f%% above the unchanged faces' %.3g", mean,
                      100 * max_mean_rise, kept_mean);
        last += "; " + method + ": " + text;
        return false;
      }
    }
    info.method = method;
    info.rings = rings;
    info.free_vertices = static_cast<int>(std::count(changed.begin(), changed.end(), 1));
    for (int f = 0; f < source.num_faces(); ++f)
      info.changed_faces += changed[source.F(f, 0)] || changed[source.F(f, 1)] || changed[source.F(f, 2)];
    r.energy = energy_in_charts(edges, r.edge_local);
    info.energy_after = r.energy;
    info.status = "repaired";
    out.map = std::move(r);
    return true;
  };
  // 1. The projection alone (few vertices, each within its own star).
  std::vector<Complex> projected;
  {
    std::vector<Complex> z;
    const std::vector<int> moved = project_folds(source, sc, index, hr, held, z, options.projection_rounds, &projected);
    std::vector<char> changed(nv, 0);
    for (int v : moved) changed[v] = 1;
    if (moved.empty())
      last = "projection: some fold has no corner whose neighbours' kernel is open";
    else if (accept(z, hr.vertex_deck_word, changed, "projection", 0))
      return out;
  }
  // 2. The distortion-aware untangling of what the projection left, on
  // growing rings around the folds left (every part of the region must
  // untangle), kept when the map's mean D' is not far above the unchanged
  // faces'.
  if (options.untangle_max_rings > 0) {
    KernelProjection sheets(source, sc, index, hr);
    sheets.set_points(projected);
    DistortionUntangler untangler(source, sc, sheets, options);
    for (int rings = options.first_rings; rings <= options.untangle_max_rings; rings *= 2) {
      int count = 0;
      const std::vector<char> free = fold_neighbourhood(source, sc, sheets, held, rings, count);
      if (count == 0) break;
      if (count > options.max_free_fraction * nv) {
        last += "; untangling: " + std::to_string(rings) + " rings free " + std::to_string(count) +
                " vertices (not local)";
        break;
      }
      ++info.tries;
      std::vector<Complex> z = projected;
      std::string why;
      int parts = 0;
      const int failed = untangler.untangle(free, z, parts, why);
      const std::string method = "untangling of " + std::to_string(rings) + " rings";
      if (failed) {
        last += "; " + method + ": " + std::to_string(failed) + " of " + std::to_string(parts) + " regions failed (" +
                why + ")";
        continue;
      }
      std::vector<char> changed = free;
      for (int v = 0; v < nv; ++v) changed[v] |= projected[v] != hr.z[v];
      if (accept(z, hr.vertex_deck_word, changed, method, rings, options.untangle_max_mean_rise)) return out;
    }
  }
  // 2. Held re-solves with own-edge weights on growing rings, each followed
  // by the projection where its region's rim still folds (the rim's faces
  // have held corners, and slivers there fold under the smallest move).
  std::vector<char> is_sliver(source.num_faces(), 0);
  for (int f = 0; f < source.num_faces(); ++f) {
    double smallest = M_PI;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d a = source.V.row(source.F(f, (k + 1) % 3)) - source.V.row(source.F(f, k));
      const Eigen::Vector3d b = source.V.row(source.F(f, (k + 2) % 3)) - source.V.row(source.F(f, k));
      smallest = std::min(smallest, std::atan2(a.cross(b).norm(), a.dot(b)));
    }
    is_sliver[f] = smallest < options.sliver_degrees * M_PI / 180;
  }
  int rings = options.first_rings;
  for (int t = 0; t < options.max_tries; ++t, rings *= 2) {
    int count = 0;
    std::vector<char> free = free_region(source, sc, per_face, held, rings, is_sliver, count);
    if (count == 0) {
      last += "; every corner of the folded faces is held";
      break;
    }
    if (count > options.max_free_fraction * nv) {
      last += "; " + std::to_string(rings) + " rings free " + std::to_string(count) + " of " + std::to_string(nv) +
              " vertices (more than " + std::to_string(static_cast<int>(100 * options.max_free_fraction + 0.5)) +
              "%: not local)";
      break;
    }
    ++info.tries;
    // The held solve: own-edge weights on the edges with a free end, none
    // elsewhere (the held vertices' terms are constant), the rest held.
    std::vector<WeightedEdge> local = edges;
    for (size_t e = 0; e < local.size(); ++e) {
      const bool touches = free[local[e].i] || free[local[e].j];
      local[e].w = touches && source_edge[e] >= 0 ? own.edges[source_edge[e]].cot_weight : 0.0;
    }
    HyperbolicHarmonicOptions hs = ho;
    hs.progress = progress;
    hs.fixed.assign(nv, 1);
    for (int v = 0; v < nv; ++v) hs.fixed[v] = !free[v];
    HyperbolicHarmonicResult r;
    try {
      r = solve_with_decks(nv, local, hr.z, hr.vertex_deck_word, group, hs);
    } catch (const Cancelled&) {
      throw;
    } catch (const Error& e) {
      last += "; " + std::to_string(rings) + " rings: the held solve failed (" + e.what() + ")";
      continue;
    }
    if (!r.converged) {
      last += "; " + std::to_string(rings) + " rings: the held solve did not converge";
      continue;
    }
    const std::string method = "held re-solve of " + std::to_string(rings) + " rings";
    if (accept(r.z, r.vertex_deck_word, free, method, rings)) return out;
    std::vector<Complex> z;
    const std::vector<int> moved = project_folds(source, sc, index, r, held, z, options.projection_rounds);
    if (moved.empty()) {
      last += "; " + method + ": the projection after it is stuck";
      continue;
    }
    for (int v : moved) free[v] = 1;
    if (accept(z, r.vertex_deck_word, free, method + " and projection", rings)) return out;
  }
  info.status = "not repaired: " + last;
  return out;
}

}  // namespace surfmap::detail
