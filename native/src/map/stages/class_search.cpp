#include "class_search.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <tuple>

#include "../../seconds_since.h"
#include "../concurrency.h"
#include "snapped_start.h"
#include "surfmap/error.h"
#include "surfmap/map/geometric_classes.h"
#include "surfmap/map/greedy_pants.h"
#include "surfmap/map/pants_classes.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/mapping_class_search.h"

namespace surfmap::detail {

std::vector<FoundClass> classes_from_more_cuts(CutLifter& lifter, SourceCuts& cuts, const ClassSpace& space,
                                               int num_vertices, int threads, double conformal_bound,
                                               const std::function<ClassData(const GroupMap&)>& data_of,
                                               const CoarseSolve& solve_coarse, const SurfaceMapOptions& options,
                                               HomotopySearchInfo& info) {
  const auto t_cuts = std::chrono::steady_clock::now();
  std::vector<FoundClass> found;
  const std::vector<int> late = spread_bases(num_vertices, options.homotopy.search.cuts);
  // The late cuts' source-only parts, on both threads.
  parallel_for(threads, static_cast<int>(late.size()), [&](int k, const std::atomic<bool>*) {
    const auto& planned = cuts.planned_bases();
    auto slot = std::find(planned.begin(), planned.end(), late[k]);
    if (slot != planned.end()) cuts.prepare_planned(static_cast<int>(slot - planned.begin()));
  });
  for (HomotopyClass& hc : lifter.lift(late)) {
    if (space.loop_image_length(hc.map) > space.max_image_letters()) continue;
    FoundClass f;
    try {
      f.data = data_of(hc.map);
    } catch (const SolveError&) {
      continue;
    }
    ++info.cut_classes;
    if (!solve_coarse(hc.map, &f.evaluation)) continue;
    const double energy = f.evaluation.result.energy;
    f.hc = std::move(hc);
    found.push_back(std::move(f));
    // Within the gap of the bound: what the twist search would not run
    // for, so the rest (lowest screen first) are not solved either.
    if (energy <= (1 + options.homotopy.search.gap) * conformal_bound) break;
  }
  info.cuts_time_s = seconds_since(t_cuts);
  return found;
}

namespace {

std::string lengths_text_of(const std::vector<double>& l) {
  std::string s;
  char buf[32];
  for (double x : l) std::snprintf(buf, sizeof buf, "%s%.3g", s.empty() ? "" : " ", x), s += buf;
  return s;
}

}  // namespace

bool layout_short_basis(const Word& layout_word, const std::vector<Word>& class_generators,
                        const std::vector<Word>& class_letters, CanonicalSchema* layout_schema,
                        GroupMap* in_class_letters, std::string* why) {
  CanonicalSchemaOptions short_schema;
  short_schema.short_generators = true;
  *layout_schema = canonical_schema(layout_word, short_schema);
  // Each layout letter as a word in the class letters.
  std::vector<Word> class_of_layout_letter;
  if (!invert_canonical_generators(class_generators, layout_word, class_letters, &class_of_layout_letter, why))
    return false;
  const DehnReducer reduce(canonical_relator(static_cast<int>(layout_word.size() / 4)));
  in_class_letters->assign(layout_schema->generators.size(), Word{});
  for (size_t j = 0; j < layout_schema->generators.size(); ++j)
    (*in_class_letters)[j] = reduce(substitute(layout_schema->generators[j], class_of_layout_letter));
  return true;
}

std::vector<FoundClass> geometric_candidate_classes(const SurfaceGroupLengths& source, const SurfaceGroupLengths& target,
                                                    const ClassSpace& space, const std::vector<GroupMap>& known,
                                                    const std::function<double(const GroupMap&)>& bound_of,
                                                    const std::function<ClassData(const GroupMap&)>& data_of,
                                                    const CoarseSolve& solve_coarse, const SurfaceMapOptions& options,
                                                    HomotopySearchInfo& info, const GroupMap* target_letters) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<FoundClass> found;
  const ShortMarking mx = short_marking(source), my = short_marking(target);
  info.source_marking = lengths_text_of(mx.generator_lengths);
  info.target_marking = lengths_text_of(my.generator_lengths);
  // The shortest closed geodesics of both (words of up to 3 letters of the
  // markings, 2 from genus 5: 24^3 words would cost more than the rest).
  const int letters = source.genus() <= 4 ? 3 : 2;
  for (const auto& [lengths, marking, text] :
       {std::tuple(&source, &mx, &info.source_geodesics), std::tuple(&target, &my, &info.target_geodesics)}) {
    std::vector<double> l;
    for (const ShortGeodesic& sg : short_geodesics(*lengths, *marking, letters, 8)) l.push_back(sg.length);
    *text = lengths_text_of(l);
  }
  GeometricClassOptions go;
  go.max_classes = std::max(6, 2 * options.homotopy.search.geometric);
  go.descents = go.max_classes;  // (all: with only 4, n_hole_torus(2) -> vase missed its geometric class)
  std::vector<GeometricClass> classes = geometric_classes(source, mx, target, my, go);
  // Classes from short pants decompositions with Fenchel–Nielsen twists
  // (map/pants_classes.h), listed after the markings' and solved within a
  // budget of their own (the same count); then those pairing the greedy
  // short pants decompositions (map/greedy_pants.h), a third list with the
  // same budget.
  const size_t marking_classes = classes.size();
  size_t caterpillar_end = classes.size();
  // (Not beyond genus go.enumerated_genus: pants_symmetries lists 2^g half
  // turns per handle permutation, and the genus-11 plate -> wheel spent
  // over 20 minutes in pants_classes without finishing; issue 13.)
  if (source.genus() <= go.enumerated_genus) {
    const PantsDecomposition px = short_pants_decomposition(source, mx), py = short_pants_decomposition(target, my);
    std::vector<double> lx, ly;
    for (const PantsCurve& c : px.curves) lx.push_back(c.length);
    for (const PantsCurve& c : py.curves) ly.push_back(c.length);
    const std::string pants_lengths = "pants lengths " + lengths_text_of(lx) + " -> " + lengths_text_of(ly);
    PantsClassOptions po;
    po.max_classes = go.max_classes;
    for (PantsClass& pc : pants_classes(source, px, target, py, po)) {
      GeometricClass gc;
      gc.theta = std::move(pc.theta);
      gc.permutation = pc.symmetry.permutation;
      for (int h : pc.symmetry.half_turn) gc.rotation.push_back(2 * h);
      gc.mismatch = pc.mismatch;
      gc.description = pc.description + " (" + pants_lengths + ")";
      classes.push_back(std::move(gc));
    }
    caterpillar_end = classes.size();
    if (options.homotopy.search.greedy_pants) {
      const auto t_greedy = std::chrono::steady_clock::now();
      // (The caterpillar's curves join the candidates: a short marking's
      // short words can miss one.)
      std::vector<Word> extra_x, extra_y;
      for (const PantsCurve& c : px.curves) extra_x.push_back(c.word);
      for (const PantsCurve& c : py.curves) extra_y.push_back(c.word);
      const GreedyPantsDecomposition gx = greedy_pants_decomposition(source, mx, extra_x);
      const GreedyPantsDecomposition gy = greedy_pants_decomposition(target, my, extra_y);
      std::vector<double> glx, gly;
      for (const GreedyPantsCurve& c : gx.curves) glx.push_back(c.length);
      for (const GreedyPantsCurve& c : gy.curves) gly.push_back(c.length);
      info.source_greedy_pants = lengths_text_of(glx) + (gx.complete ? "" : " (incomplete)");
      info.target_greedy_pants = lengths_text_of(gly) + (gy.complete ? "" : " (incomplete)");
      GreedyPantsClassOptions gpo;
      gpo.max_classes = go.max_classes;
      for (GreedyPantsClass& c : greedy_pants_classes(source, mx, gx, target, my, gy, gpo)) {
        GeometricClass gc;
        gc.theta = std::move(c.theta);
        gc.mismatch = c.cost;
        char buf[64];
        std::snprintf(buf, sizeof buf, "; greedy collar bound %.4g", c.collar_bound);
        gc.description = c.description + buf + " (greedy lengths " + info.source_greedy_pants + " -> " +
                         info.target_greedy_pants + ")";
        classes.push_back(std::move(gc));
      }
      info.greedy_pants_time_s = seconds_since(t_greedy);
    }
  }
  auto list_of = [&](size_t k) { return k < marking_classes ? 0 : k < caterpillar_end ? 1 : 2; };
  std::vector<std::vector<double>> fingerprints;
  for (const GroupMap& k : known)
    fingerprints.push_back(space.loop_image_length(k) <= space.max_image_letters() ? space.fingerprint(k)
                                                                                   : std::vector<double>{});
  // Ranked by the curve lower bound first (the mismatch breaks ties).
  std::vector<std::pair<double, size_t>> ranked;
  // (Issue 13: the classes over the letter limit, counted so that a run
  // where none is left says why: the genus-12 block -> wheel's short-marking
  // classes have curve bounds 1.6 x the conformal bound but 30-41 thousand
  // letters in the wheel's layout letters.)
  size_t over_limit = 0;
  double fewest_letters = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < classes.size(); ++k) {
    GroupMap& theta = classes[k].theta;
    if (target_letters)
      for (Word& w : theta) w = substitute(w, *target_letters);  // (reduced next, in the space's letters)
    space.reduce(theta);
    if (!space.is_isomorphism(theta)) continue;
    const double letters = space.loop_image_length(theta);
    if (letters > space.max_image_letters()) {
      ++over_limit;
      fewest_letters = std::min(fewest_letters, letters);
      continue;
    }
    ranked.push_back({bound_of(theta), k});
  }
  if (ranked.empty() && over_limit > 0) {
    char buf[192];
    std::snprintf(buf, sizeof buf,
                  "none solved: %zu of %zu geometric classes have loop images beyond the letter limit (%.0f letters "
                  "at the fewest, limit %.0f)",
                  over_limit, classes.size(), fewest_letters, space.max_image_letters());
    info.geometric_failures.push_back(buf);
  }
  std::stable_sort(ranked.begin(), ranked.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  // The markings' classes, then the caterpillar pants classes, then the
  // greedy pants classes, each list within the budget `geometric` (lowest
  // bound first).
  std::stable_sort(ranked.begin(), ranked.end(),
                   [&](const auto& x, const auto& y) { return list_of(x.second) < list_of(y.second); });
  int solved_of_list[3] = {0, 0, 0};
  for (const auto& [bound, k] : ranked) {
    const int list = list_of(k);
    if (solved_of_list[list] >= options.homotopy.search.geometric) continue;
    const GeometricClass& gc = classes[k];
    const std::vector<double> fp = space.fingerprint(gc.theta);
    bool seen = false;
    for (const auto& f : fingerprints) seen = seen || ClassSpace::same_fingerprint(f, fp);
    if (seen) continue;
    fingerprints.push_back(fp);
    ++info.geometric_classes;
    ++solved_of_list[list];
    FoundClass f;
    static const char* const list_name[3] = {"marking", "caterpillar pants", "greedy pants"};
    auto failed = [&](const std::string& why) {
      char head[96];
      std::snprintf(head, sizeof head, "%s class %d (curve bound %.4g): ", list_name[list], solved_of_list[list], bound);
      info.geometric_failures.push_back(head + why);
    };
    try {
      f.data = data_of(gc.theta);
    } catch (const SolveError& e) {
      failed(std::string("no class data: ") + e.what());
      continue;
    }
    if (!solve_coarse(gc.theta, &f.evaluation)) {
      // (The longest loop image says whether a start at the origin could
      // hold the class at all: see geometric_start_edge_size.)
      double longest = 0;
      for (double l : space.loop_image_lengths(gc.theta)) longest = std::isfinite(l) ? std::max(longest, l) : longest;
      char lbuf[64];
      std::snprintf(lbuf, sizeof lbuf, " (longest loop image %.3g units)", longest);
      f.evaluation.failure += lbuf;
      failed(f.evaluation.failure);
      continue;
    }
    char buf[96];
    std::snprintf(buf, sizeof buf, ", length mismatch %.3g, curve bound %.4g", gc.mismatch, bound);
    f.hc.description = std::string(list == 0 ? "[geometric: short markings, " : "[geometric: ") +
                       (target_letters ? "the target's lengths in its layout's short basis, " : "") + gc.description +
                       buf + "]";
    found.push_back(std::move(f));
  }
  info.geometric_time_s = seconds_since(t0);
  return found;
}

std::optional<CoarseEvaluation> twist_class_search(const GroupMap& start_map, int start_index, double start_energy,
                                                   const ClassSpace& space, const CoarseSolve& solve_coarse,
                                                   const std::vector<std::string>& start_twists,
                                                   const SurfaceMapOptions& options, HomotopySearchInfo& info,
                                                   const std::vector<MappingClassMove>& source_moves,
                                                   const std::vector<MappingClassMove>& target_moves,
                                                   bool high_kicks) {
  const auto t_search = std::chrono::steady_clock::now();
  info.run = true;
  info.start_candidate = start_index;
  GroupMap search_from = start_map;
  if (!start_twists.empty()) {
    std::vector<MappingClassMove> moves = twist_moves(space.genus());
    moves.insert(moves.end(), source_moves.begin(), source_moves.end());
    for (const std::string& name : start_twists) {
      auto it = std::find_if(moves.begin(), moves.end(), [&](const MappingClassMove& m) { return m.name == name; });
      if (it == moves.end()) throw InputError("homotopy_search_start_twists: no move named '" + name + "'");
      search_from = compose(search_from, it->automorphism.map);
      space.reduce(search_from);
    }
  }
  std::vector<CoarseEvaluation> evaluated;
  auto coarse_energy = [&](const GroupMap& theta) {
    CoarseEvaluation ev;
    if (!solve_coarse(theta, &ev)) return std::numeric_limits<double>::infinity();
    evaluated.push_back(std::move(ev));
    return evaluated.back().result.energy;
  };
  info.start_energy = start_twists.empty() ? start_energy : coarse_energy(search_from);
  TwistSearchOptions tso;
  tso.max_evaluations = options.homotopy.search.evaluations;
  tso.pair_moves = options.homotopy.search.pair_moves;
  tso.evaluations_per_step = options.homotopy.search.evaluations_per_step;
  tso.kicks = options.homotopy.search.kicks;
  tso.kick_moves = options.homotopy.search.kick_moves;
  tso.kick_evaluations = options.homotopy.search.kick_evaluations;
  tso.kick_choices = options.homotopy.search.kick_choices;
  tso.kick_seed = options.homotopy.search.kick_seed;
  if (high_kicks) {
    // (No descent: the kicks alone, from the class the search ended on.)
    const HomotopySearchOptions& s = options.homotopy.search;
    tso.kicks_only = true;
    tso.kicks = s.high_kicks;
    tso.max_evaluations = static_cast<int>(
        std::min<long long>(std::numeric_limits<int>::max(), static_cast<long long>(s.high_kicks) * (1LL + s.kick_evaluations)));
  }
  tso.source_moves = source_moves;
  tso.target_moves = target_moves;
  const TwistSearchResult ts = twist_search(search_from, info.start_energy, space.genus(),
                                            [&](const GroupMap& theta) { return space.screen(theta); }, coarse_energy, tso);
  info.moves = ts.moves;
  info.energies = ts.energies;
  info.energy = ts.energy;
  info.evaluations = static_cast<int>(ts.evaluations.size());
  for (const TwistSearchEvaluation& ev : ts.evaluations) {
    info.evaluated_moves.push_back(ev.move);
    info.evaluated_step.push_back(ev.step);
    info.evaluated_screen.push_back(ev.screen);
    info.evaluated_energy.push_back(ev.energy);
  }
  info.screened = ts.screened;
  info.stop_reason = ts.stop_reason;
  info.kicks = ts.kicks;
  info.lower_kicks = ts.improving_kicks;
  std::optional<CoarseEvaluation> found;
  if (!ts.moves.empty())
    for (CoarseEvaluation& ev : evaluated)
      if (ev.theta == ts.best) found = ev;  // (the last match, as before)
  info.time_s = seconds_since(t_search);
  return found;
}

}  // namespace surfmap::detail

namespace surfmap::detail {

std::vector<MappingClassMove> short_curve_moves(const SurfaceGroupLengths& lengths, std::string* lengths_text) {
  const ShortMarking marking = short_marking(lengths);
  const PantsDecomposition pants = short_pants_decomposition(lengths, marking);
  std::vector<MappingClassMove> moves;
  std::vector<double> l;
  for (const CurveTwist& c : short_curve_twists(lengths, marking, &pants)) {
    const std::string name = "T(" + c.name + ")";
    moves.push_back({name, c.twist});
    moves.push_back({name + "^-1", {c.twist.inverse, c.twist.map, c.twist.moves}});
    l.push_back(c.length);
  }
  *lengths_text = lengths_text_of(l);
  return moves;
}

}  // namespace surfmap::detail
