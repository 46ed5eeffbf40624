#include "nfield/energy_rows.hpp"

#include <string>

#include "nfield/errors.hpp"

namespace nfield {

ComplexSparse energy_rows(const FieldOperators& ops, int order, const std::vector<int>& unknowns) {
  if (order < 1 || order > 4)
    throw ParameterError("energy order must be 1 (harmonic) to 4, got " + std::to_string(order));
  const int N = ops.num_unknowns();
  const ComplexSparse& S = ops.harmonic_matrix();
  // The columns E_{:,U} = S (M^-1 S)^(m-1) restricted to U, computed from the right so that every product
  // iterates over |U| columns only; E is Hermitian, so the rows are their adjoint.
  std::vector<Eigen::Triplet<Complex>> triplets;
  for (std::size_t i = 0; i < unknowns.size(); ++i) {
    const int u = unknowns[i];
    if (u < 0 || u >= N) throw InputError("unknown " + std::to_string(u) + " is out of range");
    for (ComplexSparse::InnerIterator it(S, u); it; ++it)
      triplets.emplace_back(static_cast<int>(it.row()), static_cast<int>(i), it.value());
  }
  ComplexSparse cols(N, static_cast<int>(unknowns.size()));
  cols.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::VectorXcd inv_mass = ops.mass().cwiseInverse().cast<Complex>();
  for (int k = 1; k < order; ++k) {
    const ComplexSparse scaled = inv_mass.asDiagonal() * cols;
    cols = (S * scaled).pruned();
  }
  ComplexSparse rows = cols.adjoint();
  rows.makeCompressed();
  return rows;
}

}  // namespace nfield
