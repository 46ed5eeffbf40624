// Factorization of the shifted operator S - sigma M of the eigenproblem S z = lambda M z, for the
// shift-invert iterations of the spectral basis (slice_lanczos.hpp, spectrum_slicing.hpp).
//
// Two factorizations (CHOLMOD through Eigen):
//   definite:   sigma below the spectrum (S - sigma M positive definite): supernodal LL^H.
//   indefinite: any sigma: simplicial LDL^H,  P (S - sigma M) P^T = L D L^H,  L unit lower triangular,
//               D real diagonal, P the fill-reducing permutation. No pivoting for stability: a zero pivot
//               (sigma on an eigenvalue of a leading block) makes factor() return false and the caller
//               moves sigma slightly.
// Inertia (Sylvester's law): S - sigma M and D are congruent, so the number of negative entries of D is
// the number of eigenvalues lambda < sigma, counted with multiplicity. This count is exact whatever the
// conditioning (only the signs of the pivots matter), which is what makes spectrum slicing reliable.
//
// The sparsity pattern is analysed once; factor(sigma) only rewrites the diagonal (S_jj - sigma m_j) and
// refactors numerically, so one object serves every shift of a slice sequence.
#pragma once
#include <Eigen/CholmodSupport>
#include <Eigen/Core>
#include <vector>

#include "nfield/operators.hpp"

namespace nfield {

class ShiftedFactor {
 public:
  /// Analyses the pattern of S (Hermitian, lower triangle used; every diagonal entry structurally
  /// present, else SolverError). `definite` selects LL^H (sigma below the spectrum) or LDL^H (any sigma).
  ShiftedFactor(const ComplexSparse& S, const Eigen::VectorXd& mass, bool definite);

  /// Factors S - sigma M. Returns false if the factorization broke down (zero pivot, or not positive
  /// definite in the definite mode).
  bool factor(double sigma);
  double sigma() const { return sigma_; }
  bool definite() const { return definite_; }

  /// Threads of the blocked LDL^H solve (1 or 2): 1 when the caller already runs one solve per core.
  void set_solve_threads(int threads) { solve_threads_ = threads; }

  /// The number of eigenvalues lambda < sigma (negative pivots of D; LDL^H mode only, else SolverError).
  int negative_pivots() const { return ldl_.negative_pivots(); }

  /// X = (S - sigma M)^-1 B for a block of right-hand sides. Not reentrant (uses internal buffers).
  void solve_into(const Eigen::MatrixXcd& B, Eigen::MatrixXcd& X) const;

 private:
  /// The LDL^H solve, blocked: CHOLMOD solves one column at a time; this reads L once per group of 8
  /// columns (right-hand sides stored row-major) and splits the columns over two threads, which makes
  /// it several times faster for the blocks of the Lanczos iteration.
  void ldl_solve(const Eigen::MatrixXcd& B, Eigen::MatrixXcd& X) const;

  /// Eigen's simplicial LDL^H with access to CHOLMOD's factor (L and D in one array, D on the column heads).
  struct LDL : Eigen::CholmodSimplicialLDLT<ComplexSparse, Eigen::Lower> {
    const cholmod_factor* factor() const { return this->m_cholmodFactor; }
    int negative_pivots() const;
  };

  ComplexSparse A_;                   ///< S - sigma M (pattern of S, diagonal rewritten by factor())
  std::vector<int> diag_;             ///< position of A_jj in A_'s value array
  std::vector<Complex> base_diag_;    ///< S_jj
  Eigen::VectorXd mass_;
  bool definite_;
  double sigma_ = 0;
  Eigen::CholmodSupernodalLLT<ComplexSparse, Eigen::Lower> llt_;
  LDL ldl_;
  mutable std::vector<double> buffer_[2];  ///< per-thread right-hand-side blocks of ldl_solve
  int solve_threads_ = 2;
};

}  // namespace nfield
