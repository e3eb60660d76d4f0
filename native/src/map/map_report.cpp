// The one serializer of SurfaceMapResult (map/map_report.h).
#include "surfmap/map/map_report.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>

#include "surfmap/map/class_lower_bound.h"
#include "surfmap/map/map_option_names.h"

namespace surfmap {

using nlohmann::json;

namespace {

std::string distortion_measure(int genus) {
  // (docs/handle_classes.md "Quality signal": what a reviewer measuring D' another way must
  // know; the three pipelines measure the image triangle in different places.)
  const std::string common =
      "; mean weighted by the source faces' 3D areas (unweighted_mean: every face alike, which the slivers' "
      "D' dominates), max over the faces; flipped or degenerate images are counted, not averaged; source faces "
      "thinner than the solvers resolve (smallest triangle-inequality margin below 1e-4 of the mean edge: the "
      "faces intrinsic mollification reshapes, zero-area ones included) are left out of mean, max and "
      "unweighted_mean, counted in left_out_faces (ids: left_out_face_ids) with their largest D' in left_out_max";
  if (genus == 0)
    return "D' = ratio of the singular values of the affine map from each source face onto the triangle of "
           "its corners' images on the target in 3D (chords)" + common;
  if (genus == 1)
    return "D' = ratio of the singular values of the affine map from each source face (3D) onto its image "
           "triangle in the target's flat uniformization domain" + common;
  return "D' = ratio of the singular values of the map from each source face (3D) onto its image geodesic "
         "triangle in the target's hyperbolic uniformization metric (from the side lengths; not the chord "
         "triangle of the 3D image points)" + common;
}

double unweighted_mean(const std::vector<double>& per_face, const std::vector<int>& left_out) {
  std::vector<char> skip(per_face.size(), 0);
  for (int f : left_out)
    if (f >= 0 && f < static_cast<int>(skip.size())) skip[f] = 1;
  double sum = 0;
  long n = 0;
  for (size_t f = 0; f < per_face.size(); ++f)
    if (!skip[f] && std::isfinite(per_face[f])) sum += per_face[f], ++n;
  return n ? sum / static_cast<double>(n) : std::numeric_limits<double>::quiet_NaN();
}

std::string energy_ratio_basis(const SurfaceMapResult& r) {
  if (r.genus < 2 || !std::isfinite(r.energy_ratio)) return "";
  char bound[96];
  std::snprintf(bound, sizeof bound, " / 8 pi (g - 1) = %.6g (the energy of a conformal map, the least of any map)",
                conformal_bound(r.genus));
  const std::string head = "the chosen class's free optimum (landmarks not held)";
  if (std::isfinite(r.intrinsic_class_energy))
    return head + " with intrinsic Delaunay cotangent weights, the energy the classes are ranked by" + bound +
           "; the returned map fell back to positive weights on the source's own edges (its energy.final, and "
           "energy_ratio_own_edges, are on those weights: not a discretisation of the Dirichlet energy, "
           "higher for the same class)";
  if (r.source_weights.rfind("positive on the source's own edges", 0) == 0)
    return head + " with positive weights on the source's own edges (source_weights 'own')" + bound +
           "; NOT comparable with the bound: those weights are not a discretisation of the Dirichlet energy "
           "and give a higher figure than the intrinsic Delaunay energy of the same class (source_weights "
           "'auto' reports that one)";
  std::string s = head + " with intrinsic Delaunay cotangent weights, the energy the classes are ranked by" + bound;
  if (r.fold_repair.status == "repaired")
    s += "; the returned map's energy.final is after the local fold repair (fold_repair), slightly above";
  return s;
}

}  // namespace

json energy_json(const SurfaceMapResult& r) {
  return {{"energy", {{"initial", r.initial_energy}, {"final", r.final_energy}, {"history", r.energy_history}}},
          {"distortion",
           {{"mean", r.mean_dilatation},
            {"max", r.max_dilatation},
            {"unweighted_mean", unweighted_mean(r.dilatation, r.thin_source_faces)},
            {"left_out_faces", static_cast<int>(r.thin_source_faces.size())},
            {"left_out_face_ids", r.thin_source_faces},
            {"left_out_max", r.thin_source_max_dilatation},
            {"measure", distortion_measure(r.genus)}}},
          {"initial_distortion", {{"mean", r.initial_mean_dilatation}, {"max", r.initial_max_dilatation}}},
          {"flipped_triangles", r.flipped_triangles},
          {"degenerate_triangles", r.degenerate_triangles},
          {"flat_triangles", r.flat_triangles},
          {"intrinsic_flipped_triangles", r.intrinsic_flipped_triangles},
          {"layout_closure",
           {{"tolerance", r.layout_closure.tolerance},
            {"triangles", r.layout_closure.triangles},
            {"open_triangles", r.layout_closure.open_triangles},
            {"worst_gap", r.layout_closure.worst_gap},
            {"worst_triangle", r.layout_closure.worst_triangle}}},
          {"image_cover",
           {{"triangles", r.image_cover.triangles},
            {"area_ratio", r.image_cover.area_ratio},
            {"vertices_off", r.image_cover.vertices_off},
            {"worst_angle_gap", r.image_cover.worst_angle_gap}}},
          {"initial_flipped_triangles", r.initial_flipped_triangles},
          {"repaired_vertices", r.repaired_vertices},
          {"source_subdivision",
           {{"status", r.source_subdivision.status},
            {"subdivided_faces", r.source_subdivision.subdivided_faces},
            {"bends", r.source_subdivision.bends},
            {"inverted_faces", r.source_subdivision.inverted_faces},
            {"new_vertices", static_cast<int>(r.source_subdivision.source_points.size())},
            {"triangles", static_cast<int>(r.source_subdivision.faces.rows())},
            {"sphere_cover", r.source_subdivision.sphere_cover}}},
          {"target_refinement_splits", r.target_refinement_splits},
          {"target_metric", r.target_metric},
          {"target_flips", r.target_flips},
          {"target_metric_choice", r.target_metric_choice},
          {"target_loop_metric", r.target_loop_metric},
          {"target_class_loops", r.target_class_loops},
          {"canonical_generators", r.canonical_generators},
          {"canonical_generators_fallback", r.canonical_generators_fallback},
          {"fold_fallback", r.fold_fallback},
          {"source_weights", r.source_weights},
          {"source_weights_reason", r.source_weights_reason},
          {"fold_repair",
           {{"status", r.fold_repair.status},
            {"method", r.fold_repair.method},
            {"folded_faces", r.fold_repair.folded_faces},
            {"tries", r.fold_repair.tries},
            {"rings", r.fold_repair.rings},
            {"free_vertices", r.fold_repair.free_vertices},
            {"changed_faces", r.fold_repair.changed_faces},
            {"energy_before", r.fold_repair.energy_before},
            {"energy_after", r.fold_repair.energy_after}}}};
}

json landmark_json(const SurfaceMapResult& r, const SurfaceMapOptions& options) {
  return {{"landmarks", options.landmarks.size()},
          {"landmark_error", r.max_landmark_error},
          {"landmark_rings", r.landmark_rings},
          {"landmark_method", r.landmark_method},
          {"landmark_solves", r.landmark_solves},
          {"landmark_steps", r.landmark_steps},
          {"landmark_held_vertices", r.landmark_held_vertices}};
}

json initial_map_json(const SurfaceMapResult& r) {
  const InitialMapInfo& im = r.initial_map;
  const json cut_graph = {{"status", im.cut_graph_status},
                          {"branch_vertices", im.cut_graph_branch_vertices},
                          {"sides", im.cut_graph_sides},
                          {"chords_rerouted", im.cut_graph_chords_rerouted},
                          {"min_turn", im.cut_graph_min_turn},
                          {"flipped", im.cut_graph_flipped},
                          {"degenerate", im.cut_graph_degenerate},
                          {"time_s", im.cut_graph_time_s}};
  const json polygon = {{"status", im.polygon_status},
                        {"convex", im.polygon_convex},
                        {"min_turn", im.polygon_min_turn},
                        {"perimeter", im.polygon_perimeter},
                        {"chords_split", im.polygon_chords_split},
                        {"flipped", im.polygon_flipped},
                        {"repaired_vertices", im.polygon_repaired_vertices},
                        {"time_s", im.polygon_time_s}};
  return {{"construction", im.construction}, {"cut_graph", cut_graph},     {"polygon", polygon},
          {"iterations", im.iterations},     {"time_s", im.time_s},         {"located", !r.initial_forward.empty()},
          {"location_requested", im.location_requested}};
}

json candidate_json(const HomotopyCandidate& c, size_t index) {
  return {{"index", index},
          {"description", c.description},
          {"energy", c.energy},
          {"solved", c.solved},
          {"coarse_energy", c.coarse_energy},
          {"landmark_energy", c.landmark_energy},
          {"landmark_lower_bound", c.landmark_lower_bound},
          {"matrix", {c.matrix[0], c.matrix[1], c.matrix[2], c.matrix[3]}},
          {"class_lower_bound", c.class_lower_bound},
          {"class_curve_bound", c.class_curve_bound},
          {"class_bound_curves", c.class_bound_curves},
          {"words", c.words}};
}

json homotopy_search_json(const HomotopySearchInfo& hs) {
  json evaluated = json::array();
  for (size_t k = 0; k < hs.evaluated_moves.size(); ++k)
    evaluated.push_back({{"step", hs.evaluated_step[k]},
                         {"move", hs.evaluated_moves[k]},
                         {"screen", hs.evaluated_screen[k]},
                         {"energy", hs.evaluated_energy[k]}});
  return {{"run", hs.run},
          {"start_candidate", hs.start_candidate},
          {"start_energy", hs.start_energy},
          {"energy", hs.energy},
          {"moves", hs.moves},
          {"energies", hs.energies},
          {"evaluations", hs.evaluations},
          {"screened", hs.screened},
          {"stop_reason", hs.stop_reason},
          {"time_s", hs.time_s},
          {"found_candidate", hs.found_candidate},
          {"kicks", hs.kicks},
          {"lower_kicks", hs.lower_kicks},
          {"high_kicks_status", hs.high_kicks_status},
          {"cut_classes", hs.cut_classes},
          {"cuts_time_s", hs.cuts_time_s},
          {"pruned", hs.pruned},
          {"geometric_classes", hs.geometric_classes},
          {"geometric_time_s", hs.geometric_time_s},
          {"geometric_failures", hs.geometric_failures},
          {"source_marking", hs.source_marking},
          {"target_marking", hs.target_marking},
          {"source_geodesics", hs.source_geodesics},
          {"target_geodesics", hs.target_geodesics},
          {"source_greedy_pants", hs.source_greedy_pants},
          {"target_greedy_pants", hs.target_greedy_pants},
          {"greedy_pants_time_s", hs.greedy_pants_time_s},
          {"curve_twists", hs.curve_twists},
          {"coarse_solves", hs.coarse_solves},
          {"starts", hs.starts},
          {"evaluated", evaluated}};
}

json homotopy_json(const SurfaceMapResult& r) {
  json candidates = json::array();
  for (size_t i = 0; i < r.candidates.size(); ++i) candidates.push_back(candidate_json(r.candidates[i], i));
  return {{"chosen", r.chosen_candidate},
          {"chosen_words", r.chosen_class_words},
          {"candidates", candidates},
          {"ranking", {{"coarse_solves", r.ranking_coarse_solves}, {"skipped", r.ranking_skipped}, {"status", r.ranking_status}, {"long_starts", r.long_starts}}},
          {"fallbacks", {{"refused_unmapped", r.fallbacks_refused_unmapped}}},
          {"snapped_class",
           {{"index", r.snapped_class},
            {"status", r.snapped_class_status},
            {"inconsistent_faces", r.snapped_inconsistent_faces}}},
          {"search", homotopy_search_json(r.homotopy_search)}};
}

json stage_times_json(const SurfaceMapResult& r) {
  json times = json::object();
  for (const auto& [stage, seconds] : r.stage_times) times[stage] = seconds;
  times["total"] = r.total_time;
  return times;
}

json stage_json(const StageRecord& s) {
  return {{"name", s.name},
          {"time_s", s.seconds},
          {"analyses", s.analyses},
          {"factorisations", s.factorisations},
          {"newton_iterations", s.newton_iterations},
          {"peak_memory_mb", static_cast<double>(s.peak_memory_bytes) / (1024.0 * 1024.0)}};
}

json stages_json(const SurfaceMapResult& r) {
  json rows = json::array();
  for (const StageRecord& s : r.stages) rows.push_back(stage_json(s));
  rows.push_back(stage_json(r.stage_total));
  return rows;
}

std::string stage_table(const SurfaceMapResult& r) {
  size_t width = 5;
  for (const StageRecord& s : r.stages) width = std::max(width, s.name.size());
  auto row = [&](const std::string& name, const std::string& seconds, const std::string& analyses,
                 const std::string& factorisations, const std::string& newton, const std::string& peak) {
    char line[512];
    std::snprintf(line, sizeof line, "%-*s %9s %9s %15s %7s %12s\n", static_cast<int>(width), name.c_str(),
                  seconds.c_str(), analyses.c_str(), factorisations.c_str(), newton.c_str(), peak.c_str());
    return std::string(line);
  };
  auto fixed = [](double v, int digits) {
    char s[64];
    std::snprintf(s, sizeof s, "%.*f", digits, v);
    return std::string(s);
  };
  auto line_of = [&](const StageRecord& s) {
    return row(s.name, fixed(s.seconds, 3), std::to_string(s.analyses), std::to_string(s.factorisations),
               std::to_string(s.newton_iterations), fixed(static_cast<double>(s.peak_memory_bytes) / (1024.0 * 1024.0), 1));
  };
  std::string text = row("stage", "time_s", "analyses", "factorisations", "newton",
                         r.peak_memory_per_stage ? "peak_MiB" : "peak_so_far");
  for (const StageRecord& s : r.stages) text += line_of(s);
  return text + line_of(r.stage_total);
}

json directions_json(const SurfaceMapResult& r) {
  const SurfaceMapResult::DirectionCheck& d = r.directions;
  return {{"outcome", d.outcome},
          {"reason", d.reason},
          {"inverted_candidate", d.inverted_candidate},
          {"energy", d.energy},
          {"inverted_energy", d.inverted_energy},
          {"source_length_change", d.source_length_change},
          {"target_length_change", d.target_length_change},
          {"length_tolerance", d.length_tolerance},
          {"difference", d.difference},
          {"agreement", d.agreement},
          {"own_pair_ratio", d.own_pair_ratio},
          {"other_pair_ratio", d.other_pair_ratio},
          {"other_one_way_ratio", d.other_one_way_ratio},
          {"inverse_there_ratio", d.inverse_there_ratio},
          {"chosen_class_words", r.chosen_class_words},
          {"source_as_target", r.source_as_target},
          {"source_as_target_inverse", r.source_as_target_inverse},
          {"source_as_target_status", r.source_as_target_status}};
}

json quality_json(const SurfaceMapResult& r) {
  return {{"energy_ratio", r.energy_ratio},           {"energy_ratio_basis", energy_ratio_basis(r)},
          {"warning", r.quality_warning},
          {"intrinsic_class_energy", r.intrinsic_class_energy}, {"energy_ratio_own_edges", r.energy_ratio_own_edges},
          {"reverse_candidates", r.reverse_candidates}, {"reverse_status", r.reverse_status},
          {"reverse_check", r.reverse_check}, {"reverse_inverse", r.reverse_inverse},
          {"reverse_inverse_reason", r.reverse_inverse_reason},   {"directions", directions_json(r)},           {"two_way_status", r.two_way_status},
          {"two_way_time_s", r.two_way_time_s}, {"through_shape_status", r.through_shape_status}, {"through_shape_time_s", r.through_shape_time_s},         {"class_bound_status", r.class_bound_status},
          {"class_cuts_status", r.class_cuts_status},   {"class_cuts_time_s", r.class_cuts_time_s},
          {"class_bound_time_s", r.class_bound_time_s}, {"class_bound_vertices", r.class_bound_vertices}};
}

json to_json(const SurfaceMapResult& r, const SurfaceMapOptions& options) {
  json report = {{"genus", r.genus},
                 {"converged", r.converged},
                 {"iterations", r.iterations},
                 {"method", enum_name(options.solve.method)},
                 {"target_metric_requested", enum_name(options.uniformization.target_metric)},
                 {"face_charts_requested", enum_name(options.uniformization.face_charts)},
                 {"face_charts", r.face_charts.empty() ? std::string("single chart") : r.face_charts},
                 {"initial_map", initial_map_json(r)},
                 {"homotopy", homotopy_json(r)},
                 {"quality", quality_json(r)},
                 {"target_lattice",
                  {{r.target_omega1.real(), r.target_omega1.imag()}, {r.target_omega2.real(), r.target_omega2.imag()}}},
                 {"time_s", stage_times_json(r)},
                 {"stages", stages_json(r)},
                 {"peak_memory_per_stage", r.peak_memory_per_stage}};
  if (!r.flat_placement.empty()) report["flat_placement"] = r.flat_placement;
  report.update(energy_json(r));
  report.update(landmark_json(r, options));
  return report;
}

}  // namespace surfmap
