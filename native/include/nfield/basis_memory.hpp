// Peak memory of computing a spectral basis (spectral_basis.hpp), for the memory guard (memory_guard.hpp).
//
// Model, in bytes, for k eigenpairs of N unknowns (c = 16, one complex<double>):
//   dense path (use_dense_eigen):   3 N^2 c (the matrix, zheevd's workspace) + 2 N k c (result, copy);
//   one shift (k <= 1.5 slice):     factor + (2k + 2b) N c (Krylov space) + 2 N k c (result, copy);
//   slicing:                        2 x [factor + (3 slice + 2b) N c] (two workers, each with its factor and
//                                   Krylov space) + 1.1 N k c (every slice's vectors) + N k c (result);
//   single precision storage adds N k 8 (the complex<float> copy of the vectors).
// `factor` is the size of a complex Cholesky factor of S as predicted by CHOLMOD's symbolic analysis
// (cholesky_factor_bytes); the LDL^H factors of the slices have the same pattern. b is the Lanczos block.
// tests/test_memory_guard.py compares the estimate with the measured peak.
#pragma once
#include <cstddef>

#include "nfield/operators.hpp"
#include "nfield/spectral_basis.hpp"

namespace nfield {

/// Estimated peak memory (bytes) of SpectralBasis::compute(ops, k, options): the eigenvectors (computed
/// in double precision, plus the float32 copy for single storage), and per concurrent spectrum slice its
/// LDL^H factor (size from a symbolic analysis of S) and Lanczos workspace. Used by the memory guard.
std::size_t estimate_basis_bytes(const FieldOperators& ops, int k, const SpectralBasisOptions& options = {});

/// The memory guard of SpectralBasis::compute: MemoryLimitError when the estimate exceeds the budget
/// (kMemoryHeadroom x available memory), with advice on what would fit: the largest k, whether single
/// precision storage would, and that the exact mode needs no basis.
void require_basis_memory(const FieldOperators& ops, int k, const SpectralBasisOptions& options);

}  // namespace nfield
