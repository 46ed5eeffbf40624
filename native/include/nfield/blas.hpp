// Thin wrappers over the BLAS / LAPACK routines of the dense kernels (spectral basis, dense eigen path),
// on raw column-major storage, and the OpenBLAS thread guard of code that runs its own threads.
//
// The build links OpenBLAS (or the reference BLAS/LAPACK); EIGEN_USE_BLAS is deliberately not defined,
// so Eigen's own products stay Eigen's and only the calls below go to BLAS: the tall-skinny products of
// the Lanczos iteration (N x m times m x b with N >> m), the projections of the spectral basis and the
// dense Hermitian eigen-decomposition.
#pragma once
#include <complex>

#include <Eigen/Core>

namespace nfield {

/// C = alpha op(A) op(B) + beta C (zgemm) with op = 'N' (none), 'T' (transpose) or 'C' (conjugate
/// transpose); A is m x k after op, B is k x n after op, leading dimensions lda, ldb, ldc. Does nothing
/// for m <= 0 or n <= 0; for k <= 0 scales C by beta (without relying on BLAS's handling of k = 0).
void gemm(char ta, char tb, int m, int n, int k, std::complex<double> alpha, const std::complex<double>* a, int lda,
          const std::complex<double>* b, int ldb, std::complex<double> beta, std::complex<double>* c, int ldc);

/// B = alpha op(A)^-1 B (ztrsm, side 'L'): A is m x m lower ('L') or upper ('U') triangular with leading dimension
/// lda, op = 'N', 'T' or 'C', diag 'N' (or 'U' for a unit diagonal); B is m x n with leading dimension ldb.
/// Does nothing for m <= 0 or n <= 0.
void trsm_left(char uplo, char trans, char diag, int m, int n, std::complex<double> alpha, const std::complex<double>* a,
               int lda, std::complex<double>* b, int ldb);

/// y = op(A) x (zgemv / cgemv) for a column-major m x n matrix A (leading dimension m), op = 'N' or 'C'.
void gemv(char t, int m, int n, const std::complex<double>* a, const std::complex<double>* x, std::complex<double>* y);
void gemv(char t, int m, int n, const std::complex<float>* a, const std::complex<float>* x, std::complex<float>* y);

/// Eigen-decomposition A = Q diag(w) Q^H of a Hermitian matrix (LAPACK zheevd, divide and conquer; only
/// the lower triangle is read). Eigenvalues w ascending; A is overwritten by the orthonormal eigenvectors
/// Q (column j belongs to w[j]). SolverError if LAPACK reports a failure.
void hermitian_eigen(Eigen::MatrixXcd& a, Eigen::VectorXd& w);

/// Single-threaded OpenBLAS for the lifetime of the object (no effect with other BLAS implementations),
/// for code that runs its own threads: OpenBLAS threads on top of them oversubscribe the cores (and spin),
/// which costs far more than it gains on the thin matrix products of the Lanczos iteration; and for the
/// solves after a factorization, whose BLAS calls are too small to share (one column, or a few dozen on
/// the supernodes a constraint reaches). Guards may overlap in several threads: the thread count found by
/// the first is restored when the last one is destroyed.
class SingleThreadedBlas {
 public:
  SingleThreadedBlas();
  ~SingleThreadedBlas();
  SingleThreadedBlas(const SingleThreadedBlas&) = delete;
  SingleThreadedBlas& operator=(const SingleThreadedBlas&) = delete;

 private:
  bool active_ = false;  ///< OpenBLAS is there and this guard counts
};

}  // namespace nfield
