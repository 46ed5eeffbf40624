// Binding of the solvers area: the exact n-field spline solver (spline_solver.hpp), the reduced solver in a
// spectral basis (reduced_solver.hpp, paper eqs. 16-18) and the strength -> lambda map they share.
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "binding_support.hpp"
#include "nfield/mirror.hpp"
#include "nfield/reduced_solver.hpp"
#include "nfield/spectral_basis.hpp"
#include "nfield/spline_solver.hpp"

namespace nfield::python {
namespace {

SplineKind parse_kind(const std::string& kind) {
  if (kind == "direction") return SplineKind::Direction;
  if (kind == "vector") return SplineKind::Vector;
  throw ParameterError("unknown spline kind '" + kind + "' (expected 'direction' or 'vector')");
}

/// Face indices from a 1-D integer array, each in range (ConstraintError naming `what` otherwise).
std::vector<int> face_list(const FieldOperators& ops, const IndexArray& faces, const char* what) {
  if (faces.ndim() != 1) throw InputError(std::string(what) + " must be a 1-D array of face indices");
  std::vector<int> out;
  out.reserve(static_cast<std::size_t>(faces.shape(0)));
  for (py::ssize_t i = 0; i < faces.shape(0); ++i) {
    const long long f = faces.data()[i];
    if (f < 0 || f >= ops.mesh().num_faces())
      throw ConstraintError(std::string(what) + " face " + std::to_string(f) + " is out of range");
    out.push_back(static_cast<int>(f));
  }
  return out;
}

/// The frozen faces of ExactSolver: either frozen_faces with frozen_values (equal-length 1-D arrays), or
/// free_faces with held_field (every other active face held at its value in the field: a live region), or none.
FrozenFaces frozen_faces_of(const FieldOperators& ops, const py::object& frozen_faces, const py::object& frozen_values,
                            const py::object& free_faces, const py::object& held_field) {
  if (!free_faces.is_none() || !held_field.is_none()) {
    if (free_faces.is_none() || held_field.is_none())
      throw InputError("free_faces and held_field go together (the region and the field held around it)");
    if (!frozen_faces.is_none() || !frozen_values.is_none())
      throw InputError("give either frozen_faces and frozen_values or free_faces and held_field, not both");
    const std::vector<int> free = face_list(ops, free_faces.cast<IndexArray>(), "free");
    return FrozenFaces::complement(ops.mesh(), free, to_complex_vector(held_field.cast<ComplexArray>(), "held_field"));
  }
  if (frozen_faces.is_none()) return {};
  const IndexArray faces = frozen_faces.cast<IndexArray>();
  const ComplexArray values = frozen_values.cast<ComplexArray>();
  if (faces.ndim() != 1 || values.ndim() != 1 || faces.shape(0) != values.shape(0))
    throw InputError("frozen_faces and frozen_values must be 1-D arrays of equal length");
  const std::vector<int> list = face_list(ops, faces, "frozen");
  std::vector<std::pair<int, Complex>> frozen;
  frozen.reserve(list.size());
  for (std::size_t i = 0; i < list.size(); ++i) frozen.emplace_back(list[i], values.data()[i]);
  return FrozenFaces::listed(ops.mesh(), frozen);
}

/// Per-face alignment weights of ExactSolver: None (empty: weight 1 everywhere) or a 1-D float array; the solver
/// checks the length and the values (finite, >= 0).
Eigen::VectorXd optional_weights(const py::object& weights) {
  if (weights.is_none()) return {};
  const DoubleArray w = weights.cast<DoubleArray>();
  if (w.ndim() != 1) throw InputError("alignment_weight must be a 1-D array (one weight per face)");
  return Eigen::Map<const Eigen::VectorXd>(w.data(), w.shape(0));
}

/// Face indices of the substituted vector constraints (ExactSolver anchors), validated against the mesh.
std::vector<int> anchor_faces_of(const FieldOperators& ops, const py::object& anchor_faces) {
  if (anchor_faces.is_none()) return {};
  return face_list(ops, anchor_faces.cast<IndexArray>(), "anchor");
}

}  // namespace

void bind_solvers(py::module_& m) {
  m.def("strength_to_lambda", [](std::shared_ptr<FieldOperators> ops, int order, double strength) {
    if (order < 1 || order > 4) throw ParameterError("energy order must be 1 to 4");
    return strength_to_lambda(*ops, order, strength);
  }, py::arg("ops"), py::arg("order"), py::arg("strength"));

  py::class_<ExactSolver>(m, "ExactSolver", py::module_local(), "Exact n-field spline solver with cached factorization")
      .def(py::init([](std::shared_ptr<FieldOperators> ops, int order, double strength, const py::object& alignment,
                       const std::string& kind, double lambda_override, const py::object& progress,
                       const py::object& frozen_faces, const py::object& frozen_values, const py::object& anchor_faces,
                       bool cache_columns, const py::object& alignment_weight, const py::object& free_faces,
                       const py::object& held_field) {
             ComplexVector a = optional_alignment(alignment);
             const SplineKind k = parse_kind(kind);
             const PythonProgress cb = wrap_progress(progress);
             FrozenFaces frozen = frozen_faces_of(*ops, frozen_faces, frozen_values, free_faces, held_field);
             const std::vector<int> anchors = anchor_faces_of(*ops, anchor_faces);
             Eigen::VectorXd weight = optional_weights(alignment_weight);
             return run_with_progress(cb, [&] {
               return without_gil([&] {
                 return new ExactSolver(ops, order, strength, std::move(a), k, lambda_override, cb.callback,
                                        std::move(frozen), anchors, cache_columns, std::move(weight));
               });
             });
           }),
           py::arg("ops"), py::arg("order") = 2, py::arg("strength") = 1.0, py::arg("alignment") = py::none(),
           py::arg("kind") = "direction", py::arg("lambda_override") = std::numeric_limits<double>::quiet_NaN(),
           py::arg("progress") = py::none(), py::arg("frozen_faces") = py::none(),
           py::arg("frozen_values") = py::none(), py::arg("anchor_faces") = py::none(),
           py::arg("cache_columns") = true, py::arg("alignment_weight") = py::none(),
           py::arg("free_faces") = py::none(), py::arg("held_field") = py::none(),
           "Factor V = E_order - lambda M_W over the faces that are neither frozen (they keep their values) nor "
           "anchors (faces whose vector constraints are substituted); W the per-face alignment weight (1 by default); "
           "cache_columns=False: a one-shot solver. The frozen faces are frozen_faces at frozen_values, or every "
           "active face but free_faces at its value in held_field (one per face: a local solve whose cost follows "
           "the free faces, not the held ones)")
      .def("set_alignment", [](ExactSolver& s, const py::object& alignment) {
        const ComplexVector a = optional_alignment(alignment);
        without_gil([&] { s.set_alignment(a); });
      }, py::arg("alignment"), "New guide target values (W g per face): right-hand side only, no refactorization")
      .def("set_symmetry", [](ExactSolver& s, const py::object& mirror) {
        std::shared_ptr<const MirrorMap> mm;
        if (!mirror.is_none()) mm = mirror.cast<std::shared_ptr<MirrorMap>>();
        without_gil([&] { s.set_symmetry(mm); });
      }, py::arg("mirror"), "Solve on the mirror-symmetric fields of a MirrorMap (None: no symmetry)")
      .def_property_readonly("symmetric", &ExactSolver::symmetric)
      .def_property_readonly("symmetry_corrections", &ExactSolver::symmetry_corrections)
      .def("set_direction_constraint", &ExactSolver::set_direction_constraint, py::arg("face"), py::arg("d"))
      .def("set_vector_constraint", &ExactSolver::set_vector_constraint, py::arg("face"), py::arg("value"))
      .def("remove_constraint", &ExactSolver::remove_constraint, py::arg("face"))
      .def("set_singularity", &ExactSolver::set_singularity, py::arg("vertex"), py::arg("numerator"))
      .def("remove_singularity", &ExactSolver::remove_singularity, py::arg("vertex"))
      .def("clear_constraints", &ExactSolver::clear_constraints)
      .def("solve", [](ExactSolver& s) { return from_complex(without_gil([&] { return s.solve(); })); })
      .def_property_readonly("lambda_", &ExactSolver::lambda)
      .def_property_readonly("order", &ExactSolver::order)
      .def_property_readonly("sign_fixed_faces", &ExactSolver::sign_fixed_faces)
      .def_property_readonly("num_constraints", [](const ExactSolver& s) { return s.constraints().size(); })
      .def_property_readonly("num_cached_columns", &ExactSolver::num_cached_columns)
      .def_property_readonly("num_unknowns", &ExactSolver::num_unknowns)
      .def_property_readonly("num_factorizations", &ExactSolver::num_factorizations)
      .def_property_readonly("condition_estimate", &ExactSolver::condition_estimate)
      .def_property_readonly("anchor_faces", [](const ExactSolver& s) { return from_std(s.anchor_faces()); })
      .def("needs_refactorization", &ExactSolver::needs_refactorization, py::arg("vector_faces"),
           "Whether a solve with vector constraints on exactly these faces would refactor (stale anchors)")
      .def("face_frozen", &ExactSolver::face_frozen, py::arg("face"));

  py::class_<ReducedSolver>(m, "ReducedSolver", py::module_local(),
                            "Reduced n-field spline solver in a spectral basis (eqs. 16-18)")
      .def(py::init([](std::shared_ptr<FieldOperators> ops, std::shared_ptr<SpectralBasis> basis, int order,
                       double strength, const py::object& alignment, const std::string& kind,
                       double lambda_override) {
             const ComplexVector a = optional_alignment(alignment);
             const SplineKind k = parse_kind(kind);
             return without_gil([&] { return new ReducedSolver(ops, basis, order, strength, a, k, lambda_override); });
           }),
           py::arg("ops"), py::arg("basis"), py::arg("order") = 2, py::arg("strength") = 1.0,
           py::arg("alignment") = py::none(), py::arg("kind") = "direction",
           py::arg("lambda_override") = std::numeric_limits<double>::quiet_NaN())
      .def("set_strength", &ReducedSolver::set_strength, py::arg("strength"),
           "Change the alignment strength live (no factorization: O(k))")
      .def("set_lambda", &ReducedSolver::set_lambda, py::arg("lambda_"))
      .def("set_alignment", [](ReducedSolver& s, const py::object& alignment) {
        const ComplexVector a = optional_alignment(alignment);
        without_gil([&] { s.set_alignment(a); });
      }, py::arg("alignment"))
      .def("set_direction_constraint", &ReducedSolver::set_direction_constraint, py::arg("face"), py::arg("d"))
      .def("set_vector_constraint", &ReducedSolver::set_vector_constraint, py::arg("face"), py::arg("value"))
      .def("remove_constraint", &ReducedSolver::remove_constraint, py::arg("face"))
      .def("set_singularity", &ReducedSolver::set_singularity, py::arg("vertex"), py::arg("numerator"))
      .def("remove_singularity", &ReducedSolver::remove_singularity, py::arg("vertex"))
      .def("clear_constraints", &ReducedSolver::clear_constraints)
      .def("solve_coefficients", [](ReducedSolver& s) {
        return from_complex(without_gil([&] { return s.solve_coefficients(); }));
      }, "The reduced solution x (k): the field is U x (no reconstruction)")
      .def("solve", [](ReducedSolver& s) {
        return from_complex(without_gil([&] { return s.solve(); }));
      }, "The field per face (U x, constrained faces snapped)")
      .def("reconstruct", [](const ReducedSolver& s, const ComplexArray& x) {
        const ComplexVector c = to_complex_vector(x, "coefficients");
        if (c.size() != s.size())
          throw InputError("coefficients must have size k = " + std::to_string(s.size()) + ", got " +
                           std::to_string(c.size()));
        return from_complex(without_gil([&] { return s.reconstruct(c); }));
      }, py::arg("x"))
      .def_property_readonly("lambda_", &ReducedSolver::lambda)
      .def_property_readonly("order", &ReducedSolver::order)
      .def_property_readonly("size", &ReducedSolver::size)
      .def_property_readonly("sign_fixed_faces", &ReducedSolver::sign_fixed_faces)
      .def_property_readonly("constraint_residual", &ReducedSolver::constraint_residual)
      .def_property_readonly("uncovered_components", &ReducedSolver::uncovered_components)
      .def_property_readonly("num_constraints", [](const ReducedSolver& s) { return s.constraints().size(); });
}

}  // namespace nfield::python
