// Disk cache of spectral bases (spectral_basis.hpp): a basis takes about a minute for 70k faces, so it is
// computed once per mesh content, n, edge weights, k and precision and read back in a second.
//
// File format (native byte order, little-endian on every supported platform), version 1:
//   header, 40 bytes:  magic "NFBASIS1" (8) | version u32 | precision u32 (0 double, 1 single)
//                      | mesh content hash u64 | n i32 | weights i32 (0 geometric, 1 combinatorial)
//                      | k i32 | num_unknowns i32
//   eigenvalues:       k doubles, ascending
//   eigenvectors:      num_unknowns x k complex values, column-major, complex<double> or complex<float>
//   checksum:          u64, a word-wise multiply-xorshift hash chained over header, values and vectors
// The mass (diagonal of M) is not stored: it is taken from the operators the file is loaded for, whose
// content hash, n, weights and size must match the header.
//
// save_basis writes a temporary file next to the target and renames it into place, so a reader never sees a
// half-written cache and two writers cannot interleave. load_basis refuses (InputError, message naming the
// file and the reason) a missing file, a wrong magic or version, a header that does not match the
// operators (stale cache), a size that disagrees with the header (truncated), a checksum mismatch
// (corrupt) and non-finite eigenvalues.
#pragma once
#include <cstdint>
#include <string>

#include "nfield/operators.hpp"
#include "nfield/spectral_basis.hpp"

namespace nfield {

/// A file-name-safe key for a basis of k eigenpairs of these operators, e.g.
/// "basis-0123456789abcdef-n4-geometric-N69451-k500-f64". Different keys for different precisions.
std::string cache_key(const FieldOperators& ops, int k, BasisPrecision precision = BasisPrecision::Double);

/// Writes the basis (atomically: temporary file + rename). ParameterError for an empty basis; InputError
/// if the file cannot be written.
void save_basis(const SpectralBasis& basis, const std::string& path);

/// Reads a basis written by save_basis for these operators. InputError if the file cannot be read, is
/// truncated or corrupt, or was computed for different operators (mesh content, n, weights, size).
/// `expected_k` (if > 0) must match too; `expected_precision` likewise unless left unspecified (-1;
/// otherwise static_cast<int>(BasisPrecision)).
SpectralBasis load_basis(const std::string& path, const FieldOperators& ops, int expected_k = 0,
                         int expected_precision = -1);

}  // namespace nfield
