// Issue 19: the ranking's coarse solves in lockstep, stopped when clearly
// beaten (coarse_race.h).
#include "coarse_race.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>
#include <utility>

#include "../concurrency.h"
#include "surfmap/error.h"

namespace surfmap::detail {

namespace {

struct Report {
  double energy, gradient;
};

class Race {
 public:
  Race(int n, const CoarseRaceOptions& o)
      : options_(o), permits_(std::max(1, o.threads)), history_(n), ended_(n, 0), outcome_(n) {}

  // The task's turn to compute (at most options.threads at once).
  void acquire(std::unique_lock<std::mutex>& lock) {
    changed_.wait(lock, [&] { return running_ < permits_ || cancelled_; });
    ++running_;
  }

  bool report(int q, double energy, double gradient) {
    std::unique_lock<std::mutex> lock(mutex_);
    std::vector<Report>& h = history_[q];
    h.push_back({energy, gradient});
    const size_t step = h.size() - 1;
    --running_;
    changed_.notify_all();
    if (cancelled_) return false;
    // Every other task at this step too, or ended.
    changed_.wait(lock, [&] {
      if (cancelled_) return true;
      for (size_t j = 0; j < history_.size(); ++j)
        if (static_cast<int>(j) != q && !ended_[j] && history_[j].size() <= step) return false;
      return true;
    });
    if (cancelled_) return false;
    if (beaten(q, step)) {
      ended_[q] = 1;  // (its thread is leaving: no task waits for its next report)
      changed_.notify_all();
      return false;
    }
    acquire(lock);
    return true;
  }

  // A task's thread waits for its first permit.
  void start() {
    std::unique_lock<std::mutex> lock(mutex_);
    acquire(lock);
  }

  // A task's thread is done (converged, failed, stopped or thrown).
  void end(int q, bool holds_permit) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (holds_permit) --running_;
    ended_[q] = 1;
    changed_.notify_all();
    ended_one_.notify_all();
  }
  bool holds_permit(int q) {
    std::lock_guard<std::mutex> lock(mutex_);
    return !outcome_[q].beaten && !cancelled_;
  }

  void cancel() {
    std::lock_guard<std::mutex> lock(mutex_);
    cancelled_ = true;
    changed_.notify_all();
  }
  bool cancelled() {
    std::lock_guard<std::mutex> lock(mutex_);
    return cancelled_;
  }
  bool all_ended() {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::all_of(ended_.begin(), ended_.end(), [](char e) { return e != 0; });
  }
  std::mutex& mutex() { return mutex_; }
  // The calling thread waits on this one (a task's end), not on every report.
  std::condition_variable& ended_one() { return ended_one_; }
  std::vector<CoarseRaceOutcome> outcomes() {
    std::lock_guard<std::mutex> lock(mutex_);
    return outcome_;
  }

 private:
  // The stopping rule at `step` (under the lock; every other task has
  // reported `step` or ended).
  bool beaten(int q, size_t step) {
    const std::vector<Report>& h = history_[q];
    if (step == 0) return false;
    const Report& now = h[step];
    const Report& before = h[step - 1];
    if (!(now.gradient * options_.contraction <= before.gradient) || !(now.energy <= before.energy)) return false;
    const double lower = now.energy - options_.safety * (before.energy - now.energy);
    double held = options_.incumbent;
    for (size_t j = 0; j < history_.size(); ++j) {
      if (static_cast<int>(j) == q || history_[j].empty()) continue;
      const double e = history_[j][std::min(step, history_[j].size() - 1)].energy;
      if (std::isfinite(e)) held = std::min(held, e);
    }
    if (!(std::isfinite(held) && lower > (1 + options_.margin) * held)) return false;
    CoarseRaceOutcome& o = outcome_[q];
    o.beaten = true;
    o.step = static_cast<int>(step);
    o.energy = now.energy;
    o.lower = lower;
    o.held = held;
    return true;
  }

  const CoarseRaceOptions options_;
  const int permits_;
  std::mutex mutex_;
  std::condition_variable changed_, ended_one_;
  int running_ = 0;
  bool cancelled_ = false;
  std::vector<std::vector<Report>> history_;
  std::vector<char> ended_;
  std::vector<CoarseRaceOutcome> outcome_;
};

}  // namespace

std::vector<CoarseRaceOutcome> coarse_race(int n, const CoarseRaceOptions& options,
                                           const std::function<void(int, const RaceProgress&)>& solve,
                                           const std::function<bool()>& keep_going) {
  if (n <= 0) return {};
  Race race(n, options);
  std::vector<std::exception_ptr> errors(n);
  std::vector<std::thread> threads;
  threads.reserve(n);
  for (int q = 0; q < n; ++q)
    threads.emplace_back([&, q] {
      // OpenMP's max-active-levels is per thread: without this, CHOLMOD's
      // loops in this new thread would start teams again (concurrency.h;
      // measured: 3-12% more CPU for the 4.9k bench pair with --threads 1).
      const SingleThreadedBlas single_threaded_blas;
      race.start();
      try {
        solve(q, [&race, q](int, double energy, double gradient) { return race.report(q, energy, gradient); });
      } catch (const Cancelled&) {
        // Stopped by the race (beaten or cancelled): its outcome says which.
        if (!race.outcomes()[q].beaten && !race.cancelled()) errors[q] = std::current_exception();
      } catch (...) {
        errors[q] = std::current_exception();
        race.cancel();  // the others give up early; this error is rethrown
      }
      race.end(q, race.holds_permit(q));
    });
  // The calling thread polls keep_going while the tasks run.
  {
    std::unique_lock<std::mutex> lock(race.mutex());
    lock.unlock();
    while (!race.all_ended()) {
      lock.lock();
      race.ended_one().wait_for(lock, std::chrono::milliseconds(20));
      lock.unlock();
      if (keep_going && !race.cancelled() && !keep_going()) race.cancel();
    }
  }
  for (std::thread& t : threads) t.join();
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
  if (race.cancelled()) throw Cancelled("harmonic map solve cancelled");
  return race.outcomes();
}

}  // namespace surfmap::detail
