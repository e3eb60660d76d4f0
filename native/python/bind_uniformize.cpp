// Python bindings of the uniformization layer: uniformize (one call),
// ricci_flow, and the Poincaré-disk helpers used by tests and the add-on.
#include <pybind11/complex.h>

#include <optional>

#include "bindings.h"
#include "convert.h"
#include "surfmap/error.h"
#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/map/map_option_names.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/uniformize/uniformize.h"

namespace surfmap::python {
namespace {

RicciScheme parse_scheme(const std::string& s) {
  if (s == "yamabe" || s == "vertex_scaling") return RicciScheme::VertexScaling;
  if (s == "inversive" || s == "inversive_distance") return RicciScheme::InversiveDistance;
  throw InputError("scheme must be 'yamabe' or 'inversive', not '" + s + "'");
}

RicciMethod parse_method(const std::string& s) {
  if (s == "newton") return RicciMethod::Newton;
  if (s == "flow") return RicciMethod::GradientFlow;
  throw InputError("method must be 'newton' or 'flow', not '" + s + "'");
}

py::array_t<Complex> complex_array(const std::vector<Complex>& v) {
  py::array_t<Complex> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

py::array_t<double> eigen_vector(const Eigen::VectorXd& v) {
  py::array_t<double> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.data(), v.data() + v.size(), a.mutable_data());
  return a;
}

/// Möbius maps as an (n, 4) float array [a.re, a.im, b.re, b.im].
py::array_t<double> mobius_array(const std::vector<hyperbolic::Mobius>& ms) {
  py::array_t<double> a({static_cast<py::ssize_t>(ms.size()), py::ssize_t{4}});
  double* p = a.mutable_data();
  for (const auto& m : ms) *p++ = m.a.real(), *p++ = m.a.imag(), *p++ = m.b.real(), *p++ = m.b.imag();
  return a;
}

hyperbolic::Mobius to_mobius(const py::handle& obj) {
  auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a || a.size() != 4) throw InputError("a Mobius map is 4 floats [a.re, a.im, b.re, b.im]");
  const double* p = a.data();
  const hyperbolic::Mobius m{Complex(p[0], p[1]), Complex(p[2], p[3])};
  if (!(m.determinant() > 0)) throw InputError("a Mobius map of the disk needs |a|^2 - |b|^2 > 0");
  return m.normalized();
}

py::array_t<Complex> to_complex(const py::handle& obj, const char* name) {
  auto a = py::array_t<Complex, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a) throw InputError(std::string(name) + " must be an array of complex numbers");
  return a;
}

/// Wraps a Python progress(iteration, residual) callback; the GIL is taken
/// only inside the call. A Python exception stops the solve and is re-raised.
struct Progress {
  py::object callback;
  std::optional<py::error_already_set> error;
  std::function<bool(int, double)> make() {
    if (callback.is_none()) return {};
    return [this](int it, double residual) {
      py::gil_scoped_acquire gil;
      try {
        const py::object r = callback(it, residual);
        return r.is_none() || r.cast<bool>();
      } catch (py::error_already_set& e) {
        error.emplace(std::move(e));
        return false;
      }
    };
  }
};

py::dict layout_dict(const DiskLayout& L) {
  py::dict d;
  const int nF = static_cast<int>(L.corners.rows());
  py::array_t<Complex> corners({static_cast<py::ssize_t>(nF), py::ssize_t{3}});
  std::copy(L.corners.data(), L.corners.data() + L.corners.size(), corners.mutable_data());
  d["corners"] = corners;
  d["disk_positions"] = complex_array(L.disk_positions);
  d["disk_F"] = to_numpy(L.disk_faces);
  d["disk_vertex_origin"] = to_numpy(L.disk_vertex_origin);
  d["vertex_positions"] = complex_array(L.vertex_positions);
  d["vertex_copies"] = to_numpy(L.vertex_copies);
  std::vector<int> cut;
  for (size_t e = 0; e < L.cut_edge.size(); ++e)
    if (L.cut_edge[e]) cut.push_back(static_cast<int>(e));
  d["cut_edges"] = to_numpy(cut);
  d["word"] = L.word;
  d["root_face"] = L.root_face;
  // The base corner c_0 (the word and the generators are read from it).
  const int h0 = L.boundary_halfedges.empty() ? -1 : L.boundary_halfedges[0];
  if (h0 >= 0) d["base_corner"] = L.corners(h0 / 3, h0 % 3);
  d["num_flipped"] = L.num_flipped;
  d["num_unresolved"] = L.num_unresolved;
  d["num_flipped_above_roundoff"] = L.num_flipped_above_roundoff;
  d["num_flipped_local"] = L.num_flipped_local;
  d["max_vertex_holonomy"] = L.max_vertex_holonomy;
  d["layout_radius"] = L.layout_radius;
  d["coordinate_roundoff"] = L.coordinate_roundoff;
  d["max_interior_mismatch"] = L.max_interior_mismatch;
  d["interior_roundoff"] = L.interior_roundoff;
  d["max_interior_excess"] = L.max_interior_excess;
  d["max_deck_inconsistency"] = L.max_deck_inconsistency;
  d["deck_roundoff"] = L.deck_roundoff;
  d["max_deck_excess"] = L.max_deck_excess;
  d["max_corner_inconsistency"] = L.max_corner_inconsistency;
  d["corner_condition"] = L.corner_condition;
  d["max_holonomy_rotation"] = L.max_holonomy_rotation;
  d["product_relation_error"] = L.product_relation_error;
  d["relation_condition"] = L.relation_condition;
  d["area"] = L.area;
  d["time_s"] = L.time_s;
  if (L.background == Background::Hyperbolic) {
    d["generators"] = mobius_array(L.generators);
    d["side_pairings"] = mobius_array(L.side_pairings);
  } else {
    d["generator_translations"] = complex_array(L.generator_translations);
    d["side_translations"] = complex_array(L.side_translations);
  }
  return d;
}

}  // namespace

// Long on purpose: one m.def per uniformization function with its keyword
// list and docstring, read like a table of the module's entry points.
void bind_uniformize(py::module_& m) {
  m.def(
      "uniformize",
      [](py::handle Vh, py::handle Fh, const std::string& scheme, const std::string& method, double tolerance,
         int base_vertex, py::object progress, double floor_tolerance, const std::string& metric, const std::string& loop_metric) {
        const RowMatrixX3d V = to_vertices(Vh, "V");
        const RowMatrixX3i F = to_triangles(Fh, "F");
        UniformizeOptions opt;
        opt.scheme = parse_scheme(scheme);
        opt.method = parse_method(method);
        opt.tolerance = tolerance;
        opt.floor_tolerance = floor_tolerance;
        opt.metric = parse_enum<UniformizationMetric>(metric, "metric");
        opt.loops = parse_enum<LoopMetric>(loop_metric, "loops");
        opt.base_vertex = base_vertex;
        Progress p{progress, {}};
        opt.progress = p.make();
        UniformizeResult r;
        IntakeResult in;
        try {
          py::gil_scoped_release release;
          in = intake(V, F);
          if (base_vertex >= in.mesh.num_vertices())
            throw InputError("base_vertex " + std::to_string(base_vertex) + " is out of range");
          r = uniformize(in.mesh, opt);
        } catch (const Cancelled&) {
          if (p.error) throw std::move(*p.error);
          throw;
        }
        py::dict d;
        d["genus"] = r.genus;
        d["kind"] = r.kind;
        d["converged"] = r.converged;
        d["iterations"] = r.iterations;
        d["max_curvature_error"] = r.max_curvature_error;
        d["stopped_at_floor"] = r.stopped_at_floor;
        d["residual_history"] = r.residual_history;
        d["area"] = r.area;
        d["time_s"] = r.time_s;
        d["flipped_on_input"] = in.flipped;
        d["F"] = to_numpy(in.mesh.F);
        if (r.genus == 0) {
          d["sphere_positions"] = to_numpy(r.sphere.positions);
          d["removed_vertex"] = r.sphere.removed_vertex;
          d["flipped_faces"] = r.sphere.flipped_faces;
          d["input_flipped_faces"] = r.sphere.input_flipped_faces;
          d["ring_flips"] = r.sphere.ring_flips;
          d["simplicial_flips"] = r.sphere.simplicial_flips;
          d["centre_of_mass_norm"] = r.sphere.centre_of_mass_norm;
          d["centring_floor"] = r.sphere.centring_floor;
          d["centring_iterations"] = r.sphere.centring_iterations;
          d["centring_stopped_at_floor"] = r.sphere.centring_stopped_at_floor;
          d["centring_axial_only"] = r.sphere.centring_axial_only;
          return d;
        }
        d["refined_V"] = to_numpy(r.loops.mesh.V);
        d["refined_F"] = to_numpy(r.loops.mesh.F);
        d["base_vertex"] = r.loops.base_vertex;
        py::list loops;
        for (const auto& l : r.loops.loops) loops.append(to_numpy(l));
        d["loops"] = loops;
        d["u"] = eigen_vector(r.ricci.u);
        d["edge_lengths"] = eigen_vector(r.edge_lengths);  // on refined_F's edges
        d["metric"] = r.metric;
        d["loop_metric"] = r.loop_metric;
        d["single_chart"] = r.single_chart;
        d["layout_checks"] = r.layout_checks;
        d["edge_flips"] = r.edge_flips;
        d["refinement_splits"] = r.refinement_splits;
        d["layout"] = layout_dict(r.layout);
        d["product_relation_error"] = r.product_relation_error;
        if (r.genus == 1) {
          d["tau"] = r.tau;
          d["tau_reduced"] = r.tau_reduced;
          d["sl2z"] = std::vector<int>(r.modulus.sl2z, r.modulus.sl2z + 4);
          d["lattice"] = std::vector<Complex>{r.modulus.omega1, r.modulus.omega2};
        } else {
          d["generators"] = mobius_array(r.generators);
        }
        return d;
      },
      py::arg("V"), py::arg("F"), py::arg("scheme") = "yamabe", py::arg("method") = "newton",
      py::arg("tolerance") = 1e-10, py::arg("base_vertex") = -1, py::arg("progress") = py::none(),
      py::arg("floor_tolerance") = 1e-7, py::arg("metric") = "flips", py::arg("loops") = "auto",
      "Uniformization of a closed mesh (V: (n,3) float, F: (m,3) int): genus 0 -> unit sphere "
      "('sphere_positions'), genus 1 -> flat torus ('tau', 'tau_reduced', 'lattice'), genus >= 2 -> "
      "hyperbolic ('generators' as (2g,4) [a.re,a.im,b.re,b.im] of z -> (az+b)/(conj(b)z+conj(a))). "
      "'layout' holds the cut disk (complex 'corners' per face of 'refined_F', 'disk_positions', 'disk_F'). "
      "progress(iteration, residual) may return False to cancel (raises surfmap.Cancelled). Raises "
      "surfmap.UniformizationError (a SolveError) if the metric does not converge or its layout is inconsistent (a "
      "residual above `tolerance` at the floating-point floor but within `floor_tolerance` is converged, "
      "'stopped_at_floor'). metric: 'flips' (default; Ptolemy flips, loops on the intrinsic triangulation; 'auto' is "
      "the same), 'fixed' (the input connectivity) or 'fixed-first' ('fixed', 'flips' when it fails; 'metric' in the "
      "result says). loops: 'auto' (default), 'embedding' or 'metric': the lengths the loops are shortest in "
      "(genus >= 2, flip path; 'auto': 3D, the metric's when that layout fails or crowds |z| = 1; 'loop_metric' "
      "says). The GIL is released during the solve.");

  m.def(
      "ricci_flow",
      [](py::handle Vh, py::handle Fh, const std::string& background, const std::string& scheme,
         const std::string& method, double tolerance, py::object progress) {
        const RowMatrixX3d V = to_vertices(Vh, "V");
        const RowMatrixX3i F = to_triangles(Fh, "F");
        Background bg;
        if (background == "euclidean" || background == "flat")
          bg = Background::Euclidean;
        else if (background == "hyperbolic")
          bg = Background::Hyperbolic;
        else
          throw InputError("background must be 'euclidean' or 'hyperbolic', not '" + background + "'");
        RicciFlowOptions opt;
        opt.scheme = parse_scheme(scheme);
        opt.method = parse_method(method);
        opt.tolerance = tolerance;
        Progress p{progress, {}};
        opt.progress = p.make();
        RicciFlowResult r;
        Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor> ev;
        try {
          py::gil_scoped_release release;
          TriMesh mesh{V, F};
          Connectivity conn(F, static_cast<int>(V.rows()));
          ev = conn.edge_vertices();
          r = ricci_flow(conn, edge_lengths(mesh, conn), bg, opt);
        } catch (const Cancelled&) {
          if (p.error) throw std::move(*p.error);
          throw;
        }
        py::dict d;
        d["converged"] = r.converged;
        d["iterations"] = r.iterations;
        d["max_curvature_error"] = r.max_curvature_error;
        d["stopped_at_floor"] = r.stopped_at_floor;
        d["residual_history"] = r.residual_history;
        d["u"] = eigen_vector(r.u);
        d["edge_lengths"] = eigen_vector(r.edge_lengths);
        py::array_t<int> e({static_cast<py::ssize_t>(ev.rows()), py::ssize_t{2}});
        std::copy(ev.data(), ev.data() + ev.size(), e.mutable_data());
        d["edge_vertices"] = e;
        d["time_s"] = r.time_s;
        d["message"] = r.message;
        return d;
      },
      py::arg("V"), py::arg("F"), py::arg("background") = "euclidean", py::arg("scheme") = "yamabe",
      py::arg("method") = "newton", py::arg("tolerance") = 1e-10, py::arg("progress") = py::none(),
      "Discrete Ricci flow to zero curvature on a flat ('euclidean') or hyperbolic background. Returns "
      "conformal factors 'u' (#V), final 'edge_lengths' (#E, in the order of 'edge_vertices') and "
      "'converged' (check it: a failed solve is reported, not raised).");

  m.def(
      "mobius_apply",
      [](py::handle mh, py::handle zh) {
        const hyperbolic::Mobius mob = to_mobius(mh);
        const auto z = to_complex(zh, "z");
        py::array_t<Complex> out(z.request().shape);
        for (py::ssize_t i = 0; i < z.size(); ++i) out.mutable_data()[i] = mob.apply(z.data()[i]);
        return out;
      },
      py::arg("m"), py::arg("z"),
      "Applies z -> (az+b)/(conj(b)z+conj(a)) with m = [a.re, a.im, b.re, b.im] to an array of complex z.");
  m.def(
      "hyperbolic_distance",
      [](py::handle zh, py::handle wh) {
        const auto z = to_complex(zh, "z"), w = to_complex(wh, "w");
        if (z.size() != w.size()) throw InputError("z and w must have the same number of points");
        py::array_t<double> out(z.request().shape);
        for (py::ssize_t i = 0; i < z.size(); ++i) {
          if (std::abs(z.data()[i]) >= 1 || std::abs(w.data()[i]) >= 1)
            throw InputError("point " + std::to_string(i) + " is not inside the unit disk");
          out.mutable_data()[i] = hyperbolic::distance(z.data()[i], w.data()[i]);
        }
        return out;
      },
      py::arg("z"), py::arg("w"), "Poincaré-disk distance between corresponding points of two complex arrays.");
  m.def(
      "mobius_compose",
      [](py::handle a, py::handle b) {
        return mobius_array({(to_mobius(a) * to_mobius(b)).normalized()});
      },
      py::arg("m1"), py::arg("m2"), "m1 ∘ m2 (apply m2 first) as a (1, 4) array.");
}

}  // namespace surfmap::python
