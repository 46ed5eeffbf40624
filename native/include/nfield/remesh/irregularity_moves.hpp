// Local moves that lower the number of irregular vertices of a quad-dominant mesh (the quad remesher's
// clean-up, after the relaxation): edge rotations between two quads and diagonal collapses of a quad,
// guarded against folds, bent faces and changes at feature vertices.
#pragma once
#include <vector>

#include "nfield/remesh/polygon_mesh.hpp"

namespace nfield::remesh {

/// Cones extracted as a cluster of irregular vertices (a valence-7 vertex beside three valence-3 ones, a
/// 6 beside a 3 and a 5 ...): greedy local moves that lower the number of interior vertices of valence != 4
/// (the quad_stats measure), ties broken by a lower sum of |valence - 4|, so every move lowers a
/// lexicographic potential and the loop ends. Two moves, on quads only and on interior vertices off the
/// feature curves (a feature vertex's valence never changes): the rotation of an edge between two quads
/// (their hexagon re-split along another diagonal) and the collapse of a quad's diagonal (its two ends merge
/// at their midpoint; only when they share no neighbour but the quad's other two corners, so the mesh stays
/// a manifold, and those keep valence >= 3). A move is made only when every face it makes keeps its worst
/// scaled corner above `min_jacobian` and is no more bent than the faces it replaces (or bent by less than
/// about 25 degrees at a corner: next to a crease a rotated edge could join its two sides); moves are applied best first, disjoint, for up to `max_rounds`
/// rounds. `changed` (optional) receives one flag per vertex: a vertex of a face the moves made. Merged-away
/// vertices are left unused. Returns the number of moves.
int lower_irregularity(PolygonMesh& mesh, const std::vector<char>& feature_kind, double min_jacobian = 0.2,
                       int max_rounds = 8, std::vector<char>* changed = nullptr);

}  // namespace nfield::remesh
