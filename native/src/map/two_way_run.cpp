// The quality signal and the two-way run (docs/handle_classes.md, issue 14).
#include "two_way_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

#include "../seconds_since.h"
#include "surfmap/error.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/outer_automorphisms.h"

namespace surfmap::detail {

std::string four_digits(double x) {
  char s[32];
  std::snprintf(s, sizeof s, "%.4g", x);
  return s;
}

namespace {

/// SurfaceMapResult::reverse_check: whether the chosen class is (or ties
/// with) one from the other direction.
std::string symmetry_check(const SurfaceMapResult& r) {
  const std::vector<int>& rc = r.reverse_candidates;
  const int chosen = r.chosen_candidate;
  const int n = static_cast<int>(r.candidates.size());
  if (std::find(rc.begin(), rc.end(), chosen) != rc.end())
    return "the chosen class is the one carried by the target -> source map (candidate " + std::to_string(chosen) + ")";
  const double e = r.candidates[chosen].energy;
  if (std::any_of(rc.begin(), rc.end(), [&](int k) { return k < n && std::abs(r.candidates[k].energy - e) <= 1e-4 * e; }))
    return "the chosen class ties with the one carried by the target -> source map (the same energy to 1e-4: the same "
           "class up to a symmetry of the shapes)";
  if (!rc.empty()) {
    std::string s = "the chosen class is not the one carried by the target -> source map (candidates";
    for (int k : rc) s += " " + std::to_string(k);
    return s + "), which has higher energy";
  }
  if (!r.reverse_status.empty()) return "no class from the other direction to compare with (" + r.reverse_status + ")";
  return "";
}

/// Per source vertex, where `reverse` (a target -> source map) puts it: its
/// inverse correspondence, #V_source x 3.
Eigen::MatrixXd inverse_positions(const SurfaceMapResult& reverse) {
  Eigen::MatrixXd images(static_cast<Eigen::Index>(reverse.inverse.size()), 3);
  for (size_t v = 0; v < reverse.inverse.size(); ++v) images.row(static_cast<Eigen::Index>(v)) = reverse.inverse[v].position.transpose();
  return images;
}

/// map(a, b, o) into `result`; false, with the error's text in `failure`,
/// when that run fails. A cancellation is passed on, not read as a failed
/// direction (Cancelled is an Error).
bool run_map(const MapFunction& map, const TriMesh& a, const TriMesh& b, const SurfaceMapOptions& o,
             SurfaceMapResult& result, std::string& failure) {
  try {
    result = map(a, b, o);
    return true;
  } catch (const Cancelled&) {
    throw;
  } catch (const Error& e) {
    failure = e.what();
    return false;
  }
}

/// In a run given the other direction's class (reverse_class and/or the
/// source_images of its map's inverse): that class inverted as a candidate
/// of this run, algebraically (directions.inverted_candidate) or else
/// carried by the other map (reverse_candidates), its energy (ranked:
/// full-resolution or coarse estimate; infinite when not ranked) and
/// whether this run chose it (or an isometric class).
struct OtherClassHere {
  int index = -1;
  double energy = std::numeric_limits<double>::infinity();
  bool chosen = false;
  std::string how;
};

OtherClassHere other_class_here(const SurfaceMapResult& r) {
  OtherClassHere o;
  const SurfaceMapResult::DirectionCheck& d = r.directions;
  const bool isometric = d.outcome == "inverse" || d.outcome == "symmetric: both optimal";
  if (d.inverted_candidate >= 0 && d.inverted_candidate < static_cast<int>(r.candidates.size())) {
    o.index = d.inverted_candidate;
    o.how = "inverted algebraically";
    o.chosen = isometric;
  } else if (!r.reverse_candidates.empty() && r.reverse_candidates[0] < static_cast<int>(r.candidates.size())) {
    o.index = r.reverse_candidates[0];
    o.how = "carried by the other direction's map";
    o.chosen = isometric || r.reverse_inverse == 1;
  } else {
    o.how = "not listed (" + (d.reason.empty() ? r.reverse_status : d.reason) + ")";
    o.chosen = isometric;
    return o;
  }
  o.energy = o.index == r.chosen_candidate ? chosen_energy(r) : r.candidates[o.index].energy;
  if (!std::isfinite(o.energy)) o.energy = std::numeric_limits<double>::infinity();
  return o;
}

/// Issue 14, both directions agree (docs/handle_classes.md "The two directions today"): `forward`
/// (mapped with `fo`, given the other direction's class
/// ψ from `reverse`) chose θ, not ψ^-1, and θ, ψ^-1 are not isometric
/// ("different"). The other direction is mapped again given θ (its words
/// as reverse_class, and the source_images of `forward`'s inverse, so θ^-1
/// is listed there algebraically or carried when the inversion stalls) and
/// ranks it. When it then chooses θ^-1, the two directions agree.
/// Otherwise each direction prefers its own class, and the pair of inverse
/// classes with the lower total energy, E(θ) + E'(θ^-1) against
/// E(ψ^-1) + E'(ψ) (the same figures from either direction, so separate
/// runs of S -> T and T -> S pick the same pair), is kept in both:
/// `forward` is mapped again in ψ^-1 (requested class) when that pair is
/// lower. Returns a status for two_way_status; `forward.directions` says
/// "inverse" when they agree.
std::string agree_directions(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& fo,
                             const SurfaceMapResult& reverse, SurfaceMapResult& forward, const MapFunction& map) {
  std::string why;
  SurfaceMapOptions ro = reverse_options(fo);
  ro.homotopy.reverse_class = reverse_class_here(reverse, forward, why);  // θ in the other direction's letters
  if (static_cast<int>(forward.inverse.size()) == target.num_vertices())
    ro.homotopy.source_images = inverse_positions(forward);  // θ^-1 carried, when the inversion stalls
  if (ro.homotopy.reverse_class.empty() && ro.homotopy.source_images.size() == 0)
    return "directions not agreed: " + why;
  SurfaceMapResult back;
  std::string back_failure;
  if (!run_map(map, target, source, ro, back, back_failure)) {
    return std::string("directions not agreed: the other direction given this class failed: ") + back_failure;
  }
  const double bound = conformal_bound(forward.genus);
  const OtherClassHere there = other_class_here(back), here = other_class_here(forward);
  const std::string there_text = "the other direction, given this class (" + there.how +
                                 (there.index >= 0 ? ", ratio " + four_digits(there.energy / bound) : std::string()) +
                                 "), chose " + (there.chosen ? std::string("it") : std::string("its own (ratio ") +
                                 four_digits(chosen_energy(back) / bound) + ")");
  SurfaceMapResult::DirectionCheck& d = forward.directions;
  // (θ^-1's ratio there, for the through-shape step; infinite when not listed there.)
  const double there_ratio = std::isfinite(there.energy) ? there.energy / bound : std::numeric_limits<double>::quiet_NaN();
  if (there.chosen) {
    d.outcome = back.directions.outcome == "symmetric: both optimal" ? back.directions.outcome : "inverse";
    d.inverse_there_ratio = there_ratio;
    d.reason = "this direction chose its own class (ratio " + four_digits(chosen_energy(forward) / bound) +
               ") over the other direction's inverted (" + here.how +
               (here.index >= 0 ? ", ratio " + four_digits(here.energy / bound) : std::string()) + "); " + there_text +
               (back.directions.reason.empty() ? std::string() : ": " + back.directions.reason);
    return "directions agreed: " + there_text;
  }
  if (there.index < 0) return "directions not agreed: " + there_text;
  if (back.chosen_class_words != reverse.chosen_class_words)
    return "directions not agreed: " + there_text + ", a third class";
  // Both prefer their own class: the pair of lower total energy, in both.
  const double own_pair = chosen_energy(forward) + there.energy;
  const double other_pair = here.energy + chosen_energy(back);
  const std::string pairs = "pair totals (ratio here + ratio there): this class " + four_digits(own_pair / bound) +
                            ", the other direction's " + four_digits(other_pair / bound);
  if (!std::isfinite(own_pair) && !std::isfinite(other_pair))
    return "directions not agreed: neither pair's energies are known (" + there_text + "; here " + here.how + ")";
  if (!(other_pair < own_pair)) {
    d.outcome = "inverse";
    d.inverse_there_ratio = there_ratio;
    d.reason = "inverse by agreement: each direction alone prefers its own class; the pair of inverse classes "
               "with the lower total energy is this one (" + pairs + "), which the other direction, given this "
               "class, takes by the same rule (" + there_text + ")";
    return "directions agreed on this class: " + pairs;
  }
  SurfaceMapOptions requested = fo;
  requested.homotopy.class_index = here.index;
  SurfaceMapResult again;
  std::string again_failure;
  if (!run_map(map, source, target, requested, again, again_failure)) {
    return "directions not agreed: mapping again in the other direction's class inverted failed: " + again_failure;
  }
  // (Inverted algebraically, the run's own comparison finds the composite
  // inner; carried, the carried-class check compares homology and probe
  // lengths.)
  const bool inverse = again.directions.outcome == "inverse" || again.reverse_inverse == 1;
  if (inverse) {
    again.directions.outcome = "inverse";
    again.directions.inverse_there_ratio = chosen_energy(back) / bound;
  }
  again.directions.reason = std::string(inverse ? "inverse by agreement" : "not confirmed inverse") +
                            ": the pair of inverse classes with the lower total energy is the other direction's (" +
                            pairs + "), so this direction takes that class inverted (candidate " +
                            std::to_string(here.index) + ", " + here.how + ")" +
                            (again.directions.reason.empty() ? std::string() : "; " + again.directions.reason);
  forward = std::move(again);
  return "directions agreed on the other direction's class: " + pairs;
}

/// Issue 14, cheap direction check (below), when θ^-1 (this run's class
/// inverted) beats the other direction's one-way class there: the other
/// direction mapped given θ (reverse_class and this map's inverse as its
/// source_images) with its candidates and class search, as its own run
/// does. When it ends on a class ψ' of lower energy there than θ^-1
/// (`alt_there`), ψ'^-1 is solved here alone, and when E(ψ'^-1) + E'(ψ') is
/// below E(θ) + E'(θ^-1) (`own` + `alt_there`) this run adopts ψ'^-1.
/// Returns a two_way_status when it adopted (forward replaced), else ""
/// (with `there_text` extended by what the search found).
std::string search_from_this_class_there(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                         const SurfaceMapResult& reverse, SurfaceMapResult& forward,
                                         const MapFunction& map, double own, double alt_there,
                                         std::string& there_text) {
  std::string why;
  SurfaceMapOptions so = reverse_options(options);
  so.homotopy.compare_directions = false;
  so.homotopy.reverse_class = reverse_class_here(reverse, forward, why);  // θ in the other direction's letters
  if (static_cast<int>(forward.inverse.size()) == target.num_vertices())
    so.homotopy.source_images = inverse_positions(forward);
  if (so.homotopy.reverse_class.empty()) return "";
  const double bound = conformal_bound(forward.genus);
  SurfaceMapResult back;
  std::string back_failure;
  if (!run_map(map, target, source, so, back, back_failure)) {
    there_text += "; searched on from it there: failed (" + back_failure + ")";
    return "";
  }
  const double back_energy = chosen_energy(back);
  if (other_class_here(back).chosen || !(back_energy < alt_there * (1 - 1e-6))) {
    there_text += "; searched on from it there: kept it";
    return "";
  }
  there_text += "; searched on from it there: another class, ratio " + four_digits(back_energy / bound);
  // ψ' in this run's letters
  const SurfaceMapOptions fo =
      single_class_options(options, reverse_class_here(forward, back, why), SingleClass::KeepTheRest);
  if (fo.homotopy.reverse_class.empty()) {
    there_text += " (not written in this run's letters: " + why + ")";
    return "";
  }
  SurfaceMapResult here;
  std::string here_failure;
  if (!run_map(map, source, target, fo, here, here_failure)) {
    there_text += " (its inverse not solved here: " + here_failure + ")";
    return "";
  }
  const double alt_here = chosen_energy(here);
  const double own_pair = own + alt_there, other_pair = alt_here + back_energy;
  const std::string pairs = "pair totals (ratio here + ratio there): this class " + four_digits(own_pair / bound) +
                            ", the class searched from it there " + four_digits(other_pair / bound);
  if (!(other_pair < own_pair)) {
    there_text += " (" + pairs + ")";
    return "";
  }
  const std::string kept_reason = here.directions.reason;
  forward = std::move(here);
  forward.directions.outcome = "inverse";
  forward.directions.inverse_there_ratio = back_energy / bound;
  forward.directions.reason = "inverse by agreement: the other direction, given this run's first class (" +
                              there_text + "), searches on to another class; its inverse here, ratio " +
                              four_digits(alt_here / bound) + ", and it make the pair of lower total energy (" + pairs +
                              ")" + (kept_reason.empty() ? std::string() : "; " + kept_reason);
  return "directions agreed on the class the other direction searched from this one: " + pairs;
}

/// Issue 14 (docs/handle_classes.md "The two directions today"): the
/// two-way run found the other direction (class ψ, in `reverse`) no better
/// by its ratio, which says nothing about ψ^-1 here (the harmonic energy is
/// not symmetric). So, unless θ (this run's class) and ψ are already
/// inverse: ψ^-1 is solved here alone (homotopy.reverse_class_only: one
/// class, no search) and adopted when its energy is lower; else θ^-1 is
/// solved alone the other way, and when it is lower there than ψ, the
/// other direction's run adopts θ^-1 by the same rule (agreement); else
/// each prefers its own, and the pair of inverse classes of lower total
/// energy, E(θ) + E'(θ^-1) against E(ψ^-1) + E'(ψ), is kept (the rule of
/// agree_directions). Two single-class runs instead of the three whole runs
/// of the comparison. Returns a status for two_way_status.
std::string cheap_direction_check(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                  const SurfaceMapResult& reverse, SurfaceMapResult& forward, const MapFunction& map) {
  std::string why;
  const std::vector<std::vector<int>> psi = reverse_class_here(forward, reverse, why);
  SurfaceMapResult::DirectionCheck& d = forward.directions;
  if (psi.empty()) return "directions not compared: " + why;
  const int g = forward.genus;
  const OppositeClasses relation = compare_opposite_classes(psi, forward.chosen_class_words, g);
  if (relation.inner.inner) {
    d.outcome = "inverse";
    d.inverse_there_ratio = reverse.energy_ratio;
    d.reason = "the two directions chose inverse classes (the composite is inner; exact, Dehn's algorithm)";
    return "directions inverse";
  }
  if (relation.up_to_hyperelliptic) {
    d.outcome = "symmetric: both optimal";
    d.inverse_there_ratio = reverse.energy_ratio;  // (the twins' energies tie)
    d.reason = "inverse up to the hyperelliptic involution (exact), an isometry of every genus-2 surface";
    return "directions inverse up to the hyperelliptic involution";
  }
  const double bound = conformal_bound(g);
  const double own = chosen_energy(forward), own_there = chosen_energy(reverse);
  const SurfaceMapOptions fo = single_class_options(options, psi, SingleClass::KeepTheRest);
  SurfaceMapResult here;
  std::string here_failure;
  if (!run_map(map, source, target, fo, here, here_failure)) {
    d.reason = std::string("not compared: the other direction's class inverted could not be solved here: ") + here_failure;
    return "directions not compared: the other direction's class inverted not solved here (" + here_failure + ")";
  }
  const double alt = chosen_energy(here);
  const std::string here_text = "the other direction's class inverted here: ratio " + four_digits(alt / bound) +
                                " against this class's " + four_digits(own / bound);
  auto adopt = [&](const std::string& why_adopted) {
    const std::string kept_reason = here.directions.reason;
    forward = std::move(here);
    forward.directions.outcome = "inverse";
    forward.directions.inverse_there_ratio = own_there / bound;  // (ψ, the other direction's own class)
    forward.directions.reason = why_adopted + (kept_reason.empty() ? std::string() : "; " + kept_reason);
  };
  if (alt < own) {
    adopt("adopted the other direction's class inverted (" + here_text + ")");
    return "directions agreed: adopted the other direction's class inverted (" + here_text + ")";
  }
  // Vice versa: θ^-1 solved alone the other way.
  const SurfaceMapOptions ro =
      single_class_options(reverse_options(options), reverse_class_here(reverse, forward, why), SingleClass::KeepTheRest);
  double alt_there = std::numeric_limits<double>::infinity();
  std::string there_text;
  if (ro.homotopy.reverse_class.empty()) {
    there_text = "this class not written in the other direction's letters (" + why + ")";
  } else {
    SurfaceMapResult there;
    std::string there_failure;
    if (run_map(map, target, source, ro, there, there_failure)) {
      alt_there = chosen_energy(there);
      there_text = "this class inverted there: ratio " + four_digits(alt_there / bound) + " against its own " +
                   four_digits(own_there / bound);
    } else {
      there_text = "this class inverted could not be solved there: " + there_failure;
    }
  }
  if (alt_there < own_there) {
    // θ^-1 beats the other direction's one-way class there, so that direction's own run
    // (two_way_map: this direction's ratio is the lower one) carries this map and searches
    // on from θ^-1. Predict it: map the other way given θ (its words, and this map's
    // inverse as the carried loops), with its candidates and search; when that ends on
    // another class ψ' below θ^-1 there, ψ'^-1 is solved here alone and the pair of inverse
    // classes of lower total energy is kept, the pair the other direction's run ends on
    // (fertility -> genus-4 plate: θ 10.59 with θ^-1 14.3 there, against ψ'^-1 6.65 with
    // ψ' 7.65; before, separate runs of the two directions ended on these two different
    // pairs; docs/history/handle_classes.md "The issue-14 check, every pair").
    const std::string searched = search_from_this_class_there(source, target, options, reverse, forward, map,
                                                              own, alt_there, there_text);
    if (!searched.empty()) return searched;
    d.outcome = "inverse";
    d.inverse_there_ratio = alt_there / bound;
    d.reason = "inverse by agreement: the other direction takes this class inverted (" + there_text + "; " + here_text + ")";
    return "directions agreed: the other direction takes this class inverted (" + there_text + ")";
  }
  if (!std::isfinite(alt_there)) {
    d.outcome = "different";
    d.reason = "each direction keeps its own class: " + here_text + "; " + there_text;
    return "directions not agreed: " + there_text;
  }
  const double own_pair = own + alt_there, other_pair = alt + own_there;
  const std::string pairs = "pair totals (ratio here + ratio there): this class " + four_digits(own_pair / bound) +
                            ", the other direction's " + four_digits(other_pair / bound);
  if (other_pair < own_pair) {
    adopt("inverse by agreement: each direction alone prefers its own class; the pair of inverse classes with the "
          "lower total energy is the other direction's (" + pairs + ")");
    return "directions agreed on the other direction's class: " + pairs;
  }
  d.outcome = "inverse";
  d.inverse_there_ratio = alt_there / bound;
  d.reason = "inverse by agreement: each direction alone prefers its own class; the pair of inverse classes with the "
             "lower total energy is this one (" + pairs + ")";
  return "directions agreed on this class: " + pairs;
}

/// A fixed order of two meshes that does not depend on which one is the
/// source: -1 when `a` comes first, 1 when `b` does, 0 when they are the
/// same mesh (vertex count, face count, then the coordinates and the faces
/// in storage order).
int mesh_order(const TriMesh& a, const TriMesh& b) {
  if (a.num_vertices() != b.num_vertices()) return a.num_vertices() < b.num_vertices() ? -1 : 1;
  if (a.num_faces() != b.num_faces()) return a.num_faces() < b.num_faces() ? -1 : 1;
  const double *va = a.V.data(), *vb = b.V.data();
  for (Eigen::Index k = 0; k < a.V.size(); ++k)
    if (va[k] != vb[k]) return va[k] < vb[k] ? -1 : 1;
  const int *fa = a.F.data(), *fb = b.F.data();
  for (Eigen::Index k = 0; k < a.F.size(); ++k)
    if (fa[k] != fb[k]) return fa[k] < fb[k] ? -1 : 1;
  return 0;
}

/// A single-class run's energy for the pair totals: infinite when it failed,
/// did not converge or folds (the same rule for all four classes, so both
/// directions' runs read the same totals).
double usable_energy(const SurfaceMapResult& r) {
  const double e = chosen_energy(r);
  return r.converged && r.flipped_triangles == 0 && std::isfinite(e) ? e : std::numeric_limits<double>::infinity();
}

/// Issue 14 below the two-way run (HomotopyOptions::agreement_ratio;
/// docs/handle_classes.md "The two directions today"): `forward` (class θ) is at
/// agreement_ratio or more but below two_way_ratio. The other direction is
/// mapped one way (class ψ: the first run of that direction's own run, the
/// same options); unless θ and ψ are inverse (exact; genus 2 also up to the
/// hyperelliptic involution), ψ^-1 is solved here alone and θ^-1 there
/// alone (reverse_class_only), and the pair of inverse classes of lower
/// total energy, E(θ) + E'(θ^-1) against E(ψ^-1) + E'(ψ), is kept: the same
/// four solves, so the same figures, from either direction's run. Ties
/// (within 1e-6) go to the class chosen from the mesh first in mesh_order.
/// When the other direction is itself below agreement_ratio its own run
/// keeps ψ, so this run takes ψ^-1 when that maps below two_way_ratio here
/// even when θ's pair is lower (else it keeps θ and says "different").
/// Returns the status (directions.agreement; two_way_status adds it).
std::string agree_below_two_way_ratio(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                      SurfaceMapResult& forward, const MapFunction& map,
                                      std::vector<std::vector<int>>* target_letters_inverse) {
  SurfaceMapResult::DirectionCheck& d = forward.directions;
  const int g = forward.genus;
  const double bound = conformal_bound(g);
  SurfaceMapResult reverse;
  std::string failure;
  if (!run_map(map, target, source, reverse_options(options), reverse, failure)) {
    d.reason = "not compared: the other direction failed: " + failure;
    return "not agreed: the other direction failed: " + failure;
  }
  if (target_letters_inverse) *target_letters_inverse = reverse.source_as_target_inverse;
  d.other_one_way_ratio = reverse.energy_ratio;
  const std::string other = "the other direction one way: ratio " + four_digits(reverse.energy_ratio);
  std::string why;
  const std::vector<std::vector<int>> psi = reverse_class_here(forward, reverse, why);
  if (psi.empty() || forward.chosen_class_words.empty()) {
    if (why.empty()) why = "this run reported no class words";
    d.reason = "not compared: " + why;
    return "not agreed (" + other + "): " + why;
  }
  const OppositeClasses relation = compare_opposite_classes(psi, forward.chosen_class_words, g);
  if (relation.inner.inner) {
    d.outcome = "inverse";
    d.inverse_there_ratio = reverse.energy_ratio;
    d.reason = "the two directions chose inverse classes (the composite is inner; exact, Dehn's algorithm)";
    return "inverse (" + other + "): nothing solved";
  }
  if (relation.up_to_hyperelliptic) {
    d.outcome = "symmetric: both optimal";
    d.inverse_there_ratio = reverse.energy_ratio;
    d.reason = "inverse up to the hyperelliptic involution (exact), an isometry of every genus-2 surface";
    return "inverse up to the hyperelliptic involution (" + other + "): nothing solved";
  }
  // ψ^-1 here alone and θ^-1 there alone: one class each, no search.
  SurfaceMapResult here, there;
  std::string here_failure, there_failure;
  const bool here_ok = run_map(map, source, target, single_class_options(options, psi, SingleClass::Alone), here, here_failure);
  const std::vector<std::vector<int>> theta_there = reverse_class_here(reverse, forward, why);
  const bool there_ok = !theta_there.empty() &&
                        run_map(map, target, source, single_class_options(reverse_options(options), theta_there, SingleClass::Alone), there, there_failure);
  if (theta_there.empty()) there_failure = "this class not written in the other direction's letters (" + why + ")";
  const double inf = std::numeric_limits<double>::infinity();
  const double own = usable_energy(forward), own_there = usable_energy(reverse);
  const double alt_here = here_ok ? usable_energy(here) : inf, alt_there = there_ok ? usable_energy(there) : inf;
  const double own_pair = own + alt_there, other_pair = alt_here + own_there;
  d.own_pair_ratio = own_pair / bound;
  d.other_pair_ratio = other_pair / bound;
  auto ratio_text = [&](double e, bool ok, const std::string& fail) {
    return ok ? (std::isfinite(e) ? four_digits(e / bound) : std::string("not usable (not converged or folded)"))
              : "not solved (" + fail + ")";
  };
  const std::string figures = other + "; this class " + four_digits(own / bound) + " here, inverted there " +
                              ratio_text(alt_there, there_ok, there_failure) + "; the other direction's class " +
                              four_digits(own_there / bound) + " there, inverted here " +
                              ratio_text(alt_here, here_ok, here_failure) + "; pair totals " +
                              four_digits(own_pair / bound) + " (this class) and " + four_digits(other_pair / bound) +
                              " (the other direction's)";
  if (!std::isfinite(own_pair) && !std::isfinite(other_pair)) {
    d.outcome = "different";
    d.reason = "each direction keeps its own class: neither pair of inverse classes could be solved (" + figures + ")";
    return "not agreed: neither pair solved (" + figures + ")";
  }
  // Which pair: the lower total; a tie (pair_totals_tie) to the class chosen from the mesh that comes first.
  std::string rule;
  bool other_pair_kept;
  if (pair_totals_tie(own_pair, other_pair)) {
    const int order = mesh_order(source, target);
    other_pair_kept = order > 0;
    rule = std::string("a tie (within 1e-6), broken by the meshes' order: the class chosen from the ") +
           (order < 0 ? "source, which comes first" : order > 0 ? "target, which comes first" : "same mesh (this one)");
  } else {
    other_pair_kept = other_pair < own_pair;
    rule = "the pair of lower total energy";
  }
  // The other direction's own run below agreement_ratio does not run this step: it keeps ψ.
  const bool other_keeps_its_own = reverse.energy_ratio < options.homotopy.agreement_ratio;
  const bool adopt_anyway = !other_pair_kept && other_keeps_its_own && std::isfinite(alt_here) &&
                            alt_here / bound < options.homotopy.two_way_ratio;
  if (other_pair_kept || adopt_anyway) {
    if (adopt_anyway)
      rule = "the other direction is below the agreement ratio " + four_digits(options.homotopy.agreement_ratio) +
             ", so its own run keeps its class; its inverse maps here below " +
             four_digits(options.homotopy.two_way_ratio) + " (this pair's total is lower: " + rule + ")";
    const std::string kept_reason = here.directions.reason;
    const double own_ratio = d.own_pair_ratio, other_ratio = d.other_pair_ratio;
    forward = std::move(here);
    SurfaceMapResult::DirectionCheck& a = forward.directions;
    a.outcome = "inverse";
    a.reason = "inverse by agreement: kept the other direction's class inverted (" + rule + "; " + figures + ")" +
               (kept_reason.empty() ? std::string() : "; " + kept_reason);
    a.own_pair_ratio = own_ratio;
    a.other_pair_ratio = other_ratio;
    a.other_one_way_ratio = reverse.energy_ratio;
    a.inverse_there_ratio = own_there / bound;
    return "the other direction's class inverted (" + rule + "; " + figures + ")";
  }
  if (other_keeps_its_own) {
    d.outcome = "different";
    d.reason = "each direction keeps its own class: the other direction is below the agreement ratio " +
               four_digits(options.homotopy.agreement_ratio) + " (its own run keeps its class), and its class " +
               "inverted here is " + ratio_text(alt_here, here_ok, here_failure) + ", not below " +
               four_digits(options.homotopy.two_way_ratio) + " (" + figures + ")";
    return "not agreed: kept this class (" + figures + ")";
  }
  d.outcome = "inverse";
  d.inverse_there_ratio = alt_there / bound;
  d.reason = "inverse by agreement: kept this class (" + rule + "; " + figures + ")";
  return "this class (" + rule + "; " + figures + ")";
}

}  // namespace

std::vector<std::vector<int>> reverse_class_here(const SurfaceMapResult& forward, const SurfaceMapResult& reverse,
                                                 std::string& why) {
  if (reverse.chosen_class_words.empty()) why = "the other direction reported no class words";
  else if (forward.source_as_target_inverse.empty())
    why = "this source's letters as a target are missing (" + forward.source_as_target_status + ")";
  else if (reverse.source_as_target_inverse.empty())
    why = "the target's letters as a source are missing (" + reverse.source_as_target_status + ")";
  if (!why.empty()) return {};
  return compose(forward.source_as_target_inverse, compose(reverse.chosen_class_words, reverse.source_as_target_inverse));
}

bool pair_totals_tie(double own_pair, double other_pair) {
  return std::isfinite(own_pair) && std::isfinite(other_pair) &&
         std::abs(own_pair - other_pair) <= 1e-6 * std::max(own_pair, other_pair);
}

double chosen_energy(const SurfaceMapResult& r) {
  if (std::isfinite(r.intrinsic_class_energy)) return r.intrinsic_class_energy;
  const int c = r.chosen_candidate;
  return c >= 0 && c < static_cast<int>(r.candidates.size()) ? r.candidates[c].energy
                                                              : std::numeric_limits<double>::quiet_NaN();
}

// Mean D' from which the quality warning says the images are too stretched for
// straight triangles (good maps: mean D' 1-5; the twisted classes of issue 14's
// table: 12-1676).
constexpr double kStretchedImagesMeanDilatation = 100;

void assess_quality(SurfaceMapResult& result) {
  result.energy_ratio = std::numeric_limits<double>::quiet_NaN();
  result.quality_warning.clear();
  if (result.genus < 2 || result.chosen_candidate < 0 || result.chosen_candidate >= static_cast<int>(result.candidates.size()))
    return;
  result.reverse_check = symmetry_check(result);
  const HomotopyCandidate& c = result.candidates[result.chosen_candidate];
  // The class's free optimum (landmarks raise the returned map's energy on
  // purpose; that is not a sign of a twisted class).
  double energy = std::isfinite(c.energy) ? c.energy : result.final_energy;
  result.energy_ratio_own_edges = std::numeric_limits<double>::quiet_NaN();
  if (std::isfinite(result.intrinsic_class_energy)) {
    // (The own-edge fallback's energy is kept beside it.)
    result.energy_ratio_own_edges = energy / conformal_bound(result.genus);
    energy = result.intrinsic_class_energy;
  }
  result.energy_ratio = energy / conformal_bound(result.genus);
  if (result.energy_ratio >= 3.0)
    result.quality_warning = "energy " + four_digits(result.energy_ratio) +
                             " x the conformal bound 8 pi (g - 1): the handle class may be twisted; add landmarks or "
                             "pick a candidate";
  // Session 26 (edge26): a map in a far twisted class is one-to-one on the
  // surfaces (0 flipped geodesic image triangles) while its image triangles
  // are tens of hyperbolic units long and cross many target triangles; the
  // straight triangles between the images, which the UVs and the morph are
  // made of, then fold (CAD block g12 -> raw wheel g12: mean D' 1.3e7, 829
  // negatively oriented in `surfmap verify`). Said plainly, beside the ratio.
  if (result.mean_dilatation >= kStretchedImagesMeanDilatation)
    result.quality_warning += (result.quality_warning.empty() ? "" : "; ") + std::string("mean D' ") +
                              four_digits(result.mean_dilatation) +
                              ": image triangles this stretched span many target triangles, so the straight "
                              "triangles between the images (UVs, the morph) may fold where the map does not; "
                              "`surfmap verify` checks them";
}

void qualify_quality_warning(SurfaceMapResult& result) {
  static const std::string both = "; both directions end on this class";
  const std::string& outcome = result.directions.outcome;
  if (result.quality_warning.empty() || result.quality_warning.find(both) != std::string::npos) return;
  if (outcome != "inverse" && outcome != "symmetric: both optimal") return;
  result.quality_warning += both + (outcome == "inverse" ? std::string(" (the other direction's class is its inverse)")
                                                         : std::string(" (up to an isometry of the target)")) +
                            ": neither search finds a lower one, which does not make it the best (a genus-4 pair had "
                            "one 23% lower that neither found); the shapes may also be conformally far apart";
}

SurfaceMapOptions without_the_runs_own(SurfaceMapOptions o) {
  o.homotopy.class_index = -1;
  o.homotopy.class_words.clear();
  o.homotopy.two_way = false;
  o.homotopy.through_shape = false;  // (a through-shape step runs in its own run)
  o.homotopy.source_images.resize(0, 0);
  // The classes are ranked by their free energies (landmarks rank them
  // separately afterwards), so the runs made from these options are mapped
  // without them: the same run whatever landmarks are given.
  o.landmarks.clear();
  o.solve_progress = nullptr;
  return o;
}

SurfaceMapOptions reverse_options(const SurfaceMapOptions& options) {
  SurfaceMapOptions ro = without_the_runs_own(options);
  std::swap(ro.loops.source_base_vertex, ro.loops.target_base_vertex);
  return ro;
}

SurfaceMapOptions single_class_options(SurfaceMapOptions o, std::vector<std::vector<int>> reverse_class,
                                       SingleClass scope) {
  if (scope == SingleClass::Alone) o = without_the_runs_own(std::move(o));
  o.homotopy.two_way = false;
  o.homotopy.compare_directions = false;  // (read only by the two-way run)
  o.homotopy.class_words.clear();
  o.homotopy.reverse_class = std::move(reverse_class);
  o.homotopy.reverse_class_only = true;
  return o;
}

bool map_requested_two_way_class(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                 SurfaceMapResult& out, const MapFunction& map) {
  if (options.homotopy.class_index < 0 || !options.homotopy.two_way || options.homotopy.source_images.size() > 0) return false;
  const SurfaceMapResult reverse = map(target, source, reverse_options(options));
  if (static_cast<int>(reverse.inverse.size()) != source.num_vertices()) return false;
  SurfaceMapOptions fo = options;
  fo.homotopy.two_way = false;
  fo.homotopy.source_images = inverse_positions(reverse);
  out = map(source, target, fo);
  out.two_way_status = "the requested class is the two-way run's (the source's loops carried by the target -> source map)";
  return true;
}

// The source's cuts from another base vertex (the middle vertex), mapped
// one way: the last resort of rescue_by_the_other_direction. The perturbed
// botijo -> genus-5 CAD plate folds in every class from the automatic base
// vertex and in the other direction's class; from vertex 20000 of its 41158
// it maps, 19.5 x (docs/history/handle_classes.md "Every class folded").
bool rescue_by_another_cut(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                           SurfaceMapResult& out, const MapFunction& map, std::string& why) {
  if (options.loops.source_base_vertex >= 0) return false;
  SurfaceMapOptions bo = options;
  bo.homotopy.two_way = false;
  bo.homotopy.through_shape = false;  // (the rescue's last attempt: one run)
  bo.loops.fold_fallback = false;     // (the retry after folds is the whole run's, made once)
  bo.loops.source_base_vertex = source.num_vertices() / 2;
  // (The automatic cuts are the run that just folded in every class.)
  bo.loops.search_in_given_cuts = true;
  SurfaceMapResult again;
  std::string failure;
  const std::string at = "the cuts at source vertex " + std::to_string(bo.loops.source_base_vertex);
  if (!run_map(map, source, target, bo, again, failure)) {
    why += "; " + at + ": " + failure;
    return false;
  }
  out = std::move(again);
  out.two_way_status = "every one-way candidate class folded (" + why + "); " + at +
                       " gave a bijective map (the two-way run not applied to it)";
  return true;
}

bool rescue_by_the_other_direction(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                   SurfaceMapResult& out, const MapFunction& map, std::string& why,
                                   std::vector<std::vector<int>>* target_letters_inverse, bool* another_cut_left) {
  if (!options.homotopy.two_way || options.homotopy.class_index >= 0 || options.homotopy.source_images.size() > 0 ||
      options.homotopy.reverse_class_only || !options.homotopy.given_class.empty() || !options.landmarks.empty())
    return false;
  const auto t0 = std::chrono::steady_clock::now();
  auto done = [&] {
    out.two_way_time_s = seconds_since(t0);
    return true;
  };
  SurfaceMapResult reverse;
  std::string failure;
  SurfaceMapOptions ro = reverse_options(options);
  ro.loops.fold_fallback = false;  // (the retry after folds is the whole run's, made once)
  if (!run_map(map, target, source, ro, reverse, failure)) {
    why = "the other direction failed too: " + failure;
    // Both directions folded (or this one folded and the other failed): the
    // caller's retry after folds comes before the cuts at another vertex
    // (docs/robustness.md "Canonical generators").
    if (another_cut_left && options.loops.source_base_vertex < 0) {
      *another_cut_left = true;
      return false;
    }
    return rescue_by_another_cut(source, target, options, out, map, why) && done();
  }
  if (target_letters_inverse) *target_letters_inverse = reverse.source_as_target_inverse;
  if (static_cast<int>(reverse.inverse.size()) != source.num_vertices()) {
    why = "the other direction gave no inverse correspondence";
    return rescue_by_another_cut(source, target, options, out, map, why) && done();
  }
  // Only the other direction's class: the one-way candidates all folded
  // already. First the source's loops carried by that map's inverse; when
  // they give no isomorphism (a map far from conformal puts consecutive
  // loop vertices far apart), its class inverted algebraically, written in
  // this run's letters (`out`: the failed run's letters as a target).
  SurfaceMapOptions fo = options;
  fo.homotopy.two_way = false;
  fo.homotopy.source_images = inverse_positions(reverse);
  fo.homotopy.images_only = true;
  SurfaceMapResult again;
  std::string how = "the class of the source's loops carried by the target -> source map";
  if (!run_map(map, source, target, fo, again, failure)) {
    std::string no_class;
    const SurfaceMapOptions ro =
        single_class_options(options, reverse_class_here(out, reverse, no_class), SingleClass::KeepTheRest);
    std::string inverted_failure = no_class;
    if (ro.homotopy.reverse_class.empty() || !run_map(map, source, target, ro, again, inverted_failure)) {
      why = "the other direction's class (energy ratio " + four_digits(reverse.energy_ratio) + " there) failed here too: carried, " +
            failure + "; inverted algebraically, " + inverted_failure;
      return rescue_by_another_cut(source, target, options, out, map, why) && done();
    }
    how = "the target -> source map's class inverted algebraically (its loops carried: " + failure + ")";
  }
  out = std::move(again);
  out.directions.other_one_way_ratio = reverse.energy_ratio;
  out.two_way_status = "every one-way candidate class folded; " + how + " (energy ratio " + four_digits(reverse.energy_ratio) +
                       " there) gave a bijective map";
  if (out.directions.reason.empty() && out.directions.outcome.empty())
    out.directions.reason = "not compared: the class was carried from the other direction's map (every one-way class folded)";
  return done();
}

void two_way_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                 SurfaceMapResult& forward, const MapFunction& map,
                 std::vector<std::vector<int>>* target_letters_inverse) {
  if (forward.genus < 2 || options.homotopy.class_index >= 0 || options.homotopy.source_images.size() > 0 ||
      options.homotopy.reverse_class_only || !options.homotopy.given_class.empty())
    return;
  if (!options.homotopy.two_way) return void(forward.two_way_status = "not run (off)");
  const bool compare = options.homotopy.compare_directions;
  if (!compare && !(forward.energy_ratio >= options.homotopy.two_way_ratio)) {
    forward.two_way_status = "not run: energy ratio below " + four_digits(options.homotopy.two_way_ratio);
    forward.reverse_inverse_reason = "not compared: the two-way run did not run (energy ratio below " +
                                     four_digits(options.homotopy.two_way_ratio) + ")";
    forward.directions.reason = forward.reverse_inverse_reason;
    // Issue 14: between agreement_ratio and two_way_ratio, both directions agree on one pair.
    if (!(forward.energy_ratio >= options.homotopy.agreement_ratio)) return;
    if (!options.landmarks.empty()) {
      forward.directions.agreement = "not run: landmarks given (they choose the class)";
      return;
    }
    const auto t0 = std::chrono::steady_clock::now();
    const std::string agreement = agree_below_two_way_ratio(source, target, options, forward, map, target_letters_inverse);
    forward.directions.agreement = agreement;
    forward.two_way_status = "not run: energy ratio below " + four_digits(options.homotopy.two_way_ratio) +
                             "; both directions agree (ratio " + four_digits(options.homotopy.agreement_ratio) +
                             " or more): " + agreement;
    forward.two_way_time_s = seconds_since(t0);
    return;
  }
  const auto t0 = std::chrono::steady_clock::now();
  SurfaceMapResult reverse;
  auto finish = [&](std::string status) {
    forward.two_way_status = std::move(status);
    if (reverse.chosen_candidate >= 0) forward.directions.other_one_way_ratio = reverse.energy_ratio;
    if (forward.reverse_inverse < 0 && forward.reverse_inverse_reason.empty())
      forward.reverse_inverse_reason =
          "not compared: " + (forward.reverse_status.empty() ? forward.two_way_status : forward.reverse_status);
    if (forward.directions.outcome.empty() && forward.directions.reason.empty())
      forward.directions.reason = "not compared: " + forward.two_way_status;
    forward.two_way_time_s = seconds_since(t0);
  };
  std::string reverse_failure;
  if (!run_map(map, target, source, reverse_options(options), reverse, reverse_failure)) {
    return finish(std::string("the other direction failed: ") + reverse_failure);
  }
  if (target_letters_inverse) *target_letters_inverse = reverse.source_as_target_inverse;
  if (static_cast<int>(reverse.inverse.size()) != source.num_vertices())
    return finish("the other direction gave no inverse correspondence");
  const std::string rev = "target -> source energy ratio " + four_digits(reverse.energy_ratio) + " (mean D' " +
                          four_digits(reverse.mean_dilatation) + ")";
  if ((!compare && !(reverse.energy_ratio < forward.energy_ratio)) || reverse.chosen_candidate < 0) {
    forward.reverse_inverse_reason = "not compared: the other direction's energy ratio " + four_digits(reverse.energy_ratio) +
                                     " is not lower, its class was not carried";
    if (reverse.chosen_candidate < 0 || !options.homotopy.cheap_direction_check) return finish(rev + ", not lower: kept");
    // (The ratios of the two directions are not comparable energies.)
    const std::string check = cheap_direction_check(source, target, options, reverse, forward, map);
    return finish(rev + ", not lower; " + check);
  }
  SurfaceMapOptions fo = options;
  fo.homotopy.two_way = false;
  fo.homotopy.source_images = inverse_positions(reverse);  // where its inverse puts each source vertex
  std::string no_reverse_class;
  fo.homotopy.reverse_class = reverse_class_here(forward, reverse, no_reverse_class);  // its class, inverted there
  SurfaceMapResult again;
  std::string again_failure;
  if (!run_map(map, source, target, fo, again, again_failure)) {
    return finish(rev + "; mapping again with that candidate failed: " + again_failure);
  }
  const double before = forward.energy_ratio, after = again.energy_ratio;
  const std::string again_status = again.reverse_status;
  // Ties: the second run, whose report lists the other direction's class.
  const bool better = after <= before * (1 + 1e-6);
  if (fo.homotopy.reverse_class.empty()) again.directions.reason = "not compared: " + no_reverse_class;
  if (better) {
    forward = std::move(again);
    // (Agreed here: the class is the other direction's, inverted, or isometric to it.)
    if (forward.directions.outcome == "inverse" || forward.directions.outcome == "symmetric: both optimal")
      forward.directions.inverse_there_ratio = reverse.energy_ratio;
  } else {
    // (The second run's comparison is of its own chosen class.)
    forward.directions = again.directions;
    // The first run is kept: its class has lower energy than the other
    // direction's class inverted, so they are not inverse unless the second
    // run found them the same class.
    forward.reverse_inverse = again.reverse_inverse == 1 ? 1 : 0;
    forward.reverse_inverse_reason =
        (again.reverse_inverse == 1 ? std::string("the same class: ") : std::string("not inverse: ")) +
        "the other direction's class inverted has energy ratio " + four_digits(after) + " against " + four_digits(before) +
        (again.reverse_inverse_reason.empty() ? std::string() : " (" + again.reverse_inverse_reason + ")");
  }
  std::string agreement;
  if (forward.directions.outcome == "different")
    agreement = "; " + agree_directions(source, target, fo, reverse, forward, map);
  finish(rev + "; with the source's loops carried by its inverse as a candidate: energy ratio " + four_digits(after) +
         " against " + four_digits(before) + (better ? ": used" : ": kept the first") +
         (again_status.empty() ? std::string() : " (" + again_status + ")") + agreement);
}

}  // namespace surfmap::detail
