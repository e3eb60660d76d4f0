// Benchmark of the genus-0 map (map/spherical_map.h; not a test): generated
// pairs at about 10k, 40k and 160k vertices per mesh, printing per-stage
// times, the area-weighted mean and max D', and the same with 3 landmarks.
// Pairs: an asymmetric blob onto its inversion (conformally equivalent: D'
// -> 1 under refinement) and the blob onto a jittered ellipsoid meshed one
// level coarser. Any two genus-0 surfaces are conformally equivalent, so D'
// -> 1 for both pairs: what D' shows here is the discretisation error.
// Each case runs in a forked child so its peak RSS is its own.
//
//   build/bin/bench_spherical_map [--sizes 5,6,7]   (icosphere subdivision levels)
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/samples/shapes.h"

using namespace surfmap;

namespace {

TriMesh blob(int s) {
  TriMesh m = samples::sphere(s);
  for (int i = 0; i < m.num_vertices(); ++i) {
    const Eigen::Vector3d p = m.V.row(i).transpose().normalized();
    m.V.row(i) = (Eigen::Vector3d(1.6 * p.x(), p.y(), 0.7 * p.z()) * (1.0 + 0.25 * p.x() + 0.1 * p.y() * p.z())).transpose();
  }
  return m;
}

TriMesh ellipsoid(int s) {
  TriMesh m = samples::jitter(samples::sphere(s), 0.2, 5);
  for (int i = 0; i < m.num_vertices(); ++i) m.V.row(i) = m.V.row(i).cwiseProduct(Eigen::RowVector3d(1.5, 1.1, 0.8));
  return m;
}

void run_case(const char* name, const TriMesh& a, const TriMesh& b, bool landmarks) {
  const pid_t pid = fork();
  if (pid == 0) {
    SurfaceMapOptions o;
    if (landmarks) {
      // Where the free map sends three vertices: consistent landmarks.
      const SurfaceMapResult free = surface_map(a, b);
      for (int s : {0, a.num_vertices() / 3, (2 * a.num_vertices()) / 3}) {
        int t = 0;
        (b.V.rowwise() - free.forward[s].position.transpose()).rowwise().squaredNorm().minCoeff(&t);
        o.landmarks.emplace_back(s, t);
      }
    }
    try {
      const SurfaceMapResult m = surface_map(a, b, o);
      std::ostringstream st;
      st.precision(2);
      st << std::fixed;
      for (const auto& [stage, t] : m.stage_times) st << stage << " " << t << "; ";
      rusage ru{};
      getrusage(RUSAGE_SELF, &ru);
      std::printf("%-28s %8d %8d %3s %8.4f %8.4f %6d %6d %8.2f %7.0f  %s\n", name, a.num_vertices(), b.num_vertices(),
                  landmarks ? "3" : "0", m.mean_dilatation, m.max_dilatation, m.flipped_triangles, m.repaired_vertices,
                  m.total_time, ru.ru_maxrss / 1024.0, st.str().c_str());
    } catch (const Error& e) {
      std::printf("%-28s %8d %8d %3s failed: %s\n", name, a.num_vertices(), b.num_vertices(), landmarks ? "3" : "0",
                  e.what());
    }
    std::fflush(stdout);
    std::_Exit(0);
  }
  int status = 0;
  waitpid(pid, &status, 0);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes = {5, 6, 7};
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "--sizes" && i + 1 < argc) {
      sizes.clear();
      std::stringstream ss(argv[++i]);
      for (std::string x; std::getline(ss, x, ',');) sizes.push_back(std::stoi(x));
    }
  std::printf("%-28s %8s %8s %3s %8s %8s %6s %6s %8s %7s  %s\n", "pair", "#V src", "#V dst", "lm", "mean D'", "max D'",
              "flips", "repair", "total s", "RSS MB", "stages (s)");
  std::fflush(stdout);  // before forking, or every child prints it again
  for (int s : sizes) {
    const TriMesh a = blob(s);
    const TriMesh inv = samples::sphere_inversion(a, Eigen::Vector3d(3.0, 0.5, -0.4), 2.5);
    const TriMesh ell = ellipsoid(s - 1);
    for (bool lm : {false, true}) {
      run_case("blob -> inverted blob", a, inv, lm);
      run_case("blob -> jittered ellipsoid", a, ell, lm);
    }
  }
  return 0;
}
