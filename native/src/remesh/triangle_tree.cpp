#include "nfield/remesh/triangle_tree.hpp"

#include <algorithm>

namespace nfield::remesh {

Vec3 closest_point_on_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  if (len2 <= 0) return a;
  const double t = std::clamp((p - a).dot(ab) / len2, 0.0, 1.0);
  return a + t * ab;
}

Vec3 closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return closest_point_on_segment(p, a, b);
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return closest_point_on_segment(p, a, c);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return closest_point_on_segment(p, b, c);
  const double denom = va + vb + vc;
  if (!(denom > 0)) {  // degenerate triangle: nearest of its three edges
    Vec3 best = closest_point_on_segment(p, a, b);
    for (const Vec3& q : {closest_point_on_segment(p, b, c), closest_point_on_segment(p, a, c)})
      if ((q - p).squaredNorm() < (best - p).squaredNorm()) best = q;
    return best;
  }
  const double v = vb / denom, w = vc / denom;
  return a + ab * v + ac * w;
}

TriangleTree::TriangleTree(std::vector<Vec3> vertices, std::vector<std::array<int, 3>> triangles)
    : vertices_(std::move(vertices)), triangles_(std::move(triangles)) {
  const int T = static_cast<int>(triangles_.size());
  order_.resize(T);
  centroids_.resize(T);
  for (int t = 0; t < T; ++t) {
    order_[t] = t;
    const auto& tri = triangles_[t];
    centroids_[t] = (vertices_[tri[0]] + vertices_[tri[1]] + vertices_[tri[2]]) / 3.0;
  }
  if (T > 0) {
    nodes_.reserve(2 * (T / 2 + 1));
    build(0, T);
  }
}

int TriangleTree::build(int begin, int end) {
  Node node;
  node.lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  node.hi = -node.lo;
  for (int i = begin; i < end; ++i)
    for (int c = 0; c < 3; ++c) {
      const Vec3& v = vertices_[triangles_[order_[i]][c]];
      node.lo = node.lo.cwiseMin(v);
      node.hi = node.hi.cwiseMax(v);
    }
  const int index = static_cast<int>(nodes_.size());
  nodes_.push_back(node);
  if (end - begin <= 4) {
    nodes_[index].begin = begin;
    nodes_[index].end = end;
    return index;
  }
  Vec3 clo = Vec3::Constant(std::numeric_limits<double>::infinity()), chi = -clo;
  for (int i = begin; i < end; ++i) {
    clo = clo.cwiseMin(centroids_[order_[i]]);
    chi = chi.cwiseMax(centroids_[order_[i]]);
  }
  int axis = 0;
  (chi - clo).maxCoeff(&axis);
  const int mid = (begin + end) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](int a, int b) { return centroids_[a][axis] < centroids_[b][axis]; });
  const int left = build(begin, mid);
  const int right = build(mid, end);
  nodes_[index].left = left;
  nodes_[index].right = right;
  return index;
}

namespace {
double box_distance2(const Eigen::Vector3d& q, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  const Eigen::Vector3d d = (lo - q).cwiseMax(q - hi).cwiseMax(0.0);
  return d.squaredNorm();
}
}  // namespace

TriangleTree::Hit TriangleTree::closest(const Vec3& q) const {
  Hit hit;
  if (nodes_.empty()) return hit;
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (box_distance2(q, node.lo, node.hi) >= hit.squared_distance) continue;
    if (node.left < 0) {
      for (int i = node.begin; i < node.end; ++i) {
        const auto& tri = triangles_[order_[i]];
        const Vec3 p = closest_point_on_triangle(q, vertices_[tri[0]], vertices_[tri[1]], vertices_[tri[2]]);
        const double d2 = (p - q).squaredNorm();
        if (d2 < hit.squared_distance) {
          hit.squared_distance = d2;
          hit.point = p;
          hit.triangle = order_[i];
        }
      }
      continue;
    }
    const Node& l = nodes_[node.left];
    const Node& r = nodes_[node.right];
    const double dl = box_distance2(q, l.lo, l.hi), dr = box_distance2(q, r.lo, r.hi);
    // Push the farther child first so that the nearer one is searched first. Depth is O(log T) (median
    // split), far below the stack size for any mesh that fits in memory.
    if (dl < dr) {
      if (dr < hit.squared_distance) stack[top++] = node.right;
      if (dl < hit.squared_distance) stack[top++] = node.left;
    } else {
      if (dl < hit.squared_distance) stack[top++] = node.left;
      if (dr < hit.squared_distance) stack[top++] = node.right;
    }
  }
  return hit;
}

}  // namespace nfield::remesh
