#pragma once
// The uniformization metric of a target whose fixed-connectivity flow has no
// solution (docs/method.md §2.4; CAD meshes with caps such as g3_block): the
// loops' refined mesh is refined further, exactly (mesh/exact_refinement.h:
// altitude-foot splits of the edges opposite large angles, on the mesh's own
// edges in 3D), the loops follow the splits, and the flow runs again, with a
// lower angle bound each round. Everything downstream (layout, location,
// origins on the input mesh) sees an ordinary refined system of loops: the
// new vertices keep exact barycentrics on the input faces and the input
// vertices stay the first #V vertices, so forward points and the inverse map
// are still expressed on the user's mesh.
#include <string>
#include <vector>

#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {

struct FeasibleMetricOptions {
  RicciFlowOptions flow;
  /// Max-angle bounds (degrees) of the refinement rounds tried in turn when
  /// the flow on the unrefined loops mesh does not converge (default 150,
  /// 135, 120). Empty: no refinement (the plain fixed-connectivity flow).
  std::vector<double> refine_max_angles = {150, 135, 120};
};

struct FeasibleMetricResult {
  /// The system of loops the metric lives on (`loops` as given when no
  /// refinement was needed). origin_face / origin_barycentric refer to the
  /// input mesh of the original system of loops.
  SystemOfLoops loops;
  RicciFlowResult flow;
  /// Splits added by the refinement (0: the first flow converged), the angle
  /// bound of the round that converged, and why the unrefined flow failed.
  int refinement_splits = 0;
  double refinement_max_angle = 0;
  std::string unrefined_failure;
};

/// input: the mesh `loops` was computed on (system_of_loops(input)). Never
/// throws for an infeasible metric: check result.flow.converged (the last
/// round's flow is returned). Throws SolveError if rebuilding the loops on a
/// refined mesh fails its checks.
FeasibleMetricResult feasible_metric(const TriMesh& input, const SystemOfLoops& loops, Background background,
                                     const FeasibleMetricOptions& options = {});

}  // namespace surfmap
