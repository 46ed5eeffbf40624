// Closest points on a triangle mesh: point-triangle distance and a bounding-volume hierarchy over the
// active faces, for projecting curve guides and brush strokes onto the surface.
#pragma once
#include <Eigen/Core>
#include <vector>

#include "nfield/mesh.hpp"

namespace nfield {

/// Closest point to p on the triangle (a, b, c) (Ericson, Real-Time Collision Detection, 5.1.5: Voronoi
/// regions of the vertices, edges and the interior).
Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                          const Eigen::Vector3d& c);

struct SurfacePoint {
  int face = -1;              ///< -1: the mesh has no active face
  Eigen::Vector3d point;      ///< closest point on that face
  double distance = 0;        ///< |query - point| (mesh units)
};

/// Axis-aligned bounding-box tree over the active faces (median splits, leaves of up to 4 faces).
/// Immutable; queries are const and thread-safe. Ties between faces at the same distance go to the
/// smaller face index, so results do not depend on the tree's layout.
class TriangleTree {
 public:
  explicit TriangleTree(const TriangleMesh& mesh);
  /// Closest point of the surface to p.
  SurfacePoint closest(const Eigen::Vector3d& p) const;

 private:
  struct Node {
    Eigen::Vector3d lo, hi;
    int first, count;  ///< leaf: faces order_[first, first + count); inner: count = 0, children first, first + 1
  };
  double box_distance2(const Node& node, const Eigen::Vector3d& p) const;
  const TriangleMesh& mesh_;
  std::vector<Node> nodes_;
  std::vector<int> order_;
};

}  // namespace nfield
