#pragma once
// The genus >= 2 map in per-face charts of the target (issue 13): for
// targets whose hyperbolic layout one Poincaré chart in double cannot hold
// (CAD plates of genus >= 13, 40 .. 70 long in their metric). Every
// position is a target face and a point in that face's canonical chart
// (uniformize/layout.h FaceAtlas); nothing reads a global chart, a deck
// group or a fundamental polygon. Internal to src/map (surface_map.cpp).
//
// What it does, in order (docs/robustness.md "High genus"):
//  1. the target's flip-based hyperbolic metric (as the single-chart path's
//     target stage, without loops or layout) and its FaceAtlas on T';
//  2. the start: every source vertex at the target vertex nearest it in 3D
//     (the snapped overlay); every source edge's element composed of the
//     transitions along T''s edges between its ends' vertices: its own T'
//     edge, else the closing relation of a source face whose other two
//     edges are known, else the shortest edge path in the metric; edges
//     whose faces do not close are re-derived from a face while that closes
//     more faces. The class is the snapped map's, the identity's for two
//     meshings of one shape; no other class is listed or searched;
//  3. the harmonic solve in the face charts with positive weights on the
//     source's own edges (their harmonic map embeds the source);
//  4. quality (D', flipped, degenerate) from the solver's local charts;
//  5. the forward map: each vertex walked to its face, carried back through
//     the flips onto the user's target; the inverse: each target vertex
//     found in the image of a source face, searched over the target faces
//     within that image's reach of its first corner.
#include <string>

#include "map_support.h"

namespace surfmap::detail {

/// True when `options` ask for nothing the per-face path cannot give
/// (landmarks, a requested class, images or words); else `why` says what.
bool face_chart_map_applies(const SurfaceMapOptions& options, std::string* why);

/// Fills `out` with the map in per-face charts (steps above). `reason`:
/// why this path runs (the single chart's limit, or requested), kept in
/// out.face_charts. Throws UniformizationError when the target's metric
/// fails, SolveError when the snapped class does not close around every
/// source face or the solve's result folds (counts named).
void map_in_face_charts(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                        const SurfaceMapOptions& options, const std::string& reason, SurfaceMapResult& out,
                        const StageDone& stage_done);

}  // namespace surfmap::detail
