// The sparse linear system of an exact n-field spline (paper section 7, Algorithm 1 step 4; appendix B):
// which faces are unknowns, the matrix V over them, and how faces with given values enter the right-hand side.
//
// Every active face of the mesh is either
//   fixed     its value is given, so it is not an unknown: a frozen face of a local edit (paper section 9; the
//             value is copied bit-identically into the result) or an eliminated n-vector constraint u_f = d_f
//             (eq. 11 solved by substitution instead of two Lagrange rows), or
//   unknown   everything else (U).
// With V = E_m - lambda M the spline minimises z^H V z - 2 Re(z^H b) over z_U for given z_F, i.e. solves
//   V_UU z_U = b_U - V_UF z_F,     V_UF = (E_m)_UF   (M is diagonal).
// This header builds V_UU and V_UF. Constraint rows (direction, pinned, singularity) are not part of V: the
// solver adds them through the Schur complement (spline_solver.hpp), and a row's terms on fixed faces are
// known values that move to its right-hand side.
//
// Where to extend: assemble_spline_system() is the one place the matrix is assembled. Per-face weights W of the
// alignment term (guides, docs/guides.md) change the -lambda M diagonal into -lambda M_W = -lambda diag(A_f W_f);
// mirror symmetry restricts the solve to symmetric fields (spline_solver.hpp, mirror.hpp); cuts change E_m
// itself (the mesh is cut open, mesh_cuts.hpp).
//
// The shift. With lambda = 0 (an n-vector spline without alignment: eq. 8 without its alignment term) V = E_m,
// which is singular on a component whose connection has trivial holonomy (a flat or developable piece: its
// parallel field is in the kernel of E_m, whatever m). V_UU is still positive definite on every component that
// holds a fixed face: a parallel field vanishing at one face vanishes everywhere. A component without a fixed
// face gets V = E_m + shift M there (shift = kFreeComponentShift (4 pi/A)^m). The exact solver keeps this exact:
// it only leaves components without a fixed face when they receive no data (no alignment, no vector
// constraint), and the field of such a component is its smoothest field under its homogeneous constraints,
// which inverse iteration finds for any shift below the spectrum. With lambda < 0 nothing is shifted: V is
// positive definite on every mesh.
#pragma once
#include <vector>

#include "nfield/frozen_faces.hpp"
#include "nfield/operators.hpp"

namespace nfield {

/// shift / (4 pi / A)^m on components without a fixed face when lambda = 0 (see above).
constexpr double kFreeComponentShift = 1e-2;

struct SplineSystem {
  int order = 1;
  double lambda = 0;  ///< V = E_m - lambda M
  double shift = 0;   ///< added as shift * M on the shifted components (0 when none)

  std::vector<int> unknown_of_face;  ///< per mesh face: unknown index, -1 for inactive and fixed faces
  std::vector<int> face_of_unknown;
  /// The fixed faces the system refers to: the anchors (as given), then the frozen faces within the stencil of
  /// the unknowns (the columns of V_UF). A frozen face farther away does not enter the system at all, so a
  /// local solve costs its region, not the faces it holds.
  std::vector<int> fixed_faces;
  std::vector<int> fixed_of_face;    ///< per mesh face: index into fixed_faces, -1 otherwise
  std::vector<bool> shifted_component;  ///< per mesh component: V carries the shift there
  Eigen::VectorXd mass;              ///< A_f per unknown (length^2)
  ComplexSparse matrix;              ///< V_UU, both triangles stored, compressed
  ComplexSparse coupling;            ///< V_UF = (E_m)_UF, |U| x |F| (columns in the order of fixed_faces)

  int num_unknowns() const { return static_cast<int>(face_of_unknown.size()); }
};

/// Builds the system of order m (1..4) for V = E_m - lambda M_W with the given frozen faces and anchors (active,
/// distinct, not frozen; checked by the caller) and alignment weights W per face (empty: 1 everywhere; >= 0,
/// checked by the caller). Components without a fixed face are shifted when lambda == 0 (see above). No unknown
/// left (every face fixed) gives an empty system. When most faces are fixed (a local solve) only the rows of E_m
/// of the unknowns are formed (energy_rows.hpp), at a cost proportional to them.
SplineSystem assemble_spline_system(const FieldOperators& ops, int order, double lambda, const FrozenFaces& frozen,
                                    const std::vector<int>& anchors,
                                    const Eigen::VectorXd& weight = Eigen::VectorXd());

}  // namespace nfield
