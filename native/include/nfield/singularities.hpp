// Discrete singularity indices of face-based n-fields and singularity constraints (paper sections 3, 5).
//
// Index of an interior vertex v with counter-clockwise ring T_0..T_{k-1}: transport z_j to T_{j+1},
// psi_j = arg(z_{j+1} / (r_j z_j)) in (-pi, pi]; the ring's holonomy is n K_v (K_v the angle defect), so
//   index(v) = (sum_j psi_j + n K_v) / (2 pi n),
// an exact multiple of 1/n. On a closed orientable mesh the indices of a field without zeros sum to chi.
// psi is a property of the dual edge (the step crosses it one way in one ring, the other way, with -psi, in the
// ring of the edge's other end), so it is computed once per dual edge, face0 -> face1.
//
// Singularity constraint for index N/n (the paper's eq. 10 ignores the holonomy; see
// docs/math.md, section 8): impose on k-1 consecutive steps z_{j+1} = r_j exp(i delta) z_j with
// delta = (2 pi N - n K_v) / k. The closing step then holds by itself and the index is exactly N/n.
// It needs |delta| < pi, i.e. |N/n - K_v/(2 pi)| < k/(2n) (roughly the paper's |index| < k/(2n)).
#pragma once
#include <vector>

#include "nfield/constraints.hpp"
#include "nfield/operators.hpp"

namespace nfield {

struct VertexIndex {
  int vertex;
  int numerator;  ///< index = numerator / n
};

/// Index numerators of every interior vertex with a non-zero index. Rings containing a zero vector are
/// skipped (their index is undefined). `field` is per face.
std::vector<VertexIndex> singularity_indices(const FieldOperators& ops, const ComplexVector& field);

/// singularity_indices at the vertices of `faces` only (the vertices whose rings contain one of them), in vertex
/// order: where the indices can have changed when only these faces' values changed (a live local solve), at a
/// cost proportional to them. InputError for a field of another size or a face out of range.
std::vector<VertexIndex> singularity_indices_near(const FieldOperators& ops, const ComplexVector& field,
                                                  const std::vector<int>& faces);

/// Index numerator of `field` (per face) at interior vertex v; false if a ring value is zero or not finite
/// (the index is undefined there). The same rule as singularity_indices.
bool ring_index_numerator(const FieldOperators& ops, const ComplexVector& field, int vertex, int& numerator);

/// Angle in (-pi, pi] of the product of transports around the ring of an interior vertex.
double ring_holonomy(const FieldOperators& ops, int vertex);

/// The numerators N an interior vertex can carry (index N/n): the integers with |2 pi N - n K_v| < k pi,
/// as the closed range [first, second]. ConstraintError for vertices without an index (see below).
std::pair<int, int> singularity_numerator_range(const FieldOperators& ops, int vertex);

/// Rows imposing index numerator/n at vertex. Throws ConstraintError for a vertex out of range, a
/// boundary / non-manifold vertex, or an index the ring cannot carry.
std::vector<ConstraintRow> singularity_constraint_rows(const FieldOperators& ops, int vertex, int numerator);

}  // namespace nfield
