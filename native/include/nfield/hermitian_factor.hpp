// Cholesky factorization V = P^T L L^H P of a sparse complex Hermitian positive definite matrix (CHOLMOD,
// supernodal; P the fill-reducing permutation) and the solves the spline solver needs:
//
//   solve(b)              x = V^-1 b, refined until accurate (see below). One forward and one backward
//                         substitution per step; for a sparse b the first forward one only on the supernodes b
//                         reaches (forward() below).
//   solve_block(B)        V^-1 B for a dense block: one blocked CHOLMOD solve (BLAS 3 on every supernode).
//   forward(columns)      h_j = L^-1 P b_j for sparse b_j, restricted to the supernodes b_j reaches in the
//                         elimination tree (the path from b_j's supernodes to the root: 5-16% of L per column
//                         on the bunny and the armadillo), and the Gram matrix (h_i^H h_j) = (b_i^H V^-1 b_j).
//                         This is what the constraint (Schur) system needs, at a fraction of a solve.
//   backward(h)           P^T L^-H h: with forward(), V^-1 b_j as a dense block (one blocked CHOLMOD
//                         backward substitution).
//
// Accuracy. A Cholesky solve is backward stable: the residual b - V x is ~eps |V| |x|, so the error of x is
// about kappa eps (kappa the condition number): 1e-6 at order 4 on a flat mesh (kappa ~1e10), too much for the
// exact spline. The measured error of a solve is ~3 condition_estimate() eps (the spread of the pivots of L,
// squared: 1.9e-10 for an estimate of 2.8e5 on the bunny at order 2, 1.7e-11 for 6.3e4). solve() therefore
// refines when that predicts an error above ~1e-9, condition_estimate() > kRefineCondition, or when the double
// residual exceeds kRefineThreshold |b|: r = b - V x accumulated in long double
// (80-bit, 64-bit mantissa), x += V^-1 r, until the correction is below kConverged |x| (at most kMaxRefinements
// steps). The residual of a double x cannot get below ~eps |V| |x|, but its error can: each step multiplies it by
// ~kappa eps, and the last correction bounds the error left before it, so what remains is ~kConverged kappa eps,
// far below 1e-10 while kappa < 1e13. Order 3-4 splines on flat and developable meshes (kappa 1e8-1e11) come
// out accurate to ~1e-10 and better instead of ~1e-6 (and ~1e-4 with the old regularised system).
//
// Not thread-safe: the solves reuse CHOLMOD's workspace. Errors: SolverError (not positive definite, CHOLMOD
// failure), MemoryLimitError (memory_guard.hpp) before a factor that would not fit.
#pragma once
#include <cholmod.h>

#include <string>
#include <utility>
#include <vector>

#include "nfield/operators.hpp"

namespace nfield {

/// A sparse vector: (index, value) pairs (indices into the matrix' rows, distinct).
using SparseColumn = std::vector<std::pair<int, Complex>>;

class HermitianFactor {
 public:
  static constexpr double kRefineThreshold = 1e-10;  ///< max|b - V x| / max|b| above which solve() refines
  static constexpr double kRefineCondition = 1e6;    ///< condition_estimate() above which solve() refines
  static constexpr double kConverged = 1e-10;        ///< max|correction| / max|x| at which refinement stops
  static constexpr int kMaxRefinements = 4;
  /// solve() substitutes forward only on the supernodes b reaches when b has fewer than n / kSparseFraction entries.
  static constexpr int kSparseFraction = 16;
  /// Systems with fewer unknowns are factored with single-threaded BLAS (see the constructor).
  static constexpr int kThreadedFactorizationSize = 20000;

  /// Analyzes and factors `matrix` (both triangles stored; the lower one is read). `what` names the system
  /// in messages ("the factorization of the order-2 system (69451 faces)"), `advice` says what needs less
  /// memory. SolverError if the matrix is not positive definite.
  HermitianFactor(const ComplexSparse& matrix, const std::string& what, const std::string& advice);
  ~HermitianFactor();
  HermitianFactor(const HermitianFactor&) = delete;
  HermitianFactor& operator=(const HermitianFactor&) = delete;

  int size() const { return n_; }
  /// (max_j L_jj / min_j L_jj)^2: a lower bound of the condition number of V (the pivots of a Cholesky
  /// factorization lie between V's smallest and largest eigenvalue), computed once.
  double condition_estimate() const { return condition_estimate_; }
  const ComplexSparse& matrix() const { return matrix_; }

  /// V^-1 b, refined (see the header comment). `refinements` (if given) receives the number of steps taken.
  /// `refine` = false: one solve, no check (a probe).
  ComplexVector solve(const ComplexVector& b, int* refinements = nullptr) const;
  /// Whether solve() refines a solution x of V x = b (see the header comment).
  bool needs_refinement(const ComplexVector& b, const ComplexVector& x) const {
    return condition_estimate_ > kRefineCondition || relative_residual(b, x) > kRefineThreshold;
  }
  /// V^-1 B, one blocked solve, no refinement.
  Eigen::MatrixXcd solve_block(const Eigen::MatrixXcd& B) const;

  /// Forward substitutions of sparse right-hand sides (see the header comment).
  struct Forward {
    Eigen::MatrixXcd h;     ///< n x k, h_j = L^-1 P b_j (zero outside the supernodes b_j reaches)
    Eigen::MatrixXcd gram;  ///< k x k, gram(i, j) = h_i^H h_j = b_i^H V^-1 b_j
  };
  /// `keep_h` = false: only the Gram matrix (h stays empty; h is then never stored whole, only on the supernodes
  /// each column reaches).
  Forward forward(const std::vector<SparseColumn>& columns, bool keep_h = true) const;
  /// P^T L^-H h for a block in the permuted space of forward(): V^-1 b_j column by column.
  Eigen::MatrixXcd backward(const Eigen::MatrixXcd& h) const;

  /// One refinement step for a block of solutions X of V X = B (residual in long double): X += V^-1 (B - V X).
  /// Returns the size of the correction, max|dX| / max|X|.
  double refine_block(const Eigen::MatrixXcd& B, Eigen::MatrixXcd& X) const;
  /// max|B - V X| / max|B| for one column (largest real or imaginary part), computed in double (a cheap
  /// accuracy probe).
  double relative_residual(const ComplexVector& b, const ComplexVector& x) const;

 private:
  Eigen::MatrixXcd cholmod_solve_dense(int system, const Eigen::MatrixXcd& B) const;
  /// V^-1 b by one forward and one backward substitution (forward() for a sparse b, see kSparseFraction).
  ComplexVector unrefined_solve(const ComplexVector& b) const;
  /// B - V X with every product accumulated in long double, rounded to double at the end.
  Eigen::MatrixXcd extended_residual(const Eigen::MatrixXcd& B, const Eigen::MatrixXcd& X) const;

  int n_ = 0;
  ComplexSparse matrix_;  ///< V (kept for residuals)
  mutable cholmod_common common_;
  cholmod_factor* factor_ = nullptr;
  // Supernodal structure, for forward(): supernode of each (permuted) column, parent supernode (-1: root),
  // inverse permutation (row of A -> row of P A P^T).
  std::vector<int> supernode_of_, parent_, inverse_perm_;
  double condition_estimate_ = 1.0;
};

}  // namespace nfield
