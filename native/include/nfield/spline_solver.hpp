// Exact (unreduced) n-field spline solver (paper sections 5 and 7, Algorithm 1, appendix B).
//
// Let E_m be the energy matrix of order m, M the mass matrix, u' the alignment field and
// V = E_m - lambda M. Hard constraints are real rows D z = h (constraints.hpp). The solver factors V once
// (complex Hermitian, CHOLMOD supernodal) and caches, per constrained face f, the column
// G_f = V^-1 e_f (one complex back-substitution gives both real columns V^-1 e_2f and V^-1 e_2f+1 = i G_f).
// A solve is then the small dense Schur system (eq. 13)  (D V^-1 D^T) gamma = D V^-1 b - h  and the
// combination w = V^-1 b - V^-1 D^T gamma (eq. 14), with no sparse solve unless a new face appears.
//
// n-direction splines (eq. 9/12): b = M u' where u' is the alignment field with u'_f = s_f d_f at
// direction-constrained faces, s_f = 100 s_0 Abar / A_f (s_0 the RMS magnitude of the alignment field,
// 1 without one; Abar the mean face area), so each constraint weighs like 100 average aligned faces
// whatever its own size; lambda < 0. As the conventions note warns, s alone cannot settle the sign
// for higher orders (the solution is linear in s when there is no alignment), hence the pinning below.
// The +d orientation is guaranteed: after the solve, every direction-constrained face whose w_f points
// along -d (or vanishes) is pinned: its constraint becomes the n-vector constraint w_f = m d_f, with m
// the median magnitude of the correctly oriented constrained faces, and the Schur system is solved again
// (no new sparse solve). Pinned faces are reported in sign_fixed_faces().
// n-vector splines (eq. 8/11): minimize E_m(z) + mu |z - u'|_M^2 subject to the rows; V = E_m + mu M,
// b = mu M u', so lambda = -mu.
//
// Strength (user-facing, > 0) -> lambda: lambda = -strength * (4 pi / area)^m. The unit (4 pi/A)^m is
// the m-th power of the first eigenvalue scale of a round sphere of the same area, so a strength means
// the same on a mesh scaled by 1000 (lambda scales like the spectrum, 1/length^2m) and under refinement
// (the spectrum converges). Larger strength = closer alignment. Admissible lambda is (-inf, lambda_hat_1^m)
// (appendix B); we expose only lambda < 0, which keeps V positive definite on every mesh, including
// meshes whose connection has trivial holonomy (there lambda_1 = 0). Strength is limited to [1e-6, 1e6]:
// below, V is so close to singular on such meshes that the Schur complement loses the constraints'
// accuracy. Without an alignment field an n-vector spline uses mu = 1e-2 (4 pi/A)^m, i.e. eq. 8 with
// u' = 0 and a small weight: it fixes the kernel of flat meshes (a 1% pull toward zero where the spectrum
// starts at the unit). Known limit: the Schur complement goes through V, so its accuracy is about
// kappa(V)^2 eps. On meshes with a flat connection (planes, cylinders) kappa grows like (lambda_max /
// mu)^m: vector splines there are accurate to ~1e-8 for m <= 2 but only ~1e-4 for m = 3, 4.
//
// Frozen faces (local editing, committed layers; paper section 9): faces given fixed values are not
// unknowns. The system is V_UU w_U = b_U - E_UF z_F over the remaining faces U, so only faces within the
// energy's stencil (order m: dual m-ring) of U matter, and the output copies every frozen value
// bit-identically. With m >= 2 the free field joins the frozen one with a continuous derivative.
//
// Accuracy: every solve with V is followed by one step of iterative refinement (x += V^-1 (b - V x)),
// which keeps constraints exact to ~1e-12 even where V is ill-conditioned (flat or cylindrical meshes,
// whose connection has a kernel, with small lambda).
//
// A connected component that receives no data (zero alignment there, no constraint on it) is filled
// with its smoothest field; a component whose only constraints are homogeneous (singularities without
// alignment) gets the smoothest field under those constraints by inverse iteration from its smoothest
// field.
#pragma once
#include <Eigen/CholmodSupport>
#include <memory>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "nfield/constraint_system.hpp"
#include "nfield/constraints.hpp"
#include "nfield/operators.hpp"
#include "nfield/spectrum.hpp"

namespace nfield {

enum class SplineKind { Direction, Vector };

constexpr double kMinStrength = 1e-6, kMaxStrength = 1e6;
constexpr double kVectorRegularisation = 1e-2;  ///< mu / (4 pi/A)^m of n-vector splines without alignment

/// lambda = -strength * (4 pi / area)^order; ParameterError unless strength is finite and > 0.
double strength_to_lambda(const FieldOperators& ops, int order, double strength);

class ExactSolver : public ConstraintEditor {
 public:
  /// `alignment` per face (size num_faces) or empty for none. Factors V (the expensive step).
  /// `lambda_override` (if finite) replaces the strength mapping (expert use, tests); it must keep V
  /// positive definite, otherwise SolverError.
  /// `frozen`: (face, value) pairs held fixed (see above); ConstraintError for inactive/out-of-range faces.
  ExactSolver(std::shared_ptr<const FieldOperators> ops, int order, double strength, const ComplexVector& alignment,
              SplineKind kind, double lambda_override = std::numeric_limits<double>::quiet_NaN(),
              const ProgressCallback& progress = {}, const std::vector<std::pair<int, Complex>>& frozen = {});

  const FieldOperators& operators() const { return *ops_; }
  int order() const { return order_; }
  SplineKind kind() const { return kind_; }
  double lambda() const { return lambda_; }

  // Constraint editing (set_direction_constraint, set_vector_constraint, remove_constraint, set_singularity,
  // remove_singularity, clear_constraints, constraints): ConstraintEditor (constraint_system.hpp); faces
  // frozen here are refused.

  /// The raw solution w per face (not normalized; zero on inactive faces).
  ComplexVector solve();
  /// Faces whose direction constraint had to be pinned (see above) in the last solve.
  const std::vector<int>& sign_fixed_faces() const { return sign_fixed_; }
  /// Number of cached columns G_f (for diagnostics and benchmarks).
  size_t num_cached_columns() const { return columns_.size(); }
  /// Number of unknowns of the factored system (active faces that are not frozen).
  int num_unknowns() const { return static_cast<int>(face_of_unknown_.size()); }
  bool face_frozen(int face) const { return frozen_index_.count(face) > 0; }

 private:
  bool face_fixed(int face) const override { return !unknown_of_face_.empty() && frozen_index_.count(face) > 0; }
  void ensure_columns(const std::vector<int>& faces);
  /// A field kept as base + sum_f coefficient_f G_f, so that constraint updates touch only a few
  /// values and the full vector is assembled once, in a single pass over the cached columns.
  struct Response {
    const ComplexVector* base;
    std::unordered_map<int, Complex> coefficient;  ///< face -> weight of G_f
    Complex at(const ExactSolver& s, int face) const;
    ComplexVector assemble(const ExactSolver& s) const;
  };
  Response schur_solve(const std::vector<ConstraintRow>& rows, const Response& y) const;
  /// ConstraintError naming the singularities (and constrained faces on their rings) whose ring rows the
  /// solution violates: contradictory constraints the rank test missed (see the .cpp).
  void check_rows_hold(const ComplexVector& w) const;  ///< w per unknown, before snapping
  /// ConstraintError if a pinned singularity did not come out with its index (field per face).
  void check_singularity_indices(const ComplexVector& field) const;
  [[noreturn]] void throw_contradictory(const std::set<std::string>& names, const std::string& note) const;
  ComplexVector apply_inverse(const ComplexVector& b) const;

  ComplexVector to_faces(const ComplexVector& per_unknown) const;

  std::vector<int> unknown_of_face_, face_of_unknown_;  ///< this system's unknowns (active, not frozen)
  Eigen::VectorXd mass_;                                ///< face areas per unknown
  std::vector<std::pair<int, Complex>> frozen_;
  std::unordered_map<int, size_t> frozen_index_;
  ComplexSparse system_;                                ///< V_UU, kept for iterative refinement
  int order_;
  SplineKind kind_;
  double lambda_;
  ComplexVector alignment_;  ///< per unknown
  double spike_ = 1.0;       ///< s of the +d safeguard
  Eigen::CholmodSupernodalLLT<ComplexSparse, Eigen::Lower> factor_;
  ComplexVector base_response_;  ///< V^-1 b for the unmodified alignment (per unknown)
  std::unordered_map<int, ComplexVector> columns_;  ///< face -> G_f = V^-1 e_f (per unknown)
  std::vector<int> sign_fixed_;
  std::vector<bool> component_has_alignment_;
  ComplexVector smoothest_;  ///< lazily computed per-face smoothest field (component fill)
};

}  // namespace nfield
