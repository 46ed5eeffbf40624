// Neighbourhoods of faces for guides: edge rings around seed faces and brush balls around a surface point.
// Both walk the dual graph (faces sharing an interior manifold edge), so a neighbourhood never jumps across
// a gap in the surface that happens to be narrow in space.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <vector>

#include "nfield/closest_point.hpp"
#include "nfield/mesh.hpp"

namespace nfield {

/// Breadth-first walks over the faces; one instance is reused for many small walks (visit marks are
/// stamps, so a walk costs only the faces it reaches).
class FaceWalker {
 public:
  explicit FaceWalker(const TriangleMesh& mesh) : mesh_(mesh), stamp_(mesh.num_faces(), 0) {}

  /// visit(face, ring) for every face within `rings` dual steps of the seeds; the seeds are ring 1. With `limit`,
  /// the walk ends with the first ring that brings the count of visited faces past it (that ring complete).
  template <class Visit>
  void rings(const std::vector<int>& seeds, int rings, Visit&& visit,
             std::size_t limit = std::numeric_limits<std::size_t>::max()) {
    next_stamp();
    queue_.clear();
    ring_.clear();
    for (int f : seeds)
      if (f >= 0 && mesh_.face_active(f) && mark(f)) queue_.push_back(f), ring_.push_back(1);
    for (std::size_t i = 0; i < queue_.size(); ++i) {
      const int f = queue_[i], r = ring_[i];
      if (i > limit && r > ring_[i - 1]) break;  // the rings before are complete and already past the limit
      visit(f, r);
      if (r >= rings) continue;
      for (int g : mesh_.face_neighbors(f)) {
        if (g < 0) break;
        if (mark(g)) queue_.push_back(g), ring_.push_back(r + 1);
      }
    }
  }

  /// visit(face, distance) for every face connected to `start` through faces within `radius` of `center`
  /// (distance from center to the triangle; `start` is visited with distance 0, it holds the point).
  template <class Visit>
  void ball(int start, const Eigen::Vector3d& center, double radius, Visit&& visit) {
    next_stamp();
    queue_.clear();
    if (start < 0 || !mesh_.face_active(start)) return;
    mark(start);
    queue_.push_back(start);
    const auto& P = mesh_.positions();
    const auto& F = mesh_.faces();
    for (std::size_t i = 0; i < queue_.size(); ++i) {
      const int f = queue_[i];
      double distance = 0;
      if (i > 0) {
        const Eigen::Vector3d q = closest_point_on_triangle(center, P.row(F(f, 0)).transpose(),
                                                            P.row(F(f, 1)).transpose(), P.row(F(f, 2)).transpose());
        distance = (q - center).norm();
        if (distance > radius) continue;
      }
      visit(f, distance);
      for (int g : mesh_.face_neighbors(f)) {
        if (g < 0) break;
        if (mark(g)) queue_.push_back(g);
      }
    }
  }

 private:
  void next_stamp() {
    if (++current_ == 0) std::fill(stamp_.begin(), stamp_.end(), 0u), current_ = 1;
  }
  bool mark(int f) {
    if (stamp_[f] == current_) return false;
    stamp_[f] = current_;
    return true;
  }
  const TriangleMesh& mesh_;
  std::vector<unsigned> stamp_;
  unsigned current_ = 0;
  std::vector<int> queue_, ring_;
};

}  // namespace nfield
