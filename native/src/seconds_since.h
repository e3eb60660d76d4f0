#pragma once
// Wall seconds since a start on the steady clock: the stage timings of the
// results (time_s, *_seconds). Internal (native/src); the CLI and the
// benchmarks include it by its path for their own timings.
#include <chrono>

namespace surfmap::detail {

/// Seconds from `start` to now (std::chrono::steady_clock: never goes back).
inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace surfmap::detail
