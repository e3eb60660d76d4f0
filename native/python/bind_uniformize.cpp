// Python bindings of the uniformization layer: uniformize (one call),
// ricci_flow, and the Poincaré-disk helpers used by tests and the add-on.
#include <pybind11/complex.h>

#include <optional>

#include "bindings.h"
#include "convert.h"
#include "surfmap/error.h"
#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/hyperbolic_harmonic.h"
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

/// (k, 4) rows [a.re, a.im, b.re, b.im] as Möbius maps (normalised).
std::vector<hyperbolic::Mobius> to_mobius_list(const py::handle& obj, py::ssize_t k, const char* name) {
  auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a || a.size() != 4 * k) throw InputError(std::string(name) + " must be " + std::to_string(k) + " rows of 4 floats");
  std::vector<hyperbolic::Mobius> out(k);
  for (py::ssize_t e = 0; e < k; ++e) out[e] = to_mobius(py::array_t<double>(4, a.data() + 4 * e));
  return out;
}

/// hyperbolic_harmonic_map's input from Python arrays (the binding below).
HyperbolicHarmonicResult harmonic_map_from_arrays(py::handle edges_h, py::handle weights_h, py::handle rho_h,
                                                  py::handle z0_h, py::handle slides_h, py::handle geodesics_h,
                                                  py::handle ordered_h, py::handle pulls_h, double tolerance,
                                                  int max_iterations) {
  auto ij = py::array_t<int, py::array::c_style | py::array::forcecast>::ensure(edges_h);
  auto w = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(weights_h);
  if (!ij || ij.ndim() != 2 || ij.shape(1) != 2) throw InputError("edges must be a (k, 2) integer array");
  const py::ssize_t k = ij.shape(0);
  if (!w || w.size() != k) throw InputError("weights must have one entry per edge");
  const auto rho = to_mobius_list(rho_h, k, "rho");
  const auto z = to_complex(z0_h, "z0");
  std::vector<WeightedEdge> edges(k);
  for (py::ssize_t e = 0; e < k; ++e)
    edges[e].i = ij.data()[2 * e], edges[e].j = ij.data()[2 * e + 1], edges[e].w = w.data()[e], edges[e].rho = rho[e];
  HyperbolicHarmonicOptions options;
  options.tolerance = tolerance;
  options.max_iterations = max_iterations;
  if (!slides_h.is_none()) {
    auto sl = py::array_t<bool, py::array::c_style | py::array::forcecast>::ensure(slides_h);
    if (!sl || sl.size() != z.size()) throw InputError("slides must have one entry per vertex");
    options.boundary_slide.slides.assign(sl.data(), sl.data() + sl.size());
    options.boundary_slide.geodesic = to_mobius_list(geodesics_h, z.size(), "geodesics");
    if (!ordered_h.is_none()) {
      auto o = py::array_t<int, py::array::c_style | py::array::forcecast>::ensure(ordered_h);
      if (!o) throw InputError("ordered_edges must be an integer array");
      options.boundary_slide.ordered_edges.assign(o.data(), o.data() + o.size());
    }
  }
  if (!pulls_h.is_none()) {
    const auto pulls = pulls_h.cast<py::tuple>();
    if (pulls.size() != 3) throw InputError("pulls must be (vertices, weights, geodesics)");
    auto v = py::array_t<int, py::array::c_style | py::array::forcecast>::ensure(pulls[0]);
    auto pw = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(pulls[1]);
    if (!v || !pw || v.size() != pw.size()) throw InputError("pulls: one weight per vertex");
    const auto G = to_mobius_list(pulls[2], v.size(), "pull geodesics");
    for (py::ssize_t k = 0; k < v.size(); ++k) options.boundary_slide.pulls.push_back({v.data()[k], pw.data()[k], G[k]});
  }
  const int n = static_cast<int>(z.size());
  std::vector<Complex> z0(z.data(), z.data() + n);
  py::gil_scoped_release release;
  return hyperbolic_harmonic_map(n, edges, {}, std::move(z0), options);
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
         int base_vertex, py::object progress, double floor_tolerance, const std::string& metric, const std::string& loop_metric,
         bool refine) {
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
        // The altitude-foot refinement of the fixed-connectivity path is opt-in, as in the CLI.
        opt.fixed_connectivity_refinement = refine;
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
      py::arg("refine") = false,
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
      "says). refine: with metric 'fixed', refine the mesh exactly (altitude-foot splits) when the metric does not exist ('refinement_splits' counts them; the CLI's --refine). The GIL is released during the solve.");

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
      "hyperbolic_harmonic_map",
      [](py::handle edges, py::handle weights, py::handle rho, py::handle z0, py::handle slides, py::handle geodesics,
         py::handle ordered_edges, py::handle pulls, double tolerance, int max_iterations) {
        const HyperbolicHarmonicResult r = harmonic_map_from_arrays(edges, weights, rho, z0, slides, geodesics,
                                                                    ordered_edges, pulls, tolerance, max_iterations);
        return py::dict(py::arg("z") = complex_array(r.z), py::arg("energy") = r.energy,
                        py::arg("converged") = r.converged, py::arg("iterations") = r.iterations,
                        py::arg("energy_history") = r.energy_history, py::arg("gradient_history") = r.gradient_history,
                        py::arg("edge_local") = mobius_array(r.edge_local), py::arg("factorizations") = r.factorizations,
                        py::arg("slide_off_geodesic") = r.slide_off_geodesic,
                        py::arg("order_rejections") = r.order_rejections);
      },
      py::arg("edges"), py::arg("weights"), py::arg("rho"), py::arg("z0"), py::arg("slides") = py::none(),
      py::arg("geodesics") = py::none(), py::arg("ordered_edges") = py::none(), py::arg("pulls") = py::none(),
      py::arg("tolerance") = 1e-10,
      py::arg("max_iterations") = 300,
      "The core's hyperbolic harmonic map (map/hyperbolic_harmonic.h) on a simply connected chart: edges (k, 2) "
      "i -> j with weights (k) and elements rho (k, 4) (the image of edge i->j runs from z_i to rho(z_j)), start "
      "points z0 (n complex). slides (n bool) with geodesics (n, 4): vertices that slide along G(real diameter) "
      "(BoundarySlideOptions); ordered_edges: edges between sliding vertices whose order along the geodesic is "
      "kept; pulls (vertices, weights, geodesics (p, 4)): terms w d(z_v, G(diameter))^2. Returns 'z', 'energy', 'converged', 'iterations', the histories, 'edge_local' (k, 4: each edge in "
      "its ends' charts), 'factorizations', 'slide_off_geodesic', 'order_rejections'.");
  m.def(
      "intrinsic_delaunay",
      [](py::handle V, py::handle F, py::handle keep_h) {
        const RowMatrixX3d Vm = to_vertices(V);
        const Connectivity conn(to_triangles(F), static_cast<int>(Vm.rows()));
        Eigen::VectorXd lengths(conn.num_edges());
        for (int e = 0; e < conn.num_edges(); ++e)
          lengths[e] = (Vm.row(conn.edge_vertex(e, 0)) - Vm.row(conn.edge_vertex(e, 1))).norm();
        IntrinsicDelaunayOptions options;
        if (!keep_h.is_none()) {
          auto keep = py::array_t<int, py::array::c_style | py::array::forcecast>::ensure(keep_h);
          if (!keep || keep.size() % 2) throw InputError("keep must be (p, 2) vertex pairs");
          options.keep.assign(conn.num_edges(), 0);
          for (py::ssize_t k = 0; k < keep.size() / 2; ++k) {
            const int h = conn.find_halfedge(keep.data()[2 * k], keep.data()[2 * k + 1]);
            if (h < 0) throw InputError("keep: pair " + std::to_string(k) + " is not an edge");
            options.keep[conn.edge(h)] = 1;
          }
        }
        const IntrinsicDelaunayResult r = intrinsic_delaunay(conn, lengths, options);
        const py::ssize_t k = static_cast<py::ssize_t>(r.edges.size());
        py::array_t<int> ij({k, py::ssize_t{2}});
        py::array_t<double> w(k);
        std::vector<int> offsets{0}, path;
        for (py::ssize_t e = 0; e < k; ++e) {
          const IntrinsicEdge& ie = r.edges[e];
          ij.mutable_data()[2 * e] = ie.i, ij.mutable_data()[2 * e + 1] = ie.j, w.mutable_data()[e] = ie.cot_weight;
          for (int h : ie.path) path.push_back(conn.tail(h));
          path.push_back(ie.j);
          offsets.push_back(static_cast<int>(path.size()));
        }
        return py::dict(py::arg("edges") = ij, py::arg("weights") = w, py::arg("path_offsets") = to_numpy(offsets),
                        py::arg("path_vertices") = to_numpy(path), py::arg("flips") = r.flips,
                        py::arg("delaunay") = r.delaunay);
      },
      py::arg("V"), py::arg("F"), py::arg("keep") = py::none(),
      "The intrinsic Delaunay triangulation (geometry/intrinsic_delaunay.h) of a closed mesh's 3D edge lengths, "
      "edges in `keep` ((p, 2) vertex pairs) never flipped. Returns 'edges' (k, 2) i -> j, 'weights' (k, "
      "cotangent), each edge's path of original vertices from i to j (path_vertices[path_offsets[e]:"
      "path_offsets[e + 1]]), 'flips', 'delaunay'.");
  m.def(
      "mobius_compose",
      [](py::handle a, py::handle b) {
        return mobius_array({(to_mobius(a) * to_mobius(b)).normalized()});
      },
      py::arg("m1"), py::arg("m2"), "m1 ∘ m2 (apply m2 first) as a (1, 4) array.");
}

}  // namespace surfmap::python
