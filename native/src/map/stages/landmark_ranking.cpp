#include "landmark_ranking.h"

#include <algorithm>
#include <limits>

#include "surfmap/error.h"

namespace surfmap::detail {

int landmark_branch_and_bound(std::vector<int> classes, std::vector<HomotopyCandidate>& candidates,
                              const std::function<std::optional<double>(int k)>& hold) {
  std::stable_sort(classes.begin(), classes.end(), [&](int x, int y) {
    return candidates[x].landmark_lower_bound < candidates[y].landmark_lower_bound;
  });
  int best = -1;
  for (int k : classes) {
    if (best >= 0 && candidates[k].landmark_lower_bound >= candidates[best].landmark_energy) break;
    try {
      const std::optional<double> energy = hold(k);
      if (!energy) continue;
      candidates[k].landmark_energy = *energy;
      if (best < 0 || *energy < candidates[best].landmark_energy) best = k;
    } catch (const SolveError&) {
      candidates[k].landmark_energy = std::numeric_limits<double>::infinity();
    }
  }
  return best;
}

}  // namespace surfmap::detail
