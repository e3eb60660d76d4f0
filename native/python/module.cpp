#include "bindings.h"

PYBIND11_MODULE(_core, m) {
  m.doc() = "surfmap native core";
  surfmap::python::bind_errors(m);
  surfmap::python::bind_mesh(m);
  surfmap::python::bind_topology(m);
  surfmap::python::bind_map(m);
  surfmap::python::bind_samples(m);
  surfmap::python::bind_uniformize(m);
  surfmap::python::bind_verify(m);
  // SURFMAP_PY_BIND (keep this marker: add one bind_* call per line above it)
}
