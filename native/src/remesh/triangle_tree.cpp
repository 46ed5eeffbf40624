#include "nfield/remesh/triangle_tree.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

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

Eigen::Vector3d barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 v0 = b - a, v1 = c - a, v2 = p - a;
  const double d00 = v0.dot(v0), d01 = v0.dot(v1), d11 = v1.dot(v1), d20 = v2.dot(v0), d21 = v2.dot(v1);
  const double det = d00 * d11 - d01 * d01;
  if (!(det > 1e-30 * (d00 * d11 + 1e-300))) {
    const double da = (p - a).squaredNorm(), db = (p - b).squaredNorm(), dc = (p - c).squaredNorm();
    if (da <= db && da <= dc) return {1, 0, 0};
    return db <= dc ? Eigen::Vector3d(0, 1, 0) : Eigen::Vector3d(0, 0, 1);
  }
  const double v = (d11 * d20 - d01 * d21) / det, w = (d00 * d21 - d01 * d20) / det;
  return {1 - v - w, v, w};
}

SurfaceNormals surface_normals(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles) {
  SurfaceNormals n;
  const size_t T = triangles.size();
  n.face.resize(T);
  n.vertex.assign(vertices.size(), Vec3::Zero());
  n.edge.resize(T);
  std::unordered_map<long long, Vec3> edge_sum;
  auto key = [](int a, int b) {
    if (a > b) std::swap(a, b);
    return (static_cast<long long>(a) << 32) | static_cast<unsigned int>(b);
  };
  for (size_t t = 0; t < T; ++t) {
    const auto& x = triangles[t];
    const Vec3 c = (vertices[x[1]] - vertices[x[0]]).cross(vertices[x[2]] - vertices[x[0]]);
    n.face[t] = c.norm() > 0 ? Vec3(c.normalized()) : Vec3::Zero();
    for (int m = 0; m < 3; ++m) {
      const Vec3 u = vertices[x[(m + 1) % 3]] - vertices[x[m]], w = vertices[x[(m + 2) % 3]] - vertices[x[m]];
      const double angle = (u.norm() > 0 && w.norm() > 0) ? std::atan2(u.cross(w).norm(), u.dot(w)) : 0.0;
      n.vertex[x[m]] += angle * n.face[t];
      edge_sum.try_emplace(key(x[m], x[(m + 1) % 3]), Vec3::Zero()).first->second += n.face[t];
    }
  }
  for (Vec3& v : n.vertex)
    if (v.norm() > 0) v.normalize();
  for (size_t t = 0; t < T; ++t)
    for (int m = 0; m < 3; ++m) {
      const Vec3& e = edge_sum.at(key(triangles[t][m], triangles[t][(m + 1) % 3]));
      n.edge[t][m] = e.norm() > 0 ? Vec3(e.normalized()) : n.face[t];
    }
  return n;
}

Vec3 TriangleTree::surface_normal(const Vec3& q, const SurfaceNormals& normals) const {
  return normal_at(closest(q), normals);
}

Vec3 TriangleTree::normal_at(const Hit& hit, const SurfaceNormals& normals) const {
  if (hit.triangle < 0) return Vec3::Zero();
  const auto& t = triangles_[hit.triangle];
  const Eigen::Vector3d w = barycentric(hit.point, vertices_[t[0]], vertices_[t[1]], vertices_[t[2]]);
  constexpr double kOn = 1e-9;
  const int zeros = (w[0] <= kOn) + (w[1] <= kOn) + (w[2] <= kOn);
  if (zeros == 0) return normals.face[hit.triangle];
  if (zeros == 1) {  // on the edge opposite the zero weight: edge m joins corners m and m + 1
    const int opposite = w[0] <= kOn ? 0 : (w[1] <= kOn ? 1 : 2);
    return normals.edge[hit.triangle][(opposite + 1) % 3];
  }
  const int at = w[0] > kOn ? 0 : (w[1] > kOn ? 1 : 2);
  return normals.vertex[t[at]].squaredNorm() > 0 ? normals.vertex[t[at]] : normals.face[hit.triangle];
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
