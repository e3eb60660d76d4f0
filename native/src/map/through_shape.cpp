// The through-shape step (issue 14; docs/handle_classes.md "Through a
// generated shape").
#include "through_shape.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <utility>

#include "surfmap/error.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/topology/handle_basis.h"

namespace surfmap::detail {

namespace {

/// The options of a run to or from the generated shape or of the composed
/// class here: no two-way run (the caller sets it back where wanted), no
/// through-shape step, no landmarks, no requested class, no solve-progress
/// callback.
SurfaceMapOptions one_way_options(const SurfaceMapOptions& options) {
  SurfaceMapOptions o = options;
  o.homotopy.class_index = -1;
  o.homotopy.two_way = false;
  o.homotopy.through_shape = false;
  o.homotopy.source_images.resize(0, 0);
  o.homotopy.reverse_class.clear();
  o.homotopy.given_class.clear();
  o.landmarks.clear();
  o.solve_progress = nullptr;
  return o;
}

/// The composed class as a candidate of the first run: the single-class
/// run's candidate, tagged with where it came from.
HomotopyCandidate listed_candidate(const SurfaceMapResult& through, const std::string& shape) {
  HomotopyCandidate c = through.candidates[through.chosen_candidate];
  const std::string given = "the given class", tag = "through a generated " + shape;
  const size_t at = c.description.find(given);
  if (at != std::string::npos) c.description.replace(at, given.size(), tag);
  else c.description += "  [" + tag + "]";
  return c;
}

}  // namespace

std::vector<std::vector<int>> composed_class(const SurfaceMapResult& source_to_middle,
                                             const SurfaceMapResult& middle_to_target, std::string& why) {
  if (source_to_middle.chosen_class_words.empty())
    why = "the map onto the generated shape reported no class words";
  else if (middle_to_target.chosen_class_words.empty())
    why = "the map from the generated shape reported no class words";
  else if (middle_to_target.source_as_target_inverse.empty())
    why = "the generated shape's letters as a source are missing (" + middle_to_target.source_as_target_status + ")";
  if (!why.empty()) return {};
  return compose(middle_to_target.chosen_class_words,
                 compose(middle_to_target.source_as_target_inverse, source_to_middle.chosen_class_words));
}

void through_shape_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                       SurfaceMapResult& forward, const MapFunction& map) {
  const HomotopyOptions& h = options.homotopy;
  if (forward.genus < 2 || h.class_index >= 0 || h.source_images.size() > 0 || h.reverse_class_only ||
      !h.given_class.empty())
    return;
  if (!h.through_shape) return void(forward.through_shape_status = "not run (off)");
  if (!options.landmarks.empty()) return void(forward.through_shape_status = "not run: landmarks are held");
  if (!(forward.energy_ratio >= h.through_shape_ratio))
    return void(forward.through_shape_status = "not run: energy ratio below " + four_digits(h.through_shape_ratio));
  const int g = forward.genus;
  if (g > 8) return void(forward.through_shape_status = "not run: no generated n-hole torus beyond genus 8");
  const auto t0 = std::chrono::steady_clock::now();
  auto finish = [&](SurfaceMapResult& r, std::string status) {
    r.through_shape_status = std::move(status);
    r.through_shape_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  const std::string shape = "genus-" + std::to_string(g) + " n-hole torus";
  // At least 16 grid cells per handle in a row (genus <= 4), 64 for the
  // wheels beyond: at 32 cells the genus-4 n-hole torus (2.3k vertices)
  // mapped onto the genus-4 CAD plate at 11.8 x, at 48 (5.9k) at 1.04 x but
  // the fertility onto it at 8.75 x, at 64 (10k) at 4.54 x
  // (docs/handle_classes.md "Through a generated shape").
  const int resolution = std::max(h.through_shape_resolution, g <= 4 ? 16 * g : 64);
  TriMesh middle;
  try {
    middle = samples::n_hole_torus(g, resolution);
  } catch (const Cancelled&) {
    throw;
  } catch (const Error& e) {
    return finish(forward, "generating the " + shape + " failed: " + e.what());
  }
  // Onto the generated shape in the source's cuts (as given), from it in
  // the target's: the letters of this run at both ends.
  // Each with the two-way run as given: fertility -> the genus-4 n-hole
  // torus one way ends at 8.75 x, with the two-way run at 4.54 x, and the
  // composed class is only as good as that map.
  SurfaceMapOptions onto = one_way_options(options);
  onto.loops.target_base_vertex = -1;
  onto.homotopy.two_way = options.homotopy.two_way;
  SurfaceMapOptions from = one_way_options(options);
  from.loops.source_base_vertex = -1;
  from.homotopy.two_way = options.homotopy.two_way;
  SurfaceMapResult to_middle, from_middle;
  try {
    to_middle = map(source, middle, onto);
  } catch (const Cancelled&) {
    throw;
  } catch (const Error& e) {
    return finish(forward, "mapping onto the generated " + shape + " failed: " + e.what());
  }
  try {
    from_middle = map(middle, target, from);
  } catch (const Cancelled&) {
    throw;
  } catch (const Error& e) {
    return finish(forward, "mapping the generated " + shape + " onto the target failed: " + e.what());
  }
  const std::string runs = "through a generated " + shape + " (" + std::to_string(middle.num_vertices()) +
                           " vertices): source -> it " + four_digits(to_middle.energy_ratio) + ", it -> target " +
                           four_digits(from_middle.energy_ratio);
  std::string why;
  SurfaceMapOptions here = one_way_options(options);
  here.loops = options.loops;
  here.homotopy.given_class = composed_class(to_middle, from_middle, why);
  if (here.homotopy.given_class.empty()) return finish(forward, runs + "; no composed class: " + why);
  SurfaceMapResult through;
  try {
    through = map(source, target, here);
  } catch (const Cancelled&) {
    throw;
  } catch (const Error& e) {
    return finish(forward, runs + "; the composed class here failed: " + e.what());
  }
  const double before = forward.energy_ratio, after = through.energy_ratio;
  const bool better = through.chosen_candidate >= 0 && after < before * (1 - 1e-6);
  const std::string status = runs + "; the composed class here: energy ratio " + four_digits(after) + " against " +
                             four_digits(before) + (better ? ": used" : ": kept the first");
  if (!better) {
    // Listed (not solved to its optimum's map here, but its energy is):
    // the ranking's record of what was tried.
    if (through.chosen_candidate >= 0) forward.candidates.push_back(listed_candidate(through, shape));
    return finish(forward, status);
  }
  // The composed class wins: its map, with the earlier candidates listed
  // before it. The two-way run's comparison was of the class it replaces.
  std::vector<HomotopyCandidate> listed = std::move(forward.candidates);
  listed.push_back(listed_candidate(through, shape));
  const std::string two_way = forward.two_way_status;
  forward = std::move(through);
  forward.candidates = std::move(listed);
  forward.chosen_candidate = static_cast<int>(forward.candidates.size()) - 1;
  forward.two_way_status = two_way.empty() ? std::string() : two_way + " (for the class the through-shape step replaced)";
  forward.reverse_inverse = -1;
  forward.reverse_inverse_reason = "not compared: the class through the generated shape was adopted after the two-way run";
  forward.directions = SurfaceMapResult{}.directions;
  forward.directions.reason = forward.reverse_inverse_reason;
  finish(forward, status);
}

}  // namespace surfmap::detail
