// Energies and mass matrix of face-based n-vector fields (paper sections 4-6), in complex form.
//
// Unknowns: one complex representation vector z_f per *active* face (inactive faces have no unknown).
//   harmonic energy  E_H(z) = sum_{dual edges} w_e |r_e z_f0 - z_f1|^2 = z^H S z,
//   geometric weights w_e = 3 l_e^2 / (A_f0 + A_f1) (dimensionless), combinatorial weights w_e = 1,
//   mass matrix M = diag(A_f) (length^2), Laplacian L = M^-1 S (1/length^2),
//   m-harmonic energy E_m = S (M^-1 S)^(m-1)  (units length^(2-2m)).
// S is Hermitian positive semi-definite; its realification is the paper's 2|F| x 2|F| matrix (blocks
// -w_ij R_ij), which has every eigenvalue of the complex form twice.
#pragma once
#include <Eigen/Sparse>
#include <memory>
#include <string>
#include <vector>

#include "nfield/mesh.hpp"
#include "nfield/tangent_frames.hpp"

namespace nfield {

using ComplexSparse = Eigen::SparseMatrix<Complex, Eigen::ColMajor, int>;
using ComplexVector = Eigen::VectorXcd;

enum class EdgeWeights { Geometric, Combinatorial };
EdgeWeights parse_edge_weights(const std::string& name);  ///< "geometric" | "combinatorial", else ParameterError
std::string to_string(EdgeWeights w);

/// Frames, connection and energy matrices of one mesh for one symmetry order n. Immutable.
class FieldOperators {
 public:
  /// Throws ParameterError for n < 1 or n > 64.
  FieldOperators(std::shared_ptr<const TriangleMesh> mesh, int n, EdgeWeights weights = EdgeWeights::Geometric);

  const TriangleMesh& mesh() const { return *mesh_; }
  std::shared_ptr<const TriangleMesh> mesh_ptr() const { return mesh_; }
  int n() const { return n_; }
  EdgeWeights weights() const { return weights_; }
  const TangentFrames& frames() const { return frames_; }
  const LeviCivitaConnection& levi_civita() const { return connection_; }

  /// Number of unknowns (active faces) and the maps between faces and unknowns (-1: inactive face).
  int num_unknowns() const { return static_cast<int>(face_of_unknown_.size()); }
  int unknown_of_face(int f) const { return unknown_of_face_[f]; }
  int face_of_unknown(int u) const { return face_of_unknown_[u]; }

  /// r_e = exp(i n (a1 - a0)) for dual edge e (face0 -> face1); computed once per operators.
  Complex transport(int e) const { return transport_[e]; }
  /// Transport from face a to an adjacent face b across dual edge e (r_e or conj(r_e)).
  Complex transport(int e, int from_face) const {
    return mesh_->dual_edges()[e].face0 == from_face ? transport_[e] : std::conj(transport_[e]);
  }
  double edge_weight(int e) const { return edge_weight_[e]; }

  /// Diagonal of M (face areas of active faces, length^2), indexed by unknown.
  const Eigen::VectorXd& mass() const { return mass_; }
  /// S, indexed by unknowns.
  const ComplexSparse& harmonic_matrix() const { return harmonic_; }
  /// S (M^-1 S)^(order-1) for order 1..4 (ParameterError otherwise), exactly Hermitian (symmetrized).
  ComplexSparse energy_matrix(int order) const;
  /// z^H E_order z for a field given per unknown.
  double energy(const ComplexVector& z, int order) const;

  /// Per-face (size num_faces) <-> per-unknown (size num_unknowns) vectors; inactive faces get 0.
  ComplexVector to_unknowns(const ComplexVector& per_face) const;
  ComplexVector to_faces(const ComplexVector& per_unknown) const;

  /// A user-facing scale for eigenvalues of E_order: (4 pi / total_area)^order, the order-th power of the
  /// first Laplacian eigenvalue scale of a round sphere with the mesh's area (1/length^(2 order)).
  double eigenvalue_unit(int order) const;

 private:
  std::shared_ptr<const TriangleMesh> mesh_;
  int n_;
  EdgeWeights weights_;
  TangentFrames frames_;
  LeviCivitaConnection connection_;
  std::vector<int> unknown_of_face_, face_of_unknown_;
  std::vector<double> edge_weight_;
  std::vector<Complex> transport_;  ///< r_e per dual edge
  Eigen::VectorXd mass_;
  ComplexSparse harmonic_;
};

}  // namespace nfield
