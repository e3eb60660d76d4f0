#pragma once
// Local repair of the folds of the genus >= 2 map (issue 14; docs/
// handle_classes.md "Local fold repair"). With the intrinsic Delaunay
// cotangent weights the harmonic map embeds the intrinsic triangulation,
// but the straight images of a few of the user's own faces can fold
// (slivers of 0.04 degrees on the teapot: 18 of 65020 faces). Solving the
// whole map again with positive weights on the source's own edges unfolds
// them but costs every face the affine reproduction of the cotangents
// (teapot -> double torus: mean D' 3.8 -> 5.7). Here only a few vertices
// move, the rest stay where the intrinsic map put them:
//  1. projection: a corner of each folded face moves into the kernel of its
//     neighbours' polygon (every face of its star positive; Klein model,
//     where that kernel is an intersection of half-planes), as little as
//     it must; a few Gauss-Seidel rounds;
//  2. if folds stay (clusters of slivers folded together: no corner's
//     kernel is open), the untangling by distortion: the free vertices
//     within 2, 4, 8, 16 rings of the folds left move jointly, each
//     connected region in one flat chart of the target (Klein model), the
//     rim held, minimising a regularised conformal (MIPS) energy of their
//     faces that becomes a barrier on their orientation as its ε goes to 0
//     (L-BFGS); kept when the map's mean D' stays within 25% of the
//     unchanged faces';
//  3. if folds stay: the vertices within 2, 4, 8, 16 rings of the folded
//     faces' corners are solved again with positive own-edge weights
//     (positive_edge_weights), the others held, until no face folds or the
//     region stops being local; the region is closed over slivers (its rim
//     cuts none), and the projection follows where the rim still folds.
// The deck elements are untouched, so the class stays. Internal to the
// pipeline (src/map/hyperbolic_map.cpp).
#include <optional>
#include <vector>

#include "class_data.h"
#include "hyperbolic_quality.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap::detail {

struct FoldRepairOptions {
  /// Rounds of the projection over the folded faces (default 8).
  int projection_rounds = 8;
  /// The distortion-aware untangling (second stage): its regions free the
  /// vertices within first_rings, 2 first_rings, ... up to this many rings
  /// of the folds the projection left (default 16; 0 skips the stage).
  int untangle_max_rings = 16;
  /// L-BFGS iterations per value of the regularisation ε (default 300) ...
  int untangle_iterations = 300;
  /// ... and at most this many values of ε (default 40).
  int untangle_rounds = 40;
  /// Weight θ of the area term against the conformal one (default 1/128:
  /// the area only keeps faces from collapsing, the shape is what counts).
  double untangle_area_weight = 1.0 / 128;
  /// The untangled map is kept only when its area-weighted mean D' is at
  /// most this much above the unchanged faces' (default 0.25).
  double untangle_max_mean_rise = 0.25;
  /// Rings of vertices around the folded faces' corners re-solved in the
  /// first try (default 2); each further try doubles them.
  int first_rings = 2;
  /// Tries (default 4: 2, 4, 8 and 16 rings).
  int max_tries = 4;
  /// The ring region is closed over slivers: faces whose smallest angle is
  /// below this (degrees; default 5) free all their corners when one is free.
  double sliver_degrees = 5.0;
  /// No try frees more than this fraction of the vertices (default 0.1):
  /// beyond that the repair is not local and the caller's global fallback
  /// (own-edge weights everywhere) is the better map.
  double max_free_fraction = 0.1;
  /// The held solve's tolerance and iteration cap (SolveOptions).
  double tolerance = 1e-10;
  int max_iterations = 300;
};

struct FoldRepairResult {
  /// The record for the report (SurfaceMapResult::fold_repair).
  SurfaceMapResult::FoldRepair info;
  /// The repaired map (relative to the class's edges, as `hr` was; energy =
  /// its energy with the intrinsic weights), when no source face folds.
  std::optional<HyperbolicHarmonicResult> map;
};

/// The intrinsic energy Σ w_e d_e² of a solve's result from its local
/// charts (edge_local, one per edge of `edges`): any weights on the same
/// edges, exact to round-off wherever the points lie.
double energy_in_charts(const std::vector<WeightedEdge>& edges, const std::vector<hyperbolic::Mobius>& edge_local);

/// `edges`: the class's solver edges with the intrinsic weights
/// (ClassData::edges; every source edge is one, SolverEdgeIndex `index`);
/// `own`: positive_edge_weights of the source (weights per source edge);
/// `hr`: the intrinsic optimum (Newton: vertex_deck_word set); `per_face`:
/// its D' (+inf where the image folds or is flat); `held`: #V or empty,
/// vertices that must not move (landmarks). Never throws a SolveError (a
/// failed held solve is a failed try, said in info.status); Cancelled passes.
FoldRepairResult repair_folds_locally(const TriMesh& source, const Connectivity& sc,
                                      const std::vector<WeightedEdge>& edges, const SolverEdgeIndex& index,
                                      const IntrinsicDelaunayResult& own, const HyperbolicHarmonicResult& hr,
                                      const std::vector<double>& per_face, const std::vector<char>& held,
                                      const DeckGroup& group, const FundamentalPolygon& polygon,
                                      const FoldRepairOptions& options,
                                      const std::function<bool(int, double, double)>& progress = {});

}  // namespace surfmap::detail
