#include "class_search.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <string>

#include "../concurrency.h"
#include "surfmap/error.h"
#include "surfmap/topology/mapping_class_search.h"

namespace surfmap::detail {

std::vector<FoundClass> classes_from_more_cuts(CutLifter& lifter, SourceCuts& cuts, const ClassSpace& space,
                                               int num_vertices, int threads, double conformal_bound,
                                               const std::function<ClassData(const GroupMap&)>& data_of,
                                               const CoarseSolve& solve_coarse, const SurfaceMapOptions& options,
                                               HomotopySearchInfo& info) {
  const auto t_cuts = std::chrono::steady_clock::now();
  std::vector<FoundClass> found;
  const std::vector<int> late = spread_bases(num_vertices, options.homotopy.search.cuts);
  // The late cuts' source-only parts, on both threads.
  parallel_for(threads, static_cast<int>(late.size()), [&](int k, const std::atomic<bool>*) {
    const auto& planned = cuts.planned_bases();
    auto slot = std::find(planned.begin(), planned.end(), late[k]);
    if (slot != planned.end()) cuts.prepare_planned(static_cast<int>(slot - planned.begin()));
  });
  for (HomotopyClass& hc : lifter.lift(late)) {
    if (space.loop_image_length(hc.map) > space.max_image_letters()) continue;
    FoundClass f;
    try {
      f.data = data_of(hc.map);
    } catch (const SolveError&) {
      continue;
    }
    ++info.cut_classes;
    if (!solve_coarse(hc.map, &f.evaluation)) continue;
    const double energy = f.evaluation.result.energy;
    f.hc = std::move(hc);
    found.push_back(std::move(f));
    // Within the gap of the bound: what the twist search would not run
    // for, so the rest (lowest screen first) are not solved either.
    if (energy <= (1 + options.homotopy.search.gap) * conformal_bound) break;
  }
  info.cuts_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_cuts).count();
  return found;
}

std::optional<CoarseEvaluation> twist_class_search(const GroupMap& start_map, int start_index, double start_energy,
                                                   const ClassSpace& space, const CoarseSolve& solve_coarse,
                                                   const std::vector<std::string>& start_twists,
                                                   const SurfaceMapOptions& options, HomotopySearchInfo& info) {
  const auto t_search = std::chrono::steady_clock::now();
  info.run = true;
  info.start_candidate = start_index;
  GroupMap search_from = start_map;
  if (!start_twists.empty()) {
    const std::vector<MappingClassMove> moves = twist_moves(space.genus());
    for (const std::string& name : start_twists) {
      auto it = std::find_if(moves.begin(), moves.end(), [&](const MappingClassMove& m) { return m.name == name; });
      if (it == moves.end()) throw InputError("homotopy_search_start_twists: no move named '" + name + "'");
      search_from = compose(search_from, it->automorphism.map);
      space.reduce(search_from);
    }
  }
  std::vector<CoarseEvaluation> evaluated;
  auto coarse_energy = [&](const GroupMap& theta) {
    CoarseEvaluation ev;
    if (!solve_coarse(theta, &ev)) return std::numeric_limits<double>::infinity();
    evaluated.push_back(std::move(ev));
    return evaluated.back().result.energy;
  };
  info.start_energy = start_twists.empty() ? start_energy : coarse_energy(search_from);
  TwistSearchOptions tso;
  tso.max_evaluations = options.homotopy.search.evaluations;
  const TwistSearchResult ts = twist_search(search_from, info.start_energy, space.genus(),
                                            [&](const GroupMap& theta) { return space.screen(theta); }, coarse_energy, tso);
  info.moves = ts.moves;
  info.energies = ts.energies;
  info.energy = ts.energy;
  info.evaluations = static_cast<int>(ts.evaluations.size());
  for (const TwistSearchEvaluation& ev : ts.evaluations) {
    info.evaluated_moves.push_back(ev.move);
    info.evaluated_step.push_back(ev.step);
    info.evaluated_screen.push_back(ev.screen);
    info.evaluated_energy.push_back(ev.energy);
  }
  info.screened = ts.screened;
  info.stop_reason = ts.stop_reason;
  std::optional<CoarseEvaluation> found;
  if (!ts.moves.empty())
    for (CoarseEvaluation& ev : evaluated)
      if (ev.theta == ts.best) found = ev;  // (the last match, as before)
  info.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_search).count();
  return found;
}

}  // namespace surfmap::detail
