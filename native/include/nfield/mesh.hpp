// Triangle mesh connectivity with validation and cleaning for field design.
//
// Real meshes are dirty. TriangleMesh takes raw arrays, rejects what cannot be interpreted (NaN/inf
// coordinates, out-of-range indices, empty input: InputError with a message naming the problem) and
// handles the rest, listing it in a MeshReport:
//  - unused vertices: ignored;
//  - degenerate faces (a repeated vertex index, area <= 1e-14 * bbox_diagonal^2, or a needle whose height
//    is below 1e-7 times its longest edge): *excluded* from the field. They get no unknown; their field
//    value is the zero vector; edges next to them act as boundary;
//  - sliver faces (smallest angle below 1 degree but not degenerate): kept, listed;
//  - non-manifold edges (more than two active faces): cuts (no coupling across them);
//  - inconsistently oriented neighbours: each connected component is re-oriented internally by a
//    breadth-first walk (the majority orientation of the component wins); flipped faces are listed.
//    An edge across which orientation cannot be made consistent (non-orientable component, e.g. a Moebius
//    strip) becomes a cut. 3D directions are unaffected by a face's orientation, so output is meaningful.
//  - boundaries and several connected components: listed.
//
// Conventions: faces() returns the faces with their internal (consistent) orientation. A face's normal
// follows the right-hand rule on that winding. "Counter-clockwise" around a vertex means positively
// around the normal.
#pragma once
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace nfield {

using Positions = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Triangles = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

/// What TriangleMesh found and did while ingesting the input. Indices refer to the input arrays.
struct MeshReport {
  int num_input_vertices = 0;
  int num_input_faces = 0;
  std::vector<int> unused_vertices;              ///< referenced by no face
  std::vector<int> degenerate_faces;             ///< excluded from the field (zero vector)
  std::vector<int> sliver_faces;                 ///< kept; smallest angle < 1 degree
  std::vector<int> duplicate_faces;              ///< same vertex set as an earlier face; excluded like degenerate faces
  std::vector<std::array<int, 2>> nonmanifold_edges;  ///< vertex pairs (sorted) of edges with > 2 active faces: cuts
  std::vector<int> nonmanifold_vertices;         ///< faces around it do not form one fan; no singularity index
  std::vector<int> flipped_faces;                ///< re-oriented internally to agree with their component
  int num_orientation_cuts = 0;                  ///< edges cut because the component is non-orientable
  int num_boundary_edges = 0;                    ///< edges with exactly one active face (incl. next to excluded faces)
  int num_boundary_loops = 0;                    ///< closed chains of boundary edges
  int num_components = 0;                        ///< connected components of active faces through dual edges
  int euler_characteristic = 0;                  ///< V - E + F over active faces and the vertices/edges they use
  /// Human-readable one-line summaries of each non-empty item above (for CLI and UI).
  std::vector<std::string> summary() const;
};

/// An interior, manifold, consistently oriented edge shared by two active faces: an edge of the dual graph.
struct DualEdge {
  int face0, face1;  ///< face indices (input numbering)
  int vertex0, vertex1;  ///< shared edge, directed as it appears in face0 (face1 contains vertex1 -> vertex0)
};

/// Validated, cleaned, consistently oriented triangle mesh. Immutable value type.
class TriangleMesh {
 public:
  /// Throws InputError for empty input, NaN/inf coordinates, or vertex indices out of [0, V).
  TriangleMesh(const Positions& positions, const Triangles& faces);

  int num_vertices() const { return static_cast<int>(positions_.rows()); }
  int num_faces() const { return static_cast<int>(faces_.rows()); }
  const Positions& positions() const { return positions_; }
  /// Faces with internal orientation (flipped faces have two indices swapped relative to the input).
  const Triangles& faces() const { return faces_; }

  /// False for degenerate/duplicate faces, which are excluded from the field.
  bool face_active(int f) const { return face_active_[f]; }
  int num_active_faces() const { return num_active_faces_; }
  /// Unit normal (zero vector for inactive faces), area (0 for inactive faces).
  const Eigen::Vector3d& face_normal(int f) const { return normals_[f]; }
  double face_area(int f) const { return areas_[f]; }
  double total_area() const { return total_area_; }
  double bounding_box_diagonal() const { return bbox_diagonal_; }

  const std::vector<DualEdge>& dual_edges() const { return dual_edges_; }
  /// Indices into dual_edges() of the (up to 3) dual edges at face f.
  const std::vector<int>& face_dual_edges(int f) const { return face_dual_edges_[f]; }
  /// The faces across those dual edges, in the same order, -1 after the last: one contiguous array that walks
  /// over the dual graph read instead of the edge lists (no pointer chase per face).
  const std::array<int, 3>& face_neighbors(int f) const { return face_neighbors_[f]; }
  /// Connected component (0..num_components-1) of each active face through dual edges; -1 for inactive.
  const std::vector<int>& face_component() const { return face_component_; }

  /// True if v is an interior manifold vertex whose faces are all active and form one closed fan
  /// linked by dual edges. Only such vertices carry a singularity index.
  bool vertex_is_interior(int v) const { return !vertex_ring_faces_[v].empty(); }
  /// The closed fan around an interior vertex, counter-clockwise; empty for other vertices.
  /// ring_faces[j] and ring_faces[(j+1)%k] share the dual edge ring_dual_edges[j].
  const std::vector<int>& vertex_ring_faces(int v) const { return vertex_ring_faces_[v]; }
  const std::vector<int>& vertex_ring_dual_edges(int v) const { return vertex_ring_dual_edges_[v]; }
  /// All active faces incident to v (any vertex), unordered.
  const std::vector<int>& vertex_faces(int v) const { return vertex_faces_[v]; }
  /// Angle defect 2*pi - sum of corner angles at an interior vertex (radians); 0 for other vertices.
  double angle_defect(int v) const { return angle_defect_[v]; }
  /// Interior angle (radians) of face f at its corner c (0,1,2 in faces() order).
  double corner_angle(int f, int c) const;

  const MeshReport& report() const { return report_; }
  /// A 64-bit content hash of positions and faces (for caches keyed by mesh content).
  std::uint64_t content_hash() const { return hash_; }

 private:
  Positions positions_;
  Triangles faces_;
  std::vector<bool> face_active_;
  int num_active_faces_ = 0;
  std::vector<Eigen::Vector3d> normals_;
  std::vector<double> areas_;
  double total_area_ = 0, bbox_diagonal_ = 0;
  std::vector<DualEdge> dual_edges_;
  std::vector<std::vector<int>> face_dual_edges_;
  std::vector<std::array<int, 3>> face_neighbors_;
  std::vector<int> face_component_;
  std::vector<std::vector<int>> vertex_ring_faces_, vertex_ring_dual_edges_, vertex_faces_;
  std::vector<double> angle_defect_;
  MeshReport report_;
  std::uint64_t hash_ = 0;
};

}  // namespace nfield
