#include "class_ranking.h"

#include <algorithm>
#include <cmath>

namespace surfmap::detail {

FullSolvePick pick_full_solves(const std::vector<HomotopyCandidate>& candidates, const std::vector<int>& order,
                               const std::vector<char>& usable, int full_solves, const SurfaceMapOptions& options) {
  // Which classes get the full-resolution solve: the requested one, or the
  // best by coarse energy and those within the margin of it. The margin is
  // a few times the coarse-versus-fine energy differences measured between
  // classes (the discretisation error is mostly common to all classes of
  // one source, so the ranking is more accurate than the energies are).
  FullSolvePick out;
  out.full.assign(candidates.size(), 0);
  const int ncand = static_cast<int>(candidates.size());
  if (options.homotopy.class_index >= 0) {
    out.full[options.homotopy.class_index] = usable[options.homotopy.class_index];
    out.likely_class = options.homotopy.class_index;
  } else {
    const double best = candidates[order[0]].energy;
    // Ties (symmetric shapes: equal energies to ~1e-7 on the coarse copy
    // too) are decided at full resolution by the earliest candidate, the
    // overlay class first, so the earliest of the tied goes first here.
    std::vector<int> pick;
    for (int q = 0; q < ncand; ++q)
      if (usable[order[q]] && (q == 0 || options.homotopy.full_solves <= 0 ||
                               candidates[order[q]].energy <= best * (1 + kCoarseMargin)))
        pick.push_back(order[q]);
    int leader = -1;
    for (int k : pick)
      if (candidates[k].energy <= best * (1 + 1e-4) && (leader < 0 || k < leader)) leader = k;
    if (leader >= 0) pick.erase(std::find(pick.begin(), pick.end(), leader)), pick.insert(pick.begin(), leader);
    // A runner-up tied with the leader to 1e-6 on the coarse copy is the
    // same optimum up to a symmetry of the shapes (its full solve gave the
    // leader's energy to 1e-10 on the 50k bench pair): solving it again at
    // full resolution cannot change the choice, so it is not (unless every
    // class is asked for: homotopy.full_solves <= 0).
    if (!pick.empty() && options.homotopy.full_solves > 0) {
      const double lead = candidates[pick[0]].energy;
      pick.erase(std::remove_if(pick.begin() + 1, pick.end(),
                                [&](int k) { return std::abs(candidates[k].energy - lead) <= 1e-6 * lead; }),
                 pick.end());
    }
    for (int q = 0; q < static_cast<int>(pick.size()) && q < full_solves; ++q) out.full[pick[q]] = 1;
    if (!pick.empty()) out.likely_class = pick[0];
  }
  return out;
}

int choose_class(const std::vector<HomotopyCandidate>& candidates, const SurfaceMapOptions& options) {
  int chosen = -1;
  const int ncand = static_cast<int>(candidates.size());
  for (int k = 0; k < ncand; ++k)
    if (candidates[k].solved && (chosen < 0 || candidates[k].energy < candidates[chosen].energy))
      chosen = k;
  if (options.homotopy.class_index >= 0) chosen = options.homotopy.class_index;
  // Ties (symmetric shapes: a symmetry composed with the best class has the
  // same energy up to discretisation, ~1e-8..1e-5 relative) go to the
  // earliest candidate, the overlay class first.
  if (options.homotopy.class_index < 0)
    for (int k = 0; k < chosen; ++k)
      if (candidates[k].solved && candidates[k].energy <= candidates[chosen].energy * (1 + 1e-4)) {
        chosen = k;
        break;
      }
  return chosen;
}

}  // namespace surfmap::detail
