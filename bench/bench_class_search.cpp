// How wide a class search does a pair need? (issue 14, session 26;
// docs/history/handle_classes.md "Session 26"). Not a test: maps SOURCE -> TARGET
// with the default options, or with a given class (words written by an
// earlier run's report, homotopy.chosen_words, saved as one word per line of
// space-separated letters), changed by the search options below, and prints
// the candidates, the twist search's evaluations and the chosen class.
//
//   build/bin/bench_class_search SOURCE TARGET [--words FILE] [--per-step N] [--evaluations N]
//       [--kicks N] [--kick-moves N] [--kick-evaluations N] [--kick-choices N] [--seed S] [--restart-ratio R]
//       [--through-shape-ratio R]
//       [--threads N] [--out-words FILE] [--move source:NAME | target:NAME ...] [--alone]
//
// --move composes the given class with a move of twist_moves (source side:
// theta o m; target side: m o theta), as the twist search forms its
// neighbours; --alone maps in that class alone at full resolution
// (HomotopyOptions::class_words: no ranking, no search).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/map/class_lower_bound.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/topology/mapping_class_search.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_class_search SOURCE TARGET [options]\n");
    return 2;
  }
  surfmap::SurfaceMapOptions o;
  std::string words_file, out_words;
  std::vector<std::string> moves;
  bool alone = false;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--words") words_file = next();
    else if (a == "--out-words") out_words = next();
    else if (a == "--move") moves.push_back(next());
    else if (a == "--alone") alone = true;
    else if (a == "--per-step") o.homotopy.search.evaluations_per_step = std::atoi(next());
    else if (a == "--evaluations") o.homotopy.search.evaluations = std::atoi(next());
    else if (a == "--kicks") o.homotopy.search.kicks = std::atoi(next());
    else if (a == "--kick-moves") o.homotopy.search.kick_moves = std::atoi(next());
    else if (a == "--kick-evaluations") o.homotopy.search.kick_evaluations = std::atoi(next());
    else if (a == "--kick-choices") o.homotopy.search.kick_choices = std::atoi(next());
    else if (a == "--seed") o.homotopy.search.kick_seed = static_cast<unsigned>(std::atoi(next()));
    else if (a == "--restart-ratio") o.homotopy.search.restart_ratio = std::atof(next());
    else if (a == "--through-shape-ratio") o.homotopy.through_shape_ratio = std::atof(next());
    else if (a == "--threads") o.threads = std::atoi(next());
    else {
      std::fprintf(stderr, "unknown option %s\n", a.c_str());
      return 2;
    }
  }
  if (!words_file.empty()) {
    std::ifstream in(words_file);
    std::string line;
    while (std::getline(in, line)) {
      std::istringstream ls(line);
      std::vector<int> w;
      int x;
      while (ls >> x) w.push_back(x);
      o.homotopy.given_class.push_back(w);
    }
  }
  if (!moves.empty() || alone) {
    if (o.homotopy.given_class.empty()) {
      std::fprintf(stderr, "--move and --alone need --words\n");
      return 2;
    }
    const int genus = static_cast<int>(o.homotopy.given_class.size()) / 2;
    const std::vector<surfmap::MappingClassMove> all = surfmap::twist_moves(genus);
    const surfmap::DehnReducer reduce(surfmap::canonical_relator(genus));
    surfmap::GroupMap theta(o.homotopy.given_class.begin(), o.homotopy.given_class.end());
    for (const std::string& m : moves) {
      const size_t colon = m.find(':');
      const std::string side = m.substr(0, colon), name = colon == std::string::npos ? "" : m.substr(colon + 1);
      auto it = std::find_if(all.begin(), all.end(), [&](const surfmap::MappingClassMove& x) { return x.name == name; });
      if (it == all.end() || (side != "source" && side != "target")) {
        std::fprintf(stderr, "no move %s\n", m.c_str());
        return 2;
      }
      theta = reduce.each(side == "source" ? surfmap::compose(theta, it->automorphism.map)
                                           : surfmap::compose(it->automorphism.map, theta));
    }
    o.homotopy.given_class.clear();
    if (alone) o.homotopy.class_words.assign(theta.begin(), theta.end());
    else o.homotopy.given_class.assign(theta.begin(), theta.end());
  }
  try {
    const surfmap::TriMesh s = surfmap::load_mesh(argv[1]).mesh, t = surfmap::load_mesh(argv[2]).mesh;
    const surfmap::SurfaceMapResult r = surfmap::surface_map(s, t, o);
    const double bound = surfmap::conformal_bound(r.genus);
    const double e = r.chosen_candidate >= 0 ? r.candidates[r.chosen_candidate].energy : NAN;
    std::printf("chosen %d  energy %.6f  ratio %.4f  mean D' %.3f  converged %d  flipped %d\n", r.chosen_candidate, e,
                e / bound, r.mean_dilatation, r.converged ? 1 : 0, r.flipped_triangles);
    if (!r.two_way_status.empty()) std::printf("  two-way: %s\n", r.two_way_status.c_str());
    if (!r.through_shape_status.empty()) std::printf("  through-shape: %s\n", r.through_shape_status.c_str());
    for (size_t k = 0; k < r.candidates.size(); ++k) {
      const auto& c = r.candidates[k];
      std::printf("  cand %2zu E %.4f coarse %.4f solved %d  %.160s\n", k, c.energy, c.coarse_energy, c.solved ? 1 : 0,
                  c.description.c_str());
    }
    const surfmap::HomotopySearchInfo& h = r.homotopy_search;
    std::printf("search run %d start %d start_energy %.4f energy %.4f found %d evaluations %d screened %d coarse_solves %d "
                "pruned %d time %.1f s\n  stop: %s\n",
                h.run ? 1 : 0, h.start_candidate, h.start_energy, h.energy, h.found_candidate, h.evaluations, h.screened,
                h.coarse_solves, h.pruned, h.time_s, h.stop_reason.c_str());
    std::printf("  starts:");
    for (int k : h.starts) std::printf(" %d", k);
    std::printf("\n  moves:");
    for (size_t k = 0; k < h.moves.size(); ++k) std::printf(" [%s -> %.4f]", h.moves[k].c_str(), k < h.energies.size() ? h.energies[k] : NAN);
    std::printf("\n");
    std::vector<size_t> idx(h.evaluated_energy.size());
    for (size_t k = 0; k < idx.size(); ++k) idx[k] = k;
    std::stable_sort(idx.begin(), idx.end(), [&](size_t x, size_t y) { return h.evaluated_energy[x] < h.evaluated_energy[y]; });
    int finite = 0;
    for (double e : h.evaluated_energy) finite += std::isfinite(e) ? 1 : 0;
    // Single moves and pairs from the start (step 0), and how many were
    // solved (finite) or pruned by the curve bound (infinite).
    int singles = 0, singles_finite = 0, pairs = 0, pairs_finite = 0;
    for (size_t k = 0; k < h.evaluated_moves.size(); ++k) {
      const std::string& m = h.evaluated_moves[k];
      if (h.evaluated_step[k] != 0 || m.rfind("screen", 0) == 0) continue;
      const bool pair = m.find(", ") != std::string::npos;
      (pair ? pairs : singles) += 1;
      (pair ? pairs_finite : singles_finite) += std::isfinite(h.evaluated_energy[k]) ? 1 : 0;
    }
    std::printf("  step 0: %d single moves (%d solved), %d pairs (%d solved)\n", singles, singles_finite, pairs, pairs_finite);
    std::printf("  evaluated %zu (%d finite); lowest:\n", idx.size(), finite);
    for (size_t k = 0; k < std::min<size_t>(12, idx.size()); ++k)
      std::printf("    %.4f  step %d  %.200s\n", h.evaluated_energy[idx[k]], h.evaluated_step[idx[k]],
                  h.evaluated_moves[idx[k]].c_str());
    // Per kick of the iterated local search: its solves and the lowest energy
    // reached (its own evaluation and its descent's).
    std::vector<std::string> kick_names;
    std::vector<double> kick_min;
    std::vector<int> kick_count;
    for (size_t k = 0; k < h.evaluated_moves.size(); ++k) {
      const std::string& m = h.evaluated_moves[k];
      if (m.rfind("kick ", 0) != 0) continue;
      const std::string name = m.substr(0, m.find(' ', 5));
      auto it = std::find(kick_names.begin(), kick_names.end(), name);
      if (it == kick_names.end()) kick_names.push_back(name), kick_min.push_back(INFINITY), kick_count.push_back(0), it = kick_names.end() - 1;
      const size_t j = static_cast<size_t>(it - kick_names.begin());
      kick_min[j] = std::min(kick_min[j], h.evaluated_energy[k]);
      ++kick_count[j];
    }
    int back = 0, higher = 0, lower = 0, none = 0;
    for (size_t j = 0; j < kick_names.size(); ++j) {
      if (!std::isfinite(kick_min[j])) ++none;
      else if (std::abs(kick_min[j] - h.start_energy) <= 1e-6 * h.start_energy) ++back;
      else if (kick_min[j] < h.start_energy) ++lower;
      else ++higher;
    }
    if (!kick_names.empty())
      std::printf("  kicks %zu: back at the start %d, lowest above it %d, below it %d, nothing finite %d\n", kick_names.size(),
                  back, higher, lower, none);
    for (size_t j = 0; j < kick_names.size(); ++j)
      std::printf("    %s: %d solves, lowest %.4f\n", kick_names[j].c_str(), kick_count[j], kick_min[j]);
    if (!out_words.empty() && r.chosen_candidate >= 0) {
      std::ofstream out(out_words);
      for (const auto& w : r.candidates[r.chosen_candidate].words) {
        for (size_t j = 0; j < w.size(); ++j) out << (j ? " " : "") << w[j];
        out << "\n";
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
