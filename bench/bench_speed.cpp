// Speed benchmark of the genus-2 pipeline in solve units (issue 19; not a
// test). One run prints:
//   1. per pair size (default 50k and 200k source vertices): SU samples
//      interleaved with the map runs, so that the machine's load shows (SU =
//      one CHOLMOD analyse + factorise + solve of the larger mesh's cotangent
//      Laplacian, vertex 0 pinned, one BLAS thread, timed in this process),
//      their median, then every stage of the report's stage table (medians
//      over --repeat runs) in seconds and in SU, with factorisations, Newton
//      iterations and peak memory, and end to end;
//   2. the scaling rows: pair size, end-to-end seconds and SU, peak memory,
//      converged, flipped triangles;
//   3. the Newton / relaxation ratio at the same energy on a small genus-2
//      pair (--small, default 3500 source vertices): the pipeline with
//      solve.method = relaxation, its harmonic solve cancelled when its
//      energy reaches the Newton run's final energy (within 1e-6 relative).
//      Solve ratio: relaxation seconds to that energy / Newton's solve
//      stages ("full-resolution solve" + "harmonic solve"); end-to-end ratio:
//      (relaxation run's seconds until it reached that energy + the Newton
//      run's stages after the solve, which are the same work) / Newton's end
//      to end. The --repeat Newton and relaxation runs alternate (N R N R
//      ...), each pair giving its ratios, so that both sides of a ratio see
//      about the same load; the medians of the pairs' ratios are printed,
//      with the same ratio in CPU seconds (the process's, both threads),
//      which the machine's load moves much less. R_newton_s: the relaxation
//      run's "full-resolution solve" stage (the ranking's Newton solve of the
//      best classes, which the relaxation does not start from), part of its
//      end to end. With --relax-budget S the relaxation gives up after S
//      seconds of solve (ratio then marked ">").
// Each map runs in a forked child, so that its peak memory is its own.
//
//   build/bin/bench_speed [--sizes 50000,200000] [--repeat 3] [--threads 0] [--small 3500]
//                         [--relax-budget 300] [--no-ratio] [--progress] [--remeshed] [--rank-all]
// --remeshed: one implicit surface meshed twice (the overlay class is the
// best); --rank-all: every class solved on the coarse copy (the ranking
// before issue 19's early stop).
// A 1M row: --sizes 1000000 (the pair alone needs many minutes and GBs).
#include <dlfcn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <map>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <Eigen/CholmodSupport>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>
#include <nlohmann/json.hpp>

#include "surfmap/error.h"
#include "surfmap/map/map_report.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/testing/map_hooks.h"
#include "surfmap/samples/shapes.h"

using namespace surfmap;
using Clock = std::chrono::steady_clock;
using nlohmann::json;

namespace {

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The pair of bench_map's genus-2 rows: an n-hole torus onto a vase, at the
// resolution giving about `v` source vertices (implicit shapes grow like res²).
int resolution_for(int v) {
  const int r0 = 40;
  const double v0 = samples::n_hole_torus(2, r0, true).num_vertices();
  return std::max(32, static_cast<int>(std::lround(r0 * std::sqrt(v / v0))));
}

struct Pair {
  TriMesh a, b;
};
// --remeshed: the held-out kind of pair instead, one smooth implicit
// surface meshed twice on different grids (n-hole torus at res and 1.06 res;
// the overlay class is the best there).
bool g_remeshed = false;
// --rank-all: every class solved on the coarse copy (ranking_gap < 0, the
// ranking before issue 19's early stop), for a before / after in one run.
bool g_rank_all = false;
Pair make_pair_of(int v) {
  const int res = resolution_for(v);
  if (g_remeshed) return {samples::n_hole_torus(2, res, true), samples::n_hole_torus(2, static_cast<int>(std::lround(1.06 * res)), true)};
  return {samples::n_hole_torus(2, res, true), samples::vase(res, true)};
}

// One BLAS thread and no CHOLMOD OpenMP teams, as the pipeline runs them
// (src/map/concurrency.h), for the SU and every run.
void single_threaded_blas() {
  if (auto set = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) set(1);
  if (auto set = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels"))) set(0);
}

// The cotangent Laplacian of `m` without vertex 0's row and column (definite).
Eigen::SparseMatrix<double> pinned_cotangent_laplacian(const TriMesh& m) {
  std::vector<Eigen::Triplet<double>> t;
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int i = m.F(f, k), j = m.F(f, (k + 1) % 3), o = m.F(f, (k + 2) % 3);
      const Eigen::Vector3d a = m.V.row(i) - m.V.row(o), b = m.V.row(j) - m.V.row(o);
      const double w = 0.5 * a.dot(b) / std::max(a.cross(b).norm(), 1e-300);
      for (auto [r, c, s] : {std::tuple{i, i, w}, std::tuple{j, j, w}, std::tuple{i, j, -w}, std::tuple{j, i, -w}})
        if (r > 0 && c > 0) t.emplace_back(r - 1, c - 1, s);
    }
  Eigen::SparseMatrix<double> L(m.num_vertices() - 1, m.num_vertices() - 1);
  L.setFromTriplets(t.begin(), t.end());
  return L;
}

// Process CPU seconds.
double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}
std::vector<double> g_su_cpu;  // CPU seconds of every SU sample

// One solve unit: analyse + factorise + solve, seconds (its CPU seconds go
// to g_su_cpu).
double solve_unit(const Eigen::SparseMatrix<double>& L) {
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(L.rows());
  const double c0 = cpu_seconds();
  const auto t0 = Clock::now();
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>> llt;
  llt.analyzePattern(L);
  llt.factorize(L);
  const Eigen::VectorXd x = llt.solve(b);
  const double s = since(t0);
  g_su_cpu.push_back(cpu_seconds() - c0);
  if (llt.info() != Eigen::Success || !x.allFinite()) std::fprintf(stderr, "bench_speed: SU solve failed\n");
  return s;
}

// Runs `body` (returning JSON) in a forked child and returns its JSON, or
// {"error": ...}.
template <class Body>
json in_child(Body body) {
  int fd[2];
  if (pipe(fd) != 0) return {{"error", "pipe failed"}};
  const pid_t pid = fork();
  if (pid == 0) {
    close(fd[0]);
    std::string text;
    try {
      text = body().dump();
    } catch (const std::exception& e) {
      text = json{{"error", e.what()}}.dump();
    }
    size_t off = 0;
    while (off < text.size()) {
      const ssize_t w = write(fd[1], text.data() + off, text.size() - off);
      if (w <= 0) break;
      off += static_cast<size_t>(w);
    }
    close(fd[1]);
    _exit(0);
  }
  close(fd[1]);
  std::string text;
  char buf[65536];
  for (ssize_t r; (r = read(fd[0], buf, sizeof buf)) > 0;) text.append(buf, static_cast<size_t>(r));
  close(fd[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (text.empty()) return {{"error", "the run died (status " + std::to_string(status) + ")"}};
  return json::parse(text);
}

bool g_progress = false;  // --progress: every stage's end on stderr, as it happens

// One map of the pair: the report's stage table and figures; with
// `solve_end_cpu`, also the process's CPU seconds from the start to the end
// of the "harmonic solve" stage (the ratio rows' CPU after the solve).
json map_run(const Pair& p, int threads, bool solve_end_cpu = false) {
  SurfaceMapOptions opt;
  opt.threads = threads;
  if (g_rank_all) opt.homotopy.ranking_gap = -1;
  const auto t0 = Clock::now();
  const double c0 = cpu_seconds();
  double solve_end = NAN;
  if (g_progress || solve_end_cpu)
    opt.progress = [t0, c0, &solve_end](const std::string& stage, double fraction) {
      if (stage == "harmonic solve" && fraction >= 0.7) solve_end = cpu_seconds() - c0;  // the stage's end
      if (g_progress)
        std::fprintf(stderr, "bench_speed: %8.1f s %3d%% %s\n", since(t0), static_cast<int>(100 * fraction), stage.c_str());
      return true;
    };
  // Faces crossed by the location walks: their cost whatever the load.
  testing::MapHooks hooks;
  long forward_steps = -1, inverse_steps = -1;
  hooks.location_walk_steps = [&](long f, long i) { forward_steps = f, inverse_steps = i; };
  const SurfaceMapResult m = testing::surface_map(p.a, p.b, opt, hooks);
  const double cpu = cpu_seconds() - c0;
  const json report = to_json(m, opt);
  return {{"stages", report["stages"]},
          {"solve_end_cpu", std::isfinite(solve_end) ? json(solve_end) : json()},
          {"walk_steps", {forward_steps, inverse_steps}},
          {"ranking", report["homotopy"].value("ranking", json::object())},
          {"converged", m.converged},
          {"flipped", m.flipped_triangles},
          {"energy", m.final_energy},
          {"total", m.total_time},
          {"cpu", cpu}};
}

struct StageRow {
  std::vector<double> seconds, factorisations, newton, peak;
};

void size_rows(int v, int repeat, int threads, std::vector<std::string>& scaling) {
  const auto tg = Clock::now();
  const Pair p = make_pair_of(v);
  const int larger = std::max(p.a.num_vertices(), p.b.num_vertices());
  std::printf("\n== pair %d / %d vertices (generated in %.1f s)\n", p.a.num_vertices(), p.b.num_vertices(), since(tg));
  const Eigen::SparseMatrix<double> L = pinned_cotangent_laplacian(larger == p.a.num_vertices() ? p.a : p.b);
  std::vector<double> su, totals, peaks, cpus;
  std::vector<std::string> order;
  std::map<std::string, StageRow> rows;
  int converged = 0, flips = 0;
  su.push_back(solve_unit(L));
  for (int r = 0; r < repeat; ++r) {
    const json run = in_child([&] { return map_run(p, threads); });
    if (run.contains("error")) {
      std::printf("run %d failed: %s\n", r, run["error"].get<std::string>().c_str());
      su.push_back(solve_unit(L));
      continue;
    }
    for (const json& s : run["stages"]) {
      const std::string name = s["name"];
      if (!rows.count(name)) order.push_back(name);
      StageRow& row = rows[name];
      row.seconds.push_back(s["time_s"]);
      row.factorisations.push_back(s["factorisations"]);
      row.newton.push_back(s["newton_iterations"]);
      row.peak.push_back(s["peak_memory_mb"]);
    }
    totals.push_back(run["total"]);
    cpus.push_back(run.value("cpu", NAN));
    converged += run["converged"].get<bool>();
    flips = std::max(flips, run["flipped"].get<int>());
    su.push_back(solve_unit(L));
    if (run.contains("ranking") && !run["ranking"].empty())
      std::printf("  run %d ranking: %d coarse solves, %d classes skipped (%s)\n", r, run["ranking"].value("coarse_solves", -1),
                  run["ranking"].value("skipped", -1), run["ranking"].value("status", std::string()).c_str());
    std::printf("  run %d: %.3f s; SU samples so far:", r, totals.back());
    for (double s : su) std::printf(" %.3f", s);
    std::printf("\n");
    if (run.contains("walk_steps") && run["walk_steps"][0].get<long>() >= 0)
      std::printf("  run %d location walks: forward %ld faces (%.2f per source vertex), inverse %ld\n", r,
                  run["walk_steps"][0].get<long>(), run["walk_steps"][0].get<double>() / p.a.num_vertices(),
                  run["walk_steps"][1].get<long>());
    std::fflush(stdout);
  }
  const double SU = median(su);
  const std::vector<double> su_cpu(g_su_cpu.end() - static_cast<long>(su.size()), g_su_cpu.end());
  const double SU_cpu = median(su_cpu);
  std::printf("SU (median of %zu samples, %d-vertex cotangent Laplacian): %.3f s wall, %.3f s CPU\n", su.size(), larger,
              SU, SU_cpu);
  std::printf("%-34s %9s %8s %8s %7s %10s\n", "stage (medians)", "time_s", "SU", "factor.", "newton", "peak_MiB");
  for (const std::string& name : order) {
    const StageRow& row = rows[name];
    const double s = median(row.seconds);
    std::printf("%-34s %9.3f %8.2f %8.0f %7.0f %10.1f\n", name.c_str(), s, s / SU, median(row.factorisations),
                median(row.newton), median(row.peak));
  }
  // The map's CPU seconds (both threads): above its wall seconds where the
  // threads overlapped; in CPU SU, the work whatever the machine's load.
  const double cpu = median(cpus);
  std::printf("%-34s %9.3f %8s   CPU SU %.2f, CPU / wall %.2f\n", "end to end CPU (both threads)", cpu, "", cpu / SU_cpu,
              cpu / median(totals));
  const double total = median(totals);
  const double peak = rows.count("total") ? median(rows["total"].peak) : NAN;
  char line[256];
  std::snprintf(line, sizeof line, "%8d %8d %10.2f %8.3f %9.1f %10.0f %6d/%d %6d", p.a.num_vertices(),
                p.b.num_vertices(), total, SU, total / SU, peak, converged, repeat, flips);
  scaling.push_back(line);
  std::fflush(stdout);
}

// The relaxation run: seconds (and the process's CPU seconds) from the start
// to the solve's start and to the energy `target` (NaN when not reached
// within `budget`).
json relaxation_run(const Pair& p, double target, double budget, int threads) {
  SurfaceMapOptions opt;
  opt.threads = threads;
  opt.solve.method = MapMethod::Relaxation;
  opt.solve.max_iterations = 100000000;
  const auto t0 = Clock::now();
  const double c0 = cpu_seconds();
  double solve_start = NAN, reached = NAN, reached_cpu = NAN, last_energy = NAN;
  // The stage before the relaxation, "full-resolution solve", is the
  // ranking's Newton solve of the best classes (stages/harmonic_solve.h: not
  // reused as the relaxation's start): its seconds are reported apart.
  // (The ranking's solves report "homotopy candidates" at 0.4 as they go;
  // that stage ends with 0.42, the pipeline's stage_done.)
  double candidates_end = NAN, full_solve = NAN;
  opt.progress = [&](const std::string& stage, double fraction) {
    const double now = since(t0);
    if (stage == "homotopy candidates" && fraction > 0.41) candidates_end = now;
    if (stage == "full-resolution solve") full_solve = now - candidates_end;
    if (stage == "initial map") solve_start = now;
    return true;
  };
  double stopped_cpu = NAN;  // CPU seconds when the budget ran out
  opt.solve_progress = [&](int, double E, double) {
    last_energy = E;
    if (E <= target * (1 + 1e-6)) {
      reached = since(t0);
      reached_cpu = cpu_seconds() - c0;
      return false;
    }
    if (std::isfinite(solve_start) && since(t0) - solve_start > budget) {
      stopped_cpu = cpu_seconds() - c0;
      return false;
    }
    return true;
  };
  try {
    surface_map(p.a, p.b, opt);
  } catch (const Cancelled&) {
  }
  auto num = [](double x) { return std::isfinite(x) ? json(x) : json(); };
  return {{"solve_start", num(solve_start)}, {"reached", num(reached)}, {"reached_cpu", num(reached_cpu)},
          {"stopped_cpu", num(stopped_cpu)}, {"full_solve", num(full_solve)}, {"energy", num(last_energy)}};
}

double number_or_nan(const json& j, const char* key) { return j.contains(key) && j[key].is_number() ? j[key].get<double>() : NAN; }

void ratio_rows(int v, int repeat, double budget, int threads) {
  const Pair p = make_pair_of(v);
  std::printf("\n== Newton / relaxation at the same energy, pair %d / %d vertices (runs alternated N R N R ...)\n",
              p.a.num_vertices(), p.b.num_vertices());
  std::printf("%4s %10s %10s %10s %12s %10s %10s %8s %10s %10s %10s\n", "pair", "N_solve_s", "N_total_s", "N_cpu_s",
              "energy", "R_solve_s", "R_total_s", "R_cpu_s", "R_newton_s", "ratio_e2e", "ratio_cpu");
  std::vector<double> solve_ratio, total_ratio, cpu_ratio, n_total, r_solve;
  bool all_reached = true;
  for (int r = 0; r < repeat; ++r) {
    const json run = in_child([&] { return map_run(p, threads, true); });
    if (run.contains("error")) {
      std::printf("%4d the Newton run failed: %s\n", r, run["error"].get<std::string>().c_str());
      continue;
    }
    // Newton's solve stages, and its stages after the solve (the same work
    // in both runs: quality and location of the same energy's map).
    double s = 0, post = 0;
    bool past = false;
    for (const json& st : run["stages"]) {
      const std::string name = st["name"];
      if (name == "full-resolution solve" || name == "harmonic solve") s += st["time_s"].get<double>();
      if (past && name != "total") post += st["time_s"].get<double>();
      if (name == "harmonic solve") past = true;
    }
    const double total = run["total"], cpu = run["cpu"], energy = run["energy"];
    const double post_cpu = cpu - number_or_nan(run, "solve_end_cpu");
    const json relax = in_child([&] { return relaxation_run(p, energy, budget, threads); });
    if (relax.contains("error")) {
      std::printf("%4d the relaxation run failed: %s\n", r, relax["error"].get<std::string>().c_str());
      continue;
    }
    const double start = number_or_nan(relax, "solve_start"), reached = number_or_nan(relax, "reached");
    const bool got = std::isfinite(reached);
    all_reached = all_reached && got;
    const double relax_solve = got ? reached - start : budget;
    const double relax_total = (got ? reached : start + budget) + post;
    const double relax_cpu = number_or_nan(relax, got ? "reached_cpu" : "stopped_cpu") + post_cpu;
    solve_ratio.push_back(relax_solve / s), total_ratio.push_back(relax_total / total);
    cpu_ratio.push_back(relax_cpu / cpu), n_total.push_back(total), r_solve.push_back(relax_solve);
    std::printf("%4d %10.3f %10.3f %10.3f %12.10g %10.3f %10.3f %8.3f %10.3f %9s%.1f %9s%.1f\n", r, s, total, cpu, energy,
                relax_solve, relax_total, relax_cpu, number_or_nan(relax, "full_solve"), got ? "" : ">", total_ratio.back(),
                got ? "" : ">", cpu_ratio.back());
  }
  if (total_ratio.empty()) return void(std::printf("no Newton / relaxation pair completed\n"));
  const char* mark = all_reached ? "" : ">";
  std::printf("Newton end to end %.3f s, relaxation %.3f s of solve (medians of %zu pairs)\n", median(n_total),
              median(r_solve), total_ratio.size());
  std::printf("ratio relaxation/Newton (median of the pairs' ratios): solve %s%.1fx, end to end %s%.1fx, end to end in CPU "
              "seconds %s%.1fx\n",
              mark, median(solve_ratio), mark, median(total_ratio), mark, median(cpu_ratio));
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes{50000, 200000};
  int repeat = 3, threads = 0, small = 3500;
  double budget = 300;
  bool ratio = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_speed: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--sizes") {
      sizes.clear();
      std::stringstream s(next());
      for (std::string t; std::getline(s, t, ',');) sizes.push_back(std::stoi(t));
    } else if (a == "--repeat") repeat = std::max(1, std::stoi(next()));
    else if (a == "--threads") threads = std::stoi(next());
    else if (a == "--small") small = std::stoi(next());
    else if (a == "--relax-budget") budget = std::stod(next());
    else if (a == "--no-ratio") ratio = false;
    else if (a == "--progress") g_progress = true;
    else if (a == "--remeshed") g_remeshed = true;
    else if (a == "--rank-all") g_rank_all = true;
    else {
      std::fprintf(stderr, "usage: bench_speed [--sizes 50000,200000] [--repeat 3] [--threads 0] [--small 3500] "
                           "[--relax-budget 300] [--no-ratio] [--progress] [--remeshed] [--rank-all]\n");
      return 2;
    }
  }
  single_threaded_blas();
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  std::vector<std::string> scaling;
  for (int v : sizes) size_rows(v, repeat, threads, scaling);
  std::printf("\n== scaling (medians)\n%8s %8s %10s %8s %9s %10s %8s %6s\n", "Vs", "Vt", "total_s", "SU_s", "total_SU",
              "peak_MiB", "conv", "flips");
  for (const std::string& line : scaling) std::printf("%s\n", line.c_str());
  if (ratio) ratio_rows(small, repeat, budget, threads);
  return 0;
}
