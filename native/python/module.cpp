// The pybind11 module nfield._native: the native library seen from Python.
// Only native/python/ knows about Python. This file defines the module and its exception translation and
// calls the bind_<area> functions (binding_support.hpp), one per area of the library.
// Heavy calls release the GIL; progress callbacks re-acquire it.
// Every C++ exception becomes a Python exception (ValueError / RuntimeError / nfield._native.Cancelled /
// nfield._native.InsufficientMemory; std::bad_alloc -> MemoryError, other std::exception -> RuntimeError).
#include <pybind11/pybind11.h>

#include "binding_support.hpp"
#include "nfield/errors.hpp"
#include "nfield/memory_guard.hpp"

namespace py = pybind11;

namespace {

void register_exceptions(py::module_& m) {
  py::register_local_exception<nfield::Cancelled>(m, "Cancelled", PyExc_RuntimeError);
  py::register_local_exception<nfield::MemoryLimitError>(m, "InsufficientMemory", PyExc_MemoryError);
  // Module-local types and translators: two copies of this module (e.g. a development tree and an
  // installed Blender extension) can then live in one interpreter without clashing.
  // Registered after Cancelled and InsufficientMemory, so tried first; it leaves them to their translators.
  // std::bad_alloc (MemoryError) and other std::exception (RuntimeError) reach pybind11's default one.
  py::register_local_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const nfield::InputError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const nfield::ParameterError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const nfield::ConstraintError& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const nfield::SolverError& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });
}

}  // namespace

PYBIND11_MODULE(_native, m) {
  m.doc() = "nfield native solver: n-symmetry direction field splines on triangle meshes";
  register_exceptions(m);
  // Order matters only for the signatures in docstrings: a class is registered before the functions
  // that take or return it (Mesh before FieldOperators, SpectralBasis before ReducedSolver).
  nfield::python::bind_mesh(m);
  nfield::python::bind_operators(m);
  nfield::python::bind_spectral(m);
  nfield::python::bind_solvers(m);
  nfield::python::bind_streamlines(m);
  nfield::python::bind_remesh(m);
  nfield::python::bind_guides(m);  // after bind_solvers: MirrorMap is also an argument of ExactSolver.set_symmetry
}
