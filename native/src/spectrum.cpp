#include "nfield/spectrum.hpp"

#include <Eigen/CholmodSupport>
#include <Spectra/SymEigsShiftSolver.h>
#include <algorithm>
#include <cmath>

#include "nfield/dense_eigen.hpp"
#include "nfield/errors.hpp"

namespace nfield {
namespace {

/// Shift-invert operator of the realified standard problem A = M^-1/2 S M^-1/2 for Spectra:
/// y = (A - sigma I)^-1 x = M^1/2 (S - sigma M)^-1 M^1/2 x, computed with a complex factorization.
/// Real vectors interleave (Re z_0, Im z_0, Re z_1, ...).
class RealifiedShiftInvert {
 public:
  using Scalar = double;
  RealifiedShiftInvert(const ComplexSparse& S, const Eigen::VectorXd& mass, const ProgressCallback& progress,
                       int expected_ops)
      : S_(S), sqrt_mass_(mass.cwiseSqrt()), mass_(mass), progress_(progress), expected_ops_(expected_ops) {}
  Eigen::Index rows() const { return 2 * S_.rows(); }
  Eigen::Index cols() const { return 2 * S_.rows(); }
  void set_shift(double sigma) {
    ComplexSparse A = S_;
    for (int i = 0; i < A.rows(); ++i) A.coeffRef(i, i) -= sigma * mass_[i];
    factor_.compute(A);
    if (factor_.info() != Eigen::Success)
      throw SolverError("eigen solver: factorization of S - sigma M failed (matrix not positive definite)");
  }
  void perform_op(const double* x_in, double* y_out) const {
    if (progress_ && (++ops_ % 8 == 0) &&
        !progress_(std::min(0.95, static_cast<double>(ops_) / std::max(1, expected_ops_))))
      throw Cancelled("eigen computation cancelled");
    const Eigen::Index N = S_.rows();
    ComplexVector z(N);
    for (Eigen::Index i = 0; i < N; ++i) z[i] = Complex(x_in[2 * i], x_in[2 * i + 1]) * sqrt_mass_[i];
    ComplexVector y = factor_.solve(z);
    for (Eigen::Index i = 0; i < N; ++i) {
      const Complex v = y[i] * sqrt_mass_[i];
      y_out[2 * i] = v.real();
      y_out[2 * i + 1] = v.imag();
    }
  }

 private:
  const ComplexSparse& S_;
  Eigen::VectorXd sqrt_mass_, mass_;
  const ProgressCallback& progress_;
  int expected_ops_;
  mutable int ops_ = 0;
  Eigen::CholmodSupernodalLLT<ComplexSparse, Eigen::Lower> factor_;
};

/// Lanczos on the realified problem. Every complex eigenpair appears there twice (z and i z); we group
/// numerically equal Ritz values and keep the rank of their complex span, so complex multiplicities
/// (e.g. 2l+1 on a sphere) are reported correctly.
Eigenpairs lanczos_eigenpairs(const ComplexSparse& S, const Eigen::VectorXd& mass, int k, double unit,
                              const ProgressCallback& progress) {
  const int N = static_cast<int>(S.rows());
  const int nev = std::min(2 * k + 1, 2 * N - 2);
  const int ncv = std::min(2 * N, std::max(2 * nev + 1, nev + 24));
  RealifiedShiftInvert op(S, mass, progress, 4 * ncv);
  const double sigma = -1e-2 * unit;
  Spectra::SymEigsShiftSolver<RealifiedShiftInvert> eigs(op, nev, ncv, sigma);
  eigs.init();
  eigs.compute(Spectra::SortRule::LargestMagn, 1000, 1e-10, Spectra::SortRule::SmallestAlge);
  if (eigs.info() != Spectra::CompInfo::Successful)
    throw SolverError("eigen solver did not converge (Spectra shift-invert Lanczos, k=" + std::to_string(k) + ")");
  const Eigen::VectorXd values = eigs.eigenvalues();  // ascending (SmallestAlge)
  const Eigen::MatrixXd vectors = eigs.eigenvectors();
  const Eigen::VectorXd inv_sqrt = mass.cwiseSqrt().cwiseInverse();

  Eigenpairs out;
  std::vector<double> vals;
  std::vector<ComplexVector> vecs;
  int i = 0;
  while (i < values.size() && static_cast<int>(vals.size()) < k) {
    int j = i + 1;
    const double tol = 1e-8 * std::max(std::abs(values[i]), unit);
    while (j < values.size() && std::abs(values[j] - values[i]) <= tol) ++j;
    // Complex Gram-Schmidt of the group (standard inner product of the symmetric problem).
    std::vector<ComplexVector> basis;
    for (int c = i; c < j; ++c) {
      ComplexVector y(N);
      for (int t = 0; t < N; ++t) y[t] = Complex(vectors(2 * t, c), vectors(2 * t + 1, c));
      for (int pass = 0; pass < 2; ++pass)
        for (const auto& b : basis) y -= b * b.dot(y);
      const double norm = y.norm();
      if (norm > 1e-6) basis.push_back(y / norm);
    }
    for (const auto& b : basis) {
      if (static_cast<int>(vals.size()) == k) break;
      double mean = values.segment(i, j - i).mean();
      vals.push_back(mean);
      vecs.push_back(inv_sqrt.cast<Complex>().cwiseProduct(b));
    }
    i = j;
  }
  if (static_cast<int>(vals.size()) < k)
    throw SolverError("eigen solver returned fewer eigenpairs than requested");
  out.values = Eigen::Map<Eigen::VectorXd>(vals.data(), k);
  out.vectors.resize(N, k);
  for (int c = 0; c < k; ++c) out.vectors.col(c) = vecs[c];
  return out;
}

Eigenpairs eigenpairs_of(const ComplexSparse& S, const Eigen::VectorXd& mass, int k, double unit,
                         const ProgressCallback& progress) {
  const int N = static_cast<int>(S.rows());
  if (k < 1 || k > N)
    throw ParameterError("number of eigenpairs k must be between 1 and the number of faces with a field (" +
                         std::to_string(N) + "), got " + std::to_string(k));
  // Spectra's Lanczos on the realified problem (2N unknowns, 2k + 1 wanted) takes at most k = N - 2.
  if (use_dense_eigen(N, k, N - 2)) {
    Eigenpairs out = dense_eigenpairs(S, mass, k);
    if (progress) progress(1.0);
    return out;
  }
  if (k > N - 2)
    throw ParameterError("k=" + std::to_string(k) + " is too close to the problem size " + std::to_string(N) +
                         " for the iterative eigen solver; choose a smaller k");
  Eigenpairs out = lanczos_eigenpairs(S, mass, k, unit, progress);
  if (progress) progress(1.0);
  return out;
}

}  // namespace

Eigenpairs lowest_eigenpairs(const FieldOperators& ops, int k, const ProgressCallback& progress) {
  return eigenpairs_of(ops.harmonic_matrix(), ops.mass(), k, ops.eigenvalue_unit(1), progress);
}

ComplexVector smoothest_field(const FieldOperators& ops) {
  const TriangleMesh& mesh = ops.mesh();
  const int N = ops.num_unknowns();
  // Group unknowns by component.
  std::vector<std::vector<int>> members;
  for (int u = 0; u < N; ++u) {
    const int c = mesh.face_component()[ops.face_of_unknown(u)];
    if (c < 0) continue;
    if (c >= static_cast<int>(members.size())) members.resize(c + 1);
    members[c].push_back(u);
  }
  ComplexVector result = ComplexVector::Zero(N);
  const ComplexSparse& S = ops.harmonic_matrix();
  for (const auto& comp : members) {
    if (comp.empty()) continue;
    std::vector<int> local(N, -1);
    for (size_t i = 0; i < comp.size(); ++i) local[comp[i]] = static_cast<int>(i);
    const int n = static_cast<int>(comp.size());
    Eigen::VectorXd mass(n);
    double area = 0;
    for (int i = 0; i < n; ++i) area += (mass[i] = ops.mass()[comp[i]]);
    ComplexVector z;
    if (n == 1) {
      z = ComplexVector::Ones(1) / std::sqrt(mass[0]);
    } else {
      std::vector<Eigen::Triplet<Complex>> t;
      for (int i = 0; i < n; ++i)
        for (ComplexSparse::InnerIterator it(S, comp[i]); it; ++it) t.emplace_back(local[it.row()], i, it.value());
      ComplexSparse Sc(n, n);
      Sc.setFromTriplets(t.begin(), t.end());
      z = eigenpairs_of(Sc, mass, 1, std::pow(4 * M_PI / area, 1), {}).vectors.col(0);
    }
    // Fix the arbitrary complex phase deterministically: make the largest entry real positive.
    Eigen::Index imax = 0;
    z.cwiseAbs().maxCoeff(&imax);
    z *= std::conj(z[imax]) / std::abs(z[imax]);
    z *= std::sqrt(area);  // unit L2 norm -> norm sqrt(area): |z| ~ 1 per face on average
    for (int i = 0; i < n; ++i) result[comp[i]] = z[i];
  }
  return ops.to_faces(result);
}

}  // namespace nfield
