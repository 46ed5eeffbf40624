// The shifted factor S - sigma M (shifted_factor.hpp): its inertia against closed-form and dense
// eigenvalue counts (Sylvester's law), and its blocked LDL^H / LL^H solves against a dense LU solve.
//
// Tolerances: the counts are integers and must be exact. A solve with backward error beta has forward
// error <= kappa beta (kappa the 2-norm condition number of S - sigma M, computed here from its
// eigenvalues); a stable sparse factorization has beta <= c N eps with a modest c, and we allow c = 10,
// for our solve and the dense reference each.
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <random>

#include "check.hpp"
#include "nfield/errors.hpp"
#include "nfield/shifted_factor.hpp"
#include "test_problems.hpp"

using namespace nfield;
using namespace nfield::test;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

Eigen::MatrixXcd random_block(int rows, int cols, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  Eigen::MatrixXcd B(rows, cols);
  for (int j = 0; j < cols; ++j)
    for (int i = 0; i < rows; ++i) B(i, j) = Complex(normal(rng), normal(rng));
  return B;
}

int count_below(const Eigen::VectorXd& values, double sigma) {
  return static_cast<int>((values.array() < sigma).count());
}

/// Compares X = (S - sigma M)^-1 B from the factor with a dense LU solve (bounds above).
void check_solve(const ComplexSparse& S, const Eigen::VectorXd& mass, const ShiftedFactor& factor, int cols) {
  const int N = static_cast<int>(S.rows());
  const Eigen::MatrixXcd K = Eigen::MatrixXcd(S) - Eigen::MatrixXcd(mass.cast<Complex>().asDiagonal()) * factor.sigma();
  const Eigen::VectorXd mu = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(K, Eigen::EigenvaluesOnly).eigenvalues();
  const double norm_k = mu.cwiseAbs().maxCoeff(), kappa = norm_k / mu.cwiseAbs().minCoeff();
  const Eigen::MatrixXcd B = random_block(N, cols, 11);
  Eigen::MatrixXcd X;
  factor.solve_into(B, X);
  const Eigen::MatrixXcd reference = Eigen::PartialPivLU<Eigen::MatrixXcd>(K).solve(B);
  const double beta = 10 * N * kEps;
  CHECK_LE((K * X - B).norm() / (norm_k * X.norm()), beta);                      // backward error
  CHECK_LE((X - reference).norm() / reference.norm(), 2 * kappa * beta);          // forward error
}

void inertia_of_the_cycle_is_exact() {
  // Closed-form eigenvalues 2 - 2 cos((2 pi m + h) / N): the negative pivots of S - sigma M count them.
  const int N = 300;
  const double holonomy = 0.7;
  const ComplexSparse S = cycle_laplacian(N, holonomy);
  const Eigen::VectorXd mass = Eigen::VectorXd::Ones(N);
  const Eigen::VectorXd exact = cycle_eigenvalues(N, holonomy, 1.0);
  ShiftedFactor ldl(S, mass, false);
  for (double sigma : {-0.5, 0.0123, 0.5, 1.7, 3.3, 4.5}) {
    CHECK_LE(1e-6, (exact.array() - sigma).abs().minCoeff());  // sigma is not (nearly) an eigenvalue
    CHECK(ldl.factor(sigma));
    CHECK_EQ(ldl.negative_pivots(), count_below(exact, sigma));
  }
}

void indefinite_factor_on_a_mesh() {
  // Non-uniform mass, curved mesh: sigma halfway between the 41st and 42nd eigenvalues.
  const auto mesh = bumpy_torus(12, 15, 7);  // 360 faces
  const FieldOperators ops(mesh, 4);
  const ComplexSparse& S = ops.harmonic_matrix();
  const Eigen::VectorXd& mass = ops.mass();
  const Eigen::VectorXd values = reference_eigenvalues(S, mass);
  ShiftedFactor ldl(S, mass, false);
  const double sigma = 0.5 * (values[40] + values[41]);
  CHECK(ldl.factor(sigma));
  CHECK_EQ(ldl.negative_pivots(), 41);
  // 21 right-hand sides: groups of 8 with a remainder, split over two threads.
  check_solve(S, mass, ldl, 21);
  // One thread computes every column with the same operations: bit-identical.
  Eigen::MatrixXcd X2, X1;
  const Eigen::MatrixXcd B = random_block(ops.num_unknowns(), 21, 12);
  ldl.solve_into(B, X2);
  ldl.set_solve_threads(1);
  ldl.solve_into(B, X1);
  CHECK(X1 == X2);
  // Refactoring at another shift reuses the analysis.
  const double low = 0.5 * (values[4] + values[5]);
  CHECK(ldl.factor(low));
  CHECK_EQ(ldl.negative_pivots(), 5);
  check_solve(S, mass, ldl, 3);
}

void definite_factor() {
  const auto mesh = bumpy_torus(12, 15, 7);
  const FieldOperators ops(mesh, 4);
  const ComplexSparse& S = ops.harmonic_matrix();
  const Eigen::VectorXd& mass = ops.mass();
  const Eigen::VectorXd values = reference_eigenvalues(S, mass);
  ShiftedFactor llt(S, mass, true);
  CHECK(llt.factor(-1e-2 * ops.eigenvalue_unit(1)));  // below the spectrum: positive definite
  check_solve(S, mass, llt, 9);
  CHECK_THROWS(SolverError, "no LDL factor", llt.negative_pivots());
  // Inside the spectrum S - sigma M is indefinite: LL^H must report the breakdown, not return garbage.
  CHECK(!llt.factor(0.5 * (values[10] + values[11])));
}

}  // namespace

int main() {
  run("inertia_of_the_cycle_is_exact", inertia_of_the_cycle_is_exact);
  run("indefinite_factor_on_a_mesh", indefinite_factor_on_a_mesh);
  run("definite_factor", definite_factor);
  return finish();
}
