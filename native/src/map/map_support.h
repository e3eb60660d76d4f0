#pragma once
// Internal pieces shared by the flat (genus 1) and hyperbolic (genus >= 2)
// surface-map paths: the uniformized target, the source's unrefined loops,
// point location in laid-out triangles and points expressed on the input
// meshes. Not part of the public API.
#include <algorithm>
#include <array>
#include <complex>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/layout.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {
struct HyperbolicInitialMapResult;
}

namespace surfmap::detail {

/// Copies the construction and polygon figures of a genus >= 2 initial map.
void set_initial_map_info(const HyperbolicInitialMapResult& init, InitialMapInfo& info);

using Complex = std::complex<double>;
/// Records the end of a stage (name, overall fraction) and may throw Cancelled.
using StageDone = std::function<void(const std::string&, double)>;

/// The point with (clamped, renormalised) barycentrics b in face f of m.
PointOnSurface point_in_face(const TriMesh& m, int f, Eigen::Vector3d b);

/// A point given in face rf of the refined mesh s.mesh, expressed on the input
/// mesh (face + barycentrics). `cache` (#F refined, initially -1) remembers the
/// input face of each refined face.
PointOnSurface point_on_input(const TriMesh& input, const Connectivity& ic, const SystemOfLoops& s,
                              std::vector<int>& cache, int rf, const Eigen::Vector3d& b);

/// The target laid out in its uniformization metric: system of loops (refined,
/// as the layout needs simple loops), Ricci flow, disk layout.
struct UniformizedTarget {
  SystemOfLoops loops;
  DiskLayout layout;
  /// Exact splits added so that the metric exists (0: none were needed) and
  /// the max-angle bound used (uniformize/feasible_metric.h).
  int refinement_splits = 0;
  double refinement_max_angle = 0;
};

UniformizedTarget uniformized_target(const TriMesh& target, Background background, const SurfaceMapOptions& options);

/// The source's unrefined system of loops: it keeps the source's own
/// connectivity, and contracting its tree gives a one-vertex schema.
SystemOfLoops source_loops(const TriMesh& source, const SurfaceMapOptions& options);

// Uniform grid over triangles in the plane for point location.
class TriangleGrid {
 public:
  /// `margin`: bounding boxes are widened by this much (absolute) when
  /// binning, so that candidates() misses no triangle whose exact test
  /// (done by the caller in better coordinates) would accept the point.
  TriangleGrid(const std::vector<std::array<Complex, 3>>& tris, double margin = 0) : tris_(tris) {
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
  }
  /// Triangle containing p (largest minimum barycentric >= -tol) or -1.
  int locate(Complex p, Eigen::Vector3d* bary, double tol = 1e-9) const {
    const double fx = (p.real() - x0_) / cell_, fy = (p.imag() - y0_) / cell_;
    if (fx < 0 || fy < 0 || fx >= nx_ || fy >= ny_) return -1;
    int best = -1;
    double best_min = -tol;
    for (int i : cells_[static_cast<size_t>(fy) * nx_ + static_cast<int>(fx)]) {
      const Eigen::Vector3d b = barycentric(tris_[i], p);
      if (b.minCoeff() >= best_min) best_min = b.minCoeff(), best = i, *bary = b;
    }
    return best;
  }
  /// Triangles whose (widened) bounding box may contain p; empty outside the grid.
  const std::vector<int>& candidates(Complex p) const {
    static const std::vector<int> none;
    const double fx = (p.real() - x0_) / cell_, fy = (p.imag() - y0_) / cell_;
    if (!(fx >= 0 && fy >= 0 && fx < nx_ && fy < ny_)) return none;
    return cells_[static_cast<size_t>(fy) * nx_ + static_cast<int>(fx)];
  }
  static Eigen::Vector3d barycentric(const std::array<Complex, 3>& t, Complex p) {
    auto cross = [](Complex a, Complex b) { return a.real() * b.imag() - a.imag() * b.real(); };
    const double area = cross(t[1] - t[0], t[2] - t[0]);
    return Eigen::Vector3d(cross(t[1] - p, t[2] - p), cross(t[2] - p, t[0] - p), cross(t[0] - p, t[1] - p)) / area;
  }

 private:
  int cx(double x) const { return std::clamp(static_cast<int>((x - x0_) / cell_), 0, nx_ - 1); }
  int cy(double y) const { return std::clamp(static_cast<int>((y - y0_) / cell_), 0, ny_ - 1); }
  const std::vector<std::array<Complex, 3>>& tris_;
  double cell_ = 1, x0_ = 0, y0_ = 0;
  int nx_ = 1, ny_ = 1;
  std::vector<std::vector<int>> cells_;
};

/// Genus 1 (flat target): fills `out` (DESIGN.md §2.8, exact sparse solve).
void map_flat(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
              const SurfaceMapOptions& options, SurfaceMapResult& out, const StageDone& stage_done);

/// Genus 0 (through the unit sphere): fills `out` (map/spherical_map.h).
void map_spherical(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                   const SurfaceMapOptions& options, SurfaceMapResult& out, const StageDone& stage_done);

/// Genus >= 2 (hyperbolic target): fills `out` (Riemannian Newton, DESIGN.md §7).
void map_hyperbolic(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                    const SurfaceMapOptions& options, SurfaceMapResult& out, const StageDone& stage_done);

}  // namespace surfmap::detail
