#pragma once
// Issue 19: the ranking's coarse solves of the classes that can still win,
// run in lockstep so that a class clearly beaten by another is stopped
// before its solve has converged (docs/history/benchmarks.md "Coarse solves stopped when beaten"). Internal.
#include <functional>
#include <limits>
#include <vector>

namespace surfmap::detail {

struct CoarseRaceOptions {
  /// Solves computing at once (the pipeline's threads; the outcome does not
  /// depend on it). Default 1.
  int threads = 1;
  /// A solve is stopped when its energy's lower estimate is above
  /// (1 + margin) times the lowest energy held at the same step (default
  /// 0.1: kCoarseMargin, the window of classes solved at full resolution,
  /// so a stopped class could not have been solved there).
  double margin = 0.1;
  /// A converged energy known before the race (the ranking's first class),
  /// +infinity (default) when none.
  double incumbent = std::numeric_limits<double>::infinity();
  /// The energy's lower estimate at a Newton step is E - safety (E_prev - E),
  /// taken only once the step cut the gradient at least `contraction`-fold
  /// (Newton's fast local phase, where the remaining decrease is far below
  /// the last one: quadratically, or linearly at a rate of 1/contraction²
  /// in energy). Defaults 2 and 4.
  double safety = 2.0;
  double contraction = 4.0;
};

/// How one task of the race ended.
struct CoarseRaceOutcome {
  bool beaten = false;  ///< stopped before convergence by the rule above
  int step = -1;        ///< the progress report it was stopped at (0-based)
  double energy = std::numeric_limits<double>::quiet_NaN();  ///< its energy there
  double lower = std::numeric_limits<double>::quiet_NaN();   ///< its lower estimate there
  double held = std::numeric_limits<double>::quiet_NaN();    ///< the lowest energy held at that step
};

/// A task's progress report: (Newton iteration, energy, largest gradient);
/// returns false when the task must stop (beaten, or the race cancelled):
/// the solve then throws Cancelled out of `solve`, which the race catches.
using RaceProgress = std::function<bool(int, double, double)>;

/// Runs solve(q, progress) for q = 0..n-1, each on its own thread, at most
/// options.threads computing at once. Every task reports each Newton step
/// through `progress` and then waits until every other task still running
/// has reported the same step (or ended); the decision to stop a task at
/// step s reads only the values the tasks reported at steps <= s (a task
/// that ended earlier: its last report) and options.incumbent, so which
/// tasks are stopped, and where, does not depend on the threads or the
/// timing. The lowest value held at step s bounds the final energy of some
/// task from above (energies only decrease along a solve, and a task
/// stopped was above another's value), up to a task that later fails (its
/// values still count: a failure cannot be foreseen without breaking the
/// lockstep; failed coarse solves are classes with very long edges, far
/// above the others). `keep_going` (optional) is polled on the calling
/// thread while it waits (about every 20 ms); false cancels every task and
/// the race throws Cancelled. Any other exception of a task stops the
/// others (as a cancellation) and is rethrown on the calling thread after
/// every task has ended. With threads = 1 the tasks' threads take turns:
/// one solve computes at a time.
std::vector<CoarseRaceOutcome> coarse_race(int n, const CoarseRaceOptions& options,
                                           const std::function<void(int, const RaceProgress&)>& solve,
                                           const std::function<bool()>& keep_going = nullptr);

}  // namespace surfmap::detail
