#include "nfield/constraints.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "nfield/errors.hpp"

namespace nfield {

std::pair<ConstraintRow, ConstraintRow> complex_equation_rows(const std::vector<std::pair<int, Complex>>& terms,
                                                              Complex value) {
  // Re(a z) = Re(conj(conj a) z), Im(a z) = Re(-i a z) = Re(conj(i conj a) z).
  ConstraintRow re, im;
  for (const auto& [face, a] : terms) {
    re.terms.emplace_back(face, std::conj(a));
    im.terms.emplace_back(face, Complex(0, 1) * std::conj(a));
  }
  re.rhs = value.real();
  im.rhs = value.imag();
  return {re, im};
}

void ConstraintSet::set_direction(int face, Complex d) {
  const double len = std::abs(d);
  if (!std::isfinite(len) || len <= 1e-12)
    throw ConstraintError("direction constraint on face " + std::to_string(face) + " has a zero or invalid direction");
  faces[face] = {Kind::Direction, d / len};
}

void ConstraintSet::set_vector(int face, Complex value) {
  if (!std::isfinite(std::abs(value)))
    throw ConstraintError("vector constraint on face " + std::to_string(face) + " is not finite");
  faces[face] = {Kind::Vector, value};
}

void ConstraintSet::remove_face(int face) {
  if (!faces.erase(face)) throw ConstraintError("face " + std::to_string(face) + " has no constraint to remove");
}

void ConstraintSet::set_singularity(int vertex, int numerator, std::vector<ConstraintRow> ring_rows) {
  singularities[vertex] = numerator;
  singularity_rows[vertex] = std::move(ring_rows);
}

void ConstraintSet::remove_singularity(int vertex) {
  if (!singularities.erase(vertex))
    throw ConstraintError("vertex " + std::to_string(vertex) + " has no singularity constraint to remove");
  singularity_rows.erase(vertex);
}

void OrientationPins::throw_unorientable() {
  throw SolverError("could not orient every direction constraint along +d");
}

std::vector<ConstraintRow> ConstraintSet::rows(const std::vector<int>& pinned, double pin_magnitude) const {
  std::vector<ConstraintRow> out;
  for (const auto& [face, c] : faces) {
    const bool pin = std::binary_search(pinned.begin(), pinned.end(), face);
    if (c.kind == Kind::Direction && !pin) {
      ConstraintRow r;
      r.terms.emplace_back(face, Complex(0, 1) * c.value);  // <u, J d> = Re(conj(i d) u)
      out.push_back(std::move(r));
    } else {
      const Complex value = c.kind == Kind::Vector ? c.value : pin_magnitude * c.value;
      auto [re, im] = complex_equation_rows({{face, Complex(1, 0)}}, value);
      out.push_back(std::move(re));
      out.push_back(std::move(im));
    }
  }
  for (const auto& [vertex, rs] : singularity_rows) out.insert(out.end(), rs.begin(), rs.end());
  return out;
}

void require_constrainable_face(const TriangleMesh& mesh, int face) {
  if (face < 0 || face >= mesh.num_faces())
    throw ConstraintError("face " + std::to_string(face) + " is out of range (mesh has " +
                          std::to_string(mesh.num_faces()) + " faces)");
  if (!mesh.face_active(face))
    throw ConstraintError("face " + std::to_string(face) + " is degenerate and excluded from the field");
}

}  // namespace nfield
