// Spectrum slicing: the first k eigenpairs of S z = lambda M z for the spectral basis (problems above the
// dense switch-over, dense_eigen.hpp). S is Hermitian positive semi-definite, M = diag(mass) > 0.
//
// Counting. The number of eigenvalues below B is the inertia of S - B M: the negative pivots of its
// LDL^H factor (Sylvester's law, shifted_factor.hpp), exact whatever the conditioning.
//
// Slices. The wanted part of the spectrum is cut at boundaries 0 = B_0 < B_1 < ... < B_p with
// count(B_p) >= k, each slice [B_{j-1}, B_j) holding about `slice_size` (default 100) eigenvalues. The
// boundaries are first placed with Weyl's law for surfaces, count(lambda) ~ lambda area / (8 pi)
// = lambda / (2 unit) with unit = 4 pi / area (the eigenvalue unit of operators.hpp; the complex form
// counts every eigenvalue once), then corrected by the density measured at the previous boundary; the
// last slice is sized to end just above k (no tiny trailing slice).
//
// Solving. Each slice is solved on its own with the shift sigma at its centre by SliceLanczos
// (slice_lanczos.hpp), which runs until exactly count(B_j) - count(B_{j-1}) converged Ritz values lie in
// the slice: no eigenvalue of a cluster can be missed. The Krylov spaces stay small (~2 x slice), so the
// dense work is O(N k slice) instead of the O(N k^2) per restart of a single-shift solver. Two slices run
// concurrently on two cores (each with its own factorization, single-threaded BLAS and solves; OpenBLAS
// threads are set to 1 for the duration and restored); the largest slices go first to balance them.
//
// Gluing. Vectors of adjacent slices come from different shifts: M-orthogonal only up to residual / gap.
// Where their M-inner products exceed 1e-12 (a cluster across a boundary) a local Rayleigh-Ritz of S, M on
// those vectors makes them M-orthonormal again. The result is the first k of all pairs, ascending.
//
// Small k (k <= 1.5 slice_size): one shift below the spectrum, sigma = -1e-2 unit (S - sigma M positive
// definite even when S has a kernel, so the supernodal LL^H factor applies), and the k eigenvalues
// nearest it.
//
// Progress is reported from the calling thread only (never from a worker), monotone, in [0, 0.99] until
// the end; returning false cancels (Cancelled), and the workers stop at their next block.
// Measured (2-core VM shared with other jobs, OPENBLAS_NUM_THREADS=2), k = 500: bunny (69,451 faces)
// 53 s wall / 72 s CPU at load ~2 (105 s wall / 69 s CPU at load ~6); the previous single-shift block
// Krylov-Schur took 113 s CPU. Residuals ~2e-9 relative, M-orthonormality ~5e-12.
#pragma once
#include <Eigen/Core>

#include "nfield/operators.hpp"
#include "nfield/spectral_basis.hpp"
#include "nfield/spectrum.hpp"

namespace nfield {

/// The largest k spectrum slicing takes for N unknowns: (N - 1) / 3 (at least 1), so that the Krylov space
/// of a slice (about twice the wanted pairs plus a block) fits in N dimensions.
inline int sliced_max_k(int N) { return N > 3 ? (N - 1) / 3 : 1; }

/// The k smallest eigenpairs of S z = lambda M z by spectrum slicing (above): eigenvalues ascending,
/// eigenvectors N x k, M-orthonormal. `unit` is the eigenvalue scale 4 pi / area (places the first
/// boundaries and the shift of the small-k case). ParameterError if k > (N - 1) / 3 (the Krylov spaces
/// would not fit); SolverError if a factorization or the iteration fails; Cancelled through `progress`.
Eigenpairs sliced_eigenpairs(const ComplexSparse& S, const Eigen::VectorXd& mass, int k, double unit,
                             const SpectralBasisOptions& options, const ProgressCallback& progress);

}  // namespace nfield
