#include "nfield/shifted_factor.hpp"

#include <algorithm>
#include <cstddef>
#include <exception>
#include <thread>

#include "nfield/errors.hpp"

namespace nfield {

ShiftedFactor::ShiftedFactor(const ComplexSparse& S, const Eigen::VectorXd& mass, bool definite)
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

bool ShiftedFactor::factor(double sigma) {
  sigma_ = sigma;
  for (Eigen::Index j = 0; j < A_.cols(); ++j) A_.valuePtr()[diag_[j]] = base_diag_[j] - sigma * mass_[j];
  if (definite_) {
    llt_.factorize(A_);
    return llt_.info() == Eigen::Success;
  }
  ldl_.factorize(A_);
  return ldl_.info() == Eigen::Success;
}

void ShiftedFactor::solve_into(const Eigen::MatrixXcd& B, Eigen::MatrixXcd& X) const {
  if (definite_)
    X = llt_.solve(B);
  else
    ldl_solve(B, X);
}

void ShiftedFactor::ldl_solve(const Eigen::MatrixXcd& B, Eigen::MatrixXcd& X) const {
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

int ShiftedFactor::LDL::negative_pivots() const {
  const cholmod_factor* L = this->m_cholmodFactor;
  if (L == nullptr || L->is_super || L->is_ll) throw SolverError("spectral basis: no LDL factor for the inertia");
  const int* p = static_cast<const int*>(L->p);
  const double* x = static_cast<const double*>(L->x);  // complex interleaved; D on the column heads
  int neg = 0;
  for (std::size_t j = 0; j < L->n; ++j) neg += x[2 * static_cast<std::ptrdiff_t>(p[j])] < 0;
  return neg;
}

}  // namespace nfield
