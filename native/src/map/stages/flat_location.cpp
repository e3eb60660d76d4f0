#include "flat_location.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "surfmap/error.h"
#include "surfmap/map/point_location.h"

namespace surfmap::detail {
namespace {

// A point that locate_periodic misses because it lies in a crack between
// glued copies of the disk: the layout's round-off (~1e-10) at a corner of
// the tiny refined triangles where the loops fan out of their base vertex,
// where 1e-10 is more than the barycentric tolerance. The triangle of the
// lattice copies nearest to it (clamped barycentrics) when it is within
// 1e-8 of the lattice's scale; otherwise -1.
int locate_in_crack(const TriangleGrid& grid, const std::vector<std::array<Complex, 3>>& ttris, Complex p,
                    Complex centre, Complex w1, Complex w2, Eigen::Vector3d* bary) {
  const double det = w1.real() * w2.imag() - w1.imag() * w2.real();
  const Complex d = p - centre;
  const double alpha = (d.real() * w2.imag() - d.imag() * w2.real()) / det;
  const double beta = (w1.real() * d.imag() - w1.imag() * d.real()) / det;
  const Complex q0 = p - std::round(alpha) * w1 - std::round(beta) * w2;
  const double accept = 1e-8 * std::max(std::abs(w1), std::abs(w2));
  double best = accept;
  int best_f = -1;
  for (int m = -3; m <= 3; ++m)
    for (int n = -3; n <= 3; ++n) {
      const Complex q = q0 + double(m) * w1 + double(n) * w2;
      for (int f : grid.candidates(q)) {
        Eigen::Vector3d b = TriangleGrid::barycentric(ttris[f], q).cwiseMax(0.0);
        if (!(b.sum() > 0)) continue;
        b /= b.sum();
        const double dist = std::abs(b[0] * ttris[f][0] + b[1] * ttris[f][1] + b[2] * ttris[f][2] - q);
        if (dist <= best) best = dist, best_f = f, *bary = b;
      }
    }
  return best_f;
}

// The barycentrics of the long double point `pl` (whose rounding `p` was
// located in triangle `tri` with barycentrics `b`), on the same lattice
// translate, computed in long double. Why: source triangles crowded to
// ~1e-14 of the torus have images of a few ulps of the double coordinates;
// barycentrics from the extended point keep their shapes to the rounding of
// the barycentrics themselves (docs/robustness.md, "The source side").
Eigen::Vector3d extended_barycentric(const std::array<Complex, 3>& tri, const Eigen::Vector3d& b, Complex p,
                                     const std::complex<long double>& pl, Complex w1, Complex w2) {
  using LD = long double;
  using CL = std::complex<LD>;
  const Complex s = b[0] * tri[0] + b[1] * tri[1] + b[2] * tri[2] - p;  // ~ the lattice vector moved by
  const double det = w1.real() * w2.imag() - w1.imag() * w2.real();
  const double m = std::round((s.real() * w2.imag() - s.imag() * w2.real()) / det);
  const double n = std::round((w1.real() * s.imag() - w1.imag() * s.real()) / det);
  const CL q = pl + LD(m) * CL(w1) + LD(n) * CL(w2);
  auto cross = [](const CL& a, const CL& c) { return a.real() * c.imag() - a.imag() * c.real(); };
  const CL t0(tri[0]), t1(tri[1]), t2(tri[2]);
  const LD area = cross(t1 - t0, t2 - t0);
  const Eigen::Vector3d bl(static_cast<double>(cross(t1 - q, t2 - q) / area),
                           static_cast<double>(cross(t2 - q, t0 - q) / area),
                           static_cast<double>(cross(t0 - q, t1 - q) / area));
  // Only a refinement of the double location: same triangle, same sign pattern within rounding.
  if (!bl.allFinite() || (bl - b).cwiseAbs().maxCoeff() > 1e-6) return b;
  return bl;
}

}  // namespace

FlatLocationResult locate_flat_map(const TriMesh& source, const TriMesh& target, const Connectivity& tc,
                                   const SystemOfLoops& target_loops, const TargetIntrinsic* target_intrinsic,
                                   const DiskLayout& layout, Complex w1, Complex w2,
                                   const std::vector<Complex>& z, const std::vector<std::complex<long double>>* z_extended,
                                   const std::vector<Complex>& z_init,
                                   const Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>& image,
                                   const Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>& initial_image,
                                   bool locate_initial, const StageDone& stage_done) {
  FlatLocationResult out;
  // Forward map: locate every z_i in the target's disk (modulo the lattice).
  const int n = source.num_vertices();
  const int ntf = target_loops.mesh.num_faces();
  std::vector<std::array<Complex, 3>> ttris(ntf);
  Complex centre = 0;
  for (int f = 0; f < ntf; ++f) {
    for (int k = 0; k < 3; ++k) ttris[f][k] = layout.corners(f, k);
    centre += (ttris[f][0] + ttris[f][1] + ttris[f][2]) / 3.0;
  }
  centre /= double(ntf);
  const TriangleGrid tgrid(ttris);
  std::vector<int> refined_face_origin(ntf, -1);
  out.forward.resize(n);
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d b;
    int rf = locate_periodic(tgrid, z[i], centre, w1, w2, &b);
    if (rf >= 0 && z_extended) b = extended_barycentric(ttris[rf], b, z[i], (*z_extended)[i], w1, w2);
    if (rf < 0) rf = locate_in_crack(tgrid, ttris, z[i], centre, w1, w2, &b);
    if (rf < 0) throw SolveError("source vertex " + std::to_string(i) + " could not be located on the target");
    out.forward[i] = point_on_input(target, tc, target_loops, target_intrinsic, refined_face_origin, rf, b);
  }
  // The initial (uniform Tutte) map located the same way ("before" morph).
  if (locate_initial) out.initial_forward.resize(n);
  for (int i = 0; locate_initial && i < n; ++i) {
    Eigen::Vector3d b;
    int rf = locate_periodic(tgrid, z_init[i], centre, w1, w2, &b);
    if (rf < 0) rf = locate_in_crack(tgrid, ttris, z_init[i], centre, w1, w2, &b);
    if (rf < 0) {
      out.initial_forward.clear();  // left unlocated, not an error
      break;
    }
    out.initial_forward[i] = point_on_input(target, tc, target_loops, target_intrinsic, refined_face_origin, rf, b);
  }
  stage_done("forward location", 0.85);

  // Inverse map: locate every target vertex in the image of the source
  // triangles `im`; false (and `inv` emptied) if one is not covered.
  auto locate_inverse = [&](const Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>& im,
                            std::vector<PointOnSurface>& inv, int* missed) {
    std::vector<std::array<Complex, 3>> stris(source.num_faces());
    Complex scentre = 0;
    for (int f = 0; f < source.num_faces(); ++f) {
      for (int k = 0; k < 3; ++k) stris[f][k] = im(f, k);
      scentre += (stris[f][0] + stris[f][1] + stris[f][2]) / 3.0;
    }
    scentre /= double(source.num_faces());
    const TriangleGrid sgrid(stris);
    inv.resize(target.num_vertices());
    for (int v = 0; v < target.num_vertices(); ++v) {
      Eigen::Vector3d b;
      const int f = locate_periodic(sgrid, layout.vertex_positions[v], scentre, w1, w2, &b);
      if (f < 0) {
        inv.clear();
        *missed = v;
        return false;
      }
      inv[v] = point_in_face(source, f, b);
    }
    return true;
  };
  int missed = -1;
  if (!locate_inverse(image, out.inverse, &missed))
    throw SolveError("target vertex " + std::to_string(missed) + " could not be located in the source image");
  // The initial map's inverse the same way (the "before" UV transfer); left
  // empty, not an error, when a target vertex is not covered.
  if (locate_initial) locate_inverse(initial_image, out.initial_inverse, &missed);
  return out;
}

}  // namespace surfmap::detail
