#include "nfield/tangent_frames.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace nfield {

TangentFrames::TangentFrames(const TriangleMesh& mesh)
    : x_(mesh.num_faces(), Eigen::Vector3d::Zero()), y_(mesh.num_faces(), Eigen::Vector3d::Zero()) {
  const auto& P = mesh.positions();
  const auto& F = mesh.faces();
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (!mesh.face_active(f)) continue;
    const Eigen::Vector3d e = P.row(F(f, 1)) - P.row(F(f, 0));
    const Eigen::Vector3d& N = mesh.face_normal(f);
    // Remove any normal component left by rounding so that the frame is exactly orthonormal.
    const Eigen::Vector3d x = (e - e.dot(N) * N).normalized();
    x_[f] = x;
    y_[f] = N.cross(x);
  }
}

LeviCivitaConnection::LeviCivitaConnection(const TriangleMesh& mesh, const TangentFrames& frames) {
  const auto& P = mesh.positions();
  rotation_.reserve(mesh.dual_edges().size());
  for (const DualEdge& d : mesh.dual_edges()) {
    const Eigen::Vector3d e = P.row(d.vertex1) - P.row(d.vertex0);
    const Complex c0 = frames.to_tangent(d.face0, e), c1 = frames.to_tangent(d.face1, e);
    // q / |q| with |q| = |e|^2 in any units: scaled by its largest part first, so that its norm neither over- nor
    // underflows, and without a hypot (two per edge were a tenth of building the operators).
    const Complex q = c1 * std::conj(c0);
    const double big = std::max(std::abs(q.real()), std::abs(q.imag()));
    const Complex unit = big > 0 ? q / big : Complex(1.0, 0.0);
    rotation_.push_back(unit / std::sqrt(std::norm(unit)));
  }
}

Complex LeviCivitaConnection::transport(int e, int n) const {
  Complex power(1.0, 0.0), base = rotation_[e];
  for (int k = n; k > 0; k >>= 1) {
    if (k & 1) power *= base;
    if (k > 1) base *= base;
  }
  return power / std::sqrt(std::norm(power));  // |power| = 1 up to ~n ulp: no scaling needed
}

}  // namespace nfield
