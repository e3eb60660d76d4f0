// Benchmark of the pants decompositions of map/pants_classes.h (the
// caterpillar reached by twists) and map/greedy_pants.h (the greedy short
// decomposition), and of the greedy pants classes between two surfaces
// (docs/handle_classes.md "Greedy pants decomposition"): each surface is
// uniformized with its own canonical schema (as the tests do), then the
// short marking, the caterpillar and the greedy decomposition are timed and
// their curve lengths printed. With two meshes of equal genus, the greedy
// pants classes X -> Y are listed with their costs.
//
// Usage: bench_pants [--full-counts] [--cad-plate G] [MESH ...]
//   (default: generated genus-2..4 shapes; --cad-plate G adds `surfmap
//   generate cad-plate --genus G --thickness 0.3`; --full-counts: the greedy
//   decomposition counts every crossing, GreedyPantsOptions::shortcuts off)
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "../native/src/seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/map/greedy_pants.h"
#include "surfmap/map/pants_classes.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/uniformize/uniformize.h"

using namespace surfmap;
using detail::seconds_since;

namespace {

struct Surface {
  std::string name;
  std::unique_ptr<SurfaceGroupLengths> lengths;
  ShortMarking marking;
  PantsDecomposition caterpillar;
  GreedyPantsDecomposition greedy;
};

std::unique_ptr<SurfaceGroupLengths> uniformized_lengths(const TriMesh& mesh) {
  for (UniformizationMetric metric : {UniformizationMetric::IntrinsicDelaunay, UniformizationMetric::Automatic}) {
    UniformizeOptions o;
    o.metric = metric;
    try {
      const UniformizeResult u = uniformize(mesh, o);
      if (!u.converged) continue;
      const CanonicalSchema cs = canonical_schema(u.layout.word);
      return std::make_unique<SurfaceGroupLengths>(DeckGroup(u.layout), cs.generators, u.layout.word);
    } catch (const std::exception& e) {
      std::printf("  (uniformization failed: %s)\n", e.what());
    }
  }
  return nullptr;
}

void print_lengths(const char* what, const std::vector<double>& l, double total) {
  std::printf("  %-12s", what);
  for (double x : l) std::printf(" %.3g", x);
  std::printf("  (total %.4g)\n", total);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::pair<std::string, TriMesh>> meshes;
  GreedyPantsOptions greedy_options;
  try {
    for (int k = 1; k < argc; ++k) {
      const std::string arg = argv[k];
      if (arg == "--full-counts") {
        greedy_options.shortcuts = false;
      } else if (arg == "--cad-plate" && k + 1 < argc) {
        const int g = std::atoi(argv[++k]);
        meshes.emplace_back("cad_plate(" + std::to_string(g) + ")", samples::cad_plate(g, 64, 0.3));
      } else {
        meshes.emplace_back(arg, load_mesh(arg).mesh);
      }
    }
    if (meshes.empty())
      for (int g : {2, 3, 4})
        meshes.emplace_back("jittered n_hole_torus(" + std::to_string(g) + ")",
                            samples::jitter(samples::n_hole_torus(g, 30, true), 0.2, 7));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_pants: %s\n", e.what());
    return 1;
  }
  std::vector<Surface> surfaces;
  for (auto& [name, mesh] : meshes) {
    Surface s;
    s.name = name;
    std::printf("%s (%d vertices)\n", name.c_str(), mesh.num_vertices());
    auto t0 = std::chrono::steady_clock::now();
    s.lengths = uniformized_lengths(mesh);
    if (!s.lengths) {
      std::printf("  not uniformized\n");
      continue;
    }
    std::printf("  uniformize   %.2f s\n", seconds_since(t0));
    t0 = std::chrono::steady_clock::now();
    s.marking = short_marking(*s.lengths);
    std::printf("  marking      %.2f s\n", seconds_since(t0));
    t0 = std::chrono::steady_clock::now();
    s.caterpillar = short_pants_decomposition(*s.lengths, s.marking);
    const double t_cat = seconds_since(t0);
    std::vector<double> l;
    std::vector<Word> extra;
    for (const PantsCurve& c : s.caterpillar.curves) l.push_back(c.length), extra.push_back(c.word);
    print_lengths("caterpillar", l, s.caterpillar.total);
    std::printf("  caterpillar  %.2f s\n", t_cat);
    s.greedy = greedy_pants_decomposition(*s.lengths, s.marking, extra, greedy_options);
    l.clear();
    for (const GreedyPantsCurve& c : s.greedy.curves) l.push_back(c.length);
    print_lengths(s.greedy.complete ? "greedy" : "greedy (inc.)", l, s.greedy.total);
    std::printf("  greedy       %.2f s: %zu candidates, %zu examined, %zu self-crossing, %zu crossing, %zu duplicates, "
                "%zu not evaluable, %zu intersection tests\n",
                s.greedy.time_s, s.greedy.candidates, s.greedy.examined, s.greedy.self_crossing, s.greedy.crossing,
                s.greedy.duplicates, s.greedy.not_evaluable, s.greedy.intersection_tests);
    std::printf("  shared with the caterpillar: %d of %zu\n",
                shared_pants_curves(*s.lengths, s.marking, s.greedy, extra), extra.size());
    std::fflush(stdout);
    surfaces.push_back(std::move(s));
  }
  // Greedy pants classes between consecutive surfaces of equal genus.
  for (size_t k = 0; k + 1 < surfaces.size(); ++k) {
    const Surface &x = surfaces[k], &y = surfaces[k + 1];
    if (x.lengths->genus() != y.lengths->genus()) continue;
    const auto t0 = std::chrono::steady_clock::now();
    const std::vector<GreedyPantsClass> classes =
        greedy_pants_classes(*x.lengths, x.marking, x.greedy, *y.lengths, y.marking, y.greedy);
    std::printf("%s -> %s: greedy pants classes %.2f s\n", x.name.c_str(), y.name.c_str(), seconds_since(t0));
    for (const GreedyPantsClass& c : classes)
      std::printf("  cost %.4g (pants %.4g, twists %.4g), greedy collar bound %.4g (8 pi (g-1) = %.4g): %s\n", c.cost,
                  c.pants_mismatch, c.twist_mismatch, c.collar_bound, conformal_bound(x.lengths->genus()),
                  c.description.c_str());
  }
  return 0;
}
