// surfmap map SRC DST: the globally optimal map from SRC onto DST (paper
// docs/method.md §2). Writes the morph (SRC's connectivity at the mapped positions),
// a JSON report and optionally the per-vertex correspondence.
#include <cmath>
#include <fstream>
#include <future>
#include <iomanip>
#include <iostream>
#include <optional>
#include <cstdint>
#include <sstream>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "map_open.h"  // open surfaces (issue 16)
#include "surfmap/error.h"
#include "surfmap/map/map_option_names.h"
#include "surfmap/map/map_report.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/mesh_io.h"
#include "surfmap/verify/correspondence_file.h"

namespace surfmap::cli {

// Landmark pairs, one 'source_vertex target_vertex' per line; blank lines and
// '#' comments are skipped. Errors name the file and line (map_open.h).
std::vector<std::pair<int, int>> read_landmarks(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("cannot read landmarks file " + path);
  std::vector<std::pair<int, int>> pairs;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream s(line);
    long long a = 0, b = 0;
    std::string rest;
    if (!(s >> a)) {
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      throw InputError(path + ":" + std::to_string(number) + ": expected 'source_vertex target_vertex'");
    }
    if (!(s >> b) || (s >> rest) || a < 0 || b < 0 || a > INT32_MAX || b > INT32_MAX)
      throw InputError(path + ":" + std::to_string(number) + ": expected two vertex indices, got '" + line + "'");
    pairs.emplace_back(static_cast<int>(a), static_cast<int>(b));
  }
  return pairs;
}

// --class-words: a JSON list of 2g lists of int letters (the report's
// homotopy.chosen_words), one-line errors.
std::vector<std::vector<int>> parse_class_words(const std::string& text) {
  const std::string expected = "--class-words: expected a JSON list of lists of integer letters such as "
                               "[[1],[2],[3],[4]] (the report's homotopy.chosen_words)";
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_array() || j.empty()) throw InputError(expected);
  std::vector<std::vector<int>> words;
  for (const auto& w : j) {
    if (!w.is_array()) throw InputError(expected);
    words.emplace_back();
    for (const auto& x : w) {
      if (!x.is_number_integer()) throw InputError(expected);
      words.back().push_back(x.get<int>());
    }
  }
  return words;
}

// Long on purpose: one flat list of the subcommand's flags (each one
// add_option/add_flag with its help text) and the one callback that fills
// SurfaceMapOptions from them and runs the map; split, a flag and where it
// is read would sit apart.
void register_map(CLI::App& app) {
  auto* cmd = app.add_subcommand("map", "Globally optimal map from SRC onto DST (same genus)");
  // Every default is the options structs' own (map/surface_map.h), as the Python keywords'
  // (python/bind_map.cpp): one set of defaults for every path (docs/handle_classes.md
  // "Quality signal"; test test_default_map_is_the_same_on_every_path).
  struct Args {
    const SurfaceMapOptions defaults;
    std::string src, dst, out, report, correspondence, method = enum_name(defaults.solve.method), landmarks,
        initial = enum_name(defaults.initial.method), initial_out,
        source_weights = enum_name(defaults.solve.source_weights),
        target_metric = enum_name(defaults.uniformization.target_metric),
        target_loops = enum_name(defaults.uniformization.loops),
        face_charts = enum_name(defaults.uniformization.face_charts), class_words;
    int threads = defaults.threads, homotopy = defaults.homotopy.class_index,
        base_vertex = defaults.loops.source_base_vertex, target_base_vertex = defaults.loops.target_base_vertex,
        max_iterations = defaults.solve.max_iterations;
    int homotopy_candidates = defaults.homotopy.candidates, homotopy_full_solves = defaults.homotopy.full_solves,
        homotopy_extra_cuts = defaults.homotopy.extra_cuts,
        homotopy_search_evaluations = defaults.homotopy.search.evaluations;
    double tolerance = defaults.solve.tolerance, own_weights_floor = defaults.solve.own_weights_floor;
    double agreement_ratio = defaults.homotopy.agreement_ratio;  // HomotopyOptions::agreement_ratio
    double through_shape_ratio = defaults.homotopy.through_shape_ratio;  // HomotopyOptions::through_shape_ratio
    bool quiet = false, timings = false, no_homotopy_search = !defaults.homotopy.search.enabled,
         no_two_way = !defaults.homotopy.two_way, compare_directions = defaults.homotopy.compare_directions;
    bool no_cheap_direction_check = !defaults.homotopy.cheap_direction_check;
    bool no_through_shape = !defaults.homotopy.through_shape;
    bool no_local_fold_repair = !defaults.solve.local_fold_repair;
    bool no_fold_untangle = !defaults.solve.fold_untangle;  // SolveOptions::fold_untangle
    bool no_greedy_pants = !defaults.homotopy.search.greedy_pants;  // HomotopySearchOptions::greedy_pants
    bool no_snapped_start = !defaults.homotopy.search.snapped_start;  // HomotopySearchOptions::snapped_start
    bool short_canonical_generators = false;      // LoopOptions::short_canonical_generators = true
    bool classical_canonical_generators = false;  // LoopOptions::short_canonical_generators = false
    bool no_short_generators_fallback = !defaults.loops.short_generators_fallback;  // LoopOptions::short_generators_fallback
    bool no_fold_fallback = !defaults.loops.fold_fallback;  // LoopOptions::fold_fallback
    bool both_canonical_bases = false;  // LoopOptions::both_canonical_bases = true (the default, said so)
    bool one_canonical_basis = false;   // LoopOptions::both_canonical_bases = false
    bool geometric_layout_basis = defaults.homotopy.search.geometric_layout_basis;  // HomotopySearchOptions::geometric_layout_basis
    bool short_curve_twists = defaults.homotopy.search.curve_twists;  // HomotopySearchOptions::curve_twists
    int high_kicks = defaults.homotopy.search.high_kicks;  // HomotopySearchOptions::high_kicks (0: none)
    bool homotopy_both_signs = defaults.homotopy.flat_both_signs;    // HomotopyOptions::flat_both_signs
    bool no_flat_overlay = !defaults.homotopy.flat_overlay;          // HomotopyOptions::flat_overlay off
    bool landmarks_may_fold = defaults.landmarks_may_fold;          // SurfaceMapOptions::landmarks_may_fold
    bool locate_initial_map = defaults.initial.locate;              // InitialMapOptions::locate
    bool boundary_swap = false;          // open surfaces (map_open.h)
    std::vector<int> boundary_pairing;  // open surfaces (map_open.h)
    int refine_rings = OpenMapCliArgs().refine_rings, refine_levels = OpenMapCliArgs().refine_levels;
    bool no_reflection_solve = !OpenMapCliArgs().reflection_solve;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("SRC", a->src, "Source mesh")->required();
  cmd->add_option("DST", a->dst, "Target mesh")->required();
  cmd->add_option("--out", a->out, "MORPH.obj: the source's connectivity at the mapped positions")->required();
  cmd->add_option("--report", a->report, "REPORT.json")->required();
  cmd->add_option("--correspondence", a->correspondence,
                  "CORR.txt: one line per source vertex, 'target_face b0 b1 b2', then after a '# inverse' line one per "
                  "target vertex, 'source_face b0 b1 b2' (surfmap verify checks it)");
  cmd->add_option("--homotopy", a->homotopy, "Homotopy class (index into the report's candidates; default: lowest energy)");
  cmd->add_option("--class-words", a->class_words,
                  "Genus >= 2: the class named by its words, a JSON list of 2g lists of letters as the report's "
                  "homotopy.chosen_words or a candidate's words from an earlier run of the same pair and loop options "
                  "(a --homotopy index names a class only within one run's list; "
                  "docs/handle_classes.md \"Classes named by words\")");
  cmd->add_option("--base-vertex", a->base_vertex, "Base vertex of the source's system of loops");
  cmd->add_option("--target-base-vertex", a->target_base_vertex, "Base vertex of the target's system of loops");
  cmd->add_option("--method", a->method, "Optimiser of the harmonic energy (genus >= 2)")
      ->check(CLI::IsMember(enum_name_list<MapMethod>()));
  cmd->add_option("--source-weights", a->source_weights,
                  "Genus >= 1: energy weights on the source: auto (intrinsic Delaunay cotangents, positive weights on the "
                  "source's own edges if its faces' images fold), intrinsic, own")
      ->check(CLI::IsMember(enum_name_list<SourceWeights>()));
  cmd->add_flag("--no-local-fold-repair", a->no_local_fold_repair,
                "Genus >= 2, auto weights: when the intrinsic map folds some faces, solve the whole map again with "
                "own-edge weights instead of first re-solving only the vertices around the folds");
  cmd->add_flag("--no-fold-untangle", a->no_fold_untangle,
                "Genus >= 2, local fold repair: skip the untangling of fold clusters by distortion (the projection, "
                "then the held re-solves with own-edge weights, then the global fallback)");
  cmd->add_option("--own-weights-floor", a->own_weights_floor,
                  "Genus >= 1, own-edge weights: least weight, times the mean positive cotangent weight (default 0.1)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--landmarks", a->landmarks,
                  "PAIRS.txt: one 'source_vertex target_vertex' pair per line (# starts a comment), held fixed");
  cmd->add_option("--tolerance", a->tolerance, "Relative gradient tolerance of the harmonic solve")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--max-iterations", a->max_iterations, "Iteration cap of the harmonic solve (relaxation: sweeps, of the order of #V per decade of gradient)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--homotopy-candidates", a->homotopy_candidates,
                  "Genus >= 2: handle correspondences considered (best matching handle positions first)");
  cmd->add_option("--homotopy-full-solves", a->homotopy_full_solves,
                  "Genus >= 2: most candidates solved at full resolution after ranking all on a coarse copy of the source (the best, plus runners-up within 10%)");
  cmd->add_option("--initial-map", a->initial,
                  "Genus >= 2 initial map: cut_graph (source disk cut along its own edges onto the convex polygon of "
                  "its cut graph's harmonic map; else as polygon), polygon (source disk onto the target's geodesic "
                  "polygon of the source's loops when convex, else uniform) or uniform (the uniform-weight harmonic map)")
      ->check(CLI::IsMember(enum_name_list<InitialMapMethod>()));
  cmd->add_option("--initial-out", a->initial_out,
                  "INITIAL.obj: the source's connectivity at the initial map's positions on the target (genus >= 1; "
                  "implies --locate-initial-map)");
  cmd->add_flag("--locate-initial-map", a->locate_initial_map,
               "Genus >= 1: locate the initial map on the target and its inverse on the source (report: "
               "initial_map.located; off by default, the map does not depend on it)");
  cmd->add_option("--homotopy-extra-cuts", a->homotopy_extra_cuts,
                  "Genus >= 2: other systems of source loops whose lifted handle classes are added (other twist representatives)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-homotopy-search", a->no_homotopy_search,
               "Genus >= 2: no search in the mapping class group (Dehn twists) from the best candidate");
  cmd->add_option("--homotopy-search-evaluations", a->homotopy_search_evaluations,
                  "Genus >= 2: most coarse solves of the class search (report: homotopy.search)")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--homotopy-both-signs,!--no-homotopy-both-signs", a->homotopy_both_signs,
                "Genus 1 with landmarks: rank each flat class with both signs, M and -M (default on; "
                "--no-homotopy-both-signs: the canonical signs only; docs/handle_classes.md)");
  cmd->add_flag("--no-flat-overlay", a->no_flat_overlay,
                "Genus 1 without landmarks: place the map by the base vertices, not by the 3D overlay of the shapes "
                "(report: flat_placement; docs/handle_classes.md)");
  cmd->add_flag("--no-two-way", a->no_two_way,
                "Genus >= 2: do not map the other way when the energy is far above the conformal bound (report: quality)");
  cmd->add_flag("--no-through-shape", a->no_through_shape,
                "Genus >= 2: at energy ratio 3 or more, do not try the class through a generated n-hole torus of the "
                "same genus (docs/handle_classes.md \"Through generated shapes\")");
  cmd->add_option("--through-shape-ratio", a->through_shape_ratio,
                  "Genus >= 2: the energy ratio from which the class through a generated shape is tried, here or, "
                  "read the same way, in the other direction's run (default 3; "
                  "docs/handle_classes.md \"Through generated shapes\")")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-cheap-direction-check", a->no_cheap_direction_check,
                "Genus >= 2: when the other direction's ratio is not lower, keep this class without solving the other "
                "direction's class inverted here and this one there "
                "(docs/handle_classes.md \"The two directions today\")");
  cmd->add_option("--agreement-ratio", a->agreement_ratio,
                  "Genus >= 2, below the two-way run's ratio 2: from this energy ratio on (default 1.1) map the other "
                  "direction too and keep the pair of inverse classes of lower total energy, so that both directions "
                  "agree (report: quality.directions.agreement; about 3x the time; 2 or more: off; "
                  "docs/handle_classes.md \"The two directions today\")")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-greedy-pants", a->no_greedy_pants,
                "Genus >= 2: no classes from the greedy short pants decompositions in the geometric stage "
                "(docs/handle_classes.md \"Greedy pants classes\")");
  cmd->add_flag("--no-snapped-start", a->no_snapped_start,
                "Genus >= 2, sources without a coarse copy: every class from the origin, never from the snapped 3D "
                "overlay (docs/robustness.md \"High genus\")");
  cmd->add_flag("--classical-canonical-generators", a->classical_canonical_generators,
                "Genus >= 2: the classical canonical generators (cut-and-paste moves that conjugate the finished pairs; "
                "the default, accepted to say so; given, it also turns the automatic retry with the short ones off)");
  cmd->add_flag("--no-short-generators-fallback", a->no_short_generators_fallback,
                "Genus >= 2: when the classical canonical generators fail at their start edges, fail (default: run "
                "again with the short ones and say so in the report's notes; --classical-canonical-generators implies "
                "this)");
  cmd->add_flag("--no-fold-fallback", a->no_fold_fallback,
                "Genus >= 2: when every class of the default run (classical canonical generators) folds, fail "
                "(default: run once more with the short generators, one way, and say so in the report's notes; "
                "--classical-canonical-generators implies this)");
  cmd->add_flag("--short-canonical-generators", a->short_canonical_generators,
                "Genus >= 2: canonical generators from cut-and-paste moves that conjugate only the new pair, not the default "
                "classical ones (with --both-canonical-bases the candidate classes are listed in both; docs/robustness.md "
                "\"Session 23\"; report: canonical_generators)");
  cmd->add_flag("--both-canonical-bases", a->both_canonical_bases,
                "Genus >= 2: list the candidate classes in both canonical bases (classical and short) and twist-search "
                "the short basis's by its own twists (the default, accepted to say so; "
                "docs/robustness.md \"Canonical generators\", "
                "docs/handle_classes.md \"Classes named by words\")");
  cmd->add_flag("--one-canonical-basis", a->one_canonical_basis,
                "Genus >= 2: list the candidate classes in the run's canonical basis only (the default before session 25)");
  cmd->add_flag("--geometric-layout-basis", a->geometric_layout_basis,
                "Genus >= 2: the geometric classes read the target's lengths in the short canonical basis of its "
                "layout's word, then are written in its class loops' letters (off by default; docs/robustness.md "
                "\"Session 25\")");
  cmd->add_flag("--short-curve-twists", a->short_curve_twists,
                "Genus >= 2: the class search also moves by Dehn twists along each surface's short curves (its short "
                "marking's generators and short pants curves; off by default; docs/handle_classes.md)");
  cmd->add_option("--high-kicks", a->high_kicks,
                  "Genus >= 2: when the class search ends at 2x the conformal bound or more, this many kicks (random "
                  "moves of three twists, each followed by a short descent) from its best class (default 8, at most "
                  "8 x 25 coarse solves; 0: none; report: homotopy.search.high_kicks_status, kicks, lower_kicks; "
                  "docs/handle_classes.md)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--landmarks-may-fold", a->landmarks_may_fold,
                "Genus >= 1 with --landmarks: hold them by plain pins and keep the map where it folds (for its homotopy "
                "class; flipped_triangles counts the folds) instead of an error when they cannot be held bijectively");
  cmd->add_flag("--compare-directions", a->compare_directions,
                "Genus >= 2: always map the other way too and say whether the two directions' classes are inverse "
                "(report: quality.reverse_inverse; about 3x the time)");
  cmd->add_flag("--boundary-swap", a->boundary_swap,
               "Open annuli: map the source's boundary loop 0 (the longer) onto the target's loop 1 (docs/open_surfaces.md)");
  cmd->add_option("--boundary-pairing", a->boundary_pairing,
                  "Open surfaces: the target boundary loop of each source loop, by index (loops longest first; "
                  "e.g. '1 0' or '1,0'; default: loop i -> loop i)")
      ->delimiter(',');
  cmd->add_option("--refine-rings", a->refine_rings,
                  "Open surfaces through the doubles: where folds are left, the class is solved again on doubles "
                  "whose faces within this many rings of the boundary are split (default 4; report "
                  "open.refined_near_boundary)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--refine-levels", a->refine_levels,
                  "Open surfaces through the doubles: how many times those faces are split (default 2; 0: the "
                  "refinement fallback is off)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--no-reflection-solve", a->no_reflection_solve,
                "Open surfaces through the doubles: keep the doubles' own solve, without the reflection-aware solve "
                "of the half (report open.reflection_solve; docs/open_surfaces.md \"The half's solve\")");
  cmd->add_option("--target-metric", a->target_metric,
                  "Genus >= 1: the target's uniformization metric: auto (default: flips, fixed only when the flip "
                  "path fails; report: target_metric_choice), flips (Newton with intrinsic "
                  "Delaunay / Ptolemy flips, results carried back to the target's own faces), fixed (the target's "
                  "own edges, refined by altitude-foot splits when that metric does not exist) or fixed-first "
                  "(fixed, and flips only when the fixed metric cannot be delivered)")
      ->check(CLI::IsMember(enum_name_list<UniformizationMetric>()));
  cmd->add_option("--target-loops", a->target_loops,
                  "Flip path: lengths the target's loops are shortest in, as uniformize --loops: auto (default: 3D, "
                  "for genus >= 2 the metric when that layout fails or crowds |z| = 1), embedding or metric "
                  "(report: target_loop_metric)")
      ->check(CLI::IsMember(enum_name_list<LoopMetric>()));
  cmd->add_option("--face-charts", a->face_charts,
                  "Genus >= 2: auto (default: map in per-face charts of the target only when one Poincare chart "
                  "cannot hold its layout, e.g. CAD plates of genus >= 13), always (that path on every pair) or "
                  "never (stop with the single-chart error). The per-face path maps the snapped class of "
                  "near-identical shapes only, without class search or landmarks (report: face_charts)")
      ->check(CLI::IsMember(enum_name_list<FaceCharts>()));
  cmd->add_flag("--quiet", a->quiet, "No progress lines on stderr");
  cmd->add_flag("--timings", a->timings,
                "Print the stage table on stderr: per stage seconds, factorisations, Newton iterations, peak memory");
  cmd->add_option("--threads", a->threads,
                  "Threads the pipeline runs at once (0: SURFMAP_THREADS, else 2 with two cores; 1: in order); "
                  "the result does not depend on it")
      ->check(CLI::Range(0, 64));
  cmd->callback([a] {
    // The usual pair, two valid closed meshes, is read and checked once,
    // both at once (independent work; issue 19) unless --threads 1. Any
    // other pair (a boundary, a bad file) takes the path in order: open
    // surfaces (issue 16, map_open.h), else the closed intake's error, a bad
    // source reported first. (The open test used to read and check every
    // pair once more first, on one thread.)
    auto closed_or_none = [](const std::string& path) -> std::optional<IntakeResult> {
      try {
        return load_mesh(path);
      } catch (const InputError&) {
        return std::nullopt;
      }
    };
    auto load_target = std::async(a->threads == 1 ? std::launch::deferred : std::launch::async,
                                  [a, closed_or_none] { return closed_or_none(a->dst); });
    std::optional<IntakeResult> src_closed = closed_or_none(a->src), dst_closed = load_target.get();
    if (!src_closed || !dst_closed) {
      if (map_open_pair({a->src, a->dst, a->out, a->report, a->correspondence, a->initial_out, a->quiet,
                         a->landmarks, a->boundary_swap, a->boundary_pairing, a->refine_rings, a->refine_levels,
                         !a->no_reflection_solve}))
        return;
      if (!src_closed) src_closed = load_mesh(a->src);  // throws the source's error
      if (!dst_closed) dst_closed = load_mesh(a->dst);
    }
    if (a->boundary_swap || !a->boundary_pairing.empty())
      throw InputError("--boundary-swap / --boundary-pairing: only for open surfaces (meshes with boundary loops)");
    const IntakeResult src = std::move(*src_closed), dst = std::move(*dst_closed);
    check_same_genus(src.info, dst.info);
    SurfaceMapOptions opt;
    opt.homotopy.class_index = a->homotopy;
    if (!a->class_words.empty()) opt.homotopy.class_words = parse_class_words(a->class_words);
    opt.loops.source_base_vertex = a->base_vertex;
    opt.loops.target_base_vertex = a->target_base_vertex;
    if (a->short_canonical_generators && a->classical_canonical_generators)
      throw InputError("--short-canonical-generators and --classical-canonical-generators exclude each other");
    opt.loops.short_canonical_generators = a->classical_canonical_generators ? false
                                           : a->short_canonical_generators   ? true
                                                                             : SurfaceMapOptions().loops.short_canonical_generators;
    opt.loops.short_generators_fallback = !a->no_short_generators_fallback && !a->classical_canonical_generators;
    opt.loops.fold_fallback = !a->no_fold_fallback && !a->classical_canonical_generators;
    if (a->both_canonical_bases && a->one_canonical_basis)
      throw InputError("--both-canonical-bases and --one-canonical-basis exclude each other");
    opt.loops.both_canonical_bases = a->one_canonical_basis ? false
                                     : a->both_canonical_bases ? true
                                                               : SurfaceMapOptions().loops.both_canonical_bases;
    opt.homotopy.search.geometric_layout_basis = a->geometric_layout_basis;
    opt.homotopy.search.curve_twists = a->short_curve_twists;
    opt.homotopy.search.high_kicks = a->high_kicks;
    opt.solve.method = parse_enum<MapMethod>(a->method, "--method");
    opt.solve.source_weights = parse_enum<SourceWeights>(a->source_weights, "--source-weights");
    opt.solve.tolerance = a->tolerance;
    opt.solve.own_weights_floor = a->own_weights_floor;
    opt.solve.local_fold_repair = !a->no_local_fold_repair;
    opt.solve.fold_untangle = !a->no_fold_untangle;
    opt.solve.max_iterations = a->max_iterations;
    opt.homotopy.candidates = a->homotopy_candidates;
    opt.homotopy.full_solves = a->homotopy_full_solves;
    opt.initial.method = parse_enum<InitialMapMethod>(a->initial, "--initial-map");
    opt.initial.locate = a->locate_initial_map || !a->initial_out.empty();
    opt.uniformization.target_metric = parse_enum<UniformizationMetric>(a->target_metric, "--target-metric");
    opt.uniformization.loops = parse_enum<LoopMetric>(a->target_loops, "--target-loops");
    opt.uniformization.face_charts = parse_enum<FaceCharts>(a->face_charts, "--face-charts");
    opt.homotopy.extra_cuts = a->homotopy_extra_cuts;
    opt.homotopy.search.enabled = !a->no_homotopy_search;
    opt.homotopy.search.evaluations = a->homotopy_search_evaluations;
    opt.homotopy.two_way = !a->no_two_way;
    opt.homotopy.through_shape = !a->no_through_shape;
    opt.homotopy.search.greedy_pants = !a->no_greedy_pants;
    opt.homotopy.search.snapped_start = !a->no_snapped_start;
    opt.homotopy.flat_both_signs = a->homotopy_both_signs;
    opt.homotopy.flat_overlay = !a->no_flat_overlay;
    opt.homotopy.compare_directions = a->compare_directions;
    opt.homotopy.cheap_direction_check = !a->no_cheap_direction_check;
    opt.homotopy.agreement_ratio = a->agreement_ratio;
    opt.homotopy.through_shape_ratio = a->through_shape_ratio;
    opt.threads = a->threads;
    if (!a->landmarks.empty()) opt.landmarks = read_landmarks(a->landmarks);
    opt.landmarks_may_fold = a->landmarks_may_fold;
    // One line per stage and percent (the relaxation reports every few sweeps).
    std::string last_line;
    if (!a->quiet)
      opt.progress = [&last_line](const std::string& stage, double fraction) {
        std::ostringstream line;
        line << "surfmap: " << std::setw(3) << static_cast<int>(100 * fraction) << "% " << stage;
        if (line.str() != last_line) std::cerr << line.str() << "\n";
        last_line = line.str();
        return true;
      };
    // A layout out of the one chart's reach (SingleChartError) is named by
    // its file, as input errors are.
    const SurfaceMapResult m = [&] {
      try {
        return surface_map(src.mesh, dst.mesh, opt);
      } catch (const SingleChartError& e) {
        throw SingleChartError("'" + (e.mesh == "source" ? a->src : a->dst) + "': " + e.what(), e.mesh, e.layout_radius);
      }
    }();

    // Genus 0 with source faces delivered piecewise (SurfaceMapResult::
    // SourceSubdivision): the morph is the source's vertices at their images,
    // then the subdivision's new vertices, over the subdivision's triangles.
    const auto& pieces = m.source_subdivision;
    const int extra = pieces.faces.rows() ? static_cast<int>(pieces.forward.size()) : 0;
    RowMatrixX3d morph(src.mesh.num_vertices() + extra, 3);
    for (int i = 0; i < src.mesh.num_vertices(); ++i) morph.row(i) = m.forward[i].position.transpose();
    for (int k = 0; k < extra; ++k) morph.row(src.mesh.num_vertices() + k) = pieces.forward[k].position.transpose();
    const RowMatrixX3i& morph_faces = pieces.faces.rows() ? pieces.faces : src.mesh.F;
    // The report: map/map_report.h (the same keys as the Python result),
    // plus the file names and the intake notes of both meshes.
    nlohmann::json notes = nlohmann::json::array();
    for (const auto* r : {&src, &dst})
      for (const auto& n : r->info.notes) notes.push_back((r == &src ? "source: " : "target: ") + n);
    if (!m.canonical_generators_fallback.empty()) notes.push_back("map: " + m.canonical_generators_fallback);
    if (!m.fold_fallback.empty()) notes.push_back("map: " + m.fold_fallback);
    nlohmann::json report = to_json(m, opt);
    report["source"] = a->src;
    report["target"] = a->dst;
    report["notes"] = notes;
    // Everything is computed before anything is written, and each file is
    // written atomically: a failure leaves no half-written output.
    std::string corr;
    if (!a->correspondence.empty()) {
      // Forward lines as before, then the inverse section (verify/correspondence_file.h).
      std::vector<SurfacePoint> forward, inverse;
      for (const auto& p : m.forward) forward.push_back({p.face, p.barycentric});
      for (const auto& p : m.inverse) inverse.push_back({p.face, p.barycentric});
      corr = correspondence_text(forward, inverse);
    }
    if (!a->initial_out.empty() && m.initial_forward.empty())
      throw InputError("--initial-out: this map has no located initial map (genus 0)");
    write_obj(a->out, morph, morph_faces);
    if (!a->initial_out.empty()) {
      RowMatrixX3d before(src.mesh.num_vertices(), 3);
      for (int i = 0; i < before.rows(); ++i) before.row(i) = m.initial_forward[i].position.transpose();
      write_obj(a->initial_out, before, src.mesh.F);
    }
    write_text_file(a->report, report.dump(2) + "\n");
    if (!a->correspondence.empty()) write_text_file(a->correspondence, corr);
    if (a->timings) std::cerr << stage_table(m);
    if (!a->quiet) {
      std::cerr << "surfmap: mean dilatation " << m.mean_dilatation << ", max " << m.max_dilatation
                << (m.thin_source_faces.empty()
                        ? std::string()
                        : " (" + std::to_string(m.thin_source_faces.size()) +
                              " thin source faces left out: D' below the solvers' resolution)")
                << ", flipped triangles " << m.flipped_triangles
                << (std::isfinite(m.energy_ratio) ? ", energy / 8 pi (g - 1) " + std::to_string(m.energy_ratio) : std::string())
                << ", " << m.total_time << " s\n";
      if (!m.quality_warning.empty()) std::cerr << "surfmap: warning: " << m.quality_warning << "\n";
      if (!m.directions.outcome.empty())
        std::cerr << "surfmap: both directions: " << m.directions.outcome << " (" << m.directions.reason << ")\n";
      else if ((opt.homotopy.compare_directions || !m.directions.agreement.empty()) && !m.directions.reason.empty())
        std::cerr << "surfmap: both directions: " << m.directions.reason << "\n";
      if (!opt.landmarks.empty() && !m.landmark_method.empty())
        std::cerr << "surfmap: " << opt.landmarks.size() << " landmark(s) held by "
                  << (m.landmark_method == "pinned" ? std::string("plain pins") : m.landmark_method)
                  << (m.landmark_steps ? " (" + std::to_string(m.landmark_steps) + " continuation steps)" : std::string())
                  << ", " << m.landmark_solves << " held solve(s)\n";
    }
  });
}

}  // namespace surfmap::cli
