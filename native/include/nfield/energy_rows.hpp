// Rows of the m-harmonic energy matrix for a subset of the unknowns, at a cost proportional to the subset.
//
// A local solve (frozen faces: region edits, layers, live guide edits) needs only the rows of
// E_m = S (M^-1 S)^(m-1) that belong to its free unknowns U: the block E_UU it factors and the block E_UF that
// moves the frozen values to the right-hand side. Forming the whole product costs as much as the global
// problem (0.2-0.5 s for m = 2 on 70k faces); the rows alone cost as much as |U| rows. E_m is Hermitian, so
// its rows are the adjoint of its columns, and the columns are products taken from the right,
// E_{:,U} = S M^-1 S ... M^-1 S_{:,U}, in which every factor only touches the stencil of U.
#pragma once
#include <vector>

#include "nfield/operators.hpp"

namespace nfield {

/// The rows `unknowns` (indices of unknowns, any order) of E_order as a |unknowns| x num_unknowns sparse
/// matrix (row i is unknown unknowns[i]). Equal to the corresponding rows of energy_matrix(order) up to
/// rounding (energy_matrix averages E and E^H; here the rows are taken as computed). ParameterError for an
/// order outside 1..4, InputError for an unknown out of range.
ComplexSparse energy_rows(const FieldOperators& ops, int order, const std::vector<int>& unknowns);

}  // namespace nfield
