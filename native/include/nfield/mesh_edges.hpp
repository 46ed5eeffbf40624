// Undirected edges of a TriangleMesh's active faces, with the faces around each edge.
//
// TriangleMesh keeps only the dual edges (interior manifold edges between two active faces). Guides need
// every edge: boundary edges and sharp edges are features, cuts name edges by their two vertices, and a
// feature edge's direction is read in the faces next to it. Edges are numbered in the order of their
// sorted vertex pairs (v0 < v1), so the numbering depends only on the mesh.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "nfield/mesh.hpp"

namespace nfield {

/// Edge table of the active faces of one mesh. Immutable value type.
class MeshEdges {
 public:
  explicit MeshEdges(const TriangleMesh& mesh);

  int num_edges() const { return static_cast<int>(vertices_.size()); }
  /// The two vertices of edge e, smaller index first.
  const std::array<int, 2>& vertices(int e) const { return vertices_[e]; }
  /// Active faces that contain edge e (1 on the boundary, 2 inside, more on a non-manifold edge).
  int num_faces(int e) const { return offsets_[e + 1] - offsets_[e]; }
  int face(int e, int k) const { return faces_[offsets_[e] + k]; }
  /// Edge between corners c and c+1 (mod 3) of face f (faces() order); -1 for inactive faces.
  int face_edge(int f, int c) const { return face_edges_[3 * f + c]; }
  /// Edge {a, b} (either order), or -1 if no active face has it.
  int find(int a, int b) const;
  bool is_boundary(int e) const { return num_faces(e) == 1; }
  /// Bend angle (radians, [0, pi]) between the normals of the two faces of a two-face edge: 0 where the
  /// surface is flat across the edge, pi/2 on the edge of a cube. -1 for other edges.
  double dihedral_angle(const TriangleMesh& mesh, int e) const;

 private:
  std::vector<std::array<int, 2>> vertices_;
  std::vector<std::uint64_t> keys_;  ///< sorted (v0 << 32 | v1), for find()
  std::vector<int> offsets_, faces_;
  std::vector<int> face_edges_;
};

/// InputError when `unknown` (vertex pairs that MeshEdges::find did not find) is not empty: "<count> <what>
/// edge(s) are not edges of the mesh's usable faces, e.g. (a, b) ..." (the first five).
void refuse_unknown_edges(const std::vector<std::array<int, 2>>& unknown, const std::string& what);

}  // namespace nfield
