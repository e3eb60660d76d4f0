#pragma once
// Ranking of homotopy classes with landmarks (docs/method.md §2.10), shared by the
// genus-1 and genus >= 2 pipelines: landmarks change which class is best,
// so classes are ranked by their energy with the landmarks held the way the
// returned map holds them (plain pins, else the barrier continuation, else
// carried neighbourhoods: src/map/landmarks.h). That can take a
// continuation per class, so it is a branch and bound: the plain pins'
// energy is the infimum over all held maps, folded ones included, so a
// lower bound; classes are held in the order of their bounds, and one whose
// bound is not below the best held energy so far cannot win and is not
// held. Internal.
#include <functional>
#include <optional>
#include <vector>

#include "surfmap/map/surface_map.h"

namespace surfmap::detail {

/// `classes`: the indices into `candidates` that have a landmark_lower_bound
/// (ranked in the order of their bounds, ties in the given order).
/// `hold(k)`: holds the landmarks in class k and returns the held energy
/// (the caller keeps the held map), std::nullopt when the held solve did not
/// converge (the class is skipped), or throws SolveError when the landmarks
/// cannot be held bijectively (landmark_energy = +inf). Sets
/// landmark_energy of the classes held; returns the best class, or -1.
int landmark_branch_and_bound(std::vector<int> classes, std::vector<HomotopyCandidate>& candidates,
                              const std::function<std::optional<double>(int k)>& hold);

}  // namespace surfmap::detail
