// Benchmark of the Ricci flow's coarse start (uniformize/coarse_start.h; issue
// 19): the target of `bench_speed --remeshed` (n-hole torus, genus 2, smooth,
// at --resolution, default 109: 55886 vertices) and the vase
// (--vase-resolution, default 103), each uniformized with intrinsic Delaunay
// flips from u = 0 and from the coarse start, alternated --repeat times (Z C
// Z C ...), each run in this process, one BLAS thread, as the map's target
// stage runs it. Prints per run: the start, the coarse copy's vertices and its
// seconds (copy / flow / prolongation), the fine flow's seconds, Newton
// iterations, conjugate-gradient iterations, factorisations, flips, the
// residual history, and against the run from u = 0: the largest |Δu| and,
// when both end on the same triangulation, the largest relative length
// difference; then the medians per start. Not a test: no pass / fail. The
// coarse runs check the start against u = 0 as the map's target stage does
// (ricci_flow_from_checked) and print the energy's slopes φ'(0), φ'(1) along
// the segment and whether the start was used; --overshoot sets the check's
// bound (default 0.05, the map's; a large value uses every downhill start and
// still prints the slopes).
//
//   build/bin/bench_coarse_start [--resolution 109] [--vase-resolution 103] [--repeat 3]
//                                [--coarse-vertices 3000] [--sweeps 10] [--overshoot 0.05] [--mesh FILE]...
// --mesh: also a mesh file (genus >= 1; flat for a torus), e.g. --resolution 0
// --vase-resolution 0 --mesh a.obj for that mesh alone.
#include <dlfcn.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/uniformize/coarse_start.h"
#include "surfmap/uniformize/ricci_flow.h"

using namespace surfmap;

namespace {

void single_threaded_blas() {
  if (auto set = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) set(1);
  if (auto set = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels"))) set(0);
}

double median(std::vector<double> x) {
  if (x.empty()) return 0.0;
  std::sort(x.begin(), x.end());
  const size_t n = x.size();
  return n % 2 ? x[n / 2] : 0.5 * (x[n / 2 - 1] + x[n / 2]);
}

struct Run {
  double start_s = 0, flow_s = 0;
  RicciFlowResult flow;
};

void bench_mesh(const std::string& name, const TriMesh& mesh, int repeat, const CoarseStartOptions& cso,
                double overshoot) {
  const Connectivity conn(mesh.F, mesh.num_vertices());
  const Background bg = conn.genus() >= 2 ? Background::Hyperbolic : Background::Euclidean;
  const Eigen::VectorXd l = edge_lengths(mesh, conn);
  RicciFlowOptions fo;
  fo.intrinsic_delaunay = true;
  std::printf("\n%s: %d vertices, %d faces, genus %d, %s, intrinsic Delaunay, tolerance %.0e\n", name.c_str(),
              conn.num_vertices(), conn.num_faces(), conn.genus(), bg == Background::Hyperbolic ? "hyperbolic" : "flat",
              fo.tolerance);
  std::printf("%-6s %7s %22s %8s %5s %5s %5s %6s %10s %10s %10s  residuals\n", "start", "coarseV",
              "coarse s (copy/flow/u)", "flow s", "Newt", "CG", "fact", "flips", "err", "max|du|", "max dl/l");
  std::vector<double> total[2], flow_s[2];
  Eigen::VectorXd u_zero;
  Eigen::VectorXd l_zero;
  Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor> ev_zero;
  for (int k = 0; k < 2 * repeat; ++k) {
    const bool coarse = k % 2 == 1;
    Run r;
    CoarseStart cs;
    const auto t0 = std::chrono::steady_clock::now();
    if (coarse) cs = coarse_conformal_start(mesh, conn, bg, cso);
    const auto t1 = std::chrono::steady_clock::now();
    CheckedStart check;
    if (cs.ok) {
      CheckedFlow checked = ricci_flow_from_checked(conn, l, bg, fo, cs.u, overshoot);
      r.flow = std::move(checked.flow);
      check = checked.start;
    } else {
      r.flow = ricci_flow(conn, l, bg, fo);
    }
    const auto t2 = std::chrono::steady_clock::now();
    r.start_s = std::chrono::duration<double>(t1 - t0).count();
    r.flow_s = std::chrono::duration<double>(t2 - t1).count();
    if (!coarse && u_zero.size() == 0) {
      u_zero = r.flow.u;
      l_zero = r.flow.edge_lengths;
      ev_zero = r.flow.edge_vertices;
    }
    const double du = (r.flow.u - u_zero).cwiseAbs().maxCoeff();
    std::string dl = "-";
    if (r.flow.edge_vertices.rows() == ev_zero.rows() && r.flow.edge_vertices == ev_zero) {
      char b[32];
      std::snprintf(b, sizeof b, "%.2e", ((r.flow.edge_lengths - l_zero).array() / l_zero.array()).abs().maxCoeff());
      dl = b;
    } else {
      dl = "other T'";
    }
    char coarse_col[64] = "-";
    if (coarse && cs.ok)
      std::snprintf(coarse_col, sizeof coarse_col, "%.3f/%.3f/%.3f", cs.copy_seconds, cs.flow_seconds,
                    cs.prolong_seconds);
    else if (coarse)
      std::snprintf(coarse_col, sizeof coarse_col, "none");
    std::string hist;
    for (double x : r.flow.residual_history) {
      char b[16];
      std::snprintf(b, sizeof b, " %.1e", x);
      hist += b;
    }
    std::printf("%-6s %7d %22s %8.3f %5d %5d %5d %6d %10.2e %10.2e %10s %s%s\n", coarse ? "coarse" : "zero",
                cs.coarse_vertices, coarse_col, r.flow_s, r.flow.iterations, r.flow.cg_iterations,
                r.flow.factorisations, r.flow.flips, r.flow.max_curvature_error, du, dl.c_str(), hist.c_str(),
                r.flow.converged ? "" : "  NOT CONVERGED");
    if (coarse && !cs.ok) std::printf("       (no coarse start: %s)\n", cs.why.c_str());
    if (coarse && cs.ok)
      std::printf("       start %s: slopes phi'(0) %.4e phi'(1) %.4e, phi'(1)/|phi'(0)| %.4f; max residual at u = 0 %.2e\n",
                  check.start_used ? "used" : "declined", check.slope_at_zero, check.slope_at_start,
                  check.slope_at_start / std::abs(check.slope_at_zero), check.residual_at_zero);
    std::fflush(stdout);
    total[coarse].push_back(r.start_s + r.flow_s);
    flow_s[coarse].push_back(r.flow_s);
  }
  std::printf("medians: from u = 0 %.3f s; coarse start %.3f s (its flow %.3f s)\n", median(total[0]),
              median(total[1]), median(flow_s[1]));
}

}  // namespace

int main(int argc, char** argv) {
  int resolution = 109, vase_resolution = 103, repeat = 3;
  double overshoot = 0.05;
  std::vector<std::string> files;
  CoarseStartOptions cso;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> int {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return std::atoi(argv[++i]);
    };
    if (a == "--resolution") resolution = next();
    else if (a == "--vase-resolution") vase_resolution = next();
    else if (a == "--repeat") repeat = next();
    else if (a == "--coarse-vertices") cso.coarse_vertices = next();
    else if (a == "--sweeps") cso.smoothing_sweeps = next();
    else if (a == "--overshoot" && i + 1 < argc) overshoot = std::atof(argv[++i]);
    else if (a == "--mesh" && i + 1 < argc) files.push_back(argv[++i]);
    else {
      std::fprintf(stderr,
                   "usage: bench_coarse_start [--resolution 109] [--vase-resolution 103] [--repeat 3] "
                   "[--coarse-vertices 3000] [--sweeps 10] [--overshoot 0.05] [--mesh FILE]...\n");
      return 2;
    }
  }
  single_threaded_blas();
  if (resolution > 0) bench_mesh("n-hole torus (genus 2) r" + std::to_string(resolution),
                                 samples::n_hole_torus(2, resolution, true), repeat, cso, overshoot);
  if (vase_resolution > 0)
    bench_mesh("vase (genus 2) r" + std::to_string(vase_resolution), samples::vase(vase_resolution, true), repeat, cso, overshoot);
  for (const std::string& f : files) bench_mesh(f, load_mesh(f).mesh, repeat, cso, overshoot);
  return 0;
}
