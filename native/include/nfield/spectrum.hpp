// Spectrum of the n-field Laplacian: the generalized Hermitian eigenproblem S z = lambda M z (eq. 15).
//
// Eigenvalues are reported in complex form: each eigenvalue of the complex |F| x |F| problem once, with
// its complex multiplicity (the paper's real 2|F| form repeats every one of them twice). Units 1/length^2.
// Eigenvectors are M-orthonormal: z_a^H M z_b = delta_ab.
#pragma once
#include <functional>

#include "nfield/operators.hpp"

namespace nfield {

/// Called with the fraction done in [0, 1]; returning false cancels (the call then throws Cancelled).
using ProgressCallback = std::function<bool(double)>;

struct Eigenpairs {
  Eigen::VectorXd values;          ///< k eigenvalues, ascending
  Eigen::MatrixXcd vectors;        ///< num_unknowns x k, M-orthonormal (indexed by unknowns)
};

/// The k smallest eigenpairs of S z = lambda M z restricted to `unknowns` (all if empty).
/// Small problems (at most kDenseEigenLimit unknowns, or k too close to N for Lanczos) use the dense path
/// of dense_eigen.hpp, large ones Spectra's shift-invert Lanczos on the realified problem.
/// Throws ParameterError if k < 1 or k > number of unknowns, SolverError if the solver fails.
Eigenpairs lowest_eigenpairs(const FieldOperators& ops, int k, const ProgressCallback& progress = {});

/// The smoothest unit-L2 field of every connected component: the first eigenvector of each component's
/// block, per face (zero on inactive faces). Scaled so that each component's L2 norm is sqrt(its area).
ComplexVector smoothest_field(const FieldOperators& ops);

}  // namespace nfield
