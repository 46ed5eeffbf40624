#include "nfield/field_summary.hpp"

#include <cmath>
#include <string>

#include "nfield/errors.hpp"

namespace nfield {

FieldSummary summarize_field(const FieldOperators& ops, const ComplexVector& raw, int order, bool details) {
  const TriangleMesh& mesh = ops.mesh();
  const int F = mesh.num_faces();
  if (raw.size() != F)
    throw InputError("field must have one value per face (" + std::to_string(F) + "), got " +
                     std::to_string(raw.size()));
  if (order < 1 || order > 4) throw ParameterError("energy order must be 1 to 4, got " + std::to_string(order));
  FieldSummary out;
  out.unit = ComplexVector::Zero(F);
  out.first_direction = Vectors3::Zero(F, 3);
  const double n = ops.n();
  for (int f = 0; f < F; ++f) {
    const double magnitude = std::abs(raw[f]);
    if (!(magnitude > 0)) continue;
    const Complex u(raw[f].real() / magnitude, raw[f].imag() / magnitude);
    out.unit[f] = u;
    const double angle = std::atan2(u.imag(), u.real()) / n;
    const double c = std::cos(angle), s = std::sin(angle);
    const Eigen::Vector3d& x = ops.frames().x_axis(f);
    const Eigen::Vector3d& y = ops.frames().y_axis(f);
    for (int k = 0; k < 3; ++k) out.first_direction(f, k) = c * x[k] + s * y[k];
  }
  if (details) {
    out.energy = ops.energy(ops.to_unknowns(out.unit), order);
    out.singularities = singularity_indices(ops, out.unit);
  }
  return out;
}

}  // namespace nfield
