// What the exact solver (spline_solver.hpp) and the reduced solver (reduced_solver.hpp) share about hard
// constraints: the editing and validation of a ConstraintSet, the +d safeguard's alignment spike, and the
// small dense constraint system of the Schur complement method (paper eq. 13).
//
// Both solvers eliminate the field and are left with R real unknowns gamma (one per constraint row):
//   K gamma = rhs,  K = D V^-1 D^T  (exact solver; V^-1 -> Lambda^-1 in the reduced solver),
// K is symmetric positive semi-definite (R x R, R = a few dozen). It is singular exactly when rows are
// linearly dependent (two constraints on one face, a singularity ring sharing a constrained face, or, for
// the reduced solver, rows a small basis cannot tell apart).
#pragma once
#include <Eigen/Dense>
#include <memory>
#include <vector>

#include "nfield/constraints.hpp"
#include "nfield/operators.hpp"

namespace nfield {

/// Weight of the +d safeguard (paper section 5, "s_i sufficiently large"): the alignment at a
/// direction-constrained face f becomes s_f d_f, s_f = kSafeguardWeight * s_0 * mean_area / A_f, with s_0
/// the RMS magnitude of the alignment field over its non-zero faces (1 without alignment). Every
/// constrained face then adds the same weight to the right-hand side, like 100 average aligned faces.
constexpr double kSafeguardWeight = 100.0;

/// kSafeguardWeight * s_0 for an alignment field given per unknown (see kSafeguardWeight).
double safeguard_spike(const ComplexVector& alignment);

/// Change of the alignment at a direction-constrained face: s_f d_f - u'_f (s_f as in kSafeguardWeight).
inline Complex safeguard_delta(double spike, double mean_area, double area, Complex d, Complex alignment) {
  return spike * (mean_area / area) * d - alignment;
}

/// Solution of K gamma = rhs for the symmetric positive semi-definite constraint system K.
struct ConstraintSystemSolution {
  Eigen::VectorXd gamma;
  /// Empty when the system is consistent. Otherwise the rows (indices into rhs) that carry the first
  /// combination rhs has outside the range of K (|eigenvector entry| > 0.1): contradictory constraints for
  /// the exact solver; the reduced solver keeps the least-squares gamma.
  std::vector<int> conflicting_rows;
};

/// LDL^T when the pivots stay above 1e-11 of the largest one; otherwise the pseudo-inverse (eigenvalues
/// below 1e-10 of the largest dropped), i.e. the least-squares solution, and the rows of the first
/// eigen-direction in K's null space along which rhs exceeds 1e-7 of its norm (conflicting_rows).
ConstraintSystemSolution solve_constraint_system(const Eigen::MatrixXd& K, const Eigen::VectorXd& rhs);

/// Constraint editing shared by both solvers: each edit is validated against the mesh (face in range and
/// carrying a field value, direction non-zero, singularity index admissible) and stored in a ConstraintSet.
/// Errors are ConstraintError naming the face or vertex. A solver can hold faces fixed (frozen faces of a
/// local edit): constraints on them, and singularities whose ring touches them, are refused.
class ConstraintEditor {
 public:
  /// Direction constraint: d is the representation vector (normalized here).
  void set_direction_constraint(int face, Complex d);
  void set_vector_constraint(int face, Complex value);
  void remove_constraint(int face);                 ///< ConstraintError if the face has none
  void set_singularity(int vertex, int numerator);  ///< index numerator/n, validated immediately
  void remove_singularity(int vertex);              ///< ConstraintError if the vertex has none
  void clear_constraints() { constraints_ = ConstraintSet{}; }
  const ConstraintSet& constraints() const { return constraints_; }

 protected:
  explicit ConstraintEditor(std::shared_ptr<const FieldOperators> ops) : ops_(std::move(ops)) {}
  ~ConstraintEditor() = default;
  ConstraintEditor(const ConstraintEditor&) = default;
  ConstraintEditor& operator=(const ConstraintEditor&) = default;

  /// True for faces the solver holds fixed (none by default).
  virtual bool face_fixed(int /*face*/) const { return false; }
  /// ConstraintError unless a face constraint may be placed on `face`.
  void check_face(int face) const;

  std::shared_ptr<const FieldOperators> ops_;
  ConstraintSet constraints_;
};

}  // namespace nfield
