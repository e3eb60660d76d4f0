#pragma once
// The report of a surface map (SurfaceMapResult, map/surface_map.h) as JSON:
// the one serializer behind the CLI's `surfmap map --report` file and the
// Python result dict (the bindings convert this JSON and add the per-vertex
// and per-face arrays as numpy arrays), so both carry the same keys, values
// and enum spellings (map/map_option_names.h).
//
// Keys (every block is one function below, so a new block is one more
// function and one line in to_json):
//   genus, converged, iterations, method, target_metric_requested (the option:
//   auto, flips, fixed or fixed-first), landmarks (count),
//   energy {initial, final, history}, distortion {mean (area-weighted), max, unweighted_mean,
//   measure (what D' is measured on, in words)},
//   initial_distortion {mean, max}, flipped_triangles, degenerate_triangles, flat_triangles,
//   intrinsic_flipped_triangles, layout_closure {tolerance, triangles, open_triangles, worst_gap,
//   worst_triangle}, initial_flipped_triangles, repaired_vertices,
//   landmark_error, landmark_rings, landmark_method, landmark_solves,
//   landmark_steps, landmark_held_vertices,
//   initial_map {construction, cut_graph {...}, polygon {...}, iterations, time_s, located},
//   target_refinement_splits, target_metric, target_flips, target_metric_choice, target_class_loops, source_weights,
//   source_weights_reason, fold_repair {status, folded_faces, tries, rings, free_vertices, changed_faces,
//   energy_before, energy_after},
//   homotopy {chosen, chosen_words, candidates [{index, description, energy, solved, coarse_energy,
//             landmark_energy, landmark_lower_bound, matrix, class_lower_bound,
//             class_curve_bound, class_bound_curves, words}], search {..., evaluated
//             [{step, move, screen, energy}]}},
//   quality {energy_ratio, energy_ratio_basis (which energy, in words), warning,
//            intrinsic_class_energy, energy_ratio_own_edges, directions {..., chosen_class_words,
//            source_as_target, source_as_target_inverse}, reverse_candidates, reverse_status, reverse_check,
//            two_way_status, two_way_time_s, class_bound_status, class_bound_time_s,
//            class_bound_vertices},
//   target_lattice [[re, im] of omega1, [re, im] of omega2], time_s {stage: seconds, total},
//   stages [{name, time_s, analyses, factorisations, newton_iterations, peak_memory_mb}]
//   (the stage table, issue 19: one row per stage of time_s, in order, then the row
//   named "total"), peak_memory_per_stage.
// Non-finite numbers are stored as such (the CLI's dump writes them as null;
// the Python conversion keeps them as float nan / inf).
#include <string>

#include <nlohmann/json.hpp>

#include "surfmap/map/surface_map.h"

namespace surfmap {

/// The whole report of `result`, computed with `options` (echoed: the
/// optimiser's name and the number of landmarks).
nlohmann::json to_json(const SurfaceMapResult& result, const SurfaceMapOptions& options);

/// The blocks of to_json, one per concern.
nlohmann::json energy_json(const SurfaceMapResult& result);
nlohmann::json landmark_json(const SurfaceMapResult& result, const SurfaceMapOptions& options);
nlohmann::json initial_map_json(const SurfaceMapResult& result);
nlohmann::json candidate_json(const HomotopyCandidate& candidate, size_t index);
nlohmann::json homotopy_search_json(const HomotopySearchInfo& search);
nlohmann::json homotopy_json(const SurfaceMapResult& result);
nlohmann::json stage_times_json(const SurfaceMapResult& result);
/// The stage table (SurfaceMapResult::stages, then stage_total) and one row of it.
nlohmann::json stages_json(const SurfaceMapResult& result);
nlohmann::json stage_json(const StageRecord& stage);

/// The stage table as aligned text, one line per stage and the total line
/// (the CLI's `surfmap map --timings`; columns: stage, time_s, analyses,
/// factorisations, newton, peak_MiB), each line ending in a newline.
std::string stage_table(const SurfaceMapResult& result);
/// Genus >= 2 quality signal and two-way run (issue 14; docs/handle_classes.md).
nlohmann::json quality_json(const SurfaceMapResult& result);

}  // namespace surfmap
