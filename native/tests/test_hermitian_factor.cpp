// The Cholesky factor of the exact spline's system (hermitian_factor.hpp): its solves, the forward substitutions
// restricted to the elimination tree and their Gram matrix, against dense linear algebra.
//
// Problem: V = E_2 + (4 pi / A)^2 M on a bumpy torus (1440 faces, so that the supernodal elimination tree has many
// levels). Right-hand sides: unit loads at a few faces (the constraint columns of the Schur system), a sparse
// column with several entries (an anchor's coupling column) and one touching two distant faces.
// Tolerances: a backward-stable solve has forward error <= kappa beta with beta <= c N eps; we allow c = 10 for
// ours and the dense reference each (kappa = the 2-norm condition number of V, from its eigenvalues). The Gram
// matrix b_i^H V^-1 b_j is a sum of N products of such entries: the same bound, relative to |B|^2 |V^-1|.
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

#include "check.hpp"
#include "nfield/hermitian_factor.hpp"
#include "test_problems.hpp"

using namespace nfield;
using namespace nfield::test;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

struct Problem {
  ComplexSparse V;
  Eigen::MatrixXcd dense, inverse;
  double kappa = 0, norm_inverse = 0;
};

Problem make_problem() {
  const auto mesh = bumpy_torus(36, 20, 5);  // 1440 faces
  const FieldOperators ops(mesh, 4);
  Problem p;
  const double shift = std::pow(4 * M_PI / mesh->total_area(), 2);
  p.V = ops.energy_matrix(2);
  for (int u = 0; u < ops.num_unknowns(); ++u) p.V.coeffRef(u, u) += shift * ops.mass()[u];
  p.V.makeCompressed();
  p.dense = Eigen::MatrixXcd(p.V);
  const Eigen::VectorXd mu = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd>(p.dense, Eigen::EigenvaluesOnly).eigenvalues();
  p.kappa = mu.maxCoeff() / mu.minCoeff();
  p.norm_inverse = 1 / mu.minCoeff();
  p.inverse = Eigen::LLT<Eigen::MatrixXcd>(p.dense).solve(Eigen::MatrixXcd::Identity(p.V.rows(), p.V.cols()));
  return p;
}

std::vector<SparseColumn> test_columns(const Problem& p) {
  const int N = static_cast<int>(p.V.rows());
  std::vector<SparseColumn> columns;
  for (int f : {0, 7, 500, 501, N / 2, N - 1}) columns.push_back({{f, Complex(1.0, 0.0)}});
  SparseColumn stencil;  // a column of V itself (an anchor's coupling column is one)
  for (ComplexSparse::InnerIterator it(p.V, 123); it; ++it) stencil.emplace_back(static_cast<int>(it.row()), it.value());
  columns.push_back(stencil);
  columns.push_back({{3, Complex(0.5, -2.0)}, {N - 40, Complex(-1.0, 0.25)}});  // two distant faces
  return columns;
}

Eigen::MatrixXcd dense_block(const std::vector<SparseColumn>& columns, int N) {
  Eigen::MatrixXcd B = Eigen::MatrixXcd::Zero(N, static_cast<Eigen::Index>(columns.size()));
  for (size_t j = 0; j < columns.size(); ++j)
    for (const auto& [i, v] : columns[j]) B(i, static_cast<Eigen::Index>(j)) += v;
  return B;
}

void forward_gram_and_backward(const Problem& p) {
  const int N = static_cast<int>(p.V.rows());
  const HermitianFactor factor(p.V, "test system", "");
  const std::vector<SparseColumn> columns = test_columns(p);
  const Eigen::MatrixXcd B = dense_block(columns, N);
  const double beta = 20 * N * kEps;  // ours and the reference's

  const HermitianFactor::Forward full = factor.forward(columns);
  const HermitianFactor::Forward gram_only = factor.forward(columns, false);
  CHECK_EQ(gram_only.h.size(), 0);
  CHECK_EQ(full.h.rows(), N);
  // The Gram matrix does not depend on whether h is kept: the same operations in the same order.
  CHECK((full.gram - gram_only.gram).cwiseAbs().maxCoeff() == 0.0);

  const Eigen::MatrixXcd reference_gram = B.adjoint() * p.inverse * B;
  const double scale = B.colwise().norm().maxCoeff() * B.colwise().norm().maxCoeff() * p.norm_inverse;
  CHECK_LE((full.gram - reference_gram).cwiseAbs().maxCoeff(), p.kappa * beta * scale);
  // Hermitian and positive definite (the columns are independent).
  CHECK_LE((full.gram - full.gram.adjoint()).cwiseAbs().maxCoeff(), p.kappa * beta * scale);
  CHECK(Eigen::LLT<Eigen::MatrixXcd>(0.5 * (full.gram + full.gram.adjoint())).info() == Eigen::Success);

  // h_j^H h_j = gram(j, j), and backward(h) = V^-1 B.
  for (Eigen::Index j = 0; j < B.cols(); ++j)
    CHECK_LE(std::abs(full.h.col(j).squaredNorm() - full.gram(j, j)), 1e3 * kEps * std::abs(full.gram(j, j)));
  const Eigen::MatrixXcd X = factor.backward(full.h);
  const Eigen::MatrixXcd reference = p.inverse * B;
  for (Eigen::Index j = 0; j < B.cols(); ++j)
    CHECK_LE((X.col(j) - reference.col(j)).norm(), p.kappa * beta * reference.col(j).norm());

  // h vanishes outside the supernodes a column reaches: a unit load at one face leaves most of h zero.
  const double zeros = static_cast<double>((full.h.col(0).array() == Complex(0.0, 0.0)).count());
  CHECK(zeros > 0.5 * N);
}

void solves_and_residual(const Problem& p) {
  const int N = static_cast<int>(p.V.rows());
  const HermitianFactor factor(p.V, "test system", "");
  const Eigen::MatrixXcd B = dense_block(test_columns(p), N);
  const double beta = 20 * N * kEps;
  const ComplexVector b = B.col(6);  // sparse: the forward substitution only on the supernodes it reaches
  const ComplexVector x = factor.solve(b);
  const ComplexVector reference = p.inverse * b;
  CHECK_LE((x - reference).norm(), p.kappa * beta * reference.norm());
  const ComplexVector dense_b = B * ComplexVector::Ones(B.cols()) + ComplexVector::Constant(N, Complex(0.25, -0.5));
  CHECK_LE((factor.solve(dense_b) - p.inverse * dense_b).norm(), p.kappa * beta * (p.inverse * dense_b).norm());
  CHECK(factor.solve(ComplexVector::Zero(N)).isZero(0.0));
  const Eigen::MatrixXcd X = factor.solve_block(B);
  CHECK_LE((X - p.inverse * B).norm(), p.kappa * beta * (p.inverse * B).norm());
  // relative_residual: max over entries of the largest real or imaginary part of b - V x, over that of b.
  const ComplexVector r = b - p.V * x;
  const auto largest = [](const ComplexVector& v) {
    double m = 0;
    for (Eigen::Index i = 0; i < v.size(); ++i) m = std::max({m, std::abs(v[i].real()), std::abs(v[i].imag())});
    return m;
  };
  CHECK_LE(std::abs(factor.relative_residual(b, x) - largest(r) / largest(b)), 1e-3 * largest(r) / largest(b));
  CHECK_LE(factor.relative_residual(b, x), 1e-13);
  ComplexVector wrong = x;
  wrong[5] += 1.0;
  CHECK(factor.relative_residual(b, wrong) > 1e-3);
  CHECK(factor.relative_residual(ComplexVector::Zero(N), ComplexVector::Zero(N)) == 0.0);
}

}  // namespace

int main() {
  const Problem p = make_problem();
  run("forward substitutions, Gram matrix and backward substitution against dense", [&] { forward_gram_and_backward(p); });
  run("solves and the residual probe against dense", [&] { solves_and_residual(p); });
  return finish();
}
