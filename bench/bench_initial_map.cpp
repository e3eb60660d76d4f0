// The genus >= 2 initial map (map/initial_map.h, map/cut_graph_initial_map.h)
// per construction on generated pairs: raw marching-tetrahedra (sliver)
// sources of genus 2-6, a jittered source, and bench_map's genus-2 pair
// (n-hole torus -> vase) at the requested sizes. Prints per pair and method
// the construction used, the folds of the flattening before any repair, the
// initial map's own time (it runs next to the full-resolution solves, so the
// pipeline's stage time hides it), the initial and final energies, and the
// final map's flips. Not a test: a table.
//
//   build/bin/bench_initial_map [--sizes 50000] [--no-slivers] [--methods cut_graph,polygon,uniform]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "../native/src/seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/map/map_option_names.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/samples/shapes.h"

using namespace surfmap;
using detail::seconds_since;

namespace {

struct Case {
  std::string name;
  TriMesh a, b;
  int homotopy;  // -1: the pipeline's choice
};

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string t; std::getline(ss, t, ',');) out.push_back(t);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes;
  bool slivers = true;
  std::vector<std::string> methods{"cut_graph", "polygon"};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--sizes" && i + 1 < argc) {
      for (const auto& t : split(argv[++i])) sizes.push_back(std::atoi(t.c_str()));
    } else if (a == "--no-slivers") {
      slivers = false;
    } else if (a == "--methods" && i + 1 < argc) {
      methods = split(argv[++i]);
      for (const std::string& m : methods) {
        try {
          parse_enum<InitialMapMethod>(m, "--methods");
        } catch (const InputError& e) {
          std::fprintf(stderr, "%s\n", e.what());
          return 2;
        }
      }
    } else {
      std::fprintf(stderr, "usage: %s [--sizes a,b] [--no-slivers] [--methods cut_graph,polygon,uniform]\n", argv[0]);
      return 2;
    }
  }
  std::vector<Case> cases;
  if (slivers) {
    // The overlay class (homotopy 0) of an n-hole torus and a remeshed copy.
    cases.push_back({"raw g2 res 30 -> vase 30", samples::n_hole_torus(2, 30, false), samples::vase(30, true), 0});
    cases.push_back({"raw g2 res 40 -> g2 36", samples::n_hole_torus(2, 40, false), samples::n_hole_torus(2, 36, true), 0});
    cases.push_back({"raw g3 res 30 -> g3 36", samples::n_hole_torus(3, 30, false), samples::n_hole_torus(3, 36, true), 0});
    cases.push_back({"raw g4 res 30 -> g4 36", samples::n_hole_torus(4, 30, false), samples::n_hole_torus(4, 36, true), 0});
    cases.push_back({"raw g5 res 30 -> g5 36", samples::n_hole_torus(5, 30, false), samples::n_hole_torus(5, 36, true), 0});
    cases.push_back({"raw g6 res 30 -> g6 36", samples::n_hole_torus(6, 30, false), samples::n_hole_torus(6, 36, true), 0});
    cases.push_back({"jitter g2 36 -> raw g2 30", samples::jitter(samples::n_hole_torus(2, 36, true), 0.25, 3),
                     samples::n_hole_torus(2, 30, false), 0});
  }
  for (int v : sizes) {
    // bench_map's genus-2 pair and resolution rule.
    const int r0 = 40;
    const double v0 = samples::n_hole_torus(2, r0, true).num_vertices();
    const int res = std::max(32, static_cast<int>(std::lround(r0 * std::sqrt(v / v0))));
    cases.push_back({"bench g2 n-hole torus -> vase res " + std::to_string(res), samples::n_hole_torus(2, res, true),
                     samples::vase(res, true), -1});
  }
  std::printf("%-36s %6s %-10s | %-36s %4s %4s %5s %7s %7s | %10s %12s %5s %7s\n", "pair", "V_src", "method",
              "construction", "cgF", "plF", "rep", "init_s", "flat_s", "E_initial", "E_final", "flips", "total");
  for (const Case& c : cases) {
    double e_ref = -1;
    for (const std::string& method : methods) {
      SurfaceMapOptions o;
      o.homotopy.class_index = c.homotopy;
      o.initial.method = parse_enum<InitialMapMethod>(method, "--methods");
      const auto t0 = std::chrono::steady_clock::now();
      SurfaceMapResult m;
      try {
        m = surface_map(c.a, c.b, o);
      } catch (const Error& e) {
        std::printf("%-36s %6d %-10s | failed: %s\n", c.name.c_str(), c.a.num_vertices(), method.c_str(), e.what());
        continue;
      }
      const double total = seconds_since(t0);
      const InitialMapInfo& im = m.initial_map;
      // Folds of each flattening tried, before any repair (cut graph:
      // round-off only; polygon: the faces crossing its refined loops).
      const std::string cgf = im.cut_graph_status == "not tried" ? "-" : std::to_string(im.cut_graph_flipped);
      const std::string pf = im.polygon_status == "not tried" ? "-" : std::to_string(im.polygon_flipped);
      const double flat = im.construction == "cut-graph polygon" ? im.cut_graph_time_s : im.polygon_time_s;
      if (e_ref < 0) e_ref = m.final_energy;
      std::printf("%-36s %6d %-10s | %-36s %4s %4s %5d %7.3f %7.3f | %10.5g %12.10g %5d %7.2f%s\n", c.name.c_str(),
                  c.a.num_vertices(), method.c_str(), im.construction.substr(0, 36).c_str(), cgf.c_str(), pf.c_str(),
                  im.polygon_repaired_vertices, im.time_s, flat, m.initial_energy, m.final_energy, m.flipped_triangles,
                  total, std::abs(m.final_energy - e_ref) > 1e-8 * e_ref ? "  (E differs!)" : "");
      if (im.construction != "cut-graph polygon" && method == "cut_graph")
        std::printf("%-36s %6s %-10s   cut graph: %s\n", "", "", "", im.cut_graph_status.c_str());
      std::fflush(stdout);
    }
  }
  return 0;
}
