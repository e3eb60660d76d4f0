// surfmap._core.shapes: the procedural sample surfaces (samples/shapes.h),
// each returning (V float64 (n, 3), F int32 (m, 3)).
#include "bindings.h"
#include "convert.h"

#include "surfmap/samples/canonical_domain.h"
#include "surfmap/samples/shapes.h"

namespace surfmap::python {
namespace {

py::tuple out(const TriMesh& m) { return py::make_tuple(to_numpy(m.V), to_numpy(m.F)); }

TriMesh in(const py::handle& V, const py::handle& F) {
  TriMesh m;
  m.V = to_vertices(V);
  m.F = to_triangles(F);
  for (int t = 0; t < m.num_faces(); ++t)
    for (int k = 0; k < 3; ++k)
      if (m.F(t, k) < 0 || m.F(t, k) >= m.num_vertices())
        throw InputError("F: face " + std::to_string(t) + " has a vertex index out of range");
  return m;
}

}  // namespace

void bind_samples(py::module_& m) {
  auto s = m.def_submodule("shapes", "Procedural closed sample surfaces; each returns (V, F)");
  using py::arg;
  s.def("torus_of_revolution",
        [](double R, double r, int n_major, int n_minor, int variant) {
          return out(samples::torus_of_revolution(R, r, n_major, n_minor, variant));
        },
        arg("R"), arg("r"), arg("n_major"), arg("n_minor"), arg("connectivity_variant") = 0,
        "Torus of revolution (R > r), n_major x n_minor grid; variants re-triangulate the same surface.");
  s.def("n_hole_torus",
        [](int n, int resolution, bool smooth) {
          TriMesh t;
          {
            py::gil_scoped_release nogil;
            t = samples::n_hole_torus(n, resolution, smooth);
          }
          return out(t);
        },
        arg("n"), arg("resolution") = 64, arg("smooth") = true,
        "Smooth genus-n surface (n = 1..8) by marching tetrahedra; smooth=False keeps the slivers.");
  auto implicit = [&](const char* name, TriMesh (*fn)(int, bool), const char* doc) {
    s.def(name,
          [fn](int resolution, bool smooth) {
            TriMesh t;
            {
              py::gil_scoped_release nogil;
              t = fn(resolution, smooth);
            }
            return out(t);
          },
          arg("resolution") = 64, arg("smooth") = true, doc);
  };
  implicit("vase", &samples::vase, "Vase with two handles (genus 2).");
  implicit("amphora", &samples::amphora, "Amphora with two handles (genus 2).");
  implicit("peanut", &samples::peanut, "Genus-0 peanut (two blended spheres).");
  s.def("cad_plate",
        [](int holes, int segments, double thickness) { return out(samples::cad_plate(holes, segments, thickness)); },
        arg("holes") = 2, arg("segments") = 64, arg("thickness") = 0.1,
        "CAD-like plate/block with round holes (genus = holes), long fans of thin triangles.");
  s.def("insert_degenerate_faces",
        [](py::handle V, py::handle F, int count, double t, unsigned seed) {
          return out(samples::insert_degenerate_faces(in(V, F), count, t, seed));
        },
        arg("V"), arg("F"), arg("count"), arg("t") = 0.5, arg("seed") = 0,
        "Adds `count` exactly zero-area faces (t=0: coincident vertices, 0<t<1: collinear).");
  s.def("cup",
        [](int handles, int resolution, bool smooth) {
          TriMesh t;
          {
            py::gil_scoped_release nogil;
            t = samples::cup(handles, resolution, smooth);
          }
          return out(t);
        },
        arg("handles") = 1, arg("resolution") = 64, arg("smooth") = true, "Cup with `handles` handles (genus = handles).");
  s.def("polycube",
        [](int holes, int resolution, bool smooth) {
          TriMesh t;
          {
            py::gil_scoped_release nogil;
            t = samples::polycube(holes, resolution, smooth);
          }
          return out(t);
        },
        arg("holes") = 3, arg("resolution") = 64, arg("smooth") = true,
        "Rounded block with `holes` square through-holes (genus = holes).");
  s.def("jitter",
        [](const py::handle& V, const py::handle& F, double amplitude, unsigned seed) {
          return out(samples::jitter(in(V, F), amplitude, seed));
        },
        arg("V"), arg("F"), arg("amplitude"), arg("seed") = 0,
        "Random tangential vertex offsets of amplitude x local mean edge length, no flips.");
  s.def("sphere_inversion",
        [](const py::handle& V, const py::handle& F, const Eigen::Vector3d& c, double rho) {
          return out(samples::sphere_inversion(in(V, F), c, rho));
        },
        arg("V"), arg("F"), arg("c"), arg("rho"), "Conformal copy by inversion in the sphere (c, rho), outward.");
  s.def("canonical_domain",
        [](int genus, const std::string& kind, const std::string& layout, int resolution, bool unit_area) {
          samples::CanonicalDomainOptions o;
          o.genus = genus;
          if (kind == "n-torus") o.kind = samples::DomainKind::NTorus;
          else if (kind == "polycube") o.kind = samples::DomainKind::Polycube;
          else throw InputError("kind must be 'n-torus' or 'polycube', not '" + kind + "'");
          if (layout == "row") o.layout = samples::DomainLayout::Row;
          else if (layout == "ring") o.layout = samples::DomainLayout::Ring;
          else throw InputError("layout must be 'row' or 'ring', not '" + layout + "'");
          o.resolution = resolution;
          o.unit_area = unit_area;
          samples::CanonicalDomainResult d;
          {
            py::gil_scoped_release nogil;
            d = samples::canonical_domain(o);
          }
          py::dict quality(py::arg("description") = d.description, py::arg("genus") = d.genus,
                           py::arg("area") = d.area, py::arg("signed_volume") = d.signed_volume,
                           py::arg("min_angle_deg") = d.min_angle_deg,
                           py::arg("mean_min_angle_deg") = d.mean_min_angle_deg,
                           py::arg("fraction_below_20_deg") = d.fraction_below_20_deg);
          return py::make_tuple(to_numpy(d.mesh.V), to_numpy(d.mesh.F), quality);
        },
        arg("genus"), arg("kind") = "n-torus", arg("layout") = "row", arg("resolution") = 24,
        arg("unit_area") = true,
        "Canonical genus-g domain (samples/canonical_domain.h): (V, F, quality dict).");
  s.def("sphere", [](int subdivisions) { return out(samples::sphere(subdivisions)); }, arg("subdivisions") = 3,
        "Subdivided icosahedron on the unit sphere (genus 0).");
  s.def("spherical_cap", [](int rings, double bump) { return out(samples::spherical_cap(rings, bump)); },
        arg("rings"), arg("bump") = 0.0,
        "Open disk: the hemisphere z >= 0 as a polar grid (centre vertex, `rings` rings of 6 x rings vertices); "
        "`bump` adds the asymmetric bulge z += bump x z.");
}

}  // namespace surfmap::python
