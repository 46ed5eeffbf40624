#include "nfield/spectral_basis.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <new>
#include <random>

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

namespace nfield {
namespace {

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

/// Thick-restart block Lanczos (block Krylov-Schur) for the largest eigenvalues of
/// T = D (S - sigma M)^-1 D, D = M^1/2, in the standard inner product (see the header).
class BlockKrylovSchur {
 public:
  BlockKrylovSchur(const ComplexSparse& S, const VectorXd& mass, double sigma, int k, int block, int capacity,
                   double tol, int max_restarts, const ProgressCallback& progress)
      : N_(static_cast<int>(S.rows())), k_(k), b_(block), m_(capacity), tol_(tol), max_restarts_(max_restarts),
        sigma_(sigma), d_(mass.cwiseSqrt()), progress_(progress) {
    ComplexSparse A = S;
    for (int i = 0; i < N_; ++i) A.coeffRef(i, i) -= sigma * mass[i];
    factor_.compute(A);
    if (factor_.info() != Eigen::Success)
      throw SolverError("spectral basis: factorization of S - sigma M failed (matrix not positive definite)");
    try {
      V_.resize(N_, m_ + b_);
      H_.setZero(m_ + b_, m_);
    } catch (const std::bad_alloc&) {
      throw SolverError("spectral basis: not enough memory for the Krylov basis (" +
                        std::to_string(static_cast<double>(N_) * (m_ + b_) * 16 / 1e9) + " GB)");
    }
  }

  RawEigenpairs run() {
    report(0.0);
    // Start block: T applied to a deterministic random block (damps the high frequencies).
    std::mt19937_64 rng(0x6e6669656c64ULL);
    std::normal_distribution<double> normal;
    MatrixXcd X(N_, b_);
    for (Eigen::Index j = 0; j < X.cols(); ++j)
      for (Eigen::Index i = 0; i < X.rows(); ++i) X(i, j) = Complex(normal(rng), normal(rng));
    X = apply(X.data(), b_);
    orthonormalize(X, 0, rng);
    V_.middleCols(0, b_) = X;

    int cur = 0;  // columns [0, cur) have their images in H; block [cur, cur + b) is expanded next
    int nconv = 0;
    VectorXd theta;
    MatrixXcd Y;
    for (int restart = 0;; ++restart) {
      const int cycle_start = cur;
      while (cur + b_ <= m_) {
        MatrixXcd W = apply(V_.col(cur).data(), b_);
        const int j = cur + b_;
        MatrixXcd C = orthogonalize_against(W, j);
        MatrixXcd R = orthonormalize(W, j, rng);
        H_.block(0, cur, j, b_) = C;
        H_.block(j, cur, b_, b_) = R;
        V_.middleCols(j, b_) = W;
        cur = j;
        const double f = static_cast<double>(cur - cycle_start) / std::max(1, m_ - cycle_start);
        report((nconv + f * 0.5 * (k_ - nconv)) / k_);
      }
      // Rayleigh-Ritz on the projected matrix.
      MatrixXcd Hm = H_.topLeftCorner(cur, cur);
      Hm = (0.5 * (Hm + Hm.adjoint())).eval();
      VectorXd w;
      hermitian_eigen(Hm, w);
      theta = w.reverse();
      Y = Hm.rowwise().reverse();  // descending theta
      const MatrixXcd coupling = H_.block(cur, 0, b_, cur) * Y;  // b x cur
      nconv = 0;
      while (nconv < cur && coupling.col(nconv).norm() <= tol_ * theta[nconv]) ++nconv;
      if (nconv >= k_) break;
      if (restart >= max_restarts_)
        throw SolverError("spectral basis: eigen solver did not converge in " + std::to_string(max_restarts_) +
                          " restarts (" + std::to_string(nconv) + " of " + std::to_string(k_) + " converged)");
      // Thick restart: keep the l best Ritz vectors and the residual block.
      int keep = std::max(nconv + (cur - nconv) / 2, k_ + (cur - k_) / 3);
      keep = std::min(keep, cur - b_);
      rotate(Y, cur, keep);
      V_.middleCols(keep, b_) = V_.middleCols(cur, b_);
      H_.topLeftCorner(cur + b_, cur).setZero();
      for (int i = 0; i < keep; ++i) H_(i, i) = theta[i];
      H_.block(keep, 0, b_, keep) = coupling.leftCols(keep);
      cur = keep;
      restarts_ = restart + 1;
    }
    // Ritz vectors z = D^-1 V y, lambda = sigma + 1/theta.
    RawEigenpairs out;
    out.values.resize(k_);
    for (int i = 0; i < k_; ++i) out.values[i] = sigma_ + 1.0 / theta[i];
    try {
      out.vectors.resize(N_, k_);
    } catch (const std::bad_alloc&) {
      throw SolverError("spectral basis: not enough memory for the eigenvectors");
    }
    gemm('N', 'N', N_, k_, cur, 1.0, V_.data(), N_, Y.data(), static_cast<int>(Y.rows()), 0.0, out.vectors.data(), N_);
    out.vectors = d_.cwiseInverse().asDiagonal() * out.vectors;
    report(1.0);
    return out;
  }

  int restarts() const { return restarts_; }
  int solves() const { return solves_; }

 private:
  void report(double p) {
    p = std::max(progress_value_, std::min(p, 0.99));
    progress_value_ = p;
    if (progress_ && !progress_(p)) throw Cancelled("spectral basis computation cancelled");
  }

  /// D (S - sigma M)^-1 D X for X with `cols` columns starting at x (leading dimension N).
  MatrixXcd apply(const Complex* x, int cols) {
    MatrixXcd B(N_, cols);
    for (int j = 0; j < cols; ++j)
      B.col(j) = d_.cwiseProduct(Eigen::Map<const Eigen::VectorXcd>(x + static_cast<std::ptrdiff_t>(j) * N_, N_));
    MatrixXcd Z = factor_.solve(B);
    solves_ += cols;
    return d_.asDiagonal() * Z;
  }

  /// W -= V_j (V_j^H W), repeated when cancellation was strong; returns the accumulated coefficients.
  MatrixXcd orthogonalize_against(MatrixXcd& W, int j) {
    const int c = static_cast<int>(W.cols());
    MatrixXcd C = MatrixXcd::Zero(j, c), C2(j, c);
    for (int pass = 0; pass < 2; ++pass) {
      const VectorXd before = W.colwise().norm();
      gemm('C', 'N', j, c, N_, 1.0, V_.data(), N_, W.data(), N_, 0.0, C2.data(), j);
      gemm('N', 'N', N_, c, j, -1.0, V_.data(), N_, C2.data(), j, 1.0, W.data(), N_);
      C += C2;
      const VectorXd after = W.colwise().norm();
      bool again = false;
      // One classical Gram-Schmidt pass leaves components of relative size eps * before/after; repeat
      // only under strong cancellation (the DGKS 1/sqrt(2) rule is needlessly strict here).
      for (int i = 0; i < c; ++i) again |= after[i] < 0.1 * before[i];
      ++passes_;
      if (!again) break;
    }
    return C;
  }

  /// Orthonormalizes the columns of W (already orthogonal to V_j) in place by SVQB; returns R with
  /// W_in = W_out R. Numerically dependent directions are replaced by random vectors orthogonal to
  /// V_j and the rest (their rows of R are zero).
  MatrixXcd orthonormalize(MatrixXcd& W, int j, std::mt19937_64& rng) {
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
      MatrixXcd Wn(N_, c);
      gemm('N', 'N', N_, col, c, 1.0, W.data(), N_, X.data(), c, 0.0, Wn.data(), N_);
      for (size_t r = 0; r < bad.size(); ++r, ++col) {
        std::normal_distribution<double> normal;
        Eigen::VectorXcd v(N_);
        for (int i = 0; i < N_; ++i) v[i] = Complex(normal(rng), normal(rng));
        for (int rep = 0; rep < 2; ++rep) {
          if (j > 0) {
            Eigen::VectorXcd coef = V_.leftCols(j).adjoint() * v;
            v -= V_.leftCols(j) * coef;
          }
          if (col > 0) v -= Wn.leftCols(col) * (Wn.leftCols(col).adjoint() * v);
        }
        Wn.col(col) = v.normalized();
      }
      W = Wn;
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

  int N_, k_, b_, m_;
  double tol_;
  int max_restarts_;
  double sigma_;
  VectorXd d_;
  const ProgressCallback& progress_;
  double progress_value_ = 0.0;
  Eigen::CholmodSupernodalLLT<ComplexSparse, Eigen::Lower> factor_;
  MatrixXcd V_, H_;
  int restarts_ = 0, solves_ = 0, passes_ = 0;
};

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

  // Small k: smaller blocks (a block Krylov space of the same size then has a higher polynomial degree).
  const int b = std::min(options.block_size, std::max(8, k / 8));
  // Krylov capacity: room for the wanted pairs plus as many again (at least a few blocks).
  int capacity = options.subspace > 0 ? std::max(options.subspace, k + 2 * b) : k + std::max(4 * b, k);
  capacity = ((capacity + b - 1) / b) * b;
  RawEigenpairs raw;
  if (N <= options.dense_limit || capacity + b > N) {
    if (N > 4000)
      throw ParameterError("k=" + std::to_string(k) + " is too close to the problem size " + std::to_string(N) +
                           " for the iterative eigen solver; choose a smaller k");
    if (progress && !progress(0.0)) throw Cancelled("spectral basis computation cancelled");
    raw = dense_eigenpairs(S, mass, k);
    if (progress && !progress(1.0)) throw Cancelled("spectral basis computation cancelled");
  } else {
    const double sigma = -1e-2 * ops.eigenvalue_unit(1);
    try {
      BlockKrylovSchur solver(S, mass, sigma, k, b, capacity, options.tolerance, options.max_restarts, progress);
      raw = solver.run();
    } catch (const std::bad_alloc&) {
      throw SolverError("spectral basis: out of memory (k=" + std::to_string(k) + ", " + std::to_string(N) +
                        " unknowns needs about " +
                        std::to_string(static_cast<double>(N) * (capacity + b) * sizeof(Complex) / 1e9) + " GB)");
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
