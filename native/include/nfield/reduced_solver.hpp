// Reduced (spectral) n-field spline solver for real-time editing (paper section 8, eqs. 16-18).
//
// API (for the binding):
//   ReducedSolver(ops, basis, order, strength, alignment, kind[, lambda_override])
//       ops: shared FieldOperators; basis: shared SpectralBasis of the same operators (ParameterError
//       otherwise); order m in 1..4; strength -> lambda as ExactSolver (strength_to_lambda; lambda = 0 for
//       vector splines without alignment, see "Vector splines without alignment" below); alignment per face
//       or empty.
//   set_strength(s) / set_lambda(l)    only the k-vector Lambda changes: no factorization, O(k R^2).
//   set_alignment(field)               one projection U^H M u' (O(N k), ~10-50 ms for N=86k, k=500).
//   set_direction_constraint(face, d), set_vector_constraint(face, value), remove_constraint(face),
//   set_singularity(vertex, N), remove_singularity(vertex), clear_constraints(), constraints()
//                                      same semantics and errors as ExactSolver (frozen faces: none).
//   solve_coefficients() -> x (size k) the reduced solution (no reconstruction), O(k R^2 + R^3).
//   solve() -> w per face (size num_faces) = U x, constrained faces snapped onto their constraint.
//   reconstruct(x) -> per face.  sign_fixed_faces(), constraint_residual().
//   low_pass(ops, basis, field per face) -> U U^H M field per face (free function).
//
// Method. With U the M-orthonormal eigenvectors of S (eigenvalues nu_i), E_m = S (M^-1 S)^(m-1) is
// diagonal in the basis: U^H (E_m - lambda M) U = Lambda = diag(nu_i^m - lambda) (> 0 for lambda < 0).
// A constraint row l(z) = sum_k Re(conj(c_k) z_{f_k}) becomes, for z = U x, l = Re(g^H x) with
// g = sum_k c_k conj(U[f_k, :])^T = U^H d (O(k) per row: only the rows of U at 1-2 faces are read; they
// are cached per face). The reduced problem is the exact solver's Schur complement (eqs. 13-14) with
// V^-1 -> Lambda^-1 (eqs. 16-18):
//   y = Lambda^-1 b_U, b_U = U^H b (b = M u' for direction splines, mu M u' for vector splines),
//   K = Re(G^H Lambda^-1 G) (R x R, real), K gamma = Re(G^H y) - h, x = y - Lambda^-1 G gamma.
// The +d safeguard is the exact solver's: the alignment gets s_f d_f at direction-constrained faces
// (O(k) per face), then every direction-constrained face whose value points along -d is pinned to the
// n-vector constraint w_f = m d_f (m the median along-d magnitude of the right ones); no factorization.
// Constraints that are independent on the mesh can be dependent in a small basis (two constraints on
// neighbouring faces with small k): K is then solved in the least-squares sense (eigenvalues below
// 1e-10 max dropped) and constraint_residual() reports how far the rows are from holding
// (max |l(z) - h|, relative to the largest constrained value). With k large enough it is ~1e-12.
// Without any data (no alignment, only homogeneous constraints such as singularities) the solution is
// the smoothest field under the constraints, found by inverse iteration in the basis (O(k R) per step).
// Components of a multi-component mesh without any data (no alignment, constraint or singularity) get
// their smoothest field (the restriction of the lowest basis vector living on them), scaled like the
// rest, as in the exact solver; a component no basis vector reaches (k smaller than the number of
// components) stays zero and is counted in uncovered_components(). Limits: no frozen faces.
// Vector splines without alignment: lambda = 0 (eq. 8 exactly, in the basis) when every basis eigenvalue is
// positive, nu_i^m > kReducedFlatTolerance (4 pi/A)^m. On a mesh whose connection is (nearly) flat the basis
// holds the parallel field with nu_0 ~ 0 and Lambda would be singular; the exact solver then eliminates the
// constrained faces (spline_system.hpp), which a basis cannot do, so the reduced solver keeps
// lambda = -kReducedVectorRegularisation (4 pi/A)^m there: a 1% pull toward zero, far below the reduction error.
// Measured (bench/results/spectral.md; k = 500, 30 direction constraints, loaded 2-core VM): the reduced
// update is 0.6-1.8 ms whatever the mesh size (1.1 ms at 346k faces), a strength change 0.6-1.7 ms; the
// reconstruction U x is memory-bound (it reads the whole basis): 36 ms (float32) / 72 ms (double) for
// 69k faces. Float32 storage changes the reduced solution by ~3e-7 relative (largest direction change
// 0.002 degrees), six orders below the reduction error itself.
#pragma once
#include <limits>
#include <memory>
#include <unordered_map>
#include <vector>

#include "nfield/constraint_system.hpp"
#include "nfield/constraints.hpp"
#include "nfield/spectral_basis.hpp"
#include "nfield/spline_solver.hpp"

namespace nfield {

/// See "Vector splines without alignment" above.
constexpr double kReducedFlatTolerance = 1e-6, kReducedVectorRegularisation = 1e-2;

class ReducedSolver : public ConstraintEditor {
 public:
  ReducedSolver(std::shared_ptr<const FieldOperators> ops, std::shared_ptr<const SpectralBasis> basis, int order,
                double strength, const ComplexVector& alignment, SplineKind kind,
                double lambda_override = std::numeric_limits<double>::quiet_NaN());

  const FieldOperators& operators() const { return *ops_; }
  const SpectralBasis& basis() const { return *basis_; }
  int order() const { return order_; }
  SplineKind kind() const { return kind_; }
  double lambda() const { return lambda_; }
  int size() const { return basis_->size(); }

  /// Changes the strength (lambda = strength_to_lambda); only Lambda is recomputed (O(k)).
  void set_strength(double strength);
  /// Expert: sets lambda directly; ParameterError unless every nu_i^m - lambda > 0.
  void set_lambda(double lambda);
  /// New alignment field per face (size num_faces) or empty: one projection onto the basis.
  void set_alignment(const ComplexVector& alignment);

  // Constraint editing: ConstraintEditor (constraint_system.hpp), as for ExactSolver.

  /// The reduced solution x (size k): the field is U x.
  ComplexVector solve_coefficients();
  /// The field per face (size num_faces, zero on inactive faces), constrained faces snapped.
  ComplexVector solve();
  /// U x per face (size num_faces).
  ComplexVector reconstruct(const ComplexVector& x) const;
  const std::vector<int>& sign_fixed_faces() const { return sign_fixed_; }
  /// Largest violation of a constraint row in the last solve, relative to the largest constrained value.
  double constraint_residual() const { return constraint_residual_; }
  /// Components no basis vector reaches (k too small for the number of components): their field is zero.
  int uncovered_components() const { return uncovered_components_; }

 private:
  void fill_empty_components(ComplexVector& field);
  /// Per component: does some basis vector have weight on it (computed once).
  const std::vector<bool>& covered_components();
  void update_lambda(double lambda);
  /// conj(U[f, :])^T = U^H e_f (cached).
  const ComplexVector& basis_row(int face);
  Complex value_at(const ComplexVector& x, int face);  ///< (U x)_f
  ComplexVector schur_solve(const std::vector<ConstraintRow>& rows, const ComplexVector& y);

  std::shared_ptr<const SpectralBasis> basis_;
  int order_;
  SplineKind kind_;
  double lambda_ = 0;
  Eigen::VectorXd nu_m_;      ///< nu_i^order
  Eigen::VectorXd inv_diag_;  ///< 1 / (nu_i^m - lambda)
  bool has_alignment_ = false;
  ComplexVector alignment_;      ///< per unknown
  ComplexVector projected_;      ///< U^H M u' (without the rhs scale)
  double spike_ = kSafeguardWeight;
  std::unordered_map<int, ComplexVector> rows_;  ///< face -> conj(U[f, :])^T
  std::vector<int> sign_fixed_;
  double constraint_residual_ = 0;
  int uncovered_components_ = 0;
  std::vector<bool> covered_;
  ComplexVector last_x_;
  OrientationPins pins_;  ///< pinning of the last solve (snapping in solve())
};

/// U U^H M field: the M-orthogonal projection of a per-face field (size num_faces) onto the basis.
ComplexVector low_pass(const FieldOperators& ops, const SpectralBasis& basis, const ComplexVector& field);

}  // namespace nfield
