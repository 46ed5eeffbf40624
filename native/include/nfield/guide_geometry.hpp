// What guide authoring needs to know about one mesh, built once and shared: the face frames, the edge table
// (features, cuts) and the closest-point tree (curves, comb strokes). Immutable after construction, so one
// instance serves many guide edits (moving a curve re-projects it; nothing here is rebuilt).
#pragma once
#include <algorithm>
#include <cmath>
#include <memory>

#include "nfield/closest_point.hpp"
#include "nfield/mesh_edges.hpp"
#include "nfield/tangent_frames.hpp"

namespace nfield {

class GuideGeometry {
 public:
  explicit GuideGeometry(std::shared_ptr<const TriangleMesh> mesh)
      : mesh_(std::move(mesh)), frames_(*mesh_), edges_(*mesh_), tree_(*mesh_) {}

  const TriangleMesh& mesh() const { return *mesh_; }
  std::shared_ptr<const TriangleMesh> mesh_ptr() const { return mesh_; }
  const TangentFrames& frames() const { return frames_; }
  const MeshEdges& edges() const { return edges_; }
  const TriangleTree& tree() const { return tree_; }
  /// Edge length of an equilateral triangle of the mean face area (mesh units): the default sample spacing
  /// of curves is half of it.
  double typical_edge_length() const {
    return std::sqrt(4.0 / std::sqrt(3.0) * mesh_->total_area() / std::max(1, mesh_->num_active_faces()));
  }

 private:
  std::shared_ptr<const TriangleMesh> mesh_;
  TangentFrames frames_;
  MeshEdges edges_;
  TriangleTree tree_;  // holds a reference to *mesh_, which this object keeps alive
};

}  // namespace nfield
