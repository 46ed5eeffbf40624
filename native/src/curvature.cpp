#include "nfield/curvature.hpp"

#include <Eigen/Dense>
#include <cmath>

#include "nfield/errors.hpp"

namespace nfield {
namespace {

/// Angle-weighted vertex normals over active faces (zero for unused vertices).
std::vector<Eigen::Vector3d> vertex_normals(const TriangleMesh& mesh) {
  std::vector<Eigen::Vector3d> normals(mesh.num_vertices(), Eigen::Vector3d::Zero());
  const auto& F = mesh.faces();
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (!mesh.face_active(f)) continue;
    for (int c = 0; c < 3; ++c) normals[F(f, c)] += mesh.corner_angle(f, c) * mesh.face_normal(f);
  }
  for (auto& n : normals) {
    const double len = n.norm();
    if (len > 0) n /= len;
  }
  return normals;
}

}  // namespace

PrincipalCurvature principal_curvature(const TriangleMesh& mesh, const TangentFrames& frames) {
  const int nf = mesh.num_faces();
  const auto& P = mesh.positions();
  const auto& F = mesh.faces();
  const auto normals = vertex_normals(mesh);

  // 1. Per-face shape operator, as a 3D tensor T = B II B^T (B = [x y]) so it can be averaged.
  std::vector<Eigen::Matrix3d> tensor(nf, Eigen::Matrix3d::Zero());
  for (int f = 0; f < nf; ++f) {
    if (!mesh.face_active(f)) continue;
    const Eigen::Vector3d& x = frames.x_axis(f);
    const Eigen::Vector3d& y = frames.y_axis(f);
    // Unknowns (a, b, c) of II = [[a, b], [b, c]]; per edge: a ex + b ey = dnx, b ex + c ey = dny.
    Eigen::Matrix<double, 6, 3> A;
    Eigen::Matrix<double, 6, 1> rhs;
    for (int k = 0; k < 3; ++k) {
      const int i = F(f, (k + 1) % 3), j = F(f, (k + 2) % 3);
      const Eigen::Vector3d e = P.row(j) - P.row(i);
      const Eigen::Vector3d dn = normals[j] - normals[i];
      const double ex = e.dot(x), ey = e.dot(y);
      A.row(2 * k) << ex, ey, 0;
      A.row(2 * k + 1) << 0, ex, ey;
      rhs[2 * k] = dn.dot(x);
      rhs[2 * k + 1] = dn.dot(y);
    }
    const Eigen::Vector3d abc = A.colPivHouseholderQr().solve(rhs);
    if (!abc.allFinite()) continue;
    Eigen::Matrix<double, 3, 2> B;
    B.col(0) = x;
    B.col(1) = y;
    Eigen::Matrix2d II;
    II << abc[0], abc[1], abc[1], abc[2];
    tensor[f] = B * II * B.transpose();
  }

  // 2. Area-weighted average over the faces sharing a vertex with f, re-expressed in f's frame.
  PrincipalCurvature out;
  out.kmax = Eigen::VectorXd::Zero(nf);
  out.kmin = Eigen::VectorXd::Zero(nf);
  out.dir_max.assign(nf, Eigen::Vector3d::Zero());
  out.dir_min.assign(nf, Eigen::Vector3d::Zero());
  std::vector<int> stamp(nf, -1);
  for (int f = 0; f < nf; ++f) {
    if (!mesh.face_active(f)) continue;
    Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
    double weight = 0;
    for (int c = 0; c < 3; ++c)
      for (int g : mesh.vertex_faces(F(f, c))) {
        if (stamp[g] == f) continue;
        stamp[g] = f;
        sum += mesh.face_area(g) * tensor[g];
        weight += mesh.face_area(g);
      }
    if (weight <= 0) continue;
    Eigen::Matrix<double, 3, 2> B;
    B.col(0) = frames.x_axis(f);
    B.col(1) = frames.y_axis(f);
    Eigen::Matrix2d II = B.transpose() * (sum / weight) * B;
    II = 0.5 * (II + II.transpose()).eval();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(II);
    const Eigen::Vector2d k = es.eigenvalues();  // ascending
    const int imax = std::abs(k[1]) >= std::abs(k[0]) ? 1 : 0;
    out.kmax[f] = k[imax];
    out.kmin[f] = k[1 - imax];
    out.dir_max[f] = (B * es.eigenvectors().col(imax)).normalized();
    out.dir_min[f] = (B * es.eigenvectors().col(1 - imax)).normalized();
  }
  return out;
}

ComplexVector curvature_alignment(const FieldOperators& ops, bool maximal) {
  if (ops.n() % 2 != 0)
    throw ParameterError("curvature alignment needs an even symmetry n (principal directions are lines, not "
                         "vectors); got n=" + std::to_string(ops.n()));
  const TriangleMesh& mesh = ops.mesh();
  const PrincipalCurvature pc = principal_curvature(mesh, ops.frames());
  const double scale = std::sqrt(mesh.total_area());
  ComplexVector z = ComplexVector::Zero(mesh.num_faces());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (!mesh.face_active(f)) continue;
    const Eigen::Vector3d& d = maximal ? pc.dir_max[f] : pc.dir_min[f];
    const double magnitude = std::abs(pc.kmax[f] - pc.kmin[f]) * scale;
    if (!(magnitude > 0) || !std::isfinite(magnitude)) continue;
    z[f] = std::polar(magnitude, ops.n() * ops.frames().angle_of(f, d));
  }
  return z;
}

}  // namespace nfield
