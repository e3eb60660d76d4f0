#pragma once
// Tests of final maps: run the independent certificate
// (verify/map_certificate.h) on a SurfaceMapResult's forward and inverse
// maps, so "no flips" is checked by code that shares nothing with the solver.
#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include "surfmap/map/surface_map.h"
#include "surfmap/verify/map_certificate.h"

namespace surfmap::testing_support {

inline std::vector<SurfacePoint> located_points(const std::vector<PointOnSurface>& points) {
  std::vector<SurfacePoint> out;
  out.reserve(points.size());
  for (const auto& p : points) out.push_back({p.face, p.barycentric});
  return out;
}

inline MapCertificate certify_result(const TriMesh& source, const TriMesh& target, const SurfaceMapResult& m,
                                     const MapCertificateOptions& options = {}) {
  return certify_map(source, target, located_points(m.forward), located_points(m.inverse), options);
}

}  // namespace surfmap::testing_support

/// Expects the map `m` from `source` onto `target` to be certified a bijection.
#define EXPECT_CERTIFIED_MAP(source, target, m)                                                        \
  do {                                                                                                 \
    const ::surfmap::MapCertificate certificate_ = ::surfmap::testing_support::certify_result(source, target, m); \
    EXPECT_TRUE(certificate_.certified) << certificate_.summary();                                     \
  } while (0)

/// For strongly stretched maps whose vertex images leave a few chord triangles
/// folded in R^3 although the solver's map is unflipped in its uniformization
/// domain (a straight domain triangle spanning several target faces is curved
/// in R^3, and its chord can reverse; docs/verification.md): every point
/// valid, degree 1, nothing degenerate, and at most `max_fraction` of the
/// source triangles (vertices) with reversed chord images (stars not winding
/// once, compositions off). The full certificate is printed when it fails.
#define EXPECT_CERTIFIED_MAP_UP_TO_CHORD_FOLDS(source, target, m, max_fraction)                         \
  do {                                                                                                 \
    const ::surfmap::MapCertificate c_ = ::surfmap::testing_support::certify_result(source, target, m); \
    EXPECT_EQ(c_.invalid_forward + c_.invalid_inverse + c_.degenerate_triangles, 0) << c_.summary();    \
    EXPECT_EQ(c_.degree, 1) << c_.summary();                                                           \
    EXPECT_LE(c_.negative_triangles, (max_fraction) * c_.source_triangles) << c_.summary();             \
    EXPECT_LE(c_.winding_failures, (max_fraction) * c_.source_vertices) << c_.summary();                \
    EXPECT_LE(c_.inverse_failures + c_.forward_failures,                                               \
              (max_fraction) * (c_.source_vertices + c_.target_vertices)) << c_.summary();              \
    if (!c_.certified) std::printf("certificate (chord folds tolerated):\n%s\n", c_.summary().c_str()); \
  } while (0)
