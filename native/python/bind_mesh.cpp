#include "bindings.h"
#include "convert.h"

#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/mesh_io.h"
#include "surfmap/mesh/open_surface.h"

namespace py = pybind11;

namespace surfmap::python {
namespace {

// Faces come as an (m, 3) integer array or as a sequence of polygons.
PolygonSoup to_soup(const py::handle& V, const py::handle& faces) {
  PolygonSoup soup;
  soup.V = to_vertices(V);
  if (py::isinstance<py::array>(faces) && py::array(py::reinterpret_borrow<py::object>(faces)).ndim() == 2) {
    auto a = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(faces);
    if (!a) throw InputError("faces must be integers");
    const auto rows = a.shape(0), cols = a.shape(1);
    soup.polygons.assign(rows, std::vector<int>(cols));
    for (py::ssize_t f = 0; f < rows; ++f)
      for (py::ssize_t k = 0; k < cols; ++k) {
        const long long v = a.at(f, k);
        soup.polygons[f][k] = (v < INT32_MIN || v > INT32_MAX) ? -1 : static_cast<int>(v);
      }
    return soup;
  }
  for (const auto& poly : faces) {
    std::vector<int> p;
    for (const auto& idx : poly) p.push_back(py::cast<int>(idx));
    soup.polygons.push_back(std::move(p));
  }
  return soup;
}

py::dict info_to_dict(const MeshInfo& i) {
  py::dict d;
  d["num_vertices"] = i.num_vertices;
  d["num_edges"] = i.num_edges;
  d["num_faces"] = i.num_faces;
  d["num_components"] = i.num_components;
  d["num_boundary_loops"] = i.num_boundary_loops;
  d["euler_characteristic"] = i.euler_characteristic;
  d["genus"] = i.genus;
  d["valid"] = i.valid;
  d["problems"] = i.problems;
  d["notes"] = i.notes;
  d["signed_volume"] = i.signed_volume;
  d["mollified_faces"] = i.mollified_faces;
  d["mollify_epsilon"] = i.mollify_epsilon;
  d["zero_area_faces"] = i.zero_area_faces;
  return d;
}

py::dict intake_to_dict(const IntakeResult& r) {
  py::dict d;
  d["V"] = to_numpy(r.mesh.V);
  d["F"] = to_numpy(r.mesh.F);
  d["info"] = info_to_dict(r.info);
  d["source_polygon"] = to_numpy(r.source_polygon);
  d["flipped"] = r.flipped;
  return d;
}

// intake(..., allow_boundary=True): closed meshes as intake(); open ones
// through intake_open (never flipped), with the genus of the open surface
// and its boundary loops (mesh/open_surface.h).
py::dict intake_maybe_open(const PolygonSoup& soup) {
  if (inspect(soup).num_boundary_loops == 0) {
    py::dict d = intake_to_dict(intake(soup));
    d["boundary_loops"] = py::list();
    return d;
  }
  const OpenIntakeResult r = intake_open(soup);
  py::dict d = intake_to_dict(r.intake);
  d["info"]["genus"] = r.topology.genus;
  d["info"]["num_boundary_loops"] = r.topology.num_boundary_loops();
  d["info"]["topology"] = r.topology.describe();
  py::list loops;
  for (const auto& loop : r.topology.boundary_loops) loops.append(to_numpy(loop));
  d["boundary_loops"] = loops;
  return d;
}

}  // namespace

void bind_mesh(py::module_& m) {
  m.def(
      "inspect", [](py::handle V, py::handle faces) { return info_to_dict(inspect(to_soup(V, faces))); },
      py::arg("V"), py::arg("faces"),
      "Counts, genus and problems of a mesh; never raises for bad topology.");
  m.def(
      "intake",
      [](py::handle V, py::handle faces, bool allow_boundary) {
        const PolygonSoup soup = to_soup(V, faces);
        return allow_boundary ? intake_maybe_open(soup) : intake_to_dict(intake(soup));
      },
      py::arg("V"), py::arg("faces"), py::arg("allow_boundary") = false,
      "Validates, triangulates and orients a mesh outward; raises InputError naming the problem. "
      "allow_boundary=True accepts open surfaces (docs/open_surfaces.md): never flipped, info['genus'] is g of "
      "chi = 2 - 2g - b, and 'boundary_loops' lists each loop's vertex indices (longest first, surface on the "
      "left; empty for a closed mesh).");
  m.def(
      "load_mesh", [](const std::string& path) { return intake_to_dict(load_mesh(path)); }, py::arg("path"),
      "Reads (OBJ/OFF/PLY/STL) and validates a mesh file.");
  m.def(
      "read_polygon_soup",
      [](const std::string& path) {
        const PolygonSoup s = read_polygon_soup(path);
        return py::make_tuple(to_numpy(s.V), s.polygons);
      },
      py::arg("path"), "Reads a mesh file without validating it: (V, list of polygons).");
  m.def(
      "write_obj",
      [](const std::string& path, py::handle V, py::handle F) { write_obj(path, to_vertices(V), to_triangles(F)); },
      py::arg("path"), py::arg("V"), py::arg("F"), "Writes an OBJ file atomically.");
}

}  // namespace surfmap::python
