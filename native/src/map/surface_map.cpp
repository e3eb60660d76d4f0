#include "surfmap/map/surface_map.h"

#include <algorithm>
#include <chrono>
#include <string>

#include "map_support.h"
#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/work_counters.h"
#include "two_way_run.h"

namespace surfmap {

using Clock = std::chrono::steady_clock;

namespace {

// The total row of the stage table: `total` with the peak over every stage
// (the high-water mark was reset at each boundary).
void finish_stage_table(SurfaceMapResult& out, StageRecord total) {
  for (const StageRecord& s : out.stages) total.peak_memory_bytes = std::max(total.peak_memory_bytes, s.peak_memory_bytes);
  out.stage_total = total;
}

}  // namespace

SurfaceMapResult surface_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options) {
  return testing::surface_map(source, target, options, testing::MapHooks{});
}

SurfaceMapResult testing::surface_map(const TriMesh& source, const TriMesh& target, const SurfaceMapOptions& options,
                                      const MapHooks& hooks) {
  SurfaceMapResult out;
  // The two-way run's maps: the public surface_map (no hooks).
  const detail::MapFunction map_of = [](const TriMesh& s, const TriMesh& t, const SurfaceMapOptions& o) {
    return surface_map(s, t, o);
  };
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
  else
    try {
      detail::map_hyperbolic(source, target, sc, tc, options, hooks, out, stage_done);
    } catch (const InputError& e) {
      // Issue 14: a requested class index past the one-way candidates may be
      // the two-way run's class (docs/handle_classes.md).
      if (std::string(e.what()).find("does not exist") == std::string::npos ||
          !detail::map_requested_two_way_class(source, target, options, out, map_of))
        throw;
      out.total_time = std::chrono::duration<double>(Clock::now() - t_start).count();
      finish_stage_table(out, record("total", out.total_time, counts_start, work::counts()));
      return out;
    }
    catch (const SolveError& e) {
      // Issue 14 (perturbed botijo -> genus-5 CAD plate): every one-way class
      // folded; the other direction may still map, and its class carried here
      // may not fold (docs/handle_classes.md "Every class folded").
      if (std::string(e.what()).rfind("no candidate class gave a bijective map", 0) != 0) throw;
      std::string why;
      // (`out` holds what the failed run set: the source's letters as a target.)
      if (!detail::rescue_by_the_other_direction(source, target, options, out, map_of, why))
        throw SolveError(std::string(e.what()) + (why.empty() ? std::string() : "; " + why));
      out.total_time = std::chrono::duration<double>(Clock::now() - t_start).count();
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
  detail::two_way_map(source, target, options, out, map_of);  // issue 14: the other direction when poor
  if (options.homotopy.two_way) detail::qualify_quality_warning(out);  // issue 14: both directions agree on it
  out.total_time = std::chrono::duration<double>(Clock::now() - t_start).count();
  finish_stage_table(out, record("total", out.total_time, counts_start, work::counts()));
  return out;
}

}  // namespace surfmap
