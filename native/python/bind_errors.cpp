// One exception hierarchy seen from Python: surfmap.Error is the base;
// InputError is also a ValueError, SolveError also a RuntimeError,
// UniformizationError and SingleChartError SolveErrors.
#include "bindings.h"
#include "surfmap/error.h"

namespace py = pybind11;

namespace surfmap::python {

void bind_errors(py::module_& m) {
  static py::handle error = PyErr_NewExceptionWithDoc(
      "surfmap.Error", "Base of every error raised by surfmap.", PyExc_Exception, nullptr);
  static py::handle input_error = PyErr_NewExceptionWithDoc(
      "surfmap.InputError", "The input mesh or arguments are unusable; the message names the element.",
      py::make_tuple(error, py::handle(PyExc_ValueError)).release().ptr(), nullptr);
  static py::handle solve_error = PyErr_NewExceptionWithDoc(
      "surfmap.SolveError", "A numerical solve did not converge or produced an invalid result.",
      py::make_tuple(error, py::handle(PyExc_RuntimeError)).release().ptr(), nullptr);
  static py::handle uniformization_error = PyErr_NewExceptionWithDoc(
      "surfmap.UniformizationError",
      "A uniformization metric could not be delivered (the flow did not converge, the metric does not exist on the "
      "fixed connectivity, or its layout is inconsistent); a SolveError.",
      solve_error.ptr(), nullptr);
  static py::handle single_chart_error = PyErr_NewExceptionWithDoc(
      "surfmap.SingleChartError",
      "The hyperbolic layout is valid but reaches too far from the centre of the Poincare disk for the one chart "
      "the map reads (surfaces this long in their metric need per-face charts, not yet supported); a SolveError.",
      solve_error.ptr(), nullptr);
  static py::handle cancelled = PyErr_NewExceptionWithDoc(
      "surfmap.Cancelled", "The progress callback asked to stop.", error.ptr(), nullptr);
  m.attr("Error") = error;
  m.attr("InputError") = input_error;
  m.attr("SolveError") = solve_error;
  m.attr("UniformizationError") = uniformization_error;
  m.attr("SingleChartError") = single_chart_error;
  m.attr("Cancelled") = cancelled;
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      PyErr_SetString(input_error.ptr(), e.what());
    } catch (const UniformizationError& e) {
      PyErr_SetString(uniformization_error.ptr(), e.what());
    } catch (const SingleChartError& e) {
      PyErr_SetString(single_chart_error.ptr(), e.what());
    } catch (const SolveError& e) {
      PyErr_SetString(solve_error.ptr(), e.what());
    } catch (const Cancelled& e) {
      PyErr_SetString(cancelled.ptr(), e.what());
    } catch (const Error& e) {
      PyErr_SetString(error.ptr(), e.what());
    }
  });
}

}  // namespace surfmap::python
