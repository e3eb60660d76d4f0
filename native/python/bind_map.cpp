// Map layer bindings: the globally optimal surface map (paper §III–VII).
#include <cstdint>
#include <optional>

#include "bindings.h"
#include "convert.h"
#include "surfmap/error.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/intake.h"

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

}  // namespace

void bind_map(py::module_& m) {
  // What this build's surface_map accepts beyond the meshes, by keyword
  // argument name, for callers that must work with older builds (the
  // add-on): read this set instead of searching docstrings.
  m.attr("CAPABILITIES") = py::frozenset(py::make_tuple(
      "homotopy", "landmarks", "method", "tolerance", "max_iterations", "solve_progress", "homotopy_candidates",
      "homotopy_full_solves", "initial_map", "source_weights", "homotopy_search", "homotopy_search_evaluations",
      "progress", "source_base_vertex", "target_base_vertex"));
  m.def(
      "surface_map",
      [](py::handle Vs, py::handle Fs, py::handle Vt, py::handle Ft, int homotopy, int source_base_vertex,
         int target_base_vertex, py::object progress, py::object landmarks, const std::string& method,
         double tolerance, int max_iterations, py::object solve_progress, int homotopy_candidates,
         int homotopy_full_solves, const std::string& initial_map, const std::string& source_weights,
         bool homotopy_search, int homotopy_search_evaluations) {
        const RowMatrixX3d vs = to_vertices(Vs, "source V"), vt = to_vertices(Vt, "target V");
        const RowMatrixX3i fs = to_triangles(Fs, "source F"), ft = to_triangles(Ft, "target F");
        SurfaceMapOptions opt;
        opt.homotopy = homotopy;
        opt.source_base_vertex = source_base_vertex;
        opt.target_base_vertex = target_base_vertex;
        if (method == "newton") opt.method = MapMethod::Newton;
        else if (method == "relaxation") opt.method = MapMethod::Relaxation;
        else throw InputError("method must be 'newton' or 'relaxation', not '" + method + "'");
        if (!(tolerance > 0)) throw InputError("tolerance must be positive");
        if (max_iterations < 1) throw InputError("max_iterations must be at least 1");
        opt.tolerance = tolerance;
        opt.max_iterations = max_iterations;
        if (homotopy_candidates < 1) throw InputError("homotopy_candidates must be at least 1");
        if (homotopy_full_solves < 1) throw InputError("homotopy_full_solves must be at least 1");
        opt.homotopy_candidates = homotopy_candidates;
        opt.homotopy_full_solves = homotopy_full_solves;
        if (homotopy_search_evaluations < 1) throw InputError("homotopy_search_evaluations must be at least 1");
        opt.homotopy_search = homotopy_search;
        opt.homotopy_search_evaluations = homotopy_search_evaluations;
        if (initial_map == "cut_graph") opt.initial_map = InitialMapMethod::CutGraph;
        else if (initial_map == "polygon") opt.initial_map = InitialMapMethod::Polygon;
        else if (initial_map == "uniform") opt.initial_map = InitialMapMethod::UniformHarmonic;
        else throw InputError("initial_map must be 'cut_graph', 'polygon' or 'uniform', not '" + initial_map + "'");
        if (source_weights == "auto") opt.source_weights = SourceWeights::Automatic;
        else if (source_weights == "intrinsic") opt.source_weights = SourceWeights::IntrinsicDelaunay;
        else if (source_weights == "own") opt.source_weights = SourceWeights::OwnEdges;
        else throw InputError("source_weights must be 'auto', 'intrinsic' or 'own', not '" + source_weights + "'");
        if (!landmarks.is_none()) {
          const auto pairs = py::cast<std::vector<std::vector<long long>>>(
              py::module_::import("numpy").attr("asarray")(landmarks, "int64").attr("reshape")(-1, 2).attr("tolist")());
          for (const auto& p : pairs) {
            if (p[0] < 0 || p[1] < 0 || p[0] > INT32_MAX || p[1] > INT32_MAX)
              throw InputError("landmark (" + std::to_string(p[0]) + ", " + std::to_string(p[1]) + ") has a negative or too large index");
            opt.landmarks.emplace_back(static_cast<int>(p[0]), static_cast<int>(p[1]));
          }
        }
        // The callback runs on this thread with the GIL re-acquired; a Python
        // exception inside it stops the solve and is re-raised as is.
        std::optional<py::error_already_set> callback_error;
        if (!progress.is_none())
          opt.progress = [&](const std::string& stage, double fraction) {
            py::gil_scoped_acquire gil;
            try {
              const py::object r = progress(stage, fraction);
              return r.is_none() || r.cast<bool>();
            } catch (py::error_already_set& e) {
              callback_error.emplace(std::move(e));
              return false;
            }
          };
        if (!solve_progress.is_none())
          opt.solve_progress = [&](int iteration, double energy, double gradient) {
            py::gil_scoped_acquire gil;
            try {
              const py::object r = solve_progress(iteration, energy, gradient);
              return r.is_none() || r.cast<bool>();
            } catch (py::error_already_set& e) {
              callback_error.emplace(std::move(e));
              return false;
            }
          };
        SurfaceMapResult r;
        IntakeResult src, dst;
        try {
          py::gil_scoped_release release;
          try {
            src = intake(vs, fs);
          } catch (const InputError& e) {
            throw InputError(std::string("source: ") + e.what());
          }
          try {
            dst = intake(vt, ft);
          } catch (const InputError& e) {
            throw InputError(std::string("target: ") + e.what());
          }
          check_same_genus(src.info, dst.info);
          r = surface_map(src.mesh, dst.mesh, opt);
        } catch (const Cancelled&) {
          if (callback_error) throw std::move(*callback_error);
          throw;
        }
        py::dict d;
        d["genus"] = r.genus;
        d["converged"] = r.converged;
        d["iterations"] = r.iterations;
        d["energy"] = py::dict(py::arg("initial") = r.initial_energy, py::arg("final") = r.final_energy,
                               py::arg("history") = r.energy_history);
        d["distortion"] = py::dict(py::arg("mean") = r.mean_dilatation, py::arg("max") = r.max_dilatation,
                                   py::arg("per_face") = to_numpy(r.dilatation));
        d["initial_distortion"] =
            py::dict(py::arg("mean") = r.initial_mean_dilatation, py::arg("max") = r.initial_max_dilatation,
                     py::arg("per_face") = to_numpy(r.initial_dilatation));
        d["flipped_triangles"] = r.flipped_triangles;
        d["degenerate_triangles"] = r.degenerate_triangles;
        d["initial_flipped_triangles"] = r.initial_flipped_triangles;
        d["intrinsic_flipped_triangles"] = r.intrinsic_flipped_triangles;
        d["target_refinement_splits"] = r.target_refinement_splits;
        d["source_weights"] = r.source_weights;
        d["landmark_error"] = r.max_landmark_error;
        d["landmark_rings"] = r.landmark_rings;
        d["landmark_method"] = r.landmark_method;
        d["landmark_solves"] = r.landmark_solves;
        d["landmark_steps"] = r.landmark_steps;
        d["landmark_held_vertices"] = r.landmark_held_vertices;
        d["repaired_vertices"] = r.repaired_vertices;
        d["forward"] = points_to_dict(r.forward);
        d["inverse"] = points_to_dict(r.inverse);
        const InitialMapInfo& im = r.initial_map;
        d["initial_map"] = py::dict(
            py::arg("construction") = im.construction,
            py::arg("cut_graph") = py::dict(py::arg("status") = im.cut_graph_status,
                                            py::arg("branch_vertices") = im.cut_graph_branch_vertices,
                                            py::arg("sides") = im.cut_graph_sides,
                                            py::arg("chords_rerouted") = im.cut_graph_chords_rerouted,
                                            py::arg("min_turn") = im.cut_graph_min_turn,
                                            py::arg("flipped") = im.cut_graph_flipped,
                                            py::arg("degenerate") = im.cut_graph_degenerate,
                                            py::arg("time_s") = im.cut_graph_time_s),
            py::arg("polygon") = py::dict(py::arg("status") = im.polygon_status, py::arg("convex") = im.polygon_convex,
                                          py::arg("min_turn") = im.polygon_min_turn,
                                          py::arg("perimeter") = im.polygon_perimeter,
                                          py::arg("chords_split") = im.polygon_chords_split,
                                          py::arg("flipped") = im.polygon_flipped,
                                          py::arg("repaired_vertices") = im.polygon_repaired_vertices,
                                          py::arg("time_s") = im.polygon_time_s),
            py::arg("iterations") = im.iterations, py::arg("time_s") = im.time_s);
        // The initial map located on the target (None for genus 0 or when it
        // could not be located).
        d["initial_forward"] = r.initial_forward.empty() ? py::object(py::none()) : py::object(points_to_dict(r.initial_forward));
        d["initial_inverse"] = r.initial_inverse.empty() ? py::object(py::none()) : py::object(points_to_dict(r.initial_inverse));
        py::list cands;
        for (const auto& c : r.candidates)
          cands.append(py::dict(py::arg("description") = c.description, py::arg("energy") = c.energy, py::arg("solved") = c.solved,
                                py::arg("coarse_energy") = c.coarse_energy,
                                py::arg("landmark_energy") = c.landmark_energy,
                                py::arg("landmark_lower_bound") = c.landmark_lower_bound, py::arg("matrix") = std::vector<int>(c.matrix, c.matrix + 4)));
        const HomotopySearchInfo& hs = r.homotopy_search;
        py::dict search(py::arg("run") = hs.run, py::arg("start_candidate") = hs.start_candidate,
                        py::arg("start_energy") = hs.start_energy, py::arg("energy") = hs.energy,
                        py::arg("moves") = hs.moves, py::arg("energies") = hs.energies,
                        py::arg("evaluations") = hs.evaluations, py::arg("screened") = hs.screened,
                        py::arg("evaluated") = py::dict(py::arg("move") = hs.evaluated_moves, py::arg("step") = hs.evaluated_step,
                                                        py::arg("screen") = hs.evaluated_screen,
                                                        py::arg("energy") = hs.evaluated_energy),
                        py::arg("stop_reason") = hs.stop_reason, py::arg("time_s") = hs.time_s,
                        py::arg("found_candidate") = hs.found_candidate, py::arg("cut_classes") = hs.cut_classes,
                        py::arg("cuts_time_s") = hs.cuts_time_s);
        d["homotopy"] = py::dict(py::arg("chosen") = r.chosen_candidate, py::arg("candidates") = cands,
                                 py::arg("search") = search);
        py::dict times;
        for (const auto& [stage, s] : r.stage_times) times[py::str(stage)] = s;
        times["total"] = r.total_time;
        d["time_s"] = times;
        d["source_flipped"] = src.flipped;
        d["target_flipped"] = dst.flipped;
        return d;
      },
      py::arg("source_V"), py::arg("source_F"), py::arg("target_V"), py::arg("target_F"), py::arg("homotopy") = -1,
      py::arg("source_base_vertex") = -1, py::arg("target_base_vertex") = -1, py::arg("progress") = py::none(),
      py::arg("landmarks") = py::none(), py::arg("method") = "newton", py::arg("tolerance") = 1e-10,
      py::arg("max_iterations") = 300, py::arg("solve_progress") = py::none(), py::arg("homotopy_candidates") = 8,
      py::arg("homotopy_full_solves") = 2, py::arg("initial_map") = "cut_graph", py::arg("source_weights") = "auto",
      py::arg("homotopy_search") = true, py::arg("homotopy_search_evaluations") = 24,
      "Globally optimal map from the source onto the target (same genus; genus 0 through the sphere). Returns a dict "
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
      "('initial_map' in the result says which was used; 'initial_forward': the initial map located on the target, "
      "'initial_inverse': each target vertex located on the source through the initial map); `source_weights`: 'auto' "
      "(intrinsic Delaunay cotangents, the source's own edges when their images fold), 'intrinsic' or 'own' "
      "('source_weights' in the result says which were used). `progress(stage, fraction)` "
      "may return False to cancel (raises surfmap.Cancelled). The GIL is released during the solve.");
}

}  // namespace surfmap::python
