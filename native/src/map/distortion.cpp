#include "surfmap/map/distortion.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <tuple>

#include <Eigen/Dense>

#include "surfmap/geometry/hyperbolic.h"

namespace surfmap {
namespace {

// Corners of a planar triangle with the given sides: c0 = 0, c1 on the x axis.
Eigen::Matrix2d frame_from_sides(const Eigen::Vector3d& s) {
  const double a = s[0], b = s[1], c = s[2];  // |c0c1|, |c1c2|, |c2c0|
  if (!(a > 0)) return Eigen::Matrix2d::Zero();  // coincident corners: degenerate (D' infinite)
  const double x = (a * a + c * c - b * b) / (2 * a);
  const double y = std::sqrt(std::max(c * c - x * x, 0.0));
  Eigen::Matrix2d E;  // columns: c1 - c0, c2 - c0
  E << a, x, 0, y;
  return E;
}

double dilatation_of(const Eigen::Matrix2d& src, const Eigen::Matrix2d& img) {
  if (std::abs(src.determinant()) <= 0) return std::numeric_limits<double>::infinity();
  const Eigen::Matrix2d A = img * src.inverse();
  Eigen::JacobiSVD<Eigen::Matrix2d> svd(A);
  const auto s = svd.singularValues();
  if (!(s[1] > 0)) return std::numeric_limits<double>::infinity();
  return s[0] / s[1];
}

}  // namespace

std::vector<char> thin_source_faces(const RowMatrixX3d& V, const RowMatrixX3i& F, double relative_margin) {
  const int nf = static_cast<int>(F.rows());
  std::vector<char> thin(nf, 0);
  if (nf == 0) return thin;
  std::vector<double> margin(nf);
  double sum = 0;
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d p0 = V.row(F(f, 0)), p1 = V.row(F(f, 1)), p2 = V.row(F(f, 2));
    const double a = (p1 - p0).norm(), b = (p2 - p1).norm(), c = (p0 - p2).norm();
    margin[f] = std::min({a + b - c, b + c - a, c + a - b});
    sum += a + b + c;
  }
  // On a closed mesh every edge is a side of two faces: the mean side is the
  // mean edge length mollify_edge_lengths measures its margin against.
  const double delta = relative_margin * sum / (3.0 * nf);
  for (int f = 0; f < nf; ++f) thin[f] = !(margin[f] >= delta);
  return thin;
}

double triangle_dilatation(const Eigen::Vector3d& source_sides, const Eigen::Vector3d& image_sides) {
  return dilatation_of(frame_from_sides(source_sides), frame_from_sides(image_sides));
}

int image_orientation(std::complex<double> b, std::complex<double> c) {
  const double cross = b.real() * c.imag() - b.imag() * c.real();
  if (!(std::abs(cross) > kFlatImageRelativeCross * std::max(std::norm(b), std::norm(c)))) return 0;
  return cross < 0 ? -1 : 1;
}

double hyperbolic_face_dilatation(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                                  std::complex<double> b, std::complex<double> cc, const Eigen::Vector3d& is,
                                  bool thin_images) {
  using Complex = std::complex<double>;
  const Eigen::Vector3d ss((p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm());
  if (!thin_images) return triangle_dilatation(ss, is);
  const double defect = std::min({is[0] + is[1] - is[2], is[1] + is[2] - is[0], is[2] + is[0] - is[1]});
  double d = defect > 1e-4 * is.sum() ? triangle_dilatation(ss, is) : std::numeric_limits<double>::infinity();
  if (!std::isfinite(d)) {
    const Complex m = hyperbolic::klein_to_poincare(
        (hyperbolic::poincare_to_klein(b) + hyperbolic::poincare_to_klein(cc)) / 3.0);
    const Complex w0 = hyperbolic::centred(m, Complex(0.0)), w1 = hyperbolic::centred(m, b) - w0,
                  w2 = hyperbolic::centred(m, cc) - w0;
    const Eigen::Vector3d e1 = p1 - p0, e2 = p2 - p0;
    const double l1 = e1.norm();
    Eigen::Matrix2d S, I;
    S << l1, e2.dot(e1) / l1, 0, e1.cross(e2).norm() / l1;
    I << w1.real(), w2.real(), w1.imag(), w2.imag();
    const Eigen::Matrix2d A = I * S.inverse();
    const double q = A.squaredNorm() / std::abs(A.determinant());
    d = 0.5 * (q + std::sqrt(std::max(q * q - 4.0, 0.0)));
  }
  return d;
}

int widest_corner(const Eigen::Vector3d& sides) {
  if (!sides.allFinite()) return 0;
  int longest = 0;
  for (int k = 1; k < 3; ++k)
    if (sides[k] > sides[longest]) longest = k;
  return (longest + 2) % 3;
}

DistortionStats hyperbolic_image_distortion(
    const TriMesh& source,
    const std::function<std::pair<std::complex<double>, std::complex<double>>(int f)>& image_in_chart,
    const std::function<Eigen::Vector3d(int f)>& image_sides, bool thin_images,
    const std::function<std::pair<std::complex<double>, std::complex<double>>(int f, int corner)>&
        image_in_corner_chart) {
  const int nf = source.num_faces();
  DistortionStats out;
  out.per_face.assign(nf, std::numeric_limits<double>::infinity());
  const std::vector<char> thin = thin_source_faces(source.V, source.F);
  double weighted = 0, total_area = 0;
  for (int f = 0; f < nf; ++f) {
    // A zero-area source face (accepted through mollification) has no D':
    // left out of mean and max and counted, as in planar_distortion.
    {
      const Eigen::Vector3d q0 = source.V.row(source.F(f, 0)), q1 = source.V.row(source.F(f, 1)),
                            q2 = source.V.row(source.F(f, 2));
      const double longest = std::max({(q1 - q0).norm(), (q2 - q1).norm(), (q0 - q2).norm()});
      if (!(0.5 * (q1 - q0).cross(q2 - q0).norm() > 1e-14 * longest * longest)) {
        ++out.degenerate_source;
        out.thin_source.push_back(f);
        continue;
      }
    }
    auto [b, c] = image_in_chart(f);
    int orientation = image_orientation(b, c);
    // The corner the face is read from (image_in_corner_chart); its sides, read once.
    int r = 0;
    std::optional<Eigen::Vector3d> sides;
    if (orientation != 1 && image_in_corner_chart) {
      sides = image_sides(f);
      r = widest_corner(*sides);
      if (r != 0) {
        std::tie(b, c) = image_in_corner_chart(f, r);
        orientation = image_orientation(b, c);
      }
    }
    if (orientation == 0) {
      ++out.degenerate;
      const double cross = b.real() * c.imag() - b.imag() * c.real();
      if (cross > kRoundOffRelativeCross * std::max(std::norm(b), std::norm(c))) ++out.flat;
      continue;
    }
    if (orientation < 0) {
      ++out.flipped;
      continue;
    }
    const Eigen::Vector3d p0 = source.V.row(source.F(f, r)), p1 = source.V.row(source.F(f, (r + 1) % 3)),
                          p2 = source.V.row(source.F(f, (r + 2) % 3));
    if (!sides) sides = image_sides(f);
    const Eigen::Vector3d& l = *sides;
    const Eigen::Vector3d sides_from_r(l[r], l[(r + 1) % 3], l[(r + 2) % 3]);
    const double d = hyperbolic_face_dilatation(p0, p1, p2, b, c, sides_from_r, thin_images);
    out.per_face[f] = d;
    if (thin[f]) {
      out.thin_source.push_back(f);
      if (std::isfinite(d)) out.thin_source_max = std::max(out.thin_source_max, d);
      continue;
    }
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    weighted += area * d;
    total_area += area;
    out.max = std::max(out.max, d);
  }
  out.mean = total_area > 0 ? weighted / total_area : std::numeric_limits<double>::infinity();
  return out;
}

DistortionStats planar_distortion(const RowMatrixX3d& V, const RowMatrixX3i& F,
                                  const Eigen::Matrix<std::complex<double>, Eigen::Dynamic, 3, Eigen::RowMajor>& image) {
  DistortionStats out;
  const int nf = static_cast<int>(F.rows());
  out.per_face.assign(nf, std::numeric_limits<double>::infinity());
  const std::vector<char> thin = thin_source_faces(V, F);
  double weighted = 0, total_area = 0;
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d p0 = V.row(F(f, 0)), p1 = V.row(F(f, 1)), p2 = V.row(F(f, 2));
    const Eigen::Vector3d s(( p1 - p0).norm(), (p2 - p1).norm(), (p0 - p2).norm());
    const double area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    // A zero-area source face (accepted through mollification, docs/
    // robustness.md) has no defined D' and no weight in the mean: leave it
    // out of mean and max like a degenerate image, and count it.
    if (!(area > 1e-14 * std::max({s[0], s[1], s[2]}) * std::max({s[0], s[1], s[2]}))) {
      ++out.degenerate_source;
      out.thin_source.push_back(f);
      continue;
    }
    const std::complex<double> e1 = image(f, 1) - image(f, 0), e2 = image(f, 2) - image(f, 0);
    const double signed_area = 0.5 * (e1.real() * e2.imag() - e1.imag() * e2.real());
    const double scale2 = std::max({std::norm(e1), std::norm(e2), std::norm(image(f, 2) - image(f, 1))});
    if (std::abs(signed_area) <= kRoundOffRelativeCross * scale2) {
      ++out.degenerate;
      continue;
    }
    if (signed_area < 0) {
      ++out.flipped;
      continue;
    }
    Eigen::Matrix2d img;
    img << e1.real(), e2.real(), e1.imag(), e2.imag();
    const double d = dilatation_of(frame_from_sides(s), img);
    out.per_face[f] = d;
    if (thin[f]) {
      out.thin_source.push_back(f);
      if (std::isfinite(d)) out.thin_source_max = std::max(out.thin_source_max, d);
      continue;
    }
    weighted += area * d;
    total_area += area;
    out.max = std::max(out.max, d);
  }
  out.mean = total_area > 0 ? weighted / total_area : std::numeric_limits<double>::infinity();
  return out;
}

}  // namespace surfmap
