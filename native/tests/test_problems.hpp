// Test problems of the native unit tests: a pencil with a closed-form spectrum and a mesh generator.
#pragma once
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "nfield/mesh.hpp"
#include "nfield/operators.hpp"

namespace nfield::test {

/// The connection Laplacian of a cycle of N nodes with transport r = exp(i holonomy / N) on every edge
/// (total holonomy `holonomy` around the cycle), in the complex form of operators.hpp:
///   E(z) = sum_j |r z_j - z_{j+1}|^2 = z^H S z,  S_jj = 2,  S_{j,j+1} = -conj(r),  S_{j+1,j} = -r.
/// With z_j = exp(i t j) the eigen-equation closes around the cycle for t = (2 pi m + holonomy) / N, so
/// the eigenvalues are exactly 2 - 2 cos((2 pi m + holonomy) / N), m = 0..N-1 (simple unless holonomy is
/// a multiple of pi).
inline ComplexSparse cycle_laplacian(int N, double holonomy) {
  const Complex r = std::polar(1.0, holonomy / N);
  std::vector<Eigen::Triplet<Complex>> t;
  for (int j = 0; j < N; ++j) {
    const int next = (j + 1) % N;
    t.emplace_back(j, j, 2.0);
    t.emplace_back(j, next, -std::conj(r));
    t.emplace_back(next, j, -r);
  }
  ComplexSparse S(N, N);
  S.setFromTriplets(t.begin(), t.end());
  S.makeCompressed();
  return S;
}

/// The closed-form eigenvalues of cycle_laplacian divided by a uniform mass c, ascending.
inline Eigen::VectorXd cycle_eigenvalues(int N, double holonomy, double c) {
  Eigen::VectorXd v(N);
  for (int m = 0; m < N; ++m) v[m] = (2.0 - 2.0 * std::cos((2.0 * M_PI * m + holonomy) / N)) / c;
  std::sort(v.data(), v.data() + N);
  return v;
}

/// A closed torus of a x b vertices (2ab faces) with radial noise of +-5 % on the tube radius (seeded):
/// curved, without symmetry, so its n-field spectrum has no exact multiplicities and a non-trivial
/// holonomy (no kernel).
inline std::shared_ptr<TriangleMesh> bumpy_torus(int a, int b, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> noise(-0.05, 0.05);
  Positions P(a * b, 3);
  Triangles T(2 * a * b, 3);
  for (int i = 0; i < a; ++i)
    for (int j = 0; j < b; ++j) {
      const double s = 2 * M_PI * i / a, t = 2 * M_PI * j / b, r = 0.35 * (1 + noise(rng));
      P.row(i * b + j) << (1 + r * std::cos(t)) * std::cos(s), (1 + r * std::cos(t)) * std::sin(s), r * std::sin(t);
    }
  int f = 0;
  for (int i = 0; i < a; ++i)
    for (int j = 0; j < b; ++j) {
      const int v00 = i * b + j, v10 = ((i + 1) % a) * b + j, v01 = i * b + (j + 1) % b,
                v11 = ((i + 1) % a) * b + (j + 1) % b;
      T.row(f++) << v00, v10, v11;
      T.row(f++) << v00, v11, v01;
    }
  return std::make_shared<TriangleMesh>(P, T);
}

/// All eigenvalues of the pencil (S, diag(mass)) by Eigen's generalized solver: an implementation
/// independent of LAPACK's zheevd, to compare against.
inline Eigen::VectorXd reference_eigenvalues(const ComplexSparse& S, const Eigen::VectorXd& mass) {
  const Eigen::MatrixXcd A = Eigen::MatrixXcd(S);
  const Eigen::MatrixXcd B = mass.cast<Complex>().asDiagonal();
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXcd> ges(A, B, Eigen::EigenvaluesOnly);
  return ges.eigenvalues();
}

/// max_ab |(Z^H M Z - I)_ab|: how far the columns of Z are from M-orthonormal.
inline double m_orthonormality_error(const Eigen::MatrixXcd& Z, const Eigen::VectorXd& mass) {
  const Eigen::MatrixXcd G = Z.adjoint() * mass.cast<Complex>().asDiagonal() * Z;
  return (G - Eigen::MatrixXcd::Identity(G.rows(), G.cols())).cwiseAbs().maxCoeff();
}

/// max_j ||S z_j - lambda_j M z_j|| (Euclidean norm of each residual column).
inline double max_residual(const ComplexSparse& S, const Eigen::VectorXd& mass, const Eigen::VectorXd& values,
                           const Eigen::MatrixXcd& Z) {
  double worst = 0;
  for (Eigen::Index j = 0; j < Z.cols(); ++j) {
    const Eigen::VectorXcd r = S * Z.col(j) - values[j] * mass.cast<Complex>().cwiseProduct(Z.col(j));
    worst = std::max(worst, r.norm());
  }
  return worst;
}

/// The cross-field (n = 4) pencil (S, M) of a bumpy torus with its dense reference spectrum: the common
/// problem of the eigen-solver tests. `N` unknowns, `norm_a` = max |lambda| (the scale of rounding errors).
struct TorusPencil {
  TorusPencil(int a, int b, unsigned seed) : mesh(bumpy_torus(a, b, seed)), ops(mesh, 4) {}

  std::shared_ptr<TriangleMesh> mesh;
  FieldOperators ops;
  const ComplexSparse& S = ops.harmonic_matrix();
  const Eigen::VectorXd& mass = ops.mass();
  Eigen::VectorXd values = reference_eigenvalues(S, mass);
  int N = ops.num_unknowns();
  double norm_a = values.cwiseAbs().maxCoeff();
};

}  // namespace nfield::test
