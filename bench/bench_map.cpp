// Benchmark of the full mapping pipeline (not a test): generated pairs of
// genus 1..6 at about 10k, 50k and 200k vertices per mesh, printing the
// per-stage times, Newton iterations and peak memory, and comparing the
// Newton solve (genus 1: the exact sparse solve) with the paper's relaxation
// (map/harmonic_relaxation.h) on exactly the same input: the pipeline hands
// its harmonic-map problem (edges, deck elements, start = the initial map)
// over through testing::MapHooks::inspect_problem (testing/map_hooks.h).
//
// Ratio column: (time the relaxation needs to reach Newton's final energy
// within a relative 1e-6, or its own converged best) / (Newton's solve time
// on the same problem from the same start: it/newtonT columns; the pipeline's
// own solve starts from the chosen class's coarse solution, "solve" column,
// and its iterations are not shown).
// The relaxation runs under a time budget; when the budget ends first its
// remaining time is extrapolated from the observed linear rate of the energy
// gap E − E_newton over the second half of the run (marked "~"), assuming
// that rate holds. The rate only slows down, so a short budget flatters the
// relaxation: 10k genus 2, 37 s extrapolated from 20 s vs 35.7 s measured
// with 150 s; 200k genus 2, ~361 s from 20 s but ~2020 s from 240 s. Give
// large meshes a budget of minutes (--relax-budget). Relaxation
// times count sweeps only (the energy evaluations every few sweeps, needed
// just for this table, are excluded).
//
// ratioM column: measured both ways, no extrapolation: the relaxation's
// time (relaxT) over the time Newton needs to reach the relaxation's final
// energy on the same problem from the same start (N_to_rE, from Newton's
// per-iteration energies); it grows with the budget (a short one leaves the
// relaxation far from the optimum). Newton and the relaxation each run on one
// core (BLAS and CHOLMOD's OpenMP loops single-threaded).
//
// Each run happens in a forked child so that peak RSS (ru_maxrss) is its own;
// with --repeat N every case runs N times and the medians are printed.
//
//   build/bin/bench_map [--quick] [--stages] [--relax-budget S] [--repeat N] [--sizes 10000,50000,200000] [--genus 1,2,...]
#include <dlfcn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/CholmodSupport>
#include <Eigen/SparseCore>

#include "../native/src/seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/map/harmonic_relaxation.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/testing/map_hooks.h"
#include "surfmap/samples/shapes.h"

using namespace surfmap;
using detail::seconds_since;
using Clock = std::chrono::steady_clock;

namespace {

bool g_stages = false;  // --stages: every stage's time of every run, on stderr

TriMesh source_shape(int genus, int res) {
  if (genus == 1) return samples::torus_of_revolution(1.0, 0.5, 2 * res, res);
  return samples::n_hole_torus(genus, res, true);
}

TriMesh target_shape(int genus, int res) {
  if (genus == 1) return samples::torus_of_revolution(1.5, 0.5, 5 * res / 2, res, 1);
  if (genus == 2) return samples::vase(res, true);
  if (genus == 3) return samples::polycube(3, res, true);
  return samples::jitter(samples::n_hole_torus(genus, res + res / 8, true), 0.1, 7);
}

// Resolution giving about `v` source vertices: the tori have 2 res² vertices;
// implicit shapes grow like res², calibrated on one coarse mesh.
int resolution_for(int genus, int v) {
  if (genus == 1) return std::max(8, static_cast<int>(std::lround(std::sqrt(v / 2.0))));
  const int r0 = 40;
  const double v0 = source_shape(genus, r0).num_vertices();
  return std::max(32, static_cast<int>(std::lround(r0 * std::sqrt(v / v0))));
}

// Everything one run reports back to the parent (plain doubles over a pipe).
enum Field {
  kOk, kVs, kVt, kUnif, kHomotopy, kInit, kSolve, kLocate, kOther, kTotal, kNewtonIt, kNewtonT, kNewtonE,
  kSweeps, kRelaxT, kRelaxGap, kRelaxReachT, kReachKind, kRatio, kNewtonToRelaxT, kRatioMeasured, kPeakMB, kFlips,
  kInitFlips, kMeanD, kInitMeanD,
  kNumFields
};
// kReachKind: 0 measured (reached), 1 own converged best, 2 extrapolated, 3 no decrease.

std::vector<double> run_case(int genus, int v, double budget, std::string* error) {
  // One core each for the Newton-versus-relaxation comparison (the
  // relaxation's sweeps are sequential); the pipeline itself runs its BLAS
  // and CHOLMOD's OpenMP loops single-threaded too (src/map/concurrency.h),
  // with its own threads.
  if (auto set = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) set(1);
  if (auto set = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels"))) set(0);  // CHOLMOD's loops
  std::vector<double> r(kNumFields, NAN);
  r[kOk] = 0;
  const int res = resolution_for(genus, v);
  const TriMesh a = source_shape(genus, res), b = target_shape(genus, res);
  r[kVs] = a.num_vertices(), r[kVt] = b.num_vertices();
  HarmonicProblem problem;
  SurfaceMapOptions opt;
  testing::MapHooks hooks;
  hooks.inspect_problem = [&](const HarmonicProblem& p) { problem = p; };
  SurfaceMapResult m;
  try {
    m = surface_map(a, b, opt, hooks);
  } catch (const std::exception& e) {
    *error = e.what();
    return r;
  }
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  r[kPeakMB] = ru.ru_maxrss / 1024.0;
  double t[5] = {0, 0, 0, 0, 0};  // uniformization, homotopy, initial map, solve, location
  double other = 0;
  for (const auto& [stage, s] : m.stage_times) {
    if (stage.find("uniformization") != std::string::npos) t[0] += s;
    else if (stage.find("homotopy") != std::string::npos) t[1] += s;
    else if (stage.find("initial") != std::string::npos) t[2] += s;
    else if (stage.find("solve") != std::string::npos) t[3] += s;
    else if (stage.find("location") != std::string::npos) t[4] += s;
    else other += s;
  }
  if (g_stages) {
    for (const auto& [stage, sec] : m.stage_times) std::fprintf(stderr, "  %-40s %7.3f s\n", stage.c_str(), sec);
    std::fprintf(stderr, "  %-40s %7.3f s\n", "total", m.total_time);
  }
  r[kUnif] = t[0], r[kHomotopy] = t[1], r[kInit] = t[2], r[kSolve] = t[3], r[kLocate] = t[4], r[kOther] = other;
  r[kTotal] = m.total_time;
  r[kFlips] = m.flipped_triangles + m.degenerate_triangles;
  r[kInitFlips] = m.initial_flipped_triangles;
  r[kMeanD] = m.mean_dilatation, r[kInitMeanD] = m.initial_mean_dilatation;

  // Newton (genus >= 2: the pipeline's own solve; genus 1: one factorisation
  // and solve of the weight Laplacian, which is what the exact method costs
  // per class) and its final energy.
  double e_star = 0;
  std::vector<std::pair<double, double>> newton_history;  // (seconds, energy); hyperbolic only
  if (!problem.flat) {
    // The pipeline's own solve starts from the class's coarse solution (and
    // its time is in the solve column); for the comparison Newton solves
    // exactly the relaxation's problem, from the initial map.
    // Newton's energy at every iteration with the time it was reached (the
    // measured ratio below); the callback costs nothing next to an iteration.
    HyperbolicHarmonicOptions no;
    const auto t0 = Clock::now();
    no.progress = [&](int, double E, double) {
      newton_history.emplace_back(seconds_since(t0), E);
      return true;
    };
    const HyperbolicHarmonicResult nr =
        hyperbolic_harmonic_map(problem.num_vertices, problem.edges, problem.generators, problem.start, no);
    r[kNewtonT] = seconds_since(t0);
    r[kNewtonIt] = nr.iterations;
    e_star = std::min(nr.energy, m.final_energy);
  } else {
    const auto t0 = Clock::now();
    const int n = problem.num_vertices;
    std::vector<Eigen::Triplet<double>> trip;
    Eigen::VectorXd bx = Eigen::VectorXd::Zero(n), by = Eigen::VectorXd::Zero(n);
    for (size_t e = 0; e < problem.flat_i.size(); ++e) {
      const int i = problem.flat_i[e], j = problem.flat_j[e];
      const double w = problem.flat_weight[e];
      const std::complex<double> tr = problem.flat_translation[e];
      for (auto [p, q, s] : {std::tuple{i, i, w}, std::tuple{j, j, w}, std::tuple{i, j, -w}, std::tuple{j, i, -w}})
        if (p > 0 && q > 0) trip.emplace_back(p - 1, q - 1, s);
      bx[i] += w * tr.real(), by[i] += w * tr.imag(), bx[j] -= w * tr.real(), by[j] -= w * tr.imag();
    }
    Eigen::SparseMatrix<double> L(n - 1, n - 1);
    L.setFromTriplets(trip.begin(), trip.end());
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> solver(L);
    const Eigen::VectorXd x = solver.solve(bx.tail(n - 1)), y = solver.solve(by.tail(n - 1));
    r[kNewtonT] = seconds_since(t0);
    r[kNewtonIt] = 1;
    std::vector<std::complex<double>> z(n, 0.0);
    for (int i = 1; i < n; ++i) z[i] = {x[i - 1], y[i - 1]};
    for (size_t e = 0; e < problem.flat_i.size(); ++e)
      e_star += problem.flat_weight[e] * std::norm(z[problem.flat_j[e]] + problem.flat_translation[e] - z[problem.flat_i[e]]);
  }
  r[kNewtonE] = e_star;

  // The relaxation on the same input, under the time budget.
  HarmonicRelaxationOptions ro;
  ro.time_budget_s = budget;
  ro.check_every = 10;
  HarmonicRelaxationResult rr =
      problem.flat ? flat_harmonic_relaxation(problem.num_vertices, problem.flat_i, problem.flat_j, problem.flat_weight,
                                              problem.flat_translation, problem.start, ro)
                   : harmonic_relaxation(problem.num_vertices, problem.edges, problem.generators, problem.start, ro);
  r[kSweeps] = rr.iterations;
  r[kRelaxT] = rr.time_history.back();
  const double goal = e_star * (1 + 1e-6);
  const auto& E = rr.energy_history;
  const auto& T = rr.time_history;
  r[kRelaxGap] = (E.back() - e_star) / e_star;
  int hit = -1;
  for (size_t k = 0; k < E.size(); ++k)
    if (E[k] <= goal) {
      hit = static_cast<int>(k);
      break;
    }
  if (hit >= 0) {
    r[kRelaxReachT] = T[hit], r[kReachKind] = 0;
  } else if (rr.converged) {
    r[kRelaxReachT] = T.back(), r[kReachKind] = 1;
  } else {
    // Linear (geometric) rate of the gap over the second half of the run.
    const size_t k1 = E.size() - 1, k0 = k1 / 2;
    const double g0 = E[k0] - e_star, g1 = E[k1] - e_star;
    if (k1 >= 4 && g1 > 0 && g0 > g1 && T[k1] > T[k0]) {
      const double rate = std::log(g0 / g1) / (T[k1] - T[k0]);  // per second
      r[kRelaxReachT] = T[k1] + std::log(g1 / (goal - e_star)) / rate;
      r[kReachKind] = 2;
    } else {
      r[kReachKind] = 3;
    }
  }
  r[kRatio] = r[kRelaxReachT] / r[kNewtonT];
  // Measured both ways, no extrapolation: the time Newton takes to reach the
  // relaxation's final energy (where its budget or convergence left it)
  // against the relaxation's time. It grows with the budget: a short budget
  // leaves the relaxation far from the optimum, which Newton passes in its
  // first iterations (its analysis and first factorisation included).
  if (!problem.flat) {
    const double e_relax = E.back();
    r[kNewtonToRelaxT] = r[kNewtonT];
    for (const auto& [t, en] : newton_history)
      if (en <= e_relax) {
        r[kNewtonToRelaxT] = t;
        break;
      }
    r[kRatioMeasured] = T.back() / r[kNewtonToRelaxT];
  }
  r[kOk] = 1;
  return r;
}

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return std::isnan(x); }), v.end());
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

std::vector<int> parse_list(const char* s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::atoi(item.c_str()));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  double budget = 20;
  int repeat = 1;
  std::vector<int> sizes = {10000, 50000, 200000}, genera = {1, 2, 3, 4, 5, 6};
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) {
      quick = true;
    } else if (!std::strcmp(argv[i], "--stages")) {
      g_stages = true;
    } else if (!std::strcmp(argv[i], "--relax-budget") && i + 1 < argc) {
      budget = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) {
      repeat = std::max(1, std::atoi(argv[++i]));
    } else if (!std::strcmp(argv[i], "--sizes") && i + 1 < argc) {
      sizes = parse_list(argv[++i]);
    } else if (!std::strcmp(argv[i], "--genus") && i + 1 < argc) {
      genera = parse_list(argv[++i]);
    } else {
      std::fprintf(stderr,
                   "usage: %s [--quick] [--stages] [--relax-budget S] [--repeat N] [--sizes a,b,c] [--genus g1,g2,...]\n"
                   "  --quick: genus 1-3 at 10k vertices, relaxation budget 5 s\n",
                   argv[0]);
      return 2;
    }
  }
  if (quick) {
    sizes = {10000};
    genera = {1, 2, 3};
    budget = std::min(budget, 5.0);
  }
  {
    // Which BLAS CHOLMOD runs on (scripts/bootstrap.sh installs OpenBLAS).
    Dl_info info{};
    void* gemm = dlsym(RTLD_DEFAULT, "dgemm_");
    char path[4096] = "?";
    if (gemm && dladdr(gemm, &info) && info.dli_fname && !realpath(info.dli_fname, path))
      std::snprintf(path, sizeof path, "%s", info.dli_fname);
    auto threads = reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "openblas_get_num_threads"));
    std::printf("BLAS %s%s; pipeline threads %s\n", path,
                threads ? (" (OpenBLAS, " + std::to_string(threads()) + " threads; 1 in the runs)").c_str() : "",
                std::getenv("SURFMAP_THREADS") ? std::getenv("SURFMAP_THREADS") : "auto");
  }
  std::printf("relaxation budget %.0f s per case; %d run(s) per case (medians); times in seconds\n", budget, repeat);
  std::printf("%2s %7s %7s | %5s %5s %5s %6s %5s %6s | %3s %7s | %7s %7s %9s %9s %8s | %7s %6s | %6s %5s %5s %6s %6s\n",
              "g", "V_src", "V_dst", "unif", "homot", "init", "solve", "locat", "total", "it", "newtonT", "sweeps",
              "relaxT", "gap_end", "reach_T", "ratio", "N_to_rE", "ratioM", "peakMB", "flips", "flip0", "meanD", "meanD0");
  std::fflush(stdout);
  for (int v : sizes)
    for (int g : genera) {
      std::vector<std::vector<double>> runs;
      std::string error;
      for (int rep = 0; rep < repeat; ++rep) {
        int fd[2];
        if (pipe(fd) != 0) return 1;
        const pid_t pid = fork();
        if (pid == 0) {
          close(fd[0]);
          std::string err;
          std::vector<double> r;
          try {
            r = run_case(g, v, budget, &err);
          } catch (const std::exception& e) {
            err = e.what();
            r.assign(kNumFields, NAN);
            r[kOk] = 0;
          }
          if (write(fd[1], r.data(), r.size() * sizeof(double)) < 0) _exit(1);
          const size_t len = err.size();
          if (write(fd[1], &len, sizeof len) < 0 || write(fd[1], err.data(), len) < 0) _exit(1);
          _exit(0);
        }
        close(fd[1]);
        std::vector<double> r(kNumFields, NAN);
        size_t len = 0;
        const bool got = read(fd[0], r.data(), r.size() * sizeof(double)) == static_cast<ssize_t>(r.size() * sizeof(double)) &&
                         read(fd[0], &len, sizeof len) == sizeof len;
        if (got && len > 0 && len < 100000) {
          std::string e(len, ' ');
          if (read(fd[0], e.data(), len) == static_cast<ssize_t>(len)) error = e;
        }
        close(fd[0]);
        int status = 0;
        waitpid(pid, &status, 0);
        if (!got) error = "child died (status " + std::to_string(status) + ")";
        if (got && r[kOk] == 1) runs.push_back(r);
      }
      if (runs.empty()) {
        std::printf("%2d %7d         | failed: %s\n", g, v, error.c_str());
        std::fflush(stdout);
        continue;
      }
      std::vector<double> med(kNumFields);
      for (int f = 0; f < kNumFields; ++f) {
        std::vector<double> col;
        for (const auto& r : runs) col.push_back(r[f]);
        med[f] = median(col);
      }
      const int kind = static_cast<int>(runs[0][kReachKind]);
      const char* mark = kind == 2 ? "~" : kind == 1 ? "*" : kind == 3 ? "?" : " ";
      char reach[32], ratio[32];
      std::snprintf(reach, sizeof reach, "%s%.3g", mark, med[kRelaxReachT]);
      std::snprintf(ratio, sizeof ratio, "%s%.0f", mark, med[kRatio]);
      std::printf("%2d %7.0f %7.0f | %5.2f %5.2f %5.2f %6.2f %5.2f %6.2f | %3.0f %7.3f | %7.0f %7.1f %9.2e %9s %8s | %7.3f %6.0f | %6.0f %5.0f %5.0f %6.3f %6.3f\n",
                  g, med[kVs], med[kVt], med[kUnif], med[kHomotopy], med[kInit], med[kSolve], med[kLocate], med[kTotal],
                  med[kNewtonIt], med[kNewtonT], med[kSweeps], med[kRelaxT], med[kRelaxGap], reach, ratio,
                  med[kNewtonToRelaxT], med[kRatioMeasured], med[kPeakMB], med[kFlips], med[kInitFlips], med[kMeanD],
                  med[kInitMeanD]);
      std::fflush(stdout);
    }
  std::printf("reach_T / ratio: measured; ~ extrapolated from the relaxation's rate at the budget; * its own converged "
              "best; ? no measurable decrease. genus 1: Newton = one exact sparse solve.\n"
              "N_to_rE / ratioM (genus >= 2, measured): seconds Newton takes to reach the relaxation's final energy, and "
              "relaxT / N_to_rE.\n");
  return 0;
}
