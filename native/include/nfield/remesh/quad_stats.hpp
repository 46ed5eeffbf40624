// Quality statistics of a quad (or quad-dominant) mesh against the surface and field it was made from.
//
// All functions work on any polygon mesh, so the same numbers are computed for our remesher and for its
// peers. Angles in degrees, distances in mesh units.
//  - Valence: an interior vertex is regular with 4 edges. A boundary vertex is regular with
//    1 + round(theta / 90 deg) edges, theta the sum of its corner angles (3 on a straight boundary,
//    2 at a 90 degree corner, 4 at a 270 degree corner).
//  - Scaled Jacobian of a corner p with edges e1 (to the next vertex) and e2 (to the previous one):
//    (e1 x e2) . N / (|e1| |e2|), N the unit reference normal of that corner: the input's normal at its
//    point nearest to p + (e1 + e2) / 20 (just inside the corner's own wedge: a corner on a crease sees the
//    side its face lies on, and on a part thinner than a face the point is still on the corner's own side;
//    TriangleTree::surface_normal: the nearest triangle's normal, or on a tie between triangles the normal of
//    their common edge or vertex); or the face's own Newell normal without a reference. 1 for a right angle,
//    <= 0 for a folded or flipped corner. A face's value is the minimum over its corners; a face with a
//    value <= 0 is *flipped* (inverted, as a finite element with a non-positive Jacobian at a corner is):
//    it is turned against the surface, folded over, or a dart with a reflex corner. Triangles are scaled
//    by 2 / sqrt(3) so that the equilateral triangle scores 1.
//  - Edge alignment: the angle between an output edge and the nearest of the 4 directions of the cross
//    field at the input point nearest to the edge midpoint, after projecting the edge onto that input
//    triangle's plane; in [0, 45].
//  - One-sided distance from a mesh A to a surface B: the largest distance to B over samples of A (its
//    vertices, edge midpoints, face centroids and the midpoints of the centroid-to-vertex segments).
//    The symmetric Hausdorff distance is the larger of the two one-sided distances.
#pragma once
#include <array>
#include <vector>

#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/triangle_tree.hpp"

namespace nfield::remesh {

struct FaceCounts {
  int quads = 0, triangles = 0, other = 0;
  double quad_fraction() const {
    const int total = quads + triangles + other;
    return total ? static_cast<double>(quads) / total : 0.0;
  }
};
FaceCounts count_faces(const PolygonMesh& mesh);

/// Vertex valence (number of distinct edges) and whether it lies on the boundary.
struct VertexValence {
  std::vector<int> valence;
  std::vector<char> boundary;
};
VertexValence vertex_valences(const PolygonMesh& mesh);

/// Irregular vertices (see the header comment), split into interior and boundary ones.
struct IrregularVertices {
  std::vector<int> interior, boundary;
};
IrregularVertices irregular_vertices(const PolygonMesh& mesh);

/// A triangulated reference surface with one unit normal and one cross-field direction per triangle
/// (the direction may be zero: then alignment is not measured there).
struct ReferenceSurface {
  TriangleTree tree;
  SurfaceNormals normals;
  std::vector<Vec3> directions;
};
ReferenceSurface make_reference(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                                const std::vector<Vec3>& directions);

/// Scaled Jacobian of the corner at p (next, prev: its neighbours along the face) against the surface
/// normal of `tree` at p + (e1 + e2) / 20 (TriangleTree::surface_normal), or against own_normal when tree
/// is null; `triangle` applies the 2 / sqrt(3) scale.
double corner_scaled_jacobian(const Vec3& p, const Vec3& next, const Vec3& prev, const TriangleTree* tree,
                              const SurfaceNormals* normals, const Vec3& own_normal, bool triangle);

/// Minimum scaled Jacobian per face (reference may be null: then the face's Newell normal is used).
std::vector<double> scaled_jacobians(const PolygonMesh& mesh, const ReferenceSurface* reference);

/// Edge alignment angle (degrees) per unique edge (order of unique_edges); NaN where the field is zero.
std::vector<double> edge_alignment_degrees(const PolygonMesh& mesh, const ReferenceSurface& reference);

/// The points of face f, besides its corners, where the distance statistics sample a polygon: the centroid,
/// then for each corner i the midpoint of edge (i, i+1) and the point half way from corner i to the centroid.
std::vector<Vec3> face_distance_samples(const PolygonMesh& mesh, int f);

/// Largest distance from samples of `mesh` to the surface of `tree`.
double one_sided_distance(const PolygonMesh& mesh, const TriangleTree& tree);

/// Symmetric Hausdorff distance between the polygon mesh and the reference triangles (mesh units).
double hausdorff_distance(const PolygonMesh& mesh, const ReferenceSurface& reference);

}  // namespace nfield::remesh
