// The through-shape step (issue 14; docs/handle_classes.md "Through generated shapes").
#include "through_shape.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <limits>
#include <string>
#include <utility>

#include "../seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/outer_automorphisms.h"

namespace surfmap::detail {

namespace {

/// The options of a run to or from the generated shape or of the composed
/// class here: no two-way run (the caller sets it back where wanted), no
/// through-shape step, no landmarks, no requested class, no solve-progress
/// callback.
SurfaceMapOptions one_way_options(const SurfaceMapOptions& options) {
  SurfaceMapOptions o = without_the_runs_own(options);
  o.homotopy.reverse_class.clear();
  o.homotopy.given_class.clear();
  o.homotopy.given_class_names.clear();
  return o;
}

/// The options of the legs source -> M (`onto`) and M -> target: the
/// source's cuts as given at one end, the target's at the other, the
/// two-way run as given (fertility -> the genus-4 n-hole torus one way ends
/// at 8.75 x, with the two-way run at 4.54 x, and the composed class is only
/// as good as that map).
SurfaceMapOptions leg_options(const SurfaceMapOptions& options, bool onto) {
  SurfaceMapOptions o = one_way_options(options);
  (onto ? o.loops.target_base_vertex : o.loops.source_base_vertex) = -1;
  o.homotopy.two_way = options.homotopy.two_way;
  // Not the agreement below the two-way ratio (session 23): a leg needs its
  // lowest class, not one its own other direction agrees on, and it would
  // map each leg's other direction and two single classes more per leg.
  o.homotopy.agreement_ratio = std::numeric_limits<double>::infinity();
  return o;
}

/// The composed classes' run's candidates as candidates of the first run.
/// The composed classes are named by the shape each came through where they
/// are made (HomotopyOptions::given_class_names); any other candidate of
/// that run (the snapped overlay's own class) is tagged here.
HomotopyCandidate listed_candidate(const HomotopyCandidate& given) {
  HomotopyCandidate c = given;
  if (c.given_class < 0) c.description += "  [through a generated shape]";
  return c;
}

/// Wall and process CPU seconds since a start: on a loaded machine the wall
/// time says little about the step's own cost, the CPU time does.
struct Clock {
  std::chrono::steady_clock::time_point wall = std::chrono::steady_clock::now();
  std::clock_t cpu = std::clock();
  std::string text() const {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.1f s, CPU %.1f s", seconds_since(wall),
                  static_cast<double>(std::clock() - cpu) / CLOCKS_PER_SEC);
    return buf;
  }
};

}  // namespace

// Cheapest first: the plate's few hundred vertices make its legs short runs.
// Why two: each is easy to reach from different shapes (fertility onto the
// n-hole torus at 4.54 x, onto the plate 10.59 x; a polycube's holes in a row
// onto the plate), and the composed classes are ranked like any candidates.
std::vector<MiddleShape> middle_shapes(int g, int resolution, std::string& notes) {
  std::vector<MiddleShape> out;
  auto add = [&](const std::string& name, auto&& generate) {
    try {
      out.push_back({name, generate()});
    } catch (const Cancelled&) {
      throw;
    } catch (const Error& e) {
      notes += "; generating the " + name + " failed: " + e.what();
    }
  };
  add("genus-" + std::to_string(g) + " CAD plate", [&] { return samples::cad_plate(g); });
  if (g <= 8)
    add("genus-" + std::to_string(g) + " n-hole torus", [&] { return samples::n_hole_torus(g, resolution); });
  else
    notes += "; no generated n-hole torus beyond genus 8";
  return out;
}

// A leg onto or from the source or target itself repeats the run the step
// tries to improve on (issue14_check's target is the generated genus-4
// plate itself).
bool same_shape(const TriMesh& a, const TriMesh& b) {
  if (a.num_vertices() != b.num_vertices() || a.num_faces() != b.num_faces() || a.num_vertices() == 0 || a.F != b.F)
    return false;
  const Eigen::RowVector3d ca = a.V.colwise().mean(), cb = b.V.colwise().mean();
  const double sa = (a.V.colwise().maxCoeff() - a.V.colwise().minCoeff()).norm();
  const double sb = (b.V.colwise().maxCoeff() - b.V.colwise().minCoeff()).norm();
  if (!(sa > 0) || !(sb > 0)) return false;
  const double far = ((a.V.rowwise() - ca) / sa - (b.V.rowwise() - cb) / sb).rowwise().norm().maxCoeff();
  return far <= 1e-6;
}

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

bool through_shape_reached(const SurfaceMapResult& forward, double one_way_ratio, double ratio, std::string& why) {
  why.clear();
  if (forward.energy_ratio >= ratio) return true;
  const SurfaceMapResult::DirectionCheck& d = forward.directions;
  const std::string below = "energy ratio below " + four_digits(ratio);
  if (d.outcome == "inverse" || d.outcome == "symmetric: both optimal") {
    // Agreed: the other direction's run ends on this class inverted, and
    // takes the step when that class's ratio there reaches `ratio`.
    if (d.inverse_there_ratio >= ratio) {
      why = below + " here, but this class inverted is at " + four_digits(d.inverse_there_ratio) +
            " in the other direction, whose own run takes the step";
      return true;
    }
    why = below + (std::isnan(d.inverse_there_ratio) ? std::string(" (this class inverted not solved there)")
                                                     : " in both directions (this class inverted: " +
                                                           four_digits(d.inverse_there_ratio) + " there)");
    return false;
  }
  // Not agreed: the other direction's run may end anywhere up to its one-way
  // ratio, so both runs read the larger of the two one-way ratios (each run
  // maps the other direction one way with the same options).
  double larger = std::numeric_limits<double>::quiet_NaN();
  for (double r : {one_way_ratio, d.other_one_way_ratio})
    if (std::isfinite(r) && !(r <= larger)) larger = r;
  auto ratio_or_unknown = [](double r) { return std::isfinite(r) ? four_digits(r) : std::string("unknown"); };
  const std::string both = "this direction " + ratio_or_unknown(one_way_ratio) + ", the other " +
                           ratio_or_unknown(d.other_one_way_ratio);
  if (larger >= ratio) {
    why = below + " here, the directions not agreed, and a one-way ratio at " + four_digits(ratio) + " or more (" +
          both + "), so the other direction's own run may take the step";
    return true;
  }
  // (The other direction not mapped: the status is the one-direction rule's.)
  why = below + (std::isfinite(d.other_one_way_ratio) ? " (one way: " + both + ")" : std::string());
  return false;
}

void through_shape_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                       SurfaceMapResult& forward, const MapFunction& map,
                       const std::vector<std::vector<int>>& target_letters_inverse, double one_way_ratio) {
  const HomotopyOptions& h = options.homotopy;
  if (forward.genus < 2 || h.class_index >= 0 || h.source_images.size() > 0 || h.reverse_class_only ||
      !h.given_class.empty())
    return;
  if (!h.through_shape) return void(forward.through_shape_status = "not run (off)");
  if (!options.landmarks.empty()) return void(forward.through_shape_status = "not run: landmarks are held");
  std::string reached;
  if (!through_shape_reached(forward, one_way_ratio, h.through_shape_ratio, reached))
    return void(forward.through_shape_status = "not run: " + reached);
  const int g = forward.genus;
  // At least 16 grid cells per handle in a row (genus <= 4), 64 for the
  // wheels beyond: at 32 cells the genus-4 n-hole torus (2.3k vertices)
  // mapped onto the genus-4 CAD plate at 11.8 x, at 48 (5.9k) at 1.04 x but
  // the fertility onto it at 8.75 x, at 64 (10k) at 4.54 x
  // (docs/handle_classes.md "Through generated shapes").
  const int resolution = std::max(h.through_shape_resolution, g <= 4 ? 16 * g : 64);
  // (Run from below the ratio: the status says why first.)
  std::string notes = reached.empty() ? std::string() : "; run for the other direction: " + reached;
  std::vector<MiddleShape> middles;
  for (MiddleShape& m : middle_shapes(g, resolution, notes)) {
    const bool is_target = same_shape(m.mesh, target);
    if (is_target || same_shape(m.mesh, source))
      notes += "; the " + m.name + " is the " + (is_target ? "target" : "source") + " itself: skipped";
    else
      middles.push_back(std::move(m));
  }
  through_shapes_map(source, target, options, forward, map, middles, true, notes, target_letters_inverse);
}

namespace {

/// `map(s, d, o)` into `out`: "" or the error's text (a cancel goes on).
std::string map_or_error(const MapFunction& map, const TriMesh& s, const TriMesh& d, const SurfaceMapOptions& o,
                         SurfaceMapResult& out) {
  try {
    out = map(s, d, o);
    return "";
  } catch (const Cancelled&) {
    throw;
  } catch (const Error& e) {
    return e.what();
  }
}

/// " and searched on: N moves, M solves" when a given-class run's twist
/// search ran, else "".
std::string searched_on(const SurfaceMapResult& r) {
  if (!r.homotopy_search.run) return "";
  return " and searched on: " + std::to_string(r.homotopy_search.moves.size()) + " moves, " +
         std::to_string(r.homotopy_search.evaluations) + " solves";
}

/// The end of a retried leg's status: `again` (its ratio said first,
/// after `what`) replaces `leg` when lower.
std::string keep_the_lower_leg(SurfaceMapResult& leg, SurfaceMapResult& again, const std::string& what,
                               const Clock& t, bool* used = nullptr) {
  const bool lower = again.chosen_candidate >= 0 && again.energy_ratio < leg.energy_ratio * (1 - 1e-6);
  const std::string status = what + four_digits(again.energy_ratio) + "; " + t.text() + (lower ? "): used" : "): kept");
  if (lower) leg = std::move(again);
  if (used) *used = lower;
  return status;
}

// A leg that cannot help, once more through this run's own class (session
// 20, docs/handle_classes.md): fertility -> genus-4 n-hole torus ends at
// 4.542 x, and its plate leg one way at 6.654 x, so the plate was never
// composed; yet this run's class composed with torus -> plate (1.036 x) and
// searched on from there reaches 2.803 x fertility -> plate (session 18), a
// class of the leg that its own search, moving by twists of the plate's
// own cut from its own candidates, does not reach.
std::string leg_through_the_first_run(const TriMesh& source, const TriMesh& target, const TriMesh& middle,
                                      const SurfaceMapOptions& options, const SurfaceMapResult& forward,
                                      const MapFunction& map, bool onto, SurfaceMapResult& leg) {
  const Clock t;
  const std::string head = "; the leg again through this run's class (";
  // The other end's own leg, in the other direction's cuts: target -> M
  // (whose source letters are the target's) or M -> source.
  SurfaceMapOptions other_way = reverse_options(options);
  other_way.homotopy.two_way = options.homotopy.two_way;
  SurfaceMapResult other_leg;
  const std::string failed = onto ? map_or_error(map, target, middle, leg_options(other_way, true), other_leg)
                                  : map_or_error(map, middle, source, leg_options(other_way, false), other_leg);
  if (!failed.empty()) return head + (onto ? "target -> it" : "it -> source") + " failed: " + failed + ")";
  const std::string status = head + (onto ? "target -> it " : "it -> source ") + four_digits(other_leg.energy_ratio);
  std::string why;
  std::vector<std::vector<int>> theta =
      onto ? composed_class(forward, other_leg, why) : composed_class(other_leg, forward, why);
  if (theta.empty()) return status + "; no composed class: " + why + ")";
  SurfaceMapOptions o = leg_options(options, onto);
  o.homotopy.two_way = false;
  o.homotopy.given_class = std::move(theta);
  o.homotopy.given_class_names = {std::string("through this run's class and the ") + (onto ? "target" : "source")};
  SurfaceMapResult again;
  const std::string again_failed =
      onto ? map_or_error(map, source, middle, o, again) : map_or_error(map, middle, target, o, again);
  if (!again_failed.empty()) return status + "; composed, failed: " + again_failed + ")";
  return status + keep_the_lower_leg(leg, again, ", composed" + searched_on(again) + ", ", t);
}

// A stalled M -> target leg, retried as the other direction retries its
// source -> M leg, so that both directions of a pair run the same searches
// (torus g4 -> fertility: plate -> fertility searched from this run's class
// composed with the source -> M leg ends at 6.029 x, the same class searched
// fertility -> plate at 2.803 x, inverted 3.108 x there, as session 19
// measured): this run's class inverted, composed with the source -> M leg
// (`to_middle`), is searched on target -> M, and the class found, inverted,
// is solved here alone (HomotopyOptions::reverse_class_only). Needs the
// target's letters as a source (`target_letters_inverse`) and this run's
// class inverted; without them, or when the inversion stalls, the leg
// M -> source composed with this run's class is searched on M -> target
// instead (leg_through_the_first_run). When the class brought back is
// used, `from_inverse` is the target -> M class it was inverted from (the
// leg's exact inverse, ComposedLegs::from_inverse), else left empty.
std::string leg_back_through_the_first_run(const TriMesh& source, const TriMesh& target, const TriMesh& middle,
                                           const SurfaceMapOptions& options, const SurfaceMapResult& forward,
                                           const SurfaceMapResult& to_middle,
                                           const std::vector<std::vector<int>>& target_letters_inverse,
                                           const MapFunction& map, SurfaceMapResult& from_middle,
                                           GroupMap& from_inverse) {
  const size_t n = static_cast<size_t>(2 * forward.genus);
  std::string why;
  if (target_letters_inverse.size() != n) why = "the target's letters as a source are missing";
  else if (forward.chosen_class_words.size() != n || forward.source_as_target_inverse.size() != n)
    why = "this run's class words or letters are missing";
  else if (to_middle.chosen_class_words.size() != n || to_middle.source_as_target_inverse.size() != n)
    why = "the source -> it leg's class words or letters are missing";
  AutomorphismInverse inv;
  if (why.empty()) {
    // (The form of composed_classes_both_ways: θ from the source's letters
    // as a target to the target's as a source, inverted: θ^-1 in a target ->
    // source run's letters.)
    inv = invert_automorphism(
        compose(target_letters_inverse, compose(forward.chosen_class_words, forward.source_as_target_inverse)),
        forward.genus);
    if (!inv.ok) why = "this run's class not inverted: " + inv.why;
  }
  if (!why.empty())
    return "; the leg again (" + why + ")" +
           leg_through_the_first_run(source, target, middle, options, forward, map, false, from_middle);
  const Clock t;
  const std::string head = "; the leg again through this run's class inverted (";
  SurfaceMapOptions there = leg_options(reverse_options(options), true);  // target -> M
  there.homotopy.two_way = false;
  there.homotopy.given_class =
      compose(to_middle.chosen_class_words, compose(to_middle.source_as_target_inverse, inv.inverse));
  there.homotopy.given_class_names = {"through the source and this run's class inverted"};
  SurfaceMapResult back;
  const std::string back_failed = map_or_error(map, target, middle, there, back);
  if (!back_failed.empty()) return head + "target -> it failed: " + back_failed + ")";
  const std::string status =
      head + "target -> it, composed" + searched_on(back) + ", " + four_digits(back.energy_ratio);
  // The class found there, inverted, alone here (it -> target).
  const SurfaceMapOptions here =
      single_class_options(leg_options(options, false), reverse_class_here(from_middle, back, why), SingleClass::KeepTheRest);
  if (here.homotopy.reverse_class.empty()) return status + "; not brought back: " + why + ")";
  SurfaceMapResult again;
  const std::string again_failed = map_or_error(map, middle, target, here, again);
  if (!again_failed.empty()) return status + "; inverted here failed: " + again_failed + ")";
  bool used = false;
  const std::string kept = keep_the_lower_leg(from_middle, again, "; inverted here ", t, &used);
  if (used) from_inverse = back.chosen_class_words;
  return status + kept;
}

/// The through-shape step's pair rule (session 28, branch class29): a class
/// composed through a generated shape and lower here than the first run's
/// class θ0 replaced θ0 in `adopted`, and composed_classes_both_ways kept
/// the pair of inverse classes of total energy `new_pair` (E here + E' of
/// its inverse in the other direction; NaN when it compared none). θ0's pair
/// is E(θ0) + E'(θ0^-1), θ0^-1 solved alone in the other direction (target
/// -> source). When that total is not above
/// `new_pair`, `adopted` becomes `first` again (every candidate still
/// listed): a class lower in one direction and higher as a pair would leave
/// the two directions on different classes (thick CAD plate g2 -> joint,
/// session 28: 2.254 + 2.177 adopted over 2.29 + 1.921). When either total
/// is unknown the class lower here stays. Returns the status's tail.
std::string keep_the_lower_pair(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                SurfaceMapResult& first, double new_pair,
                                const std::vector<std::vector<int>>& target_letters_inverse, const MapFunction& map,
                                SurfaceMapResult& adopted) {
  const size_t n = static_cast<size_t>(2 * first.genus);
  if (!std::isfinite(new_pair)) return "";
  const std::string head = "; the first class's pair: ";
  if (target_letters_inverse.size() != n || first.chosen_class_words.size() != n ||
      first.source_as_target_inverse.size() != n)
    return head + "not compared (its words or letters are missing): kept the class lower here";
  const double bound = conformal_bound(first.genus);
  const double own = chosen_energy(first);
  const SurfaceMapOptions ao = single_class_options(
      one_way_options(reverse_options(options)),
      compose(target_letters_inverse, compose(first.chosen_class_words, first.source_as_target_inverse)),
      SingleClass::KeepTheRest);
  SurfaceMapResult inverted;
  const std::string failed = map_or_error(map, target, source, ao, inverted);
  if (!failed.empty())
    return head + "its inverse not solved in the other direction (" + failed + "): kept the class lower here";
  const double own_there = chosen_energy(inverted), first_pair = own + own_there;
  const std::string totals = four_digits(own / bound) + " + " + four_digits(own_there / bound) + " = " +
                             four_digits(first_pair / bound) + " against the adopted pair's " +
                             four_digits(new_pair / bound);
  if (!(first_pair <= new_pair)) return head + totals + ": the adopted pair is lower";
  first.candidates = std::move(adopted.candidates);  // (first's candidates lead the list, at their indices)
  const std::string reason = "the first class kept: its pair of inverse classes has the lower total (" + totals +
                             "; the class through the generated shape is lower here only)";
  first.directions.reason += (first.directions.reason.empty() ? "" : "; ") + reason;
  adopted = std::move(first);
  return head + totals + ": kept the first class (the class through the generated shape is lower here only)";
}

}  // namespace

void through_shapes_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                        SurfaceMapResult& forward, const MapFunction& map, const std::vector<MiddleShape>& middles,
                        bool stop_at_legs_that_cannot_help, std::string notes,
                        const std::vector<std::vector<int>>& target_letters_inverse) {
  const auto t0 = std::chrono::steady_clock::now();
  auto finish = [&](SurfaceMapResult& r, std::string status) {
    r.through_shape_status = std::move(status);
    r.through_shape_time_s = seconds_since(t0);
  };
  // Onto each generated shape in the source's cuts (as given), from it in
  // the target's: the letters of this run at both ends. Each with the
  // two-way run as given: fertility -> the genus-4 n-hole torus one way
  // ends at 8.75 x, with the two-way run at 4.54 x, and the composed class
  // is only as good as that map.
  const SurfaceMapOptions onto = leg_options(options, true), from = leg_options(options, false);
  const double first = forward.energy_ratio;
  std::vector<std::vector<std::vector<int>>> composed;
  std::vector<std::string> composed_through;
  std::vector<const TriMesh*> composed_middles;
  std::vector<ComposedLegs> composed_legs;
  for (const MiddleShape& m : middles) {
    const std::string it = m.name + " (" + std::to_string(m.mesh.num_vertices()) + " vertices)";
    // A leg at or above the first run's ratio cannot help: the composed
    // class is then about as far from conformal as that leg at least
    // (fertility -> the 48-cell n-hole torus 8.75 x, composed onto the
    // plate 10.16 x; through the 64-cell one 4.54 x and 5.14 x), so the
    // other leg and the class's solve are not run.
    SurfaceMapResult to_middle, from_middle;
    Clock t;
    try {
      to_middle = map(source, m.mesh, onto);
    } catch (const Cancelled&) {
      throw;
    } catch (const Error& e) {
      notes += "; mapping onto the " + it + " failed: " + e.what();
      continue;
    }
    std::string legs =
        "; through the " + it + ": source -> it " + four_digits(to_middle.energy_ratio) + " (" + t.text() + ")";
    if (stop_at_legs_that_cannot_help && !(to_middle.energy_ratio < first)) {
      legs += leg_through_the_first_run(source, target, m.mesh, options, forward, map, true, to_middle);
      if (!(to_middle.energy_ratio < first)) {
        notes += legs + ", not below " + four_digits(first) + ": cannot help";
        continue;
      }
    }
    t = Clock();
    try {
      from_middle = map(m.mesh, target, from);
    } catch (const Cancelled&) {
      throw;
    } catch (const Error& e) {
      notes += legs + "; mapping it onto the target failed: " + e.what();
      continue;
    }
    legs += ", it -> target " + four_digits(from_middle.energy_ratio) + " (" + t.text() + ")";
    GroupMap from_inverse;
    if (stop_at_legs_that_cannot_help && !(from_middle.energy_ratio < first)) {
      legs += leg_back_through_the_first_run(source, target, m.mesh, options, forward, to_middle,
                                             target_letters_inverse, map, from_middle, from_inverse);
      if (!(from_middle.energy_ratio < first)) {
        notes += legs + ", not below " + four_digits(first) + ": cannot help";
        continue;
      }
    }
    std::string why;
    std::vector<std::vector<int>> theta = composed_class(to_middle, from_middle, why);
    if (theta.empty()) {
      notes += legs + "; no composed class: " + why;
      continue;
    }
    notes += legs;
    composed.push_back(std::move(theta));
    composed_through.push_back(m.name);
    composed_middles.push_back(&m.mesh);
    composed_legs.push_back({to_middle.chosen_class_words, from_middle.chosen_class_words,
                             from_middle.source_as_target_inverse, std::move(from_inverse)});
  }
  const std::string runs = notes.empty() ? std::string("through no generated shape") : notes.substr(2);
  if (composed.empty()) return finish(forward, runs + "; no composed class to solve");
  // The composed classes ranked like any candidates (the coarse copy's
  // solves, the best at full resolution), no class search.
  SurfaceMapOptions here = one_way_options(options);
  here.loops = options.loops;
  // (The twist search runs on from the best of them, HomotopyOptions::
  // given_class: a composed class is as good as its two legs, not a local
  // minimum here; docs/handle_classes.md "Through generated shapes".)
  for (const std::vector<std::vector<int>>& theta : composed)
    here.homotopy.given_class.insert(here.homotopy.given_class.end(), theta.begin(), theta.end());
  for (const std::string& name : composed_through)
    here.homotopy.given_class_names.push_back("through a generated " + name);
  SurfaceMapResult through;
  const Clock ts;
  try {
    through = map(source, target, here);
  } catch (const Cancelled&) {
    throw;
  } catch (const Error& e) {
    return finish(forward, runs + "; the composed classes here failed: " + e.what());
  }
  const double before = forward.energy_ratio, after = through.energy_ratio;
  const bool better = through.chosen_candidate >= 0 && after < before * (1 - 1e-6);
  std::string chosen_through;
  if (through.chosen_candidate >= 0) {
    const int k = through.candidates[through.chosen_candidate].given_class;
    if (k >= 0) chosen_through = " (the class through the " + composed_through[k] + ")";
  }
  std::string searched;
  if (through.homotopy_search.run)
    searched = ", searched on from the best: " + std::to_string(through.homotopy_search.moves.size()) + " moves, " +
               std::to_string(through.homotopy_search.evaluations) + " solves (" + through.homotopy_search.stop_reason + ")";
  const std::string status = runs + "; the composed class" + (composed.size() > 1 ? "es" : "") + " here (" +
                             ts.text() + searched + "): energy ratio " + four_digits(after) + " against " +
                             four_digits(before) + chosen_through + (better ? ": used" : ": kept the first");
  // Every composed class is listed (the unchosen ones with their ranking
  // energies): the record of what was tried.
  std::vector<HomotopyCandidate> tried;
  for (const HomotopyCandidate& c : through.candidates) tried.push_back(listed_candidate(c));
  // Each direction's search from the composed classes can end in its own
  // local minimum (fertility -> genus-4 plate 2.803 x, plate -> fertility
  // 6.029 x, not inverse): searched in both directions, the pair of lower
  // total energy is kept (docs/handle_classes.md "Through generated shapes").
  // `pair_total`: the kept pair's total energy, NaN when the pairs were not compared.
  auto both_ways = [&](double* pair_total) -> std::string {
    if (!options.homotopy.two_way) return "";
    if (target_letters_inverse.empty())
      return "; both directions: not searched the other way (the other direction was not mapped, so its letters "
             "are missing)";
    return composed_classes_both_ways(source, target, options, composed, here.homotopy.given_class_names,
                                      target_letters_inverse, forward, map, composed_middles, composed_legs,
                                      pair_total);
  };
  if (!better) {
    for (HomotopyCandidate& c : tried) forward.candidates.push_back(std::move(c));
    const std::string agreed = both_ways(nullptr);
    return finish(forward, status + agreed);
  }
  // A composed class wins here: its map, with the earlier candidates listed
  // before the composed ones. The two-way run's comparison was of the class
  // it replaces. (`first_result`: that class's result, kept when its pair
  // of inverse classes has the lower total; below.)
  SurfaceMapResult first_result = forward;
  std::vector<HomotopyCandidate> listed = std::move(forward.candidates);
  const int chosen = static_cast<int>(listed.size()) + through.chosen_candidate;
  for (HomotopyCandidate& c : tried) listed.push_back(std::move(c));
  const std::string two_way = forward.two_way_status;
  const double other_one_way = forward.directions.other_one_way_ratio;
  forward = std::move(through);
  forward.candidates = std::move(listed);
  forward.chosen_candidate = chosen;
  forward.two_way_status = two_way.empty() ? std::string() : two_way + " (for the class the through-shape step replaced)";
  forward.reverse_inverse = -1;
  forward.reverse_inverse_reason = "not compared: the class through the generated shape was adopted after the two-way run";
  forward.directions = SurfaceMapResult{}.directions;
  forward.directions.reason = forward.reverse_inverse_reason;
  forward.directions.other_one_way_ratio = other_one_way;
  double new_pair = std::numeric_limits<double>::quiet_NaN();
  const std::string agreed = both_ways(&new_pair);
  finish(forward, status + agreed + keep_the_lower_pair(source, target, options, first_result, new_pair,
                                                         target_letters_inverse, map, forward));
}

namespace {

/// A composed class θ0 in the other direction's letters, ι_T^-1 ∘ θ0 ∘
/// ι_S^-1 = A ∘ B, inverted factor by factor (invert_product): B the source
/// -> M leg from the source's letters as a target (onto ∘ ι_S^-1), A the M
/// -> target leg into the target's letters as a source (ι_T^-1 ∘ from ∘
/// ι_M^-1), whose inverse is known when that leg was brought back from a
/// target -> M run (A^-1 is that run's class). The composite's long words
/// can stall where the legs' shorter ones invert (torus g4 -> fertility
/// through the plate, session 21). Letters: 2g words each.
AutomorphismInverse inverted_leg_by_leg(const ComposedLegs& l, const GroupMap& source_letters_inverse,
                                        const GroupMap& target_letters_inverse, int g) {
  const size_t n = static_cast<size_t>(2 * g);
  if (l.onto.size() != n || l.from.size() != n || l.middle_letters_inverse.size() != n) {
    AutomorphismInverse missing;
    missing.why = "a leg's words are missing";
    return missing;
  }
  return invert_product({compose(target_letters_inverse, compose(l.from, l.middle_letters_inverse)),
                         compose(l.onto, source_letters_inverse)},
                        g, {l.from_inverse.size() == n ? l.from_inverse : GroupMap{}, {}});
}

}  // namespace

std::string composed_classes_both_ways(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                       const std::vector<std::vector<std::vector<int>>>& composed,
                                       const std::vector<std::string>& names,
                                       const std::vector<std::vector<int>>& target_letters_inverse,
                                       SurfaceMapResult& forward, const MapFunction& map,
                                       const std::vector<const TriMesh*>& middles,
                                       const std::vector<ComposedLegs>& legs, double* kept_pair_total) {
  if (kept_pair_total) *kept_pair_total = std::numeric_limits<double>::quiet_NaN();
  const int g = forward.genus;
  const size_t n = static_cast<size_t>(2 * g);
  const std::string not_run = "; both directions: not searched the other way (";
  if (forward.chosen_class_words.size() != n) return not_run + "this direction's class words are missing)";
  if (forward.source_as_target_inverse.size() != n)
    return not_run + "this source's letters as a target are missing: " + forward.source_as_target_status + ")";
  if (target_letters_inverse.size() != n) return not_run + "the target's letters as a source are missing)";
  const Clock t;
  const double bound = conformal_bound(g);
  // The composed classes θ0 in the other direction (target -> source):
  // ι_T^-1 ∘ θ0 ∘ ι_S^-1 is θ0 from the source's letters as a target to
  // the target's letters as a source (the form of
  // HomotopyOptions::reverse_class), and its inverse is θ0^-1 in that
  // run's letters, the form of given_class.
  SurfaceMapOptions ro = one_way_options(reverse_options(options));
  std::string uninverted;
  int inverted_by_legs = 0, composed_the_other_way = 0;
  std::string uninverted_why;  // (why the first class composed the other way was not inverted)
  for (size_t k = 0; k < composed.size(); ++k) {
    const std::vector<std::vector<int>> there =
        compose(target_letters_inverse, compose(composed[k], forward.source_as_target_inverse));
    const std::string name = k < names.size() ? names[k] : std::string("a composed class");
    AutomorphismInverse inv = invert_automorphism(there, g);
    bool leg_by_leg = false;
    if (!inv.ok && k < legs.size()) {
      const AutomorphismInverse by_legs =
          inverted_leg_by_leg(legs[k], forward.source_as_target_inverse, target_letters_inverse, g);
      if (by_legs.ok) {
        inv = by_legs;
        leg_by_leg = true;
      } else {
        inv.why += "; leg by leg: " + by_legs.why;
      }
    }
    if (inv.ok) {
      ro.homotopy.given_class.insert(ro.homotopy.given_class.end(), inv.inverse.begin(), inv.inverse.end());
      ro.homotopy.given_class_names.push_back(name + (leg_by_leg ? ", inverted leg by leg" : ", inverted"));
      if (leg_by_leg) inverted_by_legs += 1;
      continue;
    }
    // Not inverted (the descent and the Nielsen reduction can stall on long
    // words: plate g4 -> fertility's composed class): the other direction's
    // own composed class through the same shape, from its two legs (target
    // -> M, M -> source), which its own step would compose, not invert.
    std::string leg_failure = inv.why;
    if (k < middles.size() && middles[k]) {
      // (The other direction's options, with the two-way run as given for its legs.)
      SurfaceMapOptions other_way = reverse_options(options);
      other_way.homotopy.two_way = options.homotopy.two_way;
      try {
        const SurfaceMapResult to_middle = map(target, *middles[k], leg_options(other_way, true));
        const SurfaceMapResult from_middle = map(*middles[k], source, leg_options(other_way, false));
        std::string why;
        const std::vector<std::vector<int>> other = composed_class(to_middle, from_middle, why);
        if (!other.empty()) {
          ro.homotopy.given_class.insert(ro.homotopy.given_class.end(), other.begin(), other.end());
          ro.homotopy.given_class_names.push_back(name + ", composed the other way (not inverted: " + inv.why + ")");
          if (composed_the_other_way++ == 0) uninverted_why = inv.why;
          continue;
        }
        leg_failure += "; composed the other way: " + why;
      } catch (const Cancelled&) {
        throw;
      } catch (const Error& e) {
        leg_failure += std::string("; its legs the other way failed: ") + e.what();
      }
    }
    uninverted += ", " + name + " not inverted: " + leg_failure;
  }
  if (ro.homotopy.given_class.empty()) return not_run + uninverted.substr(2) + ")";
  SurfaceMapResult back;
  try {
    back = map(target, source, ro);
  } catch (const Cancelled&) {
    throw;
  } catch (const Error& e) {
    return not_run + "the composed classes inverted failed there: " + e.what() + ")";
  }
  std::string why;
  const std::vector<std::vector<int>> psi = reverse_class_here(forward, back, why);  // ψ in this run's letters
  if (psi.empty()) return not_run + why + ")";
  const double own = chosen_energy(forward), other_there = chosen_energy(back);
  std::string status = "; both directions: the composed class" + std::string(composed.size() > 1 ? "es" : "") +
                       " inverted" + (inverted_by_legs > 0 ? std::string(" (") + std::to_string(inverted_by_legs) +
                       " leg by leg)" : std::string()) +
                       (composed_the_other_way > 0 ? std::string(" or composed the other way (") +
                       std::to_string(composed_the_other_way) + ": " + uninverted_why + ")" : std::string()) +
                       ", searched on in the other direction, ratio " + four_digits(other_there / bound);
  if (back.homotopy_search.run)
    status += " (" + std::to_string(back.homotopy_search.moves.size()) + " moves, " +
              std::to_string(back.homotopy_search.evaluations) + " solves)";
  SurfaceMapResult::DirectionCheck& d = forward.directions;
  const OppositeClasses relation = compare_opposite_classes(psi, forward.chosen_class_words, g);
  if (relation.inner.inner || relation.up_to_hyperelliptic) {
    d.outcome = relation.inner.inner ? "inverse" : "symmetric: both optimal";
    d.reason = "the other direction's search from the composed classes inverted ends on this class inverted" +
               std::string(relation.inner.inner ? "" : " up to the hyperelliptic involution") + " (exact)";
    d.inverse_there_ratio = other_there / bound;
    if (kept_pair_total) *kept_pair_total = own + other_there;
    return status + ": this class inverted (" + t.text() + ")";
  }
  // θ^-1 there alone, ψ^-1 here alone: the four energies of the two pairs.
  // (θ in the other direction's letters.)
  const SurfaceMapOptions ao = single_class_options(one_way_options(reverse_options(options)),
                                                    reverse_class_here(back, forward, why), SingleClass::KeepTheRest);
  // A class the inversion cannot invert (the descent and the Nielsen
  // reduction are heuristics, and depend on the words: plate g4 ->
  // fertility's class stalls where fertility -> plate's same class, from
  // other words, inverts) leaves its pair's total unknown: that pair cannot
  // be kept, since its other half could not be mapped.
  SurfaceMapResult alone_there, alone_here;
  const SurfaceMapOptions ho = single_class_options(one_way_options(options), psi, SingleClass::KeepTheRest);
  auto solve_alone = [&](const TriMesh& s, const TriMesh& d, const SurfaceMapOptions& so, SurfaceMapResult& r,
                         const std::string& which) -> std::string {
    const std::string failed = map_or_error(map, s, d, so, r);
    return failed.empty() ? failed : "; " + which + " not solved (" + failed + ")";
  };
  const std::string there_failed = solve_alone(target, source, ao, alone_there, "this class inverted there");
  const std::string here_failed = solve_alone(source, target, ho, alone_here, "the other direction's class inverted here");
  status += there_failed + here_failed;
  if (!there_failed.empty() && !here_failed.empty()) return status + ": not compared (" + t.text() + ")";
  const double inf = std::numeric_limits<double>::infinity();
  const double own_there = there_failed.empty() ? chosen_energy(alone_there) : inf;
  const double other_here = here_failed.empty() ? chosen_energy(alone_here) : inf;
  const double own_pair = own + own_there, other_pair = other_here + other_there;
  const std::string pairs = "pair totals (ratio here + ratio there): this class " + four_digits(own / bound) + " + " +
                            four_digits(own_there / bound) + " = " + four_digits(own_pair / bound) +
                            ", the other direction's " + four_digits(other_here / bound) + " + " +
                            four_digits(other_there / bound) + " = " + four_digits(other_pair / bound);
  // This class kept: the other direction's class inverted is listed after it.
  auto list_the_other_class = [&] {
    if (alone_here.candidates.empty()) return;
    HomotopyCandidate c = alone_here.candidates[0];
    c.description += "  [the other direction's search from the composed class, inverted]";
    forward.candidates.push_back(std::move(c));
  };
  // This class's pair unknown (its inverse not solved there) is no reason to
  // take a class that is higher here (session 20: torus g4 -> fertility
  // through the retried plate leg, 2.882 x here, its inverse not solvable
  // there, the other pair 6.153 + 6.18): this class is kept, the directions
  // not compared.
  if (!(own_there < inf) && !(other_here < own)) {
    list_the_other_class();
    d.outcome = SurfaceMapResult{}.directions.outcome;
    d.reason = "not compared: this class inverted was not solved in the other direction, and the other direction's "
               "class inverted is not lower here (" + pairs + ")";
    return status + "; " + pairs + ": kept this class, not lower here (" + t.text() + ")";
  }
  // (A tie keeps this class: the other direction's run then keeps its own,
  // each the other's inverse only when the classes are; ties of real
  // energies to 1e-9 are not expected.)
  if (!(other_pair < own_pair)) {
    list_the_other_class();
    if (kept_pair_total) *kept_pair_total = own_pair;
    d.outcome = "inverse";
    d.inverse_there_ratio = own_there / bound;
    d.reason = "inverse by agreement: the pair of inverse classes with the lower total energy is this one (" + pairs +
               ")";
    return status + "; " + pairs + ": kept this class (" + t.text() + ")";
  }
  std::vector<HomotopyCandidate> listed = std::move(forward.candidates);
  for (HomotopyCandidate c : alone_here.candidates) {
    c.description += "  [the other direction's search from the composed class, inverted]";
    listed.push_back(std::move(c));
  }
  const int chosen = static_cast<int>(listed.size()) - static_cast<int>(alone_here.candidates.size()) +
                     alone_here.chosen_candidate;
  const std::string two_way = forward.two_way_status;
  const double two_way_time = forward.two_way_time_s;
  const double other_one_way = forward.directions.other_one_way_ratio;
  forward = std::move(alone_here);
  forward.candidates = std::move(listed);
  forward.chosen_candidate = chosen;
  forward.two_way_status = two_way;
  forward.two_way_time_s = two_way_time;
  forward.reverse_inverse = -1;
  forward.reverse_inverse_reason = "not compared by carried loops: the class is the other direction's, inverted";
  forward.directions.outcome = "inverse";
  forward.directions.other_one_way_ratio = other_one_way;
  forward.directions.inverse_there_ratio = other_there / bound;
  forward.directions.reason = "inverse by agreement: the pair of inverse classes with the lower total energy is the "
                              "other direction's search from the composed classes (" + pairs + ")";
  if (kept_pair_total) *kept_pair_total = other_pair;
  return status + "; " + pairs + ": used the other direction's class inverted (" + t.text() + ")";
}

}  // namespace surfmap::detail
