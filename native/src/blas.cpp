#include "nfield/blas.hpp"

#include <cstddef>
#include <mutex>
#include <string>
#include <vector>

#include "nfield/errors.hpp"

// BLAS / LAPACK (linked by the build: OpenBLAS or the reference implementation).
extern "C" {
void zgemm_(const char* ta, const char* tb, const int* m, const int* n, const int* k, const std::complex<double>* alpha,
            const std::complex<double>* a, const int* lda, const std::complex<double>* b, const int* ldb,
            const std::complex<double>* beta, std::complex<double>* c, const int* ldc);
void ztrsm_(const char* side, const char* uplo, const char* trans, const char* diag, const int* m, const int* n,
            const std::complex<double>* alpha, const std::complex<double>* a, const int* lda, std::complex<double>* b,
            const int* ldb);
void zgemv_(const char* t, const int* m, const int* n, const std::complex<double>* alpha, const std::complex<double>* a,
            const int* lda, const std::complex<double>* x, const int* incx, const std::complex<double>* beta,
            std::complex<double>* y, const int* incy);
void cgemv_(const char* t, const int* m, const int* n, const std::complex<float>* alpha,
            const std::complex<float>* a, const int* lda, const std::complex<float>* x, const int* incx,
            const std::complex<float>* beta, std::complex<float>* y, const int* incy);
void zheevd_(const char* jobz, const char* uplo, const int* n, std::complex<double>* a, const int* lda, double* w,
             std::complex<double>* work, const int* lwork, double* rwork, const int* lrwork, int* iwork,
             const int* liwork, int* info);
}

// OpenBLAS thread control, weak: absent with other BLAS implementations.
extern "C" {
void openblas_set_num_threads(int) __attribute__((weak));
int openblas_get_num_threads(void) __attribute__((weak));
}

namespace nfield {

void gemm(char ta, char tb, int m, int n, int k, std::complex<double> alpha, const std::complex<double>* a, int lda,
          const std::complex<double>* b, int ldb, std::complex<double> beta, std::complex<double>* c, int ldc) {
  if (m <= 0 || n <= 0) return;
  if (k <= 0) {
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < m; ++i) c[i + static_cast<std::ptrdiff_t>(j) * ldc] *= beta;
    return;
  }
  zgemm_(&ta, &tb, &m, &n, &k, &alpha, a, &lda, b, &ldb, &beta, c, &ldc);
}

void trsm_left(char uplo, char trans, char diag, int m, int n, std::complex<double> alpha, const std::complex<double>* a,
               int lda, std::complex<double>* b, int ldb) {
  if (m <= 0 || n <= 0) return;
  const char side = 'L';
  ztrsm_(&side, &uplo, &trans, &diag, &m, &n, &alpha, a, &lda, b, &ldb);
}

void gemv(char t, int m, int n, const std::complex<double>* a, const std::complex<double>* x, std::complex<double>* y) {
  const int one = 1;
  const std::complex<double> alpha(1), beta(0);
  zgemv_(&t, &m, &n, &alpha, a, &m, x, &one, &beta, y, &one);
}

void gemv(char t, int m, int n, const std::complex<float>* a, const std::complex<float>* x, std::complex<float>* y) {
  const int one = 1;
  const std::complex<float> alpha(1), beta(0);
  cgemv_(&t, &m, &n, &alpha, a, &m, x, &one, &beta, y, &one);
}

void hermitian_eigen(Eigen::MatrixXcd& a, Eigen::VectorXd& w) {
  const int n = static_cast<int>(a.rows());
  w.resize(n);
  if (n == 0) return;
  // Workspace query first (lwork = -1), then the decomposition.
  int lwork = -1, lrwork = -1, liwork = -1, info = 0;
  std::complex<double> work_size;
  double rwork_size;
  int iwork_size;
  const char jobz = 'V', uplo = 'L';
  zheevd_(&jobz, &uplo, &n, a.data(), &n, w.data(), &work_size, &lwork, &rwork_size, &lrwork, &iwork_size, &liwork,
          &info);
  lwork = static_cast<int>(work_size.real()) + 1;
  lrwork = static_cast<int>(rwork_size) + 1;
  liwork = iwork_size + 1;
  std::vector<std::complex<double>> work(lwork);
  std::vector<double> rwork(lrwork);
  std::vector<int> iwork(liwork);
  zheevd_(&jobz, &uplo, &n, a.data(), &n, w.data(), work.data(), &lwork, rwork.data(), &lrwork, iwork.data(),
          &liwork, &info);
  if (info != 0) throw SolverError("dense Hermitian eigen solver (zheevd) failed, info=" + std::to_string(info));
}

namespace {
// Guards may live in several threads at once (a basis computed by a worker thread while the caller solves): the
// first one sets OpenBLAS single-threaded, the last one restores the count it found.
std::mutex blas_threads_mutex;
int guards_alive = 0;
int threads_before = 0;
}  // namespace

SingleThreadedBlas::SingleThreadedBlas() {
  if (openblas_get_num_threads == nullptr || openblas_set_num_threads == nullptr) return;
  const std::lock_guard<std::mutex> lock(blas_threads_mutex);
  active_ = true;
  if (guards_alive++ == 0) {
    threads_before = openblas_get_num_threads();
    if (threads_before > 1) openblas_set_num_threads(1);
  }
}

SingleThreadedBlas::~SingleThreadedBlas() {
  if (!active_) return;
  const std::lock_guard<std::mutex> lock(blas_threads_mutex);
  if (--guards_alive == 0 && threads_before > 1) openblas_set_num_threads(threads_before);
}

}  // namespace nfield
