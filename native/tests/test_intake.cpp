#include "surfmap/mesh/intake.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include <Eigen/Geometry>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/mesh_io.h"

namespace surfmap {
namespace {

PolygonSoup octahedron() {
  PolygonSoup s;
  s.V.resize(6, 3);
  s.V << 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1;
  s.polygons = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  return s;
}

// Torus of revolution as an n x m grid of quads (polygons, not triangles).
PolygonSoup quad_torus(int n, int m, double R = 1.0, double r = 0.4) {
  PolygonSoup s;
  s.V.resize(n * m, 3);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double u = 2 * M_PI * i / n, v = 2 * M_PI * j / m;
      s.V.row(i * m + j) << (R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u),
          r * std::sin(v);
    }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j)
      s.polygons.push_back({i * m + j, ((i + 1) % n) * m + j, ((i + 1) % n) * m + (j + 1) % m,
                            i * m + (j + 1) % m});
  return s;
}

std::string intake_error(const PolygonSoup& s) {
  try {
    intake(s);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "message: " << (text)

TEST(Intake, ValidOctahedron) {
  const MeshInfo info = inspect(octahedron());
  EXPECT_TRUE(info.valid);
  EXPECT_EQ(info.num_edges, 12);
  EXPECT_EQ(info.euler_characteristic, 2);
  EXPECT_EQ(info.genus, 0);
  EXPECT_EQ(info.num_components, 1);
  EXPECT_GT(info.signed_volume, 0);
  const IntakeResult r = intake(octahedron());
  EXPECT_FALSE(r.flipped);
}

TEST(Intake, QuadTorusIsTriangulatedWithCornerMap) {
  const PolygonSoup s = quad_torus(12, 8);
  const IntakeResult r = intake(s);
  EXPECT_EQ(r.info.genus, 1);
  ASSERT_EQ(r.mesh.num_faces(), 2 * 12 * 8);
  ASSERT_EQ(static_cast<int>(r.source_polygon.size()), r.mesh.num_faces());
  for (int t = 0; t < r.mesh.num_faces(); ++t) {
    const auto& poly = s.polygons[r.source_polygon[t]];
    for (int k = 0; k < 3; ++k)
      EXPECT_NE(std::find(poly.begin(), poly.end(), r.mesh.F(t, k)), poly.end());
  }
  Connectivity c(r.mesh.F, r.mesh.num_vertices());
  EXPECT_EQ(c.genus(), 1);
}

TEST(Intake, InwardSurfaceIsFlippedAndSaysSo) {
  PolygonSoup s = quad_torus(10, 6);
  for (auto& p : s.polygons) std::reverse(p.begin(), p.end());
  const MeshInfo info = inspect(s);
  EXPECT_LT(info.signed_volume, 0);
  ASSERT_FALSE(info.notes.empty());
  EXPECT_CONTAINS(info.notes.front(), "flipped");
  const IntakeResult r = intake(s);
  EXPECT_TRUE(r.flipped);
  double vol = 0;
  for (int f = 0; f < r.mesh.num_faces(); ++f)
    vol += r.mesh.V.row(r.mesh.F(f, 0))
               .dot(Eigen::Vector3d(r.mesh.V.row(r.mesh.F(f, 1))).cross(Eigen::Vector3d(r.mesh.V.row(r.mesh.F(f, 2)))));
  EXPECT_GT(vol, 0);
}

TEST(Intake, NonFiniteCoordinateNamesVertex) {
  PolygonSoup s = octahedron();
  s.V(3, 1) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_CONTAINS(intake_error(s), "vertex 3");
  s.V(3, 1) = std::numeric_limits<double>::infinity();
  EXPECT_CONTAINS(intake_error(s), "non-finite");
}

TEST(Intake, BadIndicesNameFace) {
  PolygonSoup s = octahedron();
  s.polygons[5][1] = 17;
  EXPECT_CONTAINS(intake_error(s), "face 5 refers to vertex 17");
  s = octahedron();
  s.polygons[2] = {1, 3, 1};
  EXPECT_CONTAINS(intake_error(s), "face 2 repeats vertex 1");
  s = octahedron();
  s.polygons[4] = {2, 0};
  EXPECT_CONTAINS(intake_error(s), "face 4 has only 2 vertices");
}

TEST(Intake, ZeroAreaFacesAreAcceptedThroughMollification) {
  // Issue 13: zero-area faces are no longer refused; the solvers mollify the
  // edge lengths and intake says how many faces that touched.
  PolygonSoup s = octahedron();
  s.V.row(4) << 0.5, 0.5, 0.0;  // on edge (0, 2): faces 0 and 4 become flat
  const MeshInfo info = inspect(s);
  EXPECT_TRUE(info.valid);
  EXPECT_EQ(info.zero_area_faces, 1);  // face 0 = (0, 2, 4): collinear
  EXPECT_GE(info.mollified_faces, 1);
  EXPECT_GT(info.mollify_epsilon, 0.0);
  ASSERT_FALSE(info.notes.empty());
  EXPECT_CONTAINS(info.notes.back(), "mollified: ");
  EXPECT_CONTAINS(info.notes.back(), "1 face had zero area");
  // A well-shaped mesh gets no note.
  EXPECT_EQ(inspect(octahedron()).mollified_faces, 0);
  EXPECT_TRUE(inspect(octahedron()).notes.empty());
}

TEST(Intake, BoundaryIsReportedAsOpenSurface) {
  PolygonSoup s = octahedron();
  s.polygons.pop_back();
  const MeshInfo info = inspect(s);
  EXPECT_FALSE(info.valid);
  EXPECT_EQ(info.num_boundary_loops, 1);
  const std::string msg = intake_error(s);
  EXPECT_CONTAINS(msg, "open");
  EXPECT_CONTAINS(msg, "needs a closed surface");
  EXPECT_CONTAINS(msg, "surfmap map");  // which command takes open surfaces
}

TEST(Intake, NonManifoldEdgeNamesEdgeAndFaces) {
  PolygonSoup s = octahedron();
  // A fin: a third face on edge (0, 2), with a new vertex.
  s.V.conservativeResize(7, 3);
  s.V.row(6) << 1, 1, 1;
  s.polygons.push_back({0, 2, 6});
  const std::string msg = intake_error(s);
  EXPECT_CONTAINS(msg, "non-manifold edge");
  EXPECT_CONTAINS(msg, "(0, 2)");
}

TEST(Intake, NonManifoldVertexIsNamed) {
  // Two octahedra sharing vertex 0 only.
  PolygonSoup a = octahedron(), s = octahedron();
  s.V.conservativeResize(11, 3);
  for (int v = 1; v < 6; ++v) s.V.row(5 + v) = a.V.row(v) + Eigen::RowVector3d(2, 0, 0);
  s.V.row(0) << 1, 0, 0;
  for (auto p : a.polygons) {
    for (int& v : p) v = v == 0 ? 0 : v + 5;
    // mirror so that the shared vertex sits on the touching side; orientation is irrelevant here
    s.polygons.push_back(p);
  }
  const std::string msg = intake_error(s);
  EXPECT_CONTAINS(msg, "vertex 0");
  EXPECT_CONTAINS(msg, "non-manifold");
}

TEST(Intake, InconsistentOrientationNamesFaces) {
  PolygonSoup s = octahedron();
  std::reverse(s.polygons[6].begin(), s.polygons[6].end());
  const std::string msg = intake_error(s);
  EXPECT_CONTAINS(msg, "inconsistently oriented");
  EXPECT_CONTAINS(msg, "6");
}

TEST(Intake, SeveralComponentsAndLooseVertex) {
  PolygonSoup s = octahedron(), b = octahedron();
  s.V.conservativeResize(12, 3);
  s.V.bottomRows(6) = b.V.rowwise() + Eigen::RowVector3d(5, 0, 0);
  for (auto p : b.polygons) {
    for (int& v : p) v += 6;
    s.polygons.push_back(p);
  }
  const MeshInfo info = inspect(s);
  EXPECT_EQ(info.num_components, 2);
  EXPECT_CONTAINS(intake_error(s), "2 separate components");

  PolygonSoup loose = octahedron();
  loose.V.conservativeResize(7, 3);
  loose.V.row(6) << 3, 3, 3;
  EXPECT_CONTAINS(intake_error(loose), "vertex 6 is not used");
}

TEST(Intake, GenusMismatchNamesBoth) {
  const MeshInfo a = inspect(octahedron()), b = inspect(quad_torus(8, 6));
  try {
    check_same_genus(a, b);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_CONTAINS(e.what(), "genus 0");
    EXPECT_CONTAINS(e.what(), "genus 1");
  }
}

class MeshFiles : public ::testing::Test {
 protected:
  std::filesystem::path dir = std::filesystem::temp_directory_path() / ("surfmap_io_" + std::to_string(::getpid()));
  void SetUp() override { std::filesystem::create_directories(dir); }
  void TearDown() override { std::filesystem::remove_all(dir); }
  std::string write(const std::string& name, const std::string& text) {
    const auto p = dir / name;
    std::ofstream(p) << text;
    return p.string();
  }
};

TEST_F(MeshFiles, ObjRoundTripKeepsDoublePrecisionAndIndices) {
  const PolygonSoup s = quad_torus(9, 7);
  const IntakeResult r = intake(s);
  const std::string path = (dir / "t.obj").string();
  write_obj(path, r.mesh.V, r.mesh.F);
  const IntakeResult back = load_mesh(path);
  ASSERT_EQ(back.mesh.num_vertices(), r.mesh.num_vertices());
  EXPECT_EQ(back.mesh.F, r.mesh.F);
  EXPECT_LT((back.mesh.V - r.mesh.V).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_EQ(back.info.genus, 1);
}

TEST_F(MeshFiles, OffAndPlyAreRead) {
  const std::string off = write("o.off",
                                "OFF\n6 8 0\n1 0 0\n-1 0 0\n0 1 0\n0 -1 0\n0 0 1\n0 0 -1\n"
                                "3 0 2 4\n3 2 1 4\n3 1 3 4\n3 3 0 4\n3 2 0 5\n3 1 2 5\n3 3 1 5\n3 0 3 5\n");
  EXPECT_EQ(load_mesh(off).info.genus, 0);
  const std::string ply = write("o.ply",
                                "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n"
                                "property float z\nelement face 8\nproperty list uchar int vertex_indices\n"
                                "end_header\n1 0 0\n-1 0 0\n0 1 0\n0 -1 0\n0 0 1\n0 0 -1\n"
                                "3 0 2 4\n3 2 1 4\n3 1 3 4\n3 3 0 4\n3 2 0 5\n3 1 2 5\n3 3 1 5\n3 0 3 5\n");
  EXPECT_EQ(load_mesh(ply).info.num_faces, 8);
}

TEST_F(MeshFiles, NonManifoldFileIsReportedNotDropped) {
  // OpenMesh's own importer would silently drop the third face on edge (1,2).
  const std::string obj = write("nm.obj",
                                "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nv -1 -1 1\n"
                                "f 1 2 3\nf 2 4 3\nf 2 3 5\nf 1 3 4\nf 1 4 2\n");
  const MeshInfo info = inspect(read_polygon_soup(obj));
  ASSERT_FALSE(info.valid);
  EXPECT_CONTAINS(info.problems.front(), "non-manifold edge");
}

TEST_F(MeshFiles, MissingGarbageAndUnknownFilesGiveInputError) {
  EXPECT_THROW(read_polygon_soup((dir / "nope.obj").string()), InputError);
  EXPECT_THROW(read_polygon_soup(write("x.xyz", "hello")), InputError);
  EXPECT_THROW(read_polygon_soup(write("g.obj", "this is not a mesh\n")), InputError);
  EXPECT_THROW(read_polygon_soup(dir.string()), InputError);
}

TEST_F(MeshFiles, WriteIsAtomicAndFailsCleanly) {
  const std::string path = (dir / "keep.obj").string();
  write_text_file(path, "original");
  EXPECT_THROW(write_text_file((dir / "no_such_dir" / "x.obj").string(), "x"), Error);
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text, "original");
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos);
}

}  // namespace
}  // namespace surfmap
