// Closest-point queries on a set of triangles: a bounding-volume hierarchy of axis-aligned boxes.
//
// Used by the quad remesher (projecting output vertices back onto the input surface) and by the quality
// statistics (Hausdorff distance, field direction at an edge midpoint). Distances are in mesh units.
// Build: O(T log T), median split along the longest axis of the centroid box, leaves of <= 4 triangles.
// Query: depth-first, nearer child first, pruned by the squared distance to the boxes.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <limits>
#include <vector>

namespace nfield::remesh {

using Vec3 = Eigen::Vector3d;

/// The point of triangle (a, b, c) nearest to p (Ericson, Real-Time Collision Detection 5.1.5, by regions).
/// Degenerate triangles are handled (the result is on one of their edges).
Vec3 closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

/// The point of segment [a, b] nearest to p.
Vec3 closest_point_on_segment(const Vec3& p, const Vec3& a, const Vec3& b);

/// Barycentric coordinates of p (assumed in the plane of the triangle) in triangle (a, b, c); for a
/// degenerate triangle the weights of its nearest vertex.
Eigen::Vector3d barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

/// Normals of a triangle surface for TriangleTree::surface_normal: per triangle, per vertex (angle-weighted
/// mean of its triangles'), and per triangle edge (edge m joins corners m and m + 1: the normalised sum of
/// the normals of the one or two triangles on it).
struct SurfaceNormals {
  std::vector<Vec3> face, vertex;
  std::vector<std::array<Vec3, 3>> edge;
};
SurfaceNormals surface_normals(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles);

class TriangleTree {
 public:
  struct Hit {
    int triangle = -1;  ///< index into the triangles given to the constructor; -1 if the tree is empty
    Vec3 point = Vec3::Zero();
    double squared_distance = std::numeric_limits<double>::infinity();
  };

  TriangleTree() = default;
  TriangleTree(std::vector<Vec3> vertices, std::vector<std::array<int, 3>> triangles);

  /// The nearest point of all triangles to q.
  Hit closest(const Vec3& q) const;
  /// The unit normal of the surface at its point nearest to q: inside the nearest triangle its own normal;
  /// on one of its edges (a tie with the neighbour across) that edge's normal; at one of its vertices (a
  /// tie with all triangles there) the vertex normal. So the answer does not depend on how a tie is broken,
  /// and on a flat part it is the plane's normal. `normals` from surface_normals() of the same triangles.
  /// Zero if the tree is empty.
  Vec3 surface_normal(const Vec3& q, const SurfaceNormals& normals) const;
  /// The same normal at a point closest() returned.
  Vec3 normal_at(const Hit& hit, const SurfaceNormals& normals) const;
  bool empty() const { return triangles_.empty(); }
  const std::vector<Vec3>& vertices() const { return vertices_; }
  const std::vector<std::array<int, 3>>& triangles() const { return triangles_; }

 private:
  struct Node {
    Vec3 lo, hi;
    int left = -1, right = -1;  ///< children (inner node) or -1
    int begin = 0, end = 0;     ///< range of order_ (leaf)
  };
  int build(int begin, int end);
  std::vector<Vec3> vertices_;
  std::vector<std::array<int, 3>> triangles_;
  std::vector<int> order_;
  std::vector<Vec3> centroids_;
  std::vector<Node> nodes_;
};

}  // namespace nfield::remesh
