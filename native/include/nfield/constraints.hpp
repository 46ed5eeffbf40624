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
#include <algorithm>
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

/// The +d safeguard's pinning state, shared by the exact and the reduced solver (spline_solver.hpp):
/// direction constraints whose solution points along -d (or vanishes) are pinned to the n-vector
/// constraint u_f = magnitude * d_f, magnitude being the median along-d value of the correctly oriented
/// constrained faces. Pins only grow within one solve, so the loop ends after at most one round per face.
struct OrientationPins {
  std::vector<int> faces;  ///< pinned faces, sorted
  double magnitude = 0;
  int rounds = 0;

  bool pinned(int face) const { return std::binary_search(faces.begin(), faces.end(), face); }

  /// Inspects a solution through value_at(face) -> Complex. Returns true if every unpinned direction
  /// constraint points along +d; otherwise pins the offenders and returns false (solve again).
  /// Throws SolverError (errors.hpp) if rounds exceed the number of constraints.
  template <class ValueAt>
  bool update(const ConstraintSet& set, ValueAt value_at) {
    std::vector<std::pair<int, double>> along;
    double scale = 0;  // the largest constrained value
    for (const auto& [f, c] : set.faces) {
      const Complex value = value_at(f);
      scale = std::max(scale, std::abs(value));
      if (c.kind == ConstraintSet::Kind::Direction && !pinned(f)) along.emplace_back(f, (std::conj(c.value) * value).real());
    }
    std::vector<int> wrong;
    std::vector<double> good;
    for (const auto& [f, t] : along) {
      if (t > 1e-8 * scale)
        good.push_back(t);
      else
        wrong.push_back(f);
    }
    if (wrong.empty()) return true;
    if (++rounds > static_cast<int>(set.faces.size()) + 1) throw_unorientable();
    if (faces.empty()) {
      if (!good.empty()) {
        std::nth_element(good.begin(), good.begin() + good.size() / 2, good.end());
        magnitude = good[good.size() / 2];
      } else {
        magnitude = scale;
      }
      if (!(magnitude > 0)) magnitude = 1.0;
    }
    faces.insert(faces.end(), wrong.begin(), wrong.end());
    std::sort(faces.begin(), faces.end());
    return false;
  }

  /// The value z of a constrained face moved exactly onto its constraint (removes rounding).
  Complex snapped(int face, const ConstraintSet::FaceConstraint& c, Complex z) const {
    if (c.kind == ConstraintSet::Kind::Vector) return c.value;
    if (pinned(face)) return magnitude * c.value;
    return (std::conj(c.value) * z).real() * c.value;
  }

 private:
  [[noreturn]] static void throw_unorientable();
};

/// ConstraintError unless `face` is a face of `mesh` that carries a field value (in range, not degenerate):
/// the check every solver makes before it accepts a face constraint.
void require_constrainable_face(const TriangleMesh& mesh, int face);

}  // namespace nfield
