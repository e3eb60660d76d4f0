#pragma once
// Choices of the genus >= 2 class ranking (docs/method.md §2.10; ranking in docs/
// method notes): which classes are solved at full resolution after the
// coarse ranking, and which solved class is the default. Internal.
#include <vector>

#include "surfmap/map/surface_map.h"

namespace surfmap::detail {

/// The coarse estimates (candidates[k].energy) may be within
/// discretisation error of each other: every class within this relative
/// margin of the best estimate is solved at full resolution (up to
/// homotopy.full_solves).
constexpr double kCoarseMargin = 0.1;

struct FullSolvePick {
  std::vector<char> full;  ///< #classes: solve at full resolution
  int likely_class = -1;   ///< the class most likely chosen (requested, or the leader), or -1
};

/// `order`: the classes by coarse energy (stable); `usable` (#classes):
/// classes with homotopy data whose solves have not failed; `full_solves`:
/// at most this many (homotopy.full_solves, or every class for <= 0, as
/// counted before the class search added any).
FullSolvePick pick_full_solves(const std::vector<HomotopyCandidate>& candidates, const std::vector<int>& order,
                               const std::vector<char>& usable, int full_solves, const SurfaceMapOptions& options);

/// The default class among those solved at full resolution: the lowest
/// energy, ties within 1e-4 relative (a symmetry of the shapes composed
/// with the best class) going to the earliest candidate; the requested one
/// when options.homotopy.class_index >= 0. -1 when none was solved.
int choose_class(const std::vector<HomotopyCandidate>& candidates, const SurfaceMapOptions& options);

}  // namespace surfmap::detail
