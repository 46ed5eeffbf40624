#include "nfield/operators.hpp"

#include <algorithm>
#include <cmath>

#include "nfield/errors.hpp"

namespace nfield {

EdgeWeights parse_edge_weights(const std::string& name) {
  if (name == "geometric") return EdgeWeights::Geometric;
  if (name == "combinatorial") return EdgeWeights::Combinatorial;
  throw ParameterError("unknown edge weights '" + name + "' (expected 'geometric' or 'combinatorial')");
}

std::string to_string(EdgeWeights w) { return w == EdgeWeights::Geometric ? "geometric" : "combinatorial"; }

FieldOperators::FieldOperators(std::shared_ptr<const TriangleMesh> mesh, int n, EdgeWeights weights)
    : mesh_(std::move(mesh)), n_(n), weights_(weights), frames_(*mesh_), connection_(*mesh_, frames_) {
  if (n < 1 || n > 64) throw ParameterError("symmetry n must be between 1 and 64, got " + std::to_string(n));
  const TriangleMesh& m = *mesh_;
  unknown_of_face_.assign(m.num_faces(), -1);
  for (int f = 0; f < m.num_faces(); ++f) {
    if (!m.face_active(f)) continue;
    unknown_of_face_[f] = static_cast<int>(face_of_unknown_.size());
    face_of_unknown_.push_back(f);
  }
  if (face_of_unknown_.empty()) throw InputError("the mesh has no usable (non-degenerate) face");
  const int N = num_unknowns();
  mass_.resize(N);
  for (int u = 0; u < N; ++u) mass_[u] = m.face_area(face_of_unknown_[u]);

  const auto& P = m.positions();
  const auto& edges = m.dual_edges();
  edge_weight_.resize(edges.size());
  transport_.resize(edges.size());
  for (size_t e = 0; e < edges.size(); ++e) {
    const DualEdge& d = edges[e];
    double w = 1.0;
    if (weights_ == EdgeWeights::Geometric) {
      const double l2 = (P.row(d.vertex1) - P.row(d.vertex0)).squaredNorm();
      w = 3.0 * l2 / (m.face_area(d.face0) + m.face_area(d.face1));
    }
    edge_weight_[e] = w;
    transport_[e] = connection_.transport(static_cast<int>(e), n_);
  }
  // S column by column (compressed storage written directly: the assembly is part of every solve from scratch).
  // w |r z_a - z_b|^2 = w (|z_a|^2 + |z_b|^2) - w conj(z_b) r z_a - w conj(z_a) conj(r) z_b  (a = face0, b = face1):
  // column a holds -w r in row b, column b holds -w conj(r) in row a, both diagonals w.
  std::vector<int> start(N + 1, 0);
  std::vector<std::pair<int, Complex>> entries;
  entries.reserve(N + 2 * edges.size());
  std::vector<std::pair<int, Complex>> column;
  for (int a = 0; a < N; ++a) {
    const int f = face_of_unknown_[a];
    column.clear();
    double diagonal = 0.0;
    for (int e : m.face_dual_edges(f)) {
      const DualEdge& d = edges[e];
      const double w = edge_weight_[e];
      diagonal += w;
      if (d.face0 == f)
        column.emplace_back(unknown_of_face_[d.face1], -w * transport_[e]);
      else
        column.emplace_back(unknown_of_face_[d.face0], -w * std::conj(transport_[e]));
    }
    column.emplace_back(a, Complex(diagonal, 0.0));
    std::sort(column.begin(), column.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    for (const auto& [row, value] : column) {
      if (!entries.empty() && static_cast<int>(entries.size()) > start[a] && entries.back().first == row)
        entries.back().second += value;  // two dual edges between the same faces (never on a clean mesh)
      else
        entries.emplace_back(row, value);
    }
    start[a + 1] = static_cast<int>(entries.size());
  }
  harmonic_.resize(N, N);
  harmonic_.resizeNonZeros(static_cast<Eigen::Index>(entries.size()));
  std::copy(start.begin(), start.end(), harmonic_.outerIndexPtr());
  for (size_t k = 0; k < entries.size(); ++k) {
    harmonic_.innerIndexPtr()[k] = entries[k].first;
    harmonic_.valuePtr()[k] = entries[k].second;
  }
}

ComplexSparse FieldOperators::energy_matrix(int order) const {
  if (order < 1 || order > 4)
    throw ParameterError("energy order must be 1 (harmonic) to 4, got " + std::to_string(order));
  ComplexSparse E = harmonic_;
  if (order == 1) return E;
  const Eigen::VectorXcd inv_mass = mass_.cwiseInverse().cast<Complex>();
  const ComplexSparse MinvS = inv_mass.asDiagonal() * harmonic_;
  for (int k = 1; k < order; ++k) E = (E * MinvS).pruned();
  // Products are Hermitian in exact arithmetic; remove the rounding asymmetry so that
  // Cholesky on one triangle sees the same matrix as products with the full one.
  ComplexSparse Eh = E.adjoint();
  E = 0.5 * (E + Eh);
  E.makeCompressed();
  return E;
}

double FieldOperators::energy(const ComplexVector& z, int order) const {
  if (z.size() != num_unknowns())
    throw InputError("expected one value per unknown (" + std::to_string(num_unknowns()) + "), got " +
                     std::to_string(z.size()));
  if (!z.allFinite()) throw InputError("the field has NaN or infinite values: its energy is undefined");
  if (order == 1) return (z.adjoint() * (harmonic_ * z)).value().real();
  // E_m = S (M^-1 S)^(m-1): apply S and M^-1 alternately instead of forming the product.
  // For even m, z^H E_m z = |L^{m/2} z|_M^2; computing it as a sum keeps it non-negative.
  ComplexVector y = z;
  for (int k = 0; k < order; ++k) {
    y = harmonic_ * y;
    if (k + 1 < order) y = y.cwiseQuotient(mass_.cast<Complex>());
  }
  return (z.adjoint() * y).value().real();
}

ComplexVector FieldOperators::to_unknowns(const ComplexVector& per_face) const {
  if (per_face.size() != mesh_->num_faces())
    throw InputError("expected one value per face (" + std::to_string(mesh_->num_faces()) + "), got " +
                     std::to_string(per_face.size()));
  ComplexVector out(num_unknowns());
  for (int u = 0; u < num_unknowns(); ++u) out[u] = per_face[face_of_unknown_[u]];
  return out;
}

ComplexVector FieldOperators::to_faces(const ComplexVector& per_unknown) const {
  ComplexVector out = ComplexVector::Zero(mesh_->num_faces());
  for (int u = 0; u < num_unknowns(); ++u) out[face_of_unknown_[u]] = per_unknown[u];
  return out;
}

double FieldOperators::eigenvalue_unit(int order) const {
  return std::pow(4.0 * M_PI / mesh_->total_area(), order);
}

}  // namespace nfield
