// Per-face tangent frames and the discrete n-connection between adjacent faces (paper section 3, eq. 1).
//
// Face f gets the positively oriented orthonormal frame (x_f, y_f): x_f is the unit first edge
// p1 - p0 of the (internally oriented) face, y_f = N_f x x_f. A tangent vector of angle a in that frame
// is the complex number exp(i a); an n-direction {a + 2 pi k / n} is represented by exp(i n a).
//
// Transport across a dual edge (f0 -> f1): if the shared 3D edge vector has angle a0 in frame f0 and a1
// in frame f1, a vector of angle t in f0 has angle t - a0 + a1 in f1, so representation vectors are
// multiplied by r = exp(i n (a1 - a0)); the reverse transport is conj(r).
#pragma once
#include <Eigen/Core>
#include <complex>
#include <vector>

#include "nfield/mesh.hpp"

namespace nfield {

using Complex = std::complex<double>;

/// Orthonormal tangent frame per face (zero vectors for inactive faces).
class TangentFrames {
 public:
  explicit TangentFrames(const TriangleMesh& mesh);
  const Eigen::Vector3d& x_axis(int f) const { return x_[f]; }
  const Eigen::Vector3d& y_axis(int f) const { return y_[f]; }
  /// Angle (radians, (-pi, pi]) of the projection of v onto face f's tangent plane.
  double angle_of(int f, const Eigen::Vector3d& v) const { return std::atan2(v.dot(y_[f]), v.dot(x_[f])); }
  /// Projection of v onto the tangent plane of f as a complex number in f's frame (units of v).
  Complex to_tangent(int f, const Eigen::Vector3d& v) const { return {v.dot(x_[f]), v.dot(y_[f])}; }
  /// 3D vector of the tangent vector t (complex, in f's frame).
  Eigen::Vector3d to_3d(int f, Complex t) const { return t.real() * x_[f] + t.imag() * y_[f]; }

 private:
  std::vector<Eigen::Vector3d> x_, y_;
};

/// The angle rotation exp(i (a1 - a0)) of every dual edge (n = 1). The n-connection is its n-th power.
/// Kept separately from n so that one mesh serves several symmetry orders.
/// The rotation comes from the edge vector in both frames without an angle: with c_k = <e, x_k> + i <e, y_k>
/// (= |e| exp(i a_k)), exp(i (a1 - a0)) = c1 conj(c0) / |c1 conj(c0)|, and its n-th power by repeated squaring
/// (renormalised): as accurate as exp(i n (atan2_1 - atan2_0)) (a phase error of ~n ulp either way), at a
/// fraction of the cost (two atan2 and a sincos per edge were a third of building the operators).
class LeviCivitaConnection {
 public:
  LeviCivitaConnection(const TriangleMesh& mesh, const TangentFrames& frames);
  /// Rotation angle a1 - a0 (radians, (-pi, pi]) of dual edge e, transport face0 -> face1.
  double angle(int e) const { return std::arg(rotation_[e]); }
  /// r_e for symmetry n >= 1: exp(i n (a1 - a0)).
  Complex transport(int e, int n) const;

 private:
  std::vector<Complex> rotation_;  ///< exp(i (a1 - a0)) per dual edge
};

/// Representation vector of a tangent vector t (complex in the face frame) for symmetry n:
/// |t| * exp(i n arg t). Zero stays zero.
inline Complex to_representation(Complex t, int n) {
  const double r = std::abs(t);
  return r == 0.0 ? Complex(0.0, 0.0) : std::polar(r, n * std::arg(t));
}

}  // namespace nfield
