// Benchmark of the full mapping pipeline (not a test): generated pairs of
// genus 1..6 at several sizes, printing per-stage time, Newton iterations and
// peak memory. Each case runs in a forked child so that peak RSS is its own.
//
//   build/bin/bench_map [--quick]
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "surfmap/map/surface_map.h"
#include "surfmap/samples/shapes.h"

using namespace surfmap;

namespace {

struct Case {
  std::string name;
  int genus;
  int resolution;
};

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

void run_case(const Case& c) {
  const TriMesh a = source_shape(c.genus, c.resolution), b = target_shape(c.genus, c.resolution);
  try {
    const SurfaceMapResult m = surface_map(a, b);
    double t_uni = 0, t_solve = 0, t_loc = 0, t_other = 0;
    for (const auto& [stage, s] : m.stage_times) {
      if (stage.find("uniformization") != std::string::npos) t_uni += s;
      else if (stage.find("solve") != std::string::npos || stage.find("candidates") != std::string::npos) t_solve += s;
      else if (stage.find("location") != std::string::npos) t_loc += s;
      else t_other += s;
    }
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    std::printf("%-10s %2d %8d %8d %6.2f %6.2f %6.2f %6.2f %7.2f %5d %7.3f %7.3f %6d %8.0f\n", c.name.c_str(), c.genus,
                a.num_vertices(), b.num_vertices(), t_uni, t_solve, t_loc, t_other, m.total_time, m.iterations,
                m.mean_dilatation, m.max_dilatation, m.flipped_triangles, ru.ru_maxrss / 1024.0);
  } catch (const std::exception& e) {
    std::printf("%-10s %2d %8d %8d  failed: %s\n", c.name.c_str(), c.genus, a.num_vertices(), b.num_vertices(), e.what());
  }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  const bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  std::vector<Case> cases;
  for (int g = 1; g <= 6; ++g) {
    cases.push_back({"small", g, g == 1 ? 50 : 40});
    if (!quick) cases.push_back({"medium", g, g == 1 ? 110 : 80});
  }
  if (!quick) cases.push_back({"large", 2, 150}), cases.push_back({"large", 1, 220});
  std::printf("%-10s %2s %8s %8s %6s %6s %6s %6s %7s %5s %7s %7s %6s %8s\n", "case", "g", "V_src", "V_dst", "unif",
              "solve", "locate", "other", "total_s", "iters", "meanD", "maxD", "flips", "peak_MB");
  std::fflush(stdout);
  for (const Case& c : cases) {
    const pid_t pid = fork();
    if (pid == 0) {
      run_case(c);
      _exit(0);
    }
    int status = 0;
    waitpid(pid, &status, 0);
  }
  return 0;
}
