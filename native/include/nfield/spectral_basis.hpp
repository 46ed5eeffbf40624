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
//   basis.save(path), SpectralBasis::load(path, ops, expected_k, expected_precision), cache_key(ops, k, prec)
//   ReducedSolver and low_pass (reduced_solver.hpp) use a basis.
//
// Algorithm (compute): spectrum slicing. The wanted part of the spectrum is cut into slices of about
// `slice_size` (100) eigenvalues at boundaries B_1 < ... < B_p with count(B_p) >= k; boundaries are
// placed with Weyl's law (count(lambda) ~ lambda area / (8 pi)) corrected by the measured density, and
// count(B) is exact: the inertia of S - B M (negative pivots of a CHOLMOD simplicial LDL^H factorization,
// Sylvester's law). Each slice [B_{j-1}, B_j) is solved independently with its own shift sigma at the
// slice centre: thick-restart block Lanczos (block Krylov-Schur, full CGS2 re-orthogonalization) on
// T = M^1/2 (S - sigma M)^-1 M^1/2, Ritz values ordered by |theta| = 1/|lambda - sigma| (nearest first),
// until exactly count(B_j) - count(B_{j-1}) Ritz pairs inside the slice have converged — so no
// eigenvalue of a cluster can be missed (if one is, the iteration restarts from a fresh random block
// orthogonal to the converged pairs). Because the Krylov spaces stay small (~2 x slice), the dense work
// is O(N k slice) instead of O(N k^2) per restart of a single-shift solver. Two slices run concurrently
// on two cores (each with its own factorization, single-threaded BLAS: OpenBLAS threads are set to 1
// for the duration and restored). The indefinite solves use the LDL^H factor with a blocked triangular
// solve (8 right-hand sides per pass over L). Vectors of adjacent slices come from different shifts;
// where their M-inner products exceed 1e-12 (a cluster across a boundary) a local Rayleigh-Ritz makes
// them orthonormal again. k <= 1.5 slice_size uses a single shift below the spectrum
// (sigma = -1e-2 (4 pi / area), S - sigma M positive definite even when S has a kernel, supernodal LL^H).
// Ritz pairs count as converged when |T y - theta y| <= tol |theta|. Small problems use a dense solver.
// Progress is reported from the calling thread only; cancel by returning false.
// Measured (2-core VM shared with other jobs, OPENBLAS_NUM_THREADS=2), k = 500: bunny (69,451 faces)
// 53 s wall / 72 s CPU at load ~2 (105 s wall / 69 s CPU at load ~6); the previous single-shift block
// Krylov-Schur took 113 s CPU. Residuals ~2e-9 relative, M-orthonormality ~5e-12.
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
  int block_size = 48;          ///< upper bound of the Lanczos block (used: max(8, slice / 8), capped by this)
  double tolerance = 1e-10;     ///< relative Ritz residual |T y - theta y| / theta for convergence
  int max_restarts = 200;       ///< SolverError beyond this
  int dense_limit = 1200;       ///< problems with at most this many unknowns use the dense solver
  int slice_size = 0;           ///< eigenpairs per spectrum slice (0: automatic, 100)
};

/// The first k eigenpairs of S z = lambda M z of one FieldOperators. Immutable value type.
class SpectralBasis {
 public:
  SpectralBasis() = default;

  /// Computes the basis. ParameterError if k < 1 or k > num_unknowns (or, above dense_limit unknowns,
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

/// Estimated peak memory (bytes) of SpectralBasis::compute(ops, k, options): the eigenvectors (computed
/// in double precision, plus the float32 copy for single storage), and per concurrent spectrum slice its
/// LDL^H factor (size from a symbolic analysis of S) and Lanczos workspace. Used by the memory guard.
std::size_t estimate_basis_bytes(const FieldOperators& ops, int k, const SpectralBasisOptions& options = {});

/// A file-name-safe key for a basis of k eigenpairs of these operators, e.g.
/// "basis-0123456789abcdef-n4-geometric-N69451-k500-f64". Different keys for different precisions.
std::string cache_key(const FieldOperators& ops, int k, BasisPrecision precision = BasisPrecision::Double);

}  // namespace nfield
