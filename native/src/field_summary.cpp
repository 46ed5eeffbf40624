#include "nfield/field_summary.hpp"

#include <cmath>
#include <string>

#include "nfield/errors.hpp"

namespace nfield {
namespace {

/// exp(i arg(z) / 2) for |z| = 1 without trigonometry: cos(t/2) = sqrt((1 + cos t) / 2), sin(t/2) = sin t / (2 cos(t/2))
/// (or the other way round for t beyond +-pi/2, where 1 + cos t would cancel). arg in (-pi, pi], so cos(t/2) >= 0,
/// and the signed zero of Im z picks the side at t = +-pi as atan2 does.
Complex half_angle(Complex z) {
  const double x = z.real(), y = z.imag();
  if (x >= 0) {
    const double c = std::sqrt(0.5 * (1 + x));
    return {c, y / (2 * c)};
  }
  const double s = std::copysign(std::sqrt(0.5 * (1 - x)), y);
  return {y / (2 * s), s};
}

/// exp(i arg(u) / n) for a unit u: repeated half angles when n is a power of two (1, 2, 4, 8, ...: a few ulp),
/// atan2 and sincos otherwise.
Complex root_direction(Complex u, int n) {
  if ((n & (n - 1)) != 0) {
    const double angle = std::atan2(u.imag(), u.real()) / n;
    return {std::cos(angle), std::sin(angle)};
  }
  const double size2 = std::norm(u);  // u = w / |w| is unit to an ulp, except for subnormal w (fewer bits)
  if (std::abs(size2 - 1) > 1e-15) u /= std::sqrt(size2);
  for (int k = n; k > 1; k >>= 1) u = half_angle(u);
  return u;
}

/// u_f and the first direction of one raw value (both zero where raw is 0).
void summarize_face(const FieldOperators& ops, Complex raw, int face, Complex& unit, Eigen::Ref<Eigen::RowVector3d> first) {
  const double magnitude = std::abs(raw);
  unit = magnitude > 0 ? Complex(raw.real() / magnitude, raw.imag() / magnitude) : Complex(0.0);
  first.setZero();
  if (unit == 0.0) return;
  const Complex d = root_direction(unit, ops.n());
  const Eigen::Vector3d& x = ops.frames().x_axis(face);
  const Eigen::Vector3d& y = ops.frames().y_axis(face);
  for (int k = 0; k < 3; ++k) first[k] = d.real() * x[k] + d.imag() * y[k];
}

}  // namespace

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
  for (int f = 0; f < F; ++f) summarize_face(ops, raw[f], f, out.unit[f], out.first_direction.row(f));
  if (details) {
    out.energy = ops.energy(ops.to_unknowns(out.unit), order);
    out.singularities = singularity_indices(ops, out.unit);
  }
  return out;
}

FieldSummary summarize_faces(const FieldOperators& ops, const ComplexVector& raw, const std::vector<int>& faces) {
  const int F = ops.mesh().num_faces();
  if (raw.size() != F)
    throw InputError("field must have one value per face (" + std::to_string(F) + "), got " +
                     std::to_string(raw.size()));
  const Eigen::Index k = static_cast<Eigen::Index>(faces.size());
  FieldSummary out;
  out.unit = ComplexVector::Zero(k);
  out.first_direction = Vectors3::Zero(k, 3);
  for (Eigen::Index i = 0; i < k; ++i) {
    const int f = faces[static_cast<std::size_t>(i)];
    if (f < 0 || f >= F) throw InputError("face " + std::to_string(f) + " is out of range");
    summarize_face(ops, raw[f], f, out.unit[i], out.first_direction.row(i));
  }
  return out;
}

}  // namespace nfield
