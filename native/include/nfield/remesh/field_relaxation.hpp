// Relaxation of a quad mesh towards the cross field: a global least-squares solve that moves the vertices
// in the tangent plane so that the edges run along the field, then the local steps of the earlier version.
//
// Each edge e = p_j - p_i is split, with the field direction q and normal n of the input at the point
// nearest its midpoint (t = n x q; the alignment of an edge is measured there), along the nearer of the axes
// q, t ("axis") and the other ("across"). With u_i the displacement of vertex i in the input's tangent plane
// at it (2 unknowns per vertex) and lengths in units of the median edge length s, the solve minimises
//   sum_e w_e [ (across . (e + u_j - u_i))^2 + 0.1 (axis . (u_j - u_i))^2 ] + 0.02 sum_i |u_i|^2,
//   w_e = 1 / max(|e|, 0.3)^2 * eps / sqrt(sin^2 a_e + eps^2), eps = 0.2, a_e the edge's angle to its axis:
// the first term is (up to the weight) the squared sine of that angle (what the alignment statistic
// measures), the second keeps each edge's extent along its axis (without it rows could slide together: a
// displacement varying only along the axis costs nothing across), the last keeps the system definite. The
// factor in a_e reweights the least squares towards the sum of |sin a|: an edge far off its axis (next to a
// cone, where no lattice follows the field) pulls its neighbours less than a nearly aligned one. The sparse
// SPD system (2 unknowns per vertex, about 10^4 at 5,000 faces) is solved at once (SimplicialLDLT), each move
// capped at s/2, the vertices projected back onto the input, the axes and weights taken again: up to 3
// outer iterations. Vertices of faces touching a feature vertex stay (next to a crease a move along the field
// can fold a face over it), as do the vertices of faces whose worst corner (scaled Jacobian against the
// input's normal, quad_untangle.hpp) is below 0.2 (they are the untangling step's) and of faces next to a
// flipped one (the untangling step moves those too, from where they were). Guarded: a vertex whose
// input normal turned by more than 30 degrees goes back; the vertices of a face whose worst corner falls below
// 0.2, or that leaves the input by more than 0.7 times the largest distance of any face before (or its own
// distance, if larger), take half their step, down to an eighth, then none.
//
// Then the local steps: with its neighbours fixed, the move of p_i minimising the squared off-axis parts of
// its edges is the mean of their off-axis parts; a Jacobi step moves every vertex a quarter of it, then back
// onto the input; feature vertices stay; the same corner guard (vertices back). They take what the solve left
// (the faces next to features, the reverted vertices). The centroid relaxation (quad_cleanup.hpp) evens the
// faces out but ignores the field; this one straightens the rows along it.
#pragma once
#include <vector>

#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/quad_extraction.hpp"

namespace nfield::remesh {

/// min(`iterations`, 3) outer iterations of the solve, then `iterations` local steps (0: nothing moves).
/// `surface_directions`: one tangent direction of the cross field per triangle of the projection surface (targets.surface's triangles, in order; zero: no field there, the vertex stays).
void relax_along_field(PolygonMesh& mesh, const std::vector<char>& feature_kind, const ProjectionTargets& targets,
                       const std::vector<Eigen::Vector3d>& surface_directions, int iterations);

/// The last pass, after the untangling and the far-point fit: min(`iterations`, 3) solve iterations and as
/// many local steps, the vertices marked in `fixed` (one entry per vertex) held where they are (the far-point
/// fit's moves keep their distance gain) while their neighbours re-align. Its local steps leave out the edges
/// more than `skip_degrees` off their axis (18 by default; 45 or more: none left out): next to an irregular
/// vertex no placement aligns every edge, and such an edge's share of the mean would bend the aligned edges
/// of the vertex it pulls; left out, it keeps its error alone (one edge in the 95th percentile instead of
/// several). If a face ends flipped that was not (nothing untangles after this pass), the pass is undone.
/// ParameterError if `fixed` does not have one entry per vertex.
void refine_along_field(PolygonMesh& mesh, const std::vector<char>& feature_kind, const ProjectionTargets& targets,
                        const std::vector<Eigen::Vector3d>& surface_directions, int iterations,
                        const std::vector<char>& fixed, double skip_degrees = 18.0);

/// The global solve alone, `iterations` outer iterations; the vertices marked in `fixed` (if given) stay.
void solve_along_field(PolygonMesh& mesh, const std::vector<char>& feature_kind, const ProjectionTargets& targets,
                       const std::vector<Eigen::Vector3d>& surface_directions, int iterations,
                       const std::vector<char>* fixed = nullptr);

/// The energy the solve lowers, without its weights: sum over the edges of sin^2 of each edge's angle to
/// the nearer field axis at its midpoint (edges where the field is zero left out). For tests and diagnostics.
double off_axis_energy(const PolygonMesh& mesh, const ProjectionTargets& targets,
                       const std::vector<Eigen::Vector3d>& surface_directions);

}  // namespace nfield::remesh
