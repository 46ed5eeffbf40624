// ExactSolver: the constraint rows (step 3 of spline_solver.hpp), the responses to unit loads (cached columns or
// the Gram matrix of a direct solve), and the checks of step 6.
#include <algorithm>
#include <cmath>
#include <sstream>

#include "nfield/errors.hpp"
#include "nfield/singularities.hpp"
#include "nfield/spline_solver.hpp"

namespace nfield {

void ExactSolver::ensure_columns(const std::vector<int>& faces) {
  if (faces.empty()) return;
  // Unit loads at unknown faces (G_f = V^-1 e_f) and the coupling columns of anchors (V^-1 V_UF e_a).
  std::vector<SparseColumn> loads(faces.size());
  for (size_t j = 0; j < faces.size(); ++j) {
    const int f = faces[j], u = system_.unknown_of_face[f];
    if (u >= 0) {
      loads[j].emplace_back(u, Complex(1.0, 0.0));
    } else {
      for (ComplexSparse::InnerIterator it(system_.coupling, system_.fixed_of_face.at(f)); it; ++it)
        loads[j].emplace_back(static_cast<int>(it.row()), it.value());
    }
  }
  Eigen::MatrixXcd G = factor_->backward(factor_->forward(loads).h);
  // Accuracy probe on one column; where V is ill-conditioned, refine the whole block (hermitian_factor.hpp).
  ComplexVector probe = ComplexVector::Zero(num_unknowns());
  for (const auto& [u, v] : loads[0]) probe[u] += v;
  if (factor_->condition_estimate() > kRefineColumnsCondition ||
      factor_->relative_residual(probe, G.col(0)) > HermitianFactor::kRefineThreshold) {
    Eigen::MatrixXcd B = Eigen::MatrixXcd::Zero(num_unknowns(), static_cast<Eigen::Index>(faces.size()));
    for (size_t j = 0; j < faces.size(); ++j)
      for (const auto& [u, v] : loads[j]) B(u, static_cast<Eigen::Index>(j)) += v;
    for (int step = 0; step < HermitianFactor::kMaxRefinements; ++step)
      if (factor_->refine_block(B, G) <= HermitianFactor::kConverged) break;
  }
  for (size_t j = 0; j < faces.size(); ++j) columns_[faces[j]] = G.col(static_cast<Eigen::Index>(j));
}

void ExactSolver::compute_gram(const std::vector<int>& faces, const ComplexVector& b) {
  gram_index_.clear();
  std::vector<SparseColumn> loads(faces.size() + 1);
  for (size_t j = 0; j < faces.size(); ++j) {
    gram_index_[faces[j]] = static_cast<int>(j);
    loads[j].emplace_back(system_.unknown_of_face.at(faces[j]), Complex(1.0, 0.0));
  }
  SparseColumn& rhs = loads.back();  // b is sparse without alignment (the safeguard, the anchors' stencils)
  for (int u = 0; u < num_unknowns(); ++u)
    if (b[u] != 0.0) rhs.emplace_back(u, b[u]);
  const Eigen::MatrixXcd gram = factor_->forward(loads, false).gram;
  const Eigen::Index k = static_cast<Eigen::Index>(faces.size());
  gram_ = gram.topLeftCorner(k, k);
  gram_rhs_ = gram.col(k).head(k);  // h_f^H h_b = e_f^T V^-1 b
}

Complex ExactSolver::entry(int face, int load) const {
  if (direct_) return gram_(gram_index_.at(face), gram_index_.at(load));
  return columns_.at(load)[system_.unknown_of_face[face]];
}

Complex ExactSolver::value_at(const Response& r, int face) const {
  const int u = system_.unknown_of_face[face];
  if (u < 0) return fixed_value(face);
  Complex v = r.base ? (*r.base)[u] : gram_rhs_[gram_index_.at(face)];
  for (const auto& [g, a] : r.coefficient)
    if (a != 0.0) v += a * entry(face, g);
  return v;
}

ComplexVector ExactSolver::assemble(const Response& r) const {
  if (!direct_) {
    ComplexVector w = *r.base;
    for (const auto& [f, a] : r.coefficient)
      if (a != 0.0) w += a * columns_.at(f);
    return w;
  }
  ComplexVector load = r.rhs ? *r.rhs : ComplexVector(ComplexVector::Zero(num_unknowns()));
  bool any = r.rhs != nullptr;
  for (const auto& [f, a] : r.coefficient)
    if (a != 0.0) load[system_.unknown_of_face.at(f)] += a, any = true;
  if (!r.base) return factor_->solve(load);
  return any ? ComplexVector(*r.base + factor_->solve(load)) : *r.base;
}

std::vector<ConstraintRow> ExactSolver::free_rows(const std::vector<ConstraintRow>& rows) const {
  std::vector<ConstraintRow> out;
  out.reserve(rows.size());
  for (const auto& row : rows) {
    ConstraintRow free;
    free.rhs = row.rhs;
    double size = std::abs(row.rhs);
    for (const auto& [f, c] : row.terms) {
      if (system_.unknown_of_face[f] >= 0) {
        free.terms.emplace_back(f, c);
      } else {  // a known value: moves to the right-hand side
        const Complex z = fixed_value(f);
        free.rhs -= (std::conj(c) * z).real();
        size += std::abs(c) * std::abs(z);
      }
    }
    if (!free.terms.empty()) {
      out.push_back(std::move(free));
    } else if (!(std::abs(free.rhs) <= 1e-9 * size)) {
      // A row on given values only (a singularity whose ring is all vector constraints) that they violate.
      std::set<std::string> names;
      for (const auto& [vertex, rs] : constraints_.singularity_rows)
        for (const auto& r : rs)
          if (r.terms.front().first == row.terms.front().first) names.insert("singularity at vertex " + std::to_string(vertex));
      for (const auto& t : row.terms)
        if (constraints_.faces.count(t.first)) names.insert("face " + std::to_string(t.first));
      throw_contradictory(names, "");
    }
  }
  return out;
}

ExactSolver::Response ExactSolver::schur_solve(const std::vector<ConstraintRow>& rows, const Response& y,
                                               Eigen::MatrixXd& K) const {
  const int R = static_cast<int>(rows.size());
  K.resize(R, R);
  if (R == 0) return y;
  // y at every constrained face, once.
  std::unordered_map<int, Complex> y_at;
  for (const auto& row : rows)
    for (const auto& t : row.terms)
      if (!y_at.count(t.first)) y_at[t.first] = value_at(y, t.first);
  Eigen::VectorXd rhs(R);
  for (int r = 0; r < R; ++r) {
    double v = -rows[r].rhs;
    for (const auto& [f, c] : rows[r].terms) v += (std::conj(c) * y_at[f]).real();
    rhs[r] = v;
    for (int s = 0; s <= r; ++s) {
      double k = 0;
      for (const auto& [fr, cr] : rows[r].terms)
        for (const auto& [fs, cs] : rows[s].terms) k += (std::conj(cr) * cs * entry(fr, fs)).real();
      K(r, s) = K(s, r) = k;
    }
  }
  // K = D V^-1 D^T is positive semi-definite; it is singular exactly when rows are linearly dependent.
  const ConstraintSystemSolution sol = solve_constraint_system(K, rhs);
  if (!sol.conflicting_rows.empty()) {
    // Name the constraints that carry the inconsistent combination.
    std::set<std::string> names;
    for (int r : sol.conflicting_rows) {
      const int f = rows[r].terms.front().first;
      std::string name = "face " + std::to_string(f);
      for (const auto& [vertex, rs] : constraints_.singularity_rows)
        for (const auto& row : rs)
          if (row.terms.front().first == f) name = "singularity at vertex " + std::to_string(vertex);
      names.insert(name);
    }
    throw_contradictory(names, "");
  }
  // w = y - sum_r gamma_r V^-1 D_r^T, kept as coefficients of the unit-load responses.
  Response w = y;
  for (int r = 0; r < R; ++r)
    for (const auto& [f, c] : rows[r].terms) w.coefficient[f] -= sol.gamma[r] * c;
  return w;
}

ComplexVector ExactSolver::response_to(const std::unordered_map<int, Complex>& loads) const {
  if (direct_) {
    ComplexVector load = ComplexVector::Zero(num_unknowns());
    for (const auto& [f, a] : loads) load[system_.unknown_of_face.at(f)] += a;
    return factor_->solve(load);
  }
  ComplexVector w = ComplexVector::Zero(num_unknowns());
  for (const auto& [f, a] : loads)
    if (a != 0.0) w += a * columns_.at(f);
  return w;
}

void ExactSolver::refine_rows(const std::vector<ConstraintRow>& rows, const Eigen::MatrixXd& K,
                              ComplexVector& field) const {
  const int R = static_cast<int>(rows.size());
  for (int step = 0; step < 3 && R > 0; ++step) {
    Eigen::VectorXd violation(R);
    double worst = 0;
    for (int r = 0; r < R; ++r) {
      double v = -rows[r].rhs, size = std::abs(rows[r].rhs);
      for (const auto& [f, c] : rows[r].terms) {
        const Complex z = field[system_.unknown_of_face[f]];
        v += (std::conj(c) * z).real();
        size += std::abs(c) * std::abs(z);
      }
      violation[r] = v;
      worst = std::max(worst, std::abs(v) / std::max(size, 1e-300));
    }
    if (!(worst > 1e-10)) return;
    const Eigen::VectorXd dgamma = solve_constraint_system(K, violation).gamma;
    std::unordered_map<int, Complex> loads;
    for (int r = 0; r < R; ++r)
      for (const auto& [f, c] : rows[r].terms) loads[f] -= dgamma[r] * c;
    field += response_to(loads);
  }
}

void ExactSolver::check_constrained_faces_carry_data(const Response& y, const Response& w) const {
  double data = 0, value = 0;
  std::set<std::string> names;
  for (const auto& [f, c] : constraints_.faces) {
    if (c.kind != ConstraintSet::Kind::Direction) return;  // a vector constraint sets a scale of its own
    data = std::max(data, std::abs(value_at(y, f)));
    value = std::max(value, std::abs(value_at(w, f)));
    names.insert("face " + std::to_string(f));
  }
  if (!(data > 0) || value > 1e-9 * data) return;
  for (const auto& [vertex, rows] : constraints_.singularity_rows)
    for (const auto& row : rows)
      for (const auto& t : row.terms)
        if (constraints_.faces.count(t.first)) names.insert("singularity at vertex " + std::to_string(vertex));
  throw_contradictory(names, "; together they force the field to vanish on the constrained faces, which then "
                             "cannot point along their directions");
}

void ExactSolver::check_rows_hold(const ComplexVector& field) const {
  // Face constraints are snapped onto their value after the solve; a singularity's ring rows are not, so they
  // are checked here. A contradictory set whose Schur complement is too ill-conditioned for the rank test in
  // schur_solve (high order, small lambda: K's null space drowns in rounding) comes back as a field that
  // violates the rows by O(1). Consistent rows hold to ~1e-12 relative (the solves are refined in extended
  // precision): a row off by more than 1e-3 of its terms' size is reported.
  // The floor 1e-9 x max|w| accepts a ring on which the spline vanishes (homogeneous rows, no data nearby):
  // there every value is rounding noise of the field and the rows hold absolutely.
  // Only rings that hold a face constraint can be contradictory: a singularity's own rows are homogeneous
  // (z = 0 satisfies them), so without a face constraint on the ring a violation is inaccuracy, not conflict.
  if (constraints_.singularity_rows.empty()) return;
  const double floor = 1e-9 * (field.size() ? field.cwiseAbs().maxCoeff() : 0.0);
  std::set<std::string> names;
  for (const auto& [vertex, rows] : constraints_.singularity_rows) {
    bool constrained_ring = false;
    for (const auto& row : rows)
      for (const auto& t : row.terms) constrained_ring |= constraints_.faces.count(t.first) > 0;
    if (!constrained_ring) continue;
    for (const auto& row : rows) {
      double value = -row.rhs, size = std::abs(row.rhs);
      for (const auto& [f, c] : row.terms) {
        const Complex z = field[f];
        value += (std::conj(c) * z).real();
        size += std::abs(c) * std::abs(z);
      }
      if (!(std::abs(value) <= 1e-3 * size + floor)) {
        names.insert("singularity at vertex " + std::to_string(vertex));
        for (const auto& t : row.terms)
          if (constraints_.faces.count(t.first)) names.insert("face " + std::to_string(t.first));
      }
    }
  }
  if (!names.empty())
    throw_contradictory(names, "; the solution cannot meet the singularity's rows (at energy order 3-4 on a flat "
                               "region this can also be ill-conditioning: try a lower order)");
}

void ExactSolver::throw_contradictory(const std::set<std::string>& names, const std::string& note) const {
  std::ostringstream msg;
  msg << "contradictory constraints: they cannot all hold at once (involved: ";
  int shown = 0;
  for (const auto& n : names) {
    if (shown++) msg << ", ";
    if (shown > 8) {
      msg << "...";
      break;
    }
    msg << n;
  }
  msg << ")" << note;
  throw ConstraintError(msg.str());
}

void ExactSolver::check_singularity_indices(const ComplexVector& field) const {
  // Every pinned singularity must come out with its index. The ring rows are homogeneous: where the rest of
  // the design (alignment, constraints) drives the field on the ring nearly to zero, or the rows are
  // ill-conditioned (an index whose per-step twist is close to pi, energy order 3-4 on a nearly flat region),
  // rounding decides the ring's index and the solve can miss it; that is reported instead of returning a
  // field without the requested singularity. A ring on which the field vanishes to rounding level (below
  // 1e-9 of the field: no data reaches it at all) has no index and is accepted.
  if (constraints_.singularities.empty()) return;
  const double floor = 1e-9 * field.cwiseAbs().maxCoeff();
  const TriangleMesh& mesh = ops_->mesh();
  for (const auto& [vertex, numerator] : constraints_.singularities) {
    double ring_max = 0;
    for (int f : mesh.vertex_ring_faces(vertex)) ring_max = std::max(ring_max, std::abs(field[f]));
    if (!(ring_max > floor)) continue;
    int got = 0;
    const bool defined = ring_index_numerator(*ops_, field, vertex, got);
    if (defined && got == numerator) continue;
    std::ostringstream msg;
    msg.precision(2);
    msg << "singularity at vertex " << vertex << ": the solve could not impose index " << numerator << "/"
        << ops_->n() << " (the field there has ";
    if (defined)
      msg << "index " << got << "/" << ops_->n();
    else
      msg << "a zero on the ring";
    msg << " and on the ring only " << ring_max / field.cwiseAbs().maxCoeff()
        << " of its largest magnitude): the rest of the design overrides the singularity, or the system is "
           "ill-conditioned (energy order "
        << order_ << "); add a constraint near the vertex, use a lower order, or an index closer to 0";
    throw ConstraintError(msg.str());
  }
}

}  // namespace nfield
