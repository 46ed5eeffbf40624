// A lattice spacing that varies with the field's own turning (the conformal scale of a cross field), so
// that a field that turns without a singularity can be followed by lattice rows that do not end.
//
// On a flat region, a cross field of angle theta is the frame of a grid of spacing h e^u (rows of one
// family the level sets of a, of the other of b, with grad a = e^-u (cos theta, sin theta) / h and
// grad b = e^-u (-sin theta, cos theta) / h) only when both gradients are curl-free, which works out to
//     grad u = -J grad theta        (J v = n x v: the quarter turn about the normal),
// the Cauchy-Riemann equations of log(1/f') for a conformal map f. Example: theta = k x gives u = -k y,
// spacing shrinking towards +y where the rows curve round. On a curved surface theta is measured against
// a frame carried by the Levi-Civita connection: d theta becomes the field's rotation 1-form omega = d theta
// - A (per edge: the angle from q_i, carried into j's tangent plane by the smallest rotation, to the
// matching direction of j's cross), whose curl is the field's singularities minus the Gaussian curvature.
// As omega is in general not exactly closed, u is the least-squares solution
//     minimise sum over triangles t of area_t |grad u - X_t|^2,   X_t = -J g_t,
// g_t the constant vector of triangle t whose dot products with its three edges best match omega (exact
// when omega sums to zero round t): the Poisson problem K u = div X, K the cotangent stiffness matrix, one
// sparse Cholesky factorization, u fixed at one vertex per component. Around a singularity omega blows up
// (u has a logarithmic pole there); triangles within `cone_radius` lattice steps of a singular triangle
// take X = 0. The result is then shifted per component so that the area-weighted mean of e^-2u is 1 (the
// lattice keeps about the face count of spacing h: a face's area is h^2 e^2u) and clamped to
// [-log max_ratio, log max_ratio] (shift and clamp repeated, the clamp last), and rounded to steps of 2^-20
// (so that rounding-level differences of the input field do not reach the lattice's discrete choices).
#pragma once
#include <vector>

#include "nfield/remesh/lattice.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

struct LatticeSpacingOptions {
  double max_ratio = 1.6;    ///< the spacing stays within [h / max_ratio, h max_ratio], >= 1
  double cone_radius = 1.5;  ///< triangles this close (in lattice steps h) to a field singularity get X = 0
};

struct LatticeSpacingReport {
  double min_ratio = 1, max_ratio = 1;  ///< smallest and largest spacing / h
  double clamped_area = 0;              ///< fraction of the area where the clamp acted
  int singular_triangles = 0;           ///< triangles whose crosses turn by a non-zero index round them
  int added_vertices = 0;               ///< surface vertices added where the spacing is finer (quad_remesher.cpp)
  double seconds = 0;                   ///< the solve (not the refinement)
};

/// The log-scale u per surface vertex (lattice spacing h e^u) of the cross field `vertex_cross` (one unit
/// tangent direction per surface vertex, any of the four), as described above. `h` is the target spacing
/// (mesh units), used for the cone radius only. Zero everywhere when the solve fails (degenerate surface).
std::vector<double> conformal_log_scale(const RemeshSurface& surface, const std::vector<Vec3>& vertex_cross, double h,
                                        const LatticeSpacingOptions& options, LatticeSpacingReport* report = nullptr);

/// The rotation 1-form of the cross field on every surface edge (a, b), a < b: the angle (radians, in
/// [-pi/4, pi/4]) from q_a, carried into b's tangent plane by the smallest rotation taking n_a to n_b, to the
/// nearest direction of b's cross, counter-clockwise about n_b.
std::vector<double> field_rotation_form(const RemeshSurface& surface, const std::vector<Vec3>& vertex_cross);

}  // namespace nfield::remesh
