// Spectral basis for real-time editing (paper section 8, eqs. 16-18).
//
// The first k eigenpairs of the Hermitian generalized problem S z = lambda M z (complex form, see
// spectrum.hpp): eigenvalues ascending (1/length^2), eigenvectors U = [u_1 .. u_k] (num_unknowns x k)
// M-orthonormal, U^H M U = I (u has units 1/length so that the field z = U x has the units of x).
// A field restricted to the basis is z = U x, with coefficients x = U^H M z (the M-orthogonal projection).
//
// Algorithm (compute): block Krylov-Schur (thick-restart block Lanczos) on the shift-inverted operator
// T = M^1/2 (S - sigma M)^-1 M^1/2 (Hermitian, eigenvalues theta = 1/(lambda - sigma) > 0), with
// sigma = -1e-2 (4 pi / area) < 0 so that S - sigma M is positive definite even when S has a kernel.
// One complex CHOLMOD supernodal factorization; every operator application solves a block of columns at
// once, and all orthogonalization / Rayleigh-Ritz / restart work is BLAS3 (zgemm, zheevd).
// Ritz pairs count as converged when |T y - theta y| <= tol theta. Small problems use a dense solver.
//
// Storage precision: double (complex<double>) or single (complex<float>, half the memory; vectors
// are computed in double and rounded, so orthonormality and reconstruction carry ~1e-7 relative error).
//
// Disk cache: save()/load() write a binary file whose header is keyed by the mesh content hash, n, the
// edge weights, k, the number of unknowns and the precision, followed by the eigenvalues, the vectors
// and a checksum. load() refuses (InputError) a file whose key does not match the operators (stale
// cache), or that is truncated or corrupt. save() writes a temporary file and renames it (atomic).
#pragma once
#include <cstdint>
#include <string>

#include "nfield/operators.hpp"
#include "nfield/spectrum.hpp"

namespace nfield {

enum class BasisPrecision { Double, Single };

/// Tuning of SpectralBasis::compute. The defaults are what the benchmarks were measured with.
struct SpectralBasisOptions {
  BasisPrecision precision = BasisPrecision::Double;
  int block_size = 48;          ///< columns per block solve (BLAS3 in CHOLMOD and in orthogonalization)
  double tolerance = 1e-10;     ///< relative Ritz residual |T y - theta y| / theta for convergence
  int max_restarts = 200;       ///< SolverError beyond this
  int dense_limit = 1200;       ///< problems with at most this many unknowns use the dense solver
  int subspace = 0;             ///< Krylov capacity (0: automatic)
};

/// The first k eigenpairs of S z = lambda M z of one FieldOperators. Immutable value type.
class SpectralBasis {
 public:
  SpectralBasis() = default;

  /// Computes the basis. ParameterError if k < 1 or k > num_unknowns (or too close to it for the
  /// iterative solver on a large problem), SolverError if the solver fails or memory runs out,
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

  /// Bytes held by the vectors, values and mass.
  std::size_t memory_bytes() const;

  /// Cache key of the operators the basis was computed for.
  std::uint64_t mesh_hash() const { return mesh_hash_; }
  int n() const { return n_; }
  EdgeWeights weights() const { return weights_; }

  /// Writes the basis (atomically: temporary file + rename). InputError if the file cannot be written.
  void save(const std::string& path) const;
  /// Reads a basis written by save() for these operators. InputError if the file cannot be read, is
  /// truncated or corrupt, or was computed for different operators (mesh content, n, weights, size).
  /// `expected_k` (if > 0) must match too; `expected_precision` likewise unless left unspecified (-1).
  static SpectralBasis load(const std::string& path, const FieldOperators& ops, int expected_k = 0,
                            int expected_precision = -1);

 private:
  Eigen::VectorXd values_;
  Eigen::MatrixXcd vectors_d_;
  Eigen::MatrixXcf vectors_f_;
  Eigen::VectorXd mass_;
  BasisPrecision precision_ = BasisPrecision::Double;
  std::uint64_t mesh_hash_ = 0;
  int n_ = 0;
  EdgeWeights weights_ = EdgeWeights::Geometric;
};

/// A file-name-safe key for a basis of k eigenpairs of these operators, e.g.
/// "basis-0123456789abcdef-n4-geometric-N69451-k500-f64". Different keys for different precisions.
std::string cache_key(const FieldOperators& ops, int k, BasisPrecision precision = BasisPrecision::Double);

}  // namespace nfield
