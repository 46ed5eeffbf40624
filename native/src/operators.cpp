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

  // S in compressed columns, written edge by edge (the assembly is part of every solve from scratch; walking the
  // dual edges in order instead of each face's edges halves its cost, which is memory latency).
  // w |r z_a - z_b|^2 = w (|z_a|^2 + |z_b|^2) - w conj(z_b) r z_a - w conj(z_a) conj(r) z_b  (a = face0, b = face1):
  // column a holds -w r in row b, column b holds -w conj(r) in row a, both diagonals w.
  const auto& P = m.positions();
  const auto& edges = m.dual_edges();
  edge_weight_.resize(edges.size());
  transport_.resize(edges.size());
  std::vector<int> start(N + 1, 0);
  for (int a = 0; a < N; ++a)
    start[a + 1] = start[a] + 1 + static_cast<int>(m.face_dual_edges(face_of_unknown_[a]).size());
  std::vector<int> row(start[N]);
  std::vector<Complex> value(start[N]);
  std::vector<int> next(start.begin(), start.end() - 1);
  std::vector<double> diagonal(N, 0.0);
  for (size_t e = 0; e < edges.size(); ++e) {
    const DualEdge& d = edges[e];
    double w = 1.0;
    if (weights_ == EdgeWeights::Geometric) {
      const double l2 = (P.row(d.vertex1) - P.row(d.vertex0)).squaredNorm();
      w = 3.0 * l2 / (m.face_area(d.face0) + m.face_area(d.face1));
    }
    const Complex r = connection_.transport(static_cast<int>(e), n_);
    edge_weight_[e] = w;
    transport_[e] = r;
    const int a = unknown_of_face_[d.face0], b = unknown_of_face_[d.face1];
    row[next[a]] = b, value[next[a]++] = -w * r;
    row[next[b]] = a, value[next[b]++] = -w * std::conj(r);
    diagonal[a] += w, diagonal[b] += w;
  }
  // Each column: its diagonal, its rows in order, two dual edges between the same faces (never on a clean mesh)
  // summed into one entry.
  harmonic_.resize(N, N);
  harmonic_.resizeNonZeros(start[N]);
  int* outer = harmonic_.outerIndexPtr();
  int* inner = harmonic_.innerIndexPtr();
  Complex* values = harmonic_.valuePtr();
  std::vector<std::pair<int, Complex>> column;
  int nnz = 0;
  for (int a = 0; a < N; ++a) {
    column.assign(1, {a, Complex(diagonal[a], 0.0)});
    for (int k = start[a]; k < next[a]; ++k) column.emplace_back(row[k], value[k]);
    std::sort(column.begin(), column.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    outer[a] = nnz;
    for (const auto& [i, v] : column) {
      if (nnz > outer[a] && inner[nnz - 1] == i) {
        values[nnz - 1] += v;
      } else {
        inner[nnz] = i, values[nnz] = v;
        ++nnz;
      }
    }
  }
  outer[N] = nnz;
  harmonic_.resizeNonZeros(nnz);
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
