#pragma once
// Stage "location" of the genus-1 map (docs/method.md §2.9: the outputs): every
// source vertex's image on the target's input mesh (forward), every target
// vertex's preimage on the source (inverse), and both for the initial
// (uniform Tutte) map, by location modulo the target lattice
// (map/point_location.h locate_periodic). Internal to src/map/flat_map.cpp.
#include <vector>

#include "../map_support.h"

namespace surfmap::detail {

struct FlatLocationResult {
  std::vector<PointOnSurface> forward, inverse;                  ///< #V source, #V target
  std::vector<PointOnSurface> initial_forward, initial_inverse;  ///< the same for the initial map, or empty
};

/// `target_loops`/`layout`: the target's refined mesh laid out in the plane
/// (`target_intrinsic`: its T' on the flip path, else null),
/// lattice (w1, w2); `z`/`z_init` (#V source): the optimum and the initial
/// map; `z_extended` (#V source, optional): the optimum in long double, whose
/// rounding is `z` (the forward barycentrics are then computed from it); `image`/`initial_image` (#F x 3): their image triangles. Reports
/// "forward location" to stage_done between the two directions. A vertex
/// of the optimum that cannot be located is a SolveError; of the initial
/// map, it leaves that output empty. `locate_initial` false
/// (InitialMapOptions::locate): the initial map is not located, both its
/// outputs are empty.
FlatLocationResult locate_flat_map(const TriMesh& source, const TriMesh& target, const Connectivity& tc,
                                   const SystemOfLoops& target_loops, const TargetIntrinsic* target_intrinsic,
                                   const DiskLayout& layout, Complex w1, Complex w2,
                                   const std::vector<Complex>& z, const std::vector<std::complex<long double>>* z_extended,
                                   const std::vector<Complex>& z_init,
                                   const Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>& image,
                                   const Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>& initial_image,
                                   bool locate_initial, const StageDone& stage_done);

}  // namespace surfmap::detail
