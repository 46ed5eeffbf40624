#include "nfield/spectrum_slicing.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <memory>
#include <new>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "nfield/blas.hpp"
#include "nfield/errors.hpp"
#include "nfield/shifted_factor.hpp"
#include "nfield/slice_lanczos.hpp"

namespace nfield {
namespace {

using Eigen::MatrixXcd;
using Eigen::VectorXd;

/// Seed of the random start blocks (slice j uses kSeed + j): results are reproducible.
constexpr std::uint64_t kSeed = 0x6e6669656c64ULL;

/// The user's progress callback seen from the calling thread: monotone, capped at 0.99 (the caller
/// reports the end), Cancelled when the callback returns false.
class Progress {
 public:
  explicit Progress(const ProgressCallback& callback) : callback_(callback) {}
  void operator()(double p) {
    p = std::max(value_, std::min(p, 0.99));
    value_ = p;
    if (callback_ && !callback_(p)) throw Cancelled("spectral basis computation cancelled");
  }

 private:
  const ProgressCallback& callback_;
  double value_ = 0;
};

/// Small k: the k eigenvalues nearest a shift below the spectrum.
Eigenpairs single_shift_eigenpairs(const ComplexSparse& S, const VectorXd& mass, const VectorXd& d, int k,
                                   double unit, const SpectralBasisOptions& opt, Progress& report) {
  const int b = std::min(opt.block_size, std::max(8, k / 8));
  ShiftedFactor factor(S, mass, true);
  if (!factor.factor(-1e-2 * unit))
    throw SolverError("spectral basis: factorization of S - sigma M failed (matrix not positive definite)");
  SliceLanczos lanczos(factor, d, -INFINITY, INFINITY, k, b, opt.tolerance, opt.max_restarts,
                       [&](double f) { report(f); }, kSeed);
  Eigenpairs r = lanczos.run();
  report(1.0);
  return r;
}

/// Boundaries B_0 = 0 < B_1 < ... < B_p and the exact counts count(B_j) (counts[0] = 0, counts[p] >= k).
struct Slices {
  std::vector<double> bounds{0.0};
  std::vector<int> counts{0};
  int size() const { return static_cast<int>(bounds.size()) - 1; }  ///< p
  int count(int j) const { return counts[j] - counts[j - 1]; }      ///< eigenvalues in slice j (1..p)
};

/// Places the slice boundaries (Weyl's law, corrected by the measured density) with exact counts from the
/// inertia of `ldl` (an LDL^H ShiftedFactor of S, M).
Slices place_slices(ShiftedFactor& ldl, int k, int slice, double unit, Progress& report) {
  Slices s;
  double density = 0.5 / unit;
  while (s.counts.back() < k) {
    const int have = s.counts.back(), need = k - have;
    const int target = need <= slice + slice / 2 ? need + std::max(3, need / 25) : slice;
    const double prev = s.bounds.back();
    double B = prev + target / density;
    int count = -1;
    for (int attempt = 0; attempt < 6; ++attempt) {
      if (!ldl.factor(B)) {
        B *= 1 + 1e-7;
        continue;
      }
      count = ldl.negative_pivots();
      const int c = count - have;
      const bool last = need <= slice + slice / 2;  // this slice should reach k (no tiny trailing slice)
      const bool ok = last ? count >= k && count <= k + std::max(6, need / 8) : c >= target * 0.6 && c <= target * 1.6;
      if (ok || attempt == 5) break;
      density = std::max(c, 1) / (B - prev);
      B = prev + (last ? target * 1.03 + 2 : target) / density;
      report(0.05 * have / k);
    }
    if (count < 0) throw SolverError("spectral basis: factorization of S - sigma M failed");
    if (count <= have) {  // no progress at all (cannot happen unless the counts are broken)
      B = prev + 4 * (B - prev);
      if (!ldl.factor(B)) throw SolverError("spectral basis: factorization of S - sigma M failed");
      count = ldl.negative_pivots();
      if (count <= have) throw SolverError("spectral basis: inertia count does not increase");
    }
    if (count - have > 0) density = (count - have) / (B - prev);
    s.bounds.push_back(B);
    s.counts.push_back(count);
    report(0.05 * std::min(count, k) / k);
  }
  return s;
}

/// Solves every slice into its columns [counts[j-1], counts[j]) of Z and entries of `values`: two workers
/// when the machine has two cores and there are at least two slices (worker 0 reuses `ldl`, worker 1 has
/// its own factor). The calling thread reports progress and forwards cancellation; the first error of a
/// worker stops the others and is rethrown.
void solve_slices(const ComplexSparse& S, const VectorXd& mass, const VectorXd& d, const Slices& slices,
                  ShiftedFactor& ldl, const SpectralBasisOptions& opt, Progress& report, MatrixXcd& Z,
                  VectorXd& values) {
  const int p = slices.size(), total = slices.counts.back();
  const std::vector<double>& bounds = slices.bounds;
  const std::vector<int>& counts = slices.counts;
  const int workers = p >= 2 && std::thread::hardware_concurrency() > 1 ? 2 : 1;
  std::vector<std::unique_ptr<ShiftedFactor>> extra;
  std::vector<ShiftedFactor*> factors{&ldl};
  for (int w = 1; w < workers; ++w) {
    extra.push_back(std::make_unique<ShiftedFactor>(S, mass, false));
    factors.push_back(extra.back().get());
  }
  // Largest slices first (balances the two workers).
  std::vector<int> queue;
  for (int j = 1; j <= p; ++j) queue.push_back(j);
  std::stable_sort(queue.begin(), queue.end(), [&](int a, int b) { return slices.count(a) > slices.count(b); });
  std::atomic<int> next_slice{0}, finished{0};
  std::atomic<bool> stop{false};
  std::unique_ptr<std::atomic<double>[]> slice_progress(new std::atomic<double>[p + 1]);
  for (int j = 0; j <= p; ++j) slice_progress[j] = 0.0;
  std::vector<std::exception_ptr> errors(workers);
  auto overall = [&]() {
    double done = 0;
    for (int j = 1; j <= p; ++j) done += slices.count(j) * slice_progress[j].load();
    return 0.05 + 0.93 * done / total;
  };
  auto worker = [&](int w) {
    try {
      for (;;) {
        if (stop) return;
        const int q = next_slice++;
        if (q >= p) return;
        const int j = queue[q];
        const int c = slices.count(j);
        if (c == 0) continue;
        ShiftedFactor& factor = *factors[w];
        factor.set_solve_threads(workers == 1 ? 2 : 1);
        const double lo = j == 1 ? -INFINITY : bounds[j - 1], hi = bounds[j];
        double sigma = 0.5 * (bounds[j - 1] + bounds[j]);
        bool ok = factor.factor(sigma);
        for (int attempt = 0; !ok && attempt < 4; ++attempt) ok = factor.factor(sigma *= 1 + 1e-6);
        if (!ok) throw SolverError("spectral basis: factorization of S - sigma M failed");
        const int b = std::min(opt.block_size, std::max(8, c / 8));
        SliceLanczos lanczos(factor, d, lo, hi, c, b, opt.tolerance, opt.max_restarts,
                             [&, j](double f) {
                               slice_progress[j] = f;
                               if (workers == 1) report(overall());
                               if (stop) throw Cancelled("spectral basis computation cancelled");
                             },
                             kSeed + j);
        Eigenpairs r = lanczos.run();
        if (r.values.size() != c) throw SolverError("spectral basis: slice returned the wrong number of eigenpairs");
        Z.middleCols(counts[j - 1], c) = r.vectors;  // disjoint columns per slice
        values.segment(counts[j - 1], c) = r.values;
        slice_progress[j] = 1.0;
      }
    } catch (...) {
      errors[w] = std::current_exception();
      stop = true;
    }
  };
  if (workers == 1) {
    worker(0);
  } else {
    SingleThreadedBlas blas_guard;  // two workers already use both cores
    std::vector<std::thread> threads;
    for (int w = 0; w < workers; ++w)
      threads.emplace_back([&, w] {
        worker(w);
        ++finished;
      });
    std::exception_ptr cancelled;
    while (finished < workers) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (!cancelled && !stop) {
        try {
          report(overall());
        } catch (...) {
          cancelled = std::current_exception();
          stop = true;
        }
      }
    }
    for (auto& t : threads) t.join();
    if (cancelled) std::rethrow_exception(cancelled);
  }
  for (const auto& e : errors)
    if (e) std::rethrow_exception(e);
}

/// Rayleigh-Ritz of S, M on the columns `idx` of Z (in place; values updated): makes a group of
/// vectors computed from different shifts exactly M-orthonormal again.
void local_rayleigh_ritz(const ComplexSparse& S, const VectorXd& mass, MatrixXcd& Z, VectorXd& values,
                         const std::vector<int>& idx) {
  const int q = static_cast<int>(idx.size());
  if (q == 0) return;
  MatrixXcd Q(Z.rows(), q);
  for (int i = 0; i < q; ++i) Q.col(i) = Z.col(idx[i]);
  const MatrixXcd MQ = mass.cast<Complex>().asDiagonal() * Q;
  const MatrixXcd SQ = S * Q;
  MatrixXcd G = Q.adjoint() * MQ, Hs = Q.adjoint() * SQ;
  G = (0.5 * (G + G.adjoint())).eval();
  Hs = (0.5 * (Hs + Hs.adjoint())).eval();
  Eigen::GeneralizedSelfAdjointEigenSolver<MatrixXcd> ges(Hs, G);
  if (ges.info() != Eigen::Success) throw SolverError("spectral basis: local Rayleigh-Ritz failed");
  const MatrixXcd Qn = Q * ges.eigenvectors();
  for (int i = 0; i < q; ++i) {
    Z.col(idx[i]) = Qn.col(i);
    values[idx[i]] = ges.eigenvalues()[i];
  }
}

/// Restores M-orthogonality between adjacent slices where it is visible (inner products above 1e-12).
void glue_slices(const ComplexSparse& S, const VectorXd& mass, const Slices& slices, MatrixXcd& Z, VectorXd& values) {
  const std::vector<int>& counts = slices.counts;
  for (int j = 1; j < slices.size(); ++j) {
    const int a0 = counts[j - 1], a1 = counts[j], b1 = counts[j + 1];
    if (a1 == a0 || b1 == a1) continue;
    const MatrixXcd G = Z.middleCols(a0, a1 - a0).adjoint() *
                        (mass.cast<Complex>().asDiagonal() * Z.middleCols(a1, b1 - a1));
    std::vector<int> idx;
    for (int r = 0; r < G.rows(); ++r)
      if (G.row(r).cwiseAbs().maxCoeff() > 1e-12) idx.push_back(a0 + r);
    for (int c = 0; c < G.cols(); ++c)
      if (G.col(c).cwiseAbs().maxCoeff() > 1e-12) idx.push_back(a1 + c);
    local_rayleigh_ritz(S, mass, Z, values, idx);
  }
}

/// The k smallest of the pairs (Z, values), ascending (moves Z when it is already in order).
Eigenpairs first_k_ascending(MatrixXcd& Z, const VectorXd& values, int k) {
  const int total = static_cast<int>(values.size());
  std::vector<int> order(total);
  for (int i = 0; i < total; ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return values[a] < values[b]; });
  Eigenpairs out;
  out.values.resize(k);
  bool sorted = true;
  for (int i = 0; i < k; ++i) sorted &= order[i] == i;
  for (int i = 0; i < k; ++i) out.values[i] = values[order[i]];
  if (sorted) {
    Z.conservativeResize(Eigen::NoChange, k);
    out.vectors = std::move(Z);
  } else {
    out.vectors.resize(Z.rows(), k);
    for (int i = 0; i < k; ++i) out.vectors.col(i) = Z.col(order[i]);
  }
  return out;
}

}  // namespace

Eigenpairs sliced_eigenpairs(const ComplexSparse& S, const VectorXd& mass, int k, double unit,
                             const SpectralBasisOptions& opt, const ProgressCallback& progress) {
  const int N = static_cast<int>(S.rows());
  const VectorXd d = mass.cwiseSqrt();
  Progress report(progress);
  report(0.0);
  const int slice = opt.slice_size > 0 ? opt.slice_size : 100;
  const int max_count = sliced_max_k(N);
  if (k > max_count)
    throw ParameterError("k=" + std::to_string(k) + " is too close to the problem size " + std::to_string(N) +
                         " for the iterative eigen solver; choose k <= " + std::to_string(max_count));
  if (k <= slice + slice / 2) return single_shift_eigenpairs(S, mass, d, k, unit, opt, report);

  ShiftedFactor ldl(S, mass, false);
  const Slices slices = place_slices(ldl, k, slice, unit, report);
  const int total = slices.counts.back();
  MatrixXcd Z;
  try {
    Z.resize(N, total);
  } catch (const std::bad_alloc&) {
    throw SolverError("spectral basis: not enough memory for the eigenvectors");
  }
  VectorXd values(total);
  solve_slices(S, mass, d, slices, ldl, opt, report, Z, values);
  glue_slices(S, mass, slices, Z, values);
  Eigenpairs out = first_k_ascending(Z, values, k);
  report(1.0);
  return out;
}

}  // namespace nfield
