#include "nfield/spline_solver.hpp"

#include "nfield/memory_guard.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "nfield/errors.hpp"
#include "nfield/singularities.hpp"

namespace nfield {

double strength_to_lambda(const FieldOperators& ops, int order, double strength) {
  if (!std::isfinite(strength) || strength < kMinStrength || strength > kMaxStrength) {
    // %g, not std::to_string: 1e-7 must not read "0.000000".
    std::ostringstream msg;
    msg << "alignment strength must be a finite number between " << kMinStrength << " and " << kMaxStrength
        << ", got " << strength;
    throw ParameterError(msg.str());
  }
  return -strength * ops.eigenvalue_unit(order);
}

ExactSolver::ExactSolver(std::shared_ptr<const FieldOperators> ops, int order, double strength,
                         const ComplexVector& alignment, SplineKind kind, double lambda_override,
                         const ProgressCallback& progress, const std::vector<std::pair<int, Complex>>& frozen)
    : ConstraintEditor(std::move(ops)), frozen_(frozen), order_(order), kind_(kind) {
  const FieldOperators& o = *ops_;
  const TriangleMesh& mesh = o.mesh();
  if (order < 1 || order > 4) throw ParameterError("energy order must be 1 to 4, got " + std::to_string(order));
  for (size_t i = 0; i < frozen_.size(); ++i) {
    const int f = frozen_[i].first;
    check_face(f);
    if (!std::isfinite(std::abs(frozen_[i].second)))
      throw InputError("frozen value on face " + std::to_string(f) + " is not finite");
    if (!frozen_index_.emplace(f, i).second) throw InputError("face " + std::to_string(f) + " is frozen twice");
  }
  unknown_of_face_.assign(mesh.num_faces(), -1);
  for (int u = 0; u < o.num_unknowns(); ++u) {
    const int f = o.face_of_unknown(u);
    if (frozen_index_.count(f)) continue;
    unknown_of_face_[f] = static_cast<int>(face_of_unknown_.size());
    face_of_unknown_.push_back(f);
  }
  const int N = num_unknowns();
  if (N == 0) throw ConstraintError("every face is frozen: nothing is left to solve for");
  mass_.resize(N);
  for (int u = 0; u < N; ++u) mass_[u] = mesh.face_area(face_of_unknown_[u]);

  const bool has_alignment = alignment.size() > 0;
  alignment_ = ComplexVector::Zero(N);
  if (has_alignment) {
    if (alignment.size() != mesh.num_faces())
      throw InputError("alignment field must have one value per face (" + std::to_string(mesh.num_faces()) +
                       "), got " + std::to_string(alignment.size()));
    if (!alignment.allFinite()) throw InputError("alignment field contains NaN or infinite values");
    for (int u = 0; u < N; ++u) alignment_[u] = alignment[face_of_unknown_[u]];
  }
  if (std::isfinite(lambda_override)) {
    lambda_ = lambda_override;
  } else if (kind == SplineKind::Vector && !has_alignment) {
    lambda_ = -kVectorRegularisation * o.eigenvalue_unit(order);
  } else {
    lambda_ = strength_to_lambda(o, order, strength);
  }
  spike_ = safeguard_spike(alignment_);  // s of the +d safeguard (constraint_system.hpp)

  component_has_alignment_.assign(std::max(1, mesh.report().num_components), false);
  for (int u = 0; u < N; ++u)
    if (std::abs(alignment_[u]) > 0) component_has_alignment_[mesh.face_component()[face_of_unknown_[u]]] = true;
  for (const auto& [f, z] : frozen_)
    if (std::abs(z) > 0) component_has_alignment_[mesh.face_component()[f]] = true;

  if (progress && !progress(0.0)) throw Cancelled("factorization cancelled");
  // V over all active faces, then the blocks V_UU (factored) and E_UF (moves frozen values to the rhs).
  ComplexSparse E = o.energy_matrix(order);
  std::vector<Eigen::Triplet<Complex>> uu;
  uu.reserve(E.nonZeros());
  ComplexVector coupling = ComplexVector::Zero(N);  // E_UF z_F
  for (int col = 0; col < E.outerSize(); ++col) {
    const int fc = o.face_of_unknown(col), uc = unknown_of_face_[fc];
    const auto frozen_col = frozen_index_.find(fc);
    for (ComplexSparse::InnerIterator it(E, col); it; ++it) {
      const int ur = unknown_of_face_[o.face_of_unknown(static_cast<int>(it.row()))];
      if (ur < 0) continue;
      if (uc >= 0)
        uu.emplace_back(ur, uc, it.value());
      else if (frozen_col != frozen_index_.end())
        coupling[ur] += it.value() * frozen_[frozen_col->second].second;
    }
  }
  for (int u = 0; u < N; ++u) uu.emplace_back(u, u, -lambda_ * mass_[u]);
  system_.resize(N, N);
  system_.setFromTriplets(uu.begin(), uu.end());
  system_.makeCompressed();
  factor_.analyzePattern(system_);
  if (factor_.info() != Eigen::Success) throw SolverError("symbolic analysis of B - lambda M failed");
  {
    // Memory guard: the numeric factor's size is known from the symbolic analysis (nnz of L).
    const std::size_t bytes = cholesky_factor_bytes(factor_.cholmod().lnz, static_cast<std::size_t>(N)) +
                              static_cast<std::size_t>(system_.nonZeros()) * (sizeof(Complex) + sizeof(int));
    require_memory(bytes, "the factorization of the order-" + std::to_string(order) + " system (" +
                              std::to_string(N) + " faces)",
                   order > 1 ? "a lower energy order needs less (its matrix is sparser), as does a decimated mesh"
                             : "a decimated mesh needs less");
  }
  factor_.factorize(system_);
  if (factor_.info() != Eigen::Success)
    throw SolverError("factorization of B - lambda M failed: the matrix is not positive definite (lambda=" +
                      std::to_string(lambda_) + ")");
  const double rhs_scale = kind_ == SplineKind::Direction ? 1.0 : -lambda_;
  const ComplexVector b = rhs_scale * mass_.cast<Complex>().cwiseProduct(alignment_) - coupling;
  base_response_ = apply_inverse(b);
  if (progress && !progress(1.0)) throw Cancelled("factorization cancelled");
}

ComplexVector ExactSolver::to_faces(const ComplexVector& per_unknown) const {
  ComplexVector out = ComplexVector::Zero(ops_->mesh().num_faces());
  for (int u = 0; u < num_unknowns(); ++u) out[face_of_unknown_[u]] = per_unknown[u];
  for (const auto& [f, z] : frozen_) out[f] = z;  // bit-identical copy
  return out;
}

ComplexVector ExactSolver::apply_inverse(const ComplexVector& b) const {
  ComplexVector x = factor_.solve(b);
  // One step of iterative refinement, only where V is ill-conditioned enough for it to matter.
  const ComplexVector r = b - system_ * x;
  if (r.norm() > 1e-10 * b.norm()) x += factor_.solve(r);
  if (!x.allFinite()) throw SolverError("back-substitution produced non-finite values");
  return x;
}

void ExactSolver::ensure_columns(const std::vector<int>& faces) {
  std::vector<int> missing;
  for (int f : faces)
    if (!columns_.count(f)) missing.push_back(f);
  if (missing.empty()) return;
  const int N = num_unknowns();
  Eigen::MatrixXcd E = Eigen::MatrixXcd::Zero(N, missing.size());
  for (size_t j = 0; j < missing.size(); ++j) E(unknown_of_face_[missing[j]], j) = 1.0;
  Eigen::MatrixXcd G = factor_.solve(E);
  const Eigen::MatrixXcd residual = E - system_ * G;  // columns of E have unit norm
  if (residual.cwiseAbs().maxCoeff() > 1e-10) G += factor_.solve(residual);  // iterative refinement
  if (!G.allFinite()) throw SolverError("back-substitution produced non-finite values");
  for (size_t j = 0; j < missing.size(); ++j) columns_[missing[j]] = G.col(j);
}

Complex ExactSolver::Response::at(const ExactSolver& s, int face) const {
  const int u = s.unknown_of_face_[face];
  Complex v = (*base)[u];
  for (const auto& [f, a] : coefficient) v += a * s.columns_.at(f)[u];
  return v;
}

ComplexVector ExactSolver::Response::assemble(const ExactSolver& s) const {
  ComplexVector w = *base;
  for (const auto& [f, a] : coefficient)
    if (a != 0.0) w += a * s.columns_.at(f);
  return w;
}

ExactSolver::Response ExactSolver::schur_solve(const std::vector<ConstraintRow>& rows, const Response& y) const {
  const int R = static_cast<int>(rows.size());
  if (R == 0) return y;
  auto unknown = [&](int f) { return unknown_of_face_[f]; };
  // y at every constrained face, once.
  std::unordered_map<int, Complex> y_at;
  for (const auto& row : rows)
    for (const auto& t : row.terms)
      if (!y_at.count(t.first)) y_at[t.first] = y.at(*this, t.first);
  Eigen::MatrixXd K(R, R);
  Eigen::VectorXd rhs(R);
  for (int r = 0; r < R; ++r) {
    double v = -rows[r].rhs;
    for (const auto& [f, c] : rows[r].terms) v += (std::conj(c) * y_at[f]).real();
    rhs[r] = v;
    for (int s = 0; s <= r; ++s) {
      double k = 0;
      for (const auto& [fr, cr] : rows[r].terms)
        for (const auto& [fs, cs] : rows[s].terms) k += (std::conj(cr) * cs * columns_.at(fs)[unknown(fr)]).real();
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
  const Eigen::VectorXd& gamma = sol.gamma;
  // w = y - sum_r gamma_r V^-1 D_r^T, kept as coefficients of the cached columns.
  Response w = y;
  for (int r = 0; r < R; ++r)
    for (const auto& [f, c] : rows[r].terms) w.coefficient[f] -= gamma[r] * c;
  return w;
}

void ExactSolver::check_rows_hold(const ComplexVector& w) const {
  // Face constraints are snapped onto their value after the solve; a singularity's ring rows are not, so they
  // are checked here. A contradictory set whose Schur complement is too ill-conditioned for the rank test in
  // schur_solve (high order, small lambda: K's null space drowns in rounding) comes back as a field that
  // violates the rows by O(1). Consistent rows hold to ~1e-12 relative, ~1e-4 in the worst documented case
  // (order 3-4 on flat regions, see the header): a row off by more than 1e-3 of its terms' size is reported.
  // The floor 1e-9 x max|w| accepts a ring on which the spline vanishes (homogeneous rows, no data nearby):
  // there every value is rounding noise of the field and the rows hold absolutely.
  // Only rings that hold a face constraint can be contradictory: a singularity's own rows are homogeneous
  // (z = 0 satisfies them), so without a face constraint on the ring a violation is inaccuracy, not conflict.
  const double floor = 1e-9 * (w.size() ? w.cwiseAbs().maxCoeff() : 0.0);
  std::set<std::string> names;
  for (const auto& [vertex, rows] : constraints_.singularity_rows) {
    bool constrained_ring = false;
    for (const auto& row : rows)
      for (const auto& t : row.terms) constrained_ring |= constraints_.faces.count(t.first) > 0;
    if (!constrained_ring) continue;
    for (const auto& row : rows) {
      double value = -row.rhs, size = std::abs(row.rhs);
      for (const auto& [f, c] : row.terms) {
        const Complex z = w[unknown_of_face_[f]];
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

ComplexVector ExactSolver::solve() {
  const FieldOperators& o = *ops_;
  const TriangleMesh& mesh = o.mesh();
  const int N = num_unknowns();
  sign_fixed_.clear();

  std::vector<int> faces;
  for (const auto& [f, c] : constraints_.faces) faces.push_back(f);
  for (const auto& [v, rs] : constraints_.singularity_rows)
    for (const auto& r : rs)
      for (const auto& t : r.terms) faces.push_back(t.first);
  std::sort(faces.begin(), faces.end());
  faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
  ensure_columns(faces);

  // Right-hand side response y = V^-1 b with the +d safeguard u'_f = s d_f at direction constraints.
  const double rhs_scale = kind_ == SplineKind::Direction ? 1.0 : -lambda_;
  Response y{&base_response_, {}};
  const int ncomp = std::max(1, mesh.report().num_components);
  std::vector<bool> has_data = component_has_alignment_, has_rows(ncomp, false);
  for (const auto& [f, c] : constraints_.faces) {
    const int comp = mesh.face_component()[f];
    has_rows[comp] = true;
    if (c.kind == ConstraintSet::Kind::Direction) {
      const int u = unknown_of_face_.at(f);
      // s_f = spike * mean_area / A_f: every constrained face adds the same weight s * mean_area * d to b.
      const double mean_area = mesh.total_area() / o.num_unknowns();
      const Complex delta = safeguard_delta(spike_, mean_area, mass_[u], c.value, alignment_[u]);
      y.coefficient[f] += (rhs_scale * mass_[u]) * delta;
      has_data[comp] = true;
    } else if (std::abs(c.value) > 0) {
      has_data[comp] = true;
    }
  }
  for (const auto& [v, rs] : constraints_.singularity_rows) has_rows[mesh.face_component()[rs.front().terms.front().first]] = true;

  // Components whose only constraints are homogeneous: seed with the smoothest field (inverse iteration).
  std::vector<bool> homogeneous(ncomp, false), empty(ncomp, false);
  bool any_homogeneous = false, any_empty = false;
  for (int c = 0; c < ncomp; ++c) {
    homogeneous[c] = has_rows[c] && !has_data[c];
    empty[c] = !has_rows[c] && !has_data[c];
    any_homogeneous |= homogeneous[c];
    any_empty |= empty[c];
  }
  if ((any_homogeneous || any_empty) && smoothest_.size() == 0) {
    const ComplexVector full = smoothest_field(o);
    smoothest_.resize(N);
    for (int u = 0; u < N; ++u) smoothest_[u] = full[face_of_unknown_[u]];
  }
  auto restrict_to = [&](const ComplexVector& z, const std::vector<bool>& mask) {
    ComplexVector out = ComplexVector::Zero(N);
    for (int u = 0; u < N; ++u)
      if (mask[mesh.face_component()[face_of_unknown_[u]]]) out[u] = z[u];
    return out;
  };

  auto solve_with_pins = [&](const Response& response) {
    OrientationPins pins;
    for (;;) {
      const Response w = schur_solve(constraints_.rows(pins.faces, pins.magnitude), response);
      if (!pins.update(constraints_, [&](int f) { return w.at(*this, f); })) continue;
      sign_fixed_ = pins.faces;
      ComplexVector field = w.assemble(*this);
      check_rows_hold(field);
      // Snap constrained faces onto their constraint: removes the rounding of the column combination
      // (relative 1e-12 of the largest term), so constraints hold to the last bit.
      for (const auto& [f, c] : constraints_.faces) {
        Complex& z = field[unknown_of_face_[f]];
        z = pins.snapped(f, c, z);
      }
      return field;
    }
  };

  ComplexVector w;
  if (!any_homogeneous) {
    w = solve_with_pins(y);
  } else {
    // Inverse iteration on the homogeneous components: their "alignment" is the current iterate.
    ComplexVector seed = restrict_to(smoothest_, homogeneous);
    for (int it = 0; it < 30; ++it) {
      const ComplexVector b = mass_.cast<Complex>().cwiseProduct(seed);
      const ComplexVector base = base_response_ + apply_inverse(b);
      Response shifted{&base, y.coefficient};
      w = solve_with_pins(shifted);
      ComplexVector next = restrict_to(w, homogeneous);
      const double norm = std::sqrt((next.cwiseAbs2().cwiseProduct(mass_)).sum());
      if (!(norm > 0)) throw SolverError("singularity constraints admit only the zero field here");
      next *= std::sqrt(restrict_to(ComplexVector(mass_.cast<Complex>()), homogeneous).real().sum()) / norm;
      const double change = (next - seed).norm() / std::max(seed.norm(), 1e-300);
      seed = next;
      if (change < 1e-9) break;
    }
  }
  if (any_empty) {
    // Scale the fill like the rest of the solution so magnitudes stay comparable.
    double rest = 0;
    int count = 0;
    for (int u = 0; u < N; ++u)
      if (!empty[mesh.face_component()[face_of_unknown_[u]]]) rest += std::norm(w[u]), ++count;
    const double scale = count && rest > 0 ? std::sqrt(rest / count) : 1.0;
    w += scale * restrict_to(smoothest_, empty);
  }
  ComplexVector out = to_faces(w);
  check_singularity_indices(out);
  return out;
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
