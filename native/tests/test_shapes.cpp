// Properties of the procedural sample shapes: closed manifold, one component,
// the stated genus, outward orientation, no zero-area faces, and the specific
// geometric promises of each generator.
#include "surfmap/samples/shapes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numeric>
#include <cstdio>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/open_surface.h"

namespace surfmap::samples {
namespace {

using Eigen::Vector3d;

double signed_volume(const TriMesh& m) {
  double vol = 0;
  for (int t = 0; t < m.num_faces(); ++t) {
    const Vector3d a = m.V.row(m.F(t, 0)), b = m.V.row(m.F(t, 1)), c = m.V.row(m.F(t, 2));
    vol += a.dot(b.cross(c)) / 6.0;
  }
  return vol;
}

double corner_angle(const TriMesh& m, int t, int c) {
  const Vector3d p = m.V.row(m.F(t, c)), q = m.V.row(m.F(t, (c + 1) % 3)), r = m.V.row(m.F(t, (c + 2) % 3));
  const Vector3d u = q - p, v = r - p;
  return std::atan2(u.cross(v).norm(), u.dot(v));
}

double min_angle_deg(const TriMesh& m) {
  double best = M_PI;
  for (int t = 0; t < m.num_faces(); ++t)
    for (int c = 0; c < 3; ++c) best = std::min(best, corner_angle(m, t, c));
  return best * 180 / M_PI;
}

int count_components(const TriMesh& m, const Connectivity& conn) {
  std::vector<int> parent(m.num_vertices());
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> find = [&](int x) { return parent[x] == x ? x : parent[x] = find(parent[x]); };
  for (int e = 0; e < conn.num_edges(); ++e) parent[find(conn.edge_vertex(e, 0))] = find(conn.edge_vertex(e, 1));
  std::set<int> roots;
  for (int v = 0; v < m.num_vertices(); ++v) roots.insert(find(v));
  return static_cast<int>(roots.size());
}

/// Every promise a generator makes about a closed surface.
void expect_closed_surface(const TriMesh& m, int genus, const std::string& what) {
  SCOPED_TRACE(what);
  ASSERT_GT(m.num_faces(), 0);
  ASSERT_TRUE(m.V.allFinite());
  Connectivity conn(m.F, m.num_vertices());  // throws unless closed manifold, consistently oriented
  EXPECT_EQ(conn.genus(), genus);
  EXPECT_EQ(conn.euler_characteristic(), 2 - 2 * genus);
  EXPECT_EQ(count_components(m, conn), 1);
  EXPECT_GT(signed_volume(m), 0.0) << "not outward oriented";
  const double diag2 = (m.V.colwise().maxCoeff() - m.V.colwise().minCoeff()).squaredNorm();
  int degenerate = 0;
  for (int t = 0; t < m.num_faces(); ++t) {
    const Vector3d a = m.V.row(m.F(t, 0)), b = m.V.row(m.F(t, 1)), c = m.V.row(m.F(t, 2));
    if ((b - a).cross(c - a).norm() <= 1e-12 * diag2) ++degenerate;
  }
  EXPECT_EQ(degenerate, 0);
}

std::set<std::array<int, 3>> face_set(const RowMatrixX3i& F) {
  std::set<std::array<int, 3>> s;
  for (int t = 0; t < F.rows(); ++t) {
    std::array<int, 3> f{F(t, 0), F(t, 1), F(t, 2)};
    std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
    s.insert(f);
  }
  return s;
}

TEST(Shapes, SphereIsSubdividedIcosahedronOnUnitSphere) {
  for (int s = 0; s <= 4; ++s) {
    const TriMesh m = sphere(s);
    expect_closed_surface(m, 0, "sphere(" + std::to_string(s) + ")");
    EXPECT_EQ(m.num_vertices(), 10 * (1 << (2 * s)) + 2);
    for (int v = 0; v < m.num_vertices(); ++v) EXPECT_NEAR(m.V.row(v).norm(), 1.0, 1e-12);
  }
  // Volume tends to 4/3 pi.
  EXPECT_NEAR(signed_volume(sphere(5)), 4.0 / 3.0 * M_PI, 0.01);
}

TEST(Shapes, SphericalCapIsAHemisphereDiskRimAtZeroHeight) {
  for (int rings : {1, 3, 8}) {
    const TriMesh m = spherical_cap(rings);
    const OpenSurfaceTopology t = open_surface_topology(m);
    EXPECT_EQ(t.genus, 0);
    ASSERT_EQ(t.num_boundary_loops(), 1);
    EXPECT_EQ(static_cast<int>(t.boundary_loops[0].size()), 6 * rings);
    EXPECT_EQ(m.num_vertices(), 1 + 6 * rings * rings);
    for (int v = 0; v < m.num_vertices(); ++v) {
      EXPECT_NEAR(m.V.row(v).norm(), 1.0, 1e-12);
      EXPECT_GE(m.V(v, 2), -1e-15);
    }
    for (int v : t.boundary_loops[0]) EXPECT_NEAR(m.V(v, 2), 0.0, 1e-15);
    // Outward (away from the sphere's centre): every face normal has a
    // positive component along its centroid.
    for (int f = 0; f < m.num_faces(); ++f) {
      const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
      EXPECT_GT((b - a).cross(c - a).dot(a + b + c), 0.0) << "face " << f;
    }
  }
  // The bump moves z by bump x z and keeps the rim at z = 0.
  const TriMesh plain = spherical_cap(4), bumped = spherical_cap(4, 0.3);
  for (int v = 0; v < plain.num_vertices(); ++v) {
    EXPECT_NEAR(bumped.V(v, 2), plain.V(v, 2) * (1 + 0.3 * plain.V(v, 0)), 1e-15);
  }
  EXPECT_THROW(spherical_cap(0), InputError);
}

TEST(Shapes, TorusOfRevolutionLiesOnTheTorusInEveryVariant) {
  const double R = 1.5, r = 0.5;
  std::vector<std::set<std::array<int, 3>>> faces;
  for (int variant = 0; variant < 4; ++variant) {
    const TriMesh m = torus_of_revolution(R, r, 48, 24, variant);
    expect_closed_surface(m, 1, "torus variant " + std::to_string(variant));
    EXPECT_EQ(m.num_vertices(), 48 * 24);
    EXPECT_EQ(m.num_faces(), 2 * 48 * 24);
    for (int v = 0; v < m.num_vertices(); ++v) {
      const double x = m.V(v, 0), y = m.V(v, 1), z = m.V(v, 2);
      EXPECT_NEAR(std::pow(std::hypot(x, y) - R, 2) + z * z, r * r, 1e-12);
    }
    EXPECT_GT(min_angle_deg(m), 10.0);
    // Volume of the polyhedron approaches 2 pi^2 R r^2 from below.
    const double exact = 2 * M_PI * M_PI * R * r * r;
    EXPECT_LT(signed_volume(m), exact);
    EXPECT_GT(signed_volume(m), 0.97 * exact);
    faces.push_back(face_set(m.F));
  }
  for (size_t a = 0; a < faces.size(); ++a)
    for (size_t b = a + 1; b < faces.size(); ++b) EXPECT_NE(faces[a], faces[b]) << a << " vs " << b;
  // Odd ring counts exercise the wrap-around of the offset variant.
  expect_closed_surface(torus_of_revolution(1.0, 0.5, 31, 17, 2), 1, "odd torus, variant 2");
}

TEST(Shapes, TorusOfRevolutionRejectsBadParameters) {
  EXPECT_THROW(torus_of_revolution(0.5, 0.5, 16, 8), InputError);
  EXPECT_THROW(torus_of_revolution(1.0, 0.0, 16, 8), InputError);
  EXPECT_THROW(torus_of_revolution(1.0, 0.5, 2, 8), InputError);
}

struct ImplicitCase {
  std::string name;
  int genus;
  std::function<TriMesh(int, bool)> make;
};

std::vector<ImplicitCase> implicit_cases() {
  std::vector<ImplicitCase> cases;
  for (int n = 1; n <= 8; ++n)
    cases.push_back({"n_hole_torus(" + std::to_string(n) + ")", n,
                     [n](int res, bool smooth) { return n_hole_torus(n, res, smooth); }});
  cases.push_back({"vase", 2, [](int res, bool smooth) { return vase(res, smooth); }});
  cases.push_back({"amphora", 2, [](int res, bool smooth) { return amphora(res, smooth); }});
  for (int h : {1, 2, 3, 5, 8})
    cases.push_back({"cup(" + std::to_string(h) + ")", h,
                     [h](int res, bool smooth) { return cup(h, res, smooth); }});
  for (int g : {1, 2, 3, 5, 8})
    cases.push_back({"polycube(" + std::to_string(g) + ")", g,
                     [g](int res, bool smooth) { return polycube(g, res, smooth); }});
  return cases;
}

TEST(Shapes, ImplicitShapesAreClosedSurfacesOfTheStatedGenus) {
  for (const auto& c : implicit_cases())
    for (int res : {32})
      for (bool smooth : {false, true}) {
        const std::string what = c.name + " res " + std::to_string(res) + (smooth ? " smooth" : " raw");
        const TriMesh m = c.make(res, smooth);
        expect_closed_surface(m, c.genus, what);
        EXPECT_GT(m.num_vertices(), 1000) << what;
        EXPECT_LT(m.num_vertices(), 30000) << what;
      }
}

TEST(Shapes, RawMarchingTetsHasSliversAndSmoothingRemovesThem) {
  for (const auto& c : implicit_cases()) {
    const TriMesh raw = c.make(36, false), smooth = c.make(36, true);
    // Smoothing only moves vertices and flips edges: same counts.
    EXPECT_EQ(raw.num_vertices(), smooth.num_vertices()) << c.name;
    EXPECT_EQ(raw.num_faces(), smooth.num_faces()) << c.name;
    const double a_raw = min_angle_deg(raw), a_smooth = min_angle_deg(smooth);
    EXPECT_LT(a_raw, 3.0) << c.name;
    EXPECT_GT(a_smooth, 8.0) << c.name;
    EXPECT_GT(a_smooth, 3 * a_raw) << c.name;
  }
}

TEST(Shapes, VertexCountGrowsQuadraticallyWithResolution) {
  const int v1 = vase(32, false).num_vertices(), v2 = vase(64, false).num_vertices();
  EXPECT_GT(v2, 3.2 * v1);
  EXPECT_LT(v2, 4.8 * v1);
}

TEST(Shapes, SmoothedVerticesStayOnTheRawSurface) {
  // The torus n_hole_torus(1) is a tube of radius 0.4 around the unit circle:
  // smoothing projects back onto it, so every vertex must be at distance 0.4
  // from the circle up to the smooth-min blending (none for one circle).
  const TriMesh m = n_hole_torus(1, 48, true);
  for (int v = 0; v < m.num_vertices(); ++v) {
    const double x = m.V(v, 0), y = m.V(v, 1), z = m.V(v, 2);
    EXPECT_NEAR(std::hypot(std::hypot(x, y) - 1.0, z), 0.4, 1e-6);
  }
}

TEST(Shapes, ImplicitShapesRejectBadArguments) {
  EXPECT_THROW(n_hole_torus(0, 32), InputError);
  EXPECT_THROW(n_hole_torus(9, 32), InputError);
  EXPECT_THROW(cup(0, 32), InputError);
  EXPECT_THROW(polycube(9, 32), InputError);
  EXPECT_THROW(vase(4), InputError);
  // Too coarse to resolve the handles: reported, not silently wrong.
  EXPECT_THROW(amphora(12, false), Error);
}

TEST(Shapes, JitterMovesTangentiallyWithoutFlipping) {
  const TriMesh m = n_hole_torus(2, 32, true);
  const TriMesh j = jitter(m, 0.25, 7);
  expect_closed_surface(j, 2, "jittered double torus");
  EXPECT_EQ(j.F, m.F);
  // Deterministic per seed, different across seeds.
  EXPECT_EQ(jitter(m, 0.25, 7).V, j.V);
  EXPECT_NE(jitter(m, 0.25, 8).V, j.V);
  double moved = 0;
  for (int t = 0; t < m.num_faces(); ++t) {
    auto normal = [&](const TriMesh& x) {
      const Vector3d a = x.V.row(x.F(t, 0)), b = x.V.row(x.F(t, 1)), c = x.V.row(x.F(t, 2));
      return Vector3d((b - a).cross(c - a));
    };
    EXPECT_GT(normal(j).dot(normal(m)), 0.0) << "face " << t << " flipped";
  }
  // Offsets are bounded by amplitude x local mean edge length (max edge here).
  double max_edge = 0;
  for (int t = 0; t < m.num_faces(); ++t)
    for (int c = 0; c < 3; ++c)
      max_edge = std::max(max_edge, (m.V.row(m.F(t, c)) - m.V.row(m.F(t, (c + 1) % 3))).norm());
  for (int v = 0; v < m.num_vertices(); ++v) {
    const double d = (j.V.row(v) - m.V.row(v)).norm();
    EXPECT_LE(d, 0.25 * max_edge + 1e-12);
    moved += d;
  }
  EXPECT_GT(moved, 0.0);
  EXPECT_THROW(jitter(m, 0.3, 1), InputError);
  EXPECT_THROW(jitter(m, -0.1, 1), InputError);
}

TEST(Shapes, SphereInversionIsAConformalOutwardCopy) {
  const TriMesh m = n_hole_torus(2, 48, true);
  // Centre outside the solid, and centre inside the solid tube.
  for (const Vector3d& c : {Vector3d(0.5, 3.0, 2.0), Vector3d(-2.15, 0.0, 0.0)}) {
    const TriMesh inv = sphere_inversion(m, c, 2.0);
    expect_closed_surface(inv, 2, "inverted double torus");
    // Inverting again gives the original positions back.
    const TriMesh back = sphere_inversion(inv, c, 2.0);
    EXPECT_LT((back.V - m.V).cwiseAbs().maxCoeff(), 1e-9);
    // Conformal: corner angles are preserved up to a first-order error in
    // (triangle size / distance to the centre), so small triangles keep
    // their angles (corners matched through the possibly reversed order).
    double worst_ratio = 0, worst_far = 0;
    const bool reversed = inv.F(0, 1) != m.F(0, 1);
    for (int t = 0; t < m.num_faces(); ++t) {
      double size = 0;
      for (int k = 0; k < 3; ++k)
        size = std::max(size, (m.V.row(m.F(t, k)) - m.V.row(m.F(t, (k + 1) % 3))).norm());
      double dist = 1e30;
      for (int k = 0; k < 3; ++k) dist = std::min(dist, (m.V.row(m.F(t, k)).transpose() - c).norm());
      for (int k = 0; k < 3; ++k) {
        const int kk = reversed ? (k == 0 ? 0 : 3 - k) : k;
        ASSERT_EQ(inv.F(t, kk), m.F(t, k));
        const double err = std::abs(corner_angle(m, t, k) - corner_angle(inv, t, kk));
        worst_ratio = std::max(worst_ratio, err / (size / dist));
        if (size / dist < 0.05) worst_far = std::max(worst_far, err);
      }
    }
    EXPECT_LT(worst_ratio, 2.0);
    EXPECT_LT(worst_far * 180 / M_PI, 4.0);
    std::printf("inversion: worst angle error / (size/dist) = %.3f, worst error where size/dist < 0.05: %.3f deg\n",
                worst_ratio, worst_far * 180 / M_PI);
  }
  EXPECT_THROW(sphere_inversion(m, m.V.row(0).transpose(), 1.0), InputError);
}

TEST(Shapes, StretchedUvSphereIsAClosedOutwardSphereWithSlivers) {
  const TriMesh m = stretched_uv_sphere(30, 200, 10.0);
  EXPECT_EQ(m.num_vertices(), 2 + 29 * 200);
  // Closed genus 0: V - E + F = 2 with E = 3F / 2.
  ASSERT_EQ(m.num_faces() % 2, 0);
  EXPECT_EQ(m.num_vertices() - 3 * m.num_faces() / 2 + m.num_faces(), 2);
  double smallest = 180.0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
    EXPECT_GT((b - a).cross(c - a).dot(a + b + c), 0.0) << "face " << f;  // outward
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = m.V.row(m.F(f, k)), q = m.V.row(m.F(f, (k + 1) % 3)), r = m.V.row(m.F(f, (k + 2) % 3));
      smallest = std::min(smallest, std::acos((q - p).normalized().dot((r - p).normalized())) * 180.0 / M_PI);
    }
  }
  EXPECT_LT(smallest, 1.5);  // the slivers the robustness checks want
  EXPECT_THROW(stretched_uv_sphere(1, 200, 10.0), InputError);
  EXPECT_THROW(stretched_uv_sphere(30, 200, 0.0), InputError);
}

TEST(Shapes, BentTaperedSphereIsBentAndTaperedAndClosed) {
  const double stretch = 10.0, bend = 0.3;
  const TriMesh m = bent_tapered_sphere(30, 200, stretch, bend), straight = stretched_uv_sphere(30, 200, stretch);
  ASSERT_EQ(m.num_vertices(), straight.num_vertices());
  ASSERT_EQ(m.F, straight.F);  // same connectivity: closed genus 0
  for (int v = 0; v < m.num_vertices(); ++v) {
    const double z = straight.V(v, 2);
    EXPECT_EQ(m.V(v, 2), z);
    EXPECT_NEAR(m.V(v, 0) - straight.V(v, 0), bend * z * z / stretch, 1e-12);  // bent: the ends move by 3
    EXPECT_NEAR(m.V(v, 1), straight.V(v, 1) * (1 + z / (2 * stretch)), 1e-12);  // tapered
  }
  double smallest = 180.0, volume = 0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
    volume += a.dot(b.cross(c)) / 6;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = m.V.row(m.F(f, k)), q = m.V.row(m.F(f, (k + 1) % 3)), r = m.V.row(m.F(f, (k + 2) % 3));
      smallest = std::min(smallest, std::acos((q - p).normalized().dot((r - p).normalized())) * 180.0 / M_PI);
    }
  }
  // Outward and not pinched: the volume of the tapered tube, about
  // (4/3) pi stretch (a bend shears cross-sections, which keeps volume).
  EXPECT_NEAR(volume, 4.0 / 3.0 * M_PI * stretch, 0.05 * 4.0 / 3.0 * M_PI * stretch);
  EXPECT_LT(smallest, 1.5);
  EXPECT_THROW(bent_tapered_sphere(30, 200, 0.5), InputError);
  EXPECT_THROW(bent_tapered_sphere(30, 200, 10.0, 1.5), InputError);
  EXPECT_THROW(bent_tapered_sphere(1, 200, 10.0), InputError);
}

}  // namespace
}  // namespace surfmap::samples
