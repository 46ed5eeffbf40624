// The surface the quad remesher works on: the input cut into a clean, consistently oriented manifold,
// its feature curves, and the cross field moved from faces to vertices.
//
// Cutting (as the field solver does): only active faces are kept, and two faces are neighbours only across
// a dual edge of TriangleMesh (interior, manifold, consistently oriented). Every vertex is split into one
// copy per fan of faces linked by dual edges, so non-manifold edges and vertices and orientation cuts
// become boundaries. Each connected component is remeshed on its own.
//
// Features: boundary edges and edges whose dihedral angle (angle between the two face normals) exceeds a
// threshold. Chains of feature edges shorter than a given length are dropped (tiny holes left by
// degenerate faces, noise creases), and so are sharp edges the cross field crosses diagonally
// (keep_features_along_field). A feature vertex with two feature edges turning by less than 45 degrees, or
// at the end of a chain, is a *curve* vertex (unit tangent along the chain), any other feature vertex (a
// junction or a sharp turn) is a *corner*.
//
// Vertex cross field: each vertex takes the corner-angle weighted n-symmetric mean (4th powers) of the
// directions of its faces, each rotated into the vertex tangent plane by the smallest rotation taking the
// face normal to the vertex normal. Around a singular vertex of the face field these 4th powers cancel, so
// the singularity moves into one of the vertex's own faces: the singularities stay where we designed them,
// within one ring. On curve vertices the cross is turned to contain the feature tangent.
#pragma once
#include <array>
#include <vector>

#include "nfield/mesh.hpp"
#include "nfield/remesh/triangle_tree.hpp"

namespace nfield::remesh {

struct RemeshSurface {
  std::vector<Vec3> positions;                 ///< cut vertices
  std::vector<int> source_vertex;              ///< input vertex of each cut vertex
  std::vector<std::array<int, 3>> triangles;   ///< consistently oriented, over cut vertices
  std::vector<int> source_triangle;            ///< input face of each triangle
  std::vector<Vec3> face_normals;
  std::vector<double> face_areas;
  std::vector<Vec3> vertex_normals;            ///< corner-angle weighted mean of face normals
  std::vector<double> vertex_areas;            ///< one third of the incident face areas (length^2)
  std::vector<std::array<int, 2>> edges;       ///< unique undirected edges (a < b)
  std::vector<std::array<int, 2>> edge_faces;  ///< the one or two triangles of each edge (-1: boundary)
  std::vector<int> adjacency_offsets, adjacency;  ///< vertex -> neighbouring vertices (CSR)
  std::vector<int> adjacency_edge;             ///< edge index of each adjacency entry
  std::vector<int> vertex_component;
  int num_components = 0;
  std::vector<double> component_area;
  std::vector<double> component_diagonal;      ///< bounding-box diagonal of each component
  std::vector<int> component_triangles;        ///< triangle count of each component

  int num_vertices() const { return static_cast<int>(positions.size()); }
};

/// Builds the cut surface from the active faces of `mesh`. InputError if no face is active.
RemeshSurface make_remesh_surface(const TriangleMesh& mesh);

/// Splits edges longer than max_length at their midpoints until none is left (each pass splits every
/// long edge once; a triangle with 1, 2 or 3 long edges becomes 2, 3 or 4 triangles, so neighbours stay
/// conforming). New vertices have source_vertex -1; new triangles keep their source_triangle (and so the
/// field direction of the input face they lie in). The position field needs edges shorter than about
/// half the lattice spacing, otherwise neighbouring lattice points are missed by every edge.
void refine_long_edges(RemeshSurface& surface, double max_length);

/// The same with a limit per vertex: an edge is long when longer than the mean of its ends' limits, and a
/// midpoint gets that mean (appended to `max_length`, which follows the vertices).
void refine_long_edges(RemeshSurface& surface, std::vector<double>& max_length);

/// Recomputes everything derived from positions and triangles (normals, areas, edges, adjacency,
/// components).
void finalize_surface(RemeshSurface& surface);

enum FeatureKind : char { kNoFeature = 0, kCurve = 1, kCorner = 2 };

struct Features {
  std::vector<char> edge_is_feature;
  std::vector<char> vertex_kind;     ///< FeatureKind per vertex
  std::vector<Vec3> vertex_tangent;  ///< unit tangent at curve vertices
  int num_boundary_edges = 0, num_sharp_edges = 0;
  int num_dropped_chains = 0;  ///< feature chains shorter than min_chain_length, not kept
};

/// sharp_angle_degrees <= 0 disables sharp edges; keep_boundary false ignores boundaries.
Features detect_features(const RemeshSurface& surface, bool keep_boundary, double sharp_angle_degrees,
                         double min_chain_length);

/// From the marked feature edges of `features`: drops chains shorter than min_chain_length, counts the
/// edges and sets the vertex kinds and tangents.
void finish_features(const RemeshSurface& surface, Features& features, double min_chain_length);

/// Keeps a sharp (non-boundary) feature edge only where the cross field runs along it: within
/// max_angle_degrees of one of the four cross directions on both its faces (triangle_directions: one
/// tangent direction per triangle, zero: no field). A crease the field crosses diagonally cannot be a lattice line without bending the field
/// there, which costs alignment and adds a pair of singularities where the angle passes 45 degrees.
/// Returns the number of edges no longer kept (the chains are then finished again).
int keep_features_along_field(const RemeshSurface& surface, Features& features, const std::vector<Vec3>& triangle_directions,
                              double max_angle_degrees, double min_chain_length);

/// Unit cross-field direction (one of the four) per vertex from one tangent direction per triangle
/// (zero: no field there). Vertices without any field get the direction of their first edge.
/// `features` may be null. num_undefined (optional) counts vertices without field.
std::vector<Vec3> vertex_cross_field(const RemeshSurface& surface, const std::vector<Vec3>& triangle_directions,
                                     const Features* features, int* num_undefined = nullptr);

/// Rotates tangent vector d of the plane with unit normal `from` into the plane with unit normal `to`
/// by the smallest rotation taking `from` to `to`.
Vec3 rotate_between_planes(const Vec3& d, const Vec3& from, const Vec3& to);

}  // namespace nfield::remesh
