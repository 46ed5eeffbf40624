#include "nfield/slice_lanczos.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "nfield/blas.hpp"
#include "nfield/errors.hpp"

namespace nfield {

using Eigen::MatrixXcd;
using Eigen::VectorXd;

SliceLanczos::SliceLanczos(const ShiftedFactor& factor, const VectorXd& d, double lo, double hi, int count,
                           int block, double tol, int max_restarts, std::function<void(double)> report,
                           std::uint64_t seed)
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

Eigenpairs SliceLanczos::run() {
  Eigenpairs out;
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

void SliceLanczos::start_block(int cur) {
  std::normal_distribution<double> normal;
  MatrixXcd R0(N_, b_), X;
  for (Eigen::Index j = 0; j < R0.cols(); ++j)
    for (Eigen::Index i = 0; i < R0.rows(); ++i) R0(i, j) = Complex(normal(rng_), normal(rng_));
  apply(R0.data(), b_, X);
  if (cur > 0) orthogonalize_against(X, cur);
  orthonormalize(X, cur);
  V_.middleCols(cur, b_) = X;
}

void SliceLanczos::apply(const Complex* x, int cols, MatrixXcd& out) {
  rhs_.resize(N_, cols);
  for (int j = 0; j < cols; ++j)
    rhs_.col(j) = d_.cwiseProduct(Eigen::Map<const Eigen::VectorXcd>(x + static_cast<std::ptrdiff_t>(j) * N_, N_));
  factor_.solve_into(rhs_, out);
  for (int j = 0; j < cols; ++j) out.col(j).array() *= d_.array();
  solves_ += cols;
}

MatrixXcd SliceLanczos::orthogonalize_against(MatrixXcd& W, int j) {
  const int c = static_cast<int>(W.cols());
  MatrixXcd C = MatrixXcd::Zero(j, c), C2(j, c);
  for (int pass = 0; pass < 2; ++pass) {
    gemm('C', 'N', j, c, N_, 1.0, V_.data(), N_, W.data(), N_, 0.0, C2.data(), j);
    gemm('N', 'N', N_, c, j, -1.0, V_.data(), N_, C2.data(), j, 1.0, W.data(), N_);
    C += C2;
  }
  return C;
}

MatrixXcd SliceLanczos::orthonormalize(MatrixXcd& W, int j) {
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

void SliceLanczos::rotate(const MatrixXcd& Y, int cur, int keep) {
  const int chunk = 2048;
  MatrixXcd tmp(chunk, keep);
  for (int r0 = 0; r0 < N_; r0 += chunk) {
    const int rows = std::min(chunk, N_ - r0);
    gemm('N', 'N', rows, keep, cur, 1.0, V_.data() + r0, N_, Y.data(), static_cast<int>(Y.rows()), 0.0, tmp.data(),
         chunk);
    V_.block(r0, 0, rows, keep) = tmp.topRows(rows);
  }
}

}  // namespace nfield
