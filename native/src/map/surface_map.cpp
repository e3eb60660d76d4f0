#include "surfmap/map/surface_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>

#include "../seconds_since.h"
#include "face_chart_map.h"
#include "map_support.h"
#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/work_counters.h"
#include "through_shape.h"
#include "two_way_run.h"

namespace surfmap {

using Clock = std::chrono::steady_clock;
using detail::seconds_since;

namespace {

// The total row of the stage table: `total` with the peak over every stage
// (the high-water mark was reset at each boundary).
void finish_stage_table(SurfaceMapResult& out, StageRecord total) {
  for (const StageRecord& s : out.stages) total.peak_memory_bytes = std::max(total.peak_memory_bytes, s.peak_memory_bytes);
  out.stage_total = total;
}

// What the first run's rescue by the other direction left for after the
// retry after folds (surface_map_run): the cuts at another base vertex.
struct LeftForAfterTheRetry {
  bool another_cut = false;
  std::string why;  // the rescue's failure so far
};

SurfaceMapResult map_in_given_cuts(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                   const testing::MapHooks& hooks, LeftForAfterTheRetry* left = nullptr);

// The maps a run makes of other pairs or other settings (the two-way run, the
// rescue, the through-shape step): the public surface_map (no hooks), their
// stages reported as "other runs (<stage>)" (SurfaceMapOptions::progress).
SurfaceMapOptions named_other_run(SurfaceMapOptions o) {
  if (o.progress)
    o.progress = [outer = o.progress](const std::string& stage, double fraction) {
      return outer("other runs (" + stage + ")", fraction);
    };
  return o;
}
SurfaceMapResult other_run(const TriMesh& s, const TriMesh& t, const SurfaceMapOptions& o) {
  return surface_map(s, t, named_other_run(o));
}

// The largest fraction reported before the map is made (testing::surface_map).
constexpr double kBeforeDone = 0.98;

// The progress of one run and of the runs it makes after its own stages (the
// other direction, the through-shape step's legs, the rescue's runs;
// SurfaceMapOptions::progress). When such runs may follow, the run's stages
// report kMainShare of their fractions; each run after them takes
// kFurtherShare of what is left below kBeforeDone, from the largest fraction
// reported so far: it reports ("other runs (starting)", that fraction) as it
// starts (a cancel is seen there), then its stages as "other runs (<stage>)"
// at its own fractions mapped into its share, its ("done", 1) at the share's
// end. So the bar moves during every run and never goes back; when no run
// follows, the last stage reports kMainShare and ("done", 1) follows.
// Session 29 (double torus -> genus-2 block): the main run took 41 s, the
// other runs 290 s after it, at a fraction held at 0.98.
class RunProgress {
 public:
  static constexpr double kMainShare = 0.5, kFurtherShare = 0.5;
  using Progress = std::function<bool(const std::string&, double)>;

  explicit RunProgress(Progress outer) : outer_(std::move(outer)) {}

  // `given` with its progress reporting the run's own stages at the run's
  // share of each fraction (1 until runs_may_follow).
  SurfaceMapOptions own_stages(const SurfaceMapOptions& given) const {
    SurfaceMapOptions o = given;
    if (outer_)
      o.progress = [outer = outer_, state = state_](const std::string& stage, double fraction) {
        return outer(stage, state->reach(state->share * std::clamp(fraction, 0.0, 1.0)));
      };
    return o;
  }
  void runs_may_follow() {
    std::lock_guard<std::mutex> lock(state_->mutex);
    state_->share = kMainShare;
  }
  // The runs after the run's stages, made by the public surface_map with their
  // progress in the next share (a run whose options carry no progress reports none).
  detail::MapFunction further_runs() const {
    return [outer = outer_, state = state_](const TriMesh& s, const TriMesh& t, SurfaceMapOptions o) {
      if (outer && o.progress) {
        double from = 0;
        {
          std::lock_guard<std::mutex> lock(state->mutex);
          from = state->reached;
        }
        const double to = from + kFurtherShare * std::max(0.0, kBeforeDone - from);
        if (!outer("other runs (starting)", from)) throw Cancelled("cancelled before another run");
        o.progress = [outer, state, from, to](const std::string& stage, double fraction) {
          return outer("other runs (" + stage + ")", state->reach(from + (to - from) * std::clamp(fraction, 0.0, 1.0)));
        };
      }
      return surface_map(s, t, o);
    };
  }

 private:
  struct State {
    std::mutex mutex;  // (a run's solves may report from several threads)
    double share = 1, reached = 0;
    double reach(double fraction) {
      std::lock_guard<std::mutex> lock(mutex);
      reached = std::max(reached, fraction);
      return fraction;
    }
  };
  Progress outer_;
  std::shared_ptr<State> state_ = std::make_shared<State>();
};

// Whether runs may follow a run's stages: what detail::two_way_map, the
// rescue by the other direction and detail::through_shape_map each require
// before their own conditions (genus >= 2, the default class, one of them on,
// one Poincare chart).
bool runs_may_follow(const SurfaceMapOptions& o, int genus) {
  const HomotopyOptions& h = o.homotopy;
  return genus >= 2 && h.class_index < 0 && h.source_images.size() == 0 && !h.reverse_class_only &&
         h.given_class.empty() && (h.two_way || h.through_shape) &&
         o.uniformization.face_charts != FaceCharts::Always;
}

// The per-face path's result (face_chart_map.h) as returned: no two-way run
// or class through a generated shape (both compare classes, and this path
// has one), no energy ratio (no class bounds), the stage table closed.
SurfaceMapResult finish_in_face_charts(SurfaceMapResult& out, StageRecord total) {
  out.two_way_status = "not run: per-face charts (one class)";
  out.through_shape_status = "not run: per-face charts (one class)";
  out.total_time = total.seconds;
  finish_stage_table(out, total);
  return std::move(out);
}

// Genus >= 2, the default class, a base vertex given: which class is chosen
// must not depend on it (issue 14). The candidates (the canonical schemata's
// a_i -> a'_i, handle permutations lifted in the cut's letters) and the
// class search (Dehn twists about the cut's generators, its ranking on the
// coarse copy, the two-way run from the swapped base vertices) are all
// built on the two cuts, so another cut is another search, which can stop
// in another local minimum (g3_block -> g3_3holes at base vertices 1000 /
// 2000: ratio 2.33 against 1.55). So the class is chosen in the automatic
// cuts, a choice that depends on the shapes only (nearest the centroid,
// highest valence), and the given base vertices only write it: the source's
// loops at the given base vertex carried by the chosen map (the class of a
// map does not depend on the cut it is written in) are the one candidate of
// a second run in the given cuts (HomotopyOptions::images_only). The same
// class has the same harmonic map, so both runs' energies agree to the
// solver's tolerance; when they do not, or the loops do not carry (a coarse
// source whose edges span many target edges), the automatic cuts' result is
// returned: the same class and map, written in the automatic cuts' letters.
// Not when LoopOptions::search_in_given_cuts asks for the given cuts' own
// search (the two-way run's last resort, which has just run the automatic
// cuts). (The genus is checked by the caller, only when these options hold.)
bool chooses_class_in_automatic_cuts(const SurfaceMapOptions& options) {
  const HomotopyOptions& h = options.homotopy;
  return (options.loops.source_base_vertex >= 0 || options.loops.target_base_vertex >= 0) &&
         !options.loops.search_in_given_cuts && h.class_index < 0 && h.source_images.size() == 0 &&
         h.reverse_class.empty() && !h.images_only && !h.reverse_class_only && h.given_class.empty();
}

// The class is the default's, chosen by the run (no class named, given or
// carried): what the retry after folds may choose again.
bool chooses_default_class(const SurfaceMapOptions& options) {
  const HomotopyOptions& h = options.homotopy;
  return h.class_index < 0 && h.source_images.size() == 0 && h.reverse_class.empty() && !h.images_only &&
         !h.reverse_class_only && h.given_class.empty() && h.class_words.empty();
}

std::string base_text(int v) { return v < 0 ? std::string("automatic") : std::to_string(v); }

SurfaceMapResult map_in_automatic_cuts(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                       const testing::MapHooks& hooks) {
  const auto t0 = Clock::now();
  SurfaceMapOptions automatic = options;
  automatic.loops = LoopOptions{};
  automatic.loops.short_canonical_generators = options.loops.short_canonical_generators;  // (not a cut's choice)
  SurfaceMapResult chosen;
  try {
    chosen = map_in_given_cuts(source, target, automatic, hooks);
  } catch (const Cancelled&) {
    throw;
  } catch (const InputError&) {
    throw;
  } catch (const Error& e) {
    // The automatic cuts failed where the given ones may not (what a base
    // vertex is given for): the class is searched in the given cuts.
    SurfaceMapResult out = map_in_given_cuts(source, target, options, hooks);
    out.class_cuts_status = std::string("chosen in the given cuts: the automatic cuts failed (") + e.what() + ")";
    return out;
  }
  const double chosen_seconds = seconds_since(t0);
  const std::string given = "source " + base_text(options.loops.source_base_vertex) + ", target " +
                            base_text(options.loops.target_base_vertex);
  auto keep_automatic = [&](const std::string& why) {
    chosen.class_cuts_status = "chosen and written in the automatic cuts: " + why +
                               " (given base vertices " + given + "); the class's words are in the automatic cuts' letters";
    chosen.class_cuts_time_s = chosen_seconds;
    return chosen;
  };
  if (static_cast<int>(chosen.forward.size()) != source.num_vertices()) return keep_automatic("no forward map to carry");
  SurfaceMapOptions carried = options;
  carried.homotopy.source_images.resize(source.num_vertices(), 3);
  for (int v = 0; v < source.num_vertices(); ++v) carried.homotopy.source_images.row(v) = chosen.forward[v].position.transpose();
  carried.homotopy.images_only = true;
  SurfaceMapResult out;
  try {
    out = map_in_given_cuts(source, target, carried, hooks);
  } catch (const Cancelled&) {
    throw;
  } catch (const Error& e) {
    return keep_automatic(std::string("carrying the class to the given cuts failed: ") + e.what());
  }
  const double difference = std::abs(out.energy_ratio - chosen.energy_ratio) / chosen.energy_ratio;
  if (!(difference <= 1e-6))
    return keep_automatic("in the given cuts the carried class's energy ratio is " + std::to_string(out.energy_ratio) +
                          " against " + std::to_string(chosen.energy_ratio) + " (relative difference " +
                          std::to_string(difference) +
                          ", above 1e-6: not taken for the same class; another class, or with landmarks the class's "
                          "free energy measured otherwise in the automatic run's ranking)");
  std::ostringstream status;
  status.precision(7);
  status << "chosen in the automatic cuts (energy ratio " << chosen.energy_ratio << ", candidate "
         << chosen.chosen_candidate << " of " << chosen.candidates.size() << "; two-way run: "
         << (chosen.two_way_status.empty() ? "-" : chosen.two_way_status) << ") and carried to the given base vertices ("
         << given << "): the same class, energy ratio " << out.energy_ratio << " (relative difference " << difference
         << ")";
  out.class_cuts_status = status.str();
  out.class_cuts_time_s = chosen_seconds;
  out.total_time += chosen_seconds;
  out.stage_total.seconds = out.total_time;
  return out;
}

}  // namespace

SurfaceMapResult surface_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options) {
  return testing::surface_map(source, target, options, testing::MapHooks{});
}

namespace {
SurfaceMapResult surface_map_run(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                 const testing::MapHooks& hooks);
}  // namespace

// The progress callback sees fractions that never decrease within a run:
// each is raised to the largest given before (a stage's solves report the
// stage's own fraction, which may come after a later stage's end was
// reported, e.g. the full-resolution solves after the ranking's end; and
// the automatic cuts' runs each count from 0). Calls are serialised, so
// that two threads' reports arrive in order. The fractions stay at most
// kBeforeDone until the run returns, which reports ("done", 1): the two-way
// run and the through-shape step may still work for as long again after the
// main run's last stage (a genus-12 pair: ten minutes at a full bar, session
// 28); they report in their shares (RunProgress).
SurfaceMapResult testing::surface_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                      const MapHooks& hooks) {
  if (!options.progress) return surface_map_run(source, target, options, hooks);
  struct Monotone {
    std::mutex mutex;
    double last = 0;
  };
  auto state = std::make_shared<Monotone>();
  SurfaceMapOptions monotone = options;
  monotone.progress = [inner = options.progress, state](const std::string& stage, double fraction) {
    std::lock_guard<std::mutex> lock(state->mutex);
    state->last = std::max(state->last, std::min(fraction, kBeforeDone));
    return inner(stage, state->last);
  };
  SurfaceMapResult out = surface_map_run(source, target, monotone, hooks);
  if (!options.progress("done", 1.0)) throw Cancelled("cancelled after the map was made");
  return out;
}

namespace {

SurfaceMapResult surface_map_run(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                 const testing::MapHooks& hooks) {
  // A class named by its words (issue 14, session 24): the one candidate
  // (stages/homotopy_classes.cpp), chosen as class 0 of that one-entry list,
  // so that everything a class index turns off (ranking, class search,
  // geometric classes, two-way run, through-shape step) is off for it too.
  const HomotopyOptions& h = options.homotopy;
  if (!h.class_words.empty()) {
    if (h.class_index >= 0 || !h.given_class.empty() || h.source_images.size() > 0 || !h.reverse_class.empty() ||
        h.images_only || h.reverse_class_only)
      throw InputError("homotopy.class_words names the one class to map in: give no class index (nor given_class, "
                       "source_images or reverse_class) with it");
    SurfaceMapOptions named = options;
    named.homotopy.class_index = 0;
    return map_in_given_cuts(source, target, named, hooks);
  }
  auto map_in_chosen_cuts = [&](const SurfaceMapOptions& o, LeftForAfterTheRetry* left = nullptr) {
    if (hooks.before_run) hooks.before_run(o);
    if (chooses_class_in_automatic_cuts(o)) {
      const Connectivity sc(source.F, source.num_vertices());
      const Connectivity tc(target.F, target.num_vertices());
      if (sc.genus() >= 2 && tc.genus() == sc.genus()) return map_in_automatic_cuts(source, target, o, hooks);
    }
    return map_in_given_cuts(source, target, o, hooks, left);
  };
  // The automatic retries below report their progress as stages "<name>
  // (<stage>)" with fractions from the largest the first run reached up to 1
  // (testing::surface_map keeps them from decreasing), so a retry does not
  // sit at the first run's last fraction; the callback can cancel it.
  struct Reached {
    std::mutex mutex;  // (the first run's solves may report from several threads)
    double fraction = 0;
  };
  auto reached = std::make_shared<Reached>();
  SurfaceMapOptions first = options;
  if (options.progress)
    first.progress = [inner = options.progress, reached](const std::string& stage, double fraction) {
      {
        std::lock_guard<std::mutex> lock(reached->mutex);
        reached->fraction = std::max(reached->fraction, fraction);
      }
      return inner(stage, fraction);
    };
  const auto t_first = Clock::now();
  double first_seconds = 0;
  // The retry's map, its times counting the first run's too.
  auto named_after_the_first = [&](SurfaceMapOptions o, const std::string& name) {
    if (options.progress) {
      std::lock_guard<std::mutex> lock(reached->mutex);
      o.progress = [inner = options.progress, from = reached->fraction, name](const std::string& stage, double fraction) {
        return inner(name + " (" + stage + ")", from + (1 - from) * std::clamp(fraction, 0.0, 1.0));
      };
    }
    return o;
  };
  auto retried = [&](const SurfaceMapOptions& retry, const std::string& name) {
    first_seconds = seconds_since(t_first);
    SurfaceMapResult out = map_in_chosen_cuts(named_after_the_first(retry, name));
    out.total_time += first_seconds;
    out.stage_total.seconds = out.total_time;
    return out;
  };
  auto shortened = [](const std::string& what) { return what.size() > 300 ? what.substr(0, 300) + " ..." : what; };
  // The retry after folds (below) applies to this run: the first run's
  // rescue by the other direction then leaves its last attempt, the cuts at
  // another base vertex, for after the retry.
  const bool fold_retry = !options.loops.short_canonical_generators && options.loops.fold_fallback &&
                          chooses_default_class(options) && Connectivity(source.F, source.num_vertices()).genus() >= 2;
  LeftForAfterTheRetry left;
  try {
    return map_in_chosen_cuts(first, fold_retry ? &left : nullptr);
  } catch (const SolveError& e) {
    const std::string what = e.what();
    // Issue 13 (session 27; LoopOptions::short_generators_fallback): a run
    // with the classical generators that stopped at its start edges is made
    // again with the short ones (the genus-12 CAD block -> raw wheel: the
    // classical run refused every class at edges "335 units long", the short
    // one maps). Read from the error's reason (SolveFailure::start_edges),
    // not its words.
    if (!options.loops.short_canonical_generators && options.loops.short_generators_fallback &&
        e.reason() == SolveFailure::start_edges) {
      SurfaceMapOptions retry = options;
      retry.loops.short_canonical_generators = true;
      SurfaceMapResult out;
      try {
        out = retried(retry, "retry with the short generators");
      } catch (const SolveError& again) {
        throw SolveError(what + "; again with the short canonical generators (the automatic retry): " + again.what(),
                         again.reason());
      }
      out.canonical_generators_fallback =
          "made with the short canonical generators: the classical ones failed at their start edges after " +
          std::to_string(static_cast<int>(first_seconds)) + " s (" + shortened(what) + ")";
      return out;
    }
    // Issue 13 (session 28; LoopOptions::fold_fallback): a default-class run
    // with the classical generators in which every class folded (after the
    // two-way run's rescue, when on) is made once more with the short
    // generators and one way: on the CAD block g12 -> raw wheel g12 the
    // classical run's class search stops in a class that folds (128 x the
    // bound), the short run's reaches one that maps one-to-one (71.7 x).
    // One way: the first run has already tried the other direction, and the
    // retry's cost stays that of one one-way run.
    //
    // Session 29: when the two-way run's rescue found the other direction
    // failing too, the retry comes before the rescue's last attempt (the
    // cuts at the source's middle vertex, one more run of the classical
    // generators), which is made only when the retry fails.
    if (fold_retry && is_fold_failure(e.reason())) {
      SurfaceMapOptions retry = options;
      retry.loops.short_canonical_generators = true;
      retry.homotopy.two_way = false;
      SurfaceMapResult out;
      try {
        out = retried(retry, "retry after folds");
      } catch (const SolveError& again) {
        std::string failure =
            what + "; again with the short canonical generators, one way (the automatic retry after folds): " + again.what();
        if (!left.another_cut) throw SolveError(failure, again.reason());
        const double before_cut = seconds_since(t_first);
        SurfaceMapResult cut;
        std::string why = left.why;
        const size_t rescue_said = why.size();  // (what rescue_by_another_cut appends is its own failure)
        const detail::MapFunction after_the_retry = [&](const TriMesh& s, const TriMesh& t, const SurfaceMapOptions& o) {
          const SurfaceMapOptions named = named_after_the_first(o, "retry at another base vertex");
          return hooks.rescue_run ? hooks.rescue_run(s, t, named) : surface_map(s, t, named);
        };
        if (!detail::rescue_by_another_cut(source, target, options, cut, after_the_retry, why))
          throw SolveError(failure + why.substr(rescue_said), again.reason());
        cut.two_way_time_s = seconds_since(t_first) - before_cut;
        detail::through_shape_map(source, target, options, cut, other_run);
        cut.total_time = seconds_since(t_first);
        cut.stage_total.seconds = cut.total_time;
        cut.fold_fallback = "not used: the retry after folds failed too (" + shortened(again.what()) +
                            "); the map is the two-way run's last resort, made after it";
        return cut;
      }
      out.fold_fallback = "made with the short canonical generators, one way: the default run folded in every class after " +
                          std::to_string(static_cast<int>(first_seconds)) + " s (" + shortened(what) + ")";
      return out;
    }
    throw;
  }
}

SurfaceMapResult map_in_given_cuts(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& given,
                                   const testing::MapHooks& hooks, LeftForAfterTheRetry* left) {
  using testing::MapHooks;
  SurfaceMapResult out;
  RunProgress progress(given.progress);
  const SurfaceMapOptions options = progress.own_stages(given);
  const detail::MapFunction map_of = progress.further_runs();
  const auto t_start = Clock::now();
  auto t_stage = t_start;
  // The stage table (issue 19): counters and the peak memory at every
  // stage boundary (surfmap/work_counters.h).
  out.peak_memory_per_stage = work::reset_peak_memory();
  const work::Counts counts_start = work::counts();
  work::Counts counts_stage = counts_start;
  auto record = [](const std::string& name, double seconds, const work::Counts& from, const work::Counts& to) {
    StageRecord s;
    s.name = name, s.seconds = seconds;
    s.analyses = to.analyses - from.analyses, s.factorisations = to.factorisations - from.factorisations;
    s.newton_iterations = to.newton_iterations - from.newton_iterations;
    s.peak_memory_bytes = work::peak_memory_bytes();
    return s;
  };
  auto stage_done = [&](const std::string& name, double fraction) {
    const auto now = Clock::now();
    const double seconds = std::chrono::duration<double>(now - t_stage).count();
    out.stage_times.emplace_back(name, seconds);
    const work::Counts counts_now = work::counts();
    out.stages.push_back(record(name, seconds, counts_stage, counts_now));
    if (out.peak_memory_per_stage) work::reset_peak_memory();
    counts_stage = counts_now;
    t_stage = now;
    if (options.progress && !options.progress(name, fraction)) throw Cancelled("cancelled after stage " + name);
  };

  const Connectivity sc(source.F, source.num_vertices());
  const Connectivity tc(target.F, target.num_vertices());
  if (sc.genus() != tc.genus())
    throw InputError("the source has genus " + std::to_string(sc.genus()) + " but the target has genus " +
                     std::to_string(tc.genus()) + "; both surfaces must have the same genus");
  out.genus = sc.genus();
  if (runs_may_follow(options, out.genus)) progress.runs_may_follow();
  if (out.genus < 2 && !options.homotopy.class_words.empty())
    throw InputError("homotopy.class_words: genus >= 2 only (this pair has genus " + std::to_string(out.genus) +
                     "; a torus's class is named by its matrix, a sphere has one class)");
  // Landmarks: valid, one-to-one (a vertex pinned to two places has no map).
  std::vector<int> src_used(source.num_vertices(), -1), dst_used(target.num_vertices(), -1);
  for (size_t k = 0; k < options.landmarks.size(); ++k) {
    const auto [s, t] = options.landmarks[k];
    const std::string which = "landmark " + std::to_string(k) + " (" + std::to_string(s) + " -> " + std::to_string(t) + ")";
    if (s < 0 || s >= source.num_vertices())
      throw InputError(which + ": source vertex out of range 0.." + std::to_string(source.num_vertices() - 1));
    if (t < 0 || t >= target.num_vertices())
      throw InputError(which + ": target vertex out of range 0.." + std::to_string(target.num_vertices() - 1));
    if (src_used[s] >= 0)
      throw InputError(which + ": source vertex " + std::to_string(s) + " is already landmark " + std::to_string(src_used[s]));
    if (dst_used[t] >= 0)
      throw InputError(which + ": target vertex " + std::to_string(t) + " is already landmark " + std::to_string(dst_used[t]));
    src_used[s] = dst_used[t] = static_cast<int>(k);
  }
  if (out.genus == 0)
    detail::map_spherical(source, target, sc, tc, options, out, stage_done);
  else if (out.genus == 1)
    detail::map_flat(source, target, sc, tc, options, hooks, out, stage_done);
  else if (options.uniformization.face_charts == FaceCharts::Always) {
    std::string why;
    if (!detail::face_chart_map_applies(options, &why)) throw InputError("face_charts 'always': " + why);
    detail::map_in_face_charts(source, target, sc, tc, options, "requested", out, stage_done);
    return finish_in_face_charts(out, record("total", seconds_since(t_start),
                                             counts_start, work::counts()));
  } else
    try {
      if (hooks.before_one_way_map) hooks.before_one_way_map(options);
      detail::map_hyperbolic(source, target, sc, tc, options, hooks, out, stage_done);
    } catch (const SingleChartError& e) {
      // Issue 13: a valid target layout no single chart holds. The map runs
      // in per-face charts instead (face_chart_map.h), on its restricted path.
      std::string why;
      if (options.uniformization.face_charts == FaceCharts::Never || e.mesh != "target" ||
          !detail::face_chart_map_applies(options, &why))
        throw SingleChartError(std::string(e.what()) + (why.empty() ? std::string() : " (" + why + ")"), e.mesh,
                               e.layout_radius);
      SurfaceMapResult fresh;
      fresh.genus = out.genus;
      fresh.peak_memory_per_stage = out.peak_memory_per_stage;
      fresh.stage_times = std::move(out.stage_times);
      fresh.stages = std::move(out.stages);
      out = std::move(fresh);
      std::ostringstream reason;
      reason << "one Poincare chart in double cannot hold the target: layout radius " << e.layout_radius;
      detail::map_in_face_charts(source, target, sc, tc, options, reason.str(), out, stage_done);
      return finish_in_face_charts(out, record("total", seconds_since(t_start),
                                               counts_start, work::counts()));
    } catch (const InputError& e) {
      // Issue 14: a requested class index past the one-way candidates may be
      // the two-way run's class (docs/handle_classes.md).
      if (std::string(e.what()).find("does not exist") == std::string::npos ||
          !detail::map_requested_two_way_class(source, target, options, out, map_of))
        throw;
      out.total_time = seconds_since(t_start);
      finish_stage_table(out, record("total", out.total_time, counts_start, work::counts()));
      return out;
    }
    catch (const SolveError& e) {
      // Issue 14 (perturbed botijo -> genus-5 CAD plate): every one-way class
      // folded; the other direction may still map, and its class carried here
      // may not fold (docs/handle_classes.md "The two directions today").
      // Read from the error's reason (SolveFailure::no_bijective_class), not
      // its words; a single class's fold (folds) does not start it.
      if (e.reason() != SolveFailure::no_bijective_class) throw;
      std::string why;
      std::vector<std::vector<int>> target_letters_inverse;  // (for the through-shape step's search both ways)
      // (`out` holds what the failed run set: the source's letters as a target.)
      bool another_cut_left = false;
      const detail::MapFunction rescue_map =
          hooks.rescue_run ? detail::MapFunction([&](const TriMesh& s, const TriMesh& t, const SurfaceMapOptions& o) {
            return hooks.rescue_run(s, t, named_other_run(o));
          })
                           : map_of;
      if (!detail::rescue_by_the_other_direction(source, target, options, out, rescue_map, why, &target_letters_inverse,
                                                 left ? &another_cut_left : nullptr)) {
        if (another_cut_left) {
          left->another_cut = true;
          left->why = why;
          why += "; the cuts at another base vertex: after the retry after folds";
        }
        throw SolveError(std::string(e.what()) + (why.empty() ? std::string() : "; " + why), e.reason());
      }
      // The rescued class can be poor too (genus-4 plate -> fertility: 14.3 x,
      // while both shapes map onto the generated n-hole torus within 4.6 x).
      detail::through_shape_map(source, target, options, out, map_of, target_letters_inverse);
      out.total_time = seconds_since(t_start);
      finish_stage_table(out, record("total", out.total_time, counts_start, work::counts()));
      return out;
    }
  // How far each landmark's source vertex was located from its target
  // vertex. Held landmarks (every genus but 0 with more than 3) sit on a lift
  // of the target vertex by construction, so what remains is the round-off
  // of locating through the layout (~1e-7 of the size on real genus-2
  // meshes, whose layouts agree across the cut only that well): they are then
  // set exactly onto their vertex, both ways.
  for (const auto& [s, t] : options.landmarks)
    out.max_landmark_error = std::max(out.max_landmark_error, (out.forward[s].position - target.V.row(t).transpose()).norm());
  if (!options.landmarks.empty() && (out.genus > 0 || options.landmarks.size() <= 3)) {
    auto at_vertex = [](const TriMesh& m, const std::vector<int>& face_of, int v) {
      PointOnSurface p;
      p.face = face_of[v];
      for (int k = 0; k < 3; ++k) p.barycentric[k] = m.F(p.face, k) == v ? 1.0 : 0.0;
      p.position = m.V.row(v).transpose();
      return p;
    };
    std::vector<int> sface(source.num_vertices(), -1), tface(target.num_vertices(), -1);
    for (int f = 0; f < source.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) sface[source.F(f, k)] = f;
    for (int f = 0; f < target.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) tface[target.F(f, k)] = f;
    for (const auto& [s, t] : options.landmarks) {
      out.forward[s] = at_vertex(target, tface, t);
      out.inverse[t] = at_vertex(source, sface, s);
    }
  }
  detail::assess_quality(out);  // issue 14: energy ratio and warning
  const double one_way_ratio = out.energy_ratio;  // (before the two-way run; the through-shape step reads it)
  std::vector<std::vector<int>> target_letters_inverse;  // the other direction's letters, when it was mapped
  detail::two_way_map(source, target, options, out, map_of, &target_letters_inverse);  // issue 14: the other direction when poor
  // Issue 14: through a generated shape when poor (here or in the other direction), the composed classes
  // searched in both directions.
  detail::through_shape_map(source, target, options, out, map_of, target_letters_inverse, one_way_ratio);
  if (options.homotopy.two_way) detail::qualify_quality_warning(out);  // issue 14: both directions agree on it
  out.total_time = seconds_since(t_start);
  finish_stage_table(out, record("total", out.total_time, counts_start, work::counts()));
  return out;
}

}  // namespace

}  // namespace surfmap
