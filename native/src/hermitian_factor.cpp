#include "nfield/hermitian_factor.hpp"

#include <Eigen/CholmodSupport>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <new>

#include "nfield/blas.hpp"
#include "nfield/errors.hpp"
#include "nfield/memory_guard.hpp"

namespace nfield {

HermitianFactor::HermitianFactor(const ComplexSparse& matrix, const std::string& what, const std::string& advice)
    : n_(static_cast<int>(matrix.rows())), matrix_(matrix) {
  matrix_.makeCompressed();
  cholmod_start(&common_);
  common_.supernodal = CHOLMOD_SUPERNODAL;  // BLAS 3 on dense blocks: the fastest factorization and block solves
  common_.final_asis = 1;                   // keep the supernodal LL^H (forward() reads it)
  common_.print = 0;                        // failures are reported as exceptions, not printed
  const ComplexSparse& stored = matrix_;
  cholmod_sparse view = Eigen::viewAsCholmod(stored.selfadjointView<Eigen::Lower>());
  factor_ = cholmod_analyze(&view, &common_);
  if (!factor_ || common_.status < CHOLMOD_OK) {
    cholmod_finish(&common_);
    throw SolverError("symbolic analysis of " + what + " failed");
  }
  try {
    // Memory guard: the numeric factor's size is known from the symbolic analysis (nnz of L).
    const std::size_t bytes = cholesky_factor_bytes(common_.lnz, static_cast<std::size_t>(n_)) +
                              static_cast<std::size_t>(matrix_.nonZeros()) * (sizeof(Complex) + sizeof(int));
    require_memory(bytes, what, advice);
  } catch (...) {
    cholmod_free_factor(&factor_, &common_);
    cholmod_finish(&common_);
    throw;
  }
  {
    // Small systems (live regions, region edits) factor with single-threaded BLAS: their supernodes are too small
    // to share, and waking OpenBLAS's threads for each costs more than it gains (a 6,226-face biharmonic region of
    // the armadillo: 24 -> 21 ms for the solver's construction on an idle 2-core machine).
    std::unique_ptr<SingleThreadedBlas> single;
    if (n_ < kThreadedFactorizationSize) single = std::make_unique<SingleThreadedBlas>();
    cholmod_factorize(&view, factor_, &common_);
  }
  if (common_.status < CHOLMOD_OK || factor_->minor != factor_->n || !factor_->is_super) {
    const int status = common_.status;
    const bool not_posdef = status >= CHOLMOD_OK && factor_->minor != factor_->n;
    cholmod_free_factor(&factor_, &common_);
    cholmod_finish(&common_);
    // CHOLMOD reports a failed allocation as a status, not as an exception: it is the same condition as
    // std::bad_alloc elsewhere in the solver (MemoryError in Python, "out of memory" on the command line)
    if (status == CHOLMOD_OUT_OF_MEMORY) throw std::bad_alloc();
    throw SolverError(not_posdef ? what + " failed: the matrix is not positive definite"
                                 : what + " failed (CHOLMOD status " + std::to_string(status) + ")");
  }
  // Supernodal elimination tree: the parent of a supernode owns its first row below the diagonal block.
  const int* super = static_cast<const int*>(factor_->super);
  const int* pi = static_cast<const int*>(factor_->pi);
  const int* rows = static_cast<const int*>(factor_->s);
  const int* perm = static_cast<const int*>(factor_->Perm);
  const int nsuper = static_cast<int>(factor_->nsuper);
  supernode_of_.assign(n_, 0);
  parent_.assign(nsuper, -1);
  for (int s = 0; s < nsuper; ++s)
    for (int j = super[s]; j < super[s + 1]; ++j) supernode_of_[j] = s;
  for (int s = 0; s < nsuper; ++s) {
    const int nscol = super[s + 1] - super[s], nsrow = pi[s + 1] - pi[s];
    if (nsrow > nscol) parent_[s] = supernode_of_[rows[pi[s] + nscol]];
  }
  const int* px = static_cast<const int*>(factor_->px);
  const Complex* values = static_cast<const Complex*>(factor_->x);
  double lo = std::numeric_limits<double>::infinity(), hi = 0;
  for (int s = 0; s < nsuper; ++s) {
    const int nscol = super[s + 1] - super[s], nsrow = pi[s + 1] - pi[s];
    for (int j = 0; j < nscol; ++j) {
      const double d = std::abs(values[px[s] + static_cast<std::ptrdiff_t>(j) * nsrow + j]);
      lo = std::min(lo, d), hi = std::max(hi, d);
    }
  }
  condition_estimate_ = lo > 0 ? (hi / lo) * (hi / lo) : std::numeric_limits<double>::infinity();
  inverse_perm_.assign(n_, 0);
  for (int k = 0; k < n_; ++k) inverse_perm_[perm ? perm[k] : k] = k;
}

HermitianFactor::~HermitianFactor() {
  cholmod_free_factor(&factor_, &common_);
  cholmod_finish(&common_);
}

Eigen::MatrixXcd HermitianFactor::cholmod_solve_dense(int system, const Eigen::MatrixXcd& B) const {
  Eigen::MatrixXcd copy = B;  // CHOLMOD's dense view needs a mutable pointer; it does not write to it
  cholmod_dense view = Eigen::viewAsCholmod(copy);
  cholmod_dense* x = cholmod_solve(system, factor_, &view, &common_);
  if (!x) throw SolverError("back-substitution failed (CHOLMOD status " + std::to_string(common_.status) + ")");
  Eigen::MatrixXcd out = Eigen::Map<const Eigen::MatrixXcd>(static_cast<const Complex*>(x->x), n_, B.cols());
  cholmod_free_dense(&x, &common_);
  return out;
}

Eigen::MatrixXcd HermitianFactor::solve_block(const Eigen::MatrixXcd& B) const {
  Eigen::MatrixXcd X = cholmod_solve_dense(CHOLMOD_A, B);
  if (!X.allFinite()) throw SolverError("back-substitution produced non-finite values");
  return X;
}

Eigen::MatrixXcd HermitianFactor::extended_residual(const Eigen::MatrixXcd& B, const Eigen::MatrixXcd& X) const {
  // Row i of the Hermitian V is the conjugate of its stored column i: r_i = b_i - sum_j conj(V_ji) x_j, summed in
  // long double registers (a gather over x, one pass over V per right-hand side).
  Eigen::MatrixXcd R(n_, B.cols());
  const int* outer = matrix_.outerIndexPtr();
  const int* inner = matrix_.innerIndexPtr();
  const Complex* value = matrix_.valuePtr();
  for (Eigen::Index c = 0; c < B.cols(); ++c) {
    const Complex* x = X.col(c).data();
    for (int i = 0; i < n_; ++i) {
      long double re = B(i, c).real(), im = B(i, c).imag();
      for (int p = outer[i]; p < outer[i + 1]; ++p) {
        const long double vr = value[p].real(), vi = -value[p].imag();  // conj(V_ji) = V_ij
        const long double xr = x[inner[p]].real(), xi = x[inner[p]].imag();
        re -= vr * xr - vi * xi;
        im -= vr * xi + vi * xr;
      }
      R(i, c) = Complex(static_cast<double>(re), static_cast<double>(im));
    }
  }
  return R;
}

namespace {
/// max_i max(|Re v_i|, |Im v_i|): within a factor sqrt(2) of max_i |v_i|, without a hypot per entry (which cost more
/// than the residual's matrix product) and without the overflow of squared magnitudes.
double max_component(const ComplexVector& v) {
  const Eigen::Map<const Eigen::VectorXd> parts(reinterpret_cast<const double*>(v.data()), 2 * v.size());
  return v.size() ? parts.cwiseAbs().maxCoeff() : 0.0;
}
}  // namespace

double HermitianFactor::relative_residual(const ComplexVector& b, const ComplexVector& x) const {
  const double scale = max_component(b);
  if (!(scale > 0)) return max_component(x) > 0 ? 1.0 : 0.0;
  ComplexVector r = b;
  r.noalias() -= matrix_ * x;
  return max_component(r) / scale;
}

ComplexVector HermitianFactor::unrefined_solve(const ComplexVector& b) const {
  // A sparse right-hand side (the stencils of substituted faces, the +d spikes and the constraint loads of a one-shot
  // solve without alignment) reaches only a few supernodes in the forward substitution: 7 % of the rows of L for
  // the 30 substituted faces of an order-1 spline on the bunny, 13 % at order 2. forward() does just those, the
  // backward substitution the rest: a third less than a full solve there.
  const Eigen::Index limit = n_ / kSparseFraction;
  SparseColumn column;
  for (Eigen::Index i = 0; i < b.size(); ++i) {
    if (b[i] == 0.0) continue;
    if (static_cast<Eigen::Index>(column.size()) >= limit) return cholmod_solve_dense(CHOLMOD_A, b);
    column.emplace_back(static_cast<int>(i), b[i]);
  }
  if (column.empty()) return ComplexVector::Zero(n_);
  return backward(forward({column}).h).col(0);
}

ComplexVector HermitianFactor::solve(const ComplexVector& b, int* refinements) const {
  ComplexVector x = unrefined_solve(b);
  int steps = 0;
  // A cheap test first: well-conditioned systems (curved meshes, moderate order) stop here.
  if (needs_refinement(b, x)) {
    while (steps < kMaxRefinements && x.allFinite()) {
      const ComplexVector correction = cholmod_solve_dense(CHOLMOD_A, extended_residual(b, x));
      x += correction;
      ++steps;
      if (!(correction.cwiseAbs().maxCoeff() > kConverged * x.cwiseAbs().maxCoeff())) break;
    }
  }
  if (!x.allFinite()) throw SolverError("back-substitution produced non-finite values");
  if (refinements) *refinements = steps;
  return x;
}

double HermitianFactor::refine_block(const Eigen::MatrixXcd& B, Eigen::MatrixXcd& X) const {
  const Eigen::MatrixXcd correction = cholmod_solve_dense(CHOLMOD_A, extended_residual(B, X));
  X += correction;
  if (!X.allFinite()) throw SolverError("back-substitution produced non-finite values");
  return correction.cwiseAbs().maxCoeff() / std::max(X.cwiseAbs().maxCoeff(), 1e-300);
}

HermitianFactor::Forward HermitianFactor::forward(const std::vector<SparseColumn>& columns, bool keep_h) const {
  const int k = static_cast<int>(columns.size());
  const int nsuper = static_cast<int>(factor_->nsuper);
  const int* super = static_cast<const int*>(factor_->super);
  const int* pi = static_cast<const int*>(factor_->pi);
  const int* px = static_cast<const int*>(factor_->px);
  const int* rows = static_cast<const int*>(factor_->s);
  const Complex* values = static_cast<const Complex*>(factor_->x);
  Forward out{keep_h ? Eigen::MatrixXcd::Zero(n_, k) : Eigen::MatrixXcd(), Eigen::MatrixXcd::Zero(k, k)};
  // Which right-hand sides reach each supernode: those with an entry in it or in a descendant (ascending, one
  // list per supernode in `reach`, from reach_start[s]).
  std::vector<int> stamp(nsuper, -1), reach_start(nsuper + 1, 0);
  auto walk = [&](auto&& visit) {
    std::fill(stamp.begin(), stamp.end(), -1);
    for (int j = 0; j < k; ++j)
      for (const auto& entry : columns[j])
        for (int s = supernode_of_[inverse_perm_.at(entry.first)]; s >= 0 && stamp[s] != j; s = parent_[s])
          stamp[s] = j, visit(s, j);
  };
  walk([&](int s, int) { ++reach_start[s + 1]; });
  for (int s = 0; s < nsuper; ++s) reach_start[s + 1] += reach_start[s];
  std::vector<int> reach(reach_start[nsuper]), fill(reach_start.begin(), reach_start.end() - 1);
  walk([&](int s, int j) { reach[fill[s]++] = j; });
  // h restricted to the supernodes: block s holds its own rows of the columns that reach it (nscol x a, column
  // major), stored one after the other. Only these rows of h are ever non-zero.
  std::vector<std::ptrdiff_t> offset(nsuper + 1, 0);
  for (int s = 0; s < nsuper; ++s)
    offset[s + 1] = offset[s] + static_cast<std::ptrdiff_t>(super[s + 1] - super[s]) * (reach_start[s + 1] - reach_start[s]);
  std::vector<Complex> blocks(static_cast<std::size_t>(offset[nsuper]), Complex(0.0, 0.0));
  auto slot = [&](int s, int j) {  // position of column j in the reach list of s (j reaches s)
    return static_cast<int>(std::lower_bound(reach.begin() + reach_start[s], reach.begin() + reach_start[s + 1], j) -
                            (reach.begin() + reach_start[s]));
  };
  for (int j = 0; j < k; ++j)
    for (const auto& [i, v] : columns[j]) {
      const int row = inverse_perm_.at(i), s = supernode_of_[row];
      const int nscol = super[s + 1] - super[s];
      blocks[offset[s] + static_cast<std::ptrdiff_t>(slot(s, j)) * nscol + (row - super[s])] += v;
    }
  // Supernodes in increasing order (children before parents): solve the diagonal block, update the rows below.
  Eigen::MatrixXcd below, g;
  std::vector<int> to_slot;
  for (int s = 0; s < nsuper; ++s) {
    const int a = reach_start[s + 1] - reach_start[s];
    if (a == 0) continue;
    const int* J = reach.data() + reach_start[s];
    const int first = super[s], nscol = super[s + 1] - super[s], nsrow = pi[s + 1] - pi[s];
    // BLAS 3 on the supernode, as CHOLMOD's own solves: X = L_ss^-1 X, then the Gram update X^H X and the rows
    // below, L_below X. (Eigen's complex products repack L_below for every call: the one-shot direction solve on the
    // bunny took 1.5-2 times as long with them.)
    const Complex* block = values + px[s];
    Complex* X = blocks.data() + offset[s];
    const Complex one(1.0, 0.0), zero(0.0, 0.0);
    trsm_left('L', 'N', 'N', nscol, a, one, block, nsrow, X, nscol);  // these rows of h are final now
    g.resize(a, a);
    gemm('C', 'N', a, a, nscol, one, X, nscol, X, nscol, zero, g.data(), a);
    for (int c1 = 0; c1 < a; ++c1)
      for (int c2 = 0; c2 < a; ++c2) out.gram(J[c1], J[c2]) += g(c1, c2);
    if (keep_h)
      for (int c = 0; c < a; ++c)
        out.h.col(J[c]).segment(first, nscol) = Eigen::Map<const ComplexVector>(X + static_cast<std::ptrdiff_t>(c) * nscol, nscol);
    if (nsrow == nscol) continue;
    below.resize(nsrow - nscol, a);
    gemm('N', 'N', nsrow - nscol, a, nscol, one, block + nscol, nsrow, X, nscol, zero, below.data(), nsrow - nscol);
    // Row r below belongs to an ancestor t, which every column reaching s reaches too: map the slots of s to those
    // of t (a merge of two ascending lists), once per run of rows in the same ancestor.
    int t = -1, t_first = 0, t_nscol = 0;
    for (int r = 0; r < nsrow - nscol; ++r) {
      const int row = rows[pi[s] + nscol + r];
      if (t < 0 || row < t_first || row >= t_first + t_nscol) {
        t = supernode_of_[row], t_first = super[t], t_nscol = super[t + 1] - super[t];
        to_slot.resize(a);
        for (int c = 0, p = reach_start[t]; c < a; ++c) {
          while (reach[p] != J[c]) ++p;
          to_slot[c] = p - reach_start[t];
        }
      }
      Complex* target = blocks.data() + offset[t] + (row - t_first);
      for (int c = 0; c < a; ++c) target[static_cast<std::ptrdiff_t>(to_slot[c]) * t_nscol] -= below(r, c);
    }
  }
  if (!out.gram.allFinite()) throw SolverError("forward substitution produced non-finite values");
  return out;
}

Eigen::MatrixXcd HermitianFactor::backward(const Eigen::MatrixXcd& h) const {
  const Eigen::MatrixXcd y = cholmod_solve_dense(CHOLMOD_Lt, h);
  Eigen::MatrixXcd x(n_, y.cols());  // P^T y: row i of x is row inverse_perm_[i] of y
  for (Eigen::Index c = 0; c < y.cols(); ++c)
    for (int i = 0; i < n_; ++i) x(i, c) = y(inverse_perm_[i], c);
  if (!x.allFinite()) throw SolverError("back-substitution produced non-finite values");
  return x;
}

}  // namespace nfield
