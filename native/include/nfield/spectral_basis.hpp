// Spectral basis for real-time editing (paper section 8, eqs. 16-18).
//
// The first k eigenpairs of the Hermitian generalized problem S z = lambda M z (complex form, see
// spectrum.hpp): eigenvalues ascending (1/length^2), eigenvectors U = [u_1 .. u_k] (num_unknowns x k)
// M-orthonormal, U^H M U = I (u has units 1/length so that the field z = U x has the units of x).
// A field restricted to the basis is z = U x, with coefficients x = U^H M z (the M-orthogonal projection).
//
// API (for the binding):
//   SpectralBasis::compute(ops, k, options = {}, progress = {}) -> SpectralBasis   (expensive; cancellable)
//   basis.size(), num_unknowns(), precision(), values() (k, ascending, 1/length^2), vector(j), vectors()
//   basis.project(z per unknown) -> x (k),  basis.reconstruct(x) -> z per unknown
//   basis.truncated(k') (first k' pairs, no recomputation), basis.with_precision(Single | Double)
//   ReducedSolver and low_pass (reduced_solver.hpp) use a basis.
//
// How compute() works, one file each:
//   memory guard first:  basis_memory.hpp (peak-memory model, refusal with advice);
//   small N or large k:  dense_eigen.hpp (full decomposition, exact; use_dense_eigen, the switch-over shared
//                        with spectrum.hpp);
//   otherwise:           spectrum_slicing.hpp (slices counted by inertia, solved concurrently) built on
//                        shifted_factor.hpp (LL^H / LDL^H of S - sigma M, inertia) and slice_lanczos.hpp
//                        (thick-restart block Lanczos of one slice); dense products in blas.hpp.
// Disk cache (save, load, cache key, file format): basis_cache.hpp.
//
// Storage precision: double (complex<double>) or single (complex<float>, half the memory; vectors
// are computed in double and rounded, so orthonormality and reconstruction carry ~1e-7 relative error).
#pragma once
#include <cstdint>
#include <string>

#include "nfield/dense_eigen.hpp"
#include "nfield/operators.hpp"
#include "nfield/spectrum.hpp"

namespace nfield {

enum class BasisPrecision { Double, Single };

/// Tuning of SpectralBasis::compute. The defaults are what the benchmarks were measured with.
struct SpectralBasisOptions {
  BasisPrecision precision = BasisPrecision::Double;
  int block_size = 48;          ///< upper bound of the Lanczos block (used: max(8, slice / 8), capped by this)
  double tolerance = 1e-10;     ///< relative Ritz residual |T y - theta y| / theta for convergence
  int max_restarts = 200;       ///< SolverError beyond this
  int dense_limit = kDenseEigenLimit;  ///< at most this many unknowns: dense solver (use_dense_eigen; tests lower it)
  int slice_size = 0;           ///< eigenpairs per spectrum slice (0: automatic, 100)
};

/// The first k eigenpairs of S z = lambda M z of one FieldOperators. Immutable value type.
class SpectralBasis {
 public:
  SpectralBasis() = default;

  /// Computes the basis. ParameterError if k < 1 or k > num_unknowns (or, above kDenseEigenMax unknowns,
  /// k > (num_unknowns - 1) / 3 for the iterative solver), SolverError if the solver fails or memory runs out,
  /// Cancelled if `progress` returns false (progress = fraction of the wanted eigenpairs converged,
  /// interpolated by work inside a restart cycle; nothing is kept on cancel).
  static SpectralBasis compute(const FieldOperators& ops, int k, const SpectralBasisOptions& options = {},
                               const ProgressCallback& progress = {});

  int size() const { return static_cast<int>(values_.size()); }  ///< k
  int num_unknowns() const { return static_cast<int>(mass_.size()); }
  BasisPrecision precision() const { return precision_; }
  /// Eigenvalues lambda_1 <= ... <= lambda_k (1/length^2).
  const Eigen::VectorXd& values() const { return values_; }
  /// Eigenvector j (per unknown, double precision whatever the storage).
  ComplexVector vector(int j) const;
  /// All eigenvectors (num_unknowns x k) converted to double.
  Eigen::MatrixXcd vectors() const;
  /// The stored vectors: exactly one of the two is non-empty, according to precision().
  const Eigen::MatrixXcd& vectors_double() const { return vectors_d_; }
  const Eigen::MatrixXcf& vectors_single() const { return vectors_f_; }
  /// Diagonal of M the basis is orthonormal for (per unknown).
  const Eigen::VectorXd& mass() const { return mass_; }

  /// Coefficients x = U^H M z (size k) of a field z given per unknown (size num_unknowns).
  ComplexVector project(const ComplexVector& z) const;
  /// The field U x per unknown (size num_unknowns) of coefficients x (size k).
  ComplexVector reconstruct(const ComplexVector& x) const;

  /// The first k' <= k eigenpairs (a copy): a smaller basis without recomputation. ParameterError
  /// unless 1 <= k' <= size().
  SpectralBasis truncated(int k) const;

  /// The same basis stored in another precision (a copy; Double -> Single rounds to ~1e-7).
  SpectralBasis with_precision(BasisPrecision precision) const;

  /// Bytes held by the vectors, values and mass.
  std::size_t memory_bytes() const;

  /// Cache key of the operators the basis was computed for.
  std::uint64_t mesh_hash() const { return mesh_hash_; }
  int n() const { return n_; }
  EdgeWeights weights() const { return weights_; }

 private:
  friend SpectralBasis load_basis(const std::string& path, const FieldOperators& ops, int expected_k,
                                  int expected_precision);  // basis_cache.hpp

  Eigen::VectorXd values_;
  Eigen::MatrixXcd vectors_d_;
  Eigen::MatrixXcf vectors_f_;
  Eigen::VectorXd mass_;
  BasisPrecision precision_ = BasisPrecision::Double;
  std::uint64_t mesh_hash_ = 0;
  int n_ = 0;
  EdgeWeights weights_ = EdgeWeights::Geometric;
};

}  // namespace nfield
