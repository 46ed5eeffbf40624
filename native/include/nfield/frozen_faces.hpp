// Faces whose values a solve holds fixed: the frozen faces of a region edit, the faces of committed layers, and
// everything outside the region of a live guide edit (paper section 9, local editing).
//
// Stored per mesh face, a flag and a value, so that asking whether a face is held costs one array read and
// holding nearly the whole mesh around a small region costs one pass over the faces (a few hundred microseconds
// on 86k faces), not a lookup structure built face by face. Two ways to say which faces are held:
//   listed      (face, value) pairs: a region edit's frozen complement, the faces of committed layers;
//   complement  every active face except the given free faces, at the values of a whole field: a live edit's
//               region around the changed faces, the rest held at the last solve.
// Only the held faces within the energy's stencil of the free ones enter the system (spline_system.hpp): the
// others matter only through the values the result copies.
#pragma once
#include <utility>
#include <vector>

#include "nfield/mesh.hpp"
#include "nfield/operators.hpp"

namespace nfield {

class FrozenFaces {
 public:
  FrozenFaces() = default;  ///< nothing held

  /// The listed faces at their values. ConstraintError for a face out of range or inactive, InputError for a
  /// non-finite value or a face listed twice.
  static FrozenFaces listed(const TriangleMesh& mesh, const std::vector<std::pair<int, Complex>>& pairs);
  /// Every active face except `free_faces`, at its value in `field` (one per face). ConstraintError for a free
  /// face out of range or inactive, InputError for a repeated free face, a field of another size or a
  /// non-finite value on a held face.
  static FrozenFaces complement(const TriangleMesh& mesh, const std::vector<int>& free_faces, ComplexVector field);

  bool empty() const { return count_ == 0; }
  int count() const { return count_; }
  bool held(int face) const { return count_ > 0 && flag_[face] != 0; }
  /// The value of a held face (unspecified for other faces).
  Complex value(int face) const { return value_[face]; }
  /// Writes the value of every held face into `field` (one per face), bit-identically.
  void copy_into(ComplexVector& field) const;
  /// Calls visit(face, value) for every held face, in face order.
  template <class Visit>
  void for_each(Visit&& visit) const {
    if (count_ == 0) return;
    for (int f = 0; f < static_cast<int>(flag_.size()); ++f)
      if (flag_[f]) visit(f, value_[f]);
  }

 private:
  std::vector<char> flag_;  ///< per face, empty when nothing is held
  ComplexVector value_;     ///< per face (meaningful where flag_ is set)
  int count_ = 0;
};

}  // namespace nfield
