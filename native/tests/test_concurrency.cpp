// Stage concurrency of the genus >= 2 pipeline (src/map/concurrency.h):
// the coarse class solves run on two threads and the initial map next to
// the full-resolution solves. Same results as in order, callbacks only on
// the calling thread, cancellation from either kind of callback.
#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <cmath>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/samples/shapes.h"
#include "certify_helpers.h"

namespace surfmap {
namespace {

struct Pair {
  TriMesh a = samples::n_hole_torus(2, 36, true);
  TriMesh b = samples::vase(40, true);
};

const Pair& pair() {
  static const Pair p;
  return p;
}

// One way, no through-shape step (no run may follow, so the main run's
// stages report their fractions as they are: 0.3 at the target's end, 0.4
// at the source side's, 0.6 at the ranking's), every report kept in `seen`.
SurfaceMapOptions one_way_reporting_to(std::vector<std::pair<std::string, double>>& seen, int threads = 0) {
  SurfaceMapOptions o;
  o.threads = threads;
  o.homotopy.two_way = false;
  o.homotopy.through_shape = false;
  o.progress = [&seen](const std::string& s, double f) {
    seen.emplace_back(s, f);
    return true;
  };
  return o;
}

TEST(SurfaceMapConcurrency, TwoThreadsGiveTheMapOfOneAndCallBackOnTheCallingThread) {
  const Pair& p = pair();
  // Big enough for the coarse ranking (at least 2000 source vertices), so
  // that both parallel sections run.
  ASSERT_GE(p.a.num_vertices(), 2000);
  SurfaceMapOptions o1, o2;
  o1.threads = 1;
  o2.threads = 2;
  o1.initial.locate = o2.initial.locate = true;  // (located on the other thread with two: compared below)
  const std::thread::id me = std::this_thread::get_id();
  int calls = 0, foreign = 0;
  std::vector<std::string> stages;
  o2.progress = [&](const std::string& s, double) {
    ++calls, foreign += std::this_thread::get_id() != me;
    if (stages.empty() || stages.back() != s) stages.push_back(s);
    return true;
  };
  o2.solve_progress = [&](int, double, double) {
    ++calls, foreign += std::this_thread::get_id() != me;
    return true;
  };
  const SurfaceMapResult m1 = surface_map(p.a, p.b, o1), m2 = surface_map(p.a, p.b, o2);
  EXPECT_GT(calls, 10);
  EXPECT_EQ(foreign, 0);
  EXPECT_NE(std::find(stages.begin(), stages.end(), "homotopy candidates"), stages.end());
  EXPECT_NE(std::find(stages.begin(), stages.end(), "initial map"), stages.end());
  // Same class, energies and map (the threads only change which core runs a
  // solve; BLAS blocking may differ, hence round-off tolerances).
  EXPECT_EQ(m1.chosen_candidate, m2.chosen_candidate);
  ASSERT_EQ(m1.candidates.size(), m2.candidates.size());
  for (size_t k = 0; k < m1.candidates.size(); ++k) {
    EXPECT_EQ(m1.candidates[k].solved, m2.candidates[k].solved) << k;
    if (std::isfinite(m1.candidates[k].energy))
      EXPECT_NEAR(m1.candidates[k].energy, m2.candidates[k].energy, 1e-9 * m1.candidates[k].energy) << k;
  }
  EXPECT_NEAR(m1.final_energy, m2.final_energy, 1e-9 * m1.final_energy);
  EXPECT_EQ(m2.flipped_triangles + m2.degenerate_triangles, 0);
  EXPECT_CERTIFIED_MAP(p.a, p.b, m2);
  // The initial map (built and located on the other thread with two) and
  // its figures.
  EXPECT_EQ(m1.initial_map.construction, m2.initial_map.construction);
  EXPECT_EQ(m1.initial_flipped_triangles, m2.initial_flipped_triangles);
  EXPECT_NEAR(m1.initial_energy, m2.initial_energy, 1e-9 * m1.initial_energy);
  EXPECT_NEAR(m1.initial_mean_dilatation, m2.initial_mean_dilatation, 1e-6 * m1.initial_mean_dilatation);
  ASSERT_EQ(m1.initial_forward.size(), m2.initial_forward.size());
  double worst = 0, worst0 = 0;
  for (size_t i = 0; i < m1.forward.size(); ++i)
    worst = std::max(worst, (m1.forward[i].position - m2.forward[i].position).norm());
  for (size_t i = 0; i < m1.initial_forward.size(); ++i)
    worst0 = std::max(worst0, (m1.initial_forward[i].position - m2.initial_forward[i].position).norm());
  ASSERT_EQ(m1.initial_inverse.size(), m2.initial_inverse.size());
  for (size_t v = 0; v < m1.inverse.size(); ++v)
    worst = std::max(worst, (m1.inverse[v].position - m2.inverse[v].position).norm());
  for (size_t v = 0; v < m1.initial_inverse.size(); ++v)
    worst0 = std::max(worst0, (m1.initial_inverse[v].position - m2.initial_inverse[v].position).norm());
  EXPECT_FALSE(m2.initial_forward.empty());
  EXPECT_LT(worst, 1e-6);
  EXPECT_LT(worst0, 1e-6);
  // The stage table (issue 19) of either run: the stages of stage_times,
  // counts that add up to at most the total, a total that holds the final
  // solve's Newton iterations and the uniformization's factorisation, and
  // peaks of at most the run's peak.
  for (const SurfaceMapResult* m : {&m1, &m2}) {
    ASSERT_EQ(m->stages.size(), m->stage_times.size());
    long long analyses = 0, factorisations = 0, newton = 0;
    for (size_t k = 0; k < m->stages.size(); ++k) {
      const StageRecord& s = m->stages[k];
      EXPECT_EQ(s.name, m->stage_times[k].first);
      EXPECT_EQ(s.seconds, m->stage_times[k].second);
      EXPECT_GE(s.analyses, 0);
      EXPECT_GE(s.factorisations, 0);
      EXPECT_GE(s.newton_iterations, 0);
      EXPECT_GT(s.peak_memory_bytes, 0) << s.name;
      EXPECT_LE(s.peak_memory_bytes, m->stage_total.peak_memory_bytes) << s.name;
      analyses += s.analyses, factorisations += s.factorisations, newton += s.newton_iterations;
    }
    EXPECT_EQ(m->stage_total.name, "total");
    EXPECT_EQ(m->stage_total.seconds, m->total_time);
    EXPECT_LE(analyses, m->stage_total.analyses);
    EXPECT_LE(factorisations, m->stage_total.factorisations);
    EXPECT_LE(newton, m->stage_total.newton_iterations);
    EXPECT_GE(m->stage_total.newton_iterations, m->iterations);
    EXPECT_GE(m->stage_total.factorisations, 2);  // the target's metric and the harmonic map at least
    EXPECT_GE(m->stage_total.analyses, 2);
    EXPECT_GE(m->stages.front().factorisations, 1);  // "target uniformization": its Newton steps' factor
  }
}

// Issue 19 (session 23): the result does not depend on the threads, bit for
// bit. The tasks that run side by side with two threads (the source side,
// the classes' data and coarse solves, the full-resolution solves beside
// the likely class's initial map and its D' and the source's letters, the
// optimum moved into P beside its distortion, the forward location beside
// the inverse and the initial map's) each write their own outputs from the
// same inputs, and the BLAS runs single-threaded in both runs, so every
// output is equal, not merely close: a task that read another's output
// before it was final, or a reduction split across threads, shows here.
TEST(SurfaceMapConcurrency, OneAndTwoThreadsGiveTheSameBits) {
  const Pair& p = pair();
  SurfaceMapOptions o1, o2;
  o1.threads = 1;
  o2.threads = 2;
  o1.initial.locate = o2.initial.locate = true;  // (the third location task)
  const SurfaceMapResult m1 = surface_map(p.a, p.b, o1), m2 = surface_map(p.a, p.b, o2);
  ASSERT_TRUE(m1.converged && m2.converged);
  EXPECT_EQ(m1.chosen_candidate, m2.chosen_candidate);
  EXPECT_EQ(m1.final_energy, m2.final_energy);
  EXPECT_EQ(m1.initial_energy, m2.initial_energy);
  EXPECT_EQ(m1.iterations, m2.iterations);
  ASSERT_EQ(m1.candidates.size(), m2.candidates.size());
  for (size_t k = 0; k < m1.candidates.size(); ++k) {
    EXPECT_EQ(m1.candidates[k].solved, m2.candidates[k].solved) << k;
    EXPECT_EQ(m1.candidates[k].energy, m2.candidates[k].energy) << k;
  }
  EXPECT_EQ(m1.flipped_triangles, m2.flipped_triangles);
  EXPECT_EQ(m1.intrinsic_flipped_triangles, m2.intrinsic_flipped_triangles);
  EXPECT_EQ(m1.mean_dilatation, m2.mean_dilatation);
  EXPECT_EQ(m1.initial_mean_dilatation, m2.initial_mean_dilatation);
  EXPECT_EQ(m1.initial_flipped_triangles, m2.initial_flipped_triangles);
  EXPECT_EQ(m1.source_image, m2.source_image);
  EXPECT_EQ(m1.source_as_target, m2.source_as_target);
  EXPECT_EQ(m1.source_as_target_inverse, m2.source_as_target_inverse);
  EXPECT_EQ(m1.source_as_target_status, m2.source_as_target_status);
  auto same_points = [](const std::vector<PointOnSurface>& a, const std::vector<PointOnSurface>& b, const char* what) {
    ASSERT_EQ(a.size(), b.size()) << what;
    int differ = 0;
    for (size_t i = 0; i < a.size(); ++i)
      differ += a[i].face != b[i].face || a[i].barycentric != b[i].barycentric || a[i].position != b[i].position;
    EXPECT_EQ(differ, 0) << what;
  };
  ASSERT_EQ(m1.forward.size(), static_cast<size_t>(p.a.num_vertices()));
  ASSERT_EQ(m1.inverse.size(), static_cast<size_t>(p.b.num_vertices()));
  ASSERT_FALSE(m1.initial_forward.empty());
  ASSERT_FALSE(m1.initial_inverse.empty());
  same_points(m1.forward, m2.forward, "forward");
  same_points(m1.inverse, m2.inverse, "inverse");
  same_points(m1.initial_forward, m2.initial_forward, "initial forward");
  same_points(m1.initial_inverse, m2.initial_inverse, "initial inverse");
}

TEST(SurfaceMapConcurrency, CancellingDuringParallelSectionsThrowsCancelled) {
  const Pair& p = pair();
  // From the coarse solves' progress (the ranking runs on two threads).
  SurfaceMapOptions o;
  o.threads = 2;
  int ranking_calls = 0;
  o.progress = [&](const std::string& s, double) { return s != "homotopy candidates" || ++ranking_calls < 3; };
  EXPECT_THROW(surface_map(p.a, p.b, o), Cancelled);
  EXPECT_EQ(ranking_calls, 3);
  // From the live solve_progress of a requested class's full-resolution
  // solve, while the initial map is being built on the other thread.
  SurfaceMapOptions o2;
  o2.threads = 2;
  o2.homotopy.class_index = 0;
  o2.solve_progress = [](int it, double, double) { return it < 1; };
  EXPECT_THROW(surface_map(p.a, p.b, o2), Cancelled);
}

// Session 26 (ui26): the target's flow, the first long stage of a map,
// reports each Newton step as "target uniformization" with a fraction that
// rises below the stage's end (0.3) and reads the answer: a cancel there
// stops the map before any later stage. Before, the stage reported once, at
// its end, so a progress bar sat at 0% and a cancel waited for the flow.
TEST(SurfaceMapConcurrency, TheTargetsFlowReportsEachStepAndCanBeCancelledInIt) {
  const Pair& p = pair();
  std::vector<std::pair<std::string, double>> seen;
  (void)surface_map(p.a, p.b, one_way_reporting_to(seen));
  std::vector<double> during;  // the target stage's reports before its end
  for (const auto& [s, f] : seen) {
    if (s != "target uniformization") break;
    if (f < 0.3) during.push_back(f);
  }
  ASSERT_GE(during.size(), 2u) << "the flow's Newton steps are not reported";
  EXPECT_TRUE(std::is_sorted(during.begin(), during.end()));
  EXPECT_GT(during.back(), 0.1);  // (the residual fell most of its way on a log scale)
  const auto end = std::find_if(seen.begin(), seen.end(), [](const auto& x) { return x.second >= 0.3; });
  ASSERT_NE(end, seen.end());
  EXPECT_EQ(end->first, "target uniformization");
  EXPECT_DOUBLE_EQ(end->second, 0.3);

  // Cancelled at the flow's first step: no later stage runs.
  std::vector<std::string> stages;
  SurfaceMapOptions c = one_way_reporting_to(seen);
  c.progress = [&](const std::string& s, double f) {
    stages.push_back(s);
    return !(s == "target uniformization" && f < 0.3);
  };
  EXPECT_THROW(surface_map(p.a, p.b, c), Cancelled);
  EXPECT_EQ(stages, std::vector<std::string>{"target uniformization"});
}

// Session 30: the source side (loops, edge words, weights, handle basis and
// the coarse copy for the ranking: 3-3.6 s without a progress point on a
// 50k-vertex source at load 7) reports inside its stage, "source homotopy
// data and weights" between the target's end (0.3) and its own (0.4): with
// one thread at its steps and inside the coarse copy's sampling, with two
// every 0.2 s while the calling thread waits for it, and once it is built.
// A cancel there stops the map in that stage. Before, the stage reported at
// its end only.
TEST(SurfaceMapConcurrency, TheSourceSideReportsInsideItsStageAndCanBeCancelledThere) {
  const Pair& p = pair();
  const std::string stage = "source homotopy data and weights";
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    std::vector<std::pair<std::string, double>> seen;
    const SurfaceMapOptions o = one_way_reporting_to(seen, threads);
    (void)surface_map(p.a, p.b, o);
    std::vector<double> inside;
    for (const auto& [s, f] : seen)
      if (s == stage && f < 0.4) inside.push_back(f);
    ASSERT_FALSE(inside.empty()) << "no point inside the stage";
    EXPECT_TRUE(std::is_sorted(inside.begin(), inside.end()));
    EXPECT_GT(inside.front(), 0.3);
    if (threads == 1) {
      // Inside the coarse copy's sampling (the side's 0.35 .. 0.95).
      EXPECT_TRUE(std::any_of(inside.begin(), inside.end(), [](double f) { return f > 0.3 + 0.08 * 0.35 && f < 0.3 + 0.08 * 0.95; }));
      EXPECT_GE(inside.size(), 5u);
    }
    // The stage's first point inside it cancels: no later stage is reported.
    std::vector<std::pair<std::string, double>> stages;
    SurfaceMapOptions c = o;
    c.progress = [&](const std::string& s, double f) {
      stages.emplace_back(s, f);
      return !(s == stage && f < 0.4);
    };
    EXPECT_THROW(surface_map(p.a, p.b, c), Cancelled);
    ASSERT_FALSE(stages.empty());
    EXPECT_EQ(stages.back().first, stage);
    EXPECT_LT(stages.back().second, 0.4);
    for (size_t k = 0; k + 1 < stages.size(); ++k) EXPECT_EQ(stages[k].first, "target uniformization");
    // Cancelled inside the coarse copy's sampling (one thread: the point's place is known).
    if (threads == 1) {
      stages.clear();
      c.progress = [&](const std::string& s, double f) {
        stages.emplace_back(s, f);
        return !(s == stage && f > 0.3 + 0.08 * 0.35 && f < 0.4);
      };
      EXPECT_THROW(surface_map(p.a, p.b, c), Cancelled);
      ASSERT_FALSE(stages.empty());
      EXPECT_EQ(stages.back().first, stage);
      EXPECT_LT(stages.back().second, 0.3 + 0.08 * 0.95);
    }
  }
}

// Session 30: the ranking (a genus-2 run's longest stage: 20 s of 31 s with
// a 50k-vertex source) reports its fraction by the classes solved, 0.4 to
// its end at 0.6, and the full-resolution solves theirs, 0.6 to 0.68; a
// cancel at the ranking's first point past 0.4 stops the map in the ranking.
// Before, the ranking reported 0.4 at every Newton step until its end.
TEST(SurfaceMapConcurrency, TheRankingsFractionMovesByTheClassesSolved) {
  const Pair& p = pair();
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    std::vector<std::pair<std::string, double>> seen;
    SurfaceMapOptions o = one_way_reporting_to(seen, threads);
    o.homotopy.ranking_gap = -1;  // (every class solved on the coarse copy)
    const SurfaceMapResult m = surface_map(p.a, p.b, o);
    ASSERT_GE(m.ranking_coarse_solves, 3);
    std::set<double> ranking;
    for (const auto& [s, f] : seen)
      if (s == "homotopy candidates" && f < 0.6) ranking.insert(f);
    // A fraction for each class solved (first 0.4: none solved yet).
    EXPECT_GE(ranking.size(), 3u);
    EXPECT_DOUBLE_EQ(*ranking.begin(), 0.4);
    const auto end = std::find(seen.begin(), seen.end(), std::make_pair(std::string("homotopy candidates"), 0.6));
    ASSERT_NE(end, seen.end());
    EXPECT_TRUE(std::none_of(seen.begin(), end, [](const auto& x) { return x.first == "full-resolution solve"; }));
    for (auto r = end + 1; r != seen.end() && r->first == "full-resolution solve"; ++r) {
      EXPECT_GE(r->second, 0.6);
      EXPECT_LE(r->second, 0.68);
    }
    // Cancelled inside the ranking, after its first class: no later stage.
    std::vector<std::string> stages;
    SurfaceMapOptions c = o;
    c.progress = [&](const std::string& s, double f) {
      stages.push_back(s);
      return !(s == "homotopy candidates" && f > 0.4 && f < 0.6);
    };
    EXPECT_THROW(surface_map(p.a, p.b, c), Cancelled);
    ASSERT_FALSE(stages.empty());
    EXPECT_EQ(stages.back(), "homotopy candidates");
    EXPECT_EQ(std::count(stages.begin(), stages.end(), "full-resolution solve"), 0);
  }
}

}  // namespace
}  // namespace surfmap
