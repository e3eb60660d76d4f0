#pragma once
// Stage concurrency of the map pipeline (issue 4's speed target: 2 cores).
// Independent work runs on a second thread: the coarse class solves of the
// ranking, and the initial ("before") map next to the full-resolution solves.
//
// Callbacks (SurfaceMapOptions::progress, solve_progress) are only ever
// called on the calling thread: Blender's progress reporting must not run on
// another thread, and Python callbacks then never race. The other threads
// see a stop flag instead, raised when any thread fails (Cancelled
// included), so that they give up early; the first exception is rethrown on
// the calling thread, unchanged.
#include <dlfcn.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <exception>
#include <future>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace surfmap::detail {

/// Held around sparse fill-reducing orderings: METIS keeps its random
/// generator's state in globals, so two orderings at once would race (and
/// could order differently from run to run).
inline std::mutex& ordering_mutex() {
  static std::mutex m;
  return m;
}

/// Threads the pipeline runs at once for SurfaceMapOptions::threads =
/// `requested`: itself when >= 1; 0: SURFMAP_THREADS when set, else the
/// hardware's, at most 2 (the stages that overlap are two or three, and
/// each holds a sparse factorisation in memory).
inline int pipeline_threads(int requested) {
  if (requested >= 1) return std::min(requested, 8);
  if (const char* s = std::getenv("SURFMAP_THREADS")) {
    const int n = std::atoi(s);
    if (n >= 1) return std::min(n, 8);
  }
  return std::thread::hardware_concurrency() >= 2 ? 2 : 1;
}

/// OpenBLAS's thread-count functions when it is the BLAS this process
/// loaded (libblas.so.3 through update-alternatives), else nullptrs.
struct OpenBlasThreads {
  int (*get)() = nullptr;
  void (*set)(int) = nullptr;
};
inline OpenBlasThreads openblas_threads() {
  // The library CHOLMOD loaded (a dependency of libblas.so.3); not found
  // through RTLD_DEFAULT when our Python module was loaded RTLD_LOCAL.
  OpenBlasThreads t;
  void* lib = dlopen("libopenblas.so.0", RTLD_LAZY | RTLD_NOLOAD);
  void* where = lib ? lib : RTLD_DEFAULT;
  t.get = reinterpret_cast<int (*)()>(dlsym(where, "openblas_get_num_threads"));
  t.set = reinterpret_cast<void (*)(int)>(dlsym(where, "openblas_set_num_threads"));
  if (lib) dlclose(lib);  // NOLOAD took a reference; the library stays loaded
  if (!t.get || !t.set) t = OpenBlasThreads();
  return t;
}

/// True when the BLAS is an optimised one (OpenBLAS), which changes which
/// sparse ordering pays (hyperbolic_harmonic.cpp).
inline bool optimised_blas() {
  static const bool yes = openblas_threads().get != nullptr;
  return yes;
}

/// While alive, a multithreaded BLAS (OpenBLAS, when libblas.so.3 is it:
/// scripts/bootstrap.sh) runs single-threaded, and so do CHOLMOD's OpenMP
/// loops (libgomp's max-active-levels 0: every parallel region gets a team
/// of one); both restored after. Two of our threads each factorising then do
/// not start more threads than cores: CHOLMOD asks for teams of 4 in small
/// supernodal loops, whose spinning threads cost ~1 s of CPU (user + system)
/// per 50k genus-2 map on two cores, measured with OMP_THREAD_LIMIT=1. And
/// the results do not depend on SurfaceMapOptions::threads: the BLAS's
/// blocking follows its thread count, and its round-off moves the coarse
/// estimates of very twisted classes (whose solves stop short of their
/// optimum) by up to 1e-3 relative. Nothing happens with a BLAS without
/// threads. The BLAS's thread count is process-wide: construct it only while
/// no BLAS call of this process is running. OpenMP's max-active-levels is
/// per thread (a thread started with std::thread or std::async begins with
/// the default), so every thread of ours that may factorise constructs one
/// as well (issue 19: on the 4.9k bench pair the pipeline's other threads
/// ran CHOLMOD's loops in teams, ~6000-8000 context switches a map against
/// ~1100 with this, and ~8% of the map's CPU).
class SingleThreadedBlas {
 public:
  SingleThreadedBlas() : blas_(openblas_threads()) {
    if (blas_.get) {
      saved_ = blas_.get();
      if (saved_ > 1) blas_.set(1);
    }
    if (void* gomp = dlopen("libgomp.so.1", RTLD_LAZY | RTLD_NOLOAD)) {
      get_levels_ = reinterpret_cast<int (*)()>(dlsym(gomp, "omp_get_max_active_levels"));
      set_levels_ = reinterpret_cast<void (*)(int)>(dlsym(gomp, "omp_set_max_active_levels"));
      dlclose(gomp);  // NOLOAD took a reference; CHOLMOD keeps it loaded
      if (get_levels_ && set_levels_) {
        saved_levels_ = get_levels_();
        set_levels_(0);
      } else {
        set_levels_ = nullptr;
      }
    }
  }
  ~SingleThreadedBlas() {
    if (blas_.set && saved_ > 1) blas_.set(saved_);
    if (set_levels_) set_levels_(saved_levels_);
  }
  SingleThreadedBlas(const SingleThreadedBlas&) = delete;
  SingleThreadedBlas& operator=(const SingleThreadedBlas&) = delete;

 private:
  OpenBlasThreads blas_;
  int saved_ = 0;
  int (*get_levels_)() = nullptr;
  void (*set_levels_)(int) = nullptr;
  int saved_levels_ = 0;
};

/// body(k, stop) for k = 0..n-1, each k once, on `threads` threads;
/// `stop` is nullptr on the calling thread (it may call callbacks) and the
/// shared stop flag on the others. The calling thread runs k = 0 (so a task
/// that reports progress can be put first); the others are taken in order. The first exception (the calling thread's
/// first) is rethrown after every thread has finished.
template <class Body>
void parallel_for(int threads, int n, Body body) {
  threads = std::min(threads, n);
  if (threads <= 1) {
    for (int k = 0; k < n; ++k) body(k, static_cast<const std::atomic<bool>*>(nullptr));
    return;
  }
  std::atomic<int> next{1};  // k = 0 is the calling thread's
  std::atomic<bool> stop{false};
  auto loop = [&](const std::atomic<bool>* flag) {
    for (int k; !stop && (k = next++) < n;) body(k, flag);
  };
  std::vector<std::future<void>> workers;
  for (int t = 1; t < threads; ++t)
    workers.push_back(std::async(std::launch::async, [&] {
      const SingleThreadedBlas single_threaded_blas;  // (per thread: OpenMP's levels, below)
      try {
        loop(&stop);
      } catch (...) {
        stop = true;
        throw;
      }
    }));
  std::exception_ptr first;
  try {
    body(0, static_cast<const std::atomic<bool>*>(nullptr));
    loop(nullptr);
  } catch (...) {
    first = std::current_exception();
    stop = true;
  }
  for (auto& w : workers) {
    try {
      w.get();
    } catch (...) {
      if (!first) first = std::current_exception();
    }
  }
  if (first) std::rethrow_exception(first);
}

}  // namespace surfmap::detail
