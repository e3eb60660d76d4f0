#pragma once
// Process-wide counters of the expensive work of the core (issue 19: the
// stage table of SurfaceMapResult::stages, docs/cli.md `--timings`): sparse
// symbolic analyses and numeric factorisations (CHOLMOD), Newton iterations
// of the harmonic solve and of the uniformization, and the peak resident
// memory of the process (Linux: VmHWM of /proc/self/status).
//
// The solvers add to the counters with one line at each analyse / factorise
// / iteration; a map reads them at every stage boundary and records the
// differences. They are atomics shared by every thread of the process, so
// work on the pipeline's second thread counts towards the stage during
// which it ran, and two maps computed at once in one process (a Python
// thread pool) count each other's work: the table is exact for one map at a
// time, which is how the CLI, the add-on and the benchmarks run.
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace surfmap::work {

/// Symbolic analyses (fill-reducing ordering + elimination tree) of sparse
/// Cholesky factorisations.
inline std::atomic<std::int64_t> analyses{0};
/// Numeric Cholesky factorisations (every attempt, a failed one included).
inline std::atomic<std::int64_t> factorisations{0};
/// Newton iterations: the hyperbolic harmonic solve's and the Ricci flow's.
inline std::atomic<std::int64_t> newton_iterations{0};

/// A snapshot of the counters.
struct Counts {
  std::int64_t analyses = 0, factorisations = 0, newton_iterations = 0;
};
inline Counts counts() { return {analyses.load(), factorisations.load(), newton_iterations.load()}; }

/// Peak resident memory of the process in bytes since the last
/// reset_peak_memory() (or the process start); 0 where /proc is missing.
inline std::int64_t peak_memory_bytes() {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (!f) return 0;
  char line[256];
  std::int64_t kb = 0;
  while (std::fgets(line, sizeof line, f))
    if (std::strncmp(line, "VmHWM:", 6) == 0) {
      std::sscanf(line + 6, "%lld", reinterpret_cast<long long*>(&kb));
      break;
    }
  std::fclose(f);
  return kb * 1024;
}

/// Resets the kernel's high-water mark of resident memory to the current
/// resident size (Linux >= 4.0: "5" to /proc/self/clear_refs), so that the
/// next peak_memory_bytes() is the peak of what ran in between. False when
/// that is not possible: peak_memory_bytes() then stays the peak so far.
inline bool reset_peak_memory() {
  std::FILE* f = std::fopen("/proc/self/clear_refs", "w");
  if (!f) return false;
  const bool ok = std::fputs("5", f) >= 0;
  return std::fclose(f) == 0 && ok;
}

}  // namespace surfmap::work
