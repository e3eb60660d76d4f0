// The local repair of folded faces (src/map/stages/fold_repair.h; issue 14,
// docs/handle_classes.md "Flat images, folds and the own-edge retry"): a generated genus-2 source
// with a few slivers folds under the intrinsic Delaunay map; only the
// vertices around the folds are solved again, and the map keeps the
// intrinsic weights everywhere else.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "surfmap/error.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/testing/map_hooks.h"
#include "certify_helpers.h"
#include "sliver_caps.h"
#include "sliver_strip.h"

namespace surfmap {
namespace {

TEST(FoldRepair, FewSliversAreRepairedLocallyInTheSameClass) {
  const TriMesh s = testing_support::with_caps(samples::n_hole_torus(2, 32, true), 37, 0.002);
  const TriMesh t = samples::amphora(36, true);
  ASSERT_EQ(Connectivity(s.F, s.num_vertices()).genus(), 2);
  SurfaceMapOptions o;
  o.homotopy.candidates = 1;
  o.homotopy.two_way = false;
  // The fixture folds with the intrinsic weights alone.
  o.solve.source_weights = SourceWeights::IntrinsicDelaunay;
  EXPECT_THROW(surface_map(s, t, o), SolveError);
  o.solve.source_weights = SourceWeights::Automatic;
  const SurfaceMapResult m = surface_map(s, t, o);
  const SurfaceMapResult::FoldRepair& r = m.fold_repair;
  ASSERT_EQ(r.status, "repaired") << m.source_weights_reason;
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_EQ(m.degenerate_triangles, 0);
  EXPECT_CERTIFIED_MAP_UP_TO_CHORD_FOLDS(s, t, m, 0.01);
  for (double d : m.dilatation) EXPECT_TRUE(std::isfinite(d));
  // Each sliver's apex folds alone here: moving it into its neighbours'
  // kernel suffices (the first stage; no held re-solve tried).
  EXPECT_EQ(r.method, "projection");
  EXPECT_EQ(r.tries, 0);
  EXPECT_EQ(r.rings, 0);
  EXPECT_EQ(m.source_weights, "intrinsic Delaunay cotangent; " + std::to_string(r.free_vertices) +
                                  " vertices around the folds moved (projection)");
  EXPECT_NE(m.source_weights_reason.find("repaired locally"), std::string::npos) << m.source_weights_reason;
  // Local: a few faces folded, and only faces near them changed.
  EXPECT_GT(r.folded_faces, 0);
  EXPECT_GT(r.free_vertices, 0);
  EXPECT_LE(r.free_vertices, 3 * r.folded_faces);
  EXPECT_LT(r.free_vertices, s.num_vertices() / 50);
  EXPECT_GE(r.changed_faces, r.folded_faces);
  EXPECT_LT(r.changed_faces, s.num_faces() / 20);
  // The intrinsic optimum is the least intrinsic energy of any map in the
  // class, so the repaired map's is above it, and barely (few vertices moved).
  EXPECT_GE(r.energy_after, r.energy_before * (1 - 1e-9));
  EXPECT_LT(r.energy_after, r.energy_before * 1.05);
  EXPECT_NEAR(m.final_energy, r.energy_after, 1e-12 * r.energy_after);
  EXPECT_NEAR(m.candidates[m.chosen_candidate].energy, r.energy_before, 1e-9 * r.energy_before);

  // The global fallback alone (the behaviour before): same class, whose
  // intrinsic optimum is the one the repair started from, but every face gets
  // the own-edge weights and the mean D' is higher.
  SurfaceMapOptions g = o;
  g.solve.local_fold_repair = false;
  const SurfaceMapResult mg = surface_map(s, t, g);
  EXPECT_EQ(mg.source_weights, "positive on the source's own edges");
  EXPECT_EQ(mg.fold_repair.status, "");
  EXPECT_EQ(mg.flipped_triangles, 0);
  EXPECT_EQ(mg.chosen_candidate, m.chosen_candidate);
  EXPECT_NEAR(mg.intrinsic_class_energy, r.energy_before, 1e-7 * r.energy_before);
  EXPECT_LT(m.mean_dilatation, mg.mean_dilatation);
}

// A strip of long slivers (each reaching 8 edges along a 20-edge path, 1e-4
// wide) folds where no single corner can unfold it: the projection is stuck,
// and the untangling by distortion repairs it in place, in the same class.
TEST(FoldRepair, SliverStripIsUntangledByDistortion) {
  const TriMesh s = testing_support::with_strip(samples::n_hole_torus(2, 32, true), 0, 20, 1e-4, 8);
  const TriMesh t = samples::amphora(36, true);
  ASSERT_EQ(Connectivity(s.F, s.num_vertices()).genus(), 2);
  SurfaceMapOptions o;
  o.homotopy.candidates = 1;
  o.homotopy.two_way = false;
  const SurfaceMapResult m = surface_map(s, t, o);
  const SurfaceMapResult::FoldRepair& r = m.fold_repair;
  ASSERT_EQ(r.status, "repaired") << m.source_weights_reason;
  EXPECT_EQ(r.method.rfind("untangling of ", 0), 0u) << r.method;
  EXPECT_GT(r.folded_faces, 0);
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_EQ(m.degenerate_triangles, 0);
  EXPECT_CERTIFIED_MAP_UP_TO_CHORD_FOLDS(s, t, m, 0.01);
  for (double d : m.dilatation) EXPECT_TRUE(std::isfinite(d));
  EXPECT_NE(m.source_weights.find("intrinsic Delaunay cotangent; "), std::string::npos) << m.source_weights;
  // Local: a few rings around the folds moved, the rest held.
  EXPECT_GT(r.free_vertices, 0);
  EXPECT_LT(r.free_vertices, s.num_vertices() / 20);
  EXPECT_LT(r.changed_faces, s.num_faces() / 10);
  EXPECT_GE(r.energy_after, r.energy_before * (1 - 1e-9));
  EXPECT_LT(r.energy_after, r.energy_before * 1.05);

  // Without the untangling (the repair before it: held re-solves, else the
  // global fallback): the same class, and no lower mean D'.
  SurfaceMapOptions g = o;
  g.solve.fold_untangle = false;
  const SurfaceMapResult mg = surface_map(s, t, g);
  EXPECT_EQ(mg.flipped_triangles, 0);
  EXPECT_EQ(mg.chosen_candidate, m.chosen_candidate);
  EXPECT_EQ(mg.fold_repair.method.find("untangling"), std::string::npos) << mg.fold_repair.method;
  EXPECT_LE(m.mean_dilatation, mg.mean_dilatation);
}

// Issue 13 (session 25): once no repair is left to try (weights other than
// Automatic here; after the own-edge fallback in a default run), a fallback
// class whose kept full-resolution solve folds is refused on that solve,
// without its initial map, with the refusal mapping it would give. The
// sliver-capped source folds in every class with the intrinsic weights.
TEST(SurfaceMapFallbacks, FoldedFallbacksAreRefusedOnTheirSolveAsMappingThemWould) {
  const TriMesh s = testing_support::with_caps(samples::n_hole_torus(2, 32, true), 37, 0.002);
  const TriMesh t = samples::amphora(36, true);
  SurfaceMapOptions o;
  o.homotopy.candidates = 2;
  o.homotopy.two_way = false;
  o.homotopy.search.enabled = false;
  o.homotopy.full_solves = 0;  // (every class solved at full resolution: each fallback has its solve kept)
  o.solve.source_weights = SourceWeights::IntrinsicDelaunay;
  o.loops.fold_fallback = false;  // (one run: the retry after folds is checked at the end)
  auto failure = [&](const testing::MapHooks& hooks) {
    try {
      surface_map(s, t, o, hooks);
    } catch (const SolveError& e) {
      EXPECT_EQ(e.reason(), SolveFailure::no_bijective_class) << e.what();
      return std::string(e.what());
    }
    ADD_FAILURE() << "mapped: the fixture must fold in every class";
    return std::string();
  };
  testing::MapHooks every;
  every.map_every_fallback = true;  // (the loop before: every fallback mapped)
  const std::string mapped = failure(every), read = failure({});
  // "no candidate class gave a bijective map (N tried[, M of them refused
  // ...]); the chosen class C (...): <its reason>; the last, class L: <its reason>"
  auto tried = [](const std::string& e) {
    const size_t at = e.find("bijective map (");
    return at == std::string::npos ? -1 : std::atoi(e.c_str() + at + 15);
  };
  ASSERT_GE(tried(mapped), 2) << mapped;
  EXPECT_EQ(tried(read), tried(mapped)) << read;
  EXPECT_EQ(mapped.find("refused on their full-resolution solves"), std::string::npos) << mapped;
  const std::string refused = std::to_string(tried(mapped) - 1) + " of them refused on their full-resolution solves";
  EXPECT_NE(read.find(refused), std::string::npos) << read;
  // The chosen class is mapped as before; each fallback's refusal is the one
  // mapping it gave, word for word (the same flipped, degenerate and
  // intrinsic counts), read off its solve.
  const size_t last_m = mapped.find("; the last, class "), last_r = read.find("; the last, class ");
  ASSERT_NE(last_m, std::string::npos);
  ASSERT_NE(last_r, std::string::npos);
  EXPECT_EQ(read.substr(read.find("); the chosen class"), last_r - read.find("); the chosen class")),
            mapped.substr(mapped.find("); the chosen class"), last_m - mapped.find("); the chosen class")));
  const std::string suffix = " (read on its full-resolution solve before its initial map: not mapped again)";
  EXPECT_EQ(read.substr(last_r), mapped.substr(last_m) + suffix);
  EXPECT_NE(mapped.find("the optimised map has "), std::string::npos) << mapped;
  // Issue 13 (session 28; LoopOptions::fold_fallback): with the retry after
  // folds on, the same run is made once more with the short generators, one
  // way; these forced weights fold there too, so the error is the first
  // run's, word for word, then the retry's, and its reason is still folds.
  o.loops.fold_fallback = true;
  const std::string retried = failure({});
  const std::string again = "; again with the short canonical generators, one way (the automatic retry after folds): ";
  ASSERT_EQ(retried.rfind(read + again, 0), 0u) << retried;
  EXPECT_NE(retried.find("bijective map (", read.size()), std::string::npos) << retried;
}

// Issue 13 (session 29): when every class folds and the two-way run's rescue
// finds the other direction failing too, the retry after folds comes before
// the rescue's last attempt (the cuts at the source's middle vertex), which
// runs only when the retry fails. The sliver-capped source folds in every
// class for real with the intrinsic weights, in the first run and in the
// retry; the hook fails the other direction and records the order.
TEST(SurfaceMapFallbacks, BothDirectionsFoldedRetryBeforeTheCutsAtAnotherVertex) {
  const TriMesh s = testing_support::with_caps(samples::n_hole_torus(2, 32, true), 37, 0.002);
  const TriMesh t = samples::amphora(36, true);
  SurfaceMapOptions o;  // (the two-way run on: its rescue runs)
  o.homotopy.candidates = 2;
  o.homotopy.search.enabled = false;
  o.homotopy.full_solves = 0;
  o.homotopy.through_shape = false;
  o.solve.source_weights = SourceWeights::IntrinsicDelaunay;
  const int middle = s.num_vertices() / 2;
  std::vector<std::string> order;
  bool cut_maps = false;  // (the cuts at the middle vertex with the weights that map)
  testing::MapHooks hooks;
  hooks.before_run = [&](const SurfaceMapOptions& run) {
    order.push_back(run.loops.short_canonical_generators ? "retry" : "first");
  };
  hooks.rescue_run = [&](const TriMesh& a, const TriMesh& b, const SurfaceMapOptions& run) {
    EXPECT_FALSE(run.loops.fold_fallback);  // (no retry of its own)
    EXPECT_FALSE(run.homotopy.two_way);
    if (a.num_vertices() == t.num_vertices()) {
      order.push_back("other direction");
      throw SolveError("the other direction folded (a test's words)", SolveFailure::folds);
    }
    order.push_back("cut at " + std::to_string(run.loops.source_base_vertex));
    SurfaceMapOptions cut = run;
    if (cut_maps) cut.solve.source_weights = SourceWeights::Automatic;
    return surface_map(a, b, cut);
  };
  auto failure = [&](const SurfaceMapOptions& opt) {
    order.clear();
    try {
      testing::surface_map(s, t, opt, hooks);
    } catch (const SolveError& e) {
      EXPECT_EQ(e.reason(), SolveFailure::no_bijective_class) << e.what();
      return std::string(e.what());
    }
    ADD_FAILURE() << "mapped";
    return std::string();
  };
  const std::string cut_at = "cut at " + std::to_string(middle);
  // Every attempt folds: first, the other direction, the retry, the cut.
  const std::string all = failure(o);
  EXPECT_EQ(order, (std::vector<std::string>{"first", "other direction", "retry", cut_at})) << all;
  const size_t other = all.find("; the other direction failed too: the other direction folded (a test's words)");
  const size_t later = all.find("; the cuts at another base vertex: after the retry after folds");
  const size_t again = all.find("; again with the short canonical generators, one way (the automatic retry after folds): ");
  const size_t cut = all.find("; the cuts at source vertex " + std::to_string(middle) + ": ");
  EXPECT_EQ(all.rfind("no candidate class gave a bijective map (", 0), 0u) << all;
  ASSERT_NE(other, std::string::npos) << all;
  ASSERT_NE(later, std::string::npos) << all;
  ASSERT_NE(again, std::string::npos) << all;
  ASSERT_NE(cut, std::string::npos) << all;
  EXPECT_LT(other, later);
  EXPECT_LT(later, again);
  EXPECT_LT(again, cut);
  // The cuts at the middle vertex mapping after the retry: their map, saying so.
  cut_maps = true;
  order.clear();
  const SurfaceMapResult m = testing::surface_map(s, t, o, hooks);
  EXPECT_EQ(order, (std::vector<std::string>{"first", "other direction", "retry", cut_at}));
  EXPECT_TRUE(m.converged);
  EXPECT_EQ(m.flipped_triangles, 0);
  EXPECT_EQ(m.degenerate_triangles, 0);
  // (The sliver caps leave a few chord triangles reversed: 48 of 10296.)
  EXPECT_CERTIFIED_MAP_UP_TO_CHORD_FOLDS(s, t, m, 0.02);
  EXPECT_EQ(m.fold_fallback.rfind("not used: the retry after folds failed too (no candidate class gave a bijective map", 0), 0u)
      << m.fold_fallback;
  EXPECT_NE(m.two_way_status.find("; the cuts at source vertex " + std::to_string(middle) + " gave a bijective map"),
            std::string::npos)
      << m.two_way_status;
  EXPECT_EQ(m.canonical_generators.rfind("classical", 0), 0u) << m.canonical_generators;
  EXPECT_GE(m.total_time, m.two_way_time_s);
  // With the retry off, the rescue's order as before: the cut right after the other direction.
  cut_maps = false;
  SurfaceMapOptions off = o;
  off.loops.fold_fallback = false;
  const std::string without = failure(off);
  EXPECT_EQ(order, (std::vector<std::string>{"first", "other direction", cut_at})) << without;
  EXPECT_EQ(without.find("again with the short"), std::string::npos) << without;
}

// Clean sources never run it.
TEST(FoldRepair, CleanSourceDoesNotRunIt) {
  const TriMesh s = samples::n_hole_torus(2, 32, true);
  const TriMesh t = samples::amphora(36, true);
  SurfaceMapOptions o;
  o.homotopy.candidates = 1;
  o.homotopy.two_way = false;
  const SurfaceMapResult m = surface_map(s, t, o);
  EXPECT_EQ(m.source_weights, "intrinsic Delaunay cotangent");
  EXPECT_EQ(m.fold_repair.status, "");
  EXPECT_EQ(m.fold_repair.folded_faces, 0);
}

}  // namespace
}  // namespace surfmap
