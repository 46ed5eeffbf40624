// The dense path of the generalized Hermitian eigenproblem S z = lambda M z (M = diag(mass), mass > 0),
// shared by lowest_eigenpairs (spectrum.hpp) and SpectralBasis::compute (spectral_basis.hpp) for small
// problems.
//
// With D = M^1/2:  S z = lambda M z  <=>  A y = lambda y,  A = D^-1 S D^-1 (Hermitian),  z = D^-1 y.
// A full eigen-decomposition of A (LAPACK zheevd, divide and conquer) yields every eigenpair; the
// orthonormal eigenvectors of A give M-orthonormal z: z_a^H M z_b = y_a^H y_b = delta_ab. It is backward
// stable (eigenvalue errors ~ eps ||A||), needs no convergence test, cannot miss a multiple eigenvalue,
// and works for any k <= N, where the iterative solvers need k well below N. Cost: O(N^3) time,
// 16 N^2 bytes for A plus zheevd's workspace (about 2 N^2 complex values).
#pragma once
#include <Eigen/Core>

#include "nfield/operators.hpp"
#include "nfield/spectrum.hpp"

namespace nfield {

/// The switch-over between the dense path and the iterative solvers (Spectra's Lanczos in spectrum.cpp,
/// spectrum slicing for the spectral basis): problems with at most this many unknowns take the dense path.
/// Measured on bumpy tori, n = 4, single process on the project's loaded 2-core VM (CPU seconds, best of
/// 2-3; dense = this file's zheevd path, which needs the full decomposition whatever k):
///     N      dense   Lanczos k=1 / 10 / 50     basis k=100 sliced   basis k=(N-1)/3 sliced
///     400    0.09    0.006 / 0.008 / 0.03      0.13                 0.18
///     800    0.46    0.016 / 0.029 / 0.15      0.46                 0.37
///     1000   0.99    0.014 / 0.033 / 0.16      0.20                 0.96
///     1200   2.18    0.030 / 0.018 / 0.13      0.51                 1.30
///     1600   8.3     0.051 / 0.076 / 0.31      0.37                 2.09
/// The dense O(N^3) cost overtakes the largest basis the iterative solver takes at about 800-1000 unknowns
/// and is 2-20x slower above; for the few eigenpairs of lowest_eigenpairs (the smoothest field: k = 1)
/// Lanczos is far faster at every size, but below ~800 unknowns both take well under a second, and the
/// dense path is exact and cannot miss a multiplicity. 800 was spectrum.cpp's switch-over already; the
/// spectral basis used 1200, where its slicing is now 2-4x faster (k = 100).
constexpr int kDenseEigenLimit = 800;

/// Above kDenseEigenLimit the dense path still serves a k the iterative solver cannot take (too close to N),
/// up to this many unknowns (O(N^3): about 80 s and 770 MB at 4000); beyond it such a k is a ParameterError.
constexpr int kDenseEigenMax = 4000;

/// Whether a problem of N unknowns with k wanted eigenpairs takes the dense path: N <= dense_limit, or
/// k > iterative_max_k (the most the caller's iterative solver can compute for N) and N <= kDenseEigenMax.
inline bool use_dense_eigen(int N, int k, int iterative_max_k, int dense_limit = kDenseEigenLimit) {
  return N <= dense_limit || (k > iterative_max_k && N <= kDenseEigenMax);
}

/// The k smallest eigenpairs of S z = lambda M z by the dense decomposition above: eigenvalues ascending
/// (units of S / M), eigenvectors N x k, M-orthonormal. S must be Hermitian up to rounding (A is
/// symmetrized). ParameterError unless 1 <= k <= N; SolverError if LAPACK fails.
Eigenpairs dense_eigenpairs(const ComplexSparse& S, const Eigen::VectorXd& mass, int k);

}  // namespace nfield
