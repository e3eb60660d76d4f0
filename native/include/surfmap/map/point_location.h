#pragma once
// Point location for the maps' outputs (docs/method.md §2.9: every vertex's image,
// and every target vertex's preimage, as a face and barycentrics): a uniform
// grid over planar triangles proposing candidates, a straight walk over a
// triangulation in the universal cover (hyperbolic), location modulo the
// fundamental polygon's side maps (hyperbolic) or modulo a lattice (flat).
// Used by the genus-1 and genus >= 2 pipelines alike.
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <vector>

#include <Eigen/Core>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/map/fundamental_polygon.h"
#include "surfmap/uniformize/layout.h"

namespace surfmap {

/// A point counts as inside a triangle when its smallest barycentric is at
/// least -kInsideTolerance.
constexpr double kInsideTolerance = 1e-9;

using PlaneTriangles = std::vector<std::array<std::complex<double>, 3>>;

// Uniform grid over triangles in the plane for point location, its dense
// cells refined into sub-grids (a quadtree-like hierarchy, subdivide_dense_cells).
class TriangleGrid {
 public:
  /// `margin`: bounding boxes are widened by this much (absolute) when
  /// binning, so that candidates() misses no triangle whose exact test
  /// (done by the caller in better coordinates) would accept the point.
  TriangleGrid(const std::vector<std::array<std::complex<double>, 3>>& tris, double margin = 0) : tris_(tris) {
    double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300, perimeter = 0;
    for (const auto& t : tris_)
      for (int k = 0; k < 3; ++k) {
        xmin = std::min(xmin, t[k].real()), xmax = std::max(xmax, t[k].real());
        ymin = std::min(ymin, t[k].imag()), ymax = std::max(ymax, t[k].imag());
        perimeter += std::abs(t[(k + 1) % 3] - t[k]);
      }
    cell_ = std::max(perimeter / (3.0 * std::max<size_t>(tris_.size(), 1)), 1e-300) * 2.0;
    x0_ = xmin, y0_ = ymin;
    nx_ = std::max(1, static_cast<int>((xmax - xmin) / cell_) + 1);
    ny_ = std::max(1, static_cast<int>((ymax - ymin) / cell_) + 1);
    if (static_cast<double>(nx_) * ny_ > 8.0 * tris_.size() + 64) {  // keep memory bounded
      const double s = std::sqrt(static_cast<double>(nx_) * ny_ / (8.0 * tris_.size() + 64));
      cell_ *= s;
      nx_ = std::max(1, static_cast<int>((xmax - xmin) / cell_) + 1);
      ny_ = std::max(1, static_cast<int>((ymax - ymin) / cell_) + 1);
    }
    cells_.assign(static_cast<size_t>(nx_) * ny_, {});
    for (int i = 0; i < static_cast<int>(tris_.size()); ++i) {
      const auto& t = tris_[i];
      const int ix0 = cx(std::min({t[0].real(), t[1].real(), t[2].real()}) - margin);
      const int ix1 = cx(std::max({t[0].real(), t[1].real(), t[2].real()}) + margin);
      const int iy0 = cy(std::min({t[0].imag(), t[1].imag(), t[2].imag()}) - margin);
      const int iy1 = cy(std::max({t[0].imag(), t[1].imag(), t[2].imag()}) + margin);
      for (int x = ix0; x <= ix1; ++x)
        for (int y = iy0; y <= iy1; ++y) cells_[static_cast<size_t>(y) * nx_ + x].push_back(i);
    }
    child_.assign(cells_.size(), -1);
    subdivide_dense_cells(margin, xmax, ymax);
  }
  /// Triangle containing p (largest minimum barycentric >= -tol) or -1.
  int locate(std::complex<double> p, Eigen::Vector3d* bary, double tol = 1e-9) const {
    int best = -1;
    double best_min = -tol;
    for (int i : candidates(p)) {
      const Eigen::Vector3d b = barycentric(tris_[i], p);
      if (b.minCoeff() >= best_min) best_min = b.minCoeff(), best = i, *bary = b;
    }
    return best;
  }
  /// Triangles whose (widened) bounding box may contain p; empty outside the grid.
  const std::vector<int>& candidates(std::complex<double> p) const {
    static const std::vector<int> none;
    const double fx = (p.real() - x0_) / cell_, fy = (p.imag() - y0_) / cell_;
    if (!(fx >= 0 && fy >= 0 && fx < nx_ && fy < ny_)) return none;
    size_t c = static_cast<size_t>(fy) * nx_ + static_cast<int>(fx);
    while (child_[c] >= 0) {  // down the sub-grids of dense cells
      const std::array<double, 4>& g = split_box_[child_[c] / (kSplit * kSplit)];
      const int jx = std::clamp(static_cast<int>((p.real() - g[0]) / g[2] * kSplit), 0, kSplit - 1);
      const int jy = std::clamp(static_cast<int>((p.imag() - g[1]) / g[3] * kSplit), 0, kSplit - 1);
      c = static_cast<size_t>(nx_) * ny_ + static_cast<size_t>(child_[c]) + static_cast<size_t>(jy) * kSplit + jx;
    }
    return cells_[c];
  }
  static Eigen::Vector3d barycentric(const std::array<std::complex<double>, 3>& t, std::complex<double> p) {
    auto cross = [](std::complex<double> a, std::complex<double> b) { return a.real() * b.imag() - a.imag() * b.real(); };
    const double area = cross(t[1] - t[0], t[2] - t[0]);
    return Eigen::Vector3d(cross(t[1] - p, t[2] - p), cross(t[2] - p, t[0] - p), cross(t[0] - p, t[1] - p)) / area;
  }

 private:
  int cx(double x) const { return std::clamp(static_cast<int>((x - x0_) / cell_), 0, nx_ - 1); }
  int cy(double y) const { return std::clamp(static_cast<int>((y - y0_) / cell_), 0, ny_ - 1); }
  // Cells holding more than kDense triangles get kSplit x kSplit sub-cells,
  // recursively (issue 19). Why: the cell size follows the mean triangle, but
  // in the Klein model the triangles near a corner of P, close to |z| = 1,
  // are thousands of times smaller than those at the centre, so a few cells
  // held ~7000 triangles each and locating the 50k genus-2 pair's target
  // vertices tested 36M candidates. A split that separates nothing (a
  // sub-cell gets every triangle) or copies the triangles into more than 3
  // sub-cells each on average (long slivers: a row of sub-cells at every
  // level) is undone, and the sub-grids hold at most kMaxEntries entries
  // per triangle in all (graded square of test_point_location.cpp, 80k
  // triangles: built in 0.13 s, at most 84 candidates per point).
  static constexpr int kSplit = 4, kDense = 24, kMaxDepth = 10;
  static constexpr size_t kMaxEntries = 8;
  size_t total_entries_ = 0;
  // A top cell is split over its part of the triangles' box (the last row
  // and column of cells overhang it).
  void subdivide_dense_cells(double margin, double xmax, double ymax) {
    struct Pending {
      size_t cell;
      double x0, y0, sx, sy;
      int depth;
    };
    std::vector<Pending> todo;
    for (int iy = 0; iy < ny_; ++iy)
      for (int ix = 0; ix < nx_; ++ix) {
        const double x0 = x0_ + ix * cell_, y0 = y0_ + iy * cell_;
        todo.push_back({static_cast<size_t>(iy) * nx_ + ix, x0, y0, std::clamp(xmax - x0, 1e-300, cell_),
                        std::clamp(ymax - y0, 1e-300, cell_), 0});
      }
    while (!todo.empty()) {
      const Pending p = todo.back();
      todo.pop_back();
      if (cells_[p.cell].size() <= static_cast<size_t>(kDense) || p.depth >= kMaxDepth) continue;
      const std::vector<int> tris = std::move(cells_[p.cell]);
      const double subx = p.sx / kSplit, suby = p.sy / kSplit;
      auto at = [&](double v, double o, double sub) {
        return std::clamp(static_cast<int>(std::floor((v - o) / sub)), 0, kSplit - 1);
      };
      std::vector<std::vector<int>> children(kSplit * kSplit);
      for (int i : tris) {
        const auto& t = tris_[i];
        const int ix0 = at(std::min({t[0].real(), t[1].real(), t[2].real()}) - margin, p.x0, subx);
        const int ix1 = at(std::max({t[0].real(), t[1].real(), t[2].real()}) + margin, p.x0, subx);
        const int iy0 = at(std::min({t[0].imag(), t[1].imag(), t[2].imag()}) - margin, p.y0, suby);
        const int iy1 = at(std::max({t[0].imag(), t[1].imag(), t[2].imag()}) + margin, p.y0, suby);
        for (int y = iy0; y <= iy1; ++y)
          for (int x = ix0; x <= ix1; ++x) children[static_cast<size_t>(y) * kSplit + x].push_back(i);
      }
      size_t largest = 0, entries = 0;
      for (const auto& c : children) largest = std::max(largest, c.size()), entries += c.size();
      if (largest >= tris.size() || entries > 3 * tris.size() ||
          total_entries_ + entries > kMaxEntries * (tris_.size() + 64)) {
        cells_[p.cell] = tris;
        continue;
      }
      total_entries_ += entries;
      const size_t first = cells_.size();
      child_[p.cell] = static_cast<int>(first - static_cast<size_t>(nx_) * ny_);
      split_box_.push_back({p.x0, p.y0, p.sx, p.sy});
      for (int k = 0; k < kSplit * kSplit; ++k) {
        cells_.push_back(std::move(children[k]));
        child_.push_back(-1);
        todo.push_back({first + k, p.x0 + (k % kSplit) * subx, p.y0 + (k / kSplit) * suby, subx, suby, p.depth + 1});
      }
    }
  }
  const std::vector<std::array<std::complex<double>, 3>>& tris_;
  double cell_ = 1, x0_ = 0, y0_ = 0;
  int nx_ = 1, ny_ = 1;
  std::vector<std::vector<int>> cells_;  ///< the nx x ny top cells, then every sub-grid's kSplit^2 cells
  /// per cell: its first sub-cell's index past the top cells (a multiple of
  /// kSplit^2), or -1 (a leaf)
  std::vector<int> child_;
  /// per split cell (k-th split: sub-cells from k kSplit^2): x0, y0, width, height
  std::vector<std::array<double, 4>> split_box_;
};

// Point location by a straight walk in the universal cover: from a point
// inside face f along the geodesic towards q, face by face. corners(f) gives
// face f's three corners in its own frame (counter-clockwise); cross(f, s,
// c, q) returns the face across side s (corner s -> s+1) and moves the two
// points into that face's frame. The geodesic is straight in the Klein
// model, and every test runs in the chart centring q, so tiny triangles near
// |z| = 1 keep their digits; following the segment (rather than the most
// violated side) cannot cycle on a triangulation with long thin triangles.
// Returns the face with q's hyperboloid barycentrics, or -1.
/// (Template: corners and cross are the caller's lambdas over its own faces.)
template <class Corners, class Cross>
int straight_walk(int f, std::complex<double> q, const Corners& corners, const Cross& cross, int max_steps, double tol,
                  Eigen::Vector3d* bary) {
  auto orient = [](std::complex<double> a, std::complex<double> b, std::complex<double> c) {
    return (b.real() - a.real()) * (c.imag() - a.imag()) - (b.imag() - a.imag()) * (c.real() - a.real());
  };
  std::array<std::complex<double>, 3> t = corners(f);
  std::complex<double> c = hyperbolic::geodesic_point(t[0], hyperbolic::midpoint(t[1], t[2]), 2.0 / 3.0);
  int entry = -1;
  for (int step = 0; step < max_steps; ++step) {
    double l[3];
    hyperbolic::triangle_barycentric(q, t[0], t[1], t[2], l);
    if (std::min({l[0], l[1], l[2]}) >= -tol) {
      *bary = Eigen::Vector3d(l[0], l[1], l[2]);
      return f;
    }
    std::complex<double> k[3];
    for (int i = 0; i < 3; ++i) k[i] = hyperbolic::poincare_to_klein(hyperbolic::centred(q, t[i]));
    const std::complex<double> kc = hyperbolic::poincare_to_klein(hyperbolic::centred(q, c));
    // Exit side: crossed by the segment c -> q (q is the origin here), with q
    // beyond it; else the side opposite the most negative barycentric.
    int exit = -1;
    double best = 0;
    for (int s = 0; s < 3; ++s) {
      if (s == entry) continue;
      const std::complex<double> p0 = k[s], p1 = k[(s + 1) % 3];
      const double o0 = orient(kc, std::complex<double>(0.0), p0), o1 = orient(kc, std::complex<double>(0.0), p1);
      const double beyond = orient(p0, p1, std::complex<double>(0.0));
      if (o0 * o1 <= 0 && beyond < 0 && beyond < best) best = beyond, exit = s;
    }
    if (exit < 0) {
      int worst = 0;
      for (int i = 1; i < 3; ++i)
        if (l[i] < l[worst]) worst = i;
      exit = (worst + 1) % 3;  // the side opposite corner `worst`
    }
    int g_entry = -1;
    const int g = cross(f, exit, c, q, &g_entry);
    if (g < 0 || !(std::abs(q) < 1) || !(std::abs(c) < 1)) return -1;
    f = g;
    entry = g_entry;
    t = corners(f);
  }
  return -1;
}


/// Hyperbolic location in the cover: the triangle of `tris` (#T corners in
/// the Poincaré disk; `grid` built over their Klein images) containing z or
/// one of its images under P's side maps. z is first reduced into P; the
/// mesh regions differ from P only near its sides and corners, so the
/// containing triangle holds an image of z under side maps that keep it
/// near P (around a corner up to 4g of them): exhaustively up to two side
/// maps, then breadth first over longer words, pruning images more than 0.5
/// Klein units outside P. Barycentrics are those of the hyperboloid model
/// in the chart centring the query (exact to round-off for tiny triangles
/// near |z| = 1; the Klein grid only proposes candidates). Returns the
/// triangle index with `bary`, or -1.
int locate_in_cover(const TriangleGrid& grid, const PlaneTriangles& tris, const FundamentalPolygon& polygon,
                    std::complex<double> z, Eigen::Vector3d* bary);

/// Hyperbolic location of a point known by its copies in one frame (e.g. a
/// target vertex's copies in its cut disk: 1 inside, 2 on a loop, 4g at
/// the base vertex), with no group element applied: the triangle of `tris`
/// (#T corners in the Poincaré disk; `grid` over their Klein images) that
/// contains one of `copies` with the largest smallest hyperboloid
/// barycentric (>= -kInsideTolerance), and that barycentric, or -1. Why:
/// at a corner of a long, thin fundamental polygon the side maps have
/// entries of 1e3 and more and send points to within 1e-10 of |z| = 1, so a
/// walk or a search that moves the query by them can end a visible distance
/// from every copy (docs/verification.md); the copies themselves are exact.
int locate_copies_in_frame(const TriangleGrid& grid, const PlaneTriangles& tris,
                           const std::vector<std::complex<double>>& copies, Eigen::Vector3d* bary);

/// Location in per-face charts (issue 13; uniformize/layout.h FaceAtlas):
/// the straight walk above from face f towards q, a point given in f's
/// canonical chart, crossing faces by the atlas's transitions, so the walk
/// needs no global chart. Returns the face containing q (hyperboloid
/// barycentrics in `bary`, smallest >= -kInsideTolerance) and in `moved` the
/// product of the transitions crossed (f's canonical coordinates -> the
/// returned face's), or -1 when max_steps faces do not reach it.
int locate_in_face_charts(const FaceAtlas& atlas, int f, std::complex<double> q, int max_steps,
                          hyperbolic::Mobius* moved, Eigen::Vector3d* bary);

/// Flat location: p modulo the lattice (w1, w2) in `grid` (Euclidean
/// barycentrics): p reduced to the parallelogram around `centre`, then the
/// translates in rings up to 3 lattice steps. Returns the triangle or -1.
int locate_periodic(const TriangleGrid& grid, std::complex<double> p, std::complex<double> centre,
                    std::complex<double> w1, std::complex<double> w2, Eigen::Vector3d* bary);

}  // namespace surfmap
