// Map layer bindings: the globally optimal surface map (docs/method.md §2).
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#ifdef __linux__
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "bindings.h"
#include "convert.h"
#include "surfmap/error.h"
#include "surfmap/map/ear_images.h"
#include "surfmap/map/map_option_names.h"
#include "surfmap/map/map_report.h"
#include "surfmap/map/open_map.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/open_surface.h"

namespace py = pybind11;

namespace surfmap::python {
namespace {

py::dict points_to_dict(const std::vector<PointOnSurface>& pts) {
  std::vector<int> face(pts.size());
  RowMatrixX3d bary(pts.size(), 3), pos(pts.size(), 3);
  for (size_t i = 0; i < pts.size(); ++i) {
    face[i] = pts[i].face;
    bary.row(i) = pts[i].barycentric.transpose();
    pos.row(i) = pts[i].position.transpose();
  }
  py::dict d;
  d["face"] = to_numpy(face);
  d["barycentric"] = to_numpy(bary);
  d["position"] = to_numpy(pos);
  return d;
}

// The report JSON (map/map_report.h) as Python objects: objects -> dict,
// arrays -> list; numbers keep their value (nan and inf included, which a
// round trip through json.dumps would turn into null).
py::object json_to_python(const nlohmann::json& j) {
  switch (j.type()) {
    case nlohmann::json::value_t::null: return py::none();
    case nlohmann::json::value_t::boolean: return py::bool_(j.get<bool>());
    case nlohmann::json::value_t::number_integer: return py::int_(j.get<long long>());
    case nlohmann::json::value_t::number_unsigned: return py::int_(j.get<unsigned long long>());
    case nlohmann::json::value_t::number_float: return py::float_(j.get<double>());
    case nlohmann::json::value_t::string: return py::str(j.get_ref<const std::string&>());
    case nlohmann::json::value_t::array: {
      py::list out;
      for (const auto& item : j) out.append(json_to_python(item));
      return std::move(out);
    }
    case nlohmann::json::value_t::object: {
      py::dict out;
      for (const auto& [key, item] : j.items()) out[py::str(key)] = json_to_python(item);
      return std::move(out);
    }
    default: throw SolveError("report: a JSON value of unexpected type");
  }
}

PolygonSoup to_soup(const RowMatrixX3d& V, const RowMatrixX3i& F) {
  PolygonSoup soup;
  soup.V = V;
  soup.polygons.resize(F.rows());
  for (int f = 0; f < F.rows(); ++f) soup.polygons[f] = {F(f, 0), F(f, 1), F(f, 2)};
  return soup;
}

// The result dict of a map (both closed and open pairs): the report JSON plus
// the per-vertex and per-face arrays as numpy arrays.
py::dict result_dict(const nlohmann::json& report, const SurfaceMapResult& r) {
  py::dict d = json_to_python(report);
  d["distortion"].cast<py::dict>()["per_face"] = to_numpy(r.dilatation);
  d["initial_distortion"].cast<py::dict>()["per_face"] = to_numpy(r.initial_dilatation);
  d["forward"] = points_to_dict(r.forward);
  d["inverse"] = points_to_dict(r.inverse);
  // The initial map located on the target (None for genus 0, open surfaces
  // or when it could not be located).
  d["initial_forward"] = r.initial_forward.empty() ? py::object(py::none()) : py::object(points_to_dict(r.initial_forward));
  d["initial_inverse"] = r.initial_inverse.empty() ? py::object(py::none()) : py::object(points_to_dict(r.initial_inverse));
  return d;
}

// `boundary_pairing` of surface_map: None (loop i -> loop i), "swap" (annuli:
// loop 0 <-> loop 1) or the target loop of each source loop by index.
void parse_boundary_pairing(const py::object& pairing, OpenMapOptions& options) {
  if (pairing.is_none()) return;
  if (py::isinstance<py::str>(pairing)) {
    if (pairing.cast<std::string>() != "swap")
      throw InputError("boundary_pairing must be None, 'swap' or a list of target loop indices, not '" +
                       pairing.cast<std::string>() + "'");
    options.swap_annulus_loops = true;
    return;
  }
  try {
    options.boundary_pairing = py::cast<std::vector<int>>(
        py::module_::import("numpy").attr("asarray")(pairing, "int64").attr("reshape")(-1).attr("tolist")());
  } catch (const py::cast_error&) {
    throw InputError("boundary_pairing must be None, 'swap' or a list of target loop indices");
  }
}

// The package this module belongs to ("surfmap", or the add-on's vendored
// "<add-on>.surfmap"), so that its Python modules are imported from the
// same copy; set by bind_map.
std::string& package_name() {
  static std::string name = "surfmap";
  return name;
}

// The `landmarks` keyword, (k, 2) source/target vertex indices, as pairs (None: none); an
// index that is negative or beyond int32 is an InputError naming the pair (the range against
// each mesh is checked by the solver).
std::vector<std::pair<int, int>> landmark_pairs(const py::object& landmarks) {
  std::vector<std::pair<int, int>> out;
  if (landmarks.is_none()) return out;
  const auto pairs = py::cast<std::vector<std::vector<long long>>>(
      py::module_::import("numpy").attr("asarray")(landmarks, "int64").attr("reshape")(-1, 2).attr("tolist")());
  for (const auto& p : pairs) {
    if (p[0] < 0 || p[1] < 0 || p[0] > INT32_MAX || p[1] > INT32_MAX)
      throw InputError("landmark (" + std::to_string(p[0]) + ", " + std::to_string(p[1]) + ") has a negative or too large index");
    out.emplace_back(static_cast<int>(p[0]), static_cast<int>(p[1]));
  }
  return out;
}

// surface_map for a pair with boundary (docs/open_surfaces.md): disks and
// annuli through map/open_map.h. Runs with the GIL held except the solve.
py::dict open_surface_map_dict(const RowMatrixX3d& vs, const RowMatrixX3i& fs, const RowMatrixX3d& vt,
                               const RowMatrixX3i& ft, const py::object& boundary_pairing,
                               const py::object& landmarks, const py::object& progress, int refine_rings,
                               int refine_levels, bool reflection_solve) {
  OpenMapOptions options;
  parse_boundary_pairing(boundary_pairing, options);
  options.landmarks = landmark_pairs(landmarks);
  // Progress: one call before and one after (the open map is two sparse
  // solves per side); False cancels like the closed map.
  auto report_progress = [&](double fraction) {
    if (progress.is_none()) return;
    const py::object r = progress("open surface map", fraction);
    if (!(r.is_none() || r.cast<bool>())) throw Cancelled("cancelled by the progress callback");
  };
  OpenMapResult r;
  auto load = [](const RowMatrixX3d& V, const RowMatrixX3i& F, const char* side) {
    try {
      return intake_open(to_soup(V, F));
    } catch (const InputError& e) {
      throw InputError(std::string(side) + ": " + e.what());
    }
  };
  std::optional<OpenIntakeResult> src, dst;
  {
    py::gil_scoped_release release;
    src.emplace(load(vs, fs, "source"));
    dst.emplace(load(vt, ft, "target"));
    try {
      check_same_open_topology(src->topology, dst->topology);
    } catch (const InputError& e) {
      // A closed surface against an open one: say first which side is open.
      const int bs = src->topology.num_boundary_loops(), bt = dst->topology.num_boundary_loops();
      const std::string side = (bs == 0) != (bt == 0) ? (bs ? "source: open surface; " : "target: open surface; ") : "";
      throw InputError(side + e.what() + " (open surfaces: docs/open_surfaces.md)");
    }
  }
  // Beyond disks and annuli: through the doubles (surfmap/open_double.py;
  // docs/open_surfaces.md "Doubling"), which returns the same dict.
  const int g = src->topology.genus, b = src->topology.num_boundary_loops();
  if (!(g == 0 && (b == 1 || b == 2))) {
    py::object pairing = boundary_pairing;
    return py::module_::import((package_name() + ".open_double").c_str())
        .attr("surface_map_open")(to_numpy(vs), to_numpy(fs), to_numpy(vt), to_numpy(ft), py::arg("boundary_pairing") = pairing,
                                  py::arg("progress") = progress, py::arg("landmarks") = landmarks,
                                  py::arg("refine_rings") = refine_rings, py::arg("refine_levels") = refine_levels,
                                  py::arg("reflection_solve") = reflection_solve)
        .cast<py::dict>();
  }
  report_progress(0.0);
  {
    py::gil_scoped_release release;
    r = open_surface_map(src->intake.mesh, src->topology, dst->intake.mesh, dst->topology, options);
  }
  report_progress(1.0);
  py::dict d = result_dict(to_json(r, options), r.map);
  d["source_flipped"] = false;  // open meshes are never reoriented
  d["target_flipped"] = false;
  return d;
}

bool has_boundary(const RowMatrixX3d& V, const RowMatrixX3i& F) {
  return inspect(to_soup(V, F)).num_boundary_loops > 0;
}

// What a closed pair's solve reads, converted from surface_map's arguments on
// the calling thread: no Python object, so that it can cross to a thread that
// never takes the GIL (MapJob).
struct ClosedInputs {
  RowMatrixX3d vs, vt;
  RowMatrixX3i fs, ft;
  SurfaceMapOptions opt;  // progress hooks left to the caller
};

// surface_map's arguments after conversion (def_with_map_arguments): the
// meshes and closed options, and what the open path and the callbacks read.
struct MapCall {
  ClosedInputs in;
  bool open = false;
  py::object progress, solve_progress, boundary_pairing, landmarks;
  int refine_rings = 4, refine_levels = 2;
  bool reflection_solve = true;
};

// A closed pair's solve: intake, the genus check, the map. Runs no Python.
struct ClosedSolve {
  IntakeResult src, dst;
  SurfaceMapResult r;
};
void solve_closed(const ClosedInputs& in, ClosedSolve& s) {
  intake_source_and_target(in.vs, in.fs, in.vt, in.ft, s.src, s.dst);
  check_same_genus(s.src.info, s.dst.info);
  s.r = surface_map(s.src.mesh, s.dst.mesh, in.opt);
}

// The result dict of a closed solve: the report's keys and values
// (map/map_report.h, as the CLI's --report file), plus the arrays as numpy
// arrays. Needs the GIL.
py::dict closed_result(const ClosedSolve& s, const SurfaceMapOptions& opt) {
  py::dict d = result_dict(to_json(s.r, opt), s.r);
  d["source_flipped"] = s.src.flipped;
  d["target_flipped"] = s.dst.flipped;
  return d;
}

// surface_map: the solve on the calling thread, the GIL released during it;
// the callbacks re-acquire it (a Python exception inside one stops the solve
// and is re-raised as is).
py::object surface_map_now(MapCall& c) {
  if (c.open)
    return open_surface_map_dict(c.in.vs, c.in.fs, c.in.vt, c.in.ft, c.boundary_pairing, c.landmarks, c.progress,
                                 c.refine_rings, c.refine_levels, c.reflection_solve);
  SurfaceMapOptions& opt = c.in.opt;
  std::optional<py::error_already_set> callback_error;
  if (!c.progress.is_none())
    opt.progress = [&](const std::string& stage, double fraction) {
      py::gil_scoped_acquire gil;
      try {
        const py::object r = c.progress(stage, fraction);
        return r.is_none() || r.cast<bool>();
      } catch (py::error_already_set& e) {
        callback_error.emplace(std::move(e));
        return false;
      }
    };
  if (!c.solve_progress.is_none())
    opt.solve_progress = [&](int iteration, double energy, double gradient) {
      py::gil_scoped_acquire gil;
      try {
        const py::object r = c.solve_progress(iteration, energy, gradient);
        return r.is_none() || r.cast<bool>();
      } catch (py::error_already_set& e) {
        callback_error.emplace(std::move(e));
        return false;
      }
    };
  ClosedSolve s;
  try {
    py::gil_scoped_release release;
    solve_closed(c.in, s);
  } catch (const Cancelled&) {
    if (callback_error) throw std::move(*callback_error);
    throw;
  }
  return closed_result(s, opt);
}

// --- MapJob: a closed pair's solve on a C++ thread that never takes the GIL
// (docs/python.md "start_surface_map and MapJob"). Its progress goes to a mutex-guarded state the
// caller polls; its cancel flag is read by the core's progress hooks, which
// then return false (the core throws Cancelled, as for surface_map's
// callbacks).

// Lowers the calling thread's scheduling priority by `step` (Linux: nice is
// per thread, and threads it starts later inherit it; a no-op elsewhere).
// Returns the step applied (0 when none); never throws.
int lower_this_thread_priority(int step) {
#ifdef __linux__
  if (step <= 0) return 0;
  const auto tid = static_cast<id_t>(syscall(SYS_gettid));
  errno = 0;
  const int now = getpriority(PRIO_PROCESS, tid);
  if (now == -1 && errno != 0) return 0;
  if (setpriority(PRIO_PROCESS, tid, std::min(now + step, 19)) != 0) return 0;
  return getpriority(PRIO_PROCESS, tid) - now;
#else
  (void)step;
  return 0;
#endif
}

long this_thread_native_id() {
#ifdef __linux__
  return static_cast<long>(syscall(SYS_gettid));
#else
  return 0;
#endif
}

// Written by the job's thread (and the core's threads through the hooks),
// read by the polls: every field behind `mutex`, but `cancel`.
struct MapJobState {
  std::mutex mutex;
  std::condition_variable finished;
  std::string stage = "starting";
  double fraction = 0;
  int iteration = -1;  // the harmonic solve's last (iteration, energy, gradient); -1: none yet
  double energy = 0, gradient = 0;
  bool done = false;
  int niceness = 0;
  long thread_id = 0;
  std::atomic<bool> cancel{false};
  ClosedInputs in;
  ClosedSolve out;
  std::exception_ptr error;
};

// The thread and its state; shared by the Python object and the exit
// registry (stop_every_job), so that either may stop it first.
class MapJobRunner {
 public:
  MapJobRunner(ClosedInputs in, int niceness) : s_(std::make_shared<MapJobState>()) {
    s_->in = std::move(in);
    MapJobState* s = s_.get();
    s->in.opt.progress = [s](const std::string& stage, double fraction) {
      std::lock_guard<std::mutex> lock(s->mutex);
      s->stage = stage;
      s->fraction = fraction;
      return !s->cancel.load();
    };
    s->in.opt.solve_progress = [s](int iteration, double energy, double gradient) {
      std::lock_guard<std::mutex> lock(s->mutex);
      s->iteration = iteration;
      s->energy = energy;
      s->gradient = gradient;
      return !s->cancel.load();
    };
    thread_ = std::thread([state = s_, niceness] { run(*state, niceness); });
  }
  ~MapJobRunner() { stop(); }  // (stop released the GIL already when called from Python)
  MapJobRunner(const MapJobRunner&) = delete;
  MapJobRunner& operator=(const MapJobRunner&) = delete;

  MapJobState& state() { return *s_; }
  // Asks the solve to stop and waits for its thread (the GIL released meanwhile when held).
  void stop() {
    s_->cancel = true;
    join();
  }
  void join() {
    if (joined_) return;  // (no GIL handoff for a job joined already, e.g. at the interpreter's exit)
    if (Py_IsInitialized() && PyGILState_Check()) {
      py::gil_scoped_release release;
      join_now();
    } else {
      join_now();
    }
  }

 private:
  static void run(MapJobState& s, int niceness) {
    const int step = lower_this_thread_priority(niceness);
    {
      std::lock_guard<std::mutex> lock(s.mutex);
      s.niceness = step;
      s.thread_id = this_thread_native_id();
    }
    try {
      solve_closed(s.in, s.out);
    } catch (...) {
      s.error = std::current_exception();
    }
    {
      // A cancel that came after the solve's last progress point, but before
      // it was done, still cancels (cancel() returned True: result() raises).
      std::lock_guard<std::mutex> lock(s.mutex);
      if (!s.error && s.cancel.load()) {
        s.error = std::make_exception_ptr(Cancelled("cancelled after the solve's last progress point"));
        s.out = ClosedSolve{};
      }
      s.done = true;
    }
    s.finished.notify_all();
  }
  void join_now() {
    std::lock_guard<std::mutex> lock(join_mutex_);
    if (thread_.joinable()) thread_.join();
    joined_ = true;
  }

  std::shared_ptr<MapJobState> s_;
  std::mutex join_mutex_;
  std::atomic<bool> joined_{false};
  std::thread thread_;
};

// Every running job, so that an interpreter that exits (Blender quitting
// mid-solve) stops them before the process's globals go: registered with
// Python's atexit by bind_map.
std::mutex& jobs_mutex() {
  static std::mutex m;
  return m;
}
std::vector<std::weak_ptr<MapJobRunner>>& jobs() {
  static std::vector<std::weak_ptr<MapJobRunner>> v;
  return v;
}
void stop_every_job() {
  std::vector<std::shared_ptr<MapJobRunner>> live;
  {
    std::lock_guard<std::mutex> lock(jobs_mutex());
    for (const auto& w : jobs())
      if (auto j = w.lock()) live.push_back(std::move(j));
  }
  for (const auto& j : live) j->stop();
}

// The Python object surfmap.MapJob (made by start_surface_map).
class MapJob {
 public:
  MapJob(ClosedInputs in, int niceness) : runner_(std::make_shared<MapJobRunner>(std::move(in), niceness)) {
    std::lock_guard<std::mutex> lock(jobs_mutex());
    auto& v = jobs();
    v.erase(std::remove_if(v.begin(), v.end(), [](const auto& w) { return w.expired(); }), v.end());
    v.push_back(runner_);
  }
  // Dropped while running: cancelled, and its thread joined (the GIL released).
  ~MapJob() { runner_->stop(); }

  // The state copied under the mutex, the dict built after it (building
  // Python objects under it would hold the solve's hooks while Python runs).
  py::dict progress() {
    MapJobState& s = runner_->state();
    std::string stage;
    double fraction, energy, gradient;
    int iteration;
    bool done;
    {
      std::lock_guard<std::mutex> lock(s.mutex);
      stage = s.stage;
      fraction = s.fraction;
      iteration = s.iteration;
      energy = s.energy;
      gradient = s.gradient;
      done = s.done;
    }
    py::dict d;
    d["stage"] = stage;
    d["fraction"] = fraction;
    d["iteration"] = iteration >= 0 ? py::object(py::int_(iteration)) : py::object(py::none());
    d["energy"] = iteration >= 0 ? py::object(py::float_(energy)) : py::object(py::none());
    d["gradient"] = iteration >= 0 ? py::object(py::float_(gradient)) : py::object(py::none());
    d["cancelled"] = s.cancel.load();
    d["done"] = done;
    return d;
  }
  // As concurrent.futures.Future.cancel: False once the job is done (its
  // result or error stands), else True and result() raises Cancelled (the
  // flag is set under the mutex that `run` reads it under when it finishes).
  bool cancel() {
    MapJobState& s = runner_->state();
    std::lock_guard<std::mutex> lock(s.mutex);
    if (s.done) return false;
    s.cancel = true;
    return true;
  }
  bool done() {
    MapJobState& s = runner_->state();
    std::lock_guard<std::mutex> lock(s.mutex);
    return s.done;
  }
  // Waits up to `timeout` seconds (None or inf: until done; 0 or less: not at
  // all, as threading.Event.wait) with the GIL released; returns done(). An
  // infinite or huge double would overflow wait_for's clock arithmetic (it
  // returned at once), so anything past a year waits without a deadline.
  bool wait(const py::object& timeout) {
    const double seconds = timeout.is_none() ? std::numeric_limits<double>::infinity() : timeout.cast<double>();
    if (std::isnan(seconds)) throw InputError("wait: timeout is NaN (give seconds, or None to wait until done)");
    MapJobState& s = runner_->state();
    py::gil_scoped_release release;
    std::unique_lock<std::mutex> lock(s.mutex);
    if (seconds > 365.0 * 24 * 3600)
      s.finished.wait(lock, [&] { return s.done; });
    else
      s.finished.wait_for(lock, std::chrono::duration<double>(std::max(seconds, 0.0)), [&] { return s.done; });
    return s.done;
  }
  // The map's dict, as surface_map returns it (waits for the solve first); the
  // solve's error re-raised here as surface_map raises it.
  py::dict result() {
    wait(py::none());
    runner_->join();
    MapJobState& s = runner_->state();
    if (s.error) std::rethrow_exception(s.error);
    return closed_result(s.out, s.in.opt);
  }
  int niceness() {
    MapJobState& s = runner_->state();
    std::lock_guard<std::mutex> lock(s.mutex);
    return s.niceness;
  }
  long thread_id() {
    MapJobState& s = runner_->state();
    std::lock_guard<std::mutex> lock(s.mutex);
    return s.thread_id;
  }

 private:
  std::shared_ptr<MapJobRunner> runner_;
};

// start_surface_map: the arguments converted here, the solve started on a MapJob's thread.
py::object start_map_job(MapCall& c, int niceness) {
  if (c.open)
    throw InputError("start_surface_map: closed surfaces only (an open pair's driver runs Python: call "
                     "surface_map on a thread of your own; docs/python.md \"start_surface_map and MapJob\")");
  if (!c.progress.is_none() || !c.solve_progress.is_none())
    throw InputError("start_surface_map takes no progress callbacks (they would run Python on the solve's "
                     "thread): poll the job's progress()");
  if (niceness < 0) throw InputError("niceness must be 0 or more");
  return py::cast(new MapJob(std::move(c.in), niceness), py::return_value_policy::take_ownership);
}

// Defines `name` in `m` with surface_map's keywords, defaults and conversions,
// then the `Extra` parameters (their py::args in `extra_args`): body(call,
// extra...) gets the converted arguments. surface_map and start_surface_map
// share this one list, so their keywords cannot drift apart.
//
// Long on purpose: one py::arg per option, in the options struct's order, read
// like a table.
template <class... Extra, class Body, class... ExtraArgs>
void def_with_map_arguments(py::module_& m, const char* name, Body body, const char* doc, ExtraArgs... extra_args) {
  m.def(
      name,
      [body](py::handle Vs, py::handle Fs, py::handle Vt, py::handle Ft, int homotopy, int source_base_vertex,
         int target_base_vertex, py::object progress, py::object landmarks, const std::string& method,
         double tolerance, int max_iterations, py::object solve_progress, int homotopy_candidates,
         int homotopy_full_solves, const std::string& initial_map, const std::string& source_weights,
         bool homotopy_search, int homotopy_search_evaluations, py::object boundary_pairing, bool two_way, int threads, const std::string& target_metric,
         py::object homotopy_images, bool homotopy_both_signs, bool flat_overlay, bool cheap_direction_check,
         bool compare_directions, bool greedy_pants, int homotopy_extra_cuts, double own_weights_floor,
         bool local_fold_repair, bool fold_untangle, const std::string& target_loops, double two_way_ratio,
         bool snapped_start, bool landmarks_may_fold, bool through_shape, const std::string& face_charts,
         bool locate_initial_map, int refine_rings, int refine_levels, bool reflection_solve,
         bool short_canonical_generators, double agreement_ratio, bool both_canonical_bases, py::object class_words,
         bool geometric_layout_basis, bool short_curve_twists, bool short_generators_fallback, int high_kicks,
         bool fold_fallback, double through_shape_ratio, Extra... extra) -> py::object {
        const RowMatrixX3d vs = to_vertices(Vs, "source V"), vt = to_vertices(Vt, "target V");
        const RowMatrixX3i fs = to_triangles(Fs, "source F"), ft = to_triangles(Ft, "target F");
        // Open surfaces (issue 16): either side with a boundary.
        bool open = false;
        {
          py::gil_scoped_release release;
          open = has_boundary(vs, fs) || has_boundary(vt, ft);
        }
        if (refine_rings < 1) throw InputError("refine_rings must be at least 1");
        if (refine_levels < 0) throw InputError("refine_levels must be at least 0");
        MapCall call;
        call.progress = progress;
        call.solve_progress = solve_progress;
        if (open) {
          call.open = true;
          call.in = ClosedInputs{vs, vt, fs, ft, {}};
          call.boundary_pairing = boundary_pairing;
          call.landmarks = landmarks;
          call.refine_rings = refine_rings;
          call.refine_levels = refine_levels;
          call.reflection_solve = reflection_solve;
          return body(call, extra...);
        }
        if (!boundary_pairing.is_none()) throw InputError("boundary_pairing: only for open surfaces (meshes with boundary loops)");
        SurfaceMapOptions opt;
        opt.homotopy.class_index = homotopy;
        if (!class_words.is_none()) {
          // (options.homotopy.class_words; CLI --class-words: a class named by its words)
          try {
            opt.homotopy.class_words = class_words.cast<std::vector<std::vector<int>>>();
          } catch (const py::cast_error&) {
            throw InputError("class_words must be a list of 2g lists of int letters (as the report's "
                             "homotopy.chosen_words)");
          }
          if (opt.homotopy.class_words.empty()) throw InputError("class_words must not be empty (None: not given)");
        }
        opt.loops.source_base_vertex = source_base_vertex;
        opt.loops.target_base_vertex = target_base_vertex;
        opt.loops.short_canonical_generators = short_canonical_generators;
        opt.loops.both_canonical_bases = both_canonical_bases;
        opt.homotopy.search.geometric_layout_basis = geometric_layout_basis;  // --geometric-layout-basis
        opt.homotopy.search.curve_twists = short_curve_twists;  // --short-curve-twists
        if (high_kicks < 0) throw InputError("high_kicks must be at least 0, got " + std::to_string(high_kicks));
        opt.homotopy.search.high_kicks = high_kicks;  // --high-kicks N (0: none)
        opt.loops.short_generators_fallback = short_generators_fallback;  // --no-short-generators-fallback
        opt.loops.fold_fallback = fold_fallback;  // --no-fold-fallback
        opt.solve.method = parse_enum<MapMethod>(method, "method");
        if (!(tolerance > 0)) throw InputError("tolerance must be positive");
        if (max_iterations < 1) throw InputError("max_iterations must be at least 1");
        opt.solve.tolerance = tolerance;
        opt.solve.max_iterations = max_iterations;
        if (homotopy_candidates < 1) throw InputError("homotopy_candidates must be at least 1");
        if (homotopy_full_solves < 1) throw InputError("homotopy_full_solves must be at least 1");
        opt.homotopy.candidates = homotopy_candidates;
        opt.homotopy.full_solves = homotopy_full_solves;
        if (homotopy_search_evaluations < 1) throw InputError("homotopy_search_evaluations must be at least 1");
        opt.homotopy.search.enabled = homotopy_search;
        opt.homotopy.search.evaluations = homotopy_search_evaluations;
        opt.homotopy.two_way = two_way;  // (options.homotopy.two_way)
        opt.homotopy.flat_both_signs = homotopy_both_signs;
        opt.homotopy.flat_overlay = flat_overlay;  // (options.homotopy.flat_overlay)
        // The CLI's other map options, one keyword each (cmd_map.cpp: --no-cheap-direction-check,
        // --compare-directions, --no-greedy-pants, --homotopy-extra-cuts, --own-weights-floor,
        // --no-local-fold-repair, --no-fold-untangle, --target-loops), so that a Python caller can run what the CLI runs.
        opt.homotopy.cheap_direction_check = cheap_direction_check;
        opt.homotopy.compare_directions = compare_directions;
        opt.homotopy.search.greedy_pants = greedy_pants;
        opt.homotopy.search.snapped_start = snapped_start;  // --no-snapped-start
        opt.homotopy.through_shape = through_shape;  // --no-through-shape
        // (options.homotopy.through_shape_ratio; CLI --through-shape-ratio)
        if (!(through_shape_ratio >= 0)) throw InputError("through_shape_ratio must be 0 or more");
        opt.homotopy.through_shape_ratio = through_shape_ratio;
        if (homotopy_extra_cuts < 0) throw InputError("homotopy_extra_cuts must be 0 or more");
        opt.homotopy.extra_cuts = homotopy_extra_cuts;
        if (!(own_weights_floor > 0)) throw InputError("own_weights_floor must be positive");
        opt.solve.own_weights_floor = own_weights_floor;
        opt.solve.local_fold_repair = local_fold_repair;
        opt.solve.fold_untangle = fold_untangle;
        opt.uniformization.loops = parse_enum<LoopMetric>(target_loops, "target_loops");
        opt.uniformization.face_charts = parse_enum<FaceCharts>(face_charts, "face_charts");
        // (options.homotopy.two_way_ratio; no CLI flag: 0 runs the other direction, and with it
        // the cheap direction check, for every pair)
        if (!(two_way_ratio >= 0)) throw InputError("two_way_ratio must be 0 or more");
        opt.homotopy.two_way_ratio = two_way_ratio;
        // (options.homotopy.agreement_ratio; CLI --agreement-ratio)
        if (!(agreement_ratio >= 0)) throw InputError("agreement_ratio must be 0 or more");
        opt.homotopy.agreement_ratio = agreement_ratio;
        if (!homotopy_images.is_none()) {
          // (options.homotopy.source_images with images_only: that class alone)
          const RowMatrixX3d images = to_vertices(homotopy_images, "homotopy_images");
          if (images.rows() != vs.rows())
            throw InputError("homotopy_images must have one row per source vertex (" + std::to_string(vs.rows()) +
                             "), not " + std::to_string(images.rows()));
          opt.homotopy.source_images = images;
          opt.homotopy.images_only = true;
        }
        opt.initial.method = parse_enum<InitialMapMethod>(initial_map, "initial_map");
        opt.initial.locate = locate_initial_map;
        opt.solve.source_weights = parse_enum<SourceWeights>(source_weights, "source_weights");
        if (threads < 0) throw InputError("threads must be 0 (automatic) or at least 1");
        opt.threads = threads;
        // (options.uniformization.target_metric)
        opt.uniformization.target_metric = parse_enum<UniformizationMetric>(target_metric, "target_metric");
        opt.landmarks = landmark_pairs(landmarks);
        opt.landmarks_may_fold = landmarks_may_fold;  // (--landmarks-may-fold)
        call.in = ClosedInputs{vs, vt, fs, ft, std::move(opt)};
        return body(call, extra...);
      },
      // Every default is the options structs' own (map/surface_map.h), as the CLI's flags
      // (cli/cmd_map.cpp): one set of defaults for every path (docs/handle_classes.md
      // "Quality signal"; test test_default_map_is_the_same_on_every_path).
      py::arg("source_V"), py::arg("source_F"), py::arg("target_V"), py::arg("target_F"),
      py::arg("homotopy") = HomotopyOptions().class_index,
      py::arg("source_base_vertex") = LoopOptions().source_base_vertex,
      py::arg("target_base_vertex") = LoopOptions().target_base_vertex, py::arg("progress") = py::none(),
      py::arg("landmarks") = py::none(), py::arg("method") = enum_name(SolveOptions().method),
      py::arg("tolerance") = SolveOptions().tolerance, py::arg("max_iterations") = SolveOptions().max_iterations,
      py::arg("solve_progress") = py::none(), py::arg("homotopy_candidates") = HomotopyOptions().candidates,
      py::arg("homotopy_full_solves") = HomotopyOptions().full_solves,
      py::arg("initial_map") = enum_name(InitialMapOptions().method),
      py::arg("source_weights") = enum_name(SolveOptions().source_weights),
      py::arg("homotopy_search") = HomotopySearchOptions().enabled,
      py::arg("homotopy_search_evaluations") = HomotopySearchOptions().evaluations,
      py::arg("boundary_pairing") = py::none(), py::arg("two_way") = HomotopyOptions().two_way,
      py::arg("threads") = SurfaceMapOptions().threads,
      py::arg("target_metric") = enum_name(UniformizationOptions().target_metric),
      py::arg("homotopy_images") = py::none(), py::arg("homotopy_both_signs") = HomotopyOptions().flat_both_signs,
      py::arg("flat_overlay") = HomotopyOptions().flat_overlay,
      py::arg("cheap_direction_check") = HomotopyOptions().cheap_direction_check,
      py::arg("compare_directions") = HomotopyOptions().compare_directions,
      py::arg("greedy_pants") = HomotopySearchOptions().greedy_pants,
      py::arg("homotopy_extra_cuts") = HomotopyOptions().extra_cuts, py::arg("own_weights_floor") = SolveOptions().own_weights_floor,
      py::arg("local_fold_repair") = SolveOptions().local_fold_repair,
      py::arg("fold_untangle") = SolveOptions().fold_untangle,
      py::arg("target_loops") = enum_name(UniformizationOptions().loops),
      py::arg("two_way_ratio") = HomotopyOptions().two_way_ratio,
      py::arg("snapped_start") = HomotopySearchOptions().snapped_start,
      py::arg("landmarks_may_fold") = SurfaceMapOptions().landmarks_may_fold,
      py::arg("through_shape") = HomotopyOptions().through_shape,
      py::arg("face_charts") = enum_name(UniformizationOptions().face_charts),
      py::arg("locate_initial_map") = InitialMapOptions().locate,
      // Open pairs through the doubles only (surfmap/open_double.py surface_map_open's keywords and
      // defaults; docs/open_surfaces.md "Options", "The half's solve").
      py::arg("refine_rings") = 4, py::arg("refine_levels") = 2, py::arg("reflection_solve") = true,
      py::arg("short_canonical_generators") = LoopOptions().short_canonical_generators,
      py::arg("agreement_ratio") = HomotopyOptions().agreement_ratio,
      py::arg("both_canonical_bases") = LoopOptions().both_canonical_bases, py::arg("class_words") = py::none(),
      py::arg("geometric_layout_basis") = HomotopySearchOptions().geometric_layout_basis,
      py::arg("short_curve_twists") = HomotopySearchOptions().curve_twists,
      py::arg("short_generators_fallback") = LoopOptions().short_generators_fallback,
      py::arg("high_kicks") = HomotopySearchOptions().high_kicks,
      py::arg("fold_fallback") = LoopOptions().fold_fallback,
      py::arg("through_shape_ratio") = HomotopyOptions().through_shape_ratio,
      extra_args..., doc);
}

}  // namespace

// Long on purpose: the map's entry points, each with its docstring, read like a table; split, a
// keyword and its documentation would sit apart (surface_map's keyword list: def_with_map_arguments).
void bind_map(py::module_& m) {
  {
    const std::string name = py::str(m.attr("__name__"));
    const size_t dot = name.rfind('.');
    if (dot != std::string::npos) package_name() = name.substr(0, dot);
  }
  // What this build's surface_map accepts beyond the meshes, by keyword
  // argument name, for callers that must work with older builds (the
  // add-on): read this set instead of searching docstrings.
  m.attr("CAPABILITIES") = py::frozenset(py::make_tuple(
      "homotopy", "landmarks", "method", "tolerance", "max_iterations", "solve_progress", "homotopy_candidates",
      "homotopy_full_solves", "initial_map", "source_weights", "homotopy_search", "homotopy_search_evaluations",
      "progress", "source_base_vertex", "target_base_vertex", "boundary_pairing", "two_way", "threads", "target_metric", "homotopy_images",
      "homotopy_both_signs", "flat_overlay", "cheap_direction_check", "compare_directions", "greedy_pants",
      "homotopy_extra_cuts", "own_weights_floor", "local_fold_repair", "fold_untangle", "target_loops", "two_way_ratio",
      "snapped_start", "landmarks_may_fold", "through_shape", "face_charts", "locate_initial_map", "refine_rings",
      "refine_levels", "reflection_solve", "short_canonical_generators", "agreement_ratio",
      "both_canonical_bases", "class_words", "geometric_layout_basis", "short_curve_twists",
      "short_generators_fallback", "high_kicks", "fold_fallback", "through_shape_ratio"));
  // What the module does beyond its keywords, for callers built against older modules (the
  // add-on): "open_landmarks" = open pairs hold `landmarks` (docs/open_surfaces.md "Landmarks").
  m.attr("FEATURES") = py::frozenset(py::make_tuple("open_landmarks"));
  // (the methods' documentation: docs/python.md "start_surface_map and MapJob")
  py::class_<MapJob>(m, "MapJob", "A closed pair's map computed on a thread that never takes the GIL (made by "
                                  "start_surface_map): progress() {stage, fraction, iteration, energy, gradient, "
                                  "cancelled, done} and done() never block on the solve; cancel() stops it at its next "
                                  "progress point and returns True (result() then raises surfmap.Cancelled), or returns "
                                  "False when the job is done already (its result or error stands, as "
                                  "concurrent.futures.Future.cancel); wait(timeout=None) waits "
                                  "with the GIL released (None or inf: until done; 0 or less: not at all) and returns "
                                  "done(); result() waits, then returns "
                                  "surface_map's dict or raises its error; niceness: the priority step the thread "
                                  "applied; thread_id: its native id (0 until it started, and off Linux).")
      .def("progress", &MapJob::progress)
      .def("cancel", &MapJob::cancel)
      .def("done", &MapJob::done)
      .def("wait", &MapJob::wait, py::arg("timeout") = py::none())
      .def("result", &MapJob::result)
      .def_property_readonly("niceness", &MapJob::niceness)
      .def_property_readonly("thread_id", &MapJob::thread_id);
  // Blender quitting (or any interpreter exiting) mid-solve: every job is cancelled and its thread
  // joined before the process's globals go.
  py::module_::import("atexit").attr("register")(py::cpp_function([] { stop_every_job(); }));
  static const char* const surface_map_doc =
      "Globally optimal map from the source onto the target (same genus; genus 0 through the sphere). Open surfaces "
      "(meshes with boundary loops, docs/open_surfaces.md): both sides must have the same genus g and number b of "
      "boundary loops (else InputError naming both); disks (0, 1) and annuli (0, 2) are mapped boundary onto boundary "
      "with the same result dict plus 'source_topology' / 'target_topology' ({genus, boundary_loops, description}) and "
      "'open' (domain, rotation, moduli, extremal_dilatation, boundary_pairing), every other (g, b) through the doubles "
      "(surfmap.open_double.surface_map_open; 'open' domain 'double'); `boundary_pairing`: None (disks, annuli: loop "
      "i -> loop i, loops longest first; doubles: ranked by energy), 'swap' (two loops) or the target loop of each "
      "source loop; the closed-map options "
      "(homotopy, method, ...) do not apply; `landmarks` (source vertex, target vertex) pairs are held as "
      "docs/open_surfaces.md 'Landmarks' says (disk: up to 3 boundary points or 1 interior + 1 boundary; annulus: the "
      "shift; doubles: each with its mirror image). Returns a dict "
      "with 'forward' (per source vertex: target 'face', 'barycentric', 'position'), 'inverse' (per target "
      "vertex, on the source), energies, distortion and the homotopy candidates. `landmarks`: (k, 2) "
      "(source vertex, target vertex) pairs held fixed; `method`: 'newton' or 'relaxation'; "
      "`solve_progress(iteration, energy, gradient)` is called every iteration of the harmonic solve (genus >= 2) "
      "and may return False to cancel; `homotopy_candidates` / `homotopy_full_solves`: how many genus >= 2 "
      "handle classes are listed / solved to convergence for the ranking; `homotopy_search`: search the mapping class "
      "group from the best candidate over Dehn twists, at most `homotopy_search_evaluations` coarse solves ('homotopy' "
      "'search' in the result: moves, energies, every neighbour evaluated); `initial_map`: 'cut_graph' (genus >= 2, the default: the source cut "
      "along its own cut graph onto the convex polygon of that graph's harmonic map into the target, an embedding by "
      "construction; else as 'polygon'), 'polygon' (the "
      "source disk onto the target's geodesic polygon of the source's loops when convex, else uniform) or 'uniform' "
      "('initial_map' in the result says which was used); `locate_initial_map`: also locate the initial map (default False; "
      "'initial_forward': the initial map located on the target, 'initial_inverse': each target vertex located on the "
      "source through the initial map, else None; 'initial_map' 'located' / 'location_requested' in the result); `source_weights`: 'auto' "
      "(intrinsic Delaunay cotangents, the source's own edges when their images fold), 'intrinsic' or 'own' "
      "('source_weights' in the result says which were used); `threads`: threads the pipeline runs at once (0: "
      "SURFMAP_THREADS, else 2 on two cores; 1: in order; the result does not depend on it); 'stages' in the result: "
      "the stage table (per stage time_s, analyses, factorisations, newton_iterations, peak_memory_mb; last row "
      "'total'); `target_metric`: 'auto' (genus >= 1 default: "
      "'flips', 'fixed' only when the flip path fails), 'flips' (the target's flip-based metric, "
      "results carried back to its own faces), 'fixed' (its own edges, refined when needed) or 'fixed-first' ('fixed', "
      "'flips' only when the fixed metric cannot be delivered); 'target_metric_requested', 'target_metric', "
      "'target_metric_choice', 'target_flips', 'target_refinement_splits' in the result; when no allowed metric can "
      "be delivered, surfmap.UniformizationError (a SolveError). `homotopy_images`: (#V_source, 3) "
      "a point on the target per source vertex (genus >= 2): the class of the source's loops carried there is the only "
      "candidate (no ranking, search or two-way run; SolveError when they do not carry). As the CLI's map flags "
      "(docs/python.md): `cheap_direction_check` (False: --no-cheap-direction-check), `compare_directions` "
      "(--compare-directions), `greedy_pants` (False: --no-greedy-pants), `homotopy_extra_cuts`, `own_weights_floor`, "
      "`local_fold_repair` (False: --no-local-fold-repair), `fold_untangle` (False: --no-fold-untangle), `snapped_start` (False: --no-snapped-start), `short_canonical_generators` (default False; True: --short-canonical-generators: genus >= 2 canonical generators whose cut-and-paste moves conjugate only the new pair; --classical-canonical-generators is the default; report 'canonical_generators'), `both_canonical_bases` (default True: the candidate classes listed in both canonical bases, --both-canonical-bases; False: --one-canonical-basis, the run's basis only), `geometric_layout_basis` (--geometric-layout-basis: genus >= 2, the geometric classes read the target's lengths in its layout's short canonical basis), `short_curve_twists` (--short-curve-twists: genus >= 2, the class search also moves by Dehn twists along each surface's short marking and short pants curves), `high_kicks` (default 8; --high-kicks N, 0: none): genus >= 2, when the class search ends at 2x the conformal bound or more, this many kicks of three random twists, each followed by a short descent, from its best class (report homotopy.search 'high_kicks_status', 'kicks', 'lower_kicks'), `short_generators_fallback` (default True; False: --no-short-generators-fallback: genus >= 2, a run with the classical canonical generators that fails at its start edges is not made again with the short ones; report 'canonical_generators_fallback'), `fold_fallback` (default True; False: --no-fold-fallback: genus >= 2, a default-class run with the classical canonical generators in which every class folds is not made once more with the short ones, one way; report 'fold_fallback'), `class_words` (--class-words: genus >= 2, the class named by its words, 2g lists of letters as the report's homotopy.chosen_words or a candidate's words from an earlier run of the same pair and loop options; solved alone like `homotopy`, whose index names a class only within one run's list), `through_shape` (False: --no-through-shape: no class through a generated n-hole torus of the same genus when the energy stays at 3x the conformal bound or more), `through_shape_ratio` (default 3; --through-shape-ratio R: the energy ratio from which that step runs, here or, read the same way, in the other direction's run; it adopts a class only when its pair of inverse classes has the lower total), `landmarks_may_fold` (--landmarks-may-fold: the landmarks held by plain pins, the map returned where it folds, for its class), `target_loops` ('auto', 'embedding', 'metric'), `face_charts` ('auto', 'always', 'never'; --face-charts: genus >= 2 in per-face charts of the target when one chart cannot hold it, the snapped class only); `two_way_ratio` (no CLI flag; default 2): the other direction "
      "is mapped when the energy is at least this many times the conformal bound (0: always); `agreement_ratio` "
      "(--agreement-ratio; default 1.1): below `two_way_ratio`, from this ratio on the other direction is mapped too "
      "and the pair of inverse classes of lower total energy kept, so both directions agree (result "
      "quality.directions.agreement; two_way_ratio or more: off). Open pairs through "
      "the doubles: `refine_rings` (default 4; --refine-rings), `refine_levels` (default 2, 0: off; --refine-levels): "
      "where folds are left, the class solved again on doubles refined that many times within that many rings of "
      "the boundary (report open.refined_near_boundary); `reflection_solve` (default True; False: "
      "--no-reflection-solve): the half solved alone, its mirror given by the reflections (report "
      "open.reflection_solve; docs/open_surfaces.md \"The half's solve\"). "
      "`progress(stage, fraction)` "
      "may return False to cancel (raises surfmap.Cancelled). The GIL is released during the solve.";
  def_with_map_arguments(m, "surface_map", [](MapCall& c) { return surface_map_now(c); }, surface_map_doc);
  def_with_map_arguments<int>(
      m, "start_surface_map", [](MapCall& c, int niceness) { return start_map_job(c, niceness); },
      "start_surface_map(source_V, source_F, target_V, target_F, ..., niceness=10): surface_map for a closed pair, "
      "started on a thread of its own that never takes the GIL; returns a surfmap.MapJob at once (poll its "
      "progress(), done(); cancel(); result() gives surface_map's dict or raises its error). The same keywords and "
      "defaults as surface_map, but no `progress` / `solve_progress` callbacks (InputError: they would run Python on "
      "the solve's thread) and no open pairs (InputError: their driver runs Python). The arguments are converted on "
      "the calling thread (their errors raised here); the mesh intake and the solve run on the job's thread, which "
      "lowers its priority by `niceness` (Linux: nice steps, up to 19; the core's threads inherit it; 0: unchanged; "
      "a no-op elsewhere). docs/python.md \"start_surface_map and MapJob\".",
      py::arg("niceness") = 10);
  m.def(
      "slide_ear_images",
      [](py::handle V, py::handle F, py::handle Vo, py::handle Fo, py::handle face, py::handle barycentric,
         bool reversing, std::vector<int> held, int max_half_window, double window_max_dilatation) {
        TriMesh mesh{to_vertices(V, "V"), to_triangles(F, "F")}, other{to_vertices(Vo, "other V"), to_triangles(Fo, "other F")};
        const OpenSurfaceTopology mt = open_surface_topology(mesh), ot = open_surface_topology(other);
        auto faces = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(face);
        const RowMatrixX3d bary = to_vertices(barycentric, "barycentric");
        if (!faces || faces.ndim() != 1 || faces.shape(0) != mesh.num_vertices() || bary.rows() != mesh.num_vertices())
          throw InputError("slide_ear_images: 'face' and 'barycentric' need one row per vertex of the mesh");
        std::vector<PointOnSurface> images(mesh.num_vertices());
        for (int i = 0; i < mesh.num_vertices(); ++i) {
          const long long f = faces.data()[i];
          if (f < 0 || f >= other.num_faces())
            throw InputError("slide_ear_images: vertex " + std::to_string(i) + " has face " + std::to_string(f) +
                             ", out of range");
          images[i].face = static_cast<int>(f);
          images[i].barycentric = bary.row(i).transpose();
          images[i].position = bary(i, 0) * other.V.row(other.F(f, 0)).transpose() +
                               bary(i, 1) * other.V.row(other.F(f, 1)).transpose() +
                               bary(i, 2) * other.V.row(other.F(f, 2)).transpose();
        }
        EarImagesOptions options;
        options.reversing = reversing;
        options.held = std::move(held);
        options.max_half_window = max_half_window;
        options.window_max_dilatation = window_max_dilatation;
        const EarImagesResult r = slide_ear_images(mesh, mt, other, ot, images, options);
        py::dict d = points_to_dict(images);
        d["ears"] = r.ears;
        d["turned"] = r.turned;
        d["moved"] = r.moved;
        d["moved_with_neighbours"] = r.moved_with_neighbours;
        d["turned_after"] = r.turned_after;
        return d;
      },
      py::arg("V"), py::arg("F"), py::arg("other_V"), py::arg("other_F"), py::arg("face"), py::arg("barycentric"),
      py::arg("reversing") = false, py::arg("held") = std::vector<int>{}, py::arg("max_half_window") = 2,
      py::arg("window_max_dilatation") = 10.0,
      "Ears (faces with three boundary corners) of the open mesh (V, F) whose images on the open mesh (other_V, "
      "other_F) turn over: the middle corner's image slid along the other boundary between its neighbours' images, "
      "to the vertex where the ear's image is least distorted among the positively oriented ones; when none rights "
      "it, windows of 3 .. 2 max_half_window + 1 boundary vertices around it slid together, where the largest D' of "
      "their faces stays below window_max_dilatation (map/ear_images.h; "
      "docs/open_surfaces.md 'Ears'). face, barycentric: per vertex its image on the other mesh; held: vertices "
      "whose images stay (landmarks). Returns {face, barycentric, position, ears, turned, moved, "
      "moved_with_neighbours, turned_after}.");
}

}  // namespace surfmap::python
