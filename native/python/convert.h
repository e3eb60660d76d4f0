#pragma once
// numpy <-> Eigen conversions shared by the bind_* files. Inputs are checked
// for shape and turned into InputError with the argument's name.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>  // every bind_*.cpp must see the same casters

#include <string>

#include "surfmap/error.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::python {

namespace py = pybind11;

inline RowMatrixX3d to_vertices(const py::handle& obj, const char* name = "V") {
  auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a || a.ndim() != 2 || a.shape(1) != 3)
    throw InputError(std::string(name) + " must be a float array of shape (n, 3)");
  RowMatrixX3d V(a.shape(0), 3);
  std::copy(a.data(), a.data() + a.size(), V.data());
  return V;
}

inline RowMatrixX3i to_triangles(const py::handle& obj, const char* name = "F") {
  auto a = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(obj);
  if (!a || a.ndim() != 2 || a.shape(1) != 3)
    throw InputError(std::string(name) + " must be an integer array of shape (m, 3)");
  RowMatrixX3i F(a.shape(0), 3);
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    const long long v = a.data()[i];
    if (v < INT32_MIN || v > INT32_MAX)
      throw InputError(std::string(name) + ": face " + std::to_string(i / 3) + " has index " +
                       std::to_string(v) + ", out of range");
    F.data()[i] = static_cast<int>(v);
  }
  return F;
}

inline py::array_t<double> to_numpy(const RowMatrixX3d& M) {
  py::array_t<double> a({static_cast<py::ssize_t>(M.rows()), py::ssize_t{3}});
  std::copy(M.data(), M.data() + M.size(), a.mutable_data());
  return a;
}

inline py::array_t<int> to_numpy(const RowMatrixX3i& M) {
  py::array_t<int> a({static_cast<py::ssize_t>(M.rows()), py::ssize_t{3}});
  std::copy(M.data(), M.data() + M.size(), a.mutable_data());
  return a;
}

template <class T>
py::array_t<T> to_numpy(const std::vector<T>& v) {
  py::array_t<T> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

/// Intake of a map's source and target (called with the GIL released); an InputError says which
/// of the two it is about ("source: ..." / "target: ...").
inline void intake_source_and_target(const RowMatrixX3d& vs, const RowMatrixX3i& fs, const RowMatrixX3d& vt,
                                     const RowMatrixX3i& ft, IntakeResult& src, IntakeResult& dst) {
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
}

}  // namespace surfmap::python
