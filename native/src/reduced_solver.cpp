#include "nfield/reduced_solver.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "nfield/errors.hpp"
#include "nfield/singularities.hpp"

namespace nfield {

ReducedSolver::ReducedSolver(std::shared_ptr<const FieldOperators> ops, std::shared_ptr<const SpectralBasis> basis,
                             int order, double strength, const ComplexVector& alignment, SplineKind kind,
                             double lambda_override)
    : ConstraintEditor(std::move(ops)), basis_(std::move(basis)), order_(order), kind_(kind) {
  if (!ops_ || !basis_) throw ParameterError("reduced solver needs operators and a spectral basis");
  if (order < 1 || order > 4) throw ParameterError("energy order must be 1 to 4, got " + std::to_string(order));
  const FieldOperators& o = *ops_;
  if (basis_->size() < 1 || basis_->num_unknowns() != o.num_unknowns() ||
      basis_->mesh_hash() != o.mesh().content_hash() || basis_->n() != o.n() || basis_->weights() != o.weights())
    throw ParameterError("spectral basis was computed for different operators (mesh, n or weights)");
  nu_m_ = basis_->values().array().max(0.0).pow(order);
  set_alignment(alignment);
  if (std::isfinite(lambda_override))
    set_lambda(lambda_override);
  else if (kind == SplineKind::Vector && !has_alignment_)
    update_lambda(nu_m_.minCoeff() > kReducedFlatTolerance * o.eigenvalue_unit(order)
                      ? 0.0
                      : -kReducedVectorRegularisation * o.eigenvalue_unit(order));
  else
    update_lambda(strength_to_lambda(o, order, strength));
}

void ReducedSolver::update_lambda(double lambda) {
  const Eigen::VectorXd diag = nu_m_.array() - lambda;
  if (!(diag.minCoeff() > 0) || !std::isfinite(lambda))
    throw ParameterError("lambda=" + std::to_string(lambda) + " makes the reduced system singular or indefinite");
  lambda_ = lambda;
  inv_diag_ = diag.cwiseInverse();
}

void ReducedSolver::set_strength(double strength) {
  if (kind_ == SplineKind::Vector && !has_alignment_) return;  // fixed regularisation, as ExactSolver
  update_lambda(strength_to_lambda(*ops_, order_, strength));
}

void ReducedSolver::set_lambda(double lambda) { update_lambda(lambda); }

void ReducedSolver::set_alignment(const ComplexVector& alignment) {
  const FieldOperators& o = *ops_;
  const TriangleMesh& mesh = o.mesh();
  const int N = o.num_unknowns();
  has_alignment_ = alignment.size() > 0;
  alignment_ = ComplexVector::Zero(N);
  if (has_alignment_) {
    if (alignment.size() != mesh.num_faces())
      throw InputError("alignment field must have one value per face (" + std::to_string(mesh.num_faces()) +
                       "), got " + std::to_string(alignment.size()));
    if (!alignment.allFinite()) throw InputError("alignment field contains NaN or infinite values");
    for (int u = 0; u < N; ++u) alignment_[u] = alignment[o.face_of_unknown(u)];
  }
  spike_ = safeguard_spike(alignment_);
  projected_ = has_alignment_ ? basis_->project(alignment_) : ComplexVector::Zero(basis_->size());
}

const ComplexVector& ReducedSolver::basis_row(int face) {
  auto it = rows_.find(face);
  if (it != rows_.end()) return it->second;
  const int u = ops_->unknown_of_face(face);
  const int k = basis_->size();
  ComplexVector r(k);
  if (basis_->precision() == BasisPrecision::Single) {
    const Eigen::MatrixXcf& U = basis_->vectors_single();
    for (int i = 0; i < k; ++i) r[i] = std::conj(Complex(U(u, i)));
  } else {
    const Eigen::MatrixXcd& U = basis_->vectors_double();
    for (int i = 0; i < k; ++i) r[i] = std::conj(U(u, i));
  }
  if (rows_.size() > 4096) rows_.clear();  // bounded cache
  return rows_.emplace(face, std::move(r)).first->second;
}

Complex ReducedSolver::value_at(const ComplexVector& x, int face) {
  return basis_row(face).dot(x);  // sum conj(conj U) x = (U x)_f
}

ComplexVector ReducedSolver::schur_solve(const std::vector<ConstraintRow>& rows, const ComplexVector& y) {
  const int R = static_cast<int>(rows.size()), k = size();
  constraint_residual_ = 0;
  if (R == 0) return y;
  // G = [g_1 .. g_R], g_r = sum_t c_t conj(U[f_t, :])^T; row functional on x: Re(g_r^H x).
  Eigen::MatrixXcd G = Eigen::MatrixXcd::Zero(k, R);
  for (int r = 0; r < R; ++r)
    for (const auto& [f, c] : rows[r].terms) G.col(r) += c * basis_row(f);
  const Eigen::MatrixXcd LG = inv_diag_.cast<Complex>().asDiagonal() * G;
  // K = Re(G^H Lambda^-1 G) = Gr^T L Gr + Gi^T L Gi (real products: half the work of the complex one).
  const Eigen::MatrixXd Gr = G.real(), Gi = G.imag();
  Eigen::MatrixXd K = Gr.transpose() * (inv_diag_.asDiagonal() * Gr);
  K.noalias() += Gi.transpose() * (inv_diag_.asDiagonal() * Gi);
  Eigen::VectorXd rhs(R), h(R);
  for (int r = 0; r < R; ++r) h[r] = rows[r].rhs;
  rhs = (G.adjoint() * y).real() - h;
  // Rows dependent in the basis: least squares (the residual below reports it).
  const Eigen::VectorXd gamma = solve_constraint_system(K, rhs).gamma;
  ComplexVector x = y - LG * gamma.cast<Complex>();
  // Constraint violation, relative to the largest value at a constrained face.
  const Eigen::VectorXd l = (G.adjoint() * x).real();
  double scale = 0;
  for (int r = 0; r < R; ++r) scale = std::max(scale, std::abs(h[r]));
  for (const auto& row : rows)
    for (const auto& t : row.terms) scale = std::max(scale, std::abs(value_at(x, t.first)));
  constraint_residual_ = (l - h).cwiseAbs().maxCoeff() / std::max(scale, 1e-300);
  return x;
}

ComplexVector ReducedSolver::solve_coefficients() {
  const FieldOperators& o = *ops_;
  const TriangleMesh& mesh = o.mesh();
  sign_fixed_.clear();
  pins_ = OrientationPins{};
  const double rhs_scale = kind_ == SplineKind::Direction ? 1.0 : -lambda_;
  // b_U = U^H b with the +d safeguard u'_f = s_f d_f at direction constraints (O(k) per face).
  ComplexVector bU = rhs_scale * projected_;
  bool has_data = has_alignment_;
  const double mean_area = mesh.total_area() / o.num_unknowns();
  for (const auto& [f, c] : constraints_.faces) {
    if (c.kind == ConstraintSet::Kind::Direction) {
      const int u = o.unknown_of_face(f);
      const double area = o.mass()[u];
      const Complex delta = safeguard_delta(spike_, mean_area, area, c.value, alignment_[u]);
      bU += (rhs_scale * area * delta) * basis_row(f);
      has_data = true;
    } else if (std::abs(c.value) > 0) {
      has_data = true;
    }
  }

  auto solve_with_pins = [&](const ComplexVector& b) {
    const ComplexVector y = inv_diag_.cast<Complex>().cwiseProduct(b);
    OrientationPins pins;
    for (;;) {
      const ComplexVector x = schur_solve(constraints_.rows(pins.faces, pins.magnitude), y);
      if (!pins.update(constraints_, [&](int f) { return value_at(x, f); })) continue;
      sign_fixed_ = pins.faces;
      pins_ = pins;
      return x;
    }
  };

  ComplexVector x;
  const int k = size();
  if (has_data) {
    x = solve_with_pins(bU);
  } else if (constraints_.size() == 0) {
    // The smoothest field: first basis vector, scaled to unit RMS (other components: see solve()).
    x = ComplexVector::Zero(k);
    x[0] = std::sqrt(mesh.total_area());
  } else {
    // Homogeneous constraints only: smoothest field under them, by inverse iteration in the basis
    // (b = M z for z = U x is b_U = x).
    ComplexVector seed = ComplexVector::Zero(k);
    seed[0] = 1.0;
    for (int it = 0; it < 50; ++it) {
      ComplexVector next = solve_with_pins(seed);
      const double norm = next.norm();
      if (!(norm > 0)) throw SolverError("singularity constraints admit only the zero field here");
      next /= norm;
      const double change = (next - seed).norm();
      seed = next;
      if (change < 1e-10) break;
    }
    x = solve_with_pins(seed * std::sqrt(mesh.total_area()));  // the exact solver's scale convention
  }
  last_x_ = x;
  return x;
}

ComplexVector ReducedSolver::reconstruct(const ComplexVector& x) const {
  return ops_->to_faces(basis_->reconstruct(x));
}

ComplexVector ReducedSolver::solve() {
  const ComplexVector x = solve_coefficients();
  ComplexVector field = reconstruct(x);
  // Snap constrained faces onto their constraint (as the exact solver does).
  for (const auto& [f, c] : constraints_.faces) field[f] = pins_.snapped(f, c, field[f]);
  fill_empty_components(field);
  return field;
}

void ReducedSolver::fill_empty_components(ComplexVector& field) {
  const FieldOperators& o = *ops_;
  const TriangleMesh& mesh = o.mesh();
  const int ncomp = std::max(1, mesh.report().num_components);
  uncovered_components_ = 0;
  if (ncomp == 1) return;  // the reduced solution already covers the only component
  const std::vector<int>& comp = mesh.face_component();
  const int N = o.num_unknowns();
  const std::vector<bool>& covered = covered_components();
  for (bool c : covered) uncovered_components_ += c ? 0 : 1;
  if (uncovered_components_ > 0) {
    // What the basis cannot reach is zero (the reduced solution there is rounding noise); constrained
    // faces keep their snapped values.
    for (int u = 0; u < N; ++u) {
      const int f = o.face_of_unknown(u);
      if (!covered[comp[f]] && !constraints_.faces.count(f)) field[f] = 0;
    }
  }
  std::vector<bool> has_data(ncomp, false);
  for (int u = 0; u < N; ++u)
    if (std::abs(alignment_[u]) > 0) has_data[comp[o.face_of_unknown(u)]] = true;
  for (const auto& [f, c] : constraints_.faces) has_data[comp[f]] = true;
  for (const auto& [v, rows] : constraints_.singularity_rows) has_data[comp[rows.front().terms.front().first]] = true;
  bool any_empty = false, any_data = false;
  for (int c = 0; c < ncomp; ++c)
    if (covered[c]) (has_data[c] ? any_data : any_empty) = true;
  if (!any_empty) return;
  // Scale of the fill: the RMS magnitude of the solved components (unit RMS if nothing was solved).
  double rest = 0, rest_area = 0;
  std::vector<double> comp_area(ncomp, 0.0);
  for (int u = 0; u < N; ++u) {
    const int f = o.face_of_unknown(u), c = comp[f];
    comp_area[c] += o.mass()[u];
    if (has_data[c] && covered[c]) rest += o.mass()[u] * std::norm(field[f]), rest_area += o.mass()[u];
  }
  const double scale = any_data && rest > 1e-300 ? std::sqrt(rest / rest_area) : 1.0;
  // Each empty component gets its smoothest field: the restriction of the lowest basis vector with weight
  // on it. (S and M are block diagonal over components, so such a restriction is an eigenvector of that
  // component's block, with the same eigenvalue, even when eigenvectors of equal eigenvalues mix blocks.)
  const int k = size();
  for (int c = 0; c < ncomp; ++c) {
    if (has_data[c] || !covered[c] || comp_area[c] <= 0) continue;
    bool filled = false;
    for (int j = 0; j < k && !filled; ++j) {
      const ComplexVector v = basis_->vector(j);
      double weight = 0;
      for (int u = 0; u < N; ++u)
        if (comp[o.face_of_unknown(u)] == c) weight += o.mass()[u] * std::norm(v[u]);
      if (weight < 1e-3) continue;  // the vector lives on other components (M-unit: total weight 1)
      const double s = scale * std::sqrt(comp_area[c] / weight);
      for (int u = 0; u < N; ++u) {
        const int f = o.face_of_unknown(u);
        if (comp[f] == c) field[f] = s * v[u];
      }
      filled = true;
    }
  }
}

const std::vector<bool>& ReducedSolver::covered_components() {
  if (!covered_.empty()) return covered_;
  const FieldOperators& o = *ops_;
  const std::vector<int>& comp = o.mesh().face_component();
  const int ncomp = std::max(1, o.mesh().report().num_components);
  covered_.assign(ncomp, false);
  std::vector<double> weight(ncomp);
  for (int j = 0; j < size(); ++j) {
    const ComplexVector v = basis_->vector(j);
    std::fill(weight.begin(), weight.end(), 0.0);
    for (int u = 0; u < o.num_unknowns(); ++u) weight[comp[o.face_of_unknown(u)]] += o.mass()[u] * std::norm(v[u]);
    for (int c = 0; c < ncomp; ++c)
      if (weight[c] >= 1e-3) covered_[c] = true;  // M-unit vectors: weight 1 in total
  }
  return covered_;
}

ComplexVector low_pass(const FieldOperators& ops, const SpectralBasis& basis, const ComplexVector& field) {
  if (basis.num_unknowns() != ops.num_unknowns() || basis.mesh_hash() != ops.mesh().content_hash() ||
      basis.n() != ops.n())
    throw ParameterError("spectral basis was computed for different operators (mesh, n or weights)");
  if (field.size() != ops.mesh().num_faces())
    throw InputError("field must have one value per face (" + std::to_string(ops.mesh().num_faces()) + "), got " +
                     std::to_string(field.size()));
  if (!field.allFinite()) throw InputError("field contains NaN or infinite values");
  return ops.to_faces(basis.reconstruct(basis.project(ops.to_unknowns(field))));
}

}  // namespace nfield
