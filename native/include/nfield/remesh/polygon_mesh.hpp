// A polygon mesh (faces of any size) as flat arrays, with the combinatorial checks and repairs the quad
// remesher needs: manifoldness and orientation, splitting of pinched vertices, one step of quad
// subdivision, fan triangulation.
//
// Conventions: faces are lists of vertex indices, counter-clockwise around the outward normal. An edge is
// *manifold* when at most two faces use it and *consistently oriented* when two faces using it traverse it
// in opposite directions. A vertex is *manifold* when its faces form a single fan (a disc or half-disc).
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <unordered_map>
#include <utility>
#include <vector>

namespace nfield::remesh {

struct PolygonMesh {
  std::vector<Eigen::Vector3d> positions;
  std::vector<int> offsets{0};  ///< face f is indices[offsets[f] .. offsets[f+1])
  std::vector<int> indices;

  int num_vertices() const { return static_cast<int>(positions.size()); }
  int num_faces() const { return static_cast<int>(offsets.size()) - 1; }
  int face_size(int f) const { return offsets[f + 1] - offsets[f]; }
  const int* face(int f) const { return indices.data() + offsets[f]; }
  void add_face(const std::vector<int>& vertices) {
    indices.insert(indices.end(), vertices.begin(), vertices.end());
    offsets.push_back(static_cast<int>(indices.size()));
  }
  /// Throws InputError if an index is out of range, a face has fewer than 3 vertices or offsets are broken.
  void validate() const;
};

/// Combinatorial health of a polygon mesh.
struct ManifoldReport {
  int nonmanifold_edges = 0;       ///< edges used by more than two faces
  int inconsistent_edges = 0;      ///< edges traversed twice in the same direction (orientation flips)
  int nonmanifold_vertices = 0;    ///< vertices whose faces do not form one fan
  int faces_with_repeated_vertex = 0;
  int boundary_edges = 0;          ///< edges used by exactly one face
  int isolated_vertices = 0;       ///< vertices used by no face
  bool manifold() const { return nonmanifold_edges == 0 && nonmanifold_vertices == 0 && faces_with_repeated_vertex == 0; }
  bool oriented() const { return inconsistent_edges == 0; }
};

ManifoldReport check_manifold(const PolygonMesh& mesh);

/// Undirected edges (sorted vertex pairs), each once, in order of first appearance.
std::vector<std::array<int, 2>> unique_edges(const PolygonMesh& mesh);

/// Removes faces until every edge is used by at most two faces, in opposite directions, and no face
/// repeats a vertex. Faces are kept greedily in order (an earlier face wins). Returns the number removed.
int remove_conflicting_faces(PolygonMesh& mesh);

/// Gives every extra fan of a pinched vertex its own copy of the vertex (same position). Returns the
/// number of vertices added. After remove_conflicting_faces this makes the mesh manifold.
int split_pinched_vertices(PolygonMesh& mesh, std::vector<int>* copied_from = nullptr);

/// Merges the two ends of every edge shorter than min_length (mesh units) into one vertex (at the first
/// one's position): faces lose the repeated vertex, faces left with fewer than 3 are dropped, then
/// remove_conflicting_faces and split_pinched_vertices keep the mesh manifold and oriented. Vertices no
/// face uses are left in place. `merged_into` (optional) receives each vertex's surviving vertex. Returns
/// the number of vertices merged away.
int collapse_short_edges(PolygonMesh& mesh, double min_length, std::vector<int>* merged_into = nullptr);

/// Removes the faces of pieces (sets of faces joined through shared vertices) with fewer than `min_faces`
/// faces. Returns the number of faces removed.
int remove_small_pieces(PolygonMesh& mesh, int min_faces);

/// Removes vertices used by no face (renumbering); returns the old index of each kept vertex.
std::vector<int> compact_vertices(PolygonMesh& mesh);

/// One step of subdivision into quads: a vertex at each face centroid and edge midpoint, each k-gon
/// becomes k quads. The result has only quads; its edges are half as long.
/// kind_of_new_vertex (optional, one per output vertex): 0 original vertex, 1 edge midpoint, 2 face centre;
/// edge_of_new_vertex: for midpoints the (sorted) edge they split.
PolygonMesh subdivide_to_quads(const PolygonMesh& mesh, std::vector<int>* kind_of_new_vertex = nullptr,
                               std::vector<std::array<int, 2>>* edge_of_new_vertex = nullptr);

/// Fan triangulation of every face from its first vertex (triangles keep the face's orientation).
/// `triangle_face` (optional) receives the face of each triangle.
std::vector<std::array<int, 3>> fan_triangulate(const PolygonMesh& mesh, std::vector<int>* triangle_face = nullptr);

/// Key of the undirected edge {a, b} (the same for both directions).
inline long long undirected_edge_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<long long>(a) << 32) | static_cast<unsigned int>(b);
}

/// The faces as vertex lists, and back (empty lists are skipped).
std::vector<std::vector<int>> face_lists(const PolygonMesh& mesh);
void set_faces(PolygonMesh& mesh, const std::vector<std::vector<int>>& faces);

/// Union of faces a and b across their shared edge (u, v), where a contains u -> v and b contains v -> u:
/// a from v round to u, then b after u up to before v.
std::vector<int> merge_polygons_across(const std::vector<int>& a, const std::vector<int>& b, int u, int v);

/// Mean of the vertices of face f (mesh units).
Eigen::Vector3d polygon_centroid(const PolygonMesh& mesh, int f);

/// Unit normal of a polygon by Newell's formula (zero for a degenerate polygon); units: none.
Eigen::Vector3d polygon_normal(const PolygonMesh& mesh, int f);
/// The same for a polygon given by its vertex list.
Eigen::Vector3d polygon_normal(const std::vector<Eigen::Vector3d>& positions, const std::vector<int>& polygon);

/// For each directed edge a -> b of the faces (key (a << 32) | b), the face containing it.
std::unordered_map<long long, int> directed_face_map(const std::vector<std::vector<int>>& faces);

}  // namespace nfield::remesh
