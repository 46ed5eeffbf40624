// Relaxation of a quad mesh towards the cross field: each vertex moves so that its edges run along the
// field.
//
// Each edge e = p_j - p_i is split, with the field direction q and normal n of the input at the point
// nearest its midpoint (t = n x q; the alignment of an edge is measured there), into its part along the
// nearer of the axes q, t (the edge as the field would have it: the same length along its axis) and the
// rest, its off-axis part o. Moving p_i by o (or p_j by -o) would align the edge; with its neighbours fixed,
// the move of p_i minimising the squared off-axis parts of all its edges is the mean of their o. Both ends
// move, so a Jacobi step moves every vertex a quarter of that mean, then back onto the input (the
// projection drops the normal part); feature vertices stay (their edges follow the feature, which the field may cross).
// Guarded: the vertices of faces whose worst corner (scaled Jacobian against the input's normal,
// quad_untangle.hpp) is below 0.2 stay (they are the untangling step's), and a face whose worst corner
// falls below 0.2 gets its vertices back. The centroid relaxation (quad_cleanup.hpp) evens the faces out but
// ignores the field; this one straightens the rows along it.
#pragma once
#include <vector>

#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/quad_extraction.hpp"

namespace nfield::remesh {

/// `iterations` steps as above. `surface_directions`: one tangent direction of the cross field per triangle
/// of the projection surface (targets.surface's triangles, in order; zero: no field there, the vertex stays).
void relax_along_field(PolygonMesh& mesh, const std::vector<char>& feature_kind, const ProjectionTargets& targets,
                       const std::vector<Eigen::Vector3d>& surface_directions, int iterations);

}  // namespace nfield::remesh
