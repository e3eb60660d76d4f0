// Canonical domains (samples/canonical_domain.h): the stated genus counted
// independently (Euler characteristic of the edge set), outward orientation
// (signed volume), unit area, triangle quality measured here from the
// corners, and bad options refused.
#include "surfmap/samples/canonical_domain.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include <Eigen/Geometry>

#include "surfmap/error.h"

namespace surfmap::samples {
namespace {

using Eigen::Vector3d;

int euler_genus(const TriMesh& m) {
  std::set<std::pair<int, int>> edges;
  for (int t = 0; t < m.num_faces(); ++t)
    for (int c = 0; c < 3; ++c) {
      const int a = m.F(t, c), b = m.F(t, (c + 1) % 3);
      edges.emplace(std::min(a, b), std::max(a, b));
    }
  const int chi = m.num_vertices() - static_cast<int>(edges.size()) + m.num_faces();
  EXPECT_EQ(chi % 2, 0);
  // Closed: every edge is shared by exactly two faces.
  EXPECT_EQ(2 * static_cast<long>(edges.size()), 3L * m.num_faces());
  return (2 - chi) / 2;
}

void expect_clean(const CanonicalDomainOptions& o) {
  SCOPED_TRACE("genus " + std::to_string(o.genus) + " kind " + std::to_string(static_cast<int>(o.kind)) +
               " layout " + std::to_string(static_cast<int>(o.layout)));
  const CanonicalDomainResult d = canonical_domain(o);
  EXPECT_EQ(d.genus, o.genus);
  EXPECT_EQ(euler_genus(d.mesh), o.genus);
  double area = 0, volume = 0, min_angle = M_PI;
  for (int t = 0; t < d.mesh.num_faces(); ++t) {
    const Vector3d a = d.mesh.V.row(d.mesh.F(t, 0)), b = d.mesh.V.row(d.mesh.F(t, 1)), c = d.mesh.V.row(d.mesh.F(t, 2));
    area += 0.5 * (b - a).cross(c - a).norm();
    volume += a.dot(b.cross(c)) / 6.0;
    const Vector3d p[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) {
      const Vector3d u = p[(k + 1) % 3] - p[k], v = p[(k + 2) % 3] - p[k];
      min_angle = std::min(min_angle, std::atan2(u.cross(v).norm(), u.dot(v)));
    }
  }
  EXPECT_NEAR(area, 1.0, 1e-9);
  EXPECT_NEAR(d.area, area, 1e-9);
  EXPECT_GT(volume, 0.0);
  EXPECT_NEAR(d.min_angle_deg, min_angle * 180 / M_PI, 1e-9);
  // Clean triangles: no sliver, and almost all triangles near equilateral.
  EXPECT_GT(d.min_angle_deg, 5.0);
  EXPECT_GT(d.mean_min_angle_deg, 40.0);
  EXPECT_LT(d.fraction_below_20_deg, 0.02);
  // Centred at the origin.
  EXPECT_LT(d.mesh.V.colwise().mean().norm(), 1e-9);
}

TEST(CanonicalDomain, NTorusRowEveryGenus) {
  for (int g : {1, 2, 4, 6}) expect_clean({g, DomainKind::NTorus, DomainLayout::Row, 32, true});
}

TEST(CanonicalDomain, NTorusRing) {
  for (int g : {2, 3, 5, 8}) expect_clean({g, DomainKind::NTorus, DomainLayout::Ring, 32, true});
}

TEST(CanonicalDomain, PolycubeAndSphere) {
  for (int g : {2, 4}) expect_clean({g, DomainKind::Polycube, DomainLayout::Row, 32, true});
  expect_clean({0, DomainKind::NTorus, DomainLayout::Row, 32, true});
}

TEST(CanonicalDomain, KeepScaleAndBadOptions) {
  const CanonicalDomainResult d = canonical_domain({2, DomainKind::NTorus, DomainLayout::Row, 32, false});
  EXPECT_GT(d.area, 5.0);  // two tori of tube radius 0.4 around circles of radius 1: about 2 x 4 pi^2 x 0.4
  EXPECT_THROW(canonical_domain({9, DomainKind::NTorus, DomainLayout::Row, 32, true}), InputError);
  EXPECT_THROW(canonical_domain({-1, DomainKind::NTorus, DomainLayout::Row, 32, true}), InputError);
  EXPECT_THROW(canonical_domain({2, DomainKind::NTorus, DomainLayout::Row, 12, true}), InputError);
  EXPECT_THROW(canonical_domain({2, DomainKind::Polycube, DomainLayout::Ring, 32, true}), InputError);
}

}  // namespace
}  // namespace surfmap::samples
