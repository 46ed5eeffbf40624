// Pure quads at full resolution: the few non-quads of a quad-dominant mesh turned into quads locally.
//
// A polygon mesh can be all quads only if its faces of odd size (triangles, pentagons) pair up: the sides of
// all faces add up to twice the edges, so on a closed piece there is an even number of them. Each odd face
// is joined to the nearest other odd face (or to the boundary) by a path of faces, found by Dijkstra's
// algorithm on the dual graph: a step costs 1, turning inside a quad (entering and leaving it by adjacent
// sides) 3 more, crossing a feature edge 2 more (20 out of or into the odd face: see below), leaving or
// entering a pentagon by a side whose midpoint leaves it no split without a flat corner 6 more (a pentagon
// with a straight corner is a quad with a T-junction: its half row goes on from that corner), and the
// cheapest path of all is made first. Along the path:
//
//  - every crossed edge gets a vertex at its midpoint (on a feature edge, a curve vertex), except the first
//    and the last one: there the odd face is merged with its neighbour on the path (unless that edge is a
//    feature or the union would revisit a vertex; then it gets a midpoint too, a flat corner the
//    relaxation opens unless it must stay on the feature; the choice at each end is the one adding the
//    fewest irregular vertices among those without such a corner);
//  - a path ending at the boundary puts a midpoint on the boundary edge (a regular boundary vertex);
//  - each face along the path then has an even number of sides and is split into quads: a quad crossed
//    straight through becomes two quads (a new edge between the midpoints, parallel to its sides: the half
//    row keeps the field's direction), a polygon of 6 sides (a triangle and a quad merged, with a midpoint;
//    a quad turned in) splits along the diagonal with the best worst corner, or around a centre vertex into
//    3 quads when every diagonal leaves a flat or folded corner; larger polygons shed quads one at a time.
//
// So an odd pair becomes a half-width row of quads between them: the output stays at the target edge length
// (one subdivision step of a lattice twice as coarse, the other route to pure quads, is 1.5-3x further from
// the input at the same face count). Positions of new vertices are plain midpoints and centroids; the caller
// projects them onto the input and relaxes.
#pragma once
#include <vector>

#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/quad_extraction.hpp"

namespace nfield::remesh {

struct PureQuadReport {
  int odd_faces = 0;       ///< faces of odd size before
  int paths = 0;           ///< odd faces paired with another (or with the boundary)
  int boundary_paths = 0;  ///< of which ending at the boundary
  int merged_ends = 0;     ///< path ends where the odd face was merged with its neighbour
  int midpoints = 0;       ///< vertices added at edge midpoints
  int centres = 0;         ///< vertices added inside faces
  int unpaired = 0;        ///< odd faces left (no other odd face or boundary reachable: cannot happen on a mesh)
  int rounds = 0;          ///< extra rounds (set by the remesher: faces still flipped were split and paired again)
  // Set by the remesher (QuadRemeshOptions::pure_quad_cones):
  int pinned_cones = 0;            ///< cones pinned to a lattice point in the output kept (0: cones left free)
  int cones_tried = 0;             ///< cones pinned in the pinned candidate (both tried; else 0)
  int irregular_free_cones = -1;   ///< irregular vertices of the candidate with free cones (-1: not made)
  int irregular_pinned_cones = -1; ///< and with pinned cones
};

/// Turns `mesh` into quads as above. `feature_kind` grows with the new vertices (kCurve for midpoints of
/// feature edges, found as edges between two feature vertices whose midpoint is within a quarter of their
/// length of a feature edge of `targets`). New vertices are appended after the old ones.
PureQuadReport convert_to_pure_quads(PolygonMesh& mesh, std::vector<char>& feature_kind, const ProjectionTargets& targets);

/// Splits an even polygon (vertex indices into `positions`) into quads as above; may append one centre
/// vertex to `positions` (then returns true in *added_centre). Polygons of 4 come back as they are.
/// `valence` (optional; vertices beyond it are new midpoints): among splits without a flat or folded
/// corner (worst scaled Jacobian >= 0.15), the one whose new edges raise the fewest vertices above
/// valence 4 (interior count) wins.
std::vector<std::vector<int>> split_even_polygon(std::vector<Eigen::Vector3d>& positions, const std::vector<int>& polygon,
                                                 bool* added_centre = nullptr, const std::vector<int>* valence = nullptr);

}  // namespace nfield::remesh
