// ExactSolver: construction, factorization and the solve pipeline (steps 1-6 of spline_solver.hpp). The
// constraint (Schur) system, the responses and the checks are in spline_schur.cpp.
#include "nfield/spline_solver.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include "nfield/blas.hpp"
#include "nfield/errors.hpp"

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
                         ComplexVector alignment, SplineKind kind, double lambda_override,
                         const ProgressCallback& progress, FrozenFaces frozen, const std::vector<int>& anchors,
                         bool cache_columns, Eigen::VectorXd alignment_weight)
    : ConstraintEditor(std::move(ops)), order_(order), kind_(kind), cache_columns_(cache_columns),
      frozen_(std::move(frozen)) {
  const FieldOperators& o = *ops_;
  const TriangleMesh& mesh = o.mesh();
  if (order < 1 || order > 4) throw ParameterError("energy order must be 1 to 4, got " + std::to_string(order));
  anchors_ = anchors;
  std::sort(anchors_.begin(), anchors_.end());
  for (size_t i = 0; i < anchors_.size(); ++i) {
    check_face(anchors_[i]);  // in range, active, not frozen
    if (i > 0 && anchors_[i] == anchors_[i - 1])
      throw ConstraintError("face " + std::to_string(anchors_[i]) + " is anchored twice");
  }
  const bool has_alignment = alignment.size() > 0;
  if (has_alignment) {
    if (alignment.size() != mesh.num_faces())
      throw InputError("alignment field must have one value per face (" + std::to_string(mesh.num_faces()) +
                       "), got " + std::to_string(alignment.size()));
    if (!alignment.allFinite()) throw InputError("alignment field contains NaN or infinite values");
    alignment_per_face_ = std::move(alignment);
  }
  if (alignment_weight.size() > 0) {
    if (alignment_weight.size() != mesh.num_faces())
      throw InputError("alignment weights must have one value per face (" + std::to_string(mesh.num_faces()) +
                       "), got " + std::to_string(alignment_weight.size()));
    for (int f = 0; f < mesh.num_faces(); ++f)
      if (!(alignment_weight[f] >= 0) || !std::isfinite(alignment_weight[f]))
        throw InputError("alignment weight on face " + std::to_string(f) + " must be a finite number >= 0");
    weight_per_face_ = std::move(alignment_weight);
  }
  if (std::isfinite(lambda_override))
    lambda_ = lambda_override;
  else if (kind == SplineKind::Vector && !has_alignment)
    lambda_ = 0.0;  // eq. 8 without its alignment term: no regularisation (see spline_system.hpp)
  else
    lambda_ = strength_to_lambda(o, order, strength);
  factor(progress);
}

void ExactSolver::factor(const ProgressCallback& progress) {
  const FieldOperators& o = *ops_;
  if (progress && !progress(0.0)) throw Cancelled("factorization cancelled");
  SplineSystem system = assemble_spline_system(o, order_, lambda_, frozen_, anchors_, weight_per_face_);
  const int N = system.num_unknowns();
  if (N == 0 && anchors_.empty()) throw ConstraintError("every face is frozen: nothing is left to solve for");
  std::unique_ptr<HermitianFactor> factor;
  if (N > 0) {
    try {
      factor = std::make_unique<HermitianFactor>(
          system.matrix, "the factorization of the order-" + std::to_string(order_) + " system (" + std::to_string(N) +
                             " faces)",
          order_ > 1 ? "a lower energy order needs less (its matrix is sparser), as does a decimated mesh"
                     : "a decimated mesh needs less");
    } catch (const SolverError& e) {
      throw SolverError(std::string(e.what()) + " (lambda=" + std::to_string(lambda_) + ")");
    }
  }
  system_ = std::move(system);
  factor_ = std::move(factor);
  ++num_factorizations_;
  columns_.clear();
  deferred_.clear();
  gram_index_.clear();
  smoothest_.resize(0);
  update_alignment();
  if (progress && !progress(1.0)) throw Cancelled("factorization cancelled");
}

void ExactSolver::update_alignment() {
  const FieldOperators& o = *ops_;
  const TriangleMesh& mesh = o.mesh();
  const int N = num_unknowns();
  alignment_ = ComplexVector::Zero(N);
  if (alignment_per_face_.size() > 0)
    for (int u = 0; u < N; ++u) alignment_[u] = alignment_per_face_[system_.face_of_unknown[u]];
  // s_0 of the safeguard: RMS alignment over the faces that are not frozen (anchors included: the value must not
  // depend on which vector constraints a solver eliminates).
  // (In the order of the unknowns, without the frozen faces: zeros do not count, so this is the same RMS as over
  // a whole-mesh vector zero on frozen faces, without one.)
  std::vector<Complex> not_frozen;
  if (alignment_per_face_.size() > 0)
    for (int u = 0; u < o.num_unknowns(); ++u)
      if (!frozen_.held(o.face_of_unknown(u))) not_frozen.push_back(alignment_per_face_[o.face_of_unknown(u)]);
  spike_ = safeguard_spike(Eigen::Map<const ComplexVector>(not_frozen.data(), static_cast<Eigen::Index>(not_frozen.size())));
  component_has_alignment_.assign(std::max(1, mesh.report().num_components), false);
  for (int u = 0; u < N; ++u)
    if (std::abs(alignment_[u]) > 0) component_has_alignment_[mesh.face_component()[system_.face_of_unknown[u]]] = true;
  frozen_.for_each([&](int f, Complex z) {
    if (z != 0.0) component_has_alignment_[mesh.face_component()[f]] = true;
  });

  // b0 = rhs_scale M u' - V_UF z_frozen; its response now for live solvers (a one-shot solver folds the anchors'
  // values and the safeguard into one right-hand side and solves once, in solve()).
  const double rhs_scale = kind_ == SplineKind::Direction ? 1.0 : -lambda_;
  b0_ = rhs_scale * system_.mass.cast<Complex>().cwiseProduct(alignment_);
  if (!frozen_.empty()) {  // the frozen faces within the stencil of the unknowns (the anchors' entries stay 0)
    ComplexVector z = ComplexVector::Zero(static_cast<Eigen::Index>(system_.fixed_faces.size()));
    for (size_t i = 0; i < system_.fixed_faces.size(); ++i)
      if (frozen_.held(system_.fixed_faces[i])) z[static_cast<Eigen::Index>(i)] = frozen_.value(system_.fixed_faces[i]);
    b0_ -= system_.coupling * z;
  }
  // (b0 = 0 without alignment and frozen values: its response is zero, no solve.)
  if (cache_columns_ && factor_) {
    const ComplexVector rhs = project(b0_);
    base_response_ = rhs.isZero(0.0) ? ComplexVector(ComplexVector::Zero(N)) : factor_->solve(rhs);
  } else {
    base_response_ = ComplexVector();
  }
}

void ExactSolver::set_alignment(const ComplexVector& alignment) {
  const TriangleMesh& mesh = ops_->mesh();
  if (alignment.size() > 0) {
    if (alignment.size() != mesh.num_faces())
      throw InputError("alignment field must have one value per face (" + std::to_string(mesh.num_faces()) +
                       "), got " + std::to_string(alignment.size()));
    if (!alignment.allFinite()) throw InputError("alignment field contains NaN or infinite values");
  }
  alignment_per_face_ = alignment;
  update_alignment();
}

void ExactSolver::set_symmetry(std::shared_ptr<const MirrorMap> mirror) {
  if (mirror) {
    if (mirror->num_faces() != ops_->mesh().num_faces())
      throw InputError("the mirror map belongs to another mesh (" + std::to_string(mirror->num_faces()) +
                       " faces, not " + std::to_string(ops_->mesh().num_faces()) + ")");
    frozen_.for_each([&](int f, Complex) {
      const int g = mirror->partner(f);
      if (g >= 0 && !frozen_.held(g))
        throw ConstraintError("face " + std::to_string(g) + " is free but its mirror face " + std::to_string(f) +
                              " is frozen: with mirror symmetry both must be free or both frozen");
    });
  }
  mirror_ = std::move(mirror);
  smoothest_.resize(0);
  // On symmetric fields only the symmetrized weights (W_f + W_g) / 2 matter (A_f = A_g, |z_f| = |z_g|); with
  // them V commutes with the mirror, which the symmetric solve relies on. Weights that are not yet symmetric
  // are symmetrized here (a new factorization).
  bool refactor = false;
  if (mirror_ && weight_per_face_.size() > 0) {
    Eigen::VectorXd w = weight_per_face_;
    for (int f = 0; f < static_cast<int>(w.size()); ++f) {
      const int g = mirror_->partner(f);
      if (g >= 0) w[f] = 0.5 * (weight_per_face_[f] + weight_per_face_[g]);
    }
    if (w != weight_per_face_) weight_per_face_ = std::move(w), refactor = true;
  }
  std::vector<int> vector_faces;
  for (const auto& [f, c] : constraints_.faces)
    if (c.kind == ConstraintSet::Kind::Vector) vector_faces.push_back(f);
  if (!anchors_.empty() && anchor_closure(vector_faces) != anchors_) {
    anchors_ = anchor_closure(vector_faces);
    refactor = true;
  }
  if (refactor)
    factor({});
  else
    update_alignment();
}

ComplexVector ExactSolver::project(const ComplexVector& z) const {
  if (!mirror_ || z.size() == 0) return z;
  const int n = ops_->n();
  ComplexVector out = z;
  for (int u = 0; u < num_unknowns(); ++u) {
    const int f = system_.face_of_unknown[u], g = mirror_->partner(f);
    const int v = g >= 0 ? system_.unknown_of_face[g] : -1;
    if (v >= 0) out[v] = 0.5 * (z[v] + mirror_->map(f, z[u], n));
  }
  return out;
}

std::vector<ConstraintRow> ExactSolver::symmetric_rows(std::vector<ConstraintRow> rows) const {
  if (mirror_)
    for (auto& row : rows) row = mirror_->symmetrized(row, ops_->n());
  return rows;
}

std::vector<int> ExactSolver::anchor_closure(const std::vector<int>& vector_faces) const {
  std::vector<int> out = vector_faces;
  if (mirror_)
    for (int f : vector_faces)
      if (mirror_->partner(f) >= 0) out.push_back(mirror_->partner(f));
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

void ExactSolver::symmetric_refinement(ComplexVector& field, const ComplexVector& rhs,
                                       const std::vector<ConstraintRow>& rows) {
  // `field` solves V w = P b - P D^T gamma with symmetrized rows and was projected onto the symmetric fields.
  // If V commutes with the mirror it is the minimiser over symmetric fields. If the mesh is symmetric only up to
  // the matching tolerance, the projected gradient g = P (b - V w) is not yet in the span of the rows: solve the
  // same constrained problem for g (homogeneous rows) and add the projected correction. Each step divides the
  // defect by ~1 / |VS - SV|; stop when the correction is at the level of rounding.
  if (!(mirror_->max_mismatch() > 0)) return;
  std::vector<ConstraintRow> homogeneous = rows;
  for (auto& r : homogeneous) r.rhs = 0.0;
  const double size = std::max(field.norm(), 1e-300);
  for (int step = 0; step < 6; ++step) {
    const ComplexVector g = rhs - project(ComplexVector(system_.matrix * field));
    const ComplexVector base = factor_->solve(g);
    Eigen::MatrixXd K;
    const Response r = schur_solve(homogeneous, Response{&base, nullptr, {}}, K);
    const ComplexVector delta = project(assemble(r));
    field += delta;
    symmetry_corrections_ = step + 1;
    if (delta.norm() <= 1e-14 * size) break;
  }
}

ComplexVector ExactSolver::to_faces(const ComplexVector& per_unknown) const {
  ComplexVector out = ComplexVector::Zero(ops_->mesh().num_faces());
  for (int u = 0; u < num_unknowns(); ++u) out[system_.face_of_unknown[u]] = per_unknown[u];
  frozen_.copy_into(out);  // bit-identical copy
  for (int f : anchors_) out[f] = fixed_value(f);
  return out;
}

Complex ExactSolver::fixed_value(int face) const {
  if (frozen_.held(face)) return frozen_.value(face);
  const auto c = constraints_.faces.find(face);
  if (c != constraints_.faces.end() && c->second.kind == ConstraintSet::Kind::Vector) return c->second.value;
  if (mirror_ && mirror_->partner(face) >= 0) {  // an anchor because its mirror face carries the constraint
    const int g = mirror_->partner(face);
    const auto m = constraints_.faces.find(g);
    if (m != constraints_.faces.end() && m->second.kind == ConstraintSet::Kind::Vector)
      return mirror_->map(g, m->second.value, ops_->n());
  }
  return 0.0;
}

bool ExactSolver::stale(const std::vector<int>& given_faces) const {
  // With symmetry a vector constraint also fixes its mirror face (fixed_value).
  const std::vector<int> vector_faces = anchor_closure(given_faces);
  // Every anchor must still carry a vector constraint (its value is what the system substitutes) ...
  for (int a : anchors_)
    if (!std::binary_search(vector_faces.begin(), vector_faces.end(), a)) return true;
  // ... and no vector constraint may sit on a shifted component: it would be data the shift distorts.
  const std::vector<int>& component = ops_->mesh().face_component();
  for (int f : vector_faces)
    if (system_.shifted_component[component[f]] && !std::binary_search(anchors_.begin(), anchors_.end(), f))
      return true;
  return false;
}

bool ExactSolver::needs_refactorization(const std::vector<int>& vector_faces) const {
  std::vector<int> sorted = vector_faces;
  std::sort(sorted.begin(), sorted.end());
  return stale(sorted);
}

ComplexVector ExactSolver::solve() {
  const FieldOperators& o = *ops_;
  const TriangleMesh& mesh = o.mesh();
  sign_fixed_.clear();

  // 1-2. The system: refactor when the anchors no longer match the vector constraints (see the header).
  std::vector<int> vector_faces;
  for (const auto& [f, c] : constraints_.faces)
    if (c.kind == ConstraintSet::Kind::Vector) vector_faces.push_back(f);
  if (stale(vector_faces)) {
    anchors_ = anchor_closure(vector_faces);
    factor({});
  }
  // Single-threaded BLAS for the solves: their calls are too small to share, and waking OpenBLAS's threads for
  // each of them costs more than it saves (bunny, order 2, 30 direction constraints: 10 % less CPU time and 20 %
  // less wall time on 2 cores).
  const SingleThreadedBlas blas_guard;
  symmetry_corrections_ = 0;
  const int N = num_unknowns();

  // 3. The rows on the unknowns, and where the entries of V^-1 come from (cached columns or a direct solve).
  const std::vector<ConstraintRow> all_rows = free_rows(symmetric_rows(constraints_.rows({}, 0.0)));
  std::vector<int> faces;
  for (const auto& [f, c] : constraints_.faces)
    if (system_.unknown_of_face[f] >= 0) faces.push_back(f);
  for (const auto& row : all_rows)
    for (const auto& t : row.terms) faces.push_back(t.first);
  std::sort(faces.begin(), faces.end());
  faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
  if (N == 0) {  // every face is fixed: the rows hold by themselves (free_rows checked them)
    const ComplexVector out = to_faces(ComplexVector());
    check_singularity_indices(out);
    return out;
  }
  std::vector<int> needed = faces;  // columns a live solve needs: the row faces and the anchors
  needed.insert(needed.end(), anchors_.begin(), anchors_.end());
  std::sort(needed.begin(), needed.end());
  std::vector<int> missing;
  for (int f : needed)
    if (!columns_.count(f)) missing.push_back(f);
  direct_ = !cache_columns_ ||
            (missing.size() > kEagerColumns && !std::includes(deferred_.begin(), deferred_.end(), missing.begin(),
                                                               missing.end()));
  if (direct_) {
    deferred_ = cache_columns_ ? missing : std::vector<int>{};
  } else {
    ensure_columns(missing);
    deferred_.clear();
  }

  // The right-hand side: b0, the anchors' values, the +d safeguard at direction constraints (step 4).
  const double rhs_scale = kind_ == SplineKind::Direction ? 1.0 : -lambda_;
  const int ncomp = std::max(1, mesh.report().num_components);
  std::vector<bool> has_data = component_has_alignment_, has_rows(ncomp, false);
  std::unordered_map<int, Complex> loads;  // face -> weight of the unit load (spikes, anchors in live solves)
  ComplexVector b = b0_;
  ComplexVector spikes = ComplexVector::Zero(N);  // the safeguard's part of b (before P)
  if (!anchors_.empty() && direct_) {  // -V_UA z_A into the right-hand side
    ComplexVector z = ComplexVector::Zero(static_cast<Eigen::Index>(system_.fixed_faces.size()));
    for (int a : anchors_) z[system_.fixed_of_face[a]] = fixed_value(a);
    b -= system_.coupling * z;
  } else {  // the anchors' columns V^-1 V_UF e_a with weights -z_a
    for (int a : anchors_) loads[a] = -fixed_value(a);
  }
  const double mean_area = mesh.total_area() / o.num_unknowns();
  for (const auto& [f, c] : constraints_.faces) {
    const int comp = mesh.face_component()[f];
    has_rows[comp] = true;
    if (c.kind == ConstraintSet::Kind::Direction) {
      const int u = system_.unknown_of_face.at(f);
      // s_f = spike * mean_area / A_f: every constrained face adds the same weight s * mean_area * d to b.
      const Complex delta = safeguard_delta(spike_, mean_area, system_.mass[u], c.value, alignment_[u]);
      const Complex load = (rhs_scale * system_.mass[u]) * delta;
      spikes[u] += load;
      if (direct_) {
        b[u] += load;  // projected below
      } else if (mirror_ && mirror_->partner(f) >= 0) {  // P (e_f load) = (e_f load + e_g T_f(load)) / 2
        loads[f] += 0.5 * load;
        loads[mirror_->partner(f)] += 0.5 * mirror_->map(f, load, o.n());
      } else {
        loads[f] += load;
      }
      if (rhs_scale != 0.0) has_data[comp] = true;
    } else if (std::abs(c.value) > 0) {
      has_data[comp] = true;
    }
  }
  for (const auto& [v, rs] : constraints_.singularity_rows)
    has_rows[mesh.face_component()[rs.front().terms.front().first]] = true;
  // y = V^-1 b: in a direct solve only its values at the constrained faces (Gram matrix), the field comes from
  // one solve at the end; in a live solve the cached base response plus the loads' columns.
  // The full right-hand side, for the symmetric defect correction: b0 - V_UF z_anchors + the safeguard.
  ComplexVector b_full;
  if (mirror_) {
    b_full = b0_ + spikes;
    if (!anchors_.empty()) {
      ComplexVector z = ComplexVector::Zero(static_cast<Eigen::Index>(system_.fixed_faces.size()));
      for (int a : anchors_) z[system_.fixed_of_face[a]] = fixed_value(a);
      b_full -= system_.coupling * z;
    }
    b_full = project(b_full);
    if (direct_) b = project(b);
  }
  Response y;
  if (direct_) {
    if (!faces.empty()) compute_gram(faces, b);
    y.rhs = &b;
  } else {
    y.base = &base_response_;
    y.coefficient = loads;
  }

  // 5. Components whose only constraints are homogeneous: seed with the smoothest field (inverse iteration).
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
    for (int u = 0; u < N; ++u) smoothest_[u] = full[system_.face_of_unknown[u]];
    smoothest_ = project(smoothest_);
  }
  auto restrict_to = [&](const ComplexVector& z, const std::vector<bool>& mask) {
    ComplexVector out = ComplexVector::Zero(N);
    for (int u = 0; u < N; ++u)
      if (mask[mesh.face_component()[system_.face_of_unknown[u]]]) out[u] = z[u];
    return out;
  };

  // 3-4, 6. The Schur solve with the +d pins, the checks, the snapping.
  auto solve_with_pins = [&](const Response& response, const ComplexVector& rhs_full) {
    OrientationPins pins;
    for (;;) {
      const std::vector<ConstraintRow> rows = free_rows(symmetric_rows(constraints_.rows(pins.faces, pins.magnitude)));
      Eigen::MatrixXd K;
      const Response w = schur_solve(rows, response, K);
      if (pins.faces.empty()) check_constrained_faces_carry_data(response, w);
      if (!pins.update(constraints_, [&](int f) { return value_at(w, f); })) continue;
      ComplexVector field = assemble(w);
      refine_rows(rows, K, field);
      if (mirror_) {
        field = project(field);
        symmetric_refinement(field, rhs_full, rows);
      }
      // The orientation once more on the assembled field: in a direct solve the values above come from the Gram
      // matrix, and a face whose value is at rounding level may come out on the other side.
      if (!pins.update(constraints_, [&](int f) {
            const int u = system_.unknown_of_face[f];
            return u >= 0 ? field[u] : fixed_value(f);
          }))
        continue;
      sign_fixed_ = pins.faces;
      check_rows_hold(to_faces(field));
      // Snap constrained faces onto their constraint: removes the rounding of the column combination
      // (relative 1e-12 of the largest term), so constraints hold to the last bit; with symmetry the mirror
      // face takes the mirror image of the snapped value, so the symmetry holds to the last bit as well.
      for (const auto& [f, c] : constraints_.faces) {
        const int u = system_.unknown_of_face[f];
        if (u < 0) continue;
        field[u] = pins.snapped(f, c, field[u]);
        const int g = mirror_ ? mirror_->partner(f) : -1;
        if (g >= 0 && g != f && system_.unknown_of_face[g] >= 0)
          field[system_.unknown_of_face[g]] = mirror_->map(f, field[u], o.n());
      }
      return field;
    }
  };

  ComplexVector w;
  if (!any_homogeneous) {
    w = solve_with_pins(y, b_full);
  } else {
    // Inverse iteration on the homogeneous components: their "alignment" is the current iterate.
    ComplexVector seed = restrict_to(smoothest_, homogeneous);
    const ComplexVector y_full = y.base ? *y.base : factor_->solve(b);  // y as a vector (direct solves)
    for (int it = 0; it < 30; ++it) {
      const ComplexVector load = project(system_.mass.cast<Complex>().cwiseProduct(seed));
      const ComplexVector base = y_full + factor_->solve(load);
      Response shifted{&base, nullptr, y.coefficient};
      w = solve_with_pins(shifted, mirror_ ? ComplexVector(b_full + load) : b_full);
      ComplexVector next = restrict_to(w, homogeneous);
      const double norm = std::sqrt((next.cwiseAbs2().cwiseProduct(system_.mass)).sum());
      if (!(norm > 0)) throw SolverError("singularity constraints admit only the zero field here");
      next *= std::sqrt(restrict_to(ComplexVector(system_.mass.cast<Complex>()), homogeneous).real().sum()) / norm;
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
      if (!empty[mesh.face_component()[system_.face_of_unknown[u]]]) rest += std::norm(w[u]), ++count;
    const double scale = count && rest > 0 ? std::sqrt(rest / count) : 1.0;
    w += scale * restrict_to(smoothest_, empty);
  }
  ComplexVector out = to_faces(w);
  check_singularity_indices(out);
  return out;
}

}  // namespace nfield
