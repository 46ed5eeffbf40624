#include "nfield/spectral_basis.hpp"

#include "nfield/memory_guard.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <new>
#include <random>
#include <atomic>
#include <memory>
#include <thread>
#include <exception>
#include <cstdlib>

#include "nfield/errors.hpp"

// BLAS / LAPACK (linked by the build: OpenBLAS or the reference implementation).
extern "C" {
void zgemm_(const char* ta, const char* tb, const int* m, const int* n, const int* k, const nfield::Complex* alpha,
            const nfield::Complex* a, const int* lda, const nfield::Complex* b, const int* ldb,
            const nfield::Complex* beta, nfield::Complex* c, const int* ldc);
void zgemv_(const char* t, const int* m, const int* n, const nfield::Complex* alpha, const nfield::Complex* a,
            const int* lda, const nfield::Complex* x, const int* incx, const nfield::Complex* beta,
            nfield::Complex* y, const int* incy);
void cgemv_(const char* t, const int* m, const int* n, const std::complex<float>* alpha,
            const std::complex<float>* a, const int* lda, const std::complex<float>* x, const int* incx,
            const std::complex<float>* beta, std::complex<float>* y, const int* incy);
void zheevd_(const char* jobz, const char* uplo, const int* n, nfield::Complex* a, const int* lda, double* w,
             nfield::Complex* work, const int* lwork, double* rwork, const int* lrwork, int* iwork,
             const int* liwork, int* info);
}

// OpenBLAS thread control, weak: absent with other BLAS implementations.
extern "C" {
void openblas_set_num_threads(int) __attribute__((weak));
int openblas_get_num_threads(void) __attribute__((weak));
}

namespace nfield {
namespace {

/// Single-threaded BLAS for the lifetime of the object (OpenBLAS only), for code that runs its own
/// threads: OpenBLAS threads on top of them oversubscribe the cores (and spin), which costs far more
/// than it gains on the thin matrix products of the Lanczos iteration.
struct SingleThreadedBlas {
  int saved = 0;
  SingleThreadedBlas() {
    if (openblas_get_num_threads != nullptr && openblas_set_num_threads != nullptr) {
      saved = openblas_get_num_threads();
      if (saved > 1) openblas_set_num_threads(1);
    }
  }
  ~SingleThreadedBlas() {
    if (saved > 1) openblas_set_num_threads(saved);
  }
  SingleThreadedBlas(const SingleThreadedBlas&) = delete;
  SingleThreadedBlas& operator=(const SingleThreadedBlas&) = delete;
};

using Eigen::MatrixXcd;
using Eigen::VectorXd;

/// C = alpha op(A) op(B) + beta C on raw column-major storage.
void gemm(char ta, char tb, int m, int n, int k, Complex alpha, const Complex* a, int lda, const Complex* b, int ldb,
          Complex beta, Complex* c, int ldc) {
  if (m <= 0 || n <= 0) return;
  if (k <= 0) {  // BLAS would scale C by beta; do it here to avoid relying on k = 0 handling
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < m; ++i) c[i + static_cast<std::ptrdiff_t>(j) * ldc] *= beta;
    return;
  }
  zgemm_(&ta, &tb, &m, &n, &k, &alpha, a, &lda, b, &ldb, &beta, c, &ldc);
}

/// Eigen-decomposition of a Hermitian matrix (LAPACK zheevd), eigenvalues ascending. A is overwritten
/// by the eigenvectors.
void hermitian_eigen(MatrixXcd& a, VectorXd& w) {
  const int n = static_cast<int>(a.rows());
  w.resize(n);
  if (n == 0) return;
  int lwork = -1, lrwork = -1, liwork = -1, info = 0;
  Complex wq;
  double rq;
  int iq;
  const char jobz = 'V', uplo = 'L';
  zheevd_(&jobz, &uplo, &n, a.data(), &n, w.data(), &wq, &lwork, &rq, &lrwork, &iq, &liwork, &info);
  lwork = static_cast<int>(wq.real()) + 1;
  lrwork = static_cast<int>(rq) + 1;
  liwork = iq + 1;
  std::vector<Complex> work(lwork);
  std::vector<double> rwork(lrwork);
  std::vector<int> iwork(liwork);
  zheevd_(&jobz, &uplo, &n, a.data(), &n, w.data(), work.data(), &lwork, rwork.data(), &lrwork, iwork.data(),
          &liwork, &info);
  if (info != 0) throw SolverError("dense Hermitian eigen solver (zheevd) failed, info=" + std::to_string(info));
}

struct RawEigenpairs {
  VectorXd values;   // ascending
  MatrixXcd vectors; // M-orthonormal
};

RawEigenpairs dense_eigenpairs(const ComplexSparse& S, const VectorXd& mass, int k) {
  const VectorXd inv_sqrt = mass.cwiseSqrt().cwiseInverse();
  MatrixXcd A = inv_sqrt.cast<Complex>().asDiagonal() * MatrixXcd(S) * inv_sqrt.cast<Complex>().asDiagonal();
  A = 0.5 * (A + A.adjoint()).eval();
  VectorXd w;
  hermitian_eigen(A, w);
  RawEigenpairs out;
  out.values = w.head(k);
  out.vectors = inv_sqrt.cast<Complex>().asDiagonal() * A.leftCols(k);
  return out;
}

/// S - sigma M factored by CHOLMOD: supernodal LL^H (sigma below the spectrum) or simplicial LDL^H
/// (any sigma; indefinite is fine, no pivoting). The LDL^H factor also gives the inertia: the number of
/// negative pivots is the number of eigenvalues below sigma (Sylvester).
class ShiftedFactor {
 public:
  ShiftedFactor(const ComplexSparse& S, const VectorXd& mass, bool definite)
      : A_(S), definite_(definite) {
    A_.makeCompressed();
    diag_.resize(A_.cols());
    for (int j = 0; j < A_.outerSize(); ++j) {
      diag_[j] = -1;
      for (ComplexSparse::InnerIterator it(A_, j); it; ++it)
        if (it.row() == j) diag_[j] = static_cast<int>(&it.valueRef() - A_.valuePtr());
      if (diag_[j] < 0) throw SolverError("spectral basis: operator has a structurally zero diagonal entry");
    }
    base_diag_.resize(A_.cols());
    for (int j = 0; j < A_.cols(); ++j) base_diag_[j] = A_.valuePtr()[diag_[j]];
    mass_ = mass;
    if (definite_)
      llt_.analyzePattern(A_);
    else
      ldl_.analyzePattern(A_);
  }

  /// Factors S - sigma M. Returns false if the factorization broke down.
  bool factor(double sigma) {
    sigma_ = sigma;
    for (Eigen::Index j = 0; j < A_.cols(); ++j) A_.valuePtr()[diag_[j]] = base_diag_[j] - sigma * mass_[j];
    if (definite_) {
      llt_.factorize(A_);
      return llt_.info() == Eigen::Success;
    }
    ldl_.factorize(A_);
    return ldl_.info() == Eigen::Success;
  }
  double sigma() const { return sigma_; }
  void set_solve_threads(int threads) { solve_threads_ = threads; }

  /// Number of eigenvalues below sigma (LDL^H only).
  int negative_pivots() const { return ldl_.negative_pivots(); }

  /// X = (S - sigma M)^-1 B. Not reentrant (uses internal buffers).
  void solve_into(const MatrixXcd& B, MatrixXcd& X) const {
    if (definite_)
      X = llt_.solve(B);
    else
      ldl_solve(B, X);
  }

 private:
  /// A^-1 B with the simplicial LDL^H factor, P A P^T = L D L^H. CHOLMOD solves one column at a time;
  /// this reads L once per group of columns (row-major right-hand sides) and splits the columns over two
  /// threads, which makes it several times faster for the blocks of the Lanczos iteration.
  void ldl_solve(const MatrixXcd& B, MatrixXcd& X) const {
    const cholmod_factor* L = ldl_.factor();
    const int n = static_cast<int>(L->n), cols = static_cast<int>(B.cols());
    const int* perm = static_cast<const int*>(L->Perm);
    const int* Lp = static_cast<const int*>(L->p);
    const int* Li = static_cast<const int*>(L->i);
    const int* Lnz = static_cast<const int*>(L->nz);
    const double* Lx = static_cast<const double*>(L->x);
    X.resize(n, cols);
    constexpr int kGroup = 8;
    auto work = [&](int c0, int c1, std::vector<double>& Y) {
      Y.resize(static_cast<std::size_t>(n) * 2 * kGroup);
      for (int g0 = c0; g0 < c1; g0 += kGroup) {
        const int r = std::min(kGroup, c1 - g0);
        const std::ptrdiff_t s = 2 * r;  // doubles per row
        for (int i = 0; i < n; ++i)
          for (int c = 0; c < r; ++c) {
            const Complex v = B(perm[i], g0 + c);
            Y[i * s + 2 * c] = v.real();
            Y[i * s + 2 * c + 1] = v.imag();
          }
        for (int j = 0; j < n; ++j) {  // L y = P b
          const double* yj = &Y[j * s];
          const int p0 = Lp[j], p1 = Lp[j] + Lnz[j];
          for (int p = p0 + 1; p < p1; ++p) {
            const double lr = Lx[2 * static_cast<std::ptrdiff_t>(p)], li = Lx[2 * static_cast<std::ptrdiff_t>(p) + 1];
            double* yi = &Y[static_cast<std::ptrdiff_t>(Li[p]) * s];
            for (int c = 0; c < 2 * r; c += 2) {
              yi[c] -= lr * yj[c] - li * yj[c + 1];
              yi[c + 1] -= lr * yj[c + 1] + li * yj[c];
            }
          }
        }
        for (int j = 0; j < n; ++j) {  // D
          const double dinv = 1.0 / Lx[2 * static_cast<std::ptrdiff_t>(Lp[j])];
          for (int c = 0; c < 2 * r; ++c) Y[j * s + c] *= dinv;
        }
        double acc[2 * kGroup];
        for (int j = n - 1; j >= 0; --j) {  // L^H z = y
          double* yj = &Y[j * s];
          for (int c = 0; c < 2 * r; ++c) acc[c] = yj[c];
          const int p0 = Lp[j], p1 = Lp[j] + Lnz[j];
          for (int p = p0 + 1; p < p1; ++p) {
            const double lr = Lx[2 * static_cast<std::ptrdiff_t>(p)], li = Lx[2 * static_cast<std::ptrdiff_t>(p) + 1];
            const double* yi = &Y[static_cast<std::ptrdiff_t>(Li[p]) * s];
            for (int c = 0; c < 2 * r; c += 2) {  // conj(l) * y_i
              acc[c] -= lr * yi[c] + li * yi[c + 1];
              acc[c + 1] -= lr * yi[c + 1] - li * yi[c];
            }
          }
          for (int c = 0; c < 2 * r; ++c) yj[c] = acc[c];
        }
        for (int i = 0; i < n; ++i)
          for (int c = 0; c < r; ++c) X(perm[i], g0 + c) = Complex(Y[i * s + 2 * c], Y[i * s + 2 * c + 1]);
      }
    };
    const int threads = solve_threads_ > 1 && cols >= 2 * kGroup && std::thread::hardware_concurrency() > 1 ? 2 : 1;
    if (threads == 1) {
      work(0, cols, buffer_[0]);
    } else {
      const int half = ((cols / 2 + kGroup - 1) / kGroup) * kGroup;
      std::exception_ptr error;
      std::thread t([&] {
        try {
          work(half, cols, buffer_[1]);
        } catch (...) {
          error = std::current_exception();
        }
      });
      work(0, half, buffer_[0]);
      t.join();
      if (error) std::rethrow_exception(error);
    }
  }

  struct LDL : Eigen::CholmodSimplicialLDLT<ComplexSparse, Eigen::Lower> {
    const cholmod_factor* factor() const { return this->m_cholmodFactor; }
    int negative_pivots() const {
      const cholmod_factor* L = this->m_cholmodFactor;
      if (L == nullptr || L->is_super || L->is_ll) throw SolverError("spectral basis: no LDL factor for the inertia");
      const int* p = static_cast<const int*>(L->p);
      const double* x = static_cast<const double*>(L->x);  // complex interleaved; D on the column heads
      int neg = 0;
      for (std::size_t j = 0; j < L->n; ++j) neg += x[2 * static_cast<std::ptrdiff_t>(p[j])] < 0;
      return neg;
    }
  };
  ComplexSparse A_;
  std::vector<int> diag_;
  std::vector<Complex> base_diag_;
  VectorXd mass_;
  bool definite_;
  double sigma_ = 0;
  Eigen::CholmodSupernodalLLT<ComplexSparse, Eigen::Lower> llt_;
  LDL ldl_;
  mutable std::vector<double> buffer_[2];
  int solve_threads_ = 2;
};

/// Thick-restart block Lanczos (block Krylov-Schur) for the eigenvalues of S z = lambda M z nearest to a
/// shift sigma, through T = D (S - sigma M)^-1 D, D = M^1/2 (Hermitian, possibly indefinite; theta =
/// 1/(lambda - sigma), largest |theta| first). Either all `count` eigenvalues in [lo, hi) are wanted
/// (count known from the inertia; the iteration runs until exactly that many Ritz pairs in the interval
/// have converged, which also catches eigenvalues missed in clusters), or (lo = -inf, hi = +inf) the
/// `count` nearest ones.
class SliceLanczos {
 public:
  SliceLanczos(const ShiftedFactor& factor, const VectorXd& d, double lo, double hi, int count, int block,
               double tol, int max_restarts, std::function<void(double)> report, std::uint64_t seed)
      : factor_(factor), N_(static_cast<int>(d.size())), b_(block), count_(count), tol_(tol),
        max_restarts_(max_restarts), sigma_(factor.sigma()), lo_(lo), hi_(hi), d_(d), report_(std::move(report)),
        rng_(seed) {
    want_ = count_ + std::max(4, count_ / 10);
    int capacity = want_ + std::max(want_, 4 * b_);
    capacity = ((capacity + b_ - 1) / b_) * b_;
    if (capacity + b_ > N_) capacity = ((N_ - b_) / b_) * b_;
    m_ = capacity;
    if (m_ < want_ + b_)
      throw ParameterError("spectral basis: " + std::to_string(count_) + " eigenpairs is too many for " +
                           std::to_string(N_) + " unknowns; choose a smaller k");
    try {
      V_.resize(N_, m_ + b_);
      H_.setZero(m_ + b_, m_);
    } catch (const std::bad_alloc&) {
      throw SolverError("spectral basis: not enough memory for the Krylov basis (" +
                        std::to_string(static_cast<double>(N_) * (m_ + b_) * 16 / 1e9) + " GB)");
    }
  }

  RawEigenpairs run() {
    RawEigenpairs out;
    if (count_ <= 0) {
      out.values.resize(0);
      out.vectors.resize(N_, 0);
      return out;
    }
    int cur = 0;
    start_block(cur);
    VectorXd theta;
    MatrixXcd Y;
    std::vector<int> chosen;
    int stalled = 0, last_in = -1;
    for (int restart = 0;; ++restart) {
      const int cycle_start = cur;
      while (cur + b_ <= m_) {
        MatrixXcd& W = work_;
        apply(V_.col(cur).data(), b_, W);
        const int j = cur + b_;
        MatrixXcd C = orthogonalize_against(W, j);
        MatrixXcd R = orthonormalize(W, j);
        H_.block(0, cur, j, b_) = C;
        H_.block(j, cur, b_, b_) = R;
        V_.middleCols(j, b_) = W;
        cur = j;
        const double f = static_cast<double>(cur - cycle_start) / std::max(1, m_ - cycle_start);
        report_((last_in > 0 ? last_in : 0) / static_cast<double>(count_) * (1 - 0.5 * f) + 0.5 * f);
      }
      // Rayleigh-Ritz on the projected matrix, Ritz values by decreasing |theta| (nearest sigma first).
      MatrixXcd Hm = H_.topLeftCorner(cur, cur);
      Hm = (0.5 * (Hm + Hm.adjoint())).eval();
      VectorXd w;
      hermitian_eigen(Hm, w);
      std::vector<int> order(cur);
      for (int i = 0; i < cur; ++i) order[i] = i;
      std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return std::abs(w[a]) > std::abs(w[b]); });
      theta.resize(cur);
      Y.resize(cur, cur);
      for (int i = 0; i < cur; ++i) {
        theta[i] = w[order[i]];
        Y.col(i) = Hm.col(order[i]);
      }
      const MatrixXcd coupling = H_.block(cur, 0, b_, cur) * Y;  // b x cur
      std::vector<bool> conv(cur);
      int nconv = 0;
      for (int i = 0; i < cur; ++i) conv[i] = coupling.col(i).norm() <= tol_ * std::abs(theta[i]);
      while (nconv < cur && conv[nconv]) ++nconv;
      chosen.clear();
      for (int i = 0; i < cur; ++i)
        if (conv[i] && in_interval(theta[i])) chosen.push_back(i);
      const bool bounded = std::isfinite(lo_) || std::isfinite(hi_);
      const int have = bounded ? static_cast<int>(chosen.size()) : nconv;
      if (have >= count_) {
        if (!bounded) {
          chosen.clear();
          for (int i = 0; i < count_; ++i) chosen.push_back(i);
        }
        chosen.resize(count_);  // (more than count only for eigenvalues within rounding of lo / hi)
        break;
      }
      if (restart >= max_restarts_)
        throw SolverError("spectral basis: eigen solver did not converge in " + std::to_string(max_restarts_) +
                          " restarts (" + std::to_string(have) + " of " + std::to_string(count_) +
                          " eigenpairs near " + std::to_string(sigma_) + ")");
      stalled = have == last_in ? stalled + 1 : 0;
      last_in = have;
      ++restarts_;
      if (stalled >= 3 && nconv >= want_) {
        // Every wanted Ritz pair converged but the interval misses eigenvalues (a cluster the Krylov
        // space has not seen): keep the converged pairs, restart from a fresh random block.
        rotate(Y, cur, nconv);
        H_.topLeftCorner(cur + b_, cur).setZero();
        for (int i = 0; i < nconv; ++i) H_(i, i) = theta[i];
        cur = nconv;
        start_block(cur);
        stalled = 0;
        continue;
      }
      // Thick restart: keep the best Ritz vectors and the residual block.
      int keep = std::max(nconv + (cur - nconv) / 2, want_ + (cur - want_) / 3);
      keep = std::min(keep, cur - b_);
      rotate(Y, cur, keep);
      V_.middleCols(keep, b_) = V_.middleCols(cur, b_);
      H_.topLeftCorner(cur + b_, cur).setZero();
      for (int i = 0; i < keep; ++i) H_(i, i) = theta[i];
      H_.block(keep, 0, b_, keep) = coupling.leftCols(keep);
      cur = keep;
    }
    // Ritz vectors z = D^-1 V y, lambda = sigma + 1/theta, ascending.
    std::sort(chosen.begin(), chosen.end(), [&](int a, int b) { return lambda_of(theta[a]) < lambda_of(theta[b]); });
    const int c = static_cast<int>(chosen.size());
    MatrixXcd Ys(cur, c);
    out.values.resize(c);
    for (int i = 0; i < c; ++i) {
      Ys.col(i) = Y.col(chosen[i]);
      out.values[i] = lambda_of(theta[chosen[i]]);
    }
    try {
      out.vectors.resize(N_, c);
    } catch (const std::bad_alloc&) {
      throw SolverError("spectral basis: not enough memory for the eigenvectors");
    }
    gemm('N', 'N', N_, c, cur, 1.0, V_.data(), N_, Ys.data(), cur, 0.0, out.vectors.data(), N_);
    out.vectors = d_.cwiseInverse().asDiagonal() * out.vectors;
    return out;
  }

  int restarts() const { return restarts_; }
  int solves() const { return solves_; }

 private:
  double lambda_of(double theta) const { return sigma_ + 1.0 / theta; }
  bool in_interval(double theta) const {
    const double l = lambda_of(theta);
    return l >= lo_ && l < hi_;
  }

  /// Block [cur, cur + b): T applied to a random block, orthonormalized against V[0, cur).
  void start_block(int cur) {
    std::normal_distribution<double> normal;
    MatrixXcd R0(N_, b_), X;
    for (Eigen::Index j = 0; j < R0.cols(); ++j)
      for (Eigen::Index i = 0; i < R0.rows(); ++i) R0(i, j) = Complex(normal(rng_), normal(rng_));
    apply(R0.data(), b_, X);
    if (cur > 0) orthogonalize_against(X, cur);
    orthonormalize(X, cur);
    V_.middleCols(cur, b_) = X;
  }

  /// D (S - sigma M)^-1 D X for X with `cols` columns starting at x (leading dimension N), into out.
  void apply(const Complex* x, int cols, MatrixXcd& out) {
    rhs_.resize(N_, cols);
    for (int j = 0; j < cols; ++j)
      rhs_.col(j) = d_.cwiseProduct(Eigen::Map<const Eigen::VectorXcd>(x + static_cast<std::ptrdiff_t>(j) * N_, N_));
    factor_.solve_into(rhs_, out);
    for (int j = 0; j < cols; ++j) out.col(j).array() *= d_.array();
    solves_ += cols;
  }

  /// W -= V_j (V_j^H W), twice (CGS2: a single classical Gram-Schmidt pass loses orthogonality once Ritz
  /// vectors converge, and the loss grows with every restart); returns the accumulated coefficients.
  MatrixXcd orthogonalize_against(MatrixXcd& W, int j) {
    const int c = static_cast<int>(W.cols());
    MatrixXcd C = MatrixXcd::Zero(j, c), C2(j, c);
    for (int pass = 0; pass < 2; ++pass) {
      gemm('C', 'N', j, c, N_, 1.0, V_.data(), N_, W.data(), N_, 0.0, C2.data(), j);
      gemm('N', 'N', N_, c, j, -1.0, V_.data(), N_, C2.data(), j, 1.0, W.data(), N_);
      C += C2;
    }
    return C;
  }

  /// Orthonormalizes the columns of W (already orthogonal to V_j) in place by SVQB; returns R with
  /// W_in = W_out R. Numerically dependent directions are replaced by random vectors orthogonal to
  /// V_j and the rest (their rows of R are zero).
  MatrixXcd orthonormalize(MatrixXcd& W, int j) {
    const int c = static_cast<int>(W.cols());
    MatrixXcd R = MatrixXcd::Identity(c, c);
    for (int pass = 0; pass < 2; ++pass) {
      MatrixXcd G(c, c);
      gemm('C', 'N', c, c, N_, 1.0, W.data(), N_, W.data(), N_, 0.0, G.data(), c);
      G = (0.5 * (G + G.adjoint())).eval();
      VectorXd dinv(c);
      for (int i = 0; i < c; ++i) dinv[i] = G(i, i).real() > 0 ? 1.0 / std::sqrt(G(i, i).real()) : 0.0;
      MatrixXcd Gs = dinv.asDiagonal() * G * dinv.asDiagonal();
      Eigen::SelfAdjointEigenSolver<MatrixXcd> es(Gs);
      const VectorXd& lam = es.eigenvalues();
      const double lmax = std::max(lam.maxCoeff(), 0.0);
      std::vector<int> good, bad;
      for (int i = 0; i < c; ++i) (lam[i] > 1e-14 * lmax && lmax > 0 ? good : bad).push_back(i);
      MatrixXcd X(c, c), Rp = MatrixXcd::Zero(c, c);
      // X maps W to the new columns; Rp maps the new columns back: W = W_new Rp.
      int col = 0;
      for (int i : good) {
        const double s = std::sqrt(lam[i]);
        X.col(col) = dinv.asDiagonal() * es.eigenvectors().col(i) / s;
        for (int t = 0; t < c; ++t)
          Rp(col, t) = dinv[t] > 0 ? s * std::conj(es.eigenvectors()(t, i)) / dinv[t] : 0.0;
        ++col;
      }
      MatrixXcd& Wn = work2_;
      Wn.resize(N_, c);
      gemm('N', 'N', N_, col, c, 1.0, W.data(), N_, X.data(), c, 0.0, Wn.data(), N_);
      for (size_t r = 0; r < bad.size(); ++r, ++col) {
        std::normal_distribution<double> normal;
        Eigen::VectorXcd v(N_);
        for (int i = 0; i < N_; ++i) v[i] = Complex(normal(rng_), normal(rng_));
        for (int rep = 0; rep < 2; ++rep) {
          if (j > 0) {
            Eigen::VectorXcd coef = V_.leftCols(j).adjoint() * v;
            v -= V_.leftCols(j) * coef;
          }
          if (col > 0) v -= Wn.leftCols(col) * (Wn.leftCols(col).adjoint() * v);
        }
        Wn.col(col) = v.normalized();
      }
      W.swap(Wn);
      R = (Rp * R).eval();
      if (bad.empty() && (lam.array() - 1.0).abs().maxCoeff() < 1e-8) break;  // already orthonormal
    }
    return R;
  }

  /// V[:, 0:keep] = V[:, 0:cur] Y[:, 0:keep], in place by row chunks.
  void rotate(const MatrixXcd& Y, int cur, int keep) {
    const int chunk = 2048;
    MatrixXcd tmp(chunk, keep);
    for (int r0 = 0; r0 < N_; r0 += chunk) {
      const int rows = std::min(chunk, N_ - r0);
      gemm('N', 'N', rows, keep, cur, 1.0, V_.data() + r0, N_, Y.data(), static_cast<int>(Y.rows()), 0.0, tmp.data(),
           chunk);
      V_.block(r0, 0, rows, keep) = tmp.topRows(rows);
    }
  }

  const ShiftedFactor& factor_;
  int N_, b_, count_, want_ = 0, m_ = 0;
  double tol_;
  int max_restarts_;
  double sigma_, lo_, hi_;
  VectorXd d_;
  std::function<void(double)> report_;
  std::mt19937_64 rng_;
  MatrixXcd V_, H_, work_, work2_, rhs_;
  int restarts_ = 0, solves_ = 0;
};

/// Rayleigh-Ritz of S, M on the columns `idx` of Z (in place; values updated): makes a group of
/// vectors computed from different shifts exactly M-orthonormal again.
void local_rayleigh_ritz(const ComplexSparse& S, const VectorXd& mass, MatrixXcd& Z, VectorXd& values,
                         const std::vector<int>& idx) {
  const int q = static_cast<int>(idx.size());
  if (q == 0) return;
  MatrixXcd Q(Z.rows(), q);
  for (int i = 0; i < q; ++i) Q.col(i) = Z.col(idx[i]);
  const MatrixXcd MQ = mass.cast<Complex>().asDiagonal() * Q;
  const MatrixXcd SQ = S * Q;
  MatrixXcd G = Q.adjoint() * MQ, Hs = Q.adjoint() * SQ;
  G = (0.5 * (G + G.adjoint())).eval();
  Hs = (0.5 * (Hs + Hs.adjoint())).eval();
  Eigen::GeneralizedSelfAdjointEigenSolver<MatrixXcd> ges(Hs, G);
  if (ges.info() != Eigen::Success) throw SolverError("spectral basis: local Rayleigh-Ritz failed");
  const MatrixXcd Qn = Q * ges.eigenvectors();
  for (int i = 0; i < q; ++i) {
    Z.col(idx[i]) = Qn.col(i);
    values[idx[i]] = ges.eigenvalues()[i];
  }
}

/// The first k eigenpairs by spectrum slicing (see the header).
RawEigenpairs sliced_eigenpairs(const ComplexSparse& S, const VectorXd& mass, int k, double unit,
                                const SpectralBasisOptions& opt, const ProgressCallback& progress) {
  const int N = static_cast<int>(S.rows());
  const VectorXd d = mass.cwiseSqrt();
  double progress_value = 0;
  auto report = [&](double p) {
    p = std::max(progress_value, std::min(p, 0.99));
    progress_value = p;
    if (progress && !progress(p)) throw Cancelled("spectral basis computation cancelled");
  };
  report(0.0);
  const int slice = opt.slice_size > 0 ? opt.slice_size : 100;
  const int max_count = std::max(1, (N - 1) / 3);
  if (k > max_count)
    throw ParameterError("k=" + std::to_string(k) + " is too close to the problem size " + std::to_string(N) +
                         " for the iterative eigen solver; choose k <= " + std::to_string(max_count));

  if (k <= slice + slice / 2) {
    // One shift below the spectrum (S - sigma M positive definite even when S has a kernel).
    const int b = std::min(opt.block_size, std::max(8, k / 8));
    ShiftedFactor factor(S, mass, true);
    if (!factor.factor(-1e-2 * unit))
      throw SolverError("spectral basis: factorization of S - sigma M failed (matrix not positive definite)");
    SliceLanczos lanczos(factor, d, -INFINITY, INFINITY, k, b, opt.tolerance, opt.max_restarts,
                         [&](double f) { report(f); }, 0x6e6669656c64ULL);
    RawEigenpairs r = lanczos.run();
    report(1.0);
    return r;
  }

  // Slice boundaries B_1 < ... < B_p with count(B_p) >= k, each slice holding about `slice` eigenvalues:
  // placed with Weyl's law (count(lambda) ~ lambda area / (8 pi) = lambda / (2 unit)), then corrected by
  // the measured density; counts are exact (inertia of S - B M).
  ShiftedFactor ldl(S, mass, false);
  std::vector<double> bounds{0.0};
  std::vector<int> counts{0};
  double density = 0.5 / unit;
  while (counts.back() < k) {
    const int have = counts.back(), need = k - have;
    const int target = need <= slice + slice / 2 ? need + std::max(3, need / 25) : slice;
    const double prev = bounds.back();
    double B = prev + target / density;
    int count = -1;
    for (int attempt = 0; attempt < 6; ++attempt) {
      if (!ldl.factor(B)) {
        B *= 1 + 1e-7;
        continue;
      }
      count = ldl.negative_pivots();
      const int c = count - have;
      const bool last = need <= slice + slice / 2;  // this slice should reach k (no tiny trailing slice)
      const bool ok = last ? count >= k && count <= k + std::max(6, need / 8) : c >= target * 0.6 && c <= target * 1.6;
      if (ok || attempt == 5) break;
      density = std::max(c, 1) / (B - prev);
      B = prev + (last ? target * 1.03 + 2 : target) / density;
      report(0.05 * have / k);
    }
    if (count < 0) throw SolverError("spectral basis: factorization of S - sigma M failed");
    if (count <= have) {  // no progress at all (cannot happen unless the counts are broken)
      B = prev + 4 * (B - prev);
      if (!ldl.factor(B)) throw SolverError("spectral basis: factorization of S - sigma M failed");
      count = ldl.negative_pivots();
      if (count <= have) throw SolverError("spectral basis: inertia count does not increase");
    }
    if (count - have > 0) density = (count - have) / (B - prev);
    bounds.push_back(B);
    counts.push_back(count);
    report(0.05 * std::min(count, k) / k);
  }
  const int total = counts.back();
  MatrixXcd Z;
  try {
    Z.resize(N, total);
  } catch (const std::bad_alloc&) {
    throw SolverError("spectral basis: not enough memory for the eigenvectors");
  }
  VectorXd values(total);
  const int p = static_cast<int>(bounds.size()) - 1;
  // Slices are independent: two workers (own factorization, single-threaded BLAS and solves) when the
  // machine has two cores; the calling thread only reports progress (the callback is never called from
  // a worker) and forwards cancellation.
  const int workers = p >= 2 && std::thread::hardware_concurrency() > 1 ? 2 : 1;
  std::vector<std::unique_ptr<ShiftedFactor>> extra;
  std::vector<ShiftedFactor*> factors{&ldl};
  for (int w = 1; w < workers; ++w) {
    extra.push_back(std::make_unique<ShiftedFactor>(S, mass, false));
    factors.push_back(extra.back().get());
  }
  // Largest slices first (balances the two workers).
  std::vector<int> queue;
  for (int j = 1; j <= p; ++j) queue.push_back(j);
  std::stable_sort(queue.begin(), queue.end(),
                   [&](int a, int b) { return counts[a] - counts[a - 1] > counts[b] - counts[b - 1]; });
  std::atomic<int> next_slice{0}, finished{0};
  std::atomic<bool> stop{false};
  std::unique_ptr<std::atomic<double>[]> slice_progress(new std::atomic<double>[p + 1]);
  for (int j = 0; j <= p; ++j) slice_progress[j] = 0.0;
  std::vector<std::exception_ptr> errors(workers);
  auto overall = [&]() {
    double done = 0;
    for (int j = 1; j <= p; ++j) done += (counts[j] - counts[j - 1]) * slice_progress[j].load();
    return 0.05 + 0.93 * done / total;
  };
  auto worker = [&](int w) {
    try {
      for (;;) {
        if (stop) return;
        const int q = next_slice++;
        if (q >= p) return;
        const int j = queue[q];
        const int c = counts[j] - counts[j - 1];
        if (c == 0) continue;
        ShiftedFactor& factor = *factors[w];
        factor.set_solve_threads(workers == 1 ? 2 : 1);
        const double lo = j == 1 ? -INFINITY : bounds[j - 1], hi = bounds[j];
        double sigma = 0.5 * (bounds[j - 1] + bounds[j]);
        bool ok = factor.factor(sigma);
        for (int attempt = 0; !ok && attempt < 4; ++attempt) ok = factor.factor(sigma *= 1 + 1e-6);
        if (!ok) throw SolverError("spectral basis: factorization of S - sigma M failed");
        const int b = std::min(opt.block_size, std::max(8, c / 8));
        SliceLanczos lanczos(factor, d, lo, hi, c, b, opt.tolerance, opt.max_restarts,
                             [&, j](double f) {
                               slice_progress[j] = f;
                               if (workers == 1) report(overall());
                               if (stop) throw Cancelled("spectral basis computation cancelled");
                             },
                             0x6e6669656c64ULL + j);
        RawEigenpairs r = lanczos.run();
        if (r.values.size() != c) throw SolverError("spectral basis: slice returned the wrong number of eigenpairs");
        Z.middleCols(counts[j - 1], c) = r.vectors;  // disjoint columns per slice
        values.segment(counts[j - 1], c) = r.values;
        slice_progress[j] = 1.0;
      }
    } catch (...) {
      errors[w] = std::current_exception();
      stop = true;
    }
  };
  if (workers == 1) {
    worker(0);
  } else {
    SingleThreadedBlas blas_guard;  // two workers already use both cores
    std::vector<std::thread> threads;
    for (int w = 0; w < workers; ++w)
      threads.emplace_back([&, w] {
        worker(w);
        ++finished;
      });
    std::exception_ptr cancelled;
    while (finished < workers) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (!cancelled && !stop) {
        try {
          report(overall());
        } catch (...) {
          cancelled = std::current_exception();
          stop = true;
        }
      }
    }
    for (auto& t : threads) t.join();
    if (cancelled) std::rethrow_exception(cancelled);
  }
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
  // Vectors of adjacent slices come from different shifts: M-orthogonal only up to residual / gap.
  // Where that is visible (clusters across a boundary), a local Rayleigh-Ritz restores it.
  for (int j = 1; j < p; ++j) {
    const int a0 = counts[j - 1], a1 = counts[j], b1 = counts[j + 1];
    if (a1 == a0 || b1 == a1) continue;
    const MatrixXcd G = Z.middleCols(a0, a1 - a0).adjoint() *
                        (mass.cast<Complex>().asDiagonal() * Z.middleCols(a1, b1 - a1));
    std::vector<int> idx;
    for (int r = 0; r < G.rows(); ++r)
      if (G.row(r).cwiseAbs().maxCoeff() > 1e-12) idx.push_back(a0 + r);
    for (int c = 0; c < G.cols(); ++c)
      if (G.col(c).cwiseAbs().maxCoeff() > 1e-12) idx.push_back(a1 + c);
    local_rayleigh_ritz(S, mass, Z, values, idx);
  }
  // Ascending order, first k.
  std::vector<int> order(total);
  for (int i = 0; i < total; ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return values[a] < values[b]; });
  RawEigenpairs out;
  out.values.resize(k);
  bool sorted = true;
  for (int i = 0; i < k; ++i) sorted &= order[i] == i;
  for (int i = 0; i < k; ++i) out.values[i] = values[order[i]];
  if (sorted) {
    Z.conservativeResize(Eigen::NoChange, k);
    out.vectors = std::move(Z);
  } else {
    out.vectors.resize(N, k);
    for (int i = 0; i < k; ++i) out.vectors.col(i) = Z.col(order[i]);
  }
  report(1.0);
  return out;
}

// ------------------------------------------------------------------------------------------ file format
constexpr char kMagic[8] = {'N', 'F', 'B', 'A', 'S', 'I', 'S', '1'};
constexpr std::uint32_t kVersion = 1;

struct Header {
  char magic[8];
  std::uint32_t version;
  std::uint32_t precision;  // 0 double, 1 single
  std::uint64_t mesh_hash;
  std::int32_t n;
  std::int32_t weights;  // 0 geometric, 1 combinatorial
  std::int32_t k;
  std::int32_t num_unknowns;
};
static_assert(sizeof(Header) == 40, "unexpected header padding");

/// A fast 64-bit checksum (word-wise multiply-xorshift) of a byte range, chained through `h`.
std::uint64_t checksum(const void* data, std::size_t bytes, std::uint64_t h) {
  const unsigned char* p = static_cast<const unsigned char*>(data);
  std::size_t i = 0;
  for (; i + 8 <= bytes; i += 8) {
    std::uint64_t w;
    std::memcpy(&w, p + i, 8);
    h ^= w + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    h *= 0xff51afd7ed558ccdULL;
  }
  for (; i < bytes; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h ^ (h >> 33);
}

std::string hex64(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

}  // namespace

// ------------------------------------------------------------------------------------------ compute

namespace {

/// Peak bytes of compute() for k eigenpairs of N unknowns whose factor has `lnz` nonzeros.
double basis_bytes(double lnz, int N, int k, const SpectralBasisOptions& opt) {
  const double c = sizeof(Complex), n = N;
  if (N <= opt.dense_limit) return 3.0 * n * n * c + 2.0 * n * k * c;  // dense Hermitian eigen solver
  const double factor = static_cast<double>(cholesky_factor_bytes(lnz, static_cast<std::size_t>(N)));
  const int slice = opt.slice_size > 0 ? opt.slice_size : 100;
  double bytes;
  if (k <= slice + slice / 2) {
    const int b = std::min(opt.block_size, std::max(8, k / 8));
    bytes = factor + (2.0 * k + 2.0 * b) * n * c + 2.0 * n * k * c;  // Krylov space, result, copy
  } else {
    const int b = std::min(opt.block_size, std::max(8, slice / 8));
    const double per_worker = factor + (3.0 * slice + 2.0 * b) * n * c;
    bytes = 2.0 * per_worker + 1.1 * n * k * c + n * k * c;  // two workers, all slices' vectors, result
  }
  if (opt.precision == BasisPrecision::Single) bytes += n * k * sizeof(std::complex<float>);
  return bytes;
}

double harmonic_factor_nonzeros(const FieldOperators& ops) {
  Eigen::CholmodSupernodalLLT<ComplexSparse, Eigen::Lower> analysis;
  analysis.analyzePattern(ops.harmonic_matrix());
  return analysis.cholmod().lnz;
}

}  // namespace

std::size_t estimate_basis_bytes(const FieldOperators& ops, int k, const SpectralBasisOptions& options) {
  const int N = ops.num_unknowns();
  const double lnz = N <= options.dense_limit ? 0.0 : harmonic_factor_nonzeros(ops);
  return static_cast<std::size_t>(basis_bytes(lnz, N, std::max(k, 1), options));
}

SpectralBasis SpectralBasis::compute(const FieldOperators& ops, int k, const SpectralBasisOptions& options,
                                     const ProgressCallback& progress) {
  const ComplexSparse& S = ops.harmonic_matrix();
  const VectorXd& mass = ops.mass();
  const int N = ops.num_unknowns();
  if (k < 1 || k > N)
    throw ParameterError("number of basis vectors k must be between 1 and the number of faces with a field (" +
                         std::to_string(N) + "), got " + std::to_string(k));
  if (options.block_size < 1 || options.block_size > 512)
    throw ParameterError("spectral basis block size must be in [1, 512], got " + std::to_string(options.block_size));
  if (!(options.tolerance > 0 && options.tolerance < 1e-2))
    throw ParameterError("spectral basis tolerance must be in (0, 1e-2)");
  {
    // Memory guard, with what would fit: the largest k, and whether single precision storage helps.
    const double lnz = N <= options.dense_limit ? 0.0 : harmonic_factor_nonzeros(ops);
    const double need = basis_bytes(lnz, N, k, options);
    const double budget = kMemoryHeadroom * static_cast<double>(available_memory_bytes());
    if (budget > 0 && need > budget) {
      int lo = 0, hi = k;  // largest k' < k that fits (need grows with k)
      while (hi - lo > 1) {
        const int mid = (lo + hi) / 2;
        (basis_bytes(lnz, N, mid, options) <= budget ? lo : hi) = mid;
      }
      std::string advice = lo >= 1 ? "k <= " + std::to_string(lo) + " fits" : "no basis size fits";
      SpectralBasisOptions single = options;
      single.precision = BasisPrecision::Single;
      if (options.precision == BasisPrecision::Double && basis_bytes(lnz, N, k, single) <= budget)
        advice += "; so does single precision storage";
      advice += "; the exact mode needs no basis";
      require_memory(static_cast<std::size_t>(need),
                     "the spectral basis of k=" + std::to_string(k) + " eigenfields (" + std::to_string(N) + " faces)",
                     advice);
    }
  }

  RawEigenpairs raw;
  if (N <= options.dense_limit) {
    if (progress && !progress(0.0)) throw Cancelled("spectral basis computation cancelled");
    raw = dense_eigenpairs(S, mass, k);
    if (progress && !progress(1.0)) throw Cancelled("spectral basis computation cancelled");
  } else {
    try {
      raw = sliced_eigenpairs(S, mass, k, ops.eigenvalue_unit(1), options, progress);
    } catch (const std::bad_alloc&) {
      throw SolverError("spectral basis: out of memory (k=" + std::to_string(k) + ", " + std::to_string(N) +
                        " unknowns)");
    }
  }

  SpectralBasis out;
  out.values_ = raw.values;
  out.mass_ = mass;
  out.precision_ = options.precision;
  out.mesh_hash_ = ops.mesh().content_hash();
  out.n_ = ops.n();
  out.weights_ = ops.weights();
  if (options.precision == BasisPrecision::Single) {
    try {
      out.vectors_f_ = raw.vectors.cast<std::complex<float>>();
    } catch (const std::bad_alloc&) {
      throw SolverError("spectral basis: not enough memory for the eigenvectors");
    }
  } else {
    out.vectors_d_ = std::move(raw.vectors);
  }
  if (progress && !progress(1.0)) throw Cancelled("spectral basis computation cancelled");
  return out;
}

// ------------------------------------------------------------------------------------------ access

ComplexVector SpectralBasis::vector(int j) const {
  if (j < 0 || j >= size()) throw ParameterError("basis vector index out of range: " + std::to_string(j));
  if (precision_ == BasisPrecision::Single) return vectors_f_.col(j).cast<Complex>();
  return vectors_d_.col(j);
}

Eigen::MatrixXcd SpectralBasis::vectors() const {
  if (precision_ == BasisPrecision::Single) return vectors_f_.cast<Complex>();
  return vectors_d_;
}

ComplexVector SpectralBasis::project(const ComplexVector& z) const {
  const int N = num_unknowns(), k = size();
  if (z.size() != N)
    throw ParameterError("project: field has " + std::to_string(z.size()) + " entries, expected " +
                         std::to_string(N));
  const int one = 1;
  const char t = 'C';
  if (precision_ == BasisPrecision::Single) {
    const Eigen::VectorXcf mz = (mass_.cast<Complex>().cwiseProduct(z)).cast<std::complex<float>>();
    Eigen::VectorXcf x(k);
    const std::complex<float> a(1), b0(0);
    cgemv_(&t, &N, &k, &a, vectors_f_.data(), &N, mz.data(), &one, &b0, x.data(), &one);
    return x.cast<Complex>();
  }
  const ComplexVector mz = mass_.cast<Complex>().cwiseProduct(z);
  ComplexVector x(k);
  const Complex a(1), b0(0);
  zgemv_(&t, &N, &k, &a, vectors_d_.data(), &N, mz.data(), &one, &b0, x.data(), &one);
  return x;
}

ComplexVector SpectralBasis::reconstruct(const ComplexVector& x) const {
  const int N = num_unknowns(), k = size();
  if (x.size() != k)
    throw ParameterError("reconstruct: " + std::to_string(x.size()) + " coefficients, expected " +
                         std::to_string(k));
  const int one = 1;
  const char t = 'N';
  if (precision_ == BasisPrecision::Single) {
    const Eigen::VectorXcf xf = x.cast<std::complex<float>>();
    Eigen::VectorXcf z(N);
    const std::complex<float> a(1), b0(0);
    cgemv_(&t, &N, &k, &a, vectors_f_.data(), &N, xf.data(), &one, &b0, z.data(), &one);
    return z.cast<Complex>();
  }
  ComplexVector z(N);
  const Complex a(1), b0(0);
  zgemv_(&t, &N, &k, &a, vectors_d_.data(), &N, x.data(), &one, &b0, z.data(), &one);
  return z;
}

SpectralBasis SpectralBasis::truncated(int k) const {
  if (k < 1 || k > size())
    throw ParameterError("truncated basis size must be between 1 and " + std::to_string(size()) + ", got " +
                         std::to_string(k));
  SpectralBasis out;
  out.values_ = values_.head(k);
  if (precision_ == BasisPrecision::Single)
    out.vectors_f_ = vectors_f_.leftCols(k);
  else
    out.vectors_d_ = vectors_d_.leftCols(k);
  out.mass_ = mass_;
  out.precision_ = precision_;
  out.mesh_hash_ = mesh_hash_;
  out.n_ = n_;
  out.weights_ = weights_;
  return out;
}

SpectralBasis SpectralBasis::with_precision(BasisPrecision precision) const {
  SpectralBasis out;
  out.values_ = values_;
  out.mass_ = mass_;
  out.precision_ = precision;
  out.mesh_hash_ = mesh_hash_;
  out.n_ = n_;
  out.weights_ = weights_;
  try {
    if (precision == precision_) {
      out.vectors_d_ = vectors_d_;
      out.vectors_f_ = vectors_f_;
    } else if (precision == BasisPrecision::Single) {
      out.vectors_f_ = vectors_d_.cast<std::complex<float>>();
    } else {
      out.vectors_d_ = vectors_f_.cast<Complex>();
    }
  } catch (const std::bad_alloc&) {
    throw SolverError("spectral basis: not enough memory to convert the basis");
  }
  return out;
}

std::size_t SpectralBasis::memory_bytes() const {
  return static_cast<std::size_t>(vectors_d_.size()) * sizeof(Complex) +
         static_cast<std::size_t>(vectors_f_.size()) * sizeof(std::complex<float>) +
         static_cast<std::size_t>(values_.size() + mass_.size()) * sizeof(double);
}

// ------------------------------------------------------------------------------------------ cache

std::string cache_key(const FieldOperators& ops, int k, BasisPrecision precision) {
  return "basis-" + hex64(ops.mesh().content_hash()) + "-n" + std::to_string(ops.n()) + "-" +
         to_string(ops.weights()) + "-N" + std::to_string(ops.num_unknowns()) + "-k" + std::to_string(k) +
         (precision == BasisPrecision::Single ? "-f32" : "-f64");
}

void SpectralBasis::save(const std::string& path) const {
  if (size() == 0) throw ParameterError("cannot save an empty spectral basis");
  Header h{};
  std::memcpy(h.magic, kMagic, 8);
  h.version = kVersion;
  h.precision = precision_ == BasisPrecision::Single ? 1 : 0;
  h.mesh_hash = mesh_hash_;
  h.n = n_;
  h.weights = weights_ == EdgeWeights::Geometric ? 0 : 1;
  h.k = size();
  h.num_unknowns = num_unknowns();
  const void* vec = precision_ == BasisPrecision::Single ? static_cast<const void*>(vectors_f_.data())
                                                         : static_cast<const void*>(vectors_d_.data());
  const std::size_t vec_bytes = precision_ == BasisPrecision::Single
                                    ? static_cast<std::size_t>(vectors_f_.size()) * sizeof(std::complex<float>)
                                    : static_cast<std::size_t>(vectors_d_.size()) * sizeof(Complex);
  const std::size_t val_bytes = static_cast<std::size_t>(values_.size()) * sizeof(double);
  std::uint64_t sum = checksum(&h, sizeof h, 0x6e6669656c64ULL);
  sum = checksum(values_.data(), val_bytes, sum);
  sum = checksum(vec, vec_bytes, sum);

  std::random_device rd;
  const std::string tmp = path + ".tmp" + hex64((static_cast<std::uint64_t>(rd()) << 32) ^ rd());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError("cannot write spectral basis cache '" + tmp + "'");
    out.write(reinterpret_cast<const char*>(&h), sizeof h);
    out.write(reinterpret_cast<const char*>(values_.data()), static_cast<std::streamsize>(val_bytes));
    out.write(static_cast<const char*>(vec), static_cast<std::streamsize>(vec_bytes));
    out.write(reinterpret_cast<const char*>(&sum), sizeof sum);
    out.flush();
    if (!out) {
      out.close();
      std::remove(tmp.c_str());
      throw InputError("writing spectral basis cache '" + tmp + "' failed (disk full?)");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw InputError("cannot move spectral basis cache into place at '" + path + "'");
  }
}

SpectralBasis SpectralBasis::load(const std::string& path, const FieldOperators& ops, int expected_k,
                                  int expected_precision) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError("cannot open spectral basis cache '" + path + "'");
  const std::streamoff file_size = in.tellg();
  in.seekg(0);
  Header h{};
  if (file_size < static_cast<std::streamoff>(sizeof h) || !in.read(reinterpret_cast<char*>(&h), sizeof h))
    throw InputError("spectral basis cache '" + path + "' is truncated (no header)");
  if (std::memcmp(h.magic, kMagic, 8) != 0) throw InputError("'" + path + "' is not an nfield spectral basis cache");
  if (h.version != kVersion)
    throw InputError("spectral basis cache '" + path + "' has unsupported version " + std::to_string(h.version));
  auto stale = [&](const std::string& what) {
    return InputError("stale spectral basis cache '" + path + "': " + what + " does not match");
  };
  if (h.mesh_hash != ops.mesh().content_hash()) throw stale("mesh content");
  if (h.n != ops.n()) throw stale("symmetry n (" + std::to_string(h.n) + " vs " + std::to_string(ops.n()) + ")");
  if (h.weights != (ops.weights() == EdgeWeights::Geometric ? 0 : 1)) throw stale("edge weights");
  if (h.num_unknowns != ops.num_unknowns()) throw stale("number of unknowns");
  if (h.precision > 1) throw InputError("spectral basis cache '" + path + "' is corrupt (precision field)");
  if (expected_k > 0 && h.k != expected_k) throw stale("k (" + std::to_string(h.k) + " vs " + std::to_string(expected_k) + ")");
  if (expected_precision >= 0 && static_cast<int>(h.precision) != expected_precision) throw stale("precision");
  if (h.k < 1 || h.k > h.num_unknowns) throw InputError("spectral basis cache '" + path + "' is corrupt (k)");

  const std::size_t N = static_cast<std::size_t>(h.num_unknowns), k = static_cast<std::size_t>(h.k);
  const std::size_t scalar = h.precision == 1 ? sizeof(std::complex<float>) : sizeof(Complex);
  const std::size_t val_bytes = k * sizeof(double), vec_bytes = N * k * scalar;
  const std::size_t expected = sizeof h + val_bytes + vec_bytes + sizeof(std::uint64_t);
  if (static_cast<std::size_t>(file_size) != expected)
    throw InputError("spectral basis cache '" + path + "' is truncated or corrupt (size " + std::to_string(file_size) +
                     " bytes, expected " + std::to_string(expected) + ")");

  SpectralBasis out;
  try {
    out.values_.resize(static_cast<Eigen::Index>(k));
    if (h.precision == 1)
      out.vectors_f_.resize(static_cast<Eigen::Index>(N), static_cast<Eigen::Index>(k));
    else
      out.vectors_d_.resize(static_cast<Eigen::Index>(N), static_cast<Eigen::Index>(k));
  } catch (const std::bad_alloc&) {
    throw SolverError("not enough memory to load spectral basis cache '" + path + "'");
  }
  void* vec = h.precision == 1 ? static_cast<void*>(out.vectors_f_.data()) : static_cast<void*>(out.vectors_d_.data());
  std::uint64_t stored = 0;
  if (!in.read(reinterpret_cast<char*>(out.values_.data()), static_cast<std::streamsize>(val_bytes)) ||
      !in.read(static_cast<char*>(vec), static_cast<std::streamsize>(vec_bytes)) ||
      !in.read(reinterpret_cast<char*>(&stored), sizeof stored))
    throw InputError("spectral basis cache '" + path + "' is truncated");
  std::uint64_t sum = checksum(&h, sizeof h, 0x6e6669656c64ULL);
  sum = checksum(out.values_.data(), val_bytes, sum);
  sum = checksum(vec, vec_bytes, sum);
  if (sum != stored) throw InputError("spectral basis cache '" + path + "' is corrupt (checksum mismatch)");
  if (!out.values_.allFinite()) throw InputError("spectral basis cache '" + path + "' is corrupt (eigenvalues)");
  out.mass_ = ops.mass();
  out.precision_ = h.precision == 1 ? BasisPrecision::Single : BasisPrecision::Double;
  out.mesh_hash_ = h.mesh_hash;
  out.n_ = h.n;
  out.weights_ = ops.weights();
  return out;
}

}  // namespace nfield
