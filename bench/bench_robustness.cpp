// Robustness benchmark (issue 13, docs/robustness.md): uniformization and
// maps over an adversarial set the project generates itself: raw
// marching-tetrahedra output of implicit surfaces of genus 0-8 at several
// resolutions (no smoothing), CAD-like parts (plates and blocks with holes,
// long fans of thin triangles), meshes with exactly zero-area faces, strong
// edge-length noise, and optionally a 1M-face mesh and a pair of
// 1M / 0.86M faces (--large).
//
//   build/bin/bench_robustness [--large] [--no-pairs] [--only SUBSTRING] [--row-timeout S]
//
// Per mesh: faces mollified at intake, converged, residual (max curvature
// error), Newton iterations, intrinsic flips, time, peak memory. Per pair
// (surface_map, default options): converged, flipped triangles, D' mean/max.
// Every row runs in a forked child, so its peak memory is its own (ru_maxrss)
// and a crash, an exception or a timeout (default 900 s per row) shows up as
// that row's status, not the end of the run.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "../native/src/seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/uniformize/uniformize.h"

using namespace surfmap;
using detail::seconds_since;
namespace s = surfmap::samples;

namespace {

struct Case {
  std::string name;
  std::function<TriMesh()> make;
};

// Runs `body` in a child; returns its one-line output (or why it failed) and
// the child's peak memory in MB.
int g_row_timeout_s = 900;

std::string in_child(const std::function<std::string()>& body, double* peak_mb) {
  int fd[2];
  if (pipe(fd) != 0) return "pipe failed";
  std::fflush(stdout);
  const pid_t pid = fork();
  if (pid == 0) {
    close(fd[0]);
    alarm(static_cast<unsigned>(g_row_timeout_s));
    std::string line;
    try {
      line = body();
    } catch (const std::exception& e) {
      line = std::string("error: ") + e.what();
    }
    if (write(fd[1], line.data(), line.size()) < 0) _exit(2);
    _exit(0);
  }
  close(fd[1]);
  std::string out;
  char buf[4096];
  for (ssize_t n; (n = read(fd[0], buf, sizeof buf)) > 0;) out.append(buf, static_cast<size_t>(n));
  close(fd[0]);
  int status = 0;
  struct rusage ru {};
  wait4(pid, &status, 0, &ru);
  *peak_mb = ru.ru_maxrss / 1024.0;
  if (WIFSIGNALED(status) && WTERMSIG(status) == SIGALRM)
    return "TIMEOUT (more than " + std::to_string(g_row_timeout_s) + " s)";
  if (WIFSIGNALED(status)) return "CRASHED (signal " + std::to_string(WTERMSIG(status)) + ")";
  return out;
}

std::string uniformize_row(const TriMesh& raw) {
  const IntakeResult in = intake(raw.V, raw.F);
  const auto t0 = std::chrono::steady_clock::now();
  UniformizeResult r;
  try {
    r = uniformize(in.mesh);
  } catch (const std::exception& e) {  // keep the counts in the row
    char head[128];
    std::snprintf(head, sizeof head, "%3d %7d %7d %6d ", in.info.genus, in.mesh.num_vertices(), in.mesh.num_faces(),
                  in.info.mollified_faces);
    return head + std::string("error after ") + std::to_string(seconds_since(t0)).substr(0, 6) + " s: " + e.what();
  }
  const double t = seconds_since(t0);
  const int flips = r.genus == 0 ? r.sphere.edge_flips : r.ricci.flips;
  char line[256];
  std::snprintf(line, sizeof line, "%3d %7d %7d %6d %5s %9.1e %5d %6d %8.2f", r.genus, in.mesh.num_vertices(),
                in.mesh.num_faces(), in.info.mollified_faces, r.converged ? "yes" : "NO", r.max_curvature_error,
                r.iterations, flips, t);
  return line;
}

std::string map_row(const TriMesh& a, const TriMesh& b) {
  const IntakeResult src = intake(a.V, a.F), dst = intake(b.V, b.F);
  const auto t0 = std::chrono::steady_clock::now();
  const SurfaceMapResult r = surface_map(src.mesh, dst.mesh);
  const double t = seconds_since(t0);
  char line[256];
  std::snprintf(line, sizeof line, "%3d %7d %7d %5s %7d %8.3f %9.2f %8.2f", src.info.genus, src.mesh.num_faces(),
                dst.mesh.num_faces(), r.converged ? "yes" : "NO", r.flipped_triangles, r.mean_dilatation,
                r.max_dilatation, t);
  return line;
}

}  // namespace

int main(int argc, char** argv) {
  bool large = false, pairs = true;
  std::string only;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--large") large = true;
    else if (arg == "--no-pairs") pairs = false;
    else if (arg == "--only" && i + 1 < argc) only = argv[++i];
    else if (arg == "--row-timeout" && i + 1 < argc) g_row_timeout_s = std::atoi(argv[++i]);
    else {
      std::fprintf(stderr, "usage: bench_robustness [--large] [--no-pairs] [--only SUBSTRING] [--row-timeout S]\n");
      return 2;
    }
  }
  std::vector<Case> meshes = {
      {"raw peanut g0 r32", [] { return s::peanut(32, false); }},
      {"raw peanut g0 r64", [] { return s::peanut(64, false); }},
      {"coarse jittered sphere g0", [] { return s::jitter(s::sphere(3), 0.29, 7); }},
      {"UV sphere g0 10:1 (1 deg)", [] { return samples::stretched_uv_sphere(30, 200, 10.0); }},
      {"UV sphere g0 20:1", [] { return samples::stretched_uv_sphere(30, 200, 20.0); }},
      {"UV sphere g0 40:1", [] { return samples::stretched_uv_sphere(30, 200, 40.0); }},
      {"bent tapered g0 10:1", [] { return samples::bent_tapered_sphere(30, 200, 10.0); }},
      {"bent tapered g0 20:1", [] { return samples::bent_tapered_sphere(30, 200, 20.0); }},
      {"needle tip g1 (cone < pi)", [] { return s::needle(s::torus_of_revolution(1.0, 0.35, 48, 16), 0, 0.8, 0.2); }},
      {"needle tip g2", [] { return s::needle(s::n_hole_torus(2, 36), 5, 0.6, 0.2); }},
      {"zero-area g0 (300 collinear)", [] { return s::insert_degenerate_faces(s::sphere(4), 300, 0.5, 2); }},
      {"raw torus g1 r32", [] { return s::n_hole_torus(1, 32, false); }},
      {"raw torus g1 r64", [] { return s::n_hole_torus(1, 64, false); }},
      {"raw 2-torus g2 r32", [] { return s::n_hole_torus(2, 32, false); }},
      {"raw 2-torus g2 r64", [] { return s::n_hole_torus(2, 64, false); }},
      {"raw 3-torus g3 r32", [] { return s::n_hole_torus(3, 32, false); }},
      {"raw 4-torus g4 r32", [] { return s::n_hole_torus(4, 32, false); }},
      {"raw wheel g5 r40", [] { return s::n_hole_torus(5, 40, false); }},
      {"raw wheel g8 r48", [] { return s::n_hole_torus(8, 48, false); }},
      {"raw wheel g6 r28 (coarse)", [] { return s::n_hole_torus(6, 28, false); }},
      {"raw wheel g7 r32 (coarse)", [] { return s::n_hole_torus(7, 32, false); }},
      {"raw wheel g8 r36 (coarse)", [] { return s::n_hole_torus(8, 36, false); }},
      {"raw vase g2 r40", [] { return s::vase(40, false); }},
      {"CAD plate g1 (64 seg)", [] { return s::cad_plate(1, 64, 0.1); }},
      {"CAD block g2 (64 seg, thick)", [] { return s::cad_plate(2, 64, 1.5); }},
      {"CAD plate g3 (128 seg fans)", [] { return s::cad_plate(3, 128, 0.1); }},
      {"zero-area g1 (60 coincident)", [] { return s::insert_degenerate_faces(s::n_hole_torus(1, 32), 60, 0.0, 1); }},
      {"zero-area g2 (60 collinear)", [] { return s::insert_degenerate_faces(s::n_hole_torus(2, 32), 60, 0.5, 2); }},
      {"zero-area raw g3 (100 mixed)",
       [] { return s::insert_degenerate_faces(s::n_hole_torus(3, 32, false), 100, 0.0, 3); }},
      {"noisy g2 (jitter 0.29)", [] { return s::jitter(s::n_hole_torus(2, 32, false), 0.29, 5); }},
      {"noisy torus g1 (jitter 0.29)", [] { return s::jitter(s::torus_of_revolution(1, 0.3, 96, 24), 0.29, 6); }},
      // High genus (issue 13's held-out set reaches 24): CAD fans around 11
      // and 24 holes, raw wheels with 11, 12 and 24 spokes (zero-area faces
      // on the genus-12 ones), and a raw genus-8 wheel of 109k faces.
      {"CAD plate g11 (64 seg fans)", [] { return s::cad_plate(11, 64, 0.1); }},
      {"CAD block g11 (64 seg, thick)", [] { return s::cad_plate(11, 64, 1.5); }},
      {"CAD plate g24 (64 seg fans)", [] { return s::cad_plate(24, 64, 0.1); }},
      {"raw wheel g11 r32", [] { return s::wheel(11, 32, false); }},
      {"raw wheel g11 r64", [] { return s::wheel(11, 64, false); }},
      {"zero-area raw wheel g12 r48", [] { return s::insert_degenerate_faces(s::wheel(12, 48, false), 40, 0.5, 3); }},
      {"zero-area raw wheel g12 r64 (t=0)",
       [] { return s::insert_degenerate_faces(s::wheel(12, 64, false), 40, 0.0, 3); }},
      {"raw wheel g8 r90 (109k faces)", [] { return s::n_hole_torus(8, 90, false); }},
      {"raw wheel g24 r100 (105k faces)", [] { return s::wheel(24, 100, false); }},
  };
  // Resolution 325 gives 1.0M faces (faces grow as the resolution squared: 280 gave 749k).
  if (large) meshes.push_back({"raw 2-torus g2 1M faces", [] { return s::n_hole_torus(2, 325, false); }});

  std::printf("Robustness: uniformization (default options) per mesh\n");
  std::printf("%-30s %3s %7s %7s %6s %5s %9s %5s %6s %8s %8s\n", "mesh", "g", "#V", "#F", "mollif", "conv",
              "residual", "iters", "flips", "time s", "peak MB");
  for (const Case& c : meshes) {
    if (!only.empty() && c.name.find(only) == std::string::npos) continue;
    double peak = 0;
    const std::string row = in_child([&] { return uniformize_row(c.make()); }, &peak);
    std::printf("%-30s %s %8.0f\n", c.name.c_str(), row.c_str(), peak);
  }
  if (!pairs) return 0;

  struct Pair {
    std::string name;
    std::function<TriMesh()> a, b;
  };
  std::vector<Pair> map_pairs = {
      {"raw g0 r32 -> raw g0 r48", [] { return s::peanut(32, false); }, [] { return s::peanut(48, false); }},
      {"raw g0 r64 -> its remesh r48", [] { return s::peanut(64, false); }, [] { return s::peanut(48, true); }},
      {"UV g0 10:1 -> raw g0 r32", [] { return samples::stretched_uv_sphere(30, 200, 10.0); },
       [] { return s::peanut(32, false); }},
      {"UV g0 20:1 -> raw g0 r32", [] { return samples::stretched_uv_sphere(30, 200, 20.0); },
       [] { return s::peanut(32, false); }},
      {"UV g0 40:1 -> UV g0 20:1", [] { return samples::stretched_uv_sphere(30, 200, 40.0); },
       [] { return samples::stretched_uv_sphere(30, 200, 20.0); }},
      {"bent g0 10:1 -> bent g0 20:1", [] { return samples::bent_tapered_sphere(30, 200, 10.0); },
       [] { return samples::bent_tapered_sphere(30, 200, 20.0); }},
      {"bent g0 10:1 -> raw g0 r32", [] { return samples::bent_tapered_sphere(30, 200, 10.0); },
       [] { return s::peanut(32, false); }},
      {"needle g1 -> raw g1 r32", [] { return s::needle(s::torus_of_revolution(1.0, 0.35, 48, 16), 0, 0.8, 0.2); },
       [] { return s::n_hole_torus(1, 32, false); }},
      {"raw g1 r32 -> needle g1", [] { return s::n_hole_torus(1, 32, false); },
       [] { return s::needle(s::torus_of_revolution(1.0, 0.35, 48, 16), 0, 0.8, 0.2); }},
      {"needle g2 -> raw vase g2 r40", [] { return s::needle(s::n_hole_torus(2, 36), 5, 0.6, 0.2); },
       [] { return s::vase(40, false); }},
      {"raw g7 r32 -> raw g7 r40", [] { return s::n_hole_torus(7, 32, false); },
       [] { return s::n_hole_torus(7, 40, false); }},
      {"zero-area g0 -> coarse g0", [] { return s::insert_degenerate_faces(s::sphere(4), 300, 0.5, 2); },
       [] { return s::jitter(s::sphere(3), 0.29, 7); }},
      {"raw g1 r32 -> raw g1 r48", [] { return s::n_hole_torus(1, 32, false); },
       [] { return s::n_hole_torus(1, 48, false); }},
      {"zero-area g2 -> raw g2 r40", [] { return s::insert_degenerate_faces(s::n_hole_torus(2, 32), 60, 0.5, 2); },
       [] { return s::n_hole_torus(2, 40, false); }},
      {"CAD block g2 -> raw g2 r32", [] { return s::cad_plate(2, 64, 1.5); },
       [] { return s::n_hole_torus(2, 32, false); }},
      {"noisy g2 -> raw vase g2 r40", [] { return s::jitter(s::n_hole_torus(2, 32, false), 0.29, 5); },
       [] { return s::vase(40, false); }},
      {"raw wheel g11 r32 -> r40", [] { return s::wheel(11, 32, false); }, [] { return s::wheel(11, 40, false); }},
      {"CAD block g11 -> raw wheel g11", [] { return s::cad_plate(11, 64, 1.5); },
       [] { return s::wheel(11, 32, false); }},
  };
  // The large pair: the 1M-face raw mesh onto another raw grid of the same
  // shape (0.86M faces), so a run of --large shows a 1M-face map end to end.
  if (large)
    map_pairs.push_back({"raw g2 1M faces -> raw g2 r300", [] { return s::n_hole_torus(2, 325, false); },
                         [] { return s::n_hole_torus(2, 300, false); }});
  std::printf("\nRobustness: surface_map (default options) per pair\n");
  std::printf("%-30s %3s %7s %7s %5s %7s %8s %9s %8s %8s\n", "pair", "g", "#F src", "#F dst", "conv", "flipped",
              "D' mean", "D' max", "time s", "peak MB");
  for (const Pair& p : map_pairs) {
    if (!only.empty() && p.name.find(only) == std::string::npos) continue;
    double peak = 0;
    const std::string row = in_child([&] { return map_row(p.a(), p.b()); }, &peak);
    std::printf("%-30s %s %8.0f\n", p.name.c_str(), row.c_str(), peak);
  }
  return 0;
}
