// Per-face and per-dual-edge views of FieldOperators data, and conversions between 3D tangent vectors,
// representation vectors and n-directions.
//
// FieldOperators index *unknowns* (active faces only, see operators.hpp); users index *faces* of the input
// mesh and *dual edges* in mesh.dual_edges() order. These functions put operator data into those orders
// (inactive faces get zeros), so that every caller (the Python module, tools, tests) shares one mapping.
//
// Representation (tangent_frames.hpp): a tangent vector t (complex, in face f's frame) of an n-field is
// stored as |t| exp(i n arg t); the n directions it stands for are the unit vectors of angle
// arg(z_f) / n + 2 pi k / n, k = 0..n-1.
#pragma once
#include <Eigen/Core>
#include <vector>

#include "nfield/operators.hpp"

namespace nfield {

/// Rows of 3D vectors (one vector per row), the layout of positions and of direction arrays.
using Vectors3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
/// A dense complex matrix stored row by row (the layout of an (F, k) NumPy array).
using RowMajorMatrixXcd = Eigen::Matrix<Complex, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Face areas (length^2) per face: the diagonal of M in face order, 0 on inactive faces.
Eigen::VectorXd mass_per_face(const FieldOperators& ops);

/// The n-connection r_e = exp(i n (a1 - a0)) of every dual edge (face0 -> face1).
ComplexVector transport_per_edge(const FieldOperators& ops);

/// The edge weight w_e of every dual edge (dimensionless).
Eigen::VectorXd weight_per_edge(const FieldOperators& ops);

/// Coordinate (COO) triplets of a sparse matrix, with row and column indices in face numbering.
struct FaceTriplets {
  std::vector<long long> rows, cols;
  std::vector<Complex> values;
};

/// The nonzeros of A (indexed by unknowns, num_unknowns x num_unknowns) as face-indexed triplets, in
/// column-major order. ParameterError if A does not have the size of the operators.
FaceTriplets to_face_triplets(const FieldOperators& ops, const ComplexSparse& A);

/// Representation vectors |t| exp(i n arg t) of 3D vectors: vectors.row(i) is projected onto the tangent
/// plane of faces[i] (t in that face's frame, units of the input; a vector along the normal gives 0).
/// ConstraintError naming the face for a face out of range, an inactive (degenerate) face or a vector
/// that is not finite; InputError if the two arrays differ in length.
ComplexVector tangent_vectors_to_representation(const FieldOperators& ops,
                                                const Eigen::Ref<const Eigen::Matrix<long long, Eigen::Dynamic, 1>>& faces,
                                                const Eigen::Ref<const Vectors3>& vectors);

/// The n unit directions of a per-face field (size num_faces): row f n + k is the 3D unit vector of angle
/// arg(z_f) / n + 2 pi k / n in f's frame. Rows of inactive faces and of faces where z_f is zero or not
/// finite are zero. InputError if the field does not have one value per face.
Vectors3 directions_per_face(const FieldOperators& ops, const ComplexVector& per_face);

/// Writes the rows of a per-unknown matrix (num_unknowns x k) to the face rows of `per_face`
/// (num_faces x k, e.g. a NumPy buffer); rows of inactive faces become 0. ParameterError on a size mismatch.
void scatter_rows_to_faces(const FieldOperators& ops, const Eigen::MatrixXcd& per_unknown,
                           Eigen::Ref<RowMajorMatrixXcd> per_face);

}  // namespace nfield
