// Sample points of the strokes of one family and their spatial index: the distance tests of the streamline
// tracer (streamlines.cpp; "a point closer than d_test to another stroke", streamlines.hpp).
//
// The index is a uniform hash grid over 3D space: a ball query visits the cells the ball's bounding box
// meets, so it costs O((2r / cell + 1)^3) cell lookups plus the points found. Two grids serve the two
// scales of the tests: the tracer's cells of d_sep for radii up to two cells (a d_test ball meets at most
// 8 cells), 4x larger cells for the large radii of low-density regions (variable spacing). Points are
// removed only in reverse insertion order (a discarded stroke is popped point by point), so removal is
// O(1).
#pragma once
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace nfield::strokes {

/// Uniform hash grid of 3D points (cell size `cell`), storing point ids. Cell coordinates are packed into
/// 64 bits (21 bits each, wrapping): aliasing only adds candidates, which are distance-checked anyway.
class HashGrid {
 public:
  explicit HashGrid(double cell) : cell_(cell), inv_(1.0 / cell) { cells_.reserve(1 << 16); }
  double cell() const { return cell_; }
  void insert(int id, const Eigen::Vector3d& p) { cells_[key(coord(p[0]), coord(p[1]), coord(p[2]))].push_back(id); }
  /// Removes `id`, which must be the most recently inserted id of its cell.
  void remove_last(int id, const Eigen::Vector3d& p) {
    auto it = cells_.find(key(coord(p[0]), coord(p[1]), coord(p[2])));
    if (it != cells_.end() && !it->second.empty() && it->second.back() == id) it->second.pop_back();
  }
  /// Calls fn(id) for every id in cells meeting the ball (p, r); fn returns true to stop early.
  template <class Fn>
  bool any_in_ball(const Eigen::Vector3d& p, double r, Fn&& fn) const {
    const long long x0 = coord(p[0] - r), x1 = coord(p[0] + r);
    const long long y0 = coord(p[1] - r), y1 = coord(p[1] + r);
    const long long z0 = coord(p[2] - r), z1 = coord(p[2] + r);
    for (long long x = x0; x <= x1; ++x)
      for (long long y = y0; y <= y1; ++y)
        for (long long z = z0; z <= z1; ++z) {
          auto it = cells_.find(key(x, y, z));
          if (it == cells_.end()) continue;
          for (int id : it->second)
            if (fn(id)) return true;
        }
    return false;
  }

 private:
  long long coord(double v) const { return static_cast<long long>(std::floor(v * inv_)); }
  static std::uint64_t key(long long x, long long y, long long z) {
    const std::uint64_t m = (1u << 21) - 1;
    return ((static_cast<std::uint64_t>(x) & m) << 42) | ((static_cast<std::uint64_t>(y) & m) << 21) |
           (static_cast<std::uint64_t>(z) & m);
  }
  double cell_, inv_;
  std::unordered_map<std::uint64_t, std::vector<int>> cells_;
};

/// Sample points of one family: positions, owning stroke, arc-length coordinate along the stroke.
struct PointSet {
  std::vector<Eigen::Vector3d> pos;
  std::vector<int> stroke;
  std::vector<double> arc;
  std::vector<Eigen::Vector3d> dir;  // field direction of the segment starting at the point
  HashGrid fine, coarse;  // coarse (4x cells) serves the large radii of low-density regions
  explicit PointSet(double cell) : fine(cell), coarse(4.0 * cell) {}
  int add(const Eigen::Vector3d& p, int s, double a, const Eigen::Vector3d& d) {
    const int id = static_cast<int>(pos.size());
    pos.push_back(p);
    dir.push_back(d);
    stroke.push_back(s);
    arc.push_back(a);
    fine.insert(id, p);
    coarse.insert(id, p);
    return id;
  }
  void pop() {
    const int id = static_cast<int>(pos.size()) - 1;
    fine.remove_last(id, pos[id]);
    coarse.remove_last(id, pos[id]);
    pos.pop_back();
    dir.pop_back();
    stroke.pop_back();
    arc.pop_back();
  }
  template <class Fn>
  bool any_in_ball(const Eigen::Vector3d& p, double r, Fn&& fn) const {
    return (r <= 2.0 * fine.cell() ? fine : coarse).any_in_ball(p, r, fn);
  }
};

}  // namespace nfield::strokes
