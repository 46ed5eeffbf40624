// Rows of the m-harmonic energy matrix for a subset of the unknowns, and the change of the energy when only a
// subset of a field changed, at a cost proportional to the subset.
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

/// The columns `unknowns` (indices of unknowns, any order) of E_order as a num_unknowns x |unknowns| sparse
/// matrix (column j is unknown unknowns[j]; row indices sorted within each column). Equal to the corresponding
/// columns of energy_matrix(order) up to rounding (energy_matrix averages E and E^H; here the columns are taken as
/// computed). ParameterError for an order outside 1..4, InputError for an unknown out of range.
ComplexSparse energy_columns(const FieldOperators& ops, int order, const std::vector<int>& unknowns);

/// The rows `unknowns` of E_order as a |unknowns| x num_unknowns sparse matrix (row i is unknown unknowns[i]):
/// the adjoint of energy_columns (E is Hermitian). Same errors.
ComplexSparse energy_rows(const FieldOperators& ops, int order, const std::vector<int>& unknowns);

/// E_m(after) - E_m(before) (FieldOperators::energy) for two fields given per face that differ only on `faces`
/// (mesh faces; inactive ones are skipped). With d = after - before (zero elsewhere) and E_m Hermitian,
///   E(after) - E(before) = 2 Re(d^H E before) + d^H E d = Re(d^H (E before + E after)),
/// and both products are needed on `faces` only: each is evaluated there from the field on their m-ring, by m
/// alternating applications of S and M^-1 restricted to shrinking neighbourhoods. Equal to the difference of two
/// full energies up to rounding, at a cost proportional to the faces, not to the mesh (a live local solve).
/// ParameterError for an order outside 1..4, InputError for fields of another size or a face out of range.
double energy_change(const FieldOperators& ops, int order, const ComplexVector& before, const ComplexVector& after,
                     const std::vector<int>& faces);

}  // namespace nfield
