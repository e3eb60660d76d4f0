// The independent certificate of a map (verify/map_certificate.h,
// docs/verification.md): it accepts real maps and rejects a fold, a
// reflection, a double cover and an inconsistent inverse.
#include "surfmap/verify/map_certificate.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <map>

#include "certify_helpers.h"
#include "surfmap/error.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/verify/correspondence_file.h"

namespace surfmap {
namespace {

using testing_support::certify_result;
using testing_support::located_points;

// A located point exactly at vertex v of m (weight 1 on one of its faces' corners).
SurfacePoint at_vertex(const TriMesh& m, int v) {
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k)
      if (m.F(f, k) == v) {
        SurfacePoint p;
        p.face = f;
        p.barycentric[k] = 1.0;
        return p;
      }
  throw InputError("vertex not on a face");
}

// The vertex permutation and face map of a mirror symmetry of m (x -> mirror(x)):
// reflected[v] is the vertex at the mirrored position; a face's mirror image is a
// face of m with the opposite corner order.
struct Mirror {
  std::vector<int> vertex, face;  // face: mirrored face index
  std::vector<std::array<int, 3>> corner;  // corner[f][k]: the corner of face[f] at vertex[F(f,k)]
};

Mirror mirror_of(const TriMesh& m, const Eigen::Vector3d& normal) {
  Mirror r;
  r.vertex.assign(m.num_vertices(), -1);
  for (int v = 0; v < m.num_vertices(); ++v) {
    const Eigen::Vector3d p = m.V.row(v).transpose(), q = p - 2 * p.dot(normal) * normal;
    for (int w = 0; w < m.num_vertices(); ++w)
      if ((m.V.row(w).transpose() - q).norm() < 1e-9) r.vertex[v] = w;
    if (r.vertex[v] < 0) throw InputError("mesh not mirror symmetric");
  }
  std::map<std::array<int, 3>, int> by_corners;
  for (int f = 0; f < m.num_faces(); ++f) {
    std::array<int, 3> key{m.F(f, 0), m.F(f, 1), m.F(f, 2)};
    std::sort(key.begin(), key.end());
    by_corners[key] = f;
  }
  r.face.resize(m.num_faces());
  r.corner.resize(m.num_faces());
  for (int f = 0; f < m.num_faces(); ++f) {
    std::array<int, 3> key{r.vertex[m.F(f, 0)], r.vertex[m.F(f, 1)], r.vertex[m.F(f, 2)]};
    std::sort(key.begin(), key.end());
    const auto it = by_corners.find(key);
    if (it == by_corners.end()) throw InputError("mirror image of a face is not a face");
    r.face[f] = it->second;
    for (int k = 0; k < 3; ++k)
      for (int l = 0; l < 3; ++l)
        if (m.F(it->second, l) == r.vertex[m.F(f, k)]) r.corner[f][k] = l;
  }
  return r;
}

SurfacePoint mirrored(const Mirror& r, const SurfacePoint& p) {
  SurfacePoint q;
  q.face = r.face[p.face];
  for (int k = 0; k < 3; ++k) q.barycentric[r.corner[p.face][k]] = p.barycentric[k];
  return q;
}

// A genus-1 pair whose target (checkerboard diagonals, even counts) is mirror
// symmetric in z -> -z, mapped by the pipeline.
struct TorusPair {
  TriMesh source = samples::torus_of_revolution(1.0, 0.45, 40, 20);
  TriMesh target = samples::torus_of_revolution(1.4, 0.5, 36, 18, 1);
  SurfaceMapResult map = surface_map(source, target);
};

const TorusPair& torus_pair() {
  static const TorusPair pair;
  return pair;
}

TEST(MapCertificate, AcceptsTheOptimalMapsOfGenus0And1) {
  const TorusPair& p = torus_pair();
  const MapCertificate c = certify_result(p.source, p.target, p.map);
  EXPECT_TRUE(c.certified) << c.summary();
  EXPECT_EQ(c.negative_triangles, 0);
  EXPECT_EQ(c.winding_failures, 0);
  EXPECT_EQ(c.degree, 1);
  EXPECT_GT(c.min_relative_area, 0.0);
  EXPECT_NEAR(c.area_ratio, 1.0, 0.05) << c.summary();
  EXPECT_LT(c.max_inverse_error, 0.25);

  const TriMesh a = samples::sphere(3), b = samples::jitter(samples::sphere(3), 0.2, 7);
  const SurfaceMapResult m = surface_map(a, b);
  const MapCertificate s = certify_result(a, b, m);
  EXPECT_TRUE(s.certified) << s.summary();
}

TEST(MapCertificate, IdentityIsExact) {
  const TriMesh m = samples::torus_of_revolution(1.0, 0.4, 12, 8, 2);
  std::vector<SurfacePoint> id(m.num_vertices());
  for (int v = 0; v < m.num_vertices(); ++v) id[v] = at_vertex(m, v);
  const MapCertificate c = certify_map(m, m, id, id);
  EXPECT_TRUE(c.certified) << c.summary();
  // Areas are projected onto the mean of the corners' vertex normals: slightly
  // below the faces' own areas on a coarse mesh.
  EXPECT_LT(c.area_ratio, 1.0);
  EXPECT_GT(c.area_ratio, 0.99);
  EXPECT_EQ(c.max_inverse_error, 0.0);
  EXPECT_EQ(c.max_forward_error, 0.0);
}

TEST(MapCertificate, RejectsOneVertexMovedAcrossAFold) {
  const TorusPair& p = torus_pair();
  std::vector<SurfacePoint> forward = located_points(p.map.forward);
  const std::vector<SurfacePoint> inverse = located_points(p.map.inverse);
  // Source vertex (i, j) = i * 20 + j of the 40 x 20 grid: its image moved onto
  // the image of (i + 2, j), across its neighbour (i + 1, j).
  const int v = 10 * 20 + 5, beyond = 12 * 20 + 5;
  forward[v] = forward[beyond];
  const MapCertificate c = certify_map(p.source, p.target, forward, inverse);
  EXPECT_FALSE(c.certified);
  EXPECT_GT(c.negative_triangles, 0) << c.summary();
  EXPECT_GT(c.winding_failures, 0);
  EXPECT_NE(c.summary().find("negatively oriented"), std::string::npos) << c.summary();
}

TEST(MapCertificate, RejectsAMapComposedWithAReflection) {
  const TorusPair& p = torus_pair();
  const Mirror r = mirror_of(p.target, Eigen::Vector3d::UnitZ());
  std::vector<SurfacePoint> forward = located_points(p.map.forward), inverse = located_points(p.map.inverse);
  // forward' = R o f, inverse' = f^-1 o R: consistent, only the orientation is wrong.
  for (auto& q : forward) q = mirrored(r, q);
  for (int t = 0; t < p.target.num_vertices(); ++t) inverse[t] = located_points(p.map.inverse)[r.vertex[t]];
  const MapCertificate c = certify_map(p.source, p.target, forward, inverse);
  EXPECT_FALSE(c.certified);
  EXPECT_EQ(c.negative_triangles, p.source.num_faces()) << c.summary();
  EXPECT_EQ(c.degree, -1);
  EXPECT_EQ(c.inverse_failures + c.forward_failures, 0) << c.summary();
}

TEST(MapCertificate, RejectsADoubleCover) {
  // Source ring i wraps twice around the target: every image triangle positive,
  // every star winds once, but the signed area is twice the target's.
  const int n = 16, m = 8;
  const TriMesh source = samples::torus_of_revolution(1.0, 0.4, 2 * n, m), target = samples::torus_of_revolution(1.0, 0.4, n, m);
  std::vector<SurfacePoint> forward(source.num_vertices()), inverse(target.num_vertices());
  for (int i = 0; i < 2 * n; ++i)
    for (int j = 0; j < m; ++j) forward[i * m + j] = at_vertex(target, (i % n) * m + j);
  for (int t = 0; t < target.num_vertices(); ++t) inverse[t] = at_vertex(source, t);
  const MapCertificate c = certify_map(source, target, forward, inverse);
  EXPECT_FALSE(c.certified);
  EXPECT_EQ(c.negative_triangles + c.degenerate_triangles + c.winding_failures, 0) << c.summary();
  // Every target face is covered exactly twice: twice the identity's (projected) area.
  std::vector<SurfacePoint> id(target.num_vertices());
  for (int t = 0; t < target.num_vertices(); ++t) id[t] = at_vertex(target, t);
  const MapCertificate once = certify_map(target, target, id, id);
  ASSERT_TRUE(once.certified) << once.summary();
  EXPECT_NEAR(c.area_ratio, 2.0 * once.area_ratio, 1e-9);
  EXPECT_EQ(c.degree, 2);
  EXPECT_EQ(c.inverse_failures, 0);
  EXPECT_EQ(c.forward_failures, source.num_vertices() / 2);  // the second sheet does not come back
}

TEST(MapCertificate, RejectsAnInconsistentInverseAndBadLocations) {
  const TorusPair& p = torus_pair();
  const std::vector<SurfacePoint> forward = located_points(p.map.forward);
  std::vector<SurfacePoint> inverse = located_points(p.map.inverse);
  std::swap(inverse[0], inverse[p.target.num_vertices() / 2]);
  MapCertificate c = certify_map(p.source, p.target, forward, inverse);
  EXPECT_FALSE(c.certified);
  EXPECT_EQ(c.negative_triangles, 0);
  EXPECT_EQ(c.inverse_failures, 2) << c.summary();

  inverse = located_points(p.map.inverse);
  inverse[3].face = p.source.num_faces();
  c = certify_map(p.source, p.target, forward, inverse);
  EXPECT_FALSE(c.certified);
  EXPECT_EQ(c.invalid_inverse, 1);
  inverse[3] = located_points(p.map.inverse)[3];
  inverse[3].barycentric = Eigen::Vector3d(1.2, -0.1, -0.1);
  EXPECT_FALSE(certify_map(p.source, p.target, forward, inverse).certified);
  inverse.pop_back();
  c = certify_map(p.source, p.target, forward, inverse);
  EXPECT_FALSE(c.certified);
  EXPECT_NE(c.failures.at(0).find("inverse map has"), std::string::npos);
}

TEST(MapCertificate, CorrespondenceFileRoundTrip) {
  const TorusPair& p = torus_pair();
  const std::vector<SurfacePoint> forward = located_points(p.map.forward), inverse = located_points(p.map.inverse);
  const std::string path = ::testing::TempDir() + "surfmap_corr_roundtrip.txt";
  {
    std::ofstream out(path);
    out << correspondence_text(forward, inverse);
  }
  const CorrespondenceFile f = read_correspondence(path);
  ASSERT_TRUE(f.has_inverse);
  ASSERT_EQ(f.forward.size(), forward.size());
  ASSERT_EQ(f.inverse.size(), inverse.size());
  for (size_t i = 0; i < forward.size(); ++i) {
    EXPECT_EQ(f.forward[i].face, forward[i].face);
    EXPECT_EQ(f.forward[i].barycentric, forward[i].barycentric);  // 17 digits: exact
  }
  EXPECT_TRUE(certify_map(p.source, p.target, f.forward, f.inverse).certified);
  {
    std::ofstream out(path, std::ios::app);
    out << "12 0.5 0.5\n";
  }
  try {
    read_correspondence(path);
    ADD_FAILURE() << "a short line was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(":" + std::to_string(forward.size() + inverse.size() + 2) + ":"),
              std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}

}  // namespace
}  // namespace surfmap
