#include "nfield/basis_memory.hpp"

#include <Eigen/CholmodSupport>
#include <algorithm>
#include <complex>
#include <string>

#include "nfield/dense_eigen.hpp"
#include "nfield/memory_guard.hpp"
#include "nfield/spectrum_slicing.hpp"

namespace nfield {
namespace {

/// Peak bytes of compute() for k eigenpairs of N unknowns whose factor has `lnz` nonzeros.
double basis_bytes(double lnz, int N, int k, const SpectralBasisOptions& opt) {
  const double c = sizeof(Complex), n = N;
  if (use_dense_eigen(N, k, sliced_max_k(N), opt.dense_limit)) return 3.0 * n * n * c + 2.0 * n * k * c;
  const double factor = static_cast<double>(cholesky_factor_bytes(lnz, static_cast<std::size_t>(N)));
  const int slice = opt.slice_size > 0 ? opt.slice_size : 100;
  double bytes;
  if (k <= slice + slice / 2) {
    const int b = std::min(opt.block_size, std::max(8, k / 8));
    bytes = factor + (2.0 * k + 2.0 * b) * n * c + 2.0 * n * k * c;  // Krylov space, result, copy
  } else {
    const int b = std::min(opt.block_size, std::max(8, slice / 8));
    const double per_worker = factor + (3.0 * slice + 2.0 * b) * n * c;
    bytes = 2.0 * per_worker + 1.1 * n * k * c + n * k * c;  // two workers, all slices' vectors, result
  }
  if (opt.precision == BasisPrecision::Single) bytes += n * k * sizeof(std::complex<float>);
  return bytes;
}

double harmonic_factor_nonzeros(const FieldOperators& ops) {
  Eigen::CholmodSupernodalLLT<ComplexSparse, Eigen::Lower> analysis;
  analysis.analyzePattern(ops.harmonic_matrix());
  return analysis.cholmod().lnz;
}

}  // namespace

std::size_t estimate_basis_bytes(const FieldOperators& ops, int k, const SpectralBasisOptions& options) {
  const int N = ops.num_unknowns();
  k = std::max(k, 1);
  const double lnz = use_dense_eigen(N, k, sliced_max_k(N), options.dense_limit) ? 0.0 : harmonic_factor_nonzeros(ops);
  return static_cast<std::size_t>(basis_bytes(lnz, N, k, options));
}

void require_basis_memory(const FieldOperators& ops, int k, const SpectralBasisOptions& options) {
  const int N = ops.num_unknowns();
  // The factor size is needed for any k the iterative path would take (the search below tries smaller k).
  const double lnz = N <= options.dense_limit ? 0.0 : harmonic_factor_nonzeros(ops);
  const double need = basis_bytes(lnz, N, k, options);
  const double budget = kMemoryHeadroom * static_cast<double>(available_memory_bytes());
  if (budget > 0 && need > budget) {
    int lo = 0, hi = k;  // largest k' < k that fits (need grows with k)
    while (hi - lo > 1) {
      const int mid = (lo + hi) / 2;
      (basis_bytes(lnz, N, mid, options) <= budget ? lo : hi) = mid;
    }
    std::string advice = lo >= 1 ? "k <= " + std::to_string(lo) + " fits" : "no basis size fits";
    SpectralBasisOptions single = options;
    single.precision = BasisPrecision::Single;
    if (options.precision == BasisPrecision::Double && basis_bytes(lnz, N, k, single) <= budget)
      advice += "; so does single precision storage";
    advice += "; the exact mode needs no basis";
    require_memory(static_cast<std::size_t>(need),
                   "the spectral basis of k=" + std::to_string(k) + " eigenfields (" + std::to_string(N) + " faces)",
                   advice);
  }
}

}  // namespace nfield
