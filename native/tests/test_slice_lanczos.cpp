// One spectrum slice by thick-restart block Lanczos (slice_lanczos.hpp) against a dense eigen-decomposition.
//
// Tolerances (tol = 1e-10, the convergence tolerance |T y - theta y| <= tol |theta|, y = M^1/2 z unit):
//  - eigenvalues: for Hermitian T some eigenvalue theta* lies within ||T y - theta y|| of theta, so
//    |lambda - lambda*| = |theta - theta*| / |theta theta*| <= tol / |theta*| = tol |lambda* - sigma|;
//    plus the dense reference's own error 10 N eps ||A|| (test_dense_eigen.cpp);
//  - residual: S z - lambda M z = -(1/theta) (S - sigma M) M^-1/2 (T y - theta y), so
//    ||S z - lambda M z|| <= tol ||S - sigma M|| / sqrt(min mass); a factor 2 for rounding;
//  - M-orthonormality: z = M^-1/2 V y with V orthonormal by CGS2 + SVQB (loss O(N eps)) and y orthonormal
//    from zheevd: 100 N eps.
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <thread>

#include "check.hpp"
#include "nfield/errors.hpp"
#include "nfield/shifted_factor.hpp"
#include "nfield/slice_lanczos.hpp"
#include "test_problems.hpp"

using namespace nfield;
using namespace nfield::test;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kTol = 1e-10;

struct Problem : TorusPencil {
  Problem() : TorusPencil(16, 20, 9) {}  // 640 faces
  Eigen::VectorXd d = mass.cwiseSqrt();

  double norm_shifted(double sigma) const {  // ||S - sigma M||_2
    const Eigen::MatrixXcd K = Eigen::MatrixXcd(S) - Eigen::MatrixXcd(mass.cast<Complex>().asDiagonal()) * sigma;
    return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(K, Eigen::EigenvaluesOnly).eigenvalues().cwiseAbs().maxCoeff();
  }

  /// Checks pairs against values[first, first + count) for a run at shift sigma.
  void check(const Eigenpairs& r, int first, int count, double sigma) const {
    CHECK_EQ(r.values.size(), count);
    CHECK_EQ(r.vectors.cols(), count);
    CHECK(std::is_sorted(r.values.data(), r.values.data() + r.values.size()));
    double worst = 0;  // largest eigenvalue error relative to its bound
    for (int i = 0; i < std::min<int>(count, static_cast<int>(r.values.size())); ++i)
      worst = std::max(worst, std::abs(r.values[i] - values[first + i]) /
                                  (kTol * std::abs(values[first + i] - sigma) + 10 * N * kEps * norm_a));
    CHECK_LE(worst, 1.0);
    CHECK_LE(m_orthonormality_error(r.vectors, mass), 100 * N * kEps);
    CHECK_LE(max_residual(S, mass, r.values, r.vectors), 2 * kTol * norm_shifted(sigma) / std::sqrt(mass.minCoeff()));
  }
};

/// One problem for every case (its dense reference decomposition is the slow part of the test).
const Problem& problem() {
  static const Problem p;
  return p;
}

void interior_slice() {
  // The 30 eigenvalues in [lo, hi) between lambda_29 and lambda_60, from a shift in the middle: the
  // factor's inertia gives the count, Lanczos must find exactly those.
  const Problem& p = problem();
  const double lo = 0.5 * (p.values[29] + p.values[30]), hi = 0.5 * (p.values[59] + p.values[60]);
  ShiftedFactor ldl(p.S, p.mass, false);
  CHECK(ldl.factor(lo));
  const int below_lo = ldl.negative_pivots();
  CHECK(ldl.factor(hi));
  const int count = ldl.negative_pivots() - below_lo;
  CHECK_EQ(below_lo, 30);
  CHECK_EQ(count, 30);
  const double sigma = 0.5 * (lo + hi);
  CHECK(ldl.factor(sigma));
  int reports = 0;
  SliceLanczos lanczos(ldl, p.d, lo, hi, count, 8, kTol, 200, [&](double) { ++reports; }, 1);
  const Eigenpairs r = lanczos.run();
  p.check(r, 30, 30, sigma);
  for (int i = 0; i < r.values.size(); ++i) CHECK(r.values[i] >= lo && r.values[i] < hi);
  CHECK(reports > 0);
  CHECK(lanczos.solves() > 0);
}

void nearest_to_a_shift_below_the_spectrum() {
  // Unbounded mode with the definite factor: the 12 eigenvalues nearest sigma < 0 are the 12 smallest.
  const Problem& p = problem();
  const double sigma = -1e-2 * p.ops.eigenvalue_unit(1);
  ShiftedFactor llt(p.S, p.mass, true);
  CHECK(llt.factor(sigma));
  SliceLanczos lanczos(llt, p.d, -INFINITY, INFINITY, 12, 8, kTol, 200, [](double) {}, 2);
  p.check(lanczos.run(), 0, 12, sigma);
}

void too_many_pairs_and_cancellation() {
  const Problem& p = problem();
  ShiftedFactor llt(p.S, p.mass, true);
  CHECK(llt.factor(-1e-2 * p.ops.eigenvalue_unit(1)));
  // The Krylov space for N - 10 pairs (plus their 10 % margin and a block) does not fit in N dimensions.
  CHECK_THROWS(ParameterError, "too many",
               SliceLanczos(llt, p.d, -INFINITY, INFINITY, p.N - 10, 8, kTol, 200, [](double) {}, 3));
  // The report callback stops the iteration by throwing (what the driver does on cancel).
  SliceLanczos lanczos(llt, p.d, -INFINITY, INFINITY, 40, 8, kTol, 200,
                       [](double) { throw Cancelled("stopped by the test"); }, 4);
  CHECK_THROWS(Cancelled, "stopped by the test", lanczos.run());
}

}  // namespace

int main() {
  run("interior_slice", interior_slice);
  run("nearest_to_a_shift_below_the_spectrum", nearest_to_a_shift_below_the_spectrum);
  run("too_many_pairs_and_cancellation", too_many_pairs_and_cancellation);
  return finish();
}
