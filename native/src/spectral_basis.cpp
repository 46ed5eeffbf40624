#include "nfield/spectral_basis.hpp"

#include <new>
#include <string>
#include <utility>

#include "nfield/basis_memory.hpp"
#include "nfield/blas.hpp"
#include "nfield/dense_eigen.hpp"
#include "nfield/errors.hpp"
#include "nfield/spectrum_slicing.hpp"

namespace nfield {

using Eigen::VectorXd;

// ------------------------------------------------------------------------------------------ compute

SpectralBasis SpectralBasis::compute(const FieldOperators& ops, int k, const SpectralBasisOptions& options,
                                     const ProgressCallback& progress) {
  const ComplexSparse& S = ops.harmonic_matrix();
  const VectorXd& mass = ops.mass();
  const int N = ops.num_unknowns();
  if (k < 1 || k > N)
    throw ParameterError("number of basis vectors k must be between 1 and the number of faces with a field (" +
                         std::to_string(N) + "), got " + std::to_string(k));
  if (options.block_size < 1 || options.block_size > 512)
    throw ParameterError("spectral basis block size must be in [1, 512], got " + std::to_string(options.block_size));
  if (!(options.tolerance > 0 && options.tolerance < 1e-2))
    throw ParameterError("spectral basis tolerance must be in (0, 1e-2)");
  require_basis_memory(ops, k, options);

  Eigenpairs raw;
  if (use_dense_eigen(N, k, sliced_max_k(N), options.dense_limit)) {
    if (progress && !progress(0.0)) throw Cancelled("spectral basis computation cancelled");
    raw = dense_eigenpairs(S, mass, k);
    if (progress && !progress(1.0)) throw Cancelled("spectral basis computation cancelled");
  } else {
    try {
      raw = sliced_eigenpairs(S, mass, k, ops.eigenvalue_unit(1), options, progress);
    } catch (const std::bad_alloc&) {
      throw SolverError("spectral basis: out of memory (k=" + std::to_string(k) + ", " + std::to_string(N) +
                        " unknowns)");
    }
  }

  SpectralBasis out;
  out.values_ = raw.values;
  out.mass_ = mass;
  out.precision_ = options.precision;
  out.mesh_hash_ = ops.mesh().content_hash();
  out.n_ = ops.n();
  out.weights_ = ops.weights();
  if (options.precision == BasisPrecision::Single) {
    try {
      out.vectors_f_ = raw.vectors.cast<std::complex<float>>();
    } catch (const std::bad_alloc&) {
      throw SolverError("spectral basis: not enough memory for the eigenvectors");
    }
  } else {
    out.vectors_d_ = std::move(raw.vectors);
  }
  if (progress && !progress(1.0)) throw Cancelled("spectral basis computation cancelled");
  return out;
}

// ------------------------------------------------------------------------------------------ access

ComplexVector SpectralBasis::vector(int j) const {
  if (j < 0 || j >= size()) throw ParameterError("basis vector index out of range: " + std::to_string(j));
  if (precision_ == BasisPrecision::Single) return vectors_f_.col(j).cast<Complex>();
  return vectors_d_.col(j);
}

Eigen::MatrixXcd SpectralBasis::vectors() const {
  if (precision_ == BasisPrecision::Single) return vectors_f_.cast<Complex>();
  return vectors_d_;
}

ComplexVector SpectralBasis::project(const ComplexVector& z) const {
  const int N = num_unknowns(), k = size();
  if (z.size() != N)
    throw ParameterError("project: field has " + std::to_string(z.size()) + " entries, expected " +
                         std::to_string(N));
  if (precision_ == BasisPrecision::Single) {
    const Eigen::VectorXcf mz = (mass_.cast<Complex>().cwiseProduct(z)).cast<std::complex<float>>();
    Eigen::VectorXcf x(k);
    gemv('C', N, k, vectors_f_.data(), mz.data(), x.data());
    return x.cast<Complex>();
  }
  const ComplexVector mz = mass_.cast<Complex>().cwiseProduct(z);
  ComplexVector x(k);
  gemv('C', N, k, vectors_d_.data(), mz.data(), x.data());
  return x;
}

ComplexVector SpectralBasis::reconstruct(const ComplexVector& x) const {
  const int N = num_unknowns(), k = size();
  if (x.size() != k)
    throw ParameterError("reconstruct: " + std::to_string(x.size()) + " coefficients, expected " +
                         std::to_string(k));
  if (precision_ == BasisPrecision::Single) {
    const Eigen::VectorXcf xf = x.cast<std::complex<float>>();
    Eigen::VectorXcf z(N);
    gemv('N', N, k, vectors_f_.data(), xf.data(), z.data());
    return z.cast<Complex>();
  }
  ComplexVector z(N);
  gemv('N', N, k, vectors_d_.data(), x.data(), z.data());
  return z;
}

SpectralBasis SpectralBasis::truncated(int k) const {
  if (k < 1 || k > size())
    throw ParameterError("truncated basis size must be between 1 and " + std::to_string(size()) + ", got " +
                         std::to_string(k));
  SpectralBasis out;
  out.values_ = values_.head(k);
  if (precision_ == BasisPrecision::Single)
    out.vectors_f_ = vectors_f_.leftCols(k);
  else
    out.vectors_d_ = vectors_d_.leftCols(k);
  out.mass_ = mass_;
  out.precision_ = precision_;
  out.mesh_hash_ = mesh_hash_;
  out.n_ = n_;
  out.weights_ = weights_;
  return out;
}

SpectralBasis SpectralBasis::with_precision(BasisPrecision precision) const {
  SpectralBasis out;
  out.values_ = values_;
  out.mass_ = mass_;
  out.precision_ = precision;
  out.mesh_hash_ = mesh_hash_;
  out.n_ = n_;
  out.weights_ = weights_;
  try {
    if (precision == precision_) {
      out.vectors_d_ = vectors_d_;
      out.vectors_f_ = vectors_f_;
    } else if (precision == BasisPrecision::Single) {
      out.vectors_f_ = vectors_d_.cast<std::complex<float>>();
    } else {
      out.vectors_d_ = vectors_f_.cast<Complex>();
    }
  } catch (const std::bad_alloc&) {
    throw SolverError("spectral basis: not enough memory to convert the basis");
  }
  return out;
}

std::size_t SpectralBasis::memory_bytes() const {
  return static_cast<std::size_t>(vectors_d_.size()) * sizeof(Complex) +
         static_cast<std::size_t>(vectors_f_.size()) * sizeof(std::complex<float>) +
         static_cast<std::size_t>(values_.size() + mass_.size()) * sizeof(double);
}

}  // namespace nfield
