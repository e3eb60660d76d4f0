// Verify layer bindings: the independent certificate of a stored map
// (verify/map_certificate.h, docs/verification.md).
#include "bindings.h"
#include "convert.h"
#include "surfmap/error.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/verify/correspondence_file.h"
#include "surfmap/verify/map_certificate.h"

namespace py = pybind11;

namespace surfmap::python {
namespace {

/// {'face': (n,), 'barycentric': (n, 3)} (surface_map's 'forward'/'inverse').
std::vector<SurfacePoint> to_points(const py::handle& obj, const char* name) {
  if (!py::isinstance<py::dict>(obj))
    throw InputError(std::string(name) + " must be a dict with 'face' (n,) and 'barycentric' (n, 3)");
  const py::dict d = py::reinterpret_borrow<py::dict>(obj);
  if (!d.contains("face") || !d.contains("barycentric"))
    throw InputError(std::string(name) + " must have 'face' and 'barycentric'");
  auto face = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(d["face"]);
  const RowMatrixX3d bary = to_vertices(d["barycentric"], (std::string(name) + " barycentric").c_str());
  if (!face || face.ndim() != 1 || face.shape(0) != bary.rows())
    throw InputError(std::string(name) + ": 'face' must be an integer array with one entry per barycentric row");
  std::vector<SurfacePoint> points(bary.rows());
  for (size_t i = 0; i < points.size(); ++i) {
    const long long f = face.data()[i];
    points[i].face = f < INT32_MIN || f > INT32_MAX ? -1 : static_cast<int>(f);
    points[i].barycentric = bary.row(i).transpose();
  }
  return points;
}

py::dict points_dict(const std::vector<SurfacePoint>& points) {
  std::vector<int> face(points.size());
  RowMatrixX3d bary(points.size(), 3);
  for (size_t i = 0; i < points.size(); ++i) face[i] = points[i].face, bary.row(i) = points[i].barycentric.transpose();
  py::dict d;
  d["face"] = to_numpy(face);
  d["barycentric"] = to_numpy(bary);
  return d;
}

}  // namespace

void bind_verify(py::module_& m) {
  m.def(
      "verify",
      [](py::handle Vs, py::handle Fs, py::handle Vt, py::handle Ft, py::handle forward, py::handle inverse,
         double barycentric_tolerance, double area_tolerance, double inverse_tolerance, bool strict) {
        const RowMatrixX3d vs = to_vertices(Vs, "source V"), vt = to_vertices(Vt, "target V");
        const RowMatrixX3i fs = to_triangles(Fs, "source F"), ft = to_triangles(Ft, "target F");
        const std::vector<SurfacePoint> fw = to_points(forward, "forward"), iv = to_points(inverse, "inverse");
        MapCertificateOptions opt;
        opt.barycentric_tolerance = barycentric_tolerance;
        opt.area_tolerance = area_tolerance;
        opt.inverse_tolerance = inverse_tolerance;
        opt.strict = strict;
        MapCertificate c;
        {
          py::gil_scoped_release release;
          IntakeResult src, dst;
          intake_source_and_target(vs, fs, vt, ft, src, dst);
          c = certify_map(src.mesh, dst.mesh, fw, iv, opt);
        }
        py::dict d;
        d["certified"] = c.certified;
        d["failures"] = c.failures;
        d["undecided"] = c.undecided;
        d["summary"] = c.summary();
        d["invalid_forward"] = c.invalid_forward;
        d["invalid_inverse"] = c.invalid_inverse;
        d["min_barycentric"] = c.min_barycentric;
        d["negative_triangles"] = c.negative_triangles;
        d["degenerate_triangles"] = c.degenerate_triangles;
        d["min_relative_area"] = c.min_relative_area;
        d["winding_failures"] = c.winding_failures;
        d["signed_image_area"] = c.signed_image_area;
        d["target_area"] = c.target_area;
        d["area_ratio"] = c.area_ratio;
        d["degree"] = c.degree;
        d["max_inverse_error"] = c.max_inverse_error;
        d["max_forward_error"] = c.max_forward_error;
        d["inverse_failures"] = c.inverse_failures;
        d["forward_failures"] = c.forward_failures;
        d["unresolved_triangles"] = c.unresolved_triangles;
        d["negative_unresolved"] = c.negative_unresolved;
        d["winding_failures_unresolved"] = c.winding_failures_unresolved;
        d["inverse_failures_unresolved"] = c.inverse_failures_unresolved;
        d["forward_failures_unresolved"] = c.forward_failures_unresolved;
        return d;
      },
      py::arg("Vs"), py::arg("Fs"), py::arg("Vt"), py::arg("Ft"), py::arg("forward"), py::arg("inverse"),
      py::arg("barycentric_tolerance") = 1e-9, py::arg("area_tolerance") = 0.25, py::arg("inverse_tolerance") = 1.0, py::arg("strict") = false,
      "Independent certificate that a map is a bijection (docs/verification.md). forward: {'face', 'barycentric'} "
      "per source vertex (surface_map's 'forward'), inverse: per target vertex. Meshes go through intake as in "
      "surface_map. Returns a dict: 'certified', 'failures', 'undecided' (checks failed only on unresolved images; "
      "failures with strict=True), 'summary' and the figures of every check.");
  m.def(
      "read_correspondence",
      [](const std::string& path) {
        const CorrespondenceFile f = read_correspondence(path);
        py::dict d;
        d["forward"] = points_dict(f.forward);
        d["inverse"] = points_dict(f.inverse);
        d["has_inverse"] = f.has_inverse;
        return d;
      },
      py::arg("path"), "CORR.txt of `surfmap map --correspondence`: {'forward', 'inverse', 'has_inverse'}.");
}

}  // namespace surfmap::python
