// The ranking's race of coarse solves (src/map/stages/coarse_race.h):
// scripted solves (energy and gradient per Newton step) stand in for the
// harmonic solves, so that the rule, its independence of the threads and
// the failure paths can be checked exactly.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

#include "../src/map/stages/coarse_race.h"
#include "surfmap/error.h"

namespace surfmap::detail {
namespace {

struct Step {
  double energy, gradient;
};
using Script = std::vector<Step>;  // the last step is the converged one

// A: the lowest class (final 10); B: far above, its gradient drops fivefold
// at step 3 (10.5 is A's energy there, B's lower estimate 31 - 2 * 9 = 13 >
// 1.1 * 10.5); C: within the 10% margin of A (never stopped); D: far above,
// slow until step 6 (45 - 2 * 5 = 35 > 11).
std::vector<Script> scripts() {
  return {
      {{1000, 50}, {100, 20}, {20, 5}, {10.5, 1}, {10.01, 0.1}, {10.0, 1e-3}},
      {{2000, 60}, {300, 30}, {40, 6}, {31, 1.2}, {30.01, 0.1}, {30.0, 1e-3}},
      {{900, 40}, {90, 10}, {15, 2}, {11.0, 0.4}, {10.81, 0.05}, {10.8, 1e-3}},
      {{500, 10}, {400, 9}, {300, 8}, {200, 7}, {100, 6}, {50, 5}, {45, 1}, {44.9, 0.1}, {44.89, 1e-3}},
  };
}

struct RaceRun {
  std::vector<CoarseRaceOutcome> outcomes;
  std::vector<int> steps_taken;  // reports made per task
  std::vector<char> finished;    // reached its converged step
  int most_at_once = 0;
};

RaceRun race_run(const std::vector<Script>& s, int threads, double incumbent = std::numeric_limits<double>::infinity(),
        bool jitter = false) {
  RaceRun r;
  const int n = static_cast<int>(s.size());
  r.steps_taken.assign(n, 0);
  r.finished.assign(n, 0);
  std::atomic<int> computing{0}, most{0};
  CoarseRaceOptions o;
  o.threads = threads;
  o.incumbent = incumbent;
  r.outcomes = coarse_race(n, o, [&](int q, const RaceProgress& report) {
    for (size_t k = 0; k < s[q].size(); ++k) {
      const int now = ++computing;
      int m = most.load();
      while (now > m && !most.compare_exchange_weak(m, now)) {
      }
      // Different task speeds, so that the lockstep is what orders them.
      if (jitter) std::this_thread::sleep_for(std::chrono::microseconds(200 * ((q * 7 + static_cast<int>(k)) % 5)));
      --computing;
      ++r.steps_taken[q];
      if (!report(static_cast<int>(k), s[q][k].energy, s[q][k].gradient)) throw Cancelled("stopped");
      if (k + 1 == s[q].size()) r.finished[q] = 1;
    }
  });
  r.most_at_once = most.load();
  return r;
}

TEST(CoarseRace, StopsOnlyTheClassesClearlyAboveTheLowestEnergyHeld) {
  const RaceRun r = race_run(scripts(), 2);
  ASSERT_EQ(r.outcomes.size(), 4u);
  EXPECT_FALSE(r.outcomes[0].beaten);
  EXPECT_TRUE(r.finished[0]);
  EXPECT_FALSE(r.outcomes[2].beaten);  // within the margin: must be solved to the end
  EXPECT_TRUE(r.finished[2]);
  ASSERT_TRUE(r.outcomes[1].beaten);
  EXPECT_EQ(r.outcomes[1].step, 3);
  EXPECT_DOUBLE_EQ(r.outcomes[1].held, 10.5);
  EXPECT_DOUBLE_EQ(r.outcomes[1].lower, 13.0);
  EXPECT_EQ(r.steps_taken[1], 4);
  EXPECT_FALSE(r.finished[1]);
  ASSERT_TRUE(r.outcomes[3].beaten);
  EXPECT_EQ(r.outcomes[3].step, 6);
  EXPECT_DOUBLE_EQ(r.outcomes[3].lower, 35.0);
  // Every stopped class's final energy is above 1.1 times the lowest final.
  const std::vector<Script> s = scripts();
  for (size_t q = 0; q < s.size(); ++q)
    if (r.outcomes[q].beaten) EXPECT_GT(s[q].back().energy, 1.1 * s[0].back().energy);
}

TEST(CoarseRace, OutcomeDoesNotDependOnTheThreadsOrTheTiming) {
  const RaceRun one = race_run(scripts(), 1);
  EXPECT_EQ(one.most_at_once, 1);
  for (int threads : {1, 2, 3, 4}) {
    for (int rep = 0; rep < 3; ++rep) {
      const RaceRun r = race_run(scripts(), threads, std::numeric_limits<double>::infinity(), true);
      EXPECT_LE(r.most_at_once, threads);
      for (size_t q = 0; q < one.outcomes.size(); ++q) {
        EXPECT_EQ(r.outcomes[q].beaten, one.outcomes[q].beaten) << "threads " << threads << " task " << q;
        EXPECT_EQ(r.outcomes[q].step, one.outcomes[q].step) << "threads " << threads << " task " << q;
        EXPECT_EQ(r.steps_taken[q], one.steps_taken[q]);
      }
    }
  }
}

TEST(CoarseRace, AnIncumbentAloneStopsAClassAndNothingStopsWithoutOne) {
  const std::vector<Script> s = {scripts()[1]};
  const RaceRun with = race_run(s, 2, 10.0);
  ASSERT_TRUE(with.outcomes[0].beaten);
  EXPECT_EQ(with.outcomes[0].step, 3);
  EXPECT_DOUBLE_EQ(with.outcomes[0].held, 10.0);
  const RaceRun without = race_run(s, 2);
  EXPECT_FALSE(without.outcomes[0].beaten);
  EXPECT_TRUE(without.finished[0]);
  // Within the margin of the incumbent: solved to the end.
  const RaceRun near = race_run(s, 2, 29.0);
  EXPECT_FALSE(near.outcomes[0].beaten);
}

TEST(CoarseRace, ATasksErrorStopsTheOthersAndIsRethrownAfterEveryTaskEnded) {
  std::atomic<int> ended{0}, completed{0};
  struct Leaving {
    std::atomic<int>& n;
    ~Leaving() { ++n; }
  };
  CoarseRaceOptions o;
  o.threads = 2;
  EXPECT_THROW(coarse_race(3, o,
                           [&](int q, const RaceProgress& report) {
                             Leaving leaving{ended};
                             for (int k = 0; k < 1000; ++k) {
                               if (q == 1 && k == 2) throw std::runtime_error("solver failed");
                               if (!report(k, 100.0 - k, 1.0)) throw Cancelled("stopped");
                             }
                             ++completed;
                           }),
               std::runtime_error);
  EXPECT_EQ(ended.load(), 3);
  EXPECT_EQ(completed.load(), 0);  // the error stopped the others (after step 2 at the latest)
}

TEST(CoarseRace, CancelledFromTheCallingThreadsCallback) {
  CoarseRaceOptions o;
  o.threads = 2;
  std::atomic<int> polls{0};
  const std::thread::id me = std::this_thread::get_id();
  std::atomic<bool> foreign{false};
  EXPECT_THROW(coarse_race(
                   2, o,
                   [&](int, const RaceProgress& report) {
                     for (int k = 0; k < 100000; ++k) {
                       std::this_thread::sleep_for(std::chrono::microseconds(100));
                       if (!report(k, 100.0, 1.0)) throw Cancelled("stopped");
                     }
                   },
                   [&] {
                     if (std::this_thread::get_id() != me) foreign = true;
                     return ++polls < 3;
                   }),
               Cancelled);
  EXPECT_FALSE(foreign.load());
  EXPECT_GE(polls.load(), 3);
}

}  // namespace
}  // namespace surfmap::detail
