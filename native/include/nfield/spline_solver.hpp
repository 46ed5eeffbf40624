// Exact (unreduced) n-field spline solver (paper sections 5 and 7, Algorithm 1, appendix B).
//
// The problem. E_m is the energy matrix of order m, M the mass matrix, u' the alignment field, V = E_m - lambda M.
//   n-vector spline (eq. 8/11):     minimise E_m(z) + mu |z - u'|^2_M,  mu = -lambda; b = mu M u'.
//                                   Without alignment mu = 0 (lambda = 0): eq. 8 exactly, no regularisation.
//   n-direction spline (eq. 9/12):  (E_m - lambda M) w = M u' + D^T gamma, lambda < 0; b = M u'.
// subject to hard constraints: n-vector constraints u_f = d_f, and real rows D z = h (constraints.hpp):
// direction constraints <u_f, J d_f> = 0, singularity rings (eq. 10, corrected), pinned faces (below).
//
// How it is solved (one place per step; this is the order of ExactSolver::solve):
//  1. The system (spline_system.hpp, assemble_spline_system): faces with given values are not unknowns. Those
//     are frozen faces (local editing) and "anchor" faces: n-vector constraints eliminated by substitution
//     (their value moves to the right-hand side, -V_UF z_F). The free block V_UU is positive definite whenever
//     each component holds a fixed face, also for lambda = 0 on flat and developable meshes, where E_m itself
//     has the parallel field in its kernel. Components without a fixed face are shifted when lambda = 0 (see
//     spline_system.hpp: exact, because such a component receives no data).
//  2. The factorization V_UU = P^T L L^H P (hermitian_factor.hpp), once per solver.
//  3. Constraint rows act through the Schur complement (eqs. 13-14): K gamma = D y - h with K = D V^-1 D^T,
//     y = V^-1 b, then w = y - V^-1 D^T gamma. A row's terms on fixed faces are known and move to its
//     right-hand side; a row left without unknowns must hold by itself (else: contradictory constraints).
//     The entries of V^-1 that K needs come from one of two places:
//       cached columns  G_f = V^-1 e_f per constrained face (and V^-1 V_UF e_a per anchor), kept between solves:
//                       re-aiming a constraint needs no sparse solve at all (O(columns)), a new face one
//                       column. New columns are computed together: forward substitutions restricted to the
//                       elimination-tree paths of their faces, then one blocked backward substitution.
//       direct solve    the Gram matrix of the forward substitutions (K exactly, at 5-16% of a solve per
//                       face), y at the constrained faces from the same substitutions (b as one more sparse
//                       right-hand side), w by one solve of b - D^T gamma: no column at all.
//     A one-shot solver (cache_columns = false: nfield.core.solve and the command line) always solves directly:
//     one factorization and one solve (plus a refinement step of the rows where V is ill-conditioned, see
//     refine_rows). A live solver (DesignSession) computes up to kEagerColumns new columns at once; a solve that
//     brings more new faces (the first solve of a loaded design) solves directly and leaves their columns to the
//     next solve that brings no new face (the first re-aim), which computes them in one block.
//  4. The +d safeguard (n-direction splines). u'_f = s_f d_f at direction-constrained faces (constraint_system.hpp:
//     s_f = 100 s_0 Abar / A_f). As the conventions note warns, s alone cannot settle the sign for higher orders
//     (the solution is linear in s without alignment), so after the solve every direction-constrained face whose
//     w_f points along -d (or vanishes) is pinned: its row becomes the n-vector constraint w_f = m d_f (m the
//     median magnitude of the correctly oriented faces) and the Schur system is solved again (no new sparse
//     solve). Pinned faces are reported in sign_fixed_faces().
//  5. Components. A component that receives no data (zero alignment, no inhomogeneous constraint) and has no
//     rows is filled with its smoothest field, scaled like the rest; one whose only constraints are homogeneous
//     (singularities without data) gets the smoothest field under them by inverse iteration. This is today's
//     behaviour and deliberately kept: eq. 8 without data has only the zero field as minimiser.
//  6. Checks: singularity rows on rings with a face constraint must hold (contradiction otherwise), every pinned
//     singularity must come out with its index, constrained faces are snapped onto their constraint.
//
// Anchors in a live solver. A live solver with lambda = 0 (n-vector spline without alignment) needs fixed faces
// to be positive definite on flat meshes, so DesignSession passes its vector-constrained faces as anchors.
// Vector constraints on other faces added later are rows (cached columns, no refactorization). The solver stays
// exact by refactoring itself (num_factorizations()) when an anchor loses its vector constraint or a vector
// constraint lands on a shifted component; needs_refactorization() predicts that. A one-shot solver anchors
// every vector constraint (no rows, no columns for them).
//
// Strength (user-facing, > 0) -> lambda = -strength (4 pi / area)^m. The unit is the m-th power of the first
// eigenvalue scale of a round sphere of the same area, so a strength means the same on a mesh scaled by 1000
// (lambda scales like the spectrum, 1/length^2m) and under refinement. Larger strength = closer alignment.
// Admissible lambda is (-inf, lambda_hat_1^m) (appendix B); we expose only lambda <= 0, which keeps V_UU positive
// definite on every mesh. Strength is limited to [1e-6, 1e6]: below, V is so close to singular on flat meshes
// that the direction constraints lose accuracy.
//
// Frozen faces (local editing, committed layers, live guide edits; paper section 9, frozen_faces.hpp): only faces
// within the energy's stencil (order m: dual m-ring) of the unknowns enter the system, and the output copies every
// frozen value bit-identically. With m >= 2 the free field joins the frozen one with a continuous derivative. A
// local solve of a small region in a large mesh costs the region: its rows of E_m (energy_rows.hpp), its
// factorization, and a few passes over per-face flags and values.
//
// Accuracy. Every solve is backward stable and, where V_UU is ill-conditioned, refined with residuals in extended
// precision (hermitian_factor.hpp), so the result satisfies the first-order conditions of its problem to
// rounding. n-vector splines (substitution, one solve) are accurate to 1e-10 or better at order 4 on a flat grid
// (kappa 3e10; before, ~1e-4 with a regularisation that also biased the result). With constraint rows the
// multipliers come from unrefined substitutions; refine_rows corrects the rows, and what remains is ~1e-3 kappa
// eps (tests/test_splines.py). Cached columns are refined when condition_estimate() exceeds
// kRefineColumnsCondition; a field summed from them carries the cancellation of their weights (~1e-3 kappa eps).
//
// Extending. New data enters in one of three places: the matrix and its substituted faces in
// assemble_spline_system (per-face alignment weights change the -lambda M diagonal there, and the right-hand
// side b0 in factor()); linear relations between faces (mirror symmetry, constraints across a cut) as rows of a
// ConstraintSet (constraints.hpp), which the Schur system takes as they are (solve() step 5 must also count them
// when it looks for components with rows); the connection (cuts) in operators.hpp.
//
// Guides (docs/guides.md). `alignment_weight` W >= 0 per face turns the alignment term into
// |lambda| (u - g)^H M_W (u - g): V = E_m - lambda M_W, and the alignment argument is then the weighted target
// W g (b = M W g, times -lambda for n-vector splines). set_alignment() changes the target only: the right-hand
// side, one solve, no refactorization.
// Mirror symmetry (set_symmetry, mirror.hpp): the solve is restricted to the fields with u(mirror f) =
// T_f(u(f)), T_f real-linear, by working with the projector P = (I + S) / 2 instead of 35k constraint rows: the
// right-hand side is P b, every constraint row is written symmetrically (it then also holds at the mirror
// face), and the solution V^-1 (P b - P D^T gamma) is projected with P. When V commutes with S (an exactly
// symmetric mesh) that is the exact minimiser over symmetric fields, with no new factorization; when the mesh is
// symmetric only up to the matching tolerance the projected solution is off by O(|VS - SV|^2) and a defect
// correction (the same solve for the residual P (b - V w), homogeneous rows) removes that to rounding.
// Fixed faces must come in mirror pairs: frozen faces (checked), anchors (their mirror faces are anchored with
// the mirror image of the value).
#pragma once
#include <limits>
#include <memory>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include "nfield/constraint_system.hpp"
#include "nfield/constraints.hpp"
#include "nfield/frozen_faces.hpp"
#include "nfield/hermitian_factor.hpp"
#include "nfield/mirror.hpp"
#include "nfield/operators.hpp"
#include "nfield/spectrum.hpp"
#include "nfield/spline_system.hpp"

namespace nfield {

enum class SplineKind { Direction, Vector };

constexpr double kMinStrength = 1e-6, kMaxStrength = 1e6;

/// lambda = -strength * (4 pi / area)^order; ParameterError unless strength is finite and > 0.
double strength_to_lambda(const FieldOperators& ops, int order, double strength);

class ExactSolver : public ConstraintEditor {
 public:
  /// New columns computed at once by a live solver; more new faces make a direct solve (see above).
  static constexpr size_t kEagerColumns = 4;
  /// condition_estimate() above which new columns are refined (hermitian_factor.hpp): unrefined columns would be
  /// off by more than ~1e-9. Lower thresholds cost too much: a long double residual per column and step.
  static constexpr double kRefineColumnsCondition = 1e6;

  /// `alignment` per face (size num_faces) or empty for none. Factors V (the expensive step).
  /// `lambda_override` (if finite) replaces the strength mapping (expert use, tests); it must keep V
  /// positive definite, otherwise SolverError. Without it: lambda = 0 for an n-vector spline without
  /// alignment, strength_to_lambda otherwise.
  /// `frozen`: the faces held fixed at their values (frozen_faces.hpp: listed, or the complement of a region).
  /// `anchors`: faces whose n-vector constraints are eliminated (see above); ConstraintError for inactive,
  /// out-of-range, frozen or repeated faces. `cache_columns` = false: a one-shot solver (direct solves).
  /// `alignment_weight`: W per face (>= 0, finite; empty: 1 everywhere), see "Guides" above.
  ExactSolver(std::shared_ptr<const FieldOperators> ops, int order, double strength, ComplexVector alignment,
              SplineKind kind, double lambda_override = std::numeric_limits<double>::quiet_NaN(),
              const ProgressCallback& progress = {}, FrozenFaces frozen = {},
              const std::vector<int>& anchors = {}, bool cache_columns = true,
              Eigen::VectorXd alignment_weight = Eigen::VectorXd());

  const FieldOperators& operators() const { return *ops_; }
  int order() const { return order_; }
  SplineKind kind() const { return kind_; }
  double lambda() const { return lambda_; }

  // Constraint editing (set_direction_constraint, set_vector_constraint, remove_constraint, set_singularity,
  // remove_singularity, clear_constraints, constraints): ConstraintEditor (constraint_system.hpp); faces
  // frozen here are refused.

  /// New guide target values (W g per face, or empty for none): only the right-hand side changes.
  void set_alignment(const ComplexVector& alignment);
  /// Solve on the mirror-symmetric fields of `mirror` (null: no symmetry). ConstraintError when a free face has
  /// a frozen mirror face; InputError for a map of another mesh.
  void set_symmetry(std::shared_ptr<const MirrorMap> mirror);
  bool symmetric() const { return mirror_ != nullptr; }
  /// Defect-correction steps of the last solve (0 without symmetry or on an exactly symmetric mesh).
  int symmetry_corrections() const { return symmetry_corrections_; }

  /// The raw solution w per face (not normalized; zero on inactive faces).
  ComplexVector solve();
  /// Faces whose direction constraint had to be pinned (see above) in the last solve.
  const std::vector<int>& sign_fixed_faces() const { return sign_fixed_; }
  /// Number of cached columns (for diagnostics and benchmarks).
  size_t num_cached_columns() const { return columns_.size(); }
  /// Number of unknowns of the factored system (active faces that are neither frozen nor anchors).
  int num_unknowns() const { return system_.num_unknowns(); }
  bool face_frozen(int face) const { return frozen_.held(face); }
  const std::vector<int>& anchor_faces() const { return anchors_; }
  /// Lower bound of the condition number of the factored V_UU (hermitian_factor.hpp); 1 without unknowns.
  double condition_estimate() const { return factor_ ? factor_->condition_estimate() : 1.0; }
  /// Factorizations so far (1 after construction; more when the anchors went stale, see above).
  int num_factorizations() const { return num_factorizations_; }
  /// Whether a solve with n-vector constraints on exactly `vector_faces` would refactor (see above).
  bool needs_refactorization(const std::vector<int>& vector_faces) const;

 private:
  bool face_fixed(int face) const override { return frozen_.held(face); }
  void factor(const ProgressCallback& progress);
  /// alignment_, the safeguard's s_0, the components with data, b0_ and (live) its response, from
  /// alignment_per_face_ and the current system.
  void update_alignment();
  /// P z per unknown (identity without symmetry).
  ComplexVector project(const ComplexVector& z) const;
  /// Rows written symmetrically (identity without symmetry).
  std::vector<ConstraintRow> symmetric_rows(std::vector<ConstraintRow> rows) const;
  /// Defect correction of a projected symmetric solution (see "Guides" above); rhs is the full right-hand side.
  void symmetric_refinement(ComplexVector& field, const ComplexVector& rhs, const std::vector<ConstraintRow>& rows);
  /// The faces to anchor for these vector-constrained faces: themselves and, with symmetry, their mirror faces.
  std::vector<int> anchor_closure(const std::vector<int>& vector_faces) const;
  bool stale(const std::vector<int>& vector_faces) const;
  Complex fixed_value(int face) const;  ///< frozen value or the anchor's vector constraint

  /// A field kept as base + sum_f coefficient_f R_f, R_f the response to a unit load at face f (the cached
  /// column, or V^-1 e_f through the Gram matrix in a direct solve), so that constraint updates touch only a
  /// few values and the full vector is assembled once. In a direct solve the base can be given by its
  /// right-hand side instead (rhs, base null): its values at constrained faces come from the Gram matrix and
  /// the field from one solve of rhs + sum_f coefficient_f e_f.
  struct Response {
    const ComplexVector* base = nullptr;
    const ComplexVector* rhs = nullptr;
    std::unordered_map<int, Complex> coefficient;  ///< face -> weight of R_f
  };
  Complex entry(int face, int load) const;  ///< (V^-1)_{face, load}: R_load at face
  Complex value_at(const Response& r, int face) const;
  ComplexVector assemble(const Response& r) const;
  void ensure_columns(const std::vector<int>& faces);
  /// Gram matrix of the unit loads at `faces` and, against them, of the right-hand side b (gram_rhs_).
  void compute_gram(const std::vector<int>& faces, const ComplexVector& b);
  /// Eqs. 13-14: gamma from K gamma = D y - h, w = y - V^-1 D^T gamma (as coefficients). K is returned in `K`.
  Response schur_solve(const std::vector<ConstraintRow>& rows, const Response& y, Eigen::MatrixXd& K) const;
  /// The field of unit loads sum_f a_f R_f (one solve in a direct solve, the columns otherwise).
  ComplexVector response_to(const std::unordered_map<int, Complex>& loads) const;
  /// Iterative refinement of the constraint system: while a row is violated by more than 1e-10 of its terms,
  /// K dgamma = D w - h and w -= V^-1 D^T dgamma (at most three steps). Needed where V is ill-conditioned: K
  /// and y at the constrained faces come from unrefined substitutions (~sqrt(kappa) eps), the field from
  /// refined solves.
  void refine_rows(const std::vector<ConstraintRow>& rows, const Eigen::MatrixXd& K, ComplexVector& field) const;
  /// Rows with their terms on fixed faces moved to the right-hand side; ConstraintError for a row without
  /// unknowns that does not hold.
  std::vector<ConstraintRow> free_rows(const std::vector<ConstraintRow>& rows) const;
  /// ConstraintError when the rows force every constrained face to vanish although the data reaches them
  /// (|w_f| <= 1e-9 |y_f| on all of them: e.g. two direction constraints on a singularity's ring that the
  /// ring's rotation cannot both meet): no face can then point along +d.
  void check_constrained_faces_carry_data(const Response& y, const Response& w) const;
  /// ConstraintError naming the singularities (and constrained faces on their rings) whose ring rows the
  /// solution violates: contradictory constraints the rank test missed (see the .cpp).
  void check_rows_hold(const ComplexVector& field) const;  ///< field per face, before snapping
  /// ConstraintError if a pinned singularity did not come out with its index (field per face).
  void check_singularity_indices(const ComplexVector& field) const;
  [[noreturn]] void throw_contradictory(const std::set<std::string>& names, const std::string& note) const;
  ComplexVector to_faces(const ComplexVector& per_unknown) const;

  // What the system depends on (kept to refactor when the anchors go stale).
  int order_;
  SplineKind kind_;
  double lambda_;
  bool cache_columns_;
  FrozenFaces frozen_;
  std::vector<int> anchors_;
  ComplexVector alignment_per_face_;  ///< as given (empty for none)
  Eigen::VectorXd weight_per_face_;   ///< alignment weights W as given (empty: 1)
  std::shared_ptr<const MirrorMap> mirror_;
  int symmetry_corrections_ = 0;

  // The factored system and what was derived from it.
  SplineSystem system_;
  std::unique_ptr<HermitianFactor> factor_;  ///< null when every face is fixed
  int num_factorizations_ = 0;
  ComplexVector alignment_;  ///< per unknown
  ComplexVector b0_;         ///< rhs_scale M u' - V_UF z_frozen (per unknown)
  ComplexVector base_response_;  ///< V^-1 b0 (live solvers)
  double spike_ = 1.0;           ///< s_0 of the +d safeguard
  std::unordered_map<int, ComplexVector> columns_;  ///< face -> G_f (unknown faces) or V^-1 V_UF e_a (anchors)
  std::vector<int> deferred_;                       ///< faces whose columns the last solve left out (sorted)
  std::unordered_map<int, int> gram_index_;         ///< face -> row of gram_ (direct solves)
  Eigen::MatrixXcd gram_;                           ///< (V^-1)_{fg} between the faces of gram_index_
  ComplexVector gram_rhs_;                          ///< (V^-1 b)_f for the faces of gram_index_
  bool direct_ = false;                             ///< the current solve is direct
  std::vector<int> sign_fixed_;
  std::vector<bool> component_has_alignment_;
  ComplexVector smoothest_;  ///< lazily computed per-unknown smoothest field (component fill)
};

}  // namespace nfield
