#include "nfield/dense_eigen.hpp"

#include <string>

#include "nfield/blas.hpp"
#include "nfield/errors.hpp"

namespace nfield {

Eigenpairs dense_eigenpairs(const ComplexSparse& S, const Eigen::VectorXd& mass, int k) {
  const Eigen::Index N = S.rows();
  if (k < 1 || k > N)
    throw ParameterError("dense eigen solver: k=" + std::to_string(k) + " must lie in [1, " + std::to_string(N) + "]");
  const Eigen::VectorXcd inv_sqrt = mass.cwiseSqrt().cwiseInverse().cast<Complex>();
  Eigen::MatrixXcd A = inv_sqrt.asDiagonal() * Eigen::MatrixXcd(S) * inv_sqrt.asDiagonal();
  A = 0.5 * (A + A.adjoint()).eval();  // exactly Hermitian: zheevd reads one triangle only
  Eigen::VectorXd w;
  hermitian_eigen(A, w);
  Eigenpairs out;
  out.values = w.head(k);
  out.vectors = inv_sqrt.asDiagonal() * A.leftCols(k);
  return out;
}

}  // namespace nfield
