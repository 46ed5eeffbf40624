#include "nfield/energy_rows.hpp"

#include <algorithm>
#include <string>
#include <vector>

#include "nfield/errors.hpp"

namespace nfield {
namespace {

/// S X for the Hermitian S and a compressed X (columns with sorted rows), without its exact zeros: per column a
/// dense accumulator over the rows it reaches, summed in the order of Eigen's sparse product, rows sorted. (Not
/// Eigen's (S * X).pruned(): that evaluates into a temporary and tests every entry with a hypot.)
ComplexSparse times_harmonic(const ComplexSparse& S, const ComplexSparse& X) {
  const int n = static_cast<int>(S.rows()), k = static_cast<int>(X.cols());
  std::vector<Complex> sum(n);
  std::vector<char> reached(n, 0);
  std::vector<int> rows, inner;
  std::vector<Complex> values;
  std::vector<int> outer(k + 1, 0);
  inner.reserve(static_cast<std::size_t>(3 * X.nonZeros()));
  values.reserve(inner.capacity());
  for (int j = 0; j < k; ++j) {
    rows.clear();
    for (ComplexSparse::InnerIterator x(X, j); x; ++x)
      for (ComplexSparse::InnerIterator it(S, x.row()); it; ++it) {
        const int i = static_cast<int>(it.row());
        if (!reached[i]) reached[i] = 1, sum[i] = it.value() * x.value(), rows.push_back(i);
        else sum[i] += it.value() * x.value();
      }
    std::sort(rows.begin(), rows.end());
    for (int i : rows) {
      reached[i] = 0;
      if (sum[i] != 0.0) inner.push_back(i), values.push_back(sum[i]);
    }
    outer[j + 1] = static_cast<int>(inner.size());
  }
  ComplexSparse out(n, k);
  out.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), out.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), out.innerIndexPtr());
  std::copy(values.begin(), values.end(), out.valuePtr());
  return out;
}

}  // namespace

ComplexSparse energy_columns(const FieldOperators& ops, int order, const std::vector<int>& unknowns) {
  if (order < 1 || order > 4)
    throw ParameterError("energy order must be 1 (harmonic) to 4, got " + std::to_string(order));
  const int N = ops.num_unknowns();
  const int k = static_cast<int>(unknowns.size());
  const ComplexSparse& S = ops.harmonic_matrix();  // compressed, sorted row indices per column
  // E_{:,U} = S (M^-1 S)^(m-1) restricted to U, computed from the right so that every product iterates over
  // |U| columns only. The first factor is S_{:,U}, copied column by column (no triplets, no sort).
  Eigen::Index nnz = 0;
  for (int u : unknowns) {
    if (u < 0 || u >= N) throw InputError("unknown " + std::to_string(u) + " is out of range");
    nnz += S.outerIndexPtr()[u + 1] - S.outerIndexPtr()[u];
  }
  ComplexSparse cols(N, k);
  cols.resizeNonZeros(nnz);
  int* outer = cols.outerIndexPtr();
  outer[0] = 0;
  for (int j = 0; j < k; ++j) {
    const int u = unknowns[j];
    const int begin = S.outerIndexPtr()[u], count = S.outerIndexPtr()[u + 1] - begin;
    std::copy(S.innerIndexPtr() + begin, S.innerIndexPtr() + begin + count, cols.innerIndexPtr() + outer[j]);
    std::copy(S.valuePtr() + begin, S.valuePtr() + begin + count, cols.valuePtr() + outer[j]);
    outer[j + 1] = outer[j] + count;
  }
  const Eigen::VectorXd& mass = ops.mass();
  for (int step = 1; step < order; ++step) {
    // M^-1 scales the rows, in place (times 1 / A, as energy_matrix does); then one more factor S from the left.
    for (Eigen::Index p = 0; p < cols.nonZeros(); ++p) cols.valuePtr()[p] *= 1.0 / mass[cols.innerIndexPtr()[p]];
    cols = times_harmonic(S, cols);
  }
  return cols;
}

ComplexSparse energy_rows(const FieldOperators& ops, int order, const std::vector<int>& unknowns) {
  ComplexSparse rows = energy_columns(ops, order, unknowns).adjoint();
  rows.makeCompressed();
  return rows;
}

double energy_change(const FieldOperators& ops, int order, const ComplexVector& before, const ComplexVector& after,
                     const std::vector<int>& faces) {
  if (order < 1 || order > 4)
    throw ParameterError("energy order must be 1 (harmonic) to 4, got " + std::to_string(order));
  const int F = ops.mesh().num_faces(), N = ops.num_unknowns();
  if (before.size() != F || after.size() != F)
    throw InputError("both fields must have one value per face (" + std::to_string(F) + ")");
  const ComplexSparse& S = ops.harmonic_matrix();
  const int* outer = S.outerIndexPtr();
  const int* inner = S.innerIndexPtr();
  const Complex* value = S.valuePtr();
  // level[k]: the unknowns where the k-th partial product is needed; level[order] = the changed unknowns, each
  // level below adds the neighbours (the pattern of S) of the one above.
  std::vector<std::vector<int>> level(order + 1);
  std::vector<int> seen(N, -1);
  for (int f : faces) {
    if (f < 0 || f >= F) throw InputError("face " + std::to_string(f) + " is out of range");
    const int u = ops.unknown_of_face(f);
    if (u >= 0 && seen[u] < 0) seen[u] = order, level[order].push_back(u);
  }
  for (int k = order; k > 0; --k) {
    level[k - 1] = level[k];
    for (int i : level[k])
      for (int p = outer[i]; p < outer[i + 1]; ++p)
        if (seen[inner[p]] < 0) seen[inner[p]] = k - 1, level[k - 1].push_back(inner[p]);
  }
  // (E z)_i on level[order]: x = z on level[0], then x <- S x (times M^-1 but for the last step) on each level.
  // S is Hermitian, so row i of S is the conjugate of its stored column i.
  auto apply = [&](const ComplexVector& field) {
    ComplexVector x = ComplexVector::Zero(N), y = ComplexVector::Zero(N);
    for (int u : level[0]) x[u] = field[ops.face_of_unknown(u)];
    for (int k = 1; k <= order; ++k) {
      for (int i : level[k]) {
        Complex sum = 0.0;
        for (int p = outer[i]; p < outer[i + 1]; ++p) sum += std::conj(value[p]) * x[inner[p]];
        y[i] = k < order ? sum / ops.mass()[i] : sum;
      }
      std::swap(x, y);
    }
    return x;
  };
  const ComplexVector e_before = apply(before), e_after = apply(after);
  double change = 0.0;
  for (int u : level[order]) {
    const int f = ops.face_of_unknown(u);
    change += (std::conj(after[f] - before[f]) * (e_before[u] + e_after[u])).real();
  }
  return change;
}

}  // namespace nfield
