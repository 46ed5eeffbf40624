#include "nfield/per_face.hpp"

#include <cmath>
#include <string>

#include "nfield/errors.hpp"

namespace nfield {

Eigen::VectorXd mass_per_face(const FieldOperators& ops) {
  Eigen::VectorXd area = Eigen::VectorXd::Zero(ops.mesh().num_faces());
  for (int u = 0; u < ops.num_unknowns(); ++u) area[ops.face_of_unknown(u)] = ops.mass()[u];
  return area;
}

ComplexVector transport_per_edge(const FieldOperators& ops) {
  ComplexVector r(static_cast<Eigen::Index>(ops.mesh().dual_edges().size()));
  for (Eigen::Index e = 0; e < r.size(); ++e) r[e] = ops.transport(static_cast<int>(e));
  return r;
}

Eigen::VectorXd weight_per_edge(const FieldOperators& ops) {
  Eigen::VectorXd w(static_cast<Eigen::Index>(ops.mesh().dual_edges().size()));
  for (Eigen::Index e = 0; e < w.size(); ++e) w[e] = ops.edge_weight(static_cast<int>(e));
  return w;
}

FaceTriplets to_face_triplets(const FieldOperators& ops, const ComplexSparse& A) {
  if (A.rows() != ops.num_unknowns() || A.cols() != ops.num_unknowns())
    throw ParameterError("matrix of size " + std::to_string(A.rows()) + " x " + std::to_string(A.cols()) +
                         " is not indexed by the " + std::to_string(ops.num_unknowns()) + " unknowns");
  FaceTriplets out;
  out.rows.reserve(static_cast<std::size_t>(A.nonZeros()));
  out.cols.reserve(static_cast<std::size_t>(A.nonZeros()));
  out.values.reserve(static_cast<std::size_t>(A.nonZeros()));
  for (int k = 0; k < A.outerSize(); ++k)
    for (ComplexSparse::InnerIterator it(A, k); it; ++it) {
      out.rows.push_back(ops.face_of_unknown(static_cast<int>(it.row())));
      out.cols.push_back(ops.face_of_unknown(static_cast<int>(it.col())));
      out.values.push_back(it.value());
    }
  return out;
}

ComplexVector tangent_vectors_to_representation(const FieldOperators& ops,
                                                const Eigen::Ref<const Eigen::Matrix<long long, Eigen::Dynamic, 1>>& faces,
                                                const Eigen::Ref<const Vectors3>& vectors) {
  if (vectors.rows() != faces.size()) throw InputError("faces and vectors must have the same length");
  const TriangleMesh& mesh = ops.mesh();
  ComplexVector out(faces.size());
  for (Eigen::Index i = 0; i < faces.size(); ++i) {
    const long long f = faces[i];
    if (f < 0 || f >= mesh.num_faces())
      throw ConstraintError("face " + std::to_string(f) + " is out of range (mesh has " +
                            std::to_string(mesh.num_faces()) + " faces)");
    if (!mesh.face_active(static_cast<int>(f)))
      throw ConstraintError("face " + std::to_string(f) + " is degenerate and excluded from the field");
    const Eigen::Vector3d v = vectors.row(i).transpose();
    if (!v.allFinite()) throw ConstraintError("vector on face " + std::to_string(f) + " is not finite");
    out[i] = to_representation(ops.frames().to_tangent(static_cast<int>(f), v), ops.n());
  }
  return out;
}

Vectors3 directions_per_face(const FieldOperators& ops, const ComplexVector& per_face) {
  const int F = ops.mesh().num_faces();
  if (per_face.size() != F) throw InputError("field must have one value per face (" + std::to_string(F) + ")");
  const int n = ops.n();
  Vectors3 out = Vectors3::Zero(static_cast<Eigen::Index>(F) * n, 3);
  for (int f = 0; f < F; ++f) {
    const double magnitude = std::abs(per_face[f]);
    if (!ops.mesh().face_active(f) || !(magnitude > 0) || !std::isfinite(magnitude)) continue;
    const double angle = std::arg(per_face[f]) / n;
    for (int k = 0; k < n; ++k)
      out.row(static_cast<Eigen::Index>(f) * n + k) =
          ops.frames().to_3d(f, std::polar(1.0, angle + 2 * M_PI * k / n)).transpose();
  }
  return out;
}

void scatter_rows_to_faces(const FieldOperators& ops, const Eigen::MatrixXcd& per_unknown,
                           Eigen::Ref<RowMajorMatrixXcd> per_face) {
  if (per_unknown.rows() != ops.num_unknowns() || per_face.rows() != ops.mesh().num_faces() ||
      per_face.cols() != per_unknown.cols())
    throw ParameterError("scatter_rows_to_faces: a " + std::to_string(per_unknown.rows()) + " x " +
                         std::to_string(per_unknown.cols()) + " matrix per unknown does not fit a " +
                         std::to_string(per_face.rows()) + " x " + std::to_string(per_face.cols()) +
                         " matrix per face");
  per_face.setZero();
  const Eigen::Index k = per_unknown.cols();
  for (int u = 0; u < ops.num_unknowns(); ++u) {
    const int f = ops.face_of_unknown(u);
    for (Eigen::Index c = 0; c < k; ++c) per_face(f, c) = per_unknown(u, c);
  }
}

}  // namespace nfield
