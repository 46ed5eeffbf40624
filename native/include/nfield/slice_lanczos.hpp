// Thick-restart block Lanczos (block Krylov-Schur) for the eigenpairs of S z = lambda M z near a shift
// sigma: the solver of one spectrum slice of the spectral basis (spectrum_slicing.hpp).
//
// Operator. With D = M^1/2 and the factor of S - sigma M (shifted_factor.hpp), the iteration runs on
//     T = D (S - sigma M)^-1 D,
// which is Hermitian (possibly indefinite) with eigenpairs (theta, y) = (1 / (lambda - sigma), D z): the
// eigenvalues of the pencil nearest sigma become the largest |theta|, which Lanczos finds first.
//
// Iteration. An orthonormal Krylov basis V (N x m, m a multiple of the block size b) with T V_m =
// V_{m+b} H (H (m+b) x m, the upper block Hessenberg projection) is grown block by block; every new block is
// orthogonalized against V twice (classical Gram-Schmidt twice, CGS2: one pass loses orthogonality once Ritz
// vectors converge, and the loss grows with every restart) and orthonormalized by SVQB (the eigen-
// decomposition of its Gram matrix; dependent directions are replaced by fresh random ones). When V is
// full, the Rayleigh-Ritz step diagonalizes the Hermitian part of H_m: Ritz values theta_i, Ritz vectors
// V y_i, ordered by decreasing |theta| (nearest sigma first). The residual of a Ritz pair is
// ||T V y - theta V y|| = ||H_{m+1,:} y|| (the coupling block), and a pair counts as converged when
//     ||H_{m+1,:} y|| <= tol |theta|.
// Thick restart (Krylov-Schur): V keeps the best Ritz vectors and the residual block; H becomes diagonal
// (the kept theta) plus the coupling row, and the iteration continues from there.
//
// What is wanted. Either the `count` eigenvalues in [lo, hi), where count is known exactly from the
// inertia (shifted_factor.hpp): the iteration runs until exactly that many converged Ritz values lie in
// the interval, so an eigenvalue that the Krylov space missed (a tight cluster) is not silently lost: when
// every wanted pair has converged and the interval still misses some, the iteration keeps the converged
// pairs and restarts from a fresh random block orthogonal to them. Or (lo = -inf, hi = +inf) the `count`
// eigenvalues nearest sigma.
//
// Output: lambda = sigma + 1 / theta ascending and z = D^-1 V y, M-orthonormal up to the convergence
// tolerance. Deterministic for a given seed (the random start blocks).
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <random>

#include "nfield/shifted_factor.hpp"
#include "nfield/spectrum.hpp"

namespace nfield {

class SliceLanczos {
 public:
  /// `factor` holds S - sigma M factored at the slice's shift; `d` = M^1/2 (per unknown). `count` pairs are
  /// wanted (see above) with blocks of `block` vectors, relative tolerance `tol`, at most `max_restarts`
  /// restarts (SolverError beyond). `report(fraction)` is called after every block (it may throw, e.g.
  /// Cancelled, to stop). ParameterError if the Krylov space needed for `count` pairs does not fit in N
  /// unknowns; SolverError if its memory cannot be allocated.
  SliceLanczos(const ShiftedFactor& factor, const Eigen::VectorXd& d, double lo, double hi, int count, int block,
               double tol, int max_restarts, std::function<void(double)> report, std::uint64_t seed);

  /// Runs the iteration: the `count` wanted eigenpairs, eigenvalues ascending, vectors M-orthonormal.
  Eigenpairs run();

  int restarts() const { return restarts_; }  ///< thick restarts done by run()
  int solves() const { return solves_; }      ///< right-hand sides solved with the factor

 private:
  double lambda_of(double theta) const { return sigma_ + 1.0 / theta; }
  bool in_interval(double theta) const {
    const double l = lambda_of(theta);
    return l >= lo_ && l < hi_;
  }

  /// Block [cur, cur + b): T applied to a random block, orthonormalized against V[0, cur).
  void start_block(int cur);
  /// D (S - sigma M)^-1 D X for X with `cols` columns starting at x (leading dimension N), into out.
  void apply(const Complex* x, int cols, Eigen::MatrixXcd& out);
  /// W -= V_j (V_j^H W), twice (CGS2); returns the accumulated coefficients V_j^H W.
  Eigen::MatrixXcd orthogonalize_against(Eigen::MatrixXcd& W, int j);
  /// Orthonormalizes the columns of W (already orthogonal to V_j) in place by SVQB; returns R with
  /// W_in = W_out R. Numerically dependent directions are replaced by random vectors orthogonal to
  /// V_j and the rest (their rows of R are zero).
  Eigen::MatrixXcd orthonormalize(Eigen::MatrixXcd& W, int j);
  /// V[:, 0:keep] = V[:, 0:cur] Y[:, 0:keep], in place by row chunks.
  void rotate(const Eigen::MatrixXcd& Y, int cur, int keep);

  const ShiftedFactor& factor_;
  int N_, b_, count_, want_ = 0, m_ = 0;
  double tol_;
  int max_restarts_;
  double sigma_, lo_, hi_;
  Eigen::VectorXd d_;
  std::function<void(double)> report_;
  std::mt19937_64 rng_;
  Eigen::MatrixXcd V_, H_, work_, work2_, rhs_;
  int restarts_ = 0, solves_ = 0;
};

}  // namespace nfield
