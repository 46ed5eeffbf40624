// What a solve reports about its raw solution, computed in one native pass (nfield.core builds its FieldResult
// from it): the unit field, the first of its n directions per face in 3D, the energy of the unit field and its
// singularity indices.
//
// For a raw n-field w (one representation vector per face, tangent_frames.hpp):
//   unit field        u_f = w_f / |w_f|, real and imaginary parts divided separately by |w_f| (a subnormal w_f
//                     stays finite), 0 where w_f = 0;
//   first direction   the unit 3D vector at angle arg(u_f) / n in f's frame, cos a x_f + sin a y_f (the other
//                     n - 1 are turned by 2 pi k / n: directions_per_face), a zero row where u_f = 0;
//   energy            E_m(u) = u^H E_m u, complex form, the paper's scale (operators.hpp);
//   singularities     the vertices where u has a non-zero index (singularities.hpp).
#pragma once
#include <limits>
#include <vector>

#include "nfield/operators.hpp"
#include "nfield/per_face.hpp"
#include "nfield/singularities.hpp"

namespace nfield {

struct FieldSummary {
  ComplexVector unit;        ///< u per face
  Vectors3 first_direction;  ///< one row per face
  double energy = std::numeric_limits<double>::quiet_NaN();  ///< E_m(u); NaN when not asked for
  std::vector<VertexIndex> singularities;                     ///< empty when not asked for
};

/// The summary of `raw` (one value per face; InputError otherwise). `details` = false (live editing) leaves out
/// the energy and the singularities, which cost more than a live solve. `order` (1..4) is the energy's order.
FieldSummary summarize_field(const FieldOperators& ops, const ComplexVector& raw, int order, bool details);

/// The unit field and the first direction of `raw` (one value per face) on `faces` only, in that order (rows of
/// `unit` and `first_direction`; no energy, no singularities): what a summary changes when only these faces'
/// raw values changed (a live local solve). The same values, bit for bit, as summarize_field on those faces.
/// InputError for a field of another size or a face out of range.
FieldSummary summarize_faces(const FieldOperators& ops, const ComplexVector& raw, const std::vector<int>& faces);

}  // namespace nfield
