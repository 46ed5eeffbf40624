#include "nfield/constraint_system.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "nfield/errors.hpp"
#include "nfield/singularities.hpp"

namespace nfield {

double safeguard_spike(const ComplexVector& alignment) {
  double sum = 0;
  int count = 0;
  for (Eigen::Index u = 0; u < alignment.size(); ++u)
    if (alignment[u] != 0.0) sum += std::norm(alignment[u]), ++count;  // (|z| > 0 without a hypot per face)
  return kSafeguardWeight * (count ? std::sqrt(sum / count) : 1.0);
}

ConstraintSystemSolution solve_constraint_system(const Eigen::MatrixXd& K, const Eigen::VectorXd& rhs) {
  const Eigen::Index R = K.rows();
  ConstraintSystemSolution out;
  Eigen::LDLT<Eigen::MatrixXd> ldlt(K);
  const Eigen::VectorXd diag = ldlt.vectorD().cwiseAbs();
  const double kmax = std::max(diag.maxCoeff(), 1e-300);
  if (ldlt.info() == Eigen::Success && diag.minCoeff() > 1e-11 * kmax) {
    out.gamma = ldlt.solve(rhs);
    return out;
  }
  // Dependent rows: the pseudo-inverse (least squares); a right-hand side outside K's range is a conflict.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(K);
  const Eigen::VectorXd ev = es.eigenvalues();
  const Eigen::MatrixXd& Q = es.eigenvectors();
  const double emax = std::max(ev.cwiseAbs().maxCoeff(), 1e-300);
  const Eigen::VectorXd q = Q.transpose() * rhs;
  const double rhs_norm = std::max(rhs.norm(), 1e-300);
  out.gamma = Eigen::VectorXd::Zero(R);
  for (Eigen::Index i = 0; i < R; ++i) {
    if (ev[i] > 1e-10 * emax) {
      out.gamma += Q.col(i) * (q[i] / ev[i]);
    } else if (out.conflicting_rows.empty() && std::abs(q[i]) > 1e-7 * rhs_norm) {
      for (Eigen::Index r = 0; r < R; ++r)
        if (std::abs(Q(r, i)) > 0.1) out.conflicting_rows.push_back(static_cast<int>(r));
    }
  }
  return out;
}

void ConstraintEditor::check_face(int face) const {
  require_constrainable_face(ops_->mesh(), face);
  if (face_fixed(face))
    throw ConstraintError("face " + std::to_string(face) + " is frozen (outside the region being edited)");
}

void ConstraintEditor::set_direction_constraint(int face, Complex d) {
  check_face(face);
  constraints_.set_direction(face, d);
}

void ConstraintEditor::set_vector_constraint(int face, Complex value) {
  check_face(face);
  constraints_.set_vector(face, value);
}

void ConstraintEditor::remove_constraint(int face) { constraints_.remove_face(face); }

void ConstraintEditor::set_singularity(int vertex, int numerator) {
  auto rows = singularity_constraint_rows(*ops_, vertex, numerator);  // validates
  for (const auto& row : rows)
    for (const auto& t : row.terms)
      if (face_fixed(t.first))
        throw ConstraintError("singularity at vertex " + std::to_string(vertex) +
                              " touches a frozen face (outside the region being edited)");
  constraints_.set_singularity(vertex, numerator, std::move(rows));
}

void ConstraintEditor::remove_singularity(int vertex) { constraints_.remove_singularity(vertex); }

}  // namespace nfield
