// Benchmark of the discrete Ricci flow (uniformize/ricci_flow.h): Newton
// (fixed connectivity), Newton with intrinsic Delaunay flips (the default of
// uniformize) and the paper's explicit flow on generated meshes of ~10k, 100k, 500k vertices.
// Every run happens in a forked child so that its peak memory (ru_maxrss) is
// its own. The flow is capped by a time budget; its residual at the cap and
// the observed linear rate give an extrapolated iteration count and time.
//
// Usage: bench_uniformize [--sizes 10000,100000,500000] [--flow-budget 20]
//                         [--no-flow] [--hyperbolic-only | --flat-only]
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "../native/src/seconds_since.h"
#include "../native/tests/holed_plate.h"
#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/uniformize/ricci_flow.h"

using namespace surfmap;
using detail::seconds_since;
using testing_support::holed_plate;  // (native/tests/holed_plate.h, shared with the tests)

namespace {

constexpr double kPi = 3.14159265358979323846;

// Torus of revolution R=3, r=1 on an n x m grid with a little seeded 3D
// jitter (so that the triangles are irregular, not a perfect grid).
TriMesh torus(int n, int m) {
  TriMesh t;
  t.V.resize(n * m, 3);
  t.F.resize(2 * n * m, 3);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> U(-0.15, 0.15);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double a = 2 * kPi * (i + U(rng)) / n, b = 2 * kPi * (j + U(rng)) / m;
      t.V.row(i * m + j) << (3 + std::cos(b)) * std::cos(a), (3 + std::cos(b)) * std::sin(a), std::sin(b);
      const int v00 = i * m + j, v10 = ((i + 1) % n) * m + j, v01 = i * m + (j + 1) % m,
                v11 = ((i + 1) % n) * m + (j + 1) % m;
      t.F.row(2 * (i * m + j)) << v00, v10, v11;
      t.F.row(2 * (i * m + j) + 1) << v00, v11, v01;
    }
  return t;
}


struct Row {
  std::string shape;
  int V = 0;
  std::string method;
  int iterations = 0;
  double time_s = 0, residual = 0;
  double peak_mb = 0;
  bool converged = false;
  std::string note;
};

void run(const std::string& shape, int target_v, bool hyperbolic, bool newton, double budget,
         double newton_time, bool flips = false) {
  TriMesh m;
  if (!hyperbolic) {
    const int n = static_cast<int>(std::round(std::sqrt(2.0 * target_v)));
    m = torus(n, std::max(3, target_v / n));
  } else {
    // genus 3 plate: about 68 unit squares -> 68 s^2 vertices
    m = holed_plate(3, std::max(1, static_cast<int>(std::round(std::sqrt(target_v / 68.0)))));
  }
  const Connectivity c(m.F);
  const Eigen::VectorXd l = edge_lengths(m, c);
  RicciFlowOptions o;
  o.method = newton ? RicciMethod::Newton : RicciMethod::GradientFlow;
  o.intrinsic_delaunay = flips;
  std::vector<double> history;
  const auto t0 = std::chrono::steady_clock::now();
  if (!newton) {
    o.progress = [&](int, double r) {
      history.push_back(r);
      return seconds_since(t0) < budget;
    };
  }
  Row row;
  row.shape = shape;
  row.V = c.num_vertices();
  row.method = flips ? "flips" : newton ? "newton" : "flow";
  try {
    const RicciFlowResult r = ricci_flow(c, l, hyperbolic ? Background::Hyperbolic : Background::Euclidean, o);
    row.iterations = r.iterations;
    row.time_s = r.time_s;
    row.residual = r.max_curvature_error;
    row.converged = r.converged;
    if (!r.converged) row.note = r.message;
    if (flips) row.note = std::to_string(r.flips) + " Ptolemy flips" + (row.note.empty() ? "" : "; " + row.note);
    if (r.stopped_at_floor) row.note += " (stopped at the floating-point floor)";
  } catch (const Cancelled&) {
    row.iterations = static_cast<int>(history.size());
    row.time_s = seconds_since(t0);
    row.residual = history.empty() ? NAN : history.back();
    // Observed linear rate over the second half of the run -> iterations to 1e-10.
    const size_t h = history.size() / 2;
    if (history.size() > 10 && history.back() < history[h]) {
      const double rate = std::pow(history.back() / history[h], 1.0 / (history.size() - 1 - h));
      const double more = std::log(1e-10 / history.back()) / std::log(rate);
      const double total_it = history.size() + more;
      const double total_t = row.time_s * total_it / history.size();
      std::ostringstream s;
      s.precision(3);
      s << "stopped at budget; rate " << rate << "/it -> ~" << total_it << " it, ~" << total_t
        << " s to 1e-10";
      if (newton_time > 0) s << " (" << total_t / newton_time << "x Newton)";
      row.note = s.str();
    } else {
      row.note = "stopped at budget; no measurable decrease";
    }
  }
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  row.peak_mb = ru.ru_maxrss / 1024.0;
  std::printf("%-10s %9d %-7s %7d %9.3f %9.1f %10.2e %-5s %s\n", row.shape.c_str(), row.V,
              row.method.c_str(), row.iterations, row.time_s, row.peak_mb, row.residual,
              row.converged ? "yes" : "no", row.note.c_str());
  std::fflush(stdout);
  // Hand the Newton time to the parent through the exit path: write it to stderr-free pipe-less file.
  if (newton && !flips) {
    FILE* f = std::fopen("/tmp/bench_uniformize_newton_time", "w");
    if (f) {
      std::fprintf(f, "%.17g\n", row.time_s);
      std::fclose(f);
    }
  }
}

void in_child(const std::string& shape, int v, bool hyp, bool newton, double budget, double nt,
              bool flips = false) {
  std::fflush(stdout);
  const pid_t pid = fork();
  if (pid == 0) {
    try {
      run(shape, v, hyp, newton, budget, nt, flips);
    } catch (const std::exception& e) {
      std::printf("%-10s %9d %-7s failed: %s\n", shape.c_str(), v, newton ? "newton" : "flow", e.what());
    }
    std::fflush(stdout);
    _exit(0);
  }
  int status = 0;
  waitpid(pid, &status, 0);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes = {10000, 100000, 500000};
  double budget = 20;
  bool flow = true, flat = true, hyp = true;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--sizes") && i + 1 < argc) {
      sizes.clear();
      std::stringstream ss(argv[++i]);
      std::string tok;
      while (std::getline(ss, tok, ',')) sizes.push_back(std::stoi(tok));
    } else if (!std::strcmp(argv[i], "--flow-budget") && i + 1 < argc) {
      budget = std::atof(argv[++i]);
    } else if (!std::strcmp(argv[i], "--no-flow")) {
      flow = false;
    } else if (!std::strcmp(argv[i], "--flat-only")) {
      hyp = false;
    } else if (!std::strcmp(argv[i], "--hyperbolic-only")) {
      flat = false;
    } else {
      std::fprintf(stderr, "usage: %s [--sizes a,b,c] [--flow-budget s] [--no-flow] [--flat-only|--hyperbolic-only]\n", argv[0]);
      return 2;
    }
  }
  std::printf("%-10s %9s %-7s %7s %9s %9s %10s %-5s %s\n", "shape", "V", "method", "iters", "time_s",
              "peak_MB", "residual", "conv", "note");
  for (int v : sizes)
    for (int h = 0; h < 2; ++h) {
      if ((h == 0 && !flat) || (h == 1 && !hyp)) continue;
      const std::string shape = h ? "genus3" : "torus";
      std::remove("/tmp/bench_uniformize_newton_time");
      in_child(shape, v, h, true, budget, 0);
      double nt = 0;
      if (FILE* f = std::fopen("/tmp/bench_uniformize_newton_time", "r")) {
        if (std::fscanf(f, "%lf", &nt) != 1) nt = 0;
        std::fclose(f);
      }
      in_child(shape, v, h, true, budget, 0, true);  // Newton with intrinsic Delaunay flips
      if (flow) in_child(shape, v, h, false, budget, nt);
    }
  return 0;
}
