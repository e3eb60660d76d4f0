#pragma once
// The through-shape step (issue 14; docs/handle_classes.md "Through a
// generated shape"). Not public API (used by surface_map.cpp).
#include "surfmap/map/surface_map.h"
#include "two_way_run.h"

namespace surfmap::detail {

/// The class of source -> middle composed with the class of middle ->
/// target, in the letters of a source -> target run with `options`' loops:
/// middle_to_target ∘ ι_M^-1 ∘ source_to_middle, where ι_M^-1
/// (middle_to_target.source_as_target_inverse) rewrites the middle shape's
/// letters as a target into its letters as a source. Empty, with `why`, when
/// a run reported no class words or letters.
std::vector<std::vector<int>> composed_class(const SurfaceMapResult& source_to_middle,
                                             const SurfaceMapResult& middle_to_target, std::string& why);

/// Genus >= 2, HomotopyOptions::through_shape, default class, no landmarks:
/// when `forward`'s energy ratio is at least through_shape_ratio, maps the
/// source onto a generated n-hole torus of its genus and that onto the
/// target (`map`, the two-way run as in `options`), solves the composed class here alone
/// (HomotopyOptions::given_class) and, when its energy is lower, returns
/// that map in `forward` with the class appended to `forward`'s candidates
/// and chosen. Always sets through_shape_status (and through_shape_time_s
/// when it ran).
void through_shape_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                       SurfaceMapResult& forward, const MapFunction& map);

}  // namespace surfmap::detail
