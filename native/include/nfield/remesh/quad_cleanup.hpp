// Local clean-up of an extracted quad-dominant mesh: fewer triangles and irregular vertices, no folded
// faces. Every operation keeps the mesh manifold and consistently oriented (it only merges faces across
// an interior edge or re-splits the union of two faces).
//
//  - Doublets: an interior vertex with two edges lies between two faces that share both of its edges (and
//    on a smooth surface one of them has a reflex corner there); the vertex is removed and the two faces
//    become one, unless it is a feature corner (the tip of a wedge). Repeated, and once more after the
//    triangle steps (merging a triangle pair lowers two valences).
//  - Triangle pairs: two triangles sharing an edge become one quad when that quad is not folded
//    (scaled Jacobian above `min_jacobian`), best pairs first.
//  - Triangle + pentagon: their union (a hexagon) is re-split into two quads along a diagonal that does not
//    raise the irregularity sum |valence - 4| of the four vertices involved, if both quads are unfolded.
//  - Triangle strips: two triangles joined by a strip of k <= 8 quads (entering each quad by one edge and
//    leaving by the opposite one) form a polygon of 2k + 4 sides, re-split into k + 1 quads with the rungs
//    shifted by one. Two vertices at opposite ends lose an edge; done when that lowers their irregularity
//    (best first) and no quad folds (only then: the shifted rungs cut across the field, so every strip
//    costs some alignment). This glides a row end (triangle + valence-5 vertex)
//    along the strip onto an opposite one, and both disappear.
//  - Cones: a valence-6 vertex beside a triangle is split into two valence-4 vertices (split_cone_vertices);
//    two joined valence-3 vertices on a pentagon are merged into one of valence 4 (merge_cone_vertices).
//  - Large faces (6 sides or more, left where the extraction found no lattice point inside): a vertex at
//    the centroid, projected onto the input, is joined to every other corner, giving k/2 quads (and one
//    triangle for odd k). Flat large polygons deviate from a curved input by a good part of an edge length.
//  - Relaxation: each vertex moves half way towards the mean of the centroids of its faces, in its tangent
//    plane (the normal part of the move is dropped), then back onto the input (projection); corner vertices
//    stay, curve vertices slide along their feature.
#pragma once
#include <vector>

#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/quad_extraction.hpp"

namespace nfield::remesh {

struct CleanupReport {
  int doublets = 0, triangle_pairs = 0, triangle_pentagon_pairs = 0, triangle_strips = 0;
  int split_cones = 0;   ///< valence-6 vertices split beside a triangle (split_cone_vertices)
  int merged_cones = 0;  ///< pairs of valence-3 vertices merged (merge_cone_vertices)
  int lowered_irregularity = 0;  ///< edge rotations and diagonal collapses (lower_irregularity)
};

/// Topological clean-up (doublets, triangle pairs, triangle + pentagon). `feature_kind` is updated with
/// the vertex renumbering. Returns what was done.
CleanupReport clean_up_quads(PolygonMesh& mesh, std::vector<char>& feature_kind, double min_jacobian = 0.2);

/// The doublet step alone, for corners too where `vertices[v]` is set (the last resort for a flipped face
/// at a feature corner met by only two faces). Leaves the removed vertices unused. Returns the number removed.
int remove_doublets_at(PolygonMesh& mesh, const std::vector<char>& feature_kind, const std::vector<char>& vertices);

/// A cone of index -1/4 extracted as a valence-6 vertex with a triangle beside it (instead of a valence-5
/// vertex, or a pentagon around the cone) is split: the vertex becomes two joined by a new edge, each with
/// three of its edges (both valence 4), the new edge running through the triangle (which becomes a quad)
/// and the face opposite it (which gains a side: a pentagon, or a quad if it was a triangle). One
/// irregular vertex fewer, and no more non-quad faces. Only interior, non-feature vertices whose six faces
/// form one fan. `feature_kind` grows with the new vertices. Returns the number split.
int split_cone_vertices(PolygonMesh& mesh, std::vector<char>& feature_kind);

/// The opposite case, a cone of index +1/4 extracted as two joined valence-3 vertices with a pentagon
/// beside them: the edge between them is collapsed (the merged vertex has valence 4; the pentagon on the
/// edge becomes a quad, the other face a triangle, or a quad if it was a pentagon too). Only interior,
/// non-feature vertices without another common neighbour (the link condition). Returns the number merged.
int merge_cone_vertices(PolygonMesh& mesh, const std::vector<char>& feature_kind);

/// The triangle-strip step alone (see above); returns the number of strips re-split.
int pair_triangles_through_strips(PolygonMesh& mesh, double min_jacobian = 0.2, int max_quads = 8);

/// Splits faces with at least `min_size` sides (see above); returns the number split. feature_kind grows
/// with the new vertices (kNoFeature).
int split_large_faces(PolygonMesh& mesh, std::vector<char>& feature_kind, const ProjectionTargets& targets,
                      int min_size = 6);

/// `iterations` relaxation steps (see above), each followed by projection onto the input. `movable`
/// (optional, one per vertex): only these vertices move.
void relax_vertices(PolygonMesh& mesh, const std::vector<char>& feature_kind, const ProjectionTargets& targets,
                    int iterations, const std::vector<char>* movable = nullptr);

/// Minimum over the corners of the polygon (given by its vertex list) of (e1 x e2) . N / (|e1||e2|), with N
/// its Newell normal; 1 for a rectangle, <= 0 when folded.
double polygon_min_jacobian(const std::vector<Vec3>& positions, const std::vector<int>& polygon);
/// The same over the corners at vertices v without skip[v] (indices beyond `skip` count).
double polygon_min_jacobian(const std::vector<Vec3>& positions, const std::vector<int>& polygon,
                            const std::vector<char>& skip);

}  // namespace nfield::remesh
