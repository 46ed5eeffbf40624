// Binding of the spectral area: lowest eigenpairs and the smoothest field (spectrum.hpp), the spectral basis
// of the reduced solver with its memory estimate and disk cache (spectral_basis.hpp, memory_guard.hpp), and
// the low-pass filter (reduced_solver.hpp). The ReducedSolver itself is bound with the solvers.
#include <string>

#include "binding_support.hpp"
#include "nfield/basis_cache.hpp"
#include "nfield/basis_memory.hpp"
#include "nfield/memory_guard.hpp"
#include "nfield/per_face.hpp"
#include "nfield/reduced_solver.hpp"
#include "nfield/spectral_basis.hpp"
#include "nfield/spectrum.hpp"

namespace nfield::python {
namespace {

BasisPrecision parse_precision(const std::string& precision) {
  if (precision == "double") return BasisPrecision::Double;
  if (precision == "single") return BasisPrecision::Single;
  throw ParameterError("unknown basis precision '" + precision + "' (expected 'double' or 'single')");
}

const char* to_string(BasisPrecision p) { return p == BasisPrecision::Double ? "double" : "single"; }

/// An (F, k) complex array with the rows of a per-unknown matrix on their faces (zero rows on excluded faces).
py::array_t<std::complex<double>> per_face_rows(const FieldOperators& ops, const Eigen::MatrixXcd& per_unknown) {
  const py::ssize_t F = ops.mesh().num_faces(), k = per_unknown.cols();
  py::array_t<std::complex<double>> out({F, k});
  Eigen::Map<RowMajorMatrixXcd> rows(out.mutable_data(), F, k);
  scatter_rows_to_faces(ops, per_unknown, rows);
  return out;
}

}  // namespace

void bind_spectral(py::module_& m) {
  m.def("eigen", [](std::shared_ptr<FieldOperators> ops, int k, const py::object& progress) {
    const PythonProgress cb = wrap_progress(progress);
    const Eigenpairs pairs = run_with_progress(cb, [&] {
      return without_gil([&] { return lowest_eigenpairs(*ops, k, cb.callback); });
    });
    return py::make_tuple(from_eigen(pairs.values), per_face_rows(*ops, pairs.vectors));
  }, py::arg("ops"), py::arg("k"), py::arg("progress") = py::none(),
        "Lowest k eigenpairs of S z = lambda M z (complex form, ascending, M-orthonormal)");

  m.def("smoothest_field", [](std::shared_ptr<FieldOperators> ops) {
    return from_complex(without_gil([&] { return smoothest_field(*ops); }));
  }, py::arg("ops"));

  // ---- spectral reduction (paper section 8): spectral_basis.hpp, reduced_solver.hpp ----
  py::class_<SpectralBasis, std::shared_ptr<SpectralBasis>>(
      m, "SpectralBasis", py::module_local(),
      "The first k eigenpairs of S z = lambda M z (M-orthonormal), for reduced solves and low-pass filtering")
      .def_static("compute", [](std::shared_ptr<FieldOperators> ops, int k, const std::string& precision,
                                const py::object& progress, double tolerance, int slice_size) {
        SpectralBasisOptions options;
        options.precision = parse_precision(precision);
        if (!(tolerance > 0 && tolerance < 1e-2)) throw ParameterError("tolerance must lie in (0, 1e-2)");
        options.tolerance = tolerance;
        if (slice_size < 0) throw ParameterError("slice_size must be >= 0 (0: automatic)");
        options.slice_size = slice_size;
        const PythonProgress cb = wrap_progress(progress);
        return run_with_progress(cb, [&] {
          return without_gil(
              [&] { return std::make_shared<SpectralBasis>(SpectralBasis::compute(*ops, k, options, cb.callback)); });
        });
      }, py::arg("ops"), py::arg("k"), py::arg("precision") = "double", py::arg("progress") = py::none(),
         py::arg("tolerance") = 1e-10, py::arg("slice_size") = 0,
         "Compute the basis (expensive; GIL released; progress(fraction) returning False cancels)")
      .def_static("load", [](const std::string& path, std::shared_ptr<FieldOperators> ops, int k,
                             const py::object& precision) {
        const int p = precision.is_none() ? -1 : static_cast<int>(parse_precision(precision.cast<std::string>()));
        return without_gil([&] { return std::make_shared<SpectralBasis>(load_basis(path, *ops, k, p)); });
      }, py::arg("path"), py::arg("ops"), py::arg("k") = 0, py::arg("precision") = py::none(),
         "Read a basis saved for these operators; ValueError if missing, corrupt or stale")
      .def("save", [](const SpectralBasis& b, const std::string& path) {
        without_gil([&] { save_basis(b, path); });
      }, py::arg("path"))
      .def_property_readonly("size", &SpectralBasis::size)
      .def_property_readonly("num_unknowns", &SpectralBasis::num_unknowns)
      .def_property_readonly("precision", [](const SpectralBasis& b) { return to_string(b.precision()); })
      .def_property_readonly("memory_bytes", &SpectralBasis::memory_bytes)
      .def_property_readonly("mesh_hash", &SpectralBasis::mesh_hash)
      .def_property_readonly("n", &SpectralBasis::n)
      .def_property_readonly("weights", [](const SpectralBasis& b) { return to_string(b.weights()); })
      .def_property_readonly("values", [](const SpectralBasis& b) { return from_eigen(b.values()); })
      .def("vectors", [](const SpectralBasis& b, std::shared_ptr<FieldOperators> ops) {
        if (b.num_unknowns() != ops->num_unknowns()) throw ParameterError("basis and operators do not match");
        return per_face_rows(*ops, b.vectors());
      }, py::arg("ops"), "The eigenvectors per face (F, k), zero rows on excluded faces")
      .def("truncated", &SpectralBasis::truncated, py::arg("k"))
      .def("with_precision", [](const SpectralBasis& b, const std::string& precision) {
        return b.with_precision(parse_precision(precision));
      }, py::arg("precision"));

  m.def("estimate_basis_bytes", [](std::shared_ptr<FieldOperators> ops, int k, const std::string& precision) {
    SpectralBasisOptions options;
    options.precision = parse_precision(precision);
    return without_gil([&] { return estimate_basis_bytes(*ops, k, options); });
  }, py::arg("ops"), py::arg("k"), py::arg("precision") = "double",
        "Estimated peak memory (bytes) of computing a basis of k eigenfields");
  m.def("available_memory_bytes", &available_memory_bytes,
        "Bytes the memory guard considers available (MemAvailable, cgroup limit, NFIELD_MEMORY_LIMIT_MB); 0 if unknown");

  m.def("basis_cache_key", [](std::shared_ptr<FieldOperators> ops, int k, const std::string& precision) {
    return cache_key(*ops, k, parse_precision(precision));
  }, py::arg("ops"), py::arg("k"), py::arg("precision") = "double",
        "File-name-safe key of a basis (mesh content hash, n, weights, size, k, precision)");

  m.def("low_pass", [](std::shared_ptr<FieldOperators> ops, std::shared_ptr<SpectralBasis> basis,
                       const ComplexArray& field) {
    const ComplexVector z = to_complex_vector(field, "field");
    return from_complex(without_gil([&] { return low_pass(*ops, *basis, z); }));
  }, py::arg("ops"), py::arg("basis"), py::arg("field"),
        "U U^H M field: the M-orthogonal projection of a per-face field onto the basis");
}

}  // namespace nfield::python
