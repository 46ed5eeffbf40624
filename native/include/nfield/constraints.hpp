// Hard constraints of n-field splines (paper sections 5 and 7) as real linear functionals.
//
// Every constraint becomes one or more rows  l(z) = sum_k Re(conj(c_k) z_{f_k}) = rhs  on the complex
// per-face field z (faces indexed as in the mesh). With <a, b> the Euclidean product of R^2 = C:
//   n-direction constraint  <u_f, J d_f> = 0       one row, c = i d_f, rhs 0          (eq. 12)
//   n-vector constraint     u_f = d_f              two rows, c = 1 and c = i            (eq. 11)
//   singularity constraint  z_{j+1} = r_j e^{i delta} z_j on k-1 steps of the ring  (eq. 10, corrected;
//                           see singularities.hpp)   two rows per step
// Rows are consumed by the exact solver through the Schur complement D V^-1 D^T (eq. 13).
#pragma once
#include <map>
#include <utility>
#include <vector>

#include "nfield/tangent_frames.hpp"

namespace nfield {

struct ConstraintRow {
  std::vector<std::pair<int, Complex>> terms;  ///< (face, c_k)
  double rhs = 0.0;
};

/// The two real rows of the complex equation sum_k a_k z_{f_k} = value (real part, imaginary part).
std::pair<ConstraintRow, ConstraintRow> complex_equation_rows(const std::vector<std::pair<int, Complex>>& terms,
                                                              Complex value);

/// A user's hard constraints: at most one per face, at most one singularity per vertex.
struct ConstraintSet {
  enum class Kind { Direction, Vector };
  struct FaceConstraint {
    Kind kind;
    Complex value;  ///< unit representation vector (Direction) or representation vector (Vector)
  };
  std::map<int, FaceConstraint> faces;  ///< face -> constraint
  std::map<int, int> singularities;     ///< vertex -> index numerator N (index N/n)
  std::map<int, std::vector<ConstraintRow>> singularity_rows;  ///< vertex -> its ring rows

  size_t size() const { return faces.size() + singularities.size(); }

  /// Editing shared by the exact and the reduced solver (the face itself is validated by the solver).
  /// ConstraintError for a zero/non-finite direction or value, or removing what is not there.
  void set_direction(int face, Complex d);
  void set_vector(int face, Complex value);
  void remove_face(int face);
  void set_singularity(int vertex, int numerator, std::vector<ConstraintRow> rows);
  void remove_singularity(int vertex);

  /// All rows: one per direction constraint, two per vector constraint, the singularity rings' rows.
  /// Direction constraints on `pinned` faces (sorted) become vector constraints of value pin_magnitude * d.
  std::vector<ConstraintRow> rows(const std::vector<int>& pinned, double pin_magnitude) const;
};

}  // namespace nfield
