#include "nfield/frozen_faces.hpp"

#include <cmath>
#include <string>
#include <utility>

#include "nfield/constraints.hpp"
#include "nfield/errors.hpp"

namespace nfield {

FrozenFaces FrozenFaces::listed(const TriangleMesh& mesh, const std::vector<std::pair<int, Complex>>& pairs) {
  FrozenFaces out;
  if (pairs.empty()) return out;
  out.flag_.assign(mesh.num_faces(), 0);
  out.value_ = ComplexVector::Zero(mesh.num_faces());
  for (const auto& [f, z] : pairs) {
    require_constrainable_face(mesh, f);
    if (!std::isfinite(z.real()) || !std::isfinite(z.imag()))
      throw InputError("frozen value on face " + std::to_string(f) + " is not finite");
    if (out.flag_[f]) throw InputError("face " + std::to_string(f) + " is frozen twice");
    out.flag_[f] = 1;
    out.value_[f] = z;
  }
  out.count_ = static_cast<int>(pairs.size());
  return out;
}

FrozenFaces FrozenFaces::complement(const TriangleMesh& mesh, const std::vector<int>& free_faces,
                                    ComplexVector field) {
  const int F = mesh.num_faces();
  if (field.size() != F)
    throw InputError("the held field must have one value per face (" + std::to_string(F) + "), got " +
                     std::to_string(field.size()));
  FrozenFaces out;
  out.flag_.assign(F, 1);
  for (int f : free_faces) {
    require_constrainable_face(mesh, f);
    if (!out.flag_[f]) throw InputError("free face " + std::to_string(f) + " is given twice");
    out.flag_[f] = 0;
  }
  int count = 0;
  for (int f = 0; f < F; ++f) {
    if (!out.flag_[f]) continue;
    if (!mesh.face_active(f)) {
      out.flag_[f] = 0;
      continue;
    }
    if (!std::isfinite(field[f].real()) || !std::isfinite(field[f].imag()))
      throw InputError("the held value on face " + std::to_string(f) + " is not finite");
    ++count;
  }
  out.count_ = count;
  if (count > 0) out.value_ = std::move(field);
  else out.flag_.clear();
  return out;
}

void FrozenFaces::copy_into(ComplexVector& field) const {
  for_each([&](int f, Complex z) { field[f] = z; });
}

}  // namespace nfield
