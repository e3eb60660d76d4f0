// Genus >= 2: the hyperbolic case of the optimal map (docs/method.md §2.8 and its
// notes). map_hyperbolic is the driver: a page of stage calls in the
// order of the paper; the stages live in stages/ (one file each, with
// their inputs, outputs and paper sections), and HyperbolicPipeline below
// only holds what the stages hand each other.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <future>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "class_bound_support.h"
#include "concurrency.h"
#include "landmarks.h"
#include "map_support.h"
#include "stages/chart_elements.h"
#include "stages/class_data.h"
#include "stages/class_ranking.h"
#include "stages/class_search.h"
#include "stages/coarse_level.h"
#include "stages/coarse_race.h"
#include "stages/harmonic_solve.h"
#include "stages/homotopy_classes.h"
#include "stages/other_basis.h"
#include "stages/hyperbolic_location.h"
#include "stages/fold_repair.h"
#include "stages/hyperbolic_quality.h"
#include "stages/initial_map_stage.h"
#include "stages/landmark_ranking.h"
#include "stages/source_cuts.h"
#include "stages/source_side.h"
#include "stages/source_weights_fallback.h"
#include "stages/snapped_start.h"
#include "surfmap/error.h"
#include "surfmap/geometry/positive_edge_weights.h"
#include "surfmap/map/fundamental_polygon.h"
#include "surfmap/map/geometric_classes.h"
#include "surfmap/map/harmonic_relaxation.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/map/initial_map.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/outer_automorphisms.h"
#include "surfmap/topology/projected_loops.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap::detail {
namespace {

using hyperbolic::Mobius;

// Issue 19: the ranking's coarse solves stop at this gradient tolerance
// (HyperbolicHarmonicOptions::tolerance), or at the solve's own when that is
// looser. Their energies are the ranking's estimates (the coarse copy's
// discretisation moves them by ~0.3%, the ranking's ties are judged to
// 1e-6) and their solutions only start the full-resolution solves, which
// converge to solve.tolerance from wherever they start. Newton's energy
// error goes like the gradient squared (~1e-14 here), while the last
// decades of gradient cost 1-4 of the 11-19 steps of a solve from the
// origin (their tails converge linearly, 5-20x per step, on the 5k bench
// pair).
constexpr double kRankingTolerance = 1e-7;

// Why a solve of the class search is not usable ("" when it is): not
// converged (its steps and last gradient) or not finite.
std::string solve_failure(const HyperbolicHarmonicResult& r) {
  bool finite = std::isfinite(r.energy);
  for (size_t i = 0; i < r.z.size() && finite; ++i) finite = std::isfinite(std::abs(r.z[i]));
  if (!finite) return "non-finite energy or positions";
  if (r.converged) return "";
  return "not converged after " + std::to_string(r.iterations) + " iterations (energy " + std::to_string(r.energy) +
         ", last gradient " + (r.gradient_history.empty() ? std::string("?") : std::to_string(r.gradient_history.back())) +
         ")";
}

// HomotopySearchOptions::high_kicks and high_kick_ratio (InputError).
void check_high_kicks(const HomotopySearchOptions& s) {
  if (s.high_kicks < 0) throw InputError("high_kicks must be at least 0, got " + std::to_string(s.high_kicks));
  if (!(s.high_kick_ratio >= 0))
    throw InputError("high_kick_ratio must be at least 0 (not NaN), got " + std::to_string(s.high_kick_ratio));
}

// Adds a restarted twist search's figures to the search's account `info`:
// the start, the evaluation and screening counts, the time, and the moves
// it evaluated (tagged with the candidate it started from).
void add_restart_figures(HomotopySearchInfo& info, const HomotopySearchInfo& run, int start) {
  info.starts.push_back(start);
  info.evaluations += run.evaluations;
  info.kicks += run.kicks;
  info.lower_kicks += run.lower_kicks;
  info.screened += run.screened;
  info.time_s += run.time_s;
  for (size_t q = 0; q < run.evaluated_moves.size(); ++q) {
    info.evaluated_moves.push_back("[from " + std::to_string(start) + "] " + run.evaluated_moves[q]);
    info.evaluated_step.push_back(run.evaluated_step[q]);
    info.evaluated_screen.push_back(run.evaluated_screen[q]);
    info.evaluated_energy.push_back(run.evaluated_energy[q]);
  }
}

// What the stages of one genus >= 2 map hand each other. The members are
// filled in the order of the methods; each method is one step of the
// driver (map_hyperbolic, below) and calls the stage functions of stages/.
class HyperbolicPipeline {
 public:
  HyperbolicPipeline(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                     const SurfaceMapOptions& options, const testing::MapHooks& hooks, SurfaceMapResult& out,
                     const StageDone& stage_done)
      : source(source), target(target), sc(sc), tc(tc), options(options), hooks(hooks), out(out),
        stage_done(stage_done), threads(pipeline_threads(options.threads)), nv(source.num_vertices()),
        own_weights(options.solve.source_weights == SourceWeights::OwnEdges), cuts(source, sc, options, out.genus) {}

  void start_source_side();
  void uniformize_target();
  /// The source's default canonical generators in the other basis
  /// (stages/other_basis.h), none unless LoopOptions::both_canonical_bases.
  std::vector<Word> other_default_generators(const SourceSide& side) const {
    if (!options.loops.both_canonical_bases) return {};
    return canonical_schema(side.sl.word, other_schema_options(options)).generators;
  }
  void start_class_bounds();
  void candidate_classes_and_data();
  void rank_on_coarse_copy();
  void search_classes();
  void solve_at_full_resolution(bool after_coarse);
  void fill_class_bounds();
  ~HyperbolicPipeline() { leaving = true; }  // (an early bounds task stops at its next Newton step)
  void choose_with_landmarks();
  void compare_with_carried_class();
  void compare_directions();
  void geometric_classes_at_full_resolution();
  void twist_search_at_full_resolution();
  CoarseSolve full_resolution_solve(double& best, double max_start_edge_size = 0);
  int append_full_class(HomotopyClass hc, ClassData cd, CoarseEvaluation& ev);
  void map_in_chosen_class();
  void release_unsolved_class_data();
  std::vector<int> accept_long_starts(bool coarse);
  const ClassData& data_for(int k);
  void build_solver_data(const std::vector<int>& classes);

  // Inputs.
  const TriMesh& source;
  const TriMesh& target;
  const Connectivity& sc;
  const Connectivity& tc;
  const SurfaceMapOptions& options;
  const testing::MapHooks& hooks;
  SurfaceMapResult& out;
  const StageDone& stage_done;
  const int threads, nv;
  bool own_weights;

  // The source side (stages/source_side.h), built on the second thread while
  // the target is uniformized, and the other cuts (stages/source_cuts.h).
  SourceCuts cuts;
  std::promise<SourceSide> source_promise;
  std::future<SourceSide> source_future = source_promise.get_future();
  SourceSide ss;
  // How much of the source side the second thread has built
  // (build_source_side's steps), for the stage's progress points.
  std::atomic<double> side_done{0};
  // The ranking's and the full-resolution solves' progress inside their
  // stages (session 30: the ranking is a genus-2 run's longest stage, 20 s
  // of 31 s with a 50k-vertex source, and the other direction's of a
  // 268-vertex block held the bar for 52 s): the classes solved of those
  // to solve make 80% of the stage; the time after them (the class search,
  // whose number of solves is not known ahead) the rest, 1 - 1 / (1 + t / T)
  // of it, T the time the classes took (all of a stage with no classes
  // planned: the small sources' geometric classes and twist search, T the
  // ranking's). Fractions: the ranking 0.4 .. ranking_end (0.6; 0.5 without
  // a coarse copy, when the search at full resolution takes longest), the
  // full-resolution solves and searches .. 0.68, the initial map 0.7, the
  // harmonic solve .. 0.8, the quality 0.83, the forward location 0.9. (Read
  // by the progress hooks, on the calling thread.)
  using Clock = std::chrono::steady_clock;
  std::atomic<int> solved_in_stage{0}, to_solve_in_stage{1};
  double ranking_end = 0.6;
  static constexpr double kFullSolvesEnd = 0.68;
  Clock::time_point stage_start = Clock::now(), classes_done;
  double classes_seconds = 1;
  bool classes_all_done = false;
  void count_in_stage(int to_solve) {
    solved_in_stage = 0;
    to_solve_in_stage = to_solve;
    if (classes_all_done) classes_seconds = std::max(0.5, seconds_between(stage_start, classes_done));
    stage_start = Clock::now();
    classes_all_done = false;
  }
  double in_stage() {
    const int total = to_solve_in_stage;
    const double classes = total > 0 ? 0.8 : 0.0;
    if (total > 0 && solved_in_stage < total) return classes * solved_in_stage / total;
    if (!classes_all_done) {
      classes_all_done = true;
      classes_done = Clock::now();
      if (total > 0) classes_seconds = std::max(0.5, seconds_between(stage_start, classes_done));
    }
    const double t = seconds_between(classes_done, Clock::now());
    return classes + (1 - classes) * (1 - 1 / (1 + t / classes_seconds));
  }
  // The full-resolution solves and searches report from the ranking's end
  // to kFullSolvesEnd (the class search's Newton steps, through `ho`).
  void report_full_resolution_solves() {
    if (options.progress)
      ho.progress = [this](int, double, double) {
        return options.progress("full-resolution solve", ranking_end + (kFullSolvesEnd - ranking_end) * in_stage());
      };
  }
  static double seconds_between(Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
  }
  // A progress point inside the stage "source homotopy data and weights"
  // (0.3 to 0.4; the candidate classes take its last 0.02): the side's
  // fraction done. Throws Cancelled when the callback says stop.
  void source_side_point(double side_fraction) const {
    if (options.progress && !options.progress("source homotopy data and weights", 0.3 + 0.08 * side_fraction))
      throw Cancelled("cancelled in the stage source homotopy data and weights");
  }
  // The target: uniformization, canonical schema, deck group, polygon P.
  std::unique_ptr<UniformizedTarget> ut;
  CanonicalSchema tcs;
  std::unique_ptr<DeckGroup> deck_group;
  std::unique_ptr<FundamentalPolygon> polygon;
  // The candidate classes (stages/homotopy_classes.h) and per class k: its
  // data (stages/class_data.h), whether it can still be chosen, the coarse
  // estimate's solve, the full-resolution solve, the landmark holds.
  std::unique_ptr<ClassSpace> space;
  std::unique_ptr<LoopProjector> projector;
  std::unique_ptr<OtherBasis> other_basis;  ///< the other canonical basis (stages/other_basis.h)
  CandidateClasses candidates;
  SolverEdgeIndex solver_index;
  std::vector<ClassData> data;  ///< per class; released ones (data_released) are empty until data_for
  /// Issue 19 (memory): classes whose data were released before the
  /// full-resolution solves (release_unsolved_class_data); data_for builds
  /// them again (a fallback). Shorter than data: the rest are not released.
  std::vector<char> data_released;
  std::vector<char> usable, coarse_failed, full;
  /// Solves of this run refused at their start edges (SolveFailure::
  /// start_edges: a candidate's, a geometric class's, a search neighbour's):
  /// a run that then fails in every class fails with that reason, which the
  /// short-generators retry reads (map/surface_map.cpp). Atomic: the class
  /// search's solves may run on other threads.
  std::atomic<int> start_edge_refusals{0};
  void note_refusal(const SolveError& e) {
    if (e.reason() == SolveFailure::start_edges) ++start_edge_refusals;
  }
  /// The reason a failure of this run carries: start_edges once a solve was refused so.
  SolveFailure refusal_reason() const {
    return start_edge_refusals > 0 ? SolveFailure::start_edges : SolveFailure::unspecified;
  }
  std::vector<char> not_ranked;  ///< classes the ranking did not solve (issue 19; still fallbacks)
  std::vector<int> order;  ///< classes by coarse energy
  int ncand = 0, full_solves = 0;
  HyperbolicHarmonicOptions ho;  ///< the ranking's solves
  /// Issue 13: sources without a coarse copy start each full-resolution
  /// solve from the overlay (stages/snapped_start.h) when that start has the
  /// lower energy; built at the first such solve (ensure_snapper).
  std::unique_ptr<SnappedStartBuilder> snapper;
  void add_snapped_class();
  void ensure_snapper() {
    if (!snapper && options.homotopy.search.snapped_start) {
      snapper = std::make_unique<SnappedStartBuilder>(source, target, ut->loops.mesh, ut->layout, *deck_group, *polygon);
      snapper->use_source_paths(sc, ss.idt);
    }
  }
  /// A full-resolution solve of `edges` from the better start of the origin
  /// and the snapped overlay (ensure_snapper first; the overlay only with
  /// HomotopySearchOptions::snapped_start). `snapped` (optional): set when
  /// the snapped start was solved from. A snapped start the solve refuses
  /// falls back to the origin.
  HyperbolicHarmonicResult solve_from_better_start(const std::vector<WeightedEdge>& edges,
                                                   const HyperbolicHarmonicOptions& o, bool* snapped = nullptr) {
    if (snapped) *snapped = false;
    if (snapper) {
      const SnappedStart s = (*snapper)(edges);
      if (s.better()) {
        try {
          HyperbolicHarmonicResult r = solve_from(nv, edges, s.z, s.deck, o);
          if (snapped) *snapped = true;
          return r;
        } catch (const SolveError&) {
          // (refused or failed from there: the origin as before)
        }
      }
    }
    return solve_from(nv, edges, std::vector<Complex>(nv, Complex(0.0)), std::vector<Word>(nv), o);
  }
  PatternSolver fine_solver, coarse_solver;
  CoarseLevel level;
  std::vector<HyperbolicHarmonicResult> coarse_result;
  std::vector<std::unique_ptr<HyperbolicHarmonicResult>> fine_result, held_result;
  std::vector<LandmarkHold> held_record;
  // The class most likely chosen (the requested one, or the ranking's
  // leader) and its initial map when it was computed next to the
  // full-resolution solves.
  int likely_class = -1;
  std::unique_ptr<ClassInitialMap> likely_init;
  /// Issue 19 (session 23): the source's letters as a target from its own
  /// loops (compare_directions), built next to the full-resolution solves
  /// on the second thread when they will be read (letters_from_own_loops).
  std::optional<SourceLetters> letters_ahead;
  /// Issue 19 (session 23): what the location walks over (the target's
  /// cover, both surfaces' neighbours), built next to the full-resolution
  /// solves on the second thread; null: built by the location.
  std::shared_ptr<const LocationCover> cover_ahead;
  HyperbolicLocationInput cover_input() const {
    HyperbolicLocationInput li;
    li.source = &source, li.target = &target, li.target_loops = &ut->loops, li.layout = &ut->layout;
    li.polygon = polygon.get();
    return li;
  }
  bool letters_from_own_loops() const {
    const UniformizationMetric policy = options.uniformization.target_metric;
    return !have_class_bounds && options.homotopy.reverse_class.empty() &&
           (policy == UniformizationMetric::Automatic || policy == UniformizationMetric::IntrinsicDelaunay);
  }
  // Per class, its free energy at full resolution with the intrinsic
  // Delaunay weights, kept when the weights fall back to the source's own
  // edges (SurfaceMapResult::intrinsic_class_energy); NaN: none.
  std::vector<double> intrinsic_energy;
  /// Why the automatic weights fell back to the source's own edges (the
  /// intrinsic map's fold counts), a note of the result; empty otherwise.
  std::string own_weights_reason;
  /// The local fold repair's record (stages/fold_repair.h), kept across the
  /// global fallback's second pass (SurfaceMapResult::fold_repair).
  SurfaceMapResult::FoldRepair fold_repair;
  /// Issue 13: the intrinsic-weight optimum of the class that fell back to
  /// the own-edge weights (retry_class), the start of its second solve.
  std::unique_ptr<HyperbolicHarmonicResult> retry_start;
  int retry_class = -1;
  /// Issue 13: set when every candidate's start was refused at the start-edge
  /// limit (accept_long_starts); the pipeline's later solves accept start
  /// edges up to geometric_start_edge_size.
  bool long_starts = false;

  // Raised on the way out (declared before the second thread, so it outlives
  // it): the second thread then prepares no more cuts.
  std::atomic<bool> leaving{false};
  // The second thread (joined on the way out, after the flags are raised:
  // members are destroyed in reverse order).
  std::future<void> side_thread;
  struct RaiseOnExit {
    std::atomic<bool>& flag;
    ~RaiseOnExit() { flag = true; }
  } raise_cut_prep_stop{cuts.stop};
  RaiseOnExit raise_leaving{leaving};
  // The source's own uniformization for the class lower bounds
  // (class_bound_support.h), built next to the candidates and the ranking;
  // declared after everything its task reads (source, ss, options), so it is
  // waited for before they are destroyed on the way out.
  std::future<SourceClassBounds> class_bounds_future;
  SourceClassBounds class_bounds;  ///< from the future, once needed
  bool have_class_bounds = false;
  /// Issue 19: the bounds every comparison with coarse energies reads (the
  /// ranking's pruning, the class search's), computed on the coarse copy
  /// itself (coarse_class_bounds: the surface those energies are measured
  /// on, at a quarter of the source's vertices or fewer); the source's own
  /// uniformization (class_bounds) only where a decision reads full-resolution
  /// energies or the source's own geometry (ranking_bounds_now).
  std::future<SourceClassBounds> coarse_bounds_future;
  SourceClassBounds coarse_bounds;
  bool have_coarse_bounds = false;
  /// Issue 19: the ranking stopped at its first class (classes_that_can_win),
  /// so the bounds decide nothing unless a later step asks for them.
  bool bounds_not_needed = false;
  /// Issue 19: no overlay class, so the ranking's first class is the
  /// canonical one, which is rarely within the ranking gap: the bounds are
  /// computed (and reported) whatever the ranking does, on the second thread
  /// from the candidates on (start_class_bounds_early).
  bool bounds_wanted = false;
  void start_class_bounds_early();
  std::unique_ptr<SurfaceGroupLengths> target_lengths;  ///< the target's, for the bounds
  const SourceClassBounds& class_bounds_now();
  const SourceClassBounds& ranking_bounds_now();
  void ensure_target_lengths() {
    if (!target_lengths) target_lengths = std::make_unique<SurfaceGroupLengths>(*deck_group, tcs.generators, ut->layout.word);
  }
  /// Issue 13 (session 25; HomotopySearchOptions::geometric_layout_basis):
  /// the target's lengths in the short canonical basis of its layout's own
  /// word, and that basis's generators as words in the class letters
  /// (tcs); null when the option is off or the basis could not be written
  /// in the class letters (said in homotopy_search.geometric_failures).
  std::unique_ptr<SurfaceGroupLengths> layout_basis_lengths;
  GroupMap layout_basis_in_class_letters;
  bool layout_basis_tried = false;
  void ensure_layout_basis();
  /// Issue 13 (session 27; HomotopySearchOptions::curve_twists): the twists
  /// along the two surfaces' short curves, in the run's class letters
  /// (source_curve_moves on the source side, target_curve_moves on the
  /// target side), made once, when the first twist search starts.
  std::vector<MappingClassMove> source_curve_moves, target_curve_moves;
  bool curve_moves_tried = false;
  void ensure_curve_moves();
  /// The target lengths the geometric classes read (after class_bounds_now)
  /// and the change of letters to pass with them (null: none).
  const SurfaceGroupLengths& geometric_target() {
    ensure_target_lengths();
    ensure_layout_basis();
    return layout_basis_lengths ? *layout_basis_lengths : *target_lengths;
  }
  const GroupMap* geometric_target_letters() const {
    return layout_basis_lengths ? &layout_basis_in_class_letters : nullptr;
  }

  HyperbolicHarmonicResult hold_in_class(int k, const HyperbolicHarmonicResult& free_k, const HyperbolicHarmonicOptions& o,
                                         bool relax, const HarmonicRelaxationOptions& ro, LandmarkHold& hold) const;
  void switch_to_own_weights();

 private:
  ClassData data_of(const GroupMap& theta) const {
    return class_data(*space, theta, source, sc, ss.edge_word, ss.idt, solver_index, ut->layout, *deck_group);
  }
  // Issue 19: a listed class's data. With a coarse copy, only its side words
  // (the coarse copy's input); the matrices and solver edges are built when
  // the class is first solved at full resolution (build_solver_data,
  // data_for). Without one, every class is solved at full resolution.
  ClassData listed_data_of(const GroupMap& theta) const {
    return class_data(*space, theta, source, sc, ss.edge_word, ss.idt, solver_index, ut->layout, *deck_group,
                      !ss.cs.ok);
  }
  HyperbolicHarmonicResult solve_from(int n, const std::vector<WeightedEdge>& edges, const std::vector<Complex>& start,
                                      const std::vector<Word>& deck_word, const HyperbolicHarmonicOptions& o) {
    return solve_with_decks(n, edges, start, deck_word, *deck_group, o, n == nv ? &fine_solver : &coarse_solver);
  }
  ClassInitialMap initial_of(int k, const std::atomic<bool>* stop, std::vector<Complex> start_z = {},
                             std::vector<Word> start_word = {}) const {
    return class_initial_map(data[k], source, sc, ss.sl, *deck_group, *polygon, options, stop, std::move(start_z),
                             std::move(start_word));
  }
  bool try_solve(int k, const std::function<HyperbolicHarmonicResult()>& solve, HyperbolicHarmonicResult& r,
                 bool coarse = false);
  int append_class(HomotopyClass hc, ClassData cd, const CoarseEvaluation& ev);
  struct FoundSearchClass {
    HomotopyClass hc;
    ClassData data;
  };
  std::optional<FoundSearchClass> found_search_class(const std::optional<CoarseEvaluation>& found, int start,
                                                     const std::vector<std::string>& start_twists,
                                                     const std::vector<std::string>& moves) const;
  int push_candidate(HomotopyClass hc, ClassData cd, HomotopyCandidate c);
  int early_ranked_class() const;
  bool ranks_every_class() const;
  bool unranked(int k) const { return k >= 0 && k < static_cast<int>(not_ranked.size()) && not_ranked[k]; }
  std::vector<int> classes_that_can_win(int first);
  void beaten_in_race(const std::vector<int>& rest, const std::vector<CoarseRaceOutcome>& outcomes);
  int skip_isometric_twins(int first, std::vector<int>& rest, const std::function<void(int, const std::string&)>& skip);
  void twist_search_from(int start, const std::vector<std::string>& start_twists, const CoarseSolve& solve,
                         HomotopySearchInfo& info, const SurfaceMapOptions* opts = nullptr, bool high_kicks = false);
  void kicks_when_high(int search_start, const std::vector<std::string>& start_twists, const CoarseSolve& solve,
                       bool full_resolution);
  HyperbolicHarmonicOptions fine_options(int k) const;
  // The other direction's class (inverted algebraically or carried) is
  // solved like a geometric class: its loops' images can be as long
  // untwisted (fertility -> genus-4 plate: the plate's class inverted had a
  // start edge of 80.5 units and was refused, so the two directions were
  // never compared; docs/handle_classes.md "The two directions today").
  void allow_long_start_edges(int k, HyperbolicHarmonicOptions& o) const {
    if (k >= 0 && (k == candidates.inverted_class || k == candidates.carried_class))
      o.max_start_edge_size = std::max(o.max_start_edge_size, options.homotopy.search.geometric_start_edge_size);
  }
};

// The source's side of the homotopy data needs no target: built on the
// second thread while the target is uniformized (concurrency.h; its errors
// are rethrown after the target's). With one thread it is built later, in
// order. The second thread then prepares the homotopy.extra_cuts' source
// parts (stages/source_cuts.h).
void HyperbolicPipeline::start_source_side() {
  if (threads <= 1) return;
  side_thread = std::async(std::launch::async, [this] {
    const SingleThreadedBlas single_threaded_blas;  // (per thread: OpenMP's levels)
    std::vector<WeightedEdge> pattern;
    try {
      // (Its steps stop it once the calling thread has left: a cancel.)
      SourceSide side = build_source_side(source, sc, options, own_weights, cuts.graph(), [this](double fraction) {
        side_done = fraction;
        return !leaving;
      });
      cuts.set_default(side.sl.loops, side.scs.generators, other_default_generators(side));
      SolverEdgeIndex index;
      index_solver_edges(sc, side.idt, index);
      pattern = solver_edge_pattern(sc, side.idt, index);
      source_promise.set_value(std::move(side));
    } catch (...) {
      source_promise.set_exception(std::current_exception());
      return;
    }
    // Issue 19: the source's own uniformization (class bounds) no longer
    // runs here next to the target's: it is computed when a decision first
    // needs it (class_bounds_now), which on a pair whose first class is
    // within the ranking gap of the conformal bound is never (a fifth of
    // the map's CPU on the 50k remeshed pair; docs/benchmarks.md).
    if (leaving) return;
    try {
      // The homotopy.extra_cuts, which are always lifted, last first:
      // the calling thread prepares them first first when it gets there
      // (stages/source_cuts.h: each once, whichever thread). Nothing else
      // speculative here: the machine's scheduler shares CPU between
      // sessions, not threads (autogroups), so under load speculative work
      // on this thread slows the other one down (10k genus 6, load 8, where
      // stage 1 does not run: 13-15 s with all 15 cuts prepared here
      // against 9-10 s).
      const int n = std::min(static_cast<int>(cuts.planned_bases().size()), options.homotopy.extra_cuts);
      for (int k = n - 1; k >= 0; --k) {
        if (cuts.stop) break;
        cuts.prepare_planned(k);
      }
    } catch (...) {
      // (prepared again where needed, which reports the error)
    }
    // Issue 19: the full-resolution solves' analysis (fill-reducing ordering
    // and symbolic factorisation of the pattern every class shares, ~0.1 s
    // at 50k source vertices), here next to the target's uniformization
    // instead of at the first full-resolution solve on the calling thread.
    // The same analysis either way: the same results.
    if (leaving) return;
    fine_solver.prepare(nv, pattern);
  });
}

// Target: hyperbolic metric, layout, canonical generators, the deck group
// (words are multiplied out through the polygon's side pairings, never
// through the loop generators' possibly huge matrices: deck_group.h) and
// the fundamental polygon P (map/fundamental_polygon.h). Then the source
// side (from the second thread, or built now).
void HyperbolicPipeline::uniformize_target() {
  ut = std::make_unique<UniformizedTarget>(uniformized_target(target, Background::Hyperbolic, options, &tc));
  record_target_metric(*ut, out);
  tcs = canonical_schema(ut->layout.word, schema_options(options));
  if (ut->class_loops) {
    // Flip path: the canonical generators of the target's own loops, on T'
    // (map_support.h ClassLoops); the loop letters the classes read are
    // those of the target's own loops (candidate_classes_and_data).
    tcs.generators = ut->class_loops->generators_in_layout_letters;
    tcs.letters = ut->class_loops->schema.letters;
  }
  {
    size_t fewest = SIZE_MAX, most = 0;
    for (const Word& g : tcs.generators) fewest = std::min(fewest, g.size()), most = std::max(most, g.size());
    out.canonical_generators = std::string(options.loops.short_canonical_generators ? "short" : "classical") +
                               ": target generators " + std::to_string(fewest) + " .. " + std::to_string(most) +
                               " layout letters";
  }
  deck_group = std::make_unique<DeckGroup>(ut->layout);
  polygon = std::make_unique<FundamentalPolygon>(ut->layout, *deck_group);
  stage_done("target uniformization", 0.3);
  // Progress points (and a cancel) inside the source side, which takes
  // seconds at 50k vertices (the coarse copy most): every 0.2 s while the
  // second thread finishes it, else at its steps.
  if (threads > 1) {
    while (source_future.wait_for(std::chrono::milliseconds(200)) != std::future_status::ready)
      source_side_point(side_done);
    ss = source_future.get();
  } else {
    ss = build_source_side(source, sc, options, own_weights, cuts.graph(), [this](double fraction) {
      source_side_point(fraction);
      return true;
    });
    cuts.set_default(ss.sl.loops, ss.scs.generators, other_default_generators(ss));
  }
  source_side_point(1);  // (then the candidate classes)
}

// Issue 14 (docs/handle_classes.md): the source in its own uniformization
// metric, for every candidate's energy lower bound from hyperbolic lengths
// (map/class_lower_bound.h). Issue 19: computed on the calling thread when
// first needed (a ranking or search decision, the report), never when the
// ranking stopped at its first class (bounds_not_needed).
void HyperbolicPipeline::start_class_bounds() {
  class_bounds_future = std::async(std::launch::deferred, [this] {
    return source_class_bounds(source, sc, ss.sl, ss.scs.generators, out.genus, options);
  });
}

// Issue 19: when the ranking solves every class (ranks_every_class) the
// bounds are computed for the report anyway; when no overlay class leads the
// candidates the ranking's first class (the least screen's) is rarely within
// the ranking gap, so the ranking will ask for the bounds after its first
// coarse solve: they are wanted (computed and reported whatever the ranking
// does, so the result does not depend on the threads) and, with two threads,
// start on the second one now, next to the class data and the coarse level,
// instead of waiting on the calling thread when the ranking gets there: the
// ranking's bounds, on the coarse copy when there is one (ranking_bounds_now).
// Pairs with an overlay class (remeshed or posed copies) keep them lazy.
void HyperbolicPipeline::start_class_bounds_early() {
  if (candidates.overlay_classes > 0 && !ranks_every_class()) return;
  bounds_wanted = true;
  if (threads <= 1) return;  // (computed when needed, at the latest by fill_class_bounds)
  // (The ranking's bounds: on the coarse copy when there is one.)
  if (ss.cs.ok) {
    coarse_bounds_future = std::async(std::launch::async, [this] {
      const SingleThreadedBlas single_threaded_blas;  // (per thread: OpenMP's levels)
      return coarse_class_bounds(ss.cs.mesh, source, ss.sl, ss.scs.generators, out.genus, options, &leaving);
    });
    return;
  }
  class_bounds_future = std::async(std::launch::async, [this] {
    const SingleThreadedBlas single_threaded_blas;  // (per thread: OpenMP's levels)
    return source_class_bounds(source, sc, ss.sl, ss.scs.generators, out.genus, options, &leaving);
  });
}

// The source's side of the bounds (waits for it the first time) and the
// target's lengths.
const SourceClassBounds& HyperbolicPipeline::class_bounds_now() {
  if (!have_class_bounds) {
    class_bounds = class_bounds_future.get();
    have_class_bounds = true;
  }
  ensure_target_lengths();
  return class_bounds;
}

// Issue 19: the bounds for comparisons with coarse energies: on the coarse
// copy when the ranking has one (from the second thread when started there),
// else the source's own (class_bounds_now). The copy's bounds bound the
// energies of maps from the copy, the surface the coarse energies are
// measured on; its hyperbolic lengths are within about 1% of the source's
// (docs/history/handle_classes.md "Bounds on the coarse copy").
const SourceClassBounds& HyperbolicPipeline::ranking_bounds_now() {
  if (!ss.cs.ok) return class_bounds_now();
  if (!have_coarse_bounds) {
    coarse_bounds = coarse_bounds_future.valid()
                        ? coarse_bounds_future.get()
                        : coarse_class_bounds(ss.cs.mesh, source, ss.sl, ss.scs.generators, out.genus, options);
    have_coarse_bounds = true;
  }
  // (A copy whose uniformization or loops failed: the source's own.)
  if (!coarse_bounds.ok) return class_bounds_now();
  ensure_target_lengths();
  return coarse_bounds;
}

// Every candidate's lower bound (HomotopyCandidate::class_lower_bound), and
// why they are missing when the source's uniformization failed. Issue 19:
// when the ranking stopped at its first class (within ranking_gap of the
// conformal bound, which every class's energy is above) and nothing else
// asked for them, no bound can change the choice: the source is not
// uniformized for the report alone, and the status says so.
void HyperbolicPipeline::fill_class_bounds() {
  if (bounds_not_needed && !bounds_wanted && !have_class_bounds && !have_coarse_bounds) {
    out.class_bound_status = "not computed: no decision needed them (the ranking " + out.ranking_status + ")";
    return;
  }
  // Issue 19: the source's own when a decision computed them, else the
  // ranking's (on the coarse copy when there is one).
  const SourceClassBounds& bounds = have_class_bounds ? class_bounds_now() : ranking_bounds_now();
  std::vector<GroupMap> class_maps;
  for (const HomotopyClass& hc : candidates.classes) class_maps.push_back(hc.map);
  detail::fill_class_bounds(bounds, *target_lengths, class_maps, out.candidates);
  out.class_bound_status = bounds.why;
  out.class_bound_time_s = bounds.time_s + (have_class_bounds && have_coarse_bounds ? coarse_bounds.time_s : 0.0);
  out.class_bound_vertices = bounds.ok ? (bounds.copy_vertices > 0 ? bounds.copy_vertices : nv) : 0;
}

// The candidate classes (stages/homotopy_classes.h) and each one's data
// (stages/class_data.h); classes too twisted to evaluate in double
// precision are listed as not solved.
void HyperbolicPipeline::candidate_classes_and_data() {
  space = std::make_unique<ClassSpace>(out.genus, ss.sl, ss.scs, tcs, ut->layout, *deck_group);
  const ClassLoops* cl = ut->class_loops.get();
  projector = std::make_unique<LoopProjector>(cl ? cl->loops : ut->loops, cl ? cl->word : ut->layout.word);
  // Issue 13/14 (docs/robustness.md "Canonical generators"): the classes of the
  // other canonical basis too (stages/other_basis.h).
  if (options.loops.both_canonical_bases) {
    other_basis = std::make_unique<OtherBasis>(out.genus, ss.sl, ss.scs, tcs, cl ? cl->schema : tcs,
                                               cl ? cl->word : ut->layout.word, ut->layout, *deck_group,
                                               other_schema_options(options));
  }
  candidates = candidate_classes(*space, source, ss.sl, ss.shb, cl ? cl->loops : ut->loops, cl ? cl->schema : tcs,
                                 *projector, options, cuts, other_basis.get());
  if (options.homotopy.extra_cuts > 0 && !ss.cs.ok) cuts.stop = true;  // no coarse copy: no class search, no more cuts needed
  if (!ss.cs.ok && options.homotopy.search.snapped_start) add_snapped_class();
  // The two-way run's class (issue 14): listed as one from the other direction.
  if (candidates.carried_class >= 0) out.reverse_candidates.push_back(candidates.carried_class);
  if (!candidates.carried_status.empty())
    out.reverse_status = "the loops carried by the target -> source map: " + candidates.carried_status;
  index_solver_edges(sc, ss.idt, solver_index);
  const std::vector<HomotopyClass>& classes = candidates.classes;
  ncand = static_cast<int>(classes.size());
  start_class_bounds_early();
  check_candidate_index(options.homotopy.class_index, ncand, "homotopy class");
  const double max_image_letters = space->max_image_letters();
  // The classes' data are independent: computed on both threads (issue 19),
  // then taken in order below, a class's error where it was thrown in order.
  std::vector<int> evaluable;
  for (int k = 0; k < ncand; ++k)
    if (space->loop_image_length(classes[k].map) <= max_image_letters) evaluable.push_back(k);
  std::vector<ClassData> computed(ncand);
  std::vector<std::exception_ptr> failed(ncand);
  parallel_for(threads, static_cast<int>(evaluable.size()), [&](int i, const std::atomic<bool>*) {
    const int k = evaluable[i];
    try {
      computed[k] = listed_data_of(classes[k].map);
    } catch (...) {
      failed[k] = std::current_exception();
    }
  });
  usable.assign(classes.size(), 1);
  for (size_t k = 0; k < classes.size(); ++k) {
    const HomotopyClass& hc = classes[k];
    const double letters = space->loop_image_length(hc.map);
    HomotopyCandidate c;
    c.description = hc.description;
    c.given_class = hc.given_class;
    c.words = hc.map;
    if (letters <= max_image_letters) {
      if (failed[k]) std::rethrow_exception(failed[k]);
      data.push_back(std::move(computed[k]));
    } else {
      data.emplace_back();
      usable[k] = 0;
      c.energy = std::numeric_limits<double>::infinity();
      c.solved = false;
      c.description += "  [not solved: the images of the source's loops have " + std::to_string(static_cast<long>(letters)) +
                       " letters, too twisted for double-precision deck elements]";
      if (options.homotopy.class_index == static_cast<int>(k))
        throw SolveError("homotopy class " + std::to_string(k) + " cannot be solved: the images of the source's loops have " +
                         std::to_string(static_cast<long>(letters)) + " letters in the target's group (at most " +
                         std::to_string(static_cast<long>(max_image_letters)) + " can be evaluated in double precision)");
    }
    for (int r = 0; r < hc.homology.rows(); ++r)
      for (int q = 0; q < hc.homology.cols(); ++q) c.homology.push_back(static_cast<int>(hc.homology(r, q)));
    out.candidates.push_back(c);
  }
  stage_done("source homotopy data and weights", 0.4);
}

// Issue 13: the snapped overlay's own class (stages/snapped_start.h), a
// candidate of sources without a coarse copy. The overlay classes carry the
// source's loops onto the target's loops in 3D and read their crossings;
// at genus 11 (the CAD plate onto itself or a remeshed copy) none of the
// classes listed that way was the identity's (its loops 1.8 .. 7.5 units
// long in the target, 12.7 .. 46.8 under every candidate). This class is
// read where the solve lives: the source's loops followed through the
// snapped map in the target's deck group, rewritten in canonical letters.
// A class the list already has (same fingerprint) is only marked.
// Not in a run that asks for one class alone: a class named by its words
// (run as class 0, it must come back as a one-entry list: the add-on keeps
// its pairings' list by that) or the other direction's class alone
// (reverse_class_only, the two-way run's single-class solves; session 25:
// on a remeshed genus-2 plate the snapped class, the identity's, was chosen
// over the twisted class asked for, test_newton_starts.cpp
// ReverseClassOnlyGetsNoSnappedClassBesideIt). images_only keeps it: on the
// open surfaces' doubles the snapped class is what brings the pants'
// twisted starts back untwisted (test_open_double.py).
void HyperbolicPipeline::add_snapped_class() {
  if (!options.homotopy.class_words.empty() || options.homotopy.reverse_class_only) {
    out.snapped_class_status = options.homotopy.reverse_class_only
                                   ? "not listed: the run solves the other direction's class alone (reverse_class_only)"
                                   : "not listed: the run solves the class named by its words alone (class_words)";
    return;
  }
  ensure_snapper();
  if (!snapper) return;
  auto note = [&](const std::string& s) { out.snapped_class_status = s; };
  const SnappedLoops loops = snapper->loop_images(sc, ss.sl.loops, ss.edge_word, ss.sl.word);
  if (!loops.why.empty() && !loops.ok) {
    note("not listed: " + loops.why);
    return;
  }
  out.snapped_inconsistent_faces = loops.inconsistent_faces;
  const std::string counts = std::to_string(loops.inconsistent_faces) + " of " + std::to_string(sc.num_faces()) +
                             " source faces inconsistent; image paths up to " + std::to_string(loops.longest_path) +
                             " target edges, " + std::to_string(loops.long_paths) + " of 2 or more";
  std::vector<Word> canonical_of_loop_letter;
  std::string why;
  if (!invert_canonical_generators(tcs.generators, ut->layout.word, tcs.letters, &canonical_of_loop_letter, &why)) {
    note("not listed: the target's canonical generators could not be inverted in its layout's letters: " + why);
    return;
  }
  GroupMap theta;
  if (!snapped_class_map(loops, ut->layout, *deck_group, canonical_of_loop_letter, ss.scs.generators, &theta, &why)) {
    note("not listed: " + why);
    return;
  }
  space->reduce(theta);
  if (!space->is_isomorphism(theta)) {
    note("not listed: not an isomorphism of the groups (" + counts + ")");
    return;
  }
  if (space->loop_image_length(theta) > space->max_image_letters()) {
    note("not listed: its loops' images are too long");
    return;
  }
  const std::string tag = "the snapped overlay's own class: each source vertex at its nearest target vertex, " +
                          std::to_string(loops.inconsistent_faces) + " source faces inconsistent";
  const std::vector<double> fp = space->fingerprint(theta);
  for (HomotopyClass& hc : candidates.classes)
    if (space->loop_image_length(hc.map) <= space->max_image_letters() &&
        ClassSpace::same_fingerprint(space->fingerprint(hc.map), fp)) {
      hc.description += "  [also " + tag + "]";
      out.snapped_class = static_cast<int>(&hc - candidates.classes.data());
      note("the same as class " + std::to_string(out.snapped_class) + " (" + counts + ")");
      return;
    }
  HomotopyClass hc;
  hc.map = theta;
  hc.homology = homology_matrix(theta, space->num_letters());
  std::string handles;
  handle_correspondence_of(ss.shb, candidates.target_basis, hc.homology, &hc.permutation, &hc.sign, &handles);
  hc.description = handles + "  [" + tag + "]";
  // (The same class in either basis: searched in the short one,
  // stages/other_basis.h.)
  hc.other_basis_map = OtherBasis::short_form(other_basis.get(), theta);
  candidates.classes.push_back(std::move(hc));
  out.snapped_class = static_cast<int>(candidates.classes.size()) - 1;
  note("listed as class " + std::to_string(out.snapped_class) + " (" + counts + ")");
}

// Runs a solve of class k; a class whose solve fails numerically (deck
// elements too large for double precision: very twisted classes) or does
// not converge is reported with infinite energy instead of failing the
// whole map, unless it was asked for. A failed coarse solve (`coarse`) of a
// class that must be solved anyway (requested, or the only one) only loses
// its estimate: it is then solved at full resolution from the origin.
bool HyperbolicPipeline::try_solve(int k, const std::function<HyperbolicHarmonicResult()>& solve,
                                   HyperbolicHarmonicResult& r, bool coarse) {
  std::string why;
  try {
    r = solve();
    bool finite = std::isfinite(r.energy);
    for (size_t i = 0; i < r.z.size() && finite; ++i) finite = std::isfinite(r.z[i].real()) && std::isfinite(r.z[i].imag());
    if (!finite) why = "non-finite energy or positions";
    else if (!r.converged)
      why = "did not converge in " + std::to_string(r.iterations) + " iterations (gradient " +
            std::to_string(r.gradient_history.empty() ? 0.0 : r.gradient_history.back()) + ")";
    else return true;
  } catch (const SolveError& e) {
    why = e.what();
    note_refusal(e);
  }
  const bool needed = options.homotopy.class_index == k || (options.homotopy.class_index < 0 && ncand == 1);
  if (needed && coarse) {
    coarse_failed[k] = 1;
    return false;
  }
  if (needed)
    throw SolveError("the harmonic map solve of homotopy class " + std::to_string(k) + " failed: " + why,
                     refusal_reason());
  usable[k] = 0;
  out.candidates[k].energy = std::numeric_limits<double>::infinity();
  out.candidates[k].solved = false;
  out.candidates[k].description += "  [solve failed: " + why + "]";
  return false;
}

// The requested class's full-resolution solve reports to solve_progress live.
HyperbolicHarmonicOptions HyperbolicPipeline::fine_options(int k) const {
  HyperbolicHarmonicOptions o = ho;
  allow_long_start_edges(k, o);
  if (options.homotopy.class_index == k && options.solve_progress)
    o.progress = [this](int it, double E, double g) {
      return options.solve_progress(it, E, g) && (!options.progress || options.progress("harmonic solve", 0.64));
    };
  return o;
}

// Ranking (docs/method.md §2.10). The energy of a class is a
// property of the two continuous surfaces, so every candidate is solved to
// convergence on a coarse copy of the source (map/coarse_source.h,
// stages/coarse_level.h; its vertices are fine vertices, its deck elements
// products of the fine ones along paths, so a coarse solution is also a
// start for the fine solve), and only the best by that estimate (and
// whichever are within kCoarseMargin of it, up to `homotopy.full_solves`)
// are solved at full resolution, from their coarse solutions prolonged to
// the fine vertices. The energy is geodesically convex, so that converged
// solve is the class's optimum: the chosen class is not solved again.
// Small sources (fewer than 4 coarse copies' worth of vertices) are ranked
// by full-resolution solves of every class instead. Returns through the
// members; false when there is no coarse copy.
void HyperbolicPipeline::rank_on_coarse_copy() {
  ho.tolerance = options.solve.tolerance;
  ho.max_iterations = options.solve.max_iterations;
  ho.relator = deck_group->side_relator();
  ho.reduce_point = [this](Complex& z) { return polygon->reduce(z); };
  ho.max_start_edge_size = options.homotopy.search.start_edge_size;
  if (options.progress)
    ho.progress = [this](int, double, double) {
      return options.progress("homotopy candidates", 0.4 + (ranking_end - 0.4) * in_stage());
    };
  count_in_stage(static_cast<int>(std::count(usable.begin(), usable.end(), 1)));
  coarse_failed.assign(ncand, 0);
  not_ranked.assign(ncand, 0);
  CoarseSource& cs = ss.cs;
  if (cs.ok)
    level = coarse_level(cs, sc, ss.edge_word, ss.sl, data, usable, *deck_group,
                         options.homotopy.search.enabled && !options.homotopy.images_only &&
                             options.homotopy.class_index < 0);
  if (!cs.ok) {
    // No coarse copy after all (coarse_level refused it): every class is
    // solved at full resolution, so every class needs its solver data.
    std::vector<int> all(ncand);
    for (int k = 0; k < ncand; ++k) all[k] = k;
    build_solver_data(all);
  }
  ranking_end = cs.ok ? 0.6 : 0.5;
  fine_result.resize(ncand);
  full.assign(ncand, 0);
  order.resize(ncand);
  for (int k = 0; k < ncand; ++k) order[k] = k;
  full_solves = options.homotopy.full_solves <= 0 ? ncand : std::min(options.homotopy.full_solves, ncand);
  if (!cs.ok) return;
  const int ncv = cs.mesh.num_vertices();
  const std::vector<Complex> corigin(ncv, Complex(0.0));
  const std::vector<Word> no_decks(ncv);
  coarse_result.resize(ncand);
  cuts.stop = true;  // the second thread is needed here
  // A coarse solve of class k; `progress` (optional) replaces the solve's
  // progress callback (another thread's stop flag, or the race's report).
  auto coarse_solve_with = [&](int k, const RaceProgress& progress) {
    HyperbolicHarmonicOptions o = ho;
    o.tolerance = std::max(ho.tolerance, kRankingTolerance);
    allow_long_start_edges(k, o);
    if (progress) o.progress = progress;
    const bool solved = try_solve(k, [&] { return solve_from(ncv, level.class_edges[k], corigin, no_decks, o); },
                                  coarse_result[k], true);
    ++solved_in_stage;
    if (!solved) return;
    out.candidates[k].coarse_energy = coarse_result[k].energy;
    out.candidates[k].energy = coarse_result[k].energy;
    out.candidates[k].solved = false;
  };
  auto coarse_solve = [&](int k, const std::atomic<bool>* stop) {
    coarse_solve_with(k, stop ? RaceProgress([stop](int, double, double) { return !*stop; }) : RaceProgress());
  };
  // Issue 19: the first candidate alone, then only the classes that can
  // still win (early_ranked_class, skip_classes_that_cannot_win), in a race
  // that stops a solve once it is clearly beaten (beaten_in_race).
  std::vector<int> rest;
  const int first = early_ranked_class();
  if (first >= 0) {
    coarse_solve(first, nullptr);
    ++out.ranking_coarse_solves;
    rest = classes_that_can_win(first);
    to_solve_in_stage = 1 + static_cast<int>(rest.size());
    out.ranking_coarse_solves += static_cast<int>(rest.size());
    CoarseRaceOptions ro;
    ro.threads = threads;
    ro.margin = kCoarseMargin;
    if (usable[first] && !coarse_failed[first]) ro.incumbent = out.candidates[first].energy;
    const std::vector<CoarseRaceOutcome> outcomes = coarse_race(
        static_cast<int>(rest.size()), ro,
        [&](int q, const RaceProgress& report) { coarse_solve_with(rest[q], report); },
        [this] { return !ho.progress || ho.progress(0, 0.0, 0.0); });
    beaten_in_race(rest, outcomes);
  } else {
    for (int k = 0; k < ncand; ++k)
      if (usable[k]) rest.push_back(k);
    to_solve_in_stage = static_cast<int>(rest.size());
    out.ranking_coarse_solves += static_cast<int>(rest.size());
    // Independent solves, on two threads (concurrency.h: only this thread
    // calls the progress callback, the other one sees a stop flag).
    parallel_for(threads, static_cast<int>(rest.size()),
                 [&](int q, const std::atomic<bool>* stop) { coarse_solve(rest[q], stop); });
  }
  const std::vector<int> again = accept_long_starts(true);
  to_solve_in_stage += static_cast<int>(again.size());
  out.ranking_coarse_solves += static_cast<int>(again.size());
  parallel_for(threads, static_cast<int>(again.size()),
               [&](int q, const std::atomic<bool>* stop) { coarse_solve(again[q], stop); });
  std::stable_sort(order.begin(), order.end(),
                   [&](int x, int y) { return out.candidates[x].energy < out.candidates[y].energy; });
}

// Issue 19: the classes whose coarse solves the race stopped as clearly
// beaten (stages/coarse_race.h: their energy's lower estimate above
// (1 + kCoarseMargin) times the lowest energy held at the same Newton step,
// so they could neither be chosen nor solved at full resolution) are not
// ranked: their estimate is infinite, their description says where they
// stopped, and they stay fallbacks (map_with_fallback), as the classes the
// bounds prune.
void HyperbolicPipeline::beaten_in_race(const std::vector<int>& rest, const std::vector<CoarseRaceOutcome>& outcomes) {
  int beaten = 0;
  for (size_t q = 0; q < rest.size() && q < outcomes.size(); ++q) {
    const CoarseRaceOutcome& o = outcomes[q];
    const int k = rest[q];
    if (!o.beaten) continue;
    char why[240];
    std::snprintf(why, sizeof why,
                  "its coarse solve was stopped at Newton step %d, energy %.6g (at least %.6g), above %g%% over %.6g, "
                  "the lowest coarse energy held at that step",
                  o.step, o.energy, o.lower, 100 * kCoarseMargin, o.held);
    not_ranked[k] = 1;
    ++out.ranking_skipped;
    out.candidates[k].energy = std::numeric_limits<double>::infinity();
    out.candidates[k].solved = false;
    out.candidates[k].description += std::string("  [not ranked: ") + why + "]";
    ++beaten;
  }
  if (beaten > 0)
    out.ranking_status += "; " + std::to_string(beaten) + (beaten == 1 ? " coarse solve" : " coarse solves") +
                          " stopped as clearly beaten";
}

// Issue 19: the class the ranking solves alone first, or -1 when every class
// is solved (below). With an overlay class (the shapes overlap), the earliest
// usable candidate, that class. Without one, the usable class of least
// ClassSpace::screen (the squared target lengths of the source loops'
// images over their source lengths, no solve; ties to the earlier), not the
// canonical class that heads the list: its energy sets how much the bounds
// prune and how early the race stops the others (on the 4.9k/6.9k bench pair
// the canonical class converges at 118.7 in 11 Newton steps, the least
// screen's, 2.22, is the winner at 26.09). Which class goes first changes no
// choice: the classes pruned or stopped are those that could not be chosen
// whatever ran first. Every class is solved (homotopy.ranking_gap < 0, every
// class asked for by homotopy.full_solves <= 0, a requested class,
// landmarks: their ranking is by the energy with the landmarks held, which
// the free energy's bounds do not bound; a test's search start, or at most
// two candidates).
bool HyperbolicPipeline::ranks_every_class() const {
  return options.homotopy.ranking_gap < 0 || options.homotopy.full_solves <= 0 || options.homotopy.class_index >= 0 ||
         !options.landmarks.empty() || hooks.homotopy_search_start >= 0 || ncand <= 2;
}

int HyperbolicPipeline::early_ranked_class() const {
  if (ranks_every_class()) return -1;
  int first = -1;
  for (int k = 0; k < ncand && first < 0; ++k)
    if (usable[k]) first = k;
  if (first < 0 || candidates.overlay_classes > 0) return first;
  double least = std::numeric_limits<double>::infinity();
  for (int k = first; k < ncand; ++k) {
    if (!usable[k]) continue;
    const double screen = space->screen(candidates.classes[k].map);
    if (screen < least) least = screen, first = k;
  }
  return first;
}

// Issue 19: after the coarse solve of `first`, the classes still worth a
// coarse solve. Every degree-1 map's energy is at least 8 pi (g - 1), so
// when `first` is within homotopy.ranking_gap of that bound no other class
// can be lower by more than the gap: none is solved. Otherwise a class whose
// curve lower bound (map/class_lower_bound.h) is above `first`'s coarse
// energy cannot win (the search's pruning rule): not solved either. Both
// tests read `first`'s coarse energy, not its full-resolution one, so they
// hold up to the coarse copy's discretisation error (a heuristic there). The
// classes not solved keep an infinite energy, say why in their description
// and stay fallbacks (map_with_fallback).
std::vector<int> HyperbolicPipeline::classes_that_can_win(int first) {
  const double conformal = conformal_bound(out.genus);
  const double e = out.candidates[first].energy;
  char why[200];
  std::vector<int> rest;
  auto skip = [&](int k, const std::string& reason) {
    not_ranked[k] = 1;
    ++out.ranking_skipped;
    out.candidates[k].energy = std::numeric_limits<double>::infinity();
    out.candidates[k].solved = false;
    out.candidates[k].description += "  [not ranked: " + reason + "]";
  };
  if (usable[first] && !coarse_failed[first] && e <= (1 + options.homotopy.ranking_gap) * conformal) {
    std::snprintf(why, sizeof why, "candidate %d's coarse energy %.6g is within %g%% of the conformal bound 8 pi (g - 1)",
                  first, e, 100 * options.homotopy.ranking_gap);
    out.ranking_status = std::string("stopped: ") + why;
    for (int k = 0; k < ncand; ++k)
      if (k != first && usable[k]) skip(k, why);
    bounds_not_needed = true;
    return rest;
  }
  const bool finite = usable[first] && !coarse_failed[first] && std::isfinite(e);
  const SourceClassBounds* bounds = finite ? &ranking_bounds_now() : nullptr;
  int pruned = 0;
  for (int k = 0; k < ncand; ++k) {
    if (k == first || !usable[k]) continue;
    const double b = bounds ? class_curve_bound_of(*bounds, *target_lengths, candidates.classes[k].map) : 0.0;
    if (b > e) {
      std::snprintf(why, sizeof why, "its curve lower bound %.6g is above candidate %d's coarse energy %.6g", b, first, e);
      skip(k, why);
      ++pruned;
    } else {
      rest.push_back(k);
    }
  }
  const int twins = skip_isometric_twins(first, rest, skip);
  out.ranking_status = pruned > 0 ? "pruned by the curve lower bounds: " + std::to_string(pruned) + " of " +
                                        std::to_string(ncand) + " classes not solved"
                                  : std::string(bounds && bounds->ok ? "no class ruled out by its curve lower bound"
                                                                     : "no curve lower bounds: every class solved");
  if (twins > 0)
    out.ranking_status += "; " + std::to_string(twins) + (twins == 1 ? " class" : " classes") +
                          " not solved as the same class as an earlier one up to an isometry of the target";
  return rest;
}

// Issue 19: drops from `rest` (increasing indices, without `first`) every
// class whose fingerprint (ClassSpace::fingerprint: the target lengths of
// the images of the probe curves x_j, x_i x_j^±1) is that of an earlier
// class kept (`first`, solved already, is always kept; so is an earlier
// class of its fingerprint, which would win the tie): the same class up to
// an isometry of the target (the criterion by which the candidate list drops lifted classes
// already known). An isometry of the target maps the class's harmonic maps
// onto the other's with the same energy, and energy ties go to the earlier
// candidate (choose_class, pick_full_solves), so the later one cannot be
// chosen: its coarse solve is not run (`skip` marks it "[not ranked: ...]";
// it stays a fallback). In genus 2 every class has such a twin, its
// composite with the hyperelliptic involution (an isometry of every genus-2
// surface): on the 5k bench pair candidates 4 and 7 ("handle 1 -> handle 1,
// handle 2 -> handle 2" with and without both half turns), coarse energies
// equal to 1e-15, the later one's solve 19 Newton steps. Returns how many
// were dropped.
int HyperbolicPipeline::skip_isometric_twins(int first, std::vector<int>& rest,
                                             const std::function<void(int, const std::string&)>& skip) {
  auto fingerprint_of = [&](int k) {
    return space->loop_image_length(candidates.classes[k].map) <= space->max_image_letters()
               ? space->fingerprint(candidates.classes[k].map)
               : std::vector<double>{};  // (not evaluable: same_fingerprint is false for it)
  };
  std::vector<int> in_order = rest;
  in_order.insert(std::upper_bound(in_order.begin(), in_order.end(), first), first);
  std::vector<std::pair<int, std::vector<double>>> kept;
  std::vector<int> solved;
  int twins = 0;
  for (int k : in_order) {
    std::vector<double> fp = fingerprint_of(k);
    int twin = -1;
    for (const auto& [j, fj] : kept)
      if (ClassSpace::same_fingerprint(fj, fp)) {
        twin = j;
        break;
      }
    if (k == first) {
      kept.push_back({k, std::move(fp)});
      continue;
    }
    if (twin >= 0) {
      skip(k, "the same class as candidate " + std::to_string(twin) +
                  " up to an isometry of the target (every probe curve's image has the same length), so the same "
                  "energy; ties go to the earlier candidate");
      ++twins;
      continue;
    }
    kept.push_back({k, std::move(fp)});
    solved.push_back(k);
  }
  rest = std::move(solved);
  return twins;
}

// The per-candidate lists every appended class extends alike (its
// description and homology copied into `c`); the caller adds the solve's
// own lists (coarse or full resolution). Returns the new index.
int HyperbolicPipeline::push_candidate(HomotopyClass hc, ClassData cd, HomotopyCandidate c) {
  c.description = hc.description;
  c.given_class = hc.given_class;
  c.words = hc.map;
  for (int r = 0; r < hc.homology.rows(); ++r)
    for (int q = 0; q < hc.homology.cols(); ++q) c.homology.push_back(static_cast<int>(hc.homology(r, q)));
  data.push_back(std::move(cd));
  candidates.classes.push_back(std::move(hc));
  out.candidates.push_back(std::move(c));
  usable.push_back(1);
  coarse_failed.push_back(0);
  not_ranked.push_back(0);
  order.push_back(ncand);
  return ncand++;
}

// Appends a class found after the ranking, with its coarse solve.
int HyperbolicPipeline::append_class(HomotopyClass hc, ClassData cd, const CoarseEvaluation& ev) {
  hc.map = ev.theta;
  hc.homology = homology_matrix(hc.map, space->num_letters());
  HomotopyCandidate c;
  c.coarse_energy = c.energy = ev.result.energy;
  c.solved = false;
  level.class_edges.push_back(ev.edges);
  coarse_result.push_back(ev.result);
  fine_result.emplace_back();
  full.push_back(0);
  const int k = push_candidate(std::move(hc), std::move(cd), std::move(c));
  std::stable_sort(order.begin(), order.end(),
                   [&](int x, int y) { return out.candidates[x].energy < out.candidates[y].energy; });
  return k;
}

// The class search (stages/class_search.h), on the coarse copy: stage 1,
// when the best class is far from the conformal bound 8 pi (g - 1), lifts
// from homotopy.search.cuts more source cuts (the bench pair
// n_hole_torus(2) -> vase at 50k vertices gets its geometric class, E 25.96
// and mean D' 1.36, only this way: the 3 default cuts give 66.8, D' 5.41,
// and no twist neighbour of that class is lower); stage 2, the twist
// search from the best class. Every map of degree 1 onto the hyperbolic
// target has E >= 2 x its area = 8 pi (g - 1) (|df|^2 >= 2 J_f, equality
// for conformal maps), so a start within homotopy.search.gap of that bound
// leaves nothing worth a search (the coarse energies of good classes sit
// 0.3-4% above it: 75.8 vs 75.4 at genus 4, 26.0 vs 25.1 for the genus-2
// demo pair).
void HyperbolicPipeline::search_classes() {
  const int ncv = ss.cs.mesh.num_vertices();
  const std::vector<Complex> corigin(ncv, Complex(0.0));
  const std::vector<Word> no_decks(ncv);
  // A converged coarse solve of class theta from the origin (false when it
  // fails or does not converge; ev->failure says why), with solve options `o`.
  const auto solve_coarse_with = [&](const HyperbolicHarmonicOptions& o) -> CoarseSolve {
   return [&, o](const GroupMap& theta, CoarseEvaluation* ev) {
    ++out.homotopy_search.coarse_solves;
    try {
      *ev = CoarseEvaluation{theta, level.edges_of(*space, theta, ut->layout, *deck_group), {}, {}};
      ev->result = solve_from(ncv, ev->edges, corigin, no_decks, o);
      ev->failure = solve_failure(ev->result);
      return ev->failure.empty();
    } catch (const SolveError& e) {
      ev->theta = theta;
      ev->failure = e.what();
      note_refusal(e);
      return false;
    }
   };
  };
  const CoarseSolve solve_coarse = solve_coarse_with(ho);
  // Issue 14 (docs/handle_classes.md): a class whose curve lower bound
  // (map/class_lower_bound.h) is above the lowest coarse energy held cannot
  // win: not solved (counted in homotopy_search.pruned). With start twists
  // (testing/map_hooks.h) the start is evaluated first, unpruned.
  double best_held = hooks.homotopy_search_start_twists.empty() && usable[order[0]] ? out.candidates[order[0]].energy
                                                                                      : std::numeric_limits<double>::infinity();
  // (The geometric classes' solves accept longer start edges: their loops'
  // images can be 25-100 units long untwisted; HomotopySearchOptions::
  // geometric_start_edge_size.)
  HyperbolicHarmonicOptions geometric_ho = ho;
  geometric_ho.max_start_edge_size = std::max(ho.max_start_edge_size, options.homotopy.search.geometric_start_edge_size);
  const auto pruned_with = [&](const CoarseSolve& unpruned_solve) -> CoarseSolve {
   return [&, unpruned_solve](const GroupMap& theta, CoarseEvaluation* ev) {
    const SourceClassBounds& bounds = ranking_bounds_now();  // (sets target_lengths)
    const double curve_bound = class_curve_bound_of(bounds, *target_lengths, theta);
    if (curve_bound > best_held) {
      ++out.homotopy_search.pruned;
      ev->failure = "pruned: curve bound " + std::to_string(curve_bound) + " above the best coarse energy " +
                    std::to_string(best_held);
      return false;
    }
    if (!unpruned_solve(theta, ev)) return false;
    best_held = std::min(best_held, ev->result.energy);
    return true;
   };
  };
  const CoarseSolve pruned_solve = pruned_with(solve_coarse);
  const CoarseSolve geometric_solve = pruned_with(solve_coarse_with(geometric_ho));
  const bool searching = !level.source_word.empty();
  const double conformal_bound = surfmap::conformal_bound(out.genus);
  const double gap_bound = (1 + options.homotopy.search.gap) * conformal_bound;
  // (order[0] not usable: every candidate failed, energy +inf; issue 13.)
  // (Given classes: only the twists from the best of them, no other kind of
  // class: HomotopyOptions::given_class.)
  const bool given = !options.homotopy.given_class.empty();
  if (searching && !given && candidates.lifter && options.homotopy.search.cuts > 0 && hooks.homotopy_search_start < 0 &&
      out.candidates[order[0]].energy > gap_bound)
    for (FoundClass& f : classes_from_more_cuts(*candidates.lifter, cuts, *space, nv, threads, conformal_bound,
                                                 [this](const GroupMap& theta) { return listed_data_of(theta); }, pruned_solve,
                                                 options, out.homotopy_search))
      append_class(std::move(f.hc), std::move(f.data), f.evaluation);
  // Issue 14 (docs/handle_classes.md "Geometric candidates"): classes from
  // short markings of the two hyperbolic metrics, under the same condition.
  std::vector<int> restart_from;
  // Issue 19: only when the best class so far is at least geometric_ratio x
  // the bound (they cost 1-6 s on genus-2 pairs and never won below it).
  if (searching && !given && options.homotopy.search.geometric > 0 && hooks.homotopy_search_start < 0 &&
      out.candidates[order[0]].energy > gap_bound &&
      out.candidates[order[0]].energy >= options.homotopy.search.geometric_ratio * conformal_bound) {
    const SourceClassBounds& bounds = class_bounds_now();
    if (bounds.ok && bounds.source) {
      std::vector<GroupMap> known;
      for (const HomotopyClass& hc : candidates.classes) known.push_back(hc.map);
      const SurfaceGroupLengths& geometric_lengths = geometric_target();
      for (FoundClass& f : geometric_candidate_classes(
               *bounds.source, geometric_lengths, *space, known,
               [&](const GroupMap& theta) { return class_curve_bound_of(bounds, *target_lengths, theta); },
               [this](const GroupMap& theta) { return listed_data_of(theta); }, geometric_solve, options, out.homotopy_search,
               geometric_target_letters())) {
        std::string handles;
        handle_correspondence_of(ss.shb, candidates.target_basis, homology_matrix(f.evaluation.theta, space->num_letters()),
                                 &f.hc.permutation, &f.hc.sign, &handles);
        f.hc.description = handles + "  " + f.hc.description;
        restart_from.push_back(append_class(std::move(f.hc), std::move(f.data), f.evaluation));
      }
    }
  }
  check_candidate_index(hooks.homotopy_search_start, ncand, "homotopy_search_start");
  const int search_start = hooks.homotopy_search_start >= 0 ? hooks.homotopy_search_start : order[0];
  const bool near_bound = hooks.homotopy_search_start_twists.empty() && out.candidates[search_start].energy <= gap_bound;
  if (searching && near_bound)
    out.homotopy_search.stop_reason = "not run: the best class is within " +
                                      std::to_string(static_cast<int>(std::lround(100 * options.homotopy.search.gap))) +
                                      "% of the conformal bound 8 pi (g - 1)";
  if (!searching || !usable[search_start] || near_bound ||
      !(std::isfinite(out.candidates[search_start].energy) || !hooks.homotopy_search_start_twists.empty()))
    return;
  HomotopySearchInfo& info = out.homotopy_search;
  twist_search_from(search_start, hooks.homotopy_search_start_twists, pruned_solve, info);
  // Restarts (issue 14: a single descent stops at "no improving
  // neighbour"): from each geometric class and the class carried from the
  // other direction (two-way run) within restart_ratio of the best coarse
  // energy, each with half the evaluations; the runs' figures are added up
  // in `info`, the classes they find appended.
  if (hooks.homotopy_search_start >= 0 || !hooks.homotopy_search_start_twists.empty())
    return kicks_when_high(search_start, hooks.homotopy_search_start_twists, pruned_solve, false);
  if (candidates.carried_class >= 0) restart_from.push_back(candidates.carried_class);
  for (int k : restart_from) {
    if (options.homotopy.search.restart_ratio <= 0) break;
    const double best = out.candidates[order[0]].energy;
    if (k == search_start || !usable[k] || !(out.candidates[k].energy <= options.homotopy.search.restart_ratio * best) ||
        out.candidates[order[0]].energy <= gap_bound)
      continue;
    HomotopySearchInfo restart;
    SurfaceMapOptions ro = options;
    ro.homotopy.search.evaluations = std::max(1, options.homotopy.search.evaluations / 2);
    twist_search_from(k, {}, pruned_solve, restart, &ro);
    add_restart_figures(info, restart, k);
    if (restart.found_candidate >= 0 && out.candidates[restart.found_candidate].energy < info.energy) {
      info.found_candidate = restart.found_candidate;
      info.energy = out.candidates[restart.found_candidate].energy;
      info.stop_reason += "; restart from candidate " + std::to_string(k) + " reached " +
                          std::to_string(out.candidates[restart.found_candidate].energy);
    }
  }
  kicks_when_high(search_start, {}, pruned_solve, false);
}

// Issue 14 (session 28; HomotopySearchOptions::high_kicks): when the search
// (restarts included) ended at or above high_kick_ratio x 8 pi (g - 1) and
// no kicks were asked for, kicks from the best class it reached (the
// CAD block <-> polycube g3 pair stops in a local minimum of single and
// paired moves at 2.03 x; a kick of three moves leaves it, to 1.81 x). The
// class found is appended like a restart's; `start_twists` (testing hooks)
// when the search from them took no move. Given classes (the through-shape
// step) are not kicked: their legs' own runs were.
void HyperbolicPipeline::kicks_when_high(int search_start, const std::vector<std::string>& start_twists,
                                         const CoarseSolve& solve, bool full_resolution) {
  HomotopySearchInfo& info = out.homotopy_search;
  const HomotopySearchOptions& s = options.homotopy.search;
  if (!info.run) return;
  if (s.high_kicks == 0) return void(info.high_kicks_status = "off");
  if (s.kicks > 0) return void(info.high_kicks_status = "not run: kicks given (" + std::to_string(s.kicks) + ")");
  if (!options.homotopy.given_class.empty()) return void(info.high_kicks_status = "not run: given classes");
  const int from = info.found_candidate >= 0 ? info.found_candidate : search_start;
  const std::vector<std::string> twists = info.found_candidate >= 0 ? std::vector<std::string>{} : start_twists;
  const double energy = info.found_candidate >= 0 ? out.candidates[from].energy : info.energy;
  const double conformal_bound = surfmap::conformal_bound(out.genus);
  char ratio[64];
  std::snprintf(ratio, sizeof ratio, "%.4g x", energy / conformal_bound);
  if (!(energy >= s.high_kick_ratio * conformal_bound)) {
    char below[64];
    std::snprintf(below, sizeof below, "%.4g x", s.high_kick_ratio);
    return void(info.high_kicks_status = std::string("not run: the search ended at ") + ratio +
                                          " the conformal bound, below " + below);
  }
  HomotopySearchInfo run;
  if (full_resolution) {
    // (No coarse copy: the classes are listed in the run's basis only.)
    std::optional<CoarseEvaluation> found = twist_class_search(
        candidates.classes[from].map, from, energy, *space, solve, twists, options, run, source_curve_moves,
        target_curve_moves, true);
    if (std::optional<FoundSearchClass> f = found_search_class(found, from, twists, run.moves)) {
      f->hc.description += "  [solved at full resolution: no coarse copy]";
      run.found_candidate = append_full_class(std::move(f->hc), std::move(f->data), *found);
    }
  } else {
    twist_search_from(from, twists, solve, run, nullptr, true);
  }
  add_restart_figures(info, run, from);
  std::string status = std::to_string(run.kicks) + " kicks from candidate " + std::to_string(from) + " at " + ratio + ": " +
                       std::to_string(run.lower_kicks) + " lower";
  if (run.found_candidate >= 0 && out.candidates[run.found_candidate].energy < energy) {
    info.found_candidate = run.found_candidate;
    info.energy = out.candidates[run.found_candidate].energy;
    char reached[64];
    std::snprintf(reached, sizeof reached, ", reached %.6g (%.4g x)", info.energy, info.energy / conformal_bound);
    status += reached;
  }
  info.high_kicks_status = status;
  info.stop_reason += "; high kicks: " + status;
}

// One twist search (stages/class_search.h) from candidate `start` (with
// `start_twists`, testing hooks), the class reached appended when it
// improved (info.found_candidate). `opts`: other options (restarts).
void HyperbolicPipeline::twist_search_from(int start, const std::vector<std::string>& start_twists,
                                           const CoarseSolve& solve, HomotopySearchInfo& info,
                                           const SurfaceMapOptions* opts, bool high_kicks) {
  const SurfaceMapOptions& o = opts ? *opts : options;
  info.starts.push_back(start);
  // A class with a map in the other canonical basis (stages/other_basis.h:
  // listed there only, or listed in both when the other is the short one)
  // is searched there, by the twists of that basis's generators, so that
  // the search does not depend on which basis the run uses; each class is
  // solved in the run's.
  const HomotopyClass& from = candidates.classes[start];
  std::optional<CoarseEvaluation> found;
  if (o.homotopy.search.curve_twists) ensure_curve_moves();
  if (other_basis && !from.other_basis_map.empty()) {
    std::vector<MappingClassMove> source_moves = source_curve_moves, target_moves = target_curve_moves;
    for (MappingClassMove& m : source_moves) m.automorphism = other_basis->automorphism_from_run(m.automorphism, true);
    for (MappingClassMove& m : target_moves) m.automorphism = other_basis->automorphism_from_run(m.automorphism, false);
    const CoarseSolve in_other = [&](const GroupMap& theta_other, CoarseEvaluation* ev) {
      GroupMap theta = other_basis->to_run(theta_other);
      space->reduce(theta);
      const bool ok = solve(theta, ev);
      ev->theta = theta_other;  // (the search compares its own words)
      return ok;
    };
    found = twist_class_search(from.other_basis_map, start, out.candidates[start].energy, other_basis->space(), in_other,
                               start_twists, o, info, source_moves, target_moves, high_kicks);
    if (found) {
      found->theta = other_basis->to_run(found->theta);
      space->reduce(found->theta);
    }
  } else {
    found = twist_class_search(from.map, start, out.candidates[start].energy, *space, solve, start_twists, o, info,
                               source_curve_moves, target_curve_moves, high_kicks);
  }
  std::optional<FoundSearchClass> f = found_search_class(found, start, start_twists, info.moves);
  if (!f) return;
  f->hc.homology = homology_matrix(found->theta, space->num_letters());
  std::string handles;
  handle_correspondence_of(ss.shb, candidates.target_basis, f->hc.homology, &f->hc.permutation, &f->hc.sign, &handles);
  f->hc.description = handles + "  " + f->hc.description;
  if (other_basis && !candidates.classes[start].other_basis_map.empty())
    f->hc.description += "  [twists of the " + other_basis->name() + " canonical basis]";
  info.found_candidate = append_class(std::move(f->hc), std::move(f->data), *found);
}

// The class a twist search found, ready to append: its description ("[class
// search from candidate <start> <start twists>: <moves>]") and data;
// nullopt when it found none, or its loops' images are too long for
// double-precision deck elements, or its data cannot be built.
std::optional<HyperbolicPipeline::FoundSearchClass> HyperbolicPipeline::found_search_class(
    const std::optional<CoarseEvaluation>& found, int start, const std::vector<std::string>& start_twists,
    const std::vector<std::string>& moves) const {
  if (!found || space->loop_image_length(found->theta) > space->max_image_letters()) return std::nullopt;
  FoundSearchClass f;
  try {
    f.data = listed_data_of(found->theta);
  } catch (const SolveError&) {
    return std::nullopt;  // (cannot happen for an exact automorphism; then the search found nothing usable)
  }
  std::string path;
  for (const std::string& m : moves) path += (path.empty() ? "" : ", ") + m;
  std::string from = std::to_string(start);
  for (const std::string& m : start_twists) from += " " + m;
  f.hc.description = "[class search from candidate " + from + ": " + path + "]";
  return f;
}

// Issue 14 (docs/handle_classes.md "Geometric candidates"): a source too
// small for a coarse copy has no class search, so its geometric classes are
// solved at full resolution here, under the search's condition (the best
// class more than `gap` above 8 pi (g - 1)) and pruned by their curve bound
// against the best energy held.
void HyperbolicPipeline::geometric_classes_at_full_resolution() {
  if (!options.homotopy.search.enabled || options.homotopy.images_only || options.homotopy.reverse_class_only ||
      !options.homotopy.given_class.empty() || options.homotopy.search.geometric <= 0 ||
      options.homotopy.class_index >= 0 ||
      hooks.homotopy_search_start >= 0)
    return;
  double best = std::numeric_limits<double>::infinity();
  for (int k = 0; k < ncand; ++k)
    if (usable[k] && out.candidates[k].solved && std::isfinite(out.candidates[k].energy))
      best = std::min(best, out.candidates[k].energy);
  // Issue 13: when every candidate failed (best infinite: the genus-11
  // plate -> wheel, whose combinatorial classes are all twisted far beyond
  // double range) the geometric classes are the only ones left.
  const double conformal = conformal_bound(out.genus);
  if (best <= (1 + options.homotopy.search.gap) * conformal || best < options.homotopy.search.geometric_ratio * conformal)
    return;
  const SourceClassBounds& bounds = class_bounds_now();
  if (!bounds.ok || !bounds.source) return;
  std::vector<GroupMap> known;
  for (const HomotopyClass& hc : candidates.classes) known.push_back(hc.map);
  const CoarseSolve solve_full = full_resolution_solve(best, options.homotopy.search.geometric_start_edge_size);
  const SurfaceGroupLengths& geometric_lengths = geometric_target();
  for (FoundClass& f : geometric_candidate_classes(
           *bounds.source, geometric_lengths, *space, known,
           [&](const GroupMap& theta) { return class_curve_bound_of(bounds, *target_lengths, theta); },
           [this](const GroupMap& theta) { return data_of(theta); }, solve_full, options, out.homotopy_search,
           geometric_target_letters())) {
    f.hc.description += "  [solved at full resolution: no coarse copy]";
    append_full_class(std::move(f.hc), std::move(f.data), f.evaluation);
  }
}

void HyperbolicPipeline::ensure_curve_moves() {
  if (curve_moves_tried) return;
  curve_moves_tried = true;
  const SourceClassBounds& bounds = class_bounds_now();
  if (!bounds.ok || !bounds.source) {
    out.homotopy_search.curve_twists = "none: the source's own uniformization is not available (class_bound_status)";
    return;
  }
  ensure_target_lengths();
  std::string source_lengths, target_lengths_text;
  try {
    source_curve_moves = short_curve_moves(*bounds.source, &source_lengths);
    target_curve_moves = short_curve_moves(*target_lengths, &target_lengths_text);
  } catch (const SolveError& e) {
    source_curve_moves.clear(), target_curve_moves.clear();
    out.homotopy_search.curve_twists = std::string("none: ") + e.what();
    return;
  }
  out.homotopy_search.curve_twists = std::to_string(source_curve_moves.size() / 2) + " source curves " + source_lengths +
                                     "; " + std::to_string(target_curve_moves.size() / 2) + " target curves " +
                                     target_lengths_text;
}

void HyperbolicPipeline::ensure_layout_basis() {
  if (layout_basis_tried || !options.homotopy.search.geometric_layout_basis) return;
  layout_basis_tried = true;
  CanonicalSchema layout_schema;
  std::string why;
  if (!layout_short_basis(ut->layout.word, tcs.generators, tcs.letters, &layout_schema, &layout_basis_in_class_letters,
                          &why)) {
    out.homotopy_search.geometric_failures.push_back(
        "the layout's short basis not used: the class loops' canonical generators could not be inverted in the "
        "layout's letters: " + why);
    return;
  }
  layout_basis_lengths = std::make_unique<SurfaceGroupLengths>(*deck_group, layout_schema.generators, ut->layout.word);
}

// A converged solve of class theta at full resolution from the origin
// (false when it fails, does not converge or is pruned: its curve bound,
// when the source's bounds exist, above `best`, which each success lowers).
// Sources too small for a coarse copy (under 2000 vertices) only. Start
// edges up to max(the solve's, `max_start_edge_size`) are accepted.
CoarseSolve HyperbolicPipeline::full_resolution_solve(double& best, double max_start_edge_size) {
  HyperbolicHarmonicOptions o = ho;
  o.max_start_edge_size = std::max(o.max_start_edge_size, max_start_edge_size);
  ensure_snapper();
  return [this, &best, o](const GroupMap& theta, CoarseEvaluation* ev) {
    const SourceClassBounds& bounds = class_bounds_now();  // (sets target_lengths)
    const double curve_bound = bounds.ok ? class_curve_bound_of(bounds, *target_lengths, theta) : 0.0;
    if (curve_bound > best) {
      ++out.homotopy_search.pruned;
      ev->failure = "pruned: curve bound " + std::to_string(curve_bound) + " above the best energy " + std::to_string(best);
      return false;
    }
    ++out.homotopy_search.coarse_solves;  // (no coarse copy: the search's solves are these)
    try {
      ev->theta = theta;
      ev->edges = data_of(theta).edges;
      ev->result = solve_from_better_start(ev->edges, o);
    } catch (const SolveError& e) {
      ev->failure = e.what();
      note_refusal(e);
      return false;
    }
    ev->failure = solve_failure(ev->result);
    if (!ev->failure.empty()) return false;
    best = std::min(best, ev->result.energy);
    return true;
  };
}

// Appends a class solved at full resolution (no coarse copy) as a solved
// candidate; returns its index. (`data_of` runs once more for `cd` at the
// caller: the evaluation carries only the edges.)
int HyperbolicPipeline::append_full_class(HomotopyClass hc, ClassData cd, CoarseEvaluation& ev) {
  hc.map = ev.theta;
  hc.homology = homology_matrix(hc.map, space->num_letters());
  std::string handles;
  handle_correspondence_of(ss.shb, candidates.target_basis, hc.homology, &hc.permutation, &hc.sign, &handles);
  hc.description = handles + "  " + hc.description;
  HomotopyCandidate c;
  c.energy = ev.result.energy;
  c.solved = true;
  fine_result.push_back(std::make_unique<HyperbolicHarmonicResult>(std::move(ev.result)));
  full.push_back(1);
  return push_candidate(std::move(hc), std::move(cd), std::move(c));
}

// Issue 14 (docs/handle_classes.md "The search, restarted"): a source too
// small for a coarse copy had no twist search (cadplate g4 -> fertility:
// the canonical schemata's class at 195 x 8 pi (g - 1), nothing searched).
// Its solves are cheap (a few hundred to 2000 vertices), so the same twist
// search runs on full-resolution solves, from the best solved class and
// restarted from the next best distinct ones within restart_ratio.
void HyperbolicPipeline::twist_search_at_full_resolution() {
  if (!options.homotopy.search.enabled || options.homotopy.class_index >= 0 || options.homotopy.reverse_class_only)
    return;
  // (With the testing hooks' start, one run from there, whatever its energy.)
  const bool hooked = hooks.homotopy_search_start >= 0;
  check_candidate_index(hooks.homotopy_search_start, ncand, "homotopy_search_start");
  const double gap_bound = hooked ? 0.0 : (1 + options.homotopy.search.gap) * conformal_bound(out.genus);
  std::vector<int> solved;
  for (int k = 0; k < ncand; ++k)
    if (usable[k] && out.candidates[k].solved && std::isfinite(out.candidates[k].energy) &&
        space->loop_image_length(candidates.classes[k].map) <= space->max_image_letters() &&
        (!hooked || k == hooks.homotopy_search_start))
      solved.push_back(k);
  std::stable_sort(solved.begin(), solved.end(),
                   [&](int x, int y) { return out.candidates[x].energy < out.candidates[y].energy; });
  if (solved.empty() || out.candidates[solved[0]].energy <= gap_bound) return;
  double best = hooked && !hooks.homotopy_search_start_twists.empty() ? std::numeric_limits<double>::infinity()
                                                                       : out.candidates[solved[0]].energy;
  const CoarseSolve solve_full = full_resolution_solve(best);
  HomotopySearchInfo& info = out.homotopy_search;
  // A solve here costs about a coarse solve scaled by nv / coarse_vertices,
  // so the evaluation budget is scaled the other way (at most 4x: 96 solves
  // of a 532-vertex source took 20 s on a loaded machine).
  const double evaluation_scale =
      std::clamp(static_cast<double>(std::max(options.homotopy.coarse_vertices, 1)) / std::max(nv, 1), 1.0, 4.0);
  std::vector<double> start_energies;  // (equal energies: the same class up to a symmetry, searched once)
  for (int start : solved) {
    const double e0 = out.candidates[start].energy;
    if (info.run && !(e0 <= options.homotopy.search.restart_ratio * best)) break;
    if (best <= gap_bound) break;
    bool same = false;
    for (double e : start_energies) same = same || std::abs(e - e0) <= 1e-6 * e;
    if (same) continue;
    start_energies.push_back(e0);
    HomotopySearchInfo run;
    SurfaceMapOptions ro = options;
    ro.homotopy.search.evaluations = std::max(1, static_cast<int>(std::lround(evaluation_scale * options.homotopy.search.evaluations)));
    if (info.run) ro.homotopy.search.evaluations = std::max(1, ro.homotopy.search.evaluations / 2);
    if (options.homotopy.search.curve_twists) ensure_curve_moves();
    std::optional<CoarseEvaluation> found =
        twist_class_search(candidates.classes[start].map, start, e0, *space, solve_full,
                           hooked ? hooks.homotopy_search_start_twists : std::vector<std::string>{}, ro, run,
                           source_curve_moves, target_curve_moves);
    const bool first = !info.run;
    if (first) {
      // (The search's own figures; the geometric classes' and the solve
      // counts, filled before, are kept.)
      info.run = true;
      info.start_candidate = run.start_candidate, info.start_energy = run.start_energy, info.energy = run.energy;
      info.moves = run.moves, info.energies = run.energies, info.evaluations = run.evaluations;
      info.evaluated_moves = run.evaluated_moves, info.evaluated_step = run.evaluated_step;
      info.evaluated_screen = run.evaluated_screen, info.evaluated_energy = run.evaluated_energy;
      info.screened = run.screened, info.stop_reason = run.stop_reason, info.time_s = run.time_s;
      info.kicks = run.kicks, info.lower_kicks = run.lower_kicks;
      info.starts.assign(1, start);
    } else {
      add_restart_figures(info, run, start);
    }
    std::optional<FoundSearchClass> f = found_search_class(
        found, start, hooked ? hooks.homotopy_search_start_twists : std::vector<std::string>{}, run.moves);
    if (!f) continue;
    f->hc.description += "  [solved at full resolution: no coarse copy]";
    const double e = found->result.energy;
    const int k = append_full_class(std::move(f->hc), std::move(f->data), *found);
    if (first || e < info.energy) {
      if (!first) info.stop_reason += "; restart from candidate " + std::to_string(start) + " reached " + std::to_string(e);
      info.found_candidate = k, info.energy = e;
    }
  }
  kicks_when_high(solved[0], hooked ? hooks.homotopy_search_start_twists : std::vector<std::string>{}, solve_full, true);
}

namespace {

// Largest relative change |l(a_p) - l(b_p)| / l(b_p) over the probes p
// (NaN when a length cannot be evaluated).
double largest_length_change(const std::vector<Word>& probes, const std::function<double(const Word&)>& a,
                             const std::function<double(const Word&)>& b) {
  double worst = 0;
  for (const Word& p : probes) {
    const double la = a(p), lb = b(p);
    if (!std::isfinite(la) || !std::isfinite(lb) || lb <= 0) return std::numeric_limits<double>::quiet_NaN();
    worst = std::max(worst, std::abs(la - lb) / lb);
  }
  return worst;
}

std::string number_text(double e, const char* nan_text) {
  char s[32];
  std::snprintf(s, sizeof s, "%.6g", e);
  return std::isfinite(e) ? std::string(s) : std::isnan(e) ? std::string(nan_text) : std::string("not solved");
}

// A candidate's energy in words: its value (full resolution, or the coarse
// estimate), or why there is none (a class the ranking did not solve keeps
// an infinite energy: "not ranked").
std::string energy_text(const HomotopyCandidate& c, bool not_ranked) {
  if (not_ranked && !std::isfinite(c.energy)) return "not ranked";
  return number_text(c.energy, "not ranked") + (std::isfinite(c.energy) && !c.solved ? " (coarse estimate)" : "");
}

}  // namespace

// Issue 14 (docs/handle_classes.md "Both directions"): the class carried
// from a target -> source map (two-way run) is that map's class inverted,
// in this run's letters; whether the chosen class is the same outer class:
// the same action on homology (exact) and the same target lengths of every
// probe curve's image (ClassSpace::fingerprint; equal for one class, and
// for classes differing by an isometry of the target).
void HyperbolicPipeline::compare_with_carried_class() {
  const int k = candidates.carried_class, c = out.chosen_candidate;
  if (k < 0 || c < 0 || k >= ncand || c >= ncand) return;
  const std::string ck = "candidate " + std::to_string(k), cc = "candidate " + std::to_string(c);
  if (c == k) {
    out.reverse_inverse = 1;
    out.reverse_inverse_reason = "the chosen class is the other direction's class inverted (" + ck + ")";
    return;
  }
  const GroupMap& a = candidates.classes[c].map;
  const GroupMap& b = candidates.classes[k].map;
  const int n = space->num_letters();
  const bool same_homology = homology_matrix(a, n) == homology_matrix(b, n);
  const bool evaluable = space->loop_image_length(a) <= space->max_image_letters() &&
                         space->loop_image_length(b) <= space->max_image_letters();
  const bool same_lengths = evaluable && ClassSpace::same_fingerprint(space->fingerprint(a), space->fingerprint(b));
  const std::string energies = " (energies " + energy_text(out.candidates[c], unranked(c)) + " and " +
                               energy_text(out.candidates[k], unranked(k)) + ")";
  if (same_homology && same_lengths) {
    out.reverse_inverse = 1;
    out.reverse_inverse_reason = "the chosen class (" + cc + ") and the other direction's class inverted (" + ck +
                                 ") act alike on homology and give every probe curve's image the same length: the same "
                                 "class" + energies;
    return;
  }
  out.reverse_inverse = 0;
  out.reverse_inverse_reason =
      "the chosen class (" + cc + ") is not the other direction's class inverted (" + ck + "): " +
      (!same_homology ? std::string("they pair the handles differently (different action on homology)")
                      : !evaluable ? std::string("same action on homology; lengths not evaluable")
                                   : std::string("same action on homology but different lengths of the probe curves' "
                                                 "images (a Torelli twist apart)")) +
      ", and the chosen one has the lower energy" + energies;
}


// Issue 14 (docs/handle_classes.md "Both directions"): the chosen class's
// words and the source's letters as a target (for the two-way run to
// compose), and, with homotopy.reverse_class (the other direction's class
// psi in this run's letters, target -> source), the algebraic comparison:
// phi = psi ∘ theta is a mapping class of the source; inner means the two
// classes are inverse (exact). Otherwise the two classes theta and
// theta' = psi^-1 differ by phi on the source (theta' = theta ∘ phi^-1) and
// by theta' ∘ theta^-1 = (theta ∘ psi)^-1 on the target; either one preserving the lengths of
// every probe curve (within the tolerance) is an isometry of that surface's
// hyperbolic metric, under which the harmonic energy is invariant: both
// classes are optimal. Else the lower energy was kept (the ranking).
void HyperbolicPipeline::compare_directions() {
  const int c = out.chosen_candidate;
  if (c < 0 || c >= ncand) return;
  const int g = out.genus, n = 2 * g;
  const GroupMap& theta = candidates.classes[c].map;
  out.chosen_class_words = theta;
  const GroupMap& psi = options.homotopy.reverse_class;
  if (letters_from_own_loops()) {
    // Issue 19: the source's letters as a target from its own loops (no
    // uniformization: class_bound_support.h source_letters_from_own_loops;
    // the ranking's bounds on the coarse copy have no letters of the source),
    // built ahead on the second thread when there is one (the same function
    // of the same inputs).
    SourceLetters letters = letters_ahead ? std::move(*letters_ahead)
                                          : source_letters_from_own_loops(source, sc, ss.sl, ss.scs.generators, g, options);
    letters_ahead.reset();
    out.source_as_target = std::move(letters.as_target);
    out.source_as_target_inverse = std::move(letters.as_target_inverse);
    out.source_as_target_status = std::move(letters.as_target_status);
    return;
  }
  const SourceClassBounds& bounds = class_bounds_now();
  out.source_as_target = bounds.letters.as_target;
  out.source_as_target_inverse = bounds.letters.as_target_inverse;
  out.source_as_target_status = !bounds.ok ? "the source's own uniformization failed: " + bounds.why : bounds.letters.as_target_status;
  if (psi.empty()) return;
  SurfaceMapResult::DirectionCheck& d = out.directions;
  if (static_cast<int>(psi.size()) != n) return void(d.reason = candidates.inverted_status);
  for (const Word& w : psi)
    for (int x : w)
      if (x == 0 || std::abs(x) > n) return void(d.reason = candidates.inverted_status);
  const OppositeClasses relation = compare_opposite_classes(psi, theta, g);
  const GroupMap& phi = relation.composite;
  std::vector<std::string> names;
  for (int i = 1; i <= g; ++i) names.push_back("a" + std::to_string(i)), names.push_back("b" + std::to_string(i));
  d.difference.clear();
  for (int j = 0; j < n; ++j) d.difference += (j ? ", " : "") + names[j] + " -> " + to_text(phi[j], names);
  d.energy = out.candidates[c].energy;
  const int k = candidates.inverted_class;
  d.inverted_candidate = k;
  if (k >= 0 && k < ncand) d.inverted_energy = out.candidates[k].energy;
  const InnerTest& inner = relation.inner;
  if (inner.inner) {
    d.outcome = "inverse";
    d.reason = "the composite of the two classes is inner (conjugation by a word of " +
               std::to_string(inner.conjugator.size()) + " letters; exact, Dehn's algorithm)";
    return;
  }
  if (relation.up_to_hyperelliptic) {
    // (Every genus-2 surface has it as an isometry, so the two classes'
    // discrete energies tie exactly and the ranking picks either.)
    d.outcome = "symmetric: both optimal";
    d.reason = "inverse up to the hyperelliptic involution (exact: the composite times it is inner): an isometry of "
               "every genus-2 surface, so both classes have the same energy (" +
               energy_text(out.candidates[c], unranked(c)) + (k >= 0 ? " and " + energy_text(out.candidates[k], unranked(k)) : std::string()) +
               "); the maps differ by that half turn of the target";
    return;
  }
  const std::vector<Word> probes = marking_probes(g);
  if (bounds.ok && bounds.source)
    d.source_length_change = largest_length_change(
        probes, [&](const Word& p) { return bounds.source->length(substitute(p, phi)); },
        [&](const Word& p) { return bounds.source->length(p); });
  if (target_lengths) {
    // theta' ∘ theta^-1 = (theta ∘ psi)^-1: an isometry of the target
    // exactly when theta ∘ psi is (no inverse needed).
    const DehnReducer reduce(canonical_relator(g));
    GroupMap chi = compose(theta, psi);
    for (Word& w : chi) w = reduce(w);
    d.target_length_change = largest_length_change(
        probes, [&](const Word& p) { return target_lengths->length(substitute(p, chi)); },
        [&](const Word& p) { return target_lengths->length(p); });
  }
  const bool source_isometry = d.source_length_change <= d.length_tolerance;
  const bool target_isometry = d.target_length_change <= d.length_tolerance;
  const std::string energies = "energy " + energy_text(out.candidates[c], unranked(c)) + " here, the other direction's class inverted " +
                               (k >= 0 ? energy_text(out.candidates[k], unranked(k)) + " (candidate " + std::to_string(k) + ")"
                                       : "not listed (" + candidates.inverted_status + ")");
  const std::string why_not = "not inverse (" + inner.why + ")";
  if (source_isometry || target_isometry) {
    d.outcome = "symmetric: both optimal";
    d.reason = why_not + ", but they differ by a mapping class preserving every probe curve's length on the " +
               (source_isometry ? std::string("source") : std::string("target")) +
               " (an isometry of its hyperbolic metric, so the same energy); " + energies;
  } else {
    d.outcome = "different";
    d.reason = why_not + " and not by an isometry (probe lengths change by up to " +
               number_text(d.source_length_change, "?") + " on the source, " + number_text(d.target_length_change, "?") +
               " on the target, relative); kept the lower energy: " +
               energies;
  }
}

// Full-resolution solves: after the coarse ranking (`after_coarse`), the
// classes pick_full_solves chooses (stages/class_ranking.h), each from its
// coarse solution prolonged (stages/coarse_level.h; the first on this
// thread: it may report live progress) and, on the second thread, the
// likely class's initial map (-1 in the task list; with one thread it is
// built when needed); without a coarse copy, every class from the origin or
// the snapped overlay, whichever starts lower (stages/snapped_start.h).
void HyperbolicPipeline::solve_at_full_resolution(bool after_coarse) {
  if (!after_coarse) {
    ensure_snapper();
    auto solve_class = [&](int k) {
      auto r = std::make_unique<HyperbolicHarmonicResult>();
      bool snapped = false;
      const bool solved = try_solve(k, [&] { return solve_from_better_start(data[k].edges, fine_options(k), &snapped); }, *r);
      ++solved_in_stage;
      if (!solved) return;
      if (snapped) out.candidates[k].description += "  [started from the snapped overlay]";
      out.candidates[k].energy = r->energy;
      out.candidates[k].solved = true;
      full[k] = 1;
      fine_result[k] = std::move(r);
    };
    for (int k = 0; k < ncand; ++k)
      if (usable[k]) solve_class(k);
    const std::vector<int> again = accept_long_starts(false);
    to_solve_in_stage += static_cast<int>(again.size());
    for (int k : again) solve_class(k);
    stage_done("homotopy candidates", ranking_end);
    // The geometric classes and the twist search at full resolution (small
    // sources) belong to the next stage.
    report_full_resolution_solves();
    count_in_stage(0);
    return;
  }
  FullSolvePick picked = pick_full_solves(out.candidates, order, usable, full_solves, options);
  full = std::move(picked.full);
  likely_class = picked.likely_class;
  release_unsolved_class_data();
  stage_done("homotopy candidates", ranking_end);
  // The solves below belong to the next stage (ho's hook said "homotopy
  // candidates" up to ranking_end, that stage's end).
  report_full_resolution_solves();
  const CoarseSource& cs = ss.cs;
  const std::vector<int> settle = prolongation_order(cs, sc);
  std::vector<int> tasks;
  for (int k = 0; k < ncand; ++k)
    if (full[k] && usable[k]) tasks.push_back(k);
  const bool init_ahead = threads > 1 && likely_class >= 0 && usable[likely_class];
  // Issue 19: the solver data of the classes solved here (and of the likely
  // class, for its initial map ahead), built now, on both threads.
  std::vector<int> build = tasks;
  if (init_ahead && !full[likely_class]) build.push_back(likely_class);
  build_solver_data(build);
  if (init_ahead) tasks.insert(tasks.begin() + std::min<size_t>(1, tasks.size()), -1);
  // Issue 19 (session 23): the source's letters for compare_directions, on
  // the second thread after the initial map (the solves leave it idle).
  if (threads > 1 && letters_from_own_loops()) tasks.push_back(-2);
  if (threads > 1) tasks.push_back(-3);  // and the location's cover
  count_in_stage(static_cast<int>(std::count_if(tasks.begin(), tasks.end(), [](int k) { return k >= 0; })));
  std::exception_ptr init_error;
  // Class k's coarse solution prolonged to the fine vertices (all at the
  // origin when its coarse solve failed).
  auto prolonged = [&](int k, std::vector<Complex>& z, std::vector<Word>& deck) {
    if (coarse_failed[k]) {
      z.assign(nv, Complex(0.0));
      deck.assign(nv, Word{});
      return;
    }
    prolong(cs, sc, settle, coarse_result[k], data[k], *deck_group, z, deck);
  };
  parallel_for(threads, static_cast<int>(tasks.size()), [&](int t, const std::atomic<bool>* stop) {
    const int k = tasks[t];
    if (k == -3) {
      try {
        cover_ahead = location_cover(cover_input());
      } catch (...) {
        // (built again by the location, which reports the error)
      }
      return;
    }
    if (k == -2) {
      try {
        letters_ahead = source_letters_from_own_loops(source, sc, ss.sl, ss.scs.generators, out.genus, options);
      } catch (...) {
        // (built again by compare_directions, which reports the error)
      }
      return;
    }
    if (k < 0) {
      try {
        // The uniform-weight fallback (polygon not usable) starts from the
        // class's prolonged coarse solution: the same map, in fewer steps.
        std::vector<Complex> z;
        std::vector<Word> deck;
        if (!coarse_failed[likely_class]) prolonged(likely_class, z, deck);
        likely_init = std::make_unique<ClassInitialMap>(initial_of(likely_class, stop, std::move(z), std::move(deck)));
        likely_init->distortion = initial_map_distortion(source, *deck_group, *likely_init);  // (issue 19: D' too)
      } catch (...) {
        init_error = std::current_exception();  // rethrown only if the class is chosen: built again then
      }
      return;
    }
    std::vector<Complex> z;
    std::vector<Word> deck;
    prolonged(k, z, deck);
    HyperbolicHarmonicOptions o = fine_options(k);
    if (stop) o.progress = [stop](int, double, double) { return !*stop; };
    auto r = std::make_unique<HyperbolicHarmonicResult>();
    const bool solved = try_solve(k, [&] { return solve_from(nv, data[k].edges, z, deck, o); }, *r);
    ++solved_in_stage;
    if (!solved) return;
    out.candidates[k].energy = r->energy;
    out.candidates[k].solved = true;
    fine_result[k] = std::move(r);
  });
  if (init_error) likely_init.reset();
}

// Issue 13 (HomotopySearchOptions::start_edge_size): when no candidate has
// an energy after the ranking's solves (on the coarse copy: `coarse`, else
// at full resolution), the classes whose start from the origin has an edge
// beyond the start-edge limit (every vertex at the origin, one sheet: an
// edge starts as long as its deck element moves the origin) were refused
// only for that. Their loops' images are that long in the target (85-300
// units for the combinatorial classes of the genus-9 plate -> wheel), and
// no start with short edges is at hand for them: the initial maps develop
// the source in one Poincare chart, which holds polygons of a few units
// only (tried: every such class's initial map fell back to the origin).
// So the limit is raised to geometric_start_edge_size, as for the geometric
// classes, for these classes and every later solve of the map (class
// search, fallbacks): Newton from the origin then converges (7 of the 8
// classes of that pair). Returns the classes to solve again (empty when
// some class has an energy or none was refused), marked usable again.
std::vector<int> HyperbolicPipeline::accept_long_starts(bool coarse) {
  std::vector<int> again;
  for (int k = 0; k < ncand; ++k)
    if (usable[k] && std::isfinite(out.candidates[k].energy)) return again;
  const double raised = std::max(ho.max_start_edge_size, options.homotopy.search.geometric_start_edge_size);
  if (!(raised > ho.max_start_edge_size)) return again;
  double longest = 0;
  for (int k = 0; k < ncand; ++k) {
    const std::vector<WeightedEdge>& edges = coarse ? level.class_edges[k] : data[k].edges;
    if (edges.empty() || (coarse && !coarse_failed[k] && usable[k])) continue;
    bool refused = false;
    for (const WeightedEdge& e : edges) {
      const double size = e.rho.size();
      if (!(size < ho.max_start_edge_size) && size < raised) {
        refused = true;
        longest = std::max(longest, e.rho.displacement_of_origin());
      }
    }
    if (refused) again.push_back(k);
  }
  if (again.empty()) return again;
  long_starts = true;
  ho.max_start_edge_size = raised;
  char text[200];
  std::snprintf(text, sizeof text,
                "every candidate's start from the origin was refused; %d solved again accepting start edges up to "
                "%.3g (the longest %.1f units)",
                static_cast<int>(again.size()), raised, longest);
  out.long_starts = text;
  for (int k : again) {
    usable[k] = 1;
    if (coarse) coarse_failed[k] = 0;
    out.candidates[k].description += "  [solved again accepting long start edges]";
  }
  return again;
}

// Issue 19 (memory): every candidate's homotopy data (a deck element and
// side word per source edge, the solver's edges: ~130 bytes per source
// edge, ~0.4 GB per class at 1M source vertices, with 10-15 candidates) were
// held through the full-resolution solves, whose factorisations came on top
// (the 1M bench pair's peak, 11.9 GB, was there). Only the classes solved at full
// resolution and the likely class's initial map need them now; the others
// are fallbacks, whose data data_for builds again (the same function of the
// same inputs, so the same data) if one is ever used.
void HyperbolicPipeline::release_unsolved_class_data() {
  data_released.assign(ncand, 0);
  for (int k = 0; k < ncand; ++k)
    if (!full[k] && k != likely_class && !data[k].side_word_edge.empty()) {
      data[k] = ClassData{};
      data_released[k] = 1;
    }
}

// Class k's data with its solver data, built when it was released or
// holds only its side words (listed_data_of).
const ClassData& HyperbolicPipeline::data_for(int k) {
  const bool released = k < static_cast<int>(data_released.size()) && data_released[k];
  if (released || (!data[k].side_word_edge.empty() && !data[k].has_solver_data())) {
    data[k] = data_of(candidates.classes[k].map);
    if (released) data_released[k] = 0;
  }
  return data[k];
}

// Issue 19: the solver data of `classes` (those with only their side
// words), on both threads; the same function of the same inputs as
// data_for, so the same data.
void HyperbolicPipeline::build_solver_data(const std::vector<int>& classes) {
  std::vector<int> missing;
  for (int k : classes)
    if (!data[k].side_word_edge.empty() && !data[k].has_solver_data()) missing.push_back(k);
  std::vector<ClassData> built(missing.size());
  std::vector<std::exception_ptr> failed(missing.size());
  parallel_for(threads, static_cast<int>(missing.size()), [&](int i, const std::atomic<bool>*) {
    try {
      built[i] = data_of(candidates.classes[missing[i]].map);
    } catch (...) {
      failed[i] = std::current_exception();
    }
  });
  for (size_t i = 0; i < missing.size(); ++i) {
    if (failed[i]) std::rethrow_exception(failed[i]);
    data[missing[i]] = std::move(built[i]);
  }
}

// Landmarks in class k from its free optimum `free_k` (landmarks.h): plain
// pins, else the barrier continuation, else carried neighbourhoods; the
// returned map is bijective or this throws (options.landmarks_may_fold: the
// plain pins alone, folded or not). Folds are the source faces
// hyperbolic_distortion leaves without a dilatation (flipped or degenerate;
// chart elements from reduced side words when the solver kept them); the
// continuation's face elements are the free optimum's.
HyperbolicHarmonicResult HyperbolicPipeline::hold_in_class(int k, const HyperbolicHarmonicResult& free_k,
                                                           const HyperbolicHarmonicOptions& o, bool relax,
                                                           const HarmonicRelaxationOptions& ro, LandmarkHold& hold) const {
  std::vector<int> lm_source, lm_target_vertex;
  std::vector<Complex> lm_target;
  for (const auto& [s, t] : options.landmarks)
    lm_source.push_back(s), lm_target_vertex.push_back(t), lm_target.push_back(ut->layout.vertex_positions[t]);
  const std::vector<Mobius> halfedge_rho = data[k].halfedge_rho(sc);
  const std::vector<Word> halfedge_word = data[k].halfedge_words(sc);
  auto bad_faces = [&](const HyperbolicHarmonicResult& held) {
    const DistortionStats q = held.vertex_deck_word.size() == held.z.size()
                                  ? hyperbolic_distortion(source, *deck_group, halfedge_word, held.z, held.vertex_deck_word)
                                  : hyperbolic_distortion(source, halfedge_rho, held.z, held.vertex_deck);
    std::vector<int> bad;
    for (int f = 0; f < source.num_faces(); ++f)
      if (!std::isfinite(q.per_face[f])) bad.push_back(f);
    return bad;
  };
  if (options.landmarks_may_fold) {
    HyperbolicHarmonicResult pins =
        hold_hyperbolic_landmarks(source.num_vertices(), data[k].edges, deck_group->side_pairings(),
                                  deck_group->side_pairings(), free_k, lm_source, lm_target, lm_target_vertex, o, relax, ro,
                                  nullptr, nullptr, &hold);
    if (!bad_faces(pins).empty()) hold.method = "pinned (folds allowed)";
    return pins;
  }
  std::vector<Mobius> face_elements(3 * source.num_faces());
  for (int h = 0; h < 3 * source.num_faces(); ++h)
    face_elements[h] = effective_element(free_k, h, sc, *deck_group, halfedge_word, halfedge_rho);
  return hold_hyperbolic_landmarks(source.num_vertices(), data[k].edges, deck_group->side_pairings(),
                                   deck_group->side_pairings(), free_k, lm_source, lm_target, lm_target_vertex, o, relax,
                                   ro, &source.F, bad_faces, &hold, &face_elements);
}

// The default class (stages/class_ranking.h); with landmarks (and no class
// requested) the classes solved at full resolution are ranked by their
// energy with the landmarks held (stages/landmark_ranking.h: branch and
// bound on the plain pins' energies), and the chosen class's held map is
// kept. Classes only estimated on the coarse copy are not ranked (their
// free estimate is not comparable).
void HyperbolicPipeline::choose_with_landmarks() {
  out.chosen_candidate = choose_class(out.candidates, options);
  if (out.chosen_candidate < 0) {
    // Each class's own reason (its description's bracketed note), so the
    // one-line error says which stage failed where.
    std::string why;
    for (size_t k = 0; k < out.candidates.size() && k < 4; ++k) {
      const std::string& d = out.candidates[k].description;
      const size_t at = d.rfind("  [");
      why += (k ? "; " : ": ") + std::string("class ") + std::to_string(k) + (at == std::string::npos ? std::string(" not solved") : d.substr(at + 2));
    }
    if (out.candidates.size() > 4) why += "; ... (" + std::to_string(out.candidates.size()) + " classes)";
    if (!out.snapped_class_status.empty()) why += "; the snapped overlay's class: " + out.snapped_class_status;
    // The geometric classes tried last (no coarse copy: at full resolution)
    // and why each failed, else why none was tried.
    const HomotopySearchInfo& hs = out.homotopy_search;
    if (hs.geometric_classes > 0 || !hs.geometric_failures.empty()) {
      why += "; geometric classes: " + std::to_string(hs.geometric_classes) + " tried";
      for (size_t q = 0; q < hs.geometric_failures.size() && q < 4; ++q) why += (q ? "; " : ": ") + hs.geometric_failures[q];
      if (hs.geometric_failures.size() > 4) why += "; ... (" + std::to_string(hs.geometric_failures.size()) + " failed)";
    } else if (!out.class_bound_status.empty()) {
      why += "; no geometric class (" + out.class_bound_status + ")";
    }
    throw SolveError("the harmonic map solve failed in every candidate homotopy class" + why,
                     refusal_reason());
  }
  held_result.resize(ncand);
  held_record.resize(ncand);
  if (!options.landmarks.empty() && options.homotopy.class_index < 0) {
    HyperbolicHarmonicOptions lo;
    lo.tolerance = options.solve.tolerance;
    lo.max_iterations = options.solve.max_iterations;
    lo.progress = [this](int, double, double) { return !options.progress || options.progress("landmarks", 0.68); };
    std::vector<int> lm_s, lm_t;
    std::vector<Complex> lm_p;
    for (const auto& [s, t] : options.landmarks)
      lm_s.push_back(s), lm_t.push_back(t), lm_p.push_back(ut->layout.vertex_positions[t]);
    std::vector<int> bounded;
    for (int k = 0; k < ncand; ++k) {
      if (!out.candidates[k].solved || !fine_result[k]) continue;
      try {
        const HyperbolicHarmonicResult pins = hold_hyperbolic_landmarks(
            nv, data[k].edges, deck_group->side_pairings(), deck_group->side_pairings(), *fine_result[k], lm_s, lm_p, lm_t, lo);
        if (!pins.converged) continue;
        out.candidates[k].landmark_lower_bound = pins.energy;
        bounded.push_back(k);
      } catch (const SolveError&) {
      }
    }
    const int best = landmark_branch_and_bound(bounded, out.candidates, [&](int k) -> std::optional<double> {
      auto held = std::make_unique<HyperbolicHarmonicResult>(hold_in_class(k, *fine_result[k], lo, false, {}, held_record[k]));
      if (!held->converged) return std::nullopt;
      const double energy = held->energy;
      held_result[k] = std::move(held);
      return energy;
    });
    if (best >= 0) out.chosen_candidate = best;
  }
  stage_done("full-resolution solve", kFullSolvesEnd);
}

// The automatic source weights' fallback (stages/source_weights_fallback.h):
// the class stays, the energy and so the map change. Every class's data
// follows the new weights.
void HyperbolicPipeline::switch_to_own_weights() {
  own_weights = true;
  ss.idt = positive_edge_weights(sc, edge_lengths(source, sc), {options.solve.own_weights_floor});
  index_solver_edges(sc, ss.idt, solver_index);
  fine_solver.reset();  // (another pattern)
  // (empty: never evaluable, or released: data_for builds it with the new
  // weights when needed)
  for (int k = 0; k < ncand; ++k)
    if (!data[k].edges.empty()) data[k] = data_of(candidates.classes[k].map);
}

// The single-class pipeline for the chosen class (out.chosen_candidate):
// initial map (stages/initial_map_stage.h; computed next to the
// full-resolution solves when this class was the likely choice), harmonic
// solve (stages/harmonic_solve.h), landmarks (hold_in_class; the ranking's
// held map when it was this class's), quality (stages/hyperbolic_quality.h)
// and location (stages/hyperbolic_location.h). False when the source
// weights were switched (switch_to_own_weights) and the class must be
// mapped again; SolveError when the class cannot be used.
bool map_class(HyperbolicPipeline& p);

bool map_class(HyperbolicPipeline& p) {
  const SurfaceMapOptions& options = p.options;
  SurfaceMapResult& out = p.out;
  const int k = out.chosen_candidate;
  out.source_weights = source_weights_name(p.own_weights, p.ss.idt.raised_weights);
  if (!p.own_weights) p.own_weights_reason.clear(), p.fold_repair = {};  // (an earlier class's)
  const ClassData& cd = p.data_for(k);

  ClassInitialMap initial;
  if (p.likely_init && p.likely_class == k) {
    initial = std::move(*p.likely_init);
    p.likely_init.reset();
  } else {
    initial = class_initial_map(cd, p.source, p.sc, p.ss.sl, *p.deck_group, *p.polygon, options, nullptr);
  }
  const HyperbolicInitialMapResult& init = initial.init;
  set_initial_map_info(init, out.initial_map);
  out.initial_map.location_requested = options.initial.locate;
  if (p.hooks.inspect_initial_map)
    p.hooks.inspect_initial_map({&initial.halfedge_rho, &initial.halfedge_word, p.deck_group.get(), &init});
  const DistortionStats q0 =
      initial.distortion ? *initial.distortion : initial_map_distortion(p.source, *p.deck_group, initial);
  store_initial_distortion(q0, out);
  p.stage_done("initial map", 0.7);

  const SolveProgress solve_progress = chosen_solve_progress(options);
  // Issue 13: the second solve of a class after the own-edge weights
  // fallback starts from its first optimum (the same class and vertices,
  // other weights), not from the initial map, which for a class whose loop
  // images are longer than one Poincare chart holds is every vertex at the
  // origin (plate -> wheel genus 9: "edge 192 starts 83.2 units long").
  HyperbolicInitialMapResult first_optimum;
  const bool from_first = p.retry_start && p.retry_class == k && p.own_weights;
  if (from_first) {
    first_optimum.z = p.retry_start->z;
    first_optimum.vertex_deck = p.retry_start->vertex_deck;
    first_optimum.vertex_deck_word = p.retry_start->vertex_deck_word;
  }
  p.retry_start.reset();
  ChosenSolve solved = solve_chosen_class(p.nv, cd.edges, init, *p.deck_group, *p.polygon, options,
                                          std::move(p.fine_result[k]), solve_progress, &p.fine_solver,
                                          p.hooks.inspect_problem, from_first ? &first_optimum : nullptr,
                                          p.ho.max_start_edge_size);
  out.initial_energy = solved.initial_energy;
  HyperbolicHarmonicResult& hr = solved.result;
  const double free_energy = hr.energy;
  if (!options.landmarks.empty()) {
    HyperbolicHarmonicOptions lo;
    lo.tolerance = options.solve.tolerance;
    lo.max_iterations = options.solve.max_iterations;
    lo.progress = solve_progress;
    // The relaxation holds them too (its sweeps skip the held vertices).
    const bool relax = options.solve.method == MapMethod::Relaxation;
    HarmonicRelaxationOptions ro;
    ro.tolerance = options.solve.tolerance;
    ro.max_iterations = options.solve.max_iterations;
    ro.check_every = 10;
    ro.progress = solve_progress;
    LandmarkHold hold;
    HyperbolicHarmonicResult held;
    if (solved.reused && p.held_result[k]) {
      held = std::move(*p.held_result[k]);
      p.held_result[k].reset();
      hold = p.held_record[k];
    } else {
      held = p.hold_in_class(k, hr, lo, relax, ro, hold);
    }
    out.candidates[k].landmark_energy = held.energy;
    out.landmark_rings = hold.rings;
    out.landmark_method = hold.method;
    out.landmark_solves = hold.solves;
    out.landmark_steps = hold.barrier_steps;
    out.landmark_held_vertices = hold.held_vertices;
    if (!held.converged)
      throw SolveError(std::string("the harmonic map with the landmarks held (") + (relax ? "relaxation" : "Newton") +
                       ") did not converge in " + std::to_string(held.iterations) + " iterations");
    held.energy_history.insert(held.energy_history.begin(), hr.energy_history.begin(), hr.energy_history.end());
    held.iterations += hr.iterations;
    hr = std::move(held);
  }
  out.converged = true;
  out.iterations = hr.iterations;
  out.energy_history = hr.energy_history;
  out.final_energy = hr.energy;
  out.candidates[k].energy = hr.energy;
  out.candidates[k].solved = true;
  p.stage_done("harmonic solve", 0.8);

  // Issue 19 (session 23): the optimum moved into P and its distortion are
  // independent when the solver kept its local charts (Newton; the
  // relaxation's are built by place_in_polygon, so they wait for it): two
  // tasks, on both threads when there are two.
  MapInPolygon placed;
  DistortionStats quality;
  int intrinsic_flips = 0;
  LayoutClosure closure;
  const bool charts_kept = static_cast<int>(hr.edge_local.size()) == static_cast<int>(cd.edges.size());
  parallel_for(charts_kept ? p.threads : 1, 2, [&](int task, const std::atomic<bool>*) {
    if (task == 0) {
      placed = place_in_polygon(p.source, p.sc, *p.polygon, *p.deck_group, cd.side_word_edge, cd.rho_edge,
                                p.solver_index, static_cast<int>(cd.edges.size()), hr);
      return;
    }
    quality = chart_distortion(p.source, p.sc, hr.edge_local, p.solver_index);
    intrinsic_flips = intrinsic_flipped_triangles(p.ss.idt, hr.edge_local);
    closure = intrinsic_layout_closure(p.ss.idt, hr.edge_local);
  });
  store_distortion(quality, out);
  out.intrinsic_flipped_triangles = intrinsic_flips;
  out.layout_closure = closure;
  const std::string folds = "the intrinsic Delaunay map of class " + std::to_string(k) + " folds " +
                            std::to_string(out.flipped_triangles) + " and flattens " +
                            std::to_string(out.degenerate_triangles) + " of the source's faces (" +
                            std::to_string(out.intrinsic_flipped_triangles) + " intrinsic triangles flipped" +
                            (quality.flat ? "; " + std::to_string(quality.flat) + " more flat but positive"
                                          : std::string()) +
                            ")";
  // landmarks_may_fold: the held map's folds are the caller's to keep (no
  // repair, no own-edge weights).
  const bool keep_folds = options.landmarks_may_fold && !options.landmarks.empty();
  // Flat but positive faces (quality.flat) are one-to-one: the repair tries
  // to open them, but when it cannot the map is kept as it is.
  if ((out.flipped_triangles || out.degenerate_triangles || quality.flat) && !p.own_weights && !keep_folds &&
      options.solve.source_weights == SourceWeights::Automatic && options.solve.local_fold_repair) {
    // Issue 14: repair the few folded faces where they are (stages/
    // fold_repair.h) instead of giving every face the own-edge weights.
    FoldRepairOptions fo;
    fo.tolerance = options.solve.tolerance;
    fo.max_iterations = options.solve.max_iterations;
    if (!options.solve.fold_untangle) fo.untangle_max_rings = 0;
    std::vector<char> held;
    if (!options.landmarks.empty()) {
      held.assign(p.nv, 0);
      for (const auto& [s, t] : options.landmarks) held[s] = 1;
    }
    const IntrinsicDelaunayResult own =
        positive_edge_weights(p.sc, edge_lengths(p.source, p.sc), {options.solve.own_weights_floor});
    FoldRepairResult fr = repair_folds_locally(p.source, p.sc, cd.edges, p.solver_index, own, hr, quality.per_face,
                                               held, *p.deck_group, *p.polygon, fo, solve_progress);
    p.fold_repair = fr.info;
    if (fr.map) {
      hr = std::move(*fr.map);
      placed = place_in_polygon(p.source, p.sc, *p.polygon, *p.deck_group, cd.side_word_edge, cd.rho_edge,
                                p.solver_index, static_cast<int>(cd.edges.size()), hr);
      store_distortion(chart_distortion(p.source, p.sc, hr.edge_local, p.solver_index), out);
      out.intrinsic_flipped_triangles = intrinsic_flipped_triangles(p.ss.idt, hr.edge_local);
      out.layout_closure = intrinsic_layout_closure(p.ss.idt, hr.edge_local);
      // The returned map's energy with the intrinsic weights; the class's
      // (candidates[k].energy, energy_ratio) stays its optimum.
      out.final_energy = hr.energy;
      // ("projection": corners moved into their neighbours' kernel; "held
      // re-solve of R rings": own-edge weights there; stages/fold_repair.h)
      const std::string moved = std::to_string(fr.info.free_vertices) + " vertices around the folds moved (" +
                                fr.info.method + ")";
      out.source_weights += "; " + moved;
      p.own_weights_reason = folds + ": repaired locally, " + moved + ", the rest held";
    } else if (!out.flipped_triangles && !out.degenerate_triangles) {
      p.own_weights_reason = folds + ": kept as it is, flat but positive faces being one-to-one (local repair " +
                             fr.info.status + ")";
    }
  }
  if (!keep_folds && retry_with_own_weights(options, p.own_weights, out)) {
    // The classes' energies so far are the intrinsic ones (solved classes).
    p.intrinsic_energy.assign(p.ncand, std::numeric_limits<double>::quiet_NaN());
    for (int q = 0; q < p.ncand; ++q)
      if (out.candidates[q].solved) p.intrinsic_energy[q] = out.candidates[q].energy;
    p.intrinsic_energy[k] = free_energy;
    p.own_weights_reason = folds + ": mapped again with positive weights on its own edges" +
                           (p.fold_repair.status.empty() ? std::string() : " (local repair " + p.fold_repair.status + ")");
    if (hr.vertex_deck_word.size() == hr.z.size()) {
      p.retry_start = std::make_unique<HyperbolicHarmonicResult>(hr);
      p.retry_class = k;
    }
    p.switch_to_own_weights();
    return false;
  }
  out.source_image = placed.zp;
  if (static_cast<int>(hr.edge_local.size()) == static_cast<int>(cd.edges.size()))
    out.image_cover = image_cover(p.source, p.sc, hr.edge_local, p.solver_index);
  p.stage_done("quality", 0.83);

  HyperbolicLocationInput li;
  li.source = &p.source, li.target = &p.target, li.sc = &p.sc, li.tc = &p.tc;
  li.target_loops = &p.ut->loops, li.target_intrinsic = p.ut->intrinsic.get(), li.layout = &p.ut->layout, li.polygon = p.polygon.get(), li.group = p.deck_group.get();
  li.zp = &placed.zp, li.eff_edge = &placed.eff_edge, li.image = &placed.image;
  li.init = &init, li.halfedge_rho = &initial.halfedge_rho, li.halfedge_word = &initial.halfedge_word;
  li.threads = p.threads;
  li.cover = p.cover_ahead.get();
  li.locate_initial = options.initial.locate;
  li.inverse_full_search = p.hooks.inverse_full_search;
  li.forward_index_order = p.hooks.forward_index_order;
  HyperbolicLocationResult located = locate_hyperbolic_map(li, p.stage_done);
  if (p.hooks.location_walk_steps) p.hooks.location_walk_steps(located.forward_walk_steps, located.inverse_walk_steps);
  if (p.hooks.inverse_location_counts) {
    const InverseLocationCounts& c = located.inverse_counts;
    p.hooks.inverse_location_counts(c.in_frame, c.from_neighbour, c.from_grid, c.full_scan);
  }
  out.forward = std::move(located.forward);
  out.inverse = std::move(located.inverse);
  out.initial_forward = std::move(located.initial_forward);
  out.initial_inverse = std::move(located.initial_inverse);
  p.stage_done("inverse location", 1.0);
  return true;
}

// Issue 13 (session 25): whether map_class would refuse class k on its
// full-resolution solve alone, read before its initial map is built.
// map_class keeps that solve (solve_chosen_class: Newton from the default
// start, no landmarks), and once no repair is left to try (the own-edge
// weights are in use, after the chosen class fell back to them or as the
// requested weights) any folded or flattened face of it is refused by
// retry_with_own_weights. The same figures are read here, the same way
// (the optimum placed in P, its charts' distortion), so the outcome is
// map_class's; only the initial map (and its distortion) that map_class
// builds first is saved. Classes without a kept solve (coarse-ranked only)
// are mapped as before (docs/history/robustness.md "Session 25": on the genus-12
// block <-> wheel pair those are the cost). Returns the refusal ("" when
// the class must be mapped).
std::string refused_by_its_solve(HyperbolicPipeline& p, int k) {
  const SurfaceMapOptions& o = p.options;
  if (p.hooks.map_every_fallback) return {};
  if (!o.landmarks.empty() || o.solve.method != MapMethod::Newton || o.solve.start_seed != 0) return {};
  if (!p.own_weights && o.solve.source_weights == SourceWeights::Automatic) return {};  // (repairs left)
  if (k >= static_cast<int>(p.fine_result.size()) || !p.fine_result[k]) return {};
  const ClassData& cd = p.data_for(k);
  HyperbolicHarmonicResult hr = *p.fine_result[k];
  place_in_polygon(p.source, p.sc, *p.polygon, *p.deck_group, cd.side_word_edge, cd.rho_edge, p.solver_index,
                   static_cast<int>(cd.edges.size()), hr);
  SurfaceMapResult read;
  store_distortion(chart_distortion(p.source, p.sc, hr.edge_local, p.solver_index), read);
  read.intrinsic_flipped_triangles = intrinsic_flipped_triangles(p.ss.idt, hr.edge_local);
  try {
    // (false: nothing folds, the class is mapped; it cannot ask for the
    // own-edge weights here, the condition above having excluded that)
    retry_with_own_weights(o, p.own_weights, read);
  } catch (const SolveError& e) {
    return std::string(e.what()) + " (read on its full-resolution solve before its initial map: not mapped again)";
  }
  return {};
}

// The chosen class, then (when it was the default and fails in map_class:
// flips, location) the next ones: solved classes by energy, then the
// coarse-ranked ones by their estimate (solved from their initial maps).
// A class that fails gets "[not used: ...]" in its description; one that
// refused_by_its_solve decides is not mapped (SurfaceMapResult::
// fallbacks_refused_unmapped).
void map_with_fallback(HyperbolicPipeline& p) {
  SurfaceMapResult& out = p.out;
  std::vector<int> fallback;
  for (int k = 0; k < p.ncand; ++k)
    if (k != out.chosen_candidate && p.usable[k] &&
        (std::isfinite(out.candidates[k].energy) || (k < static_cast<int>(p.not_ranked.size()) && p.not_ranked[k])))
      fallback.push_back(k);
  std::stable_sort(fallback.begin(), fallback.end(), [&](int x, int y) {
    const bool sx = out.candidates[x].solved, sy = out.candidates[y].solved;
    return sx != sy ? sx : out.candidates[x].energy < out.candidates[y].energy;
  });
  if (p.options.homotopy.class_index >= 0) fallback.clear();
  fallback.insert(fallback.begin(), out.chosen_candidate);
  const SurfaceMapResult before_attempts = out;
  int refused_unmapped = 0;
  auto reset_keeping_candidates = [&] {
    const std::vector<HomotopyCandidate> cands = out.candidates;
    out = before_attempts;
    out.candidates = cands;
    out.fallbacks_refused_unmapped = refused_unmapped;
  };
  for (size_t attempt = 0; attempt < fallback.size(); ++attempt) {
    try {
      if (attempt > 0) reset_keeping_candidates();
      out.chosen_candidate = fallback[attempt];
      const std::string refused = attempt > 0 ? refused_by_its_solve(p, fallback[attempt]) : std::string();
      if (!refused.empty()) {
        ++refused_unmapped;
        throw SolveError(refused);
      }
      if (map_class(p)) {
        const int k = out.chosen_candidate;
        if (p.own_weights && k < static_cast<int>(p.intrinsic_energy.size())) out.intrinsic_class_energy = p.intrinsic_energy[k];
        out.source_weights_reason = p.own_weights_reason;
        out.fold_repair = p.fold_repair;
        out.fallbacks_refused_unmapped = refused_unmapped;
        return;
      }
      reset_keeping_candidates();  // the source weights changed: the same class again
      --attempt;
    } catch (const SolveError& e) {
      if (attempt + 1 >= fallback.size() && attempt == 0) throw;
      if (attempt + 1 >= fallback.size()) {
        // Issue 13: the last fallback's reason alone hid the chosen class's
        // (plate -> wheel genus 9: the chosen class, 147 x the bound, came
        // out with 3 folds, the last fallback with 415).
        const int c = fallback[0];
        char head[320], unmapped[120] = "";
        if (refused_unmapped)
          std::snprintf(unmapped, sizeof unmapped, ", %d of them refused on their full-resolution solves without being mapped again",
                        refused_unmapped);
        // Session 25: after the own-edge weights fallback a candidate's
        // energy is its own-edge one, a coarser discretisation than the
        // intrinsic Delaunay energy the ranking and the conformal bound
        // speak of (block -> wheel g12: 127468 own-edge, 461 x the bound,
        // against its intrinsic 19822.5, 71.7 x); the head gives the class's
        // intrinsic energy and names the other.
        // (The switch may have come at a later class, c then keeping its
        // intrinsic energy: nothing to name.)
        const double intrinsic = p.own_weights && c < static_cast<int>(p.intrinsic_energy.size()) &&
                                         p.intrinsic_energy[c] != out.candidates[c].energy
                                     ? p.intrinsic_energy[c]
                                     : std::numeric_limits<double>::quiet_NaN();
        const double energy = std::isfinite(intrinsic) ? intrinsic : out.candidates[c].energy;
        char own_edges[80] = "";
        if (std::isfinite(intrinsic))
          std::snprintf(own_edges, sizeof own_edges, "; %.6g with the own-edge weights", out.candidates[c].energy);
        std::snprintf(head, sizeof head, "no candidate class gave a bijective map (%d tried%s); the chosen class %d (energy %.6g, %.3g x 8 pi (g - 1)%s): ",
                      static_cast<int>(fallback.size()), unmapped, c, energy, energy / conformal_bound(out.genus),
                      own_edges);
        const std::string& d = out.candidates[c].description;
        const size_t at = d.rfind("  [not used: ");
        throw SolveError(head + (at == std::string::npos ? std::string("?") : d.substr(at + 13, d.size() - at - 14)) +
                             "; the last, class " + std::to_string(fallback[attempt]) + ": " + e.what(),
                         SolveFailure::no_bijective_class);
      }
      out.candidates[fallback[attempt]].description += std::string("  [not used: ") + e.what() + "]";
    }
  }
}

}  // namespace

// Genus >= 2 (docs/method.md §2.8): hyperbolic target, harmonic map by
// preconditioned Riemannian Newton (map/hyperbolic_harmonic.h) or the
// paper's relaxation, in the homotopy class of lowest energy among the
// candidates of stages/homotopy_classes.h.
void map_hyperbolic(const TriMesh& source, const TriMesh& target, const Connectivity& sc, const Connectivity& tc,
                    const SurfaceMapOptions& options, const testing::MapHooks& hooks, SurfaceMapResult& out,
                    const StageDone& stage_done) {
  const SingleThreadedBlas single_threaded_blas;  // concurrency.h: our own threads instead
  check_high_kicks(options.homotopy.search);
  HyperbolicPipeline p(source, target, sc, tc, options, hooks, out, stage_done);
  p.start_source_side();           // docs/method.md §2.6 on the second thread: loops, edge words, weights, coarse copy
  p.uniformize_target();           // docs/method.md §2.4-2.5: hyperbolic metric, layout, deck group, polygon P
  p.start_class_bounds();          // issue 14: the source's own uniformization, for class lower bounds
  p.candidate_classes_and_data();  // docs/method.md §2.10: candidate homotopy classes and their deck elements
  p.rank_on_coarse_copy();         // ranking: every class solved on the coarse copy
  if (p.ss.cs.ok && !options.homotopy.images_only && !options.homotopy.reverse_class_only)
    p.search_classes();  // more cuts, Dehn twists (mapping_class_search.h)
  p.solve_at_full_resolution(p.ss.cs.ok);  // docs/method.md §2.8: the best classes at full resolution
  if (!p.ss.cs.ok) p.geometric_classes_at_full_resolution();  // issue 14: small sources (no coarse copy)
  if (!p.ss.cs.ok) p.twist_search_at_full_resolution();  // issue 14: the twist search there too
  p.fill_class_bounds();           // issue 14: every candidate's energy lower bound
  p.choose_with_landmarks();       // lowest energy; with landmarks, docs/method.md §2.10 branch and bound
  p.compare_with_carried_class();  // issue 14: the two directions' classes inverse or not
  try {
    map_with_fallback(p);          // initial map, harmonic solve, landmarks, quality, location
  } catch (const SolveError&) {
    // Every class folded: the source's letters as a target are still set in
    // `out` (surface_map's rescue writes the other direction's class in
    // them, two_way_run.h rescue_by_the_other_direction). Their failure must
    // not hide the fold's error.
    try {
      p.compare_directions();
    } catch (const Cancelled&) {
      throw;
    } catch (const Error&) {
    }
    throw;
  }
  p.compare_directions();          // issue 14: the class's words; both directions compared algebraically
}

}  // namespace surfmap::detail
