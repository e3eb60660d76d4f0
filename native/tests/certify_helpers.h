#pragma once
// Tests of final maps: run the independent certificate
// (verify/map_certificate.h) on a SurfaceMapResult's forward and inverse
// maps, so "no flips" is checked by code that shares nothing with the solver.
#include <gtest/gtest.h>

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
