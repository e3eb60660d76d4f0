#pragma once
// Each layer's bindings live in python/bind_<layer>.cpp; module.cpp calls them.
#include <pybind11/pybind11.h>

namespace surfmap::python {

void bind_errors(pybind11::module_& m);
void bind_mesh(pybind11::module_& m);
void bind_topology(pybind11::module_& m);
void bind_uniformize(pybind11::module_& m);
void bind_samples(pybind11::module_& m);
void bind_map(pybind11::module_& m);
void bind_verify(pybind11::module_& m);

}  // namespace surfmap::python
