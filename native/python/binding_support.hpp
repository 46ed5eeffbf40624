// Shared helpers of the pybind11 module nfield._native (module.cpp and the bind_<area>.cpp files):
// NumPy <-> Eigen conversions with input checks, GIL release, and the adaptor that turns a Python progress
// callable into a ProgressCallback and its exceptions back into themselves.
//
// Layout of the module: module.cpp defines `_native`, registers the exception translation and calls one
// `void nfield::python::bind_<area>(pybind11::module_& m)` per area (declared below), each defined in
// native/python/bind_<area>.cpp. CMakeLists.txt compiles every native/python/*.cpp into the module, so a
// new area is a new bind_<area>.cpp, one declaration here and one call in module.cpp.
//
// Rules every binding follows: heavy calls run through without_gil (or a gil_scoped_release block);
// arguments are converted to Eigen types before the GIL is released and results to NumPy after it is
// re-acquired; library exceptions reach Python through the translator of module.cpp (InputError,
// ParameterError, ConstraintError -> ValueError; SolverError -> RuntimeError; Cancelled and
// MemoryLimitError -> the module's Cancelled / InsufficientMemory).
#pragma once
// Every binding file includes the same type casters (through this header): pybind11 requires that a C++
// type converts the same way in every translation unit of a module.
#include <pybind11/complex.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <complex>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "nfield/errors.hpp"
#include "nfield/mesh.hpp"
#include "nfield/operators.hpp"
#include "nfield/spectrum.hpp"

namespace nfield::python {

namespace py = pybind11;

// ---- the areas of the module (each in native/python/bind_<area>.cpp), called in this order by module.cpp
void bind_mesh(py::module_& m);         ///< Mesh, read_mesh
void bind_operators(py::module_& m);    ///< FieldOperators, curvature alignment, singularity indices
void bind_spectral(py::module_& m);     ///< eigen, smoothest_field, SpectralBasis, low_pass, basis memory and cache
void bind_solvers(py::module_& m);      ///< strength_to_lambda, ExactSolver, ReducedSolver
void bind_streamlines(py::module_& m);  ///< trace_streamlines
void bind_remesh(py::module_& m);       ///< quad_remesh, polygon mesh checks and quality statistics
void bind_guides(py::module_& m);       ///< features, curve and comb guides, guide fields, mirror maps, cuts

// ---- NumPy arguments (C-contiguous, converted on the way in)
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using IndexArray = py::array_t<long long, py::array::c_style | py::array::forcecast>;
using ComplexArray = py::array_t<std::complex<double>, py::array::c_style | py::array::forcecast>;

/// InputError unless `a` has shape (k, cols).
void require_shape(const py::array& a, py::ssize_t cols, const char* what);
/// (V, 3) float array -> Positions.
Positions to_positions(const DoubleArray& a);
/// (F, 3) integer array -> Triangles; InputError for indices outside the int range.
Triangles to_triangles(const IndexArray& a, const char* what = "faces");
/// 1-D complex array -> ComplexVector; InputError otherwise.
ComplexVector to_complex_vector(const ComplexArray& a, const char* what);
/// Alignment argument of the solvers: None (no alignment, empty vector) or one complex value per face.
ComplexVector optional_alignment(const py::object& alignment);

// ---- NumPy results (fresh arrays owning a copy)
py::array_t<std::complex<double>> from_complex(const ComplexVector& v);
py::array_t<double> from_eigen(const Eigen::VectorXd& v);
/// (k, 3) array of 3D vectors.
py::array_t<double> from_vec3(const std::vector<Eigen::Vector3d>& v);

/// 1-D array of a std::vector.
template <class Vec>
py::array_t<typename Vec::value_type> from_std(const Vec& v) {
  py::array_t<typename Vec::value_type> out(v.size());
  std::copy(v.begin(), v.end(), out.mutable_data());
  return out;
}

/// (rows, cols) array of a row-major Eigen matrix (Positions, Triangles, Vectors3).
template <class RowMajorMatrix>
py::array_t<typename RowMajorMatrix::Scalar> from_rows(const RowMajorMatrix& a) {
  static_assert(RowMajorMatrix::IsRowMajor, "from_rows copies row-major storage");
  py::array_t<typename RowMajorMatrix::Scalar> out({static_cast<py::ssize_t>(a.rows()), static_cast<py::ssize_t>(a.cols())});
  std::copy(a.data(), a.data() + a.size(), out.mutable_data());
  return out;
}

/// A dict of named values: named("a", x, "b", y, ...) with x, y anything pybind11 converts. The native
/// reports (plain structs of counts) become dicts this way, one expression each.
inline void add_named(py::dict&) {}
template <class T, class... Rest>
void add_named(py::dict& d, const char* key, T&& value, Rest&&... rest) {
  d[key] = py::cast(std::forward<T>(value));
  add_named(d, std::forward<Rest>(rest)...);
}
template <class... Items>
py::dict named(Items&&... items) {
  static_assert(sizeof...(Items) % 2 == 0, "named() takes name, value pairs");
  py::dict d;
  add_named(d, std::forward<Items>(items)...);
  return d;
}

// ---- the GIL

/// Runs `work` with the GIL released and returns its result (which must not be a Python object).
template <class Work>
auto without_gil(Work&& work) -> decltype(work()) {
  py::gil_scoped_release release;
  return work();
}

// ---- progress and cancellation

/// A Python progress callable for the native code: called with the GIL held; False cancels. An exception
/// raised by the callable (KeyboardInterrupt too) cancels the computation and is then re-raised as itself
/// by run_with_progress instead of becoming Cancelled.
struct PythonProgress {
  ProgressCallback callback;  ///< empty when the callable is None
  std::shared_ptr<std::optional<py::error_already_set>> error = std::make_shared<std::optional<py::error_already_set>>();
};

PythonProgress wrap_progress(const py::object& callable);

/// Runs `work` (which releases the GIL itself) and turns a cancel caused by an exception of the progress
/// callable back into that exception.
template <class Work>
auto run_with_progress(const PythonProgress& progress, Work&& work) -> decltype(work()) {
  try {
    return work();
  } catch (const Cancelled&) {
    if (progress.error->has_value()) {
      py::error_already_set e = std::move(**progress.error);
      progress.error->reset();
      throw e;
    }
    throw;
  }
}

}  // namespace nfield::python
