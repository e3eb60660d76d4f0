#pragma once
// Landmarks of the genus-1 map (docs/method.md §2.10; src/map/landmarks.h): each
// source vertex held at the lift of its target vertex nearest to where the
// class's free optimum puts it; plain pins first (the exact held optimum),
// if that folds the interior-point continuation (the bijective map of least
// energy, up to its barrier), and if that stalls, carried neighbourhoods.
// Internal to src/map/flat_map.cpp.
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "../landmarks.h"
#include "../map_support.h"
#include "surfmap/geometry/intrinsic_delaunay.h"

namespace surfmap::detail {

/// A held map: #V points, its energy, how it was held, and the vertices
/// held and where (the initial map holds the same).
struct FlatHold {
  std::vector<Complex> z;
  double energy = 0;
  std::string method = "pinned";
  std::vector<int> rings;
  int solves = 1, steps = 0, held_count = 0;
  std::vector<int> held;
  std::vector<Complex> values;
};

/// Everything holding the landmarks in a class needs but the class.
struct FlatLandmarkProblem {
  const TriMesh* source = nullptr;
  const IntrinsicDelaunayResult* idt = nullptr;
  const std::vector<std::pair<int, int>>* landmarks = nullptr;  ///< (source vertex, target vertex)
  std::vector<int> lm_source;        ///< #landmarks source vertices
  std::vector<Complex> lm_target;    ///< #landmarks target vertices in the layout
  Complex w1, w2;                    ///< the target lattice
  /// The class's free optimum for intrinsic translations t (#idt edges).
  std::function<std::vector<Complex>(const std::vector<Complex>& t)> free_optimum;
  /// The plain pins' solve (PinnedFlatHarmonic with the cotangent weights).
  const PinnedFlatHarmonic* pinned = nullptr;
  /// Image triangles (#F x 3) of the source's faces for edge translations te (#E) and points z.
  std::function<Eigen::Matrix<Complex, Eigen::Dynamic, 3, Eigen::RowMajor>(const std::vector<Complex>& te,
                                                                            const std::vector<Complex>& z)>
      image_corners;
  /// SurfaceMapOptions::landmarks_may_fold: the plain pins' map is returned
  /// folded or not (no continuation, no carried neighbourhoods).
  bool folds_allowed = false;
};

/// The landmarks held in the class with translations t (#idt edges) and te
/// (#E source edges); a SolveError when they cannot be held bijectively
/// (unless problem.folds_allowed: then the plain pins, method "pinned (folds
/// allowed)" when they fold).
FlatHold hold_flat_landmarks(const FlatLandmarkProblem& problem, const std::vector<Complex>& t,
                             const std::vector<Complex>& te);

}  // namespace surfmap::detail
