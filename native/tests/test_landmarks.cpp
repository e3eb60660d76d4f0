// Landmarks (paper §VII-C): source vertices held on their target vertices
// for genus >= 1 (map/landmarks.h); genus 0 is in test_spherical_map.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/map/harmonic_relaxation.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/samples/shapes.h"

namespace surfmap {
namespace {

int nearest_vertex(const TriMesh& m, const Eigen::Vector3d& p) {
  int best = 0;
  (m.V.rowwise() - p.transpose()).rowwise().squaredNorm().minCoeff(&best);
  return best;
}

void expect_landmarks_hit(const SurfaceMapResult& m, const TriMesh& source, const TriMesh& target,
                          const SurfaceMapOptions& o) {
  for (const auto& [s, t] : o.landmarks) {
    EXPECT_LT((m.forward[s].position - target.V.row(t).transpose()).norm(), 1e-12) << s << " -> " << t;
    EXPECT_LT((m.inverse[t].position - source.V.row(s).transpose()).norm(), 1e-12) << s << " -> " << t;
    const auto& b = m.forward[s].barycentric;
    EXPECT_DOUBLE_EQ(b.maxCoeff(), 1.0);
    EXPECT_EQ(target.F(m.forward[s].face, [&] { int k; b.maxCoeff(&k); return k; }()), t);
  }
  // Where the solve and the location put it before it was set onto its
  // vertex: the held landmark really is on the target vertex.
  EXPECT_LT(m.max_landmark_error, 1e-9);
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_EQ(m.degenerate_triangles, 0);
  // The held map is the optimum of the held problem: no worse than its
  // Tutte-type initial map holding the same lifts.
  EXPECT_LE(m.final_energy, m.initial_energy * (1 + 1e-12));
}

TEST(LandmarksFlat, OneLandmarkIsATranslation) {
  // The flat optimum is unique up to translation, so holding one vertex
  // anywhere costs nothing: same energy, every vertex moved by the same
  // translation of the torus.
  const TriMesh a = samples::torus_of_revolution(1.0, 0.5, 60, 30);
  const TriMesh b = samples::torus_of_revolution(1.5, 0.5, 75, 30, 1);
  const SurfaceMapResult free = surface_map(a, b);
  for (const auto& pair : {std::pair{0, 0}, std::pair{17, 1234}, std::pair{900, 77}}) {
    SurfaceMapOptions o;
    o.landmarks = {pair};
    const SurfaceMapResult m = surface_map(a, b, o);
    expect_landmarks_hit(m, a, b, o);
    EXPECT_NEAR(m.final_energy, free.final_energy, 1e-9 * free.final_energy);
    EXPECT_NEAR(m.mean_dilatation, free.mean_dilatation, 1e-6);
    EXPECT_EQ(m.chosen_candidate, free.chosen_candidate);
  }
}

TEST(LandmarksFlat, ConsistentLandmarksHitExactlyWithoutFlips) {
  // Landmarks where the free map (nearly) sends them, on a sliver source:
  // hit exactly, no flips, and holding them can only raise the energy.
  const TriMesh a = samples::n_hole_torus(1, 34, false);
  const TriMesh b = samples::torus_of_revolution(1.3, 0.45, 80, 36);
  const SurfaceMapResult free = surface_map(a, b);
  ASSERT_EQ(free.flipped_triangles, 0);
  const int picks[] = {3, a.num_vertices() / 3, (2 * a.num_vertices()) / 3};
  for (int k = 1; k <= 3; ++k) {
    SurfaceMapOptions o;
    for (int q = 0; q < k; ++q) o.landmarks.emplace_back(picks[q], nearest_vertex(b, free.forward[picks[q]].position));
    const SurfaceMapResult m = surface_map(a, b, o);
    expect_landmarks_hit(m, a, b, o);
    EXPECT_GE(m.final_energy, free.final_energy * (1 - 1e-12));
    EXPECT_LT(m.final_energy, 1.05 * free.final_energy) << k;  // consistent landmarks cost little
  }
}

TEST(LandmarksFlat, LandmarksAwayFromTheFreeMapRaiseTheEnergyAndStayBijective) {
  // Vertex 34 u + v of each torus grid sits at angles (2π u/n, 2π v/34).
  const TriMesh a = samples::torus_of_revolution(1.0, 0.45, 64, 34);
  const TriMesh b = samples::torus_of_revolution(1.4, 0.5, 64, 34, 2);
  SurfaceMapOptions o;
  o.landmarks = {{0, 0}};
  const SurfaceMapResult one = surface_map(a, b, o);
  // Where the map holding vertex 0 sends vertex s, in grid coordinates of b.
  const int s = 34 * 20 + 5, t = nearest_vertex(b, one.forward[s].position);
  auto grid = [](int u, int v) { return 34 * ((u % 64 + 64) % 64) + (v % 34 + 34) % 34; };
  // The second landmark two cells off: hit, no flips, a higher energy.
  o.landmarks = {{0, 0}, {s, grid(t / 34 + 2, t % 34 + 1)}};
  const SurfaceMapResult m = surface_map(a, b, o);
  expect_landmarks_hit(m, a, b, o);
  EXPECT_GT(m.final_energy, one.final_energy * 1.0001);
  // A quarter turn off (16 columns, ~16 edge lengths): the plain pins fold;
  // the interior-point continuation holds both without a flip.
  o.landmarks = {{0, 0}, {s, grid(t / 34 + 16, t % 34)}};
  const SurfaceMapResult q = surface_map(a, b, o);
  expect_landmarks_hit(q, a, b, o);
  EXPECT_EQ(q.landmark_method, "barrier continuation");
  EXPECT_GT(q.final_energy, m.final_energy);
}

// Target vertices along a shortest edge path from `from` towards the target
// vertex farthest from it (path[k] is k edges away).
std::vector<int> path_away(const TriMesh& m, int from) {
  std::vector<std::vector<int>> nb(m.num_vertices());
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) nb[m.F(f, k)].push_back(m.F(f, (k + 1) % 3)), nb[m.F(f, (k + 1) % 3)].push_back(m.F(f, k));
  int far = 0;
  (m.V.rowwise() - m.V.row(from)).rowwise().squaredNorm().maxCoeff(&far);
  std::vector<int> prev(m.num_vertices(), -2), queue{from};
  prev[from] = -1;
  for (size_t q = 0; q < queue.size(); ++q)
    for (int v : nb[queue[q]])
      if (prev[v] == -2) prev[v] = queue[q], queue.push_back(v);
  std::vector<int> path;
  for (int v = far; v >= 0; v = prev[v]) path.push_back(v);
  return {path.rbegin(), path.rend()};
}

double mean_edge(const TriMesh& m) {
  double s = 0;
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) s += (m.V.row(m.F(f, k)) - m.V.row(m.F(f, (k + 1) % 3))).norm();
  return s / (3.0 * m.num_faces());
}

TEST(LandmarksFlat, FarLandmarksStayBijectiveByInteriorPointContinuation) {
  // A landmark 20 edges (19 edge lengths, 0.46 of the diagonal) from where
  // the free map puts it: the plain pins fold (the held optimum is unique,
  // so no continuation of it helps); the barrier continuation moves the
  // landmarks there with the map bijective at every step.
  const TriMesh a = samples::torus_of_revolution(1.0, 0.45, 64, 34);
  const TriMesh b = samples::torus_of_revolution(1.4, 0.5, 64, 34, 2);
  const SurfaceMapResult free = surface_map(a, b);
  const int s = 34 * 20 + 5;
  const std::vector<int> path = path_away(b, nearest_vertex(b, free.forward[s].position));
  ASSERT_GT(path.size(), 21u);
  const int t = path[20];
  EXPECT_GT((b.V.row(t).transpose() - free.forward[s].position).norm(), 15 * mean_edge(b));
  SurfaceMapOptions o;
  o.landmarks = {{0, nearest_vertex(b, free.forward[0].position)}, {s, t}};
  HarmonicProblem problem;
  o.inspect_problem = [&](const HarmonicProblem& p) { problem = p; };
  const SurfaceMapResult m = surface_map(a, b, o);
  expect_landmarks_hit(m, a, b, o);
  EXPECT_EQ(m.landmark_method, "barrier continuation");
  EXPECT_GT(m.landmark_solves, 2);
  // Energy recomputed from the returned cover positions and the problem's
  // own edges, weights and translations; it lies above the (folded) plain
  // pinned optimum, the infimum without bijectivity, and not far above.
  ASSERT_TRUE(problem.flat);
  const auto& z = m.source_image;
  double E = 0;
  for (size_t e = 0; e < problem.flat_i.size(); ++e)
    E += problem.flat_weight[e] * std::norm(z[problem.flat_j[e]] + problem.flat_translation[e] - z[problem.flat_i[e]]);
  EXPECT_NEAR(E, m.final_energy, 1e-9 * m.final_energy);
  const double pinned = m.candidates[m.chosen_candidate].landmark_energy;
  EXPECT_GT(m.final_energy, pinned * (1 + 1e-6));
  EXPECT_LT(m.final_energy, 1.15 * pinned);
  EXPECT_GT(m.final_energy, free.final_energy * 1.01);
}

TEST(LandmarksHyperbolic, FarLandmarkStaysBijective) {
  // Genus 2: a landmark 8 edges (10.8 mean edge lengths) from its free
  // image. Its plain pin folds the map (refused before); with its
  // neighbourhood carried along the geodesic it is hit exactly, no flips.
  const TriMesh a = samples::n_hole_torus(2, 20, true);
  const TriMesh b = samples::vase(24, true);
  const SurfaceMapResult free = surface_map(a, b);
  const int s = a.num_vertices() / 3;
  const std::vector<int> path = path_away(b, nearest_vertex(b, free.forward[s].position));
  ASSERT_GT(path.size(), 9u);
  SurfaceMapOptions o;
  o.landmarks = {{s, path[8]}};
  EXPECT_GT((b.V.row(path[8]).transpose() - free.forward[s].position).norm(), 10 * mean_edge(b));
  const SurfaceMapResult m = surface_map(a, b, o);
  expect_landmarks_hit(m, a, b, o);
  EXPECT_TRUE(m.converged);
  ASSERT_EQ(m.landmark_rings.size(), 1u);
  EXPECT_GT(m.landmark_rings[0], 0);
  EXPECT_GT(m.final_energy, free.final_energy * 1.001);
}

TEST(LandmarksHyperbolic, LandmarksTooFarAreRefusedByName) {
  // 10 edges on this coarse genus-2 source (a third of the way round): the
  // carried neighbourhood would hold half the source; refused, naming it.
  const TriMesh a = samples::n_hole_torus(2, 14, true);
  const TriMesh b = samples::vase(18, true);
  const SurfaceMapResult free = surface_map(a, b);
  const int s = a.num_vertices() / 3;
  const std::vector<int> path = path_away(b, nearest_vertex(b, free.forward[s].position));
  SurfaceMapOptions o;
  o.landmarks = {{s, path[10]}};
  o.homotopy = free.chosen_candidate;  // this class only
  try {
    surface_map(a, b, o);
    FAIL() << "a map was returned";
  } catch (const SolveError& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("landmark 0 (" + std::to_string(s) + " -> " + std::to_string(path[10]) + ")"), std::string::npos) << w;
    EXPECT_NE(w.find("cannot be held without folding the map in this homotopy class"), std::string::npos) << w;
  }
}

TEST(LandmarksHyperbolic, RelaxationHoldsThemLikeNewton) {
  // The paper's per-vertex relaxation with the landmarks' vertices skipped
  // solves the same held problem as Newton: same energy, same map.
  const TriMesh a = samples::n_hole_torus(2, 14, true);
  const TriMesh b = samples::vase(18, true);
  const SurfaceMapResult free = surface_map(a, b);
  SurfaceMapOptions o;
  for (int p : {11, a.num_vertices() / 3, (2 * a.num_vertices()) / 3})
    o.landmarks.emplace_back(p, nearest_vertex(b, free.forward[p].position));
  const SurfaceMapResult newton = surface_map(a, b, o);
  expect_landmarks_hit(newton, a, b, o);
  o.method = MapMethod::Relaxation;
  o.tolerance = 1e-7;
  o.max_iterations = 100000;
  const SurfaceMapResult relax = surface_map(a, b, o);
  expect_landmarks_hit(relax, a, b, o);
  EXPECT_TRUE(relax.converged);
  EXPECT_GT(relax.iterations, newton.iterations);  // sweeps, not Newton steps
  EXPECT_NEAR(relax.final_energy, newton.final_energy, 1e-8 * newton.final_energy);
  EXPECT_GT(relax.final_energy, free.final_energy * (1 + 1e-6));  // the landmarks did move the map
  const double diag = (b.V.colwise().maxCoeff() - b.V.colwise().minCoeff()).norm();
  double worst = 0;
  for (int i = 0; i < a.num_vertices(); ++i)
    worst = std::max(worst, (relax.forward[i].position - newton.forward[i].position).norm());
  EXPECT_LT(worst, 1e-4 * diag);
}

TEST(Landmarks, BadPairsAreInputErrors) {
  const TriMesh a = samples::torus_of_revolution(1.0, 0.5, 20, 10);
  SurfaceMapOptions o;
  o.landmarks = {{0, 1000}};
  EXPECT_THROW(surface_map(a, a, o), InputError);
  o.landmarks = {{0, 1}, {0, 2}};
  EXPECT_THROW(surface_map(a, a, o), InputError);
  o.landmarks = {{0, 1}, {3, 1}};
  EXPECT_THROW(surface_map(a, a, o), InputError);
  o.landmarks = {{-1, 1}};
  EXPECT_THROW(surface_map(a, a, o), InputError);
}

}  // namespace
}  // namespace surfmap
