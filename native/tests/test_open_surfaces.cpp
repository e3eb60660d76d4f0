// Open surfaces (issue 16, docs/open_surfaces.md): intake of meshes with
// boundary, conformal disk and annulus maps, maps between open surfaces.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <iostream>

#include <cmath>
#include <complex>
#include <functional>
#include <tuple>

#include <Eigen/Geometry>

#include "surfmap/error.h"
#include "surfmap/map/ear_images.h"
#include "surfmap/map/open_conformal.h"
#include "surfmap/map/open_map.h"
#include "surfmap/mesh/open_surface.h"

namespace surfmap {
namespace {

// Triangles between two rings of vertices (ids with angles increasing,
// closed), inner ring first so that faces are counter-clockwise in the
// (angle, ring) order; greedy by angle.
void zip_rings(const std::vector<int>& a, const std::vector<double>& ta, const std::vector<int>& b,
               const std::vector<double>& tb, std::vector<Eigen::Vector3i>& faces) {
  const int na = static_cast<int>(a.size()), nb = static_cast<int>(b.size());
  if (na == 1) {
    for (int j = 0; j < nb; ++j) faces.emplace_back(a[0], b[j], b[(j + 1) % nb]);
    return;
  }
  int i = 0, j = 0;
  auto angle_a = [&](int k) { return ta[k % na] + 2 * M_PI * (k / na); };
  auto angle_b = [&](int k) { return tb[k % nb] + 2 * M_PI * (k / nb); };
  while (i < na || j < nb) {
    const bool advance_b = j < nb && (i >= na || angle_b(j + 1) < angle_a(i + 1));
    if (advance_b) {
      faces.emplace_back(a[i % na], b[j % nb], b[(j + 1) % nb]);
      ++j;
    } else {
      faces.emplace_back(a[i % na], b[j % nb], a[(i + 1) % na]);
      ++i;
    }
  }
}

// Rings of vertices at "radii" 0..rings (ring k: counts(k) vertices at
// angles offset by offset(k)), placed by position(ring, angle).
TriMesh ring_mesh(int rings, const std::function<int(int)>& counts, const std::function<double(int)>& offset,
                  const std::function<Eigen::Vector3d(int, double)>& position) {
  std::vector<Eigen::Vector3d> V;
  std::vector<Eigen::Vector3i> faces;
  std::vector<int> prev_ids;
  std::vector<double> prev_angles;
  for (int k = 0; k <= rings; ++k) {
    std::vector<int> ids;
    std::vector<double> angles;
    const int n = counts(k);
    for (int j = 0; j < n; ++j) {
      const double t = offset(k) + 2 * M_PI * j / n;
      ids.push_back(static_cast<int>(V.size()));
      angles.push_back(t);
      V.push_back(position(k, t));
    }
    if (k > 0) zip_rings(prev_ids, prev_angles, ids, angles, faces);
    prev_ids = ids, prev_angles = angles;
  }
  TriMesh m;
  m.V.resize(V.size(), 3);
  for (size_t i = 0; i < V.size(); ++i) m.V.row(i) = V[i].transpose();
  m.F.resize(faces.size(), 3);
  for (size_t f = 0; f < faces.size(); ++f) m.F.row(f) = faces[f].transpose();
  return m;
}

// Disk of n rings (6k vertices on ring k), lifted by `lift` from the plane.
TriMesh disk(int n, const std::function<Eigen::Vector3d(double r, double t)>& lift, double twist = 0) {
  return ring_mesh(
      n, [](int k) { return k == 0 ? 1 : 6 * k; }, [twist](int k) { return twist * k; },
      [&](int k, double t) { return lift(static_cast<double>(k) / n, t); });
}

TriMesh hemisphere(int n) {
  return disk(n, [](double r, double t) {
    const double phi = r * M_PI / 2;
    return Eigen::Vector3d(std::sin(phi) * std::cos(t), std::sin(phi) * std::sin(t), std::cos(phi));
  });
}

// Square [-1, 1]^2 as an n x n grid, diagonals alternating.
TriMesh square(int n) {
  TriMesh m;
  m.V.resize((n + 1) * (n + 1), 3);
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) m.V.row(i * (n + 1) + j) << -1 + 2.0 * j / n, -1 + 2.0 * i / n, 0;
  m.F.resize(2 * n * n, 3);
  int f = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const int a = i * (n + 1) + j, b = a + 1, c = a + n + 1, d = c + 1;
      if ((i + j) % 2) {
        m.F.row(f++) << a, b, d;
        m.F.row(f++) << a, d, c;
      } else {
        m.F.row(f++) << a, b, c;
        m.F.row(f++) << b, d, c;
      }
    }
  return m;
}

// Prism tube: `around` vertices per ring of radius 1, `rows` rows up to
// `height`; intrinsically a flat cylinder of circumference around * chord.
TriMesh tube(int around, int rows, double height) {
  return ring_mesh(
      rows, [around](int) { return around; }, [around](int k) { return (k % 2) * M_PI / around; },
      [&](int k, double t) { return Eigen::Vector3d(std::cos(t), std::sin(t), height * k / rows); });
}

// Planar annulus between radii 1 and r1, geometric radial spacing.
TriMesh planar_annulus(int around, int rings, double r1) {
  return ring_mesh(
      rings, [around](int) { return around; }, [around](int k) { return (k % 2) * M_PI / around; },
      [&](int k, double t) {
        const double r = std::pow(r1, static_cast<double>(k) / rings);
        return Eigen::Vector3d(r * std::cos(t), r * std::sin(t), 0);
      });
}

PolygonSoup soup_of(const TriMesh& m) {
  PolygonSoup s;
  s.V = m.V;
  for (int f = 0; f < m.num_faces(); ++f) s.polygons.push_back({m.F(f, 0), m.F(f, 1), m.F(f, 2)});
  return s;
}

TEST(OpenSurfaces, IntakeCountsLoopsAndGenus) {
  const OpenIntakeResult d = intake_open(soup_of(hemisphere(6)));
  EXPECT_EQ(d.topology.genus, 0);
  ASSERT_EQ(d.topology.num_boundary_loops(), 1);
  EXPECT_EQ(d.topology.boundary_loops[0].size(), 36u);
  EXPECT_EQ(d.intake.info.num_boundary_loops, 1);
  // Loop direction: the surface on the left, i.e. consecutive loop vertices
  // run along a face's halfedge.
  const auto& loop = d.topology.boundary_loops[0];
  const TriMesh& m = d.intake.mesh;
  int along = 0;
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k)
      if (m.F(f, k) == loop[0] && m.F(f, (k + 1) % 3) == loop[1]) ++along;
  EXPECT_EQ(along, 1);
  const OpenIntakeResult a = intake_open(soup_of(tube(12, 5, 1.0)));
  EXPECT_EQ(a.topology.genus, 0);
  EXPECT_EQ(a.topology.num_boundary_loops(), 2);
  EXPECT_EQ(a.topology.euler_characteristic, 0);
  // Closed meshes keep refusing boundaries through the ordinary intake.
  EXPECT_THROW(intake(soup_of(hemisphere(4))), InputError);
}

TEST(OpenSurfaces, BowtieBoundaryVertexRefusedByName) {
  // Two squares sharing only vertex 4 (a bowtie on the boundary).
  PolygonSoup s;
  s.V.resize(7, 3);
  s.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 2, 0, 3, 2, 0, 3, 3, 0;
  s.polygons = {{0, 1, 4}, {0, 4, 3}, {1, 2, 4}, {4, 5, 6}};
  try {
    intake_open(s);
    FAIL() << "bowtie accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 4"), std::string::npos) << e.what();
  }
}

TEST(OpenSurfaces, MismatchedTopologyNamesBoth) {
  const OpenIntakeResult d = intake_open(soup_of(hemisphere(4)));
  const OpenIntakeResult a = intake_open(soup_of(tube(12, 4, 1.0)));
  try {
    open_surface_map(d.intake.mesh, d.topology, a.intake.mesh, a.topology);
    FAIL();
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("genus 0 with 1 boundary loop"), std::string::npos) << msg;
    EXPECT_NE(msg.find("genus 0 with 2 boundary loops"), std::string::npos) << msg;
  }
}

TEST(OpenSurfaces, DiskWithoutInteriorVertexIsRefused) {
  TriMesh fan;  // a square of two triangles: every vertex on the boundary
  fan.V.resize(4, 3);
  fan.V << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
  fan.F.resize(2, 3);
  fan.F << 0, 1, 2, 0, 2, 3;
  const OpenSurfaceTopology t = open_surface_topology(fan);
  EXPECT_EQ(t.num_boundary_loops(), 1);
  EXPECT_THROW(disk_conformal_map(fan, t), InputError);
}

TEST(OpenSurfaces, CylinderModulusWithinHalfPercent) {
  // Prism tube: exact modulus height / (around * chord).
  for (const auto& [around, rows, height] : {std::tuple{48, 12, 1.0}, std::tuple{40, 30, 3.0}}) {
    const TriMesh m = tube(around, rows, height);
    const OpenSurfaceTopology t = open_surface_topology(m);
    const OpenConformalResult r = annulus_conformal_map(m, t);
    const double exact = height / (around * 2 * std::sin(M_PI / around));
    EXPECT_NEAR(r.modulus / exact, 1.0, 0.005) << around << " " << rows;
    EXPECT_LE(r.modulus_from_u, r.modulus_from_theta * (1 + 1e-9));  // the bracket (equal: linear on a prism)
    EXPECT_EQ(r.flipped_faces, 0);
    std::cout << "  tube " << around << "x" << rows << ": modulus " << r.modulus << " prism value " << exact << " bracket ["
              << r.modulus_from_u << ", " << r.modulus_from_theta << "]\n";
  }
  // Planar annulus 1 < |z| < 2: modulus ln 2 / 2π (curved boundary: the
  // discretisation error of the inscribed polygons, refined until 0.5%).
  const TriMesh ann = planar_annulus(96, 24, 2.0);
  const OpenConformalResult r = annulus_conformal_map(ann, open_surface_topology(ann));
  EXPECT_NEAR(r.modulus / (std::log(2.0) / (2 * M_PI)), 1.0, 0.005) << r.modulus;
  EXPECT_LT(r.modulus_from_u, r.modulus_from_theta);  // a strict bracket on curved boundaries
  std::cout << "  planar annulus 1..2: modulus " << r.modulus << " exact " << std::log(2.0) / (2 * M_PI) << " bracket ["
            << r.modulus_from_u << ", " << r.modulus_from_theta << "]\n";
}

// W x H rectangle as an n x m grid (alternating diagonals); corners are
// vertices 0 (0, 0), m (W, 0), (n + 1)(m + 1) - 1 (W, H), n (m + 1) (0, H).
TriMesh rectangle(int n, int m, double W, double H) {
  TriMesh r;
  r.V.resize((n + 1) * (m + 1), 3);
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= m; ++j) r.V.row(i * (m + 1) + j) << W * j / m, H * i / n, 0;
  r.F.resize(2 * n * m, 3);
  int f = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const int a = i * (m + 1) + j, b = a + 1, c = a + m + 1, d = c + 1;
      if ((i + j) % 2) {
        r.F.row(f++) << a, b, d;
        r.F.row(f++) << a, d, c;
      } else {
        r.F.row(f++) << a, b, c;
        r.F.row(f++) << b, d, c;
      }
    }
  return r;
}

TEST(OpenSurfaces, RectangleConformalModulusWithinHalfPercent) {
  // The disk map is the free-boundary Riemann map, so the four corners of a
  // W x H rectangle land on the circle with the cross ratio of the
  // rectangle's conformal modulus W / H (Schwarz-Christoffel: corners at
  // -1/k, -1, 1, 1/k of the half plane, width 2K(k), height K(k'), cross
  // ratio ((1 - k) / (1 + k))^2). Nothing here is the solver's: the modulus
  // comes from the corners' images alone.
  auto modulus_of_corners = [](std::complex<double> tl, std::complex<double> bl, std::complex<double> br,
                               std::complex<double> tr) {
    const double lambda = std::abs((bl - tl) * (tr - br) / ((br - tl) * (tr - bl)));
    const double k = (1 - std::sqrt(lambda)) / (1 + std::sqrt(lambda));
    return 2 * std::comp_ellint_1(k) / std::comp_ellint_1(std::sqrt(1 - k * k));
  };
  for (const auto& [W, H, n] : {std::tuple{1.0, 1.0, 24}, std::tuple{2.0, 1.0, 24}, std::tuple{3.0, 1.0, 20}}) {
    const int m = static_cast<int>(std::lround(n * W / H));
    const TriMesh rect = rectangle(n, m, W, H);
    const OpenConformalResult r = disk_conformal_map(rect, open_surface_topology(rect));
    EXPECT_EQ(r.flipped_faces, 0);
    const int bl = 0, br = m, tr = (n + 1) * (m + 1) - 1, tl = n * (m + 1);
    for (int c : {bl, br, tr, tl}) EXPECT_NEAR(std::abs(r.uv[c]), 1.0, 1e-12);
    const double modulus = modulus_of_corners(r.uv[tl], r.uv[bl], r.uv[br], r.uv[tr]);
    EXPECT_NEAR(modulus / (W / H), 1.0, 0.005) << W << " x " << H;
    // The other pair of sides: the reciprocal modulus.
    const double other = modulus_of_corners(r.uv[bl], r.uv[br], r.uv[tr], r.uv[tl]);
    EXPECT_NEAR(other * (W / H), 1.0, 0.005) << W << " x " << H;
    std::cout << "  rectangle " << W << " x " << H << " (" << m << " x " << n << " grid): conformal modulus " << modulus
              << " vs " << W / H << " (" << 100 * (modulus / (W / H) - 1) << "%), reciprocal " << other << "\n";
  }
}

TEST(OpenSurfaces, DiskConformalMapIsCentredAndEmbedded) {
  const TriMesh m = hemisphere(16);
  const OpenConformalResult r = disk_conformal_map(m, open_surface_topology(m));
  EXPECT_EQ(r.flipped_faces, 0);
  double max_radius = 0;
  for (const auto& z : r.uv) max_radius = std::max(max_radius, std::abs(z));
  EXPECT_NEAR(max_radius, 1.0, 1e-12);
  // By symmetry the hemisphere's conformal disk map is radial: the images
  // of one latitude ring share a radius (stereographic: tan(phi/2)).
  int v = 1;
  for (int k = 1; k < 16; ++k) v += 6 * k;  // start of ring 16 (the boundary)
  int ring8 = 1;  // ring 8 starts after 1 + 6 (1 + ... + 7) vertices
  for (int k = 1; k < 8; ++k) ring8 += 6 * k;
  const double expected = std::tan(M_PI / 8) / std::tan(M_PI / 4);  // stereographic radius at phi = pi/4
  for (int j = 0; j < 48; ++j) EXPECT_NEAR(std::abs(r.uv[ring8 + j]), expected, 0.01);
  EXPECT_NEAR(std::abs(r.uv[v]), 1.0, 1e-12);
}

TEST(OpenSurfaces, HemisphereToSquareIsConformalUnderRefinement) {
  double previous = 1e9;
  for (int n : {8, 16, 32}) {
    const TriMesh s = hemisphere(n), t = square(2 * n);
    const OpenMapResult r = open_surface_map(s, open_surface_topology(s), t, open_surface_topology(t));
    EXPECT_EQ(r.map.flipped_triangles, 0) << n;
    EXPECT_EQ(r.map.degenerate_triangles, 0) << n;
    EXPECT_LT(r.map.mean_dilatation, previous) << n;
    previous = r.map.mean_dilatation;
    std::cout << "  hemisphere rings " << n << " (" << s.num_faces() << " faces) -> square " << 2 * n << "x" << 2 * n
              << ": mean D' " << r.map.mean_dilatation << ", max " << r.map.max_dilatation << ", flipped "
              << r.map.flipped_triangles << "\n";
    // Every target vertex has a preimage on the source surface.
    for (const auto& p : r.map.inverse) EXPECT_NEAR(p.position.norm(), 1.0, 0.02);
  }
  EXPECT_LT(previous, 1.05);
}

TEST(OpenSurfaces, RemeshedDiskMapsNearIdentity) {
  // An asymmetric bumpy disk, meshed twice with different rings and twist.
  auto lift = [](double r, double t) {
    const double R = r * (1 + 0.25 * std::cos(t) + 0.1 * std::sin(2 * t));
    const double x = R * std::cos(t), y = R * std::sin(t);
    return Eigen::Vector3d(x, y, 0.3 * x * y + 0.2 * x * x - 0.1 * y);
  };
  const TriMesh a = disk(14, lift), b = disk(19, lift, 0.13);
  const OpenMapResult r = open_surface_map(a, open_surface_topology(a), b, open_surface_topology(b));
  double mean = 0;
  for (int i = 0; i < a.num_vertices(); ++i) mean += (r.map.forward[i].position - a.V.row(i).transpose()).norm();
  mean /= a.num_vertices();
  EXPECT_LT(mean, 0.02) << "mean displacement of the identity map";
  std::cout << "  remeshed disk: mean displacement " << mean << ", mean D' " << r.map.mean_dilatation << "\n";
  EXPECT_EQ(r.map.flipped_triangles, 0);
  EXPECT_LT(r.map.mean_dilatation, 1.05);
}

TEST(OpenSurfaces, AnnulusMapHitsExtremalDilatation) {
  // Tube of modulus ~0.25 -> tube of modulus ~0.5: the affine stretch has
  // D' = ratio of the moduli on every face.
  const TriMesh s = tube(40, 10, 1.0), t = tube(36, 16, 2.0);
  const OpenMapResult r = open_surface_map(s, open_surface_topology(s), t, open_surface_topology(t));
  const double ms = 1.0 / (40 * 2 * std::sin(M_PI / 40)), mt = 2.0 / (36 * 2 * std::sin(M_PI / 36));
  EXPECT_NEAR(r.extremal_dilatation / (mt / ms), 1.0, 0.005);
  EXPECT_NEAR(r.map.mean_dilatation / (mt / ms), 1.0, 0.01) << r.map.mean_dilatation;
  EXPECT_EQ(r.map.flipped_triangles, 0);
  // Planar annulus (modulus ln 2 / 2π) -> tube: conformal ∘ stretch ∘ conformal.
  const TriMesh p = planar_annulus(96, 24, 2.0);
  const OpenMapResult q = open_surface_map(p, open_surface_topology(p), t, open_surface_topology(t));
  const double k = mt / (std::log(2.0) / (2 * M_PI));
  EXPECT_NEAR(q.map.mean_dilatation / k, 1.0, 0.01) << q.map.mean_dilatation << " vs " << k;
  EXPECT_EQ(q.map.flipped_triangles, 0);
  std::cout << "  tube -> tube: mean D' " << r.map.mean_dilatation << " extremal " << mt / ms
            << "; planar annulus -> tube: mean D' " << q.map.mean_dilatation << " extremal " << k << "\n";
}

TEST(OpenSurfaces, AnnulusLoopsCanBeSwapped) {
  const TriMesh s = tube(40, 10, 1.0), t = tube(36, 16, 2.0);
  const OpenSurfaceTopology ts = open_surface_topology(s), tt = open_surface_topology(t);
  OpenMapOptions options;
  options.swap_annulus_loops = true;
  const OpenMapResult r = open_surface_map(s, ts, t, tt, options);
  EXPECT_EQ(r.map.flipped_triangles, 0);
  EXPECT_NEAR(r.map.mean_dilatation / r.extremal_dilatation, 1.0, 0.01);
  // The source's loop 0 lands on the target's loop 1 (and vice versa): by
  // height, the tubes' loops are at z = 0 and z = height.
  const double z_dst_loop1 = t.V(tt.boundary_loops[1][0], 2);
  for (int v : ts.boundary_loops[0]) EXPECT_NEAR(r.map.forward[v].position.z(), z_dst_loop1, 1e-9);
  const OpenMapResult plain = open_surface_map(s, ts, t, tt);
  for (int v : ts.boundary_loops[0])
    EXPECT_NEAR(plain.map.forward[v].position.z(), t.V(tt.boundary_loops[0][0], 2), 1e-9);
}

TEST(OpenSurfaces, AnnulusTwistIsChosenByEnergyAndATwistedStartIsUntwisted) {
  // A planar annulus 1 < |z| < 2 onto a remeshed copy of itself (other ring
  // and sector counts): the Dehn twist about the core is ranked by the
  // morph's energy. From twist 0 the search stays at 0 (both neighbours
  // cost more) and the map is the identity; from a start twisted by 2 turns
  // it steps down 2 -> 1 -> 0 and returns the same map; a twist forced
  // without the search keeps boundary on boundary but moves the middle ring
  // by a half turn, at a higher energy.
  const TriMesh s = planar_annulus(64, 16, 2.0), t = planar_annulus(80, 21, 2.0);
  const OpenSurfaceTopology ts = open_surface_topology(s), tt = open_surface_topology(t);
  auto mean_offset = [&](const OpenMapResult& r) {
    double sum = 0;
    for (int i = 0; i < s.num_vertices(); ++i) sum += (r.map.forward[i].position - s.V.row(i).transpose()).norm();
    return sum / s.num_vertices() / 4.0;  // over the diagonal (4)
  };
  const OpenMapResult plain = open_surface_map(s, ts, t, tt);
  EXPECT_EQ(plain.twist, 0);
  ASSERT_EQ(plain.twist_energies.size(), 3u);  // 0, then +1 and -1
  EXPECT_EQ(plain.twist_energies[0].first, 0);
  EXPECT_GT(plain.twist_energies[1].second, 2 * plain.twist_energies[0].second);
  EXPECT_GT(plain.twist_energies[2].second, 2 * plain.twist_energies[0].second);
  EXPECT_NEAR(plain.map.final_energy, plain.twist_energies[0].second, 1e-9 * plain.map.final_energy);
  EXPECT_LT(mean_offset(plain), 0.005);
  EXPECT_EQ(plain.map.flipped_triangles, 0);

  OpenMapOptions twisted;
  twisted.twist = 2;
  const OpenMapResult back = open_surface_map(s, ts, t, tt, twisted);
  EXPECT_EQ(back.twist, 0);
  std::vector<int> visited;
  for (const auto& [k, e] : back.twist_energies) visited.push_back(k);
  EXPECT_EQ(visited, (std::vector<int>{2, 3, 1, 2, 0, 1, -1}));
  EXPECT_LT(back.twist_energies[2].second, back.twist_energies[0].second);   // 1 below 2
  EXPECT_LT(back.twist_energies[4].second, back.twist_energies[2].second);   // 0 below 1
  for (int i = 0; i < s.num_vertices(); ++i)
    EXPECT_LT((back.map.forward[i].position - plain.map.forward[i].position).norm(), 1e-9) << i;

  OpenMapOptions forced;
  forced.twist = 1;
  forced.twist_search = false;
  const OpenMapResult one = open_surface_map(s, ts, t, tt, forced);
  EXPECT_EQ(one.twist, 1);
  EXPECT_TRUE(one.twist_energies.empty());
  EXPECT_GT(one.map.final_energy, 2 * plain.map.final_energy);
  for (const auto& loop : ts.boundary_loops)
    for (int v : loop) {
      const double r = one.map.forward[v].position.head<2>().norm(), r0 = s.V.row(v).head<2>().norm();
      EXPECT_NEAR(r, r0, 0.01) << v;  // each loop onto its own circle (chords of the other mesh)
    }
  // The loops turn alike (a whole turn apart), the middle ring half a turn
  // against them (whatever the shift the alignment chose).
  auto turn = [&](int v) {
    const Eigen::Vector3d p = one.map.forward[v].position;
    return std::polar(1.0, std::atan2(p.y(), p.x()) - std::atan2(s.V(v, 1), s.V(v, 0)));
  };
  const int inner = 3, outer = 16 * 64 + 3, mid = 8 * 64 + 3;  // rings 0, 16 (the loops), 8
  EXPECT_LT(std::abs(turn(inner) - turn(outer)), 0.1);
  EXPECT_GT(std::abs(turn(mid) - turn(inner)), 1.9);
}

TEST(OpenSurfaces, EarTrianglesAreDegenerateNotFlipped) {
  // A tube with one ear glued onto its top loop: the ear's three corners lie
  // on one boundary loop, so its image on the cylinder is degenerate.
  TriMesh s = tube(40, 10, 1.0);
  const OpenSurfaceTopology before = open_surface_topology(s);
  const auto& top = before.boundary_loops[0][0] == 0 ? before.boundary_loops[1] : before.boundary_loops[0];
  const int a = top[0], b = top[1], nv = s.num_vertices(), nf = s.num_faces();
  const Eigen::Vector3d pa = s.V.row(a), pb = s.V.row(b);
  s.V.conservativeResize(nv + 1, 3);
  s.V.row(nv) = (0.5 * (pa + pb) + Eigen::Vector3d(0, 0, 0.05)).transpose();
  s.F.conservativeResize(nf + 1, 3);
  s.F.row(nf) << b, a, nv;
  const OpenSurfaceTopology with_ear = open_surface_topology(s);
  ASSERT_EQ(with_ear.num_boundary_loops(), 2);
  const TriMesh t = tube(36, 16, 2.0);
  const OpenMapResult r = open_surface_map(s, with_ear, t, open_surface_topology(t));
  EXPECT_EQ(r.ear_triangles, 1);
  EXPECT_EQ(r.ear_triangles_degenerate, 1);
  EXPECT_EQ(r.source_domain.degenerate_faces, 1);
  EXPECT_EQ(r.source_domain.flipped_faces, 0);
  EXPECT_EQ(r.map.flipped_triangles, 0);
  EXPECT_NEAR(r.map.mean_dilatation / r.extremal_dilatation, 1.0, 0.01);
}

// A quad fan around o with an ear (p0, q, p1) below its edge p0 p1, mapped
// by the identity onto the same fan whose boundary between p0 and p1 runs
// through a notch u2 (inside the chord) and, when `bump`, a bump u1
// (outside): q's image on the notch turns the ear over.
struct EarCase {
  TriMesh mesh, other;
  std::vector<PointOnSurface> images;
};

EarCase ear_case(bool bump) {
  EarCase c;
  c.mesh.V.resize(6, 3);
  c.mesh.V << 0, 0, 0, 1, 0, 0, 1, 1.5, 0, 0, 1.5, 0, 0.5, 0.75, 0, 0.5, -0.3, 0;  // p0 p1 p2 p3 o q
  c.mesh.F.resize(5, 3);
  c.mesh.F << 4, 0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 0, 5, 1;
  c.other.V.resize(bump ? 7 : 6, 3);
  c.other.V.topRows(5) = c.mesh.V.topRows(5);
  c.other.V.row(5) << 0.3, 0.15, 0;  // u2: the notch
  if (bump) c.other.V.row(6) << 0.7, -0.3, 0;  // u1: the bump
  if (bump) {
    c.other.F.resize(6, 3);
    c.other.F << 4, 0, 5, 4, 5, 6, 4, 6, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0;
  } else {
    c.other.F.resize(5, 3);
    c.other.F << 4, 0, 5, 4, 5, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0;
  }
  // Each vertex onto the same vertex of `other`, q onto the notch.
  for (int v = 0; v < 6; ++v) {
    const int w = v == 5 ? 5 : v;
    PointOnSurface p;
    for (int f = 0; f < c.other.num_faces() && p.face < 0; ++f)
      for (int k = 0; k < 3; ++k)
        if (c.other.F(f, k) == w) p.face = f, p.barycentric = Eigen::Vector3d::Unit(k);
    p.position = c.other.V.row(w);
    c.images.push_back(p);
  }
  return c;
}

TEST(OpenSurfaces, TurnedEarsImageSlidAlongTheOtherBoundary) {
  // The ear's middle corner q goes from the notch to the bump, the one vertex
  // of the arc between p0's and p1's images where the ear's image is
  // positively oriented; nothing else moves. Without the bump no vertex of
  // any corner's arc will do: the map is left as it was, the ear counted.
  for (const bool bump : {true, false}) {
    EarCase c = ear_case(bump);
    for (int f = 0; f < c.other.num_faces(); ++f) {
      const Eigen::Vector3d a = c.other.V.row(c.other.F(f, 0)), b = c.other.V.row(c.other.F(f, 1)),
                            d = c.other.V.row(c.other.F(f, 2));
      ASSERT_GT((b - a).cross(d - a).z(), 0) << "face " << f;
    }
    const std::vector<PointOnSurface> before = c.images;
    const EarImagesResult r = slide_ear_images(c.mesh, open_surface_topology(c.mesh), c.other,
                                               open_surface_topology(c.other), c.images);
    EXPECT_EQ(r.ears, 1);
    EXPECT_EQ(r.turned, 1);
    EXPECT_EQ(r.moved, bump ? 1 : 0);
    EXPECT_EQ(r.turned_after, bump ? 0 : 1);
    for (int v = 0; v < 5; ++v) EXPECT_LT((c.images[v].position - before[v].position).norm(), 1e-15) << v;
    const Eigen::Vector3d expected = bump ? Eigen::Vector3d(0.7, -0.3, 0) : Eigen::Vector3d(0.3, 0.15, 0);
    EXPECT_LT((c.images[5].position - expected).norm(), 1e-15);
    const PointOnSurface& q = c.images[5];
    Eigen::RowVector3d at = Eigen::RowVector3d::Zero();
    for (int k = 0; k < 3; ++k) at += q.barycentric[k] * c.other.V.row(c.other.F(q.face, k));
    EXPECT_LT((at - q.position.transpose()).norm(), 1e-15);
  }
}

// A square fan (0,0)-(4,0)-(4,3)-(0,3) around o whose bottom side carries an
// ear (a, b, c) below the chord a c, mapped onto a fan of the same square
// whose bottom side zigzags: notch u1, bump u2, notch u3. a's and c's images
// lie on the edges either side of the notch u1 and b's on it, so the arc
// between a's and c's images holds no vertex but the notch: the middle
// corner alone cannot right the ear; sliding a, b and c together can.
struct WindowEarCase {
  TriMesh mesh, other;
  std::vector<PointOnSurface> images;
};

WindowEarCase window_ear_case() {
  WindowEarCase c;
  c.mesh.V.resize(8, 3);
  c.mesh.V << 0, 0, 0, 0.5, 0, 0, 1, -0.3, 0, 1.5, 0, 0, 4, 0, 0, 4, 3, 0, 0, 3, 0, 2, 1.5, 0;  // p0 a b c p4 . . o
  c.mesh.F.resize(7, 3);
  c.mesh.F << 0, 1, 7, 1, 3, 7, 1, 2, 3, 3, 4, 7, 4, 5, 7, 5, 6, 7, 6, 0, 7;
  c.other.V.resize(8, 3);
  c.other.V << 0, 0, 0, 1, 0.15, 0, 2, -0.15, 0, 3, 0.15, 0, 4, 0, 0, 4, 3, 0, 0, 3, 0, 2, 1.5, 0;  // u0 .. u4 . . o
  c.other.F.resize(7, 3);
  c.other.F << 0, 1, 7, 1, 2, 7, 2, 3, 7, 3, 4, 7, 4, 5, 7, 5, 6, 7, 6, 0, 7;
  auto on_edge = [&](int f, int i, int j, double t) {  // the point (1 - t) u_i + t u_j of other's face f
    PointOnSurface p;
    p.face = f;
    p.barycentric.setZero();
    for (int k = 0; k < 3; ++k) {
      if (c.other.F(f, k) == i) p.barycentric[k] += 1 - t;
      if (c.other.F(f, k) == j) p.barycentric[k] += t;
    }
    p.position = (1 - t) * c.other.V.row(i).transpose() + t * c.other.V.row(j).transpose();
    return p;
  };
  c.images = {on_edge(0, 0, 1, 0.0), on_edge(0, 0, 1, 0.5), on_edge(1, 1, 2, 0.0), on_edge(1, 1, 2, 0.5),
              on_edge(4, 4, 5, 0.0), on_edge(4, 5, 4, 0.0), on_edge(5, 6, 7, 0.0), on_edge(0, 7, 0, 0.0)};
  return c;
}

TEST(OpenSurfaces, TurnedEarRightedByAWindowWhenItsMiddleCornerCannot) {
  const auto positive = [](const WindowEarCase& c, int f) {
    const Eigen::Vector3d a = c.images[c.mesh.F(f, 0)].position, b = c.images[c.mesh.F(f, 1)].position,
                          d = c.images[c.mesh.F(f, 2)].position;
    return (b - a).cross(d - a).z() > 1e-12;
  };
  {  // the fixture: every face of both fans and every image but the ear's positively oriented
    const WindowEarCase c = window_ear_case();
    for (int f = 0; f < 7; ++f) {
      const Eigen::Vector3d a = c.mesh.V.row(c.mesh.F(f, 0)), b = c.mesh.V.row(c.mesh.F(f, 1)),
                            d = c.mesh.V.row(c.mesh.F(f, 2));
      ASSERT_GT((b - a).cross(d - a).z(), 0) << "face " << f;
      const Eigen::Vector3d u = c.other.V.row(c.other.F(f, 0)), v = c.other.V.row(c.other.F(f, 1)),
                            w = c.other.V.row(c.other.F(f, 2));
      ASSERT_GT((v - u).cross(w - u).z(), 0) << "other face " << f;
      ASSERT_EQ(positive(c, f), f != 2) << "image of face " << f;
    }
  }
  const WindowEarCase start = window_ear_case();
  const OpenSurfaceTopology mt = open_surface_topology(start.mesh), ot = open_surface_topology(start.other);
  for (const int max_half_window : {0, 1, 2}) {
    WindowEarCase c = window_ear_case();
    EarImagesOptions options;
    options.max_half_window = max_half_window;
    const EarImagesResult r = slide_ear_images(c.mesh, mt, c.other, ot, c.images, options);
    EXPECT_EQ(r.ears, 1);
    EXPECT_EQ(r.turned, 1);
    EXPECT_EQ(r.moved, max_half_window > 0 ? 1 : 0) << max_half_window;
    EXPECT_EQ(r.moved_with_neighbours, r.moved);
    EXPECT_EQ(r.turned_after, max_half_window > 0 ? 0 : 1);
    for (int f = 0; f < 7; ++f) EXPECT_EQ(positive(c, f), max_half_window > 0 || f != 2) << f;
    // Only the window's images move, along the bottom side (y within the zigzag, x in order).
    for (int v : {0, 4, 5, 6, 7}) EXPECT_LT((c.images[v].position - start.images[v].position).norm(), 1e-15) << v;
    double x = 0;
    for (int v : {1, 2, 3}) {
      const Eigen::Vector3d p = c.images[v].position;
      EXPECT_GT(p.x(), x) << v;
      EXPECT_LT(std::abs(p.y()), 0.15 + 1e-12) << v;
      x = p.x();
      Eigen::RowVector3d at = Eigen::RowVector3d::Zero();
      for (int k = 0; k < 3; ++k) at += c.images[v].barycentric[k] * c.other.V.row(c.other.F(c.images[v].face, k));
      EXPECT_LT((at - p.transpose()).norm(), 1e-12) << v;
    }
    EXPECT_LT(x, 4.0);
  }
  {  // b held (a landmark) on the notch: no choice of a's and c's images rights the ear, so nothing moves
    WindowEarCase c = window_ear_case();
    EarImagesOptions options;
    options.held = {2};
    const EarImagesResult r = slide_ear_images(c.mesh, mt, c.other, ot, c.images, options);
    EXPECT_EQ(r.moved, 0);
    EXPECT_EQ(r.turned_after, 1);
    for (int v = 0; v < 8; ++v) EXPECT_LT((c.images[v].position - start.images[v].position).norm(), 1e-15) << v;
  }
}

TEST(OpenSurfaces, EarsOfACoarseMaskOnAJaggedLoopAreRighted) {
  // A coarse disk (a square grid: its corners are ears) onto a finer disk
  // whose rim zigzags (every other rim vertex pulled in): many ears' chord
  // images span a notch of the rim. Both directions, after the slide no ear
  // image turns over in 3D, boundary stays on boundary.
  const TriMesh sq = square(6);
  const TriMesh jag = disk(10, [](double r, double t) {
    const int k = static_cast<int>(std::lround(t / (2 * M_PI) * 60));
    const double rim = r >= 1.0 - 1e-12 && k % 2 ? 0.93 : 1.0;
    return Eigen::Vector3d(r * rim * std::cos(t), r * rim * std::sin(t), 0.0);
  });
  int turned_before = 0;
  for (const auto& [s, t] : {std::pair<const TriMesh*, const TriMesh*>{&sq, &jag}, {&jag, &sq}}) {
    const OpenSurfaceTopology ts = open_surface_topology(*s), tt = open_surface_topology(*t);
    const OpenMapResult r = open_surface_map(*s, ts, *t, tt);
    std::cout << "  ears: forward " << r.forward_ears.ears << " (" << r.forward_ears.turned << " turned, "
              << r.forward_ears.moved << " righted, " << r.forward_ears.turned_after << " left); inverse "
              << r.inverse_ears.ears << " (" << r.inverse_ears.turned << " turned, " << r.inverse_ears.moved
              << " righted, " << r.inverse_ears.turned_after << " left)\n";
    turned_before += r.forward_ears.turned + r.inverse_ears.turned;
    EXPECT_EQ(r.forward_ears.turned_after + r.inverse_ears.turned_after, 0);
    EXPECT_EQ(r.map.flipped_triangles, 0);
    // Counted here: every source face's image (3D chord) against +z.
    for (const auto& [m, o, pts] : {std::tuple<const TriMesh*, const TriMesh*, const std::vector<PointOnSurface>*>{
                                        s, t, &r.map.forward},
                                    {t, s, &r.map.inverse}}) {
      int turned = 0;
      for (int f = 0; f < m->num_faces(); ++f) {
        const Eigen::Vector3d a = (*pts)[m->F(f, 0)].position, b = (*pts)[m->F(f, 1)].position,
                              c = (*pts)[m->F(f, 2)].position;
        turned += (b - a).cross(c - a).z() <= 1e-12 * std::max((b - a).squaredNorm(), (c - a).squaredNorm());
      }
      EXPECT_EQ(turned, 0);
    }
  }
  EXPECT_GT(turned_before, 0);  // the chord images did turn over
}

TEST(OpenSurfaces, BoundaryOntoTheTargetsBoundaryPastItsEars) {
  // Ears glued onto every other edge of a tube's top loop: each ear's inner
  // edge (a chord of the loop) lies on the cylinder's boundary line as well,
  // and a boundary point located on a chord landed there in 3D, off the
  // target's boundary (a holed sphere: 1.8% of the diagonal). Every boundary
  // vertex of the source must land on the paired loop's polyline, and each
  // target boundary vertex on the source's, both directions.
  TriMesh eared = tube(40, 10, 1.0);
  {
    const OpenSurfaceTopology t0 = open_surface_topology(eared);
    const auto& top = eared.V(t0.boundary_loops[0][0], 2) > 0.5 ? t0.boundary_loops[0] : t0.boundary_loops[1];
    const int nv = eared.num_vertices(), nf = eared.num_faces(), n = static_cast<int>(top.size());
    eared.V.conservativeResize(nv + n / 2, 3);
    eared.F.conservativeResize(nf + n / 2, 3);
    for (int k = 0; k < n / 2; ++k) {
      const int a = top[2 * k], b = top[(2 * k + 1) % n];
      eared.V.row(nv + k) = (0.5 * (eared.V.row(a) + eared.V.row(b)) + Eigen::RowVector3d(0, 0, 0.05));
      eared.F.row(nf + k) << b, a, nv + k;
    }
  }
  const TriMesh plain = tube(36, 16, 2.0);
  auto distance_to_loop = [](const TriMesh& m, const std::vector<int>& loop, const Eigen::Vector3d& p) {
    double best = 1e300;
    for (size_t i = 0; i < loop.size(); ++i) {
      const Eigen::Vector3d a = m.V.row(loop[i]), b = m.V.row(loop[(i + 1) % loop.size()]);
      const double t = std::clamp((p - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
      best = std::min(best, (a + t * (b - a) - p).norm());
    }
    return best;
  };
  for (const auto& [s, t] : {std::pair<const TriMesh*, const TriMesh*>{&plain, &eared}, {&eared, &plain}}) {
    const OpenSurfaceTopology ts = open_surface_topology(*s), tt = open_surface_topology(*t);
    ASSERT_EQ(tt.num_boundary_loops(), 2);
    const OpenMapResult r = open_surface_map(*s, ts, *t, tt);
    double worst = 0, worst_back = 0;
    for (int i = 0; i < 2; ++i) {
      for (int v : ts.boundary_loops[i])
        worst = std::max(worst, distance_to_loop(*t, tt.boundary_loops[r.boundary_pairing[i]], r.map.forward[v].position));
      for (int v : tt.boundary_loops[r.boundary_pairing[i]])
        worst_back = std::max(worst_back, distance_to_loop(*s, ts.boundary_loops[i], r.map.inverse[v].position));
    }
    EXPECT_LT(worst, 1e-12);
    EXPECT_LT(worst_back, 1e-12);
    EXPECT_EQ(r.map.flipped_triangles, 0);
  }
}

TEST(OpenSurfaces, BoundaryPairingByIndexIsTheSwapAndTheReportNamesBothSides) {
  const TriMesh s = tube(40, 10, 1.0), t = tube(36, 16, 2.0);
  const OpenSurfaceTopology ts = open_surface_topology(s), tt = open_surface_topology(t);
  OpenMapOptions swap, by_index;
  swap.swap_annulus_loops = true;
  by_index.boundary_pairing = {1, 0};
  const OpenMapResult a = open_surface_map(s, ts, t, tt, swap), b = open_surface_map(s, ts, t, tt, by_index);
  EXPECT_EQ(a.boundary_pairing, (std::vector<int>{1, 0}));
  EXPECT_EQ(b.boundary_pairing, (std::vector<int>{1, 0}));
  for (int v = 0; v < s.num_vertices(); ++v)
    EXPECT_LT((a.map.forward[v].position - b.map.forward[v].position).norm(), 1e-12);
  const nlohmann::json report = to_json(b, by_index);
  EXPECT_EQ(report["source_topology"]["genus"], 0);
  EXPECT_EQ(report["source_topology"]["boundary_loops"], 2);
  EXPECT_EQ(report["target_topology"]["boundary_loops"], 2);
  EXPECT_EQ(report["open"]["boundary_pairing"], nlohmann::json::array({1, 0}));
  EXPECT_EQ(report["method"], "open");
  EXPECT_EQ(report["flipped_triangles"], b.map.flipped_triangles);
  EXPECT_DOUBLE_EQ(report["distortion"]["mean"].get<double>(), b.map.mean_dilatation);
  // Not a permutation: one line naming the pairing.
  for (const std::vector<int>& bad : {std::vector<int>{0, 0}, std::vector<int>{0}, std::vector<int>{0, 2}}) {
    OpenMapOptions o;
    o.boundary_pairing = bad;
    try {
      open_surface_map(s, ts, t, tt, o);
      ADD_FAILURE() << "accepted a bad pairing";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("boundary pairing ["), std::string::npos) << e.what();
    }
  }
}


// Rows of isosceles triangles with apex angle 2 atan(aspect / 2) (152 deg
// for aspect 8): row i shifted by half a cell when odd, so every triangle
// has its apex on the next row. `around` > 0 wraps the rows into a tube of
// that many cells (an annulus); otherwise a strip of `cells` cells (a disk),
// bent (z = sin(pi x) / 10) so the surface is not planar.
TriMesh obtuse_rows(int cells, int rows, double aspect, bool tube_shape) {
  const double w = 1.0 / cells, h = w / aspect;
  // Row i's x coordinates: tube: j w (+ w / 2 when odd); strip: the same
  // plus, on odd rows, the ends 0 and 1 so the strip has straight sides.
  std::vector<std::vector<double>> xs(rows + 1);
  for (int i = 0; i <= rows; ++i) {
    if (!tube_shape && i % 2) xs[i].push_back(0.0);
    for (int j = 0; j < cells + (tube_shape || i % 2 ? 0 : 1); ++j) xs[i].push_back((j + 0.5 * (i % 2)) * w);
    if (!tube_shape && i % 2) xs[i].push_back(1.0);
  }
  std::vector<int> first(rows + 2, 0);
  for (int i = 0; i <= rows; ++i) first[i + 1] = first[i] + static_cast<int>(xs[i].size());
  TriMesh m;
  m.V.resize(first[rows + 1], 3);
  for (int i = 0; i <= rows; ++i)
    for (size_t j = 0; j < xs[i].size(); ++j) {
      const double x = xs[i][j], y = i * h;
      if (tube_shape)
        m.V.row(first[i] + j) << std::cos(2 * M_PI * x) / (2 * M_PI), std::sin(2 * M_PI * x) / (2 * M_PI), y;
      else
        m.V.row(first[i] + j) << x, y, 0.1 * std::sin(M_PI * x);
    }
  std::vector<std::array<int, 3>> faces;
  for (int i = 0; i < rows; ++i) {
    const std::vector<double>&lower = xs[i], &upper = xs[i + 1];
    const int nl = static_cast<int>(lower.size()), nu = static_cast<int>(upper.size());
    auto L = [&](int p) { return first[i] + p % nl; };
    auto U = [&](int q) { return first[i + 1] + q % nu; };
    // Zip the two rows from left to right (the tube's rows wrap around: one
    // more step on each, back to the first vertex).
    const int end_l = tube_shape ? nl : nl - 1, end_u = tube_shape ? nu : nu - 1;
    auto x_of = [&](const std::vector<double>& row, int p) { return p < static_cast<int>(row.size()) ? row[p] : 1.0 + row[0]; };
    int p = 0, q = 0;
    while (p < end_l || q < end_u) {
      if (q == end_u || (p < end_l && x_of(lower, p + 1) <= x_of(upper, q + 1)))
        faces.push_back({L(p), L(p + 1), U(q)}), ++p;
      else
        faces.push_back({L(p), U(q + 1), U(q)}), ++q;
    }
  }
  m.F.resize(static_cast<int>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) m.F.row(static_cast<int>(f)) << faces[f][0], faces[f][1], faces[f][2];
  return m;
}

double largest_angle_degrees(const TriMesh& m, int f) {
  double best = 0;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d c = m.V.row(m.F(f, k)), a = m.V.row(m.F(f, (k + 1) % 3)), b = m.V.row(m.F(f, (k + 2) % 3));
    best = std::max(best, std::acos(std::clamp((a - c).normalized().dot((b - c).normalized()), -1.0, 1.0)));
  }
  return best * 180 / M_PI;
}

TEST(OpenSurfaces, ObtuseTrianglesMapWithIntrinsicDelaunayWeights) {
  // Every triangle has an angle above 150 degrees, so the mesh's own
  // cotangent weights are negative across most interior edges; the
  // intrinsic Delaunay weights are not, and the maps have no flipped face.
  for (const bool tube_shape : {false, true}) {
    const TriMesh m = obtuse_rows(tube_shape ? 40 : 24, tube_shape ? 60 : 40, 8.0, tube_shape);
    const OpenSurfaceTopology t = open_surface_topology(m);
    ASSERT_EQ(t.genus, 0);
    ASSERT_EQ(t.num_boundary_loops(), tube_shape ? 2 : 1);
    int obtuse = 0;
    for (int f = 0; f < m.num_faces(); ++f) obtuse += largest_angle_degrees(m, f) > 150;
    EXPECT_GT(obtuse, m.num_faces() / 2);
    const OpenConformalResult r = tube_shape ? annulus_conformal_map(m, t) : disk_conformal_map(m, t);
    OpenConformalOptions own_options;
    own_options.weights = OpenConformalWeights::own;
    const OpenConformalResult own = tube_shape ? annulus_conformal_map(m, t, own_options) : disk_conformal_map(m, t, own_options);
    EXPECT_GT(r.own_negative_weights, m.num_faces() / 4);  // the test is meaningful: own weights are negative
    EXPECT_EQ(own.negative_weights, own.own_negative_weights);
    if (!tube_shape) EXPECT_GT(own.flipped_faces, 0);  // and they fold the disk's map
    EXPECT_GT(r.intrinsic_flips, 0);
    EXPECT_EQ(r.weights, OpenConformalWeights::intrinsic);
    EXPECT_EQ(r.flipped_faces, 0);
    EXPECT_EQ(r.degenerate_faces, 0);
    for (const auto& z : r.uv) EXPECT_TRUE(std::isfinite(z.real()) && std::isfinite(z.imag()));
    std::cout << "  " << (tube_shape ? "annulus" : "disk") << " " << m.num_faces() << " faces, " << obtuse
              << " with an angle > 150 deg: own weights " << r.own_negative_weights << " negative, "
              << own.flipped_faces << " flipped; intrinsic " << r.intrinsic_flips << " flips, " << r.negative_weights
              << " negative, " << r.flipped_faces << " flipped (first " << r.intrinsic_flipped_faces << ", kept "
              << r.kept_faces << ")";
    if (tube_shape) std::cout << ", modulus " << r.modulus << " (own " << own.modulus << ")";
    std::cout << "\n";
  }
}

}  // namespace
}  // namespace surfmap
