// Mirror symmetry of a mesh about a coordinate plane, and how it acts on face-based n-fields.
//
// The reflection R about the plane {x_axis = offset} maps the surface onto itself when the mesh is
// symmetric. Vertices are matched to the vertex nearest to their mirror image (within `tolerance`, mesh
// units), faces to the face whose vertices are the images of theirs. A face without such a partner (or whose
// vertices have none) is listed as unmatched.
//
// Action on fields. Write a unit tangent vector of face f as exp(i a) in f's frame. R maps f's tangent
// plane onto its partner g's; with p = (R x_f expressed in g's frame) and the sign s of the orientation
// R induces between the two frames (R y_f = s i p), R exp(i a) = p exp(i s a). A reflection reverses the
// surface's orientation, so for a consistently oriented symmetric mesh s = -1, and the representation
// vectors (symmetry n) map conjugate-linearly:
//     z_g = p^n conj(z_f)        (s = -1),          z_g = p^n z_f        (s = +1: the two halves are
//                                                                       oriented against each other).
// The map T_f: z_f -> z_g is real-linear and an isometry of R^2 = C, T_g = T_f^-1, so the symmetry operator
// (S z)_g = T_f z_f is an orthogonal involution and P = (I + S) / 2 is the orthogonal projector onto the
// symmetric fields. A face its own partner (crossing the plane) maps to itself: there the symmetric
// fields are the fixed line of T_f.
#pragma once
#include <Eigen/Core>
#include <string>
#include <vector>

#include "nfield/constraints.hpp"
#include "nfield/tangent_frames.hpp"

namespace nfield {

/// Axis 0, 1, 2 (x, y, z) from "x" | "y" | "z"; ParameterError otherwise.
int parse_mirror_axis(const std::string& name);

class MirrorMap {
 public:
  /// 0 <= tolerance <= 0.1 bounding-box diagonal (mesh units); ParameterError for a bad axis, tolerance or offset.
  MirrorMap(const TriangleMesh& mesh, const TangentFrames& frames, int axis, double offset, double tolerance);

  int axis() const { return axis_; }
  int num_faces() const { return static_cast<int>(partner_.size()); }
  int num_vertices() const { return static_cast<int>(vertex_partner_.size()); }
  double offset() const { return offset_; }
  /// Mirror face of f, or -1 (inactive or unmatched).
  int partner(int f) const { return partner_[f]; }
  /// Mirror vertex of v, or -1.
  int vertex_partner(int v) const { return vertex_partner_[v]; }
  /// Active faces without a partner, sorted.
  const std::vector<int>& unmatched() const { return unmatched_; }
  int num_matched() const { return num_matched_; }
  /// Largest distance between a matched vertex's mirror image and its partner (mesh units).
  double max_mismatch() const { return max_mismatch_; }

  /// T_f for symmetry n applied to z: the representation vector on partner(f) of the mirror image of z.
  Complex map(int f, Complex z, int n) const;
  bool conjugate(int f) const { return conjugate_[f]; }
  /// p (unit) of the header: the n = 1 phase of T_f.
  Complex phase(int f) const { return phase_[f]; }

  /// The row l(z) = sum Re(conj(c_k) z_k) restricted to symmetric fields, written symmetrically:
  /// l(P z) = sum (Re(conj(c_k) z_k) + Re(conj(c'_k) z_partner(k))) / 2 with c'_k = T_k c_k (T_k is its own
  /// adjoint's inverse), so that rows of the symmetric problem stay rows of the usual form.
  ConstraintRow symmetrized(const ConstraintRow& row, int n) const;
  /// (P z) per face (size num_faces); faces without partner keep their value.
  Eigen::VectorXcd project(const Eigen::VectorXcd& z, int n) const;
  /// Largest |z_g - T_f z_f| over matched pairs, relative to max |z|: 0 for a symmetric field.
  double asymmetry(const Eigen::VectorXcd& z, int n) const;

 private:
  int axis_;
  double offset_;
  std::vector<int> partner_, vertex_partner_, unmatched_;
  std::vector<Complex> phase_;
  std::vector<char> conjugate_;
  int num_matched_ = 0;
  double max_mismatch_ = 0;
};

}  // namespace nfield
