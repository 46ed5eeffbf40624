// The spectral basis driver (spectrum_slicing.hpp, SpectralBasis::compute) against a dense
// eigen-decomposition: several slices solved on two threads and glued, the single-shift case, the dense
// fallback for a k the slicing cannot take, progress and cancellation.
//
// Tolerances (tol = 1e-10, see test_slice_lanczos.cpp for the derivation): an eigenvalue computed from a
// shift sigma is within tol |lambda - sigma| of the true one; every shift lies in [-unit, B_p] and every
// wanted eigenvalue below B_p <= lambda_{k+10} (the last boundary overshoots k by a few pairs), so the
// bound is tol lambda_{k+10} plus the reference's 10 N eps ||A||. Residuals are bounded by
// tol ||S - sigma M|| / sqrt(min mass) <= tol (||S|| + lambda_{k+10} max mass) / sqrt(min mass), times 2 for
// rounding. Across slices the glue step re-orthogonalizes every pair whose M-inner product exceeds 1e-12;
// within a slice the loss is O(N eps): we allow 100 N eps.
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <thread>
#include <vector>

#include "check.hpp"
#include "nfield/basis_memory.hpp"
#include "nfield/dense_eigen.hpp"
#include "nfield/errors.hpp"
#include "nfield/spectral_basis.hpp"
#include "nfield/spectrum_slicing.hpp"
#include "test_problems.hpp"

using namespace nfield;
using namespace nfield::test;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kTol = 1e-10;

struct Problem : TorusPencil {
  Problem() : TorusPencil(18, 25, 13) {}  // 900 faces
  double norm_s = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(Eigen::MatrixXcd(S), Eigen::EigenvaluesOnly)
                      .eigenvalues()
                      .cwiseAbs()
                      .maxCoeff();

  void check(const SpectralBasis& basis, int k) const {
    CHECK_EQ(basis.size(), k);
    const double top = values[std::min(k + 10, N - 1)];
    const Eigen::VectorXd& v = basis.values();
    CHECK(std::is_sorted(v.data(), v.data() + v.size()));
    double value_error = 0;
    for (int i = 0; i < std::min(k, basis.size()); ++i) value_error = std::max(value_error, std::abs(v[i] - values[i]));
    CHECK_LE(value_error, kTol * top + 10 * N * kEps * norm_a);
    const Eigen::MatrixXcd U = basis.vectors();
    const double residual = max_residual(S, mass, v, U);
    CHECK_LE(residual, 2 * kTol * (norm_s + top * mass.maxCoeff()) / std::sqrt(mass.minCoeff()));
    // M-orthonormality. Pairs from one Lanczos run (one slice, or glued across a boundary) are orthonormal
    // to O(N eps): 100 N eps. Pairs from different shifts are orthogonal up to their residuals: with
    // S z_i = lambda_i M z_i + r_i and S Hermitian, (lambda_i - lambda_j) z_j^H M z_i = z_i^H r_j conj - z_j^H r_i,
    // so |z_j^H M z_i| <= 2 max ||r|| max ||z|| / |lambda_i - lambda_j|, with ||z|| <= 1 / sqrt(min mass).
    const Eigen::MatrixXcd G = U.adjoint() * mass.cast<Complex>().asDiagonal() * U;
    double worst = 0;  // largest |G - I| relative to its bound
    for (int i = 0; i < G.rows(); ++i)
      for (int j = 0; j < G.cols(); ++j) {
        const double error = std::abs(G(i, j) - (i == j ? 1.0 : 0.0));
        const double from_residuals =
            i == j ? 0.0 : 2 * residual / std::sqrt(mass.minCoeff()) / std::abs(v[i] - v[j]);
        worst = std::max(worst, error / std::max(100 * N * kEps, from_residuals));
      }
    CHECK_LE(worst, 1.0);
    if (verbose()) {
      Eigen::Index wi = 0, wj = 0;
      (G - Eigen::MatrixXcd::Identity(G.rows(), G.cols())).cwiseAbs().maxCoeff(&wi, &wj);
      std::printf("  largest |G - I| = %.3g at (%d, %d), lambda %.6g and %.6g\n",
                  std::abs(G(wi, wj) - (wi == wj ? 1.0 : 0.0)), int(wi), int(wj), v[wi], v[wj]);
    }
  }
};

/// One problem for every case (its dense reference decomposition is the slow part of the test).
const Problem& problem() {
  static const Problem p;
  return p;
}

SpectralBasisOptions sliced_options() {
  SpectralBasisOptions options;
  options.dense_limit = 0;  // force the iterative path on a small problem
  options.slice_size = 40;
  return options;
}

void several_slices_on_two_threads() {
  const Problem& p = problem();
  const int k = 150;  // > 1.5 slice: about four slices
  std::vector<double> reported;
  std::vector<std::thread::id> threads;
  const SpectralBasis basis = SpectralBasis::compute(p.ops, k, sliced_options(), [&](double f) {
    reported.push_back(f);
    threads.push_back(std::this_thread::get_id());
    return true;
  });
  p.check(basis, k);
  // Progress: from the calling thread only, non-decreasing, ending at 1.
  CHECK(!reported.empty());
  CHECK(std::is_sorted(reported.begin(), reported.end()));
  CHECK(!reported.empty() && reported.back() == 1.0);
  for (const auto& id : threads) CHECK(id == std::this_thread::get_id());
}

void single_shift_for_small_k() {
  const Problem& p = problem();
  p.check(SpectralBasis::compute(p.ops, 50, sliced_options()), 50);  // k <= 1.5 slice: one shift
}

void cancel_stops_the_workers() {
  const Problem& p = problem();
  CHECK_THROWS(Cancelled, "cancelled",
               SpectralBasis::compute(p.ops, 150, sliced_options(), [](double f) { return f < 0.2; }));
}

void k_beyond_the_slicing_takes_the_dense_path() {
  // (N - 1) / 3 is the most the slicing takes; a larger k is served by the dense path (use_dense_eigen),
  // bit-identical to dense_eigenpairs.
  const Problem& p = problem();
  const int k = sliced_max_k(p.N) + 5;
  const SpectralBasis basis = SpectralBasis::compute(p.ops, k, sliced_options());
  const Eigenpairs dense = dense_eigenpairs(p.S, p.mass, k);
  CHECK(basis.values() == dense.values);
  CHECK(basis.vectors() == dense.vectors);
  CHECK(use_dense_eigen(p.N, k, sliced_max_k(p.N), 0));
  CHECK(!use_dense_eigen(kDenseEigenMax + 1, k, sliced_max_k(kDenseEigenMax + 1), 0));
  // sliced_eigenpairs itself refuses such a k with a message naming the limit.
  CHECK_THROWS(ParameterError, "too close to the problem size",
               sliced_eigenpairs(p.S, p.mass, k, p.ops.eigenvalue_unit(1), sliced_options(), {}));
}

}  // namespace

int main() {
  run("several_slices_on_two_threads", several_slices_on_two_threads);
  run("single_shift_for_small_k", single_shift_for_small_k);
  run("cancel_stops_the_workers", cancel_stops_the_workers);
  run("k_beyond_the_slicing_takes_the_dense_path", k_beyond_the_slicing_takes_the_dense_path);
  return finish();
}
