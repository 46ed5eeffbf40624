#include "nfield/constraints.hpp"

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

}  // namespace nfield
