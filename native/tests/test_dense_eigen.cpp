// The dense eigen path (dense_eigen.hpp) against a closed-form spectrum and an independent solver, and
// the claim that lowest_eigenpairs and the spectral basis share it below the switch-over.
//
// Tolerances: zheevd is backward stable, so every computed eigenvalue is within c N eps ||A|| of an exact
// one and the eigenvectors are orthonormal to c N eps, with a modest c; we allow c = 10 (A = M^-1/2 S
// M^-1/2, ||A|| = its largest eigenvalue). Any algorithmic error (a wrong scaling by M, a missed
// symmetrization, a lost multiplicity) is orders of magnitude larger.
#include <Eigen/Core>
#include <cmath>
#include <limits>

#include "check.hpp"
#include "nfield/dense_eigen.hpp"
#include "nfield/errors.hpp"
#include "nfield/spectral_basis.hpp"
#include "nfield/spectrum.hpp"
#include "test_problems.hpp"

using namespace nfield;
using namespace nfield::test;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

void closed_form_cycle() {
  // Uniform mass c: the pencil's eigenvalues are the cycle's divided by c.
  const int N = 64;
  const double holonomy = 1.3, c = 0.25;
  const ComplexSparse S = cycle_laplacian(N, holonomy);
  const Eigen::VectorXd mass = Eigen::VectorXd::Constant(N, c);
  const Eigenpairs all = dense_eigenpairs(S, mass, N);
  const Eigen::VectorXd exact = cycle_eigenvalues(N, holonomy, c);
  const double norm_a = exact.maxCoeff();  // ||A|| = 4 / c at most
  CHECK_LE((all.values - exact).cwiseAbs().maxCoeff(), 10 * N * kEps * norm_a);
  CHECK_LE(m_orthonormality_error(all.vectors, mass), 10 * N * kEps);
  // ||S z - lambda M z|| = ||M^1/2 (A y - lambda y)|| <= sqrt(c) 10 N eps ||A||.
  CHECK_LE(max_residual(S, mass, all.values, all.vectors), 10 * N * kEps * norm_a * std::sqrt(c));

  // k < N returns the k smallest pairs of the same decomposition.
  const Eigenpairs first = dense_eigenpairs(S, mass, 10);
  CHECK_EQ(first.values.size(), 10);
  CHECK_EQ(first.vectors.rows(), N);
  CHECK_EQ(first.vectors.cols(), 10);
  CHECK_LE((first.values - exact.head(10)).cwiseAbs().maxCoeff(), 10 * N * kEps * norm_a);
}

void mesh_pencil_against_independent_solver() {
  // Non-uniform mass (face areas) on a curved mesh: compare with Eigen's generalized solver (Cholesky of
  // M, then its own tridiagonal QR: independent of LAPACK). Both are within 10 N eps ||A|| of the truth.
  const auto mesh = bumpy_torus(8, 10, 3);
  const FieldOperators ops(mesh, 4);
  const ComplexSparse& S = ops.harmonic_matrix();
  const Eigen::VectorXd& mass = ops.mass();
  const int N = ops.num_unknowns();
  const Eigenpairs all = dense_eigenpairs(S, mass, N);
  const Eigen::VectorXd reference = reference_eigenvalues(S, mass);
  const double norm_a = reference.cwiseAbs().maxCoeff();
  CHECK_LE((all.values - reference).cwiseAbs().maxCoeff(), 2 * 10 * N * kEps * norm_a);
  CHECK(std::is_sorted(all.values.data(), all.values.data() + N));
  CHECK_LE(m_orthonormality_error(all.vectors, mass), 10 * N * kEps);
  CHECK_LE(max_residual(S, mass, all.values, all.vectors), 10 * N * kEps * norm_a * std::sqrt(mass.maxCoeff()));
  // S is positive semi-definite: no eigenvalue below -10 N eps ||A||.
  CHECK_LE(-all.values[0], 10 * N * kEps * norm_a);
}

void bad_k_is_a_parameter_error() {
  const ComplexSparse S = cycle_laplacian(8, 0.5);
  const Eigen::VectorXd mass = Eigen::VectorXd::Ones(8);
  CHECK_THROWS(ParameterError, "k=0", dense_eigenpairs(S, mass, 0));
  CHECK_THROWS(ParameterError, "k=9", dense_eigenpairs(S, mass, 9));
}

void one_path_below_the_switch_over() {
  // lowest_eigenpairs and SpectralBasis::compute both take dense_eigenpairs at or below the switch-over:
  // the same floating-point operations, so bit-identical eigenvalues.
  const auto mesh = bumpy_torus(10, 12, 5);  // 240 faces
  const FieldOperators ops(mesh, 2);
  CHECK(ops.num_unknowns() <= kDenseEigenLimit);
  const int k = 20;
  const Eigenpairs dense = dense_eigenpairs(ops.harmonic_matrix(), ops.mass(), k);
  const Eigenpairs lowest = lowest_eigenpairs(ops, k);
  const SpectralBasis basis = SpectralBasis::compute(ops, k);
  CHECK(lowest.values == dense.values);
  CHECK(basis.values() == dense.values);
  CHECK(basis.vectors() == dense.vectors);
}

}  // namespace

int main() {
  run("closed_form_cycle", closed_form_cycle);
  run("mesh_pencil_against_independent_solver", mesh_pencil_against_independent_solver);
  run("bad_k_is_a_parameter_error", bad_k_is_a_parameter_error);
  run("one_path_below_the_switch_over", one_path_below_the_switch_over);
  return finish();
}
