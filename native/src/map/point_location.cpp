#include "surfmap/map/point_location.h"

#include <set>
#include <string>
#include <utility>

#include "surfmap/error.h"

namespace surfmap {
namespace {

using Complex = std::complex<double>;

// Best candidate triangle of the grid for z (largest smallest hyperboloid
// barycentric, at least -kInsideTolerance), or -1.
int exact_locate(const TriangleGrid& grid, const PlaneTriangles& tris, Complex z, Eigen::Vector3d* bary) {
  int best = -1;
  double best_min = -kInsideTolerance;
  for (int t : grid.candidates(hyperbolic::poincare_to_klein(z))) {
    double l[3];
    hyperbolic::triangle_barycentric(z, tris[t][0], tris[t][1], tris[t][2], l);
    const double m = std::min({l[0], l[1], l[2]});
    if (m >= best_min) best_min = m, best = t, *bary = Eigen::Vector3d(l[0], l[1], l[2]);
  }
  return best;
}

}  // namespace

int locate_in_cover(const TriangleGrid& grid, const PlaneTriangles& tris, const FundamentalPolygon& polygon, Complex z,
                    Eigen::Vector3d* bary) {
  polygon.reduce(z);
  const std::vector<hyperbolic::Mobius>& side_map = polygon.side_maps();
  const int nsides = polygon.num_sides();
  // Exhaustively up to two side maps (the usual case: the mesh's cut sides
  // bulge away from P's geodesic sides) ...
  int f = exact_locate(grid, tris, z, bary);
  for (int a1 = 0; f < 0 && a1 < nsides; ++a1) {
    const Complex w = side_map[a1].apply(z);
    f = exact_locate(grid, tris, w, bary);
    for (int a2 = 0; f < 0 && a2 < nsides; ++a2) f = exact_locate(grid, tris, side_map[a2].apply(w), bary);
  }
  if (f >= 0) return f;
  // ... then breadth first over longer words (around corners up to 4g),
  // pruning images that are far from P.
  std::vector<Complex> frontier{z};
  std::set<std::pair<long long, long long>> seen;
  auto key = [](Complex w) { return std::make_pair(std::llround(w.real() * 1e9), std::llround(w.imag() * 1e9)); };
  seen.insert(key(z));
  for (int depth = 1; depth <= nsides && !frontier.empty() && seen.size() < 20000; ++depth) {
    std::vector<Complex> next;
    for (Complex w : frontier)
      for (const auto& m : side_map) {
        const Complex q = m.apply(w);
        if (polygon.outside_by(q) > 0.5 || !seen.insert(key(q)).second) continue;
        if ((f = exact_locate(grid, tris, q, bary)) >= 0) return f;
        next.push_back(q);
      }
    frontier.swap(next);
  }
  return -1;
}

int locate_copies_in_frame(const TriangleGrid& grid, const PlaneTriangles& tris, const std::vector<Complex>& copies,
                           Eigen::Vector3d* bary) {
  int best = -1;
  double best_min = -kInsideTolerance;
  for (const Complex& z : copies) {
    Eigen::Vector3d b;
    const int f = exact_locate(grid, tris, z, &b);
    if (f >= 0 && b.minCoeff() >= best_min) best_min = b.minCoeff(), best = f, *bary = b;
  }
  return best;
}

int locate_in_face_charts(const FaceAtlas& atlas, int f, Complex q, int max_steps, hyperbolic::Mobius* moved,
                          Eigen::Vector3d* bary) {
  if (f < 0 || f >= atlas.num_faces()) throw InputError("locate_in_face_charts: face " + std::to_string(f) + " out of range");
  hyperbolic::Mobius product;
  auto corners = [&](int g) { return atlas.corners[g]; };
  auto cross = [&](int g, int side, Complex& c, Complex& p, int* entry) {
    const int t = atlas.twin[3 * g + side];
    const hyperbolic::Mobius& T = atlas.transition[t];  // g's coordinates -> face(t)'s
    c = T.apply(c), p = T.apply(p);
    product = (T * product).normalized();
    *entry = t % 3;
    return t / 3;
  };
  const int found = straight_walk(f, q, corners, cross, max_steps, kInsideTolerance, bary);
  if (found >= 0) *moved = product;
  return found;
}

int locate_periodic(const TriangleGrid& grid, Complex p, Complex centre, Complex w1, Complex w2, Eigen::Vector3d* bary) {
  const double det = w1.real() * w2.imag() - w1.imag() * w2.real();
  const Complex d = p - centre;
  const double alpha = (d.real() * w2.imag() - d.imag() * w2.real()) / det;
  const double beta = (w1.real() * d.imag() - w1.imag() * d.real()) / det;
  const Complex q = p - std::round(alpha) * w1 - std::round(beta) * w2;
  for (int ring = 0; ring <= 3; ++ring)
    for (int m = -ring; m <= ring; ++m)
      for (int n = -ring; n <= ring; ++n) {
        if (std::max(std::abs(m), std::abs(n)) != ring) continue;
        const int f = grid.locate(q + double(m) * w1 + double(n) * w2, bary);
        if (f >= 0) return f;
      }
  return -1;
}

}  // namespace surfmap
