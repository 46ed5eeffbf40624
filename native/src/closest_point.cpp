#include "nfield/closest_point.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nfield {

Eigen::Vector3d closest_point_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                          const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + (d1 / (d1 - d3)) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + (d2 / (d2 - d6)) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  const double denom = va + vb + vc;
  if (!(denom > 0)) return a;  // degenerate triangle (inactive faces are never in the tree)
  return a + ab * (vb / denom) + ac * (vc / denom);
}

TriangleTree::TriangleTree(const TriangleMesh& mesh) : mesh_(mesh) {
  const auto& P = mesh.positions();
  const auto& F = mesh.faces();
  std::vector<Eigen::Vector3d> centroid(mesh.num_faces());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (!mesh.face_active(f)) continue;
    order_.push_back(f);
    centroid[f] = (P.row(F(f, 0)) + P.row(F(f, 1)) + P.row(F(f, 2))).transpose() / 3.0;
  }
  if (order_.empty()) return;
  struct Task {
    int node, first, count;
  };
  nodes_.push_back({Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 0, 0});
  std::vector<Task> stack{{0, 0, static_cast<int>(order_.size())}};
  while (!stack.empty()) {
    const Task t = stack.back();
    stack.pop_back();
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    Eigen::Vector3d clo = lo, chi = hi;
    for (int i = t.first; i < t.first + t.count; ++i) {
      const int f = order_[i];
      for (int c = 0; c < 3; ++c) {
        lo = lo.cwiseMin(P.row(F(f, c)).transpose());
        hi = hi.cwiseMax(P.row(F(f, c)).transpose());
      }
      clo = clo.cwiseMin(centroid[f]);
      chi = chi.cwiseMax(centroid[f]);
    }
    nodes_[t.node].lo = lo;
    nodes_[t.node].hi = hi;
    if (t.count <= 4) {
      nodes_[t.node].first = t.first;
      nodes_[t.node].count = t.count;
      continue;
    }
    int axis = 0;
    (chi - clo).maxCoeff(&axis);
    const int half = t.count / 2;
    std::nth_element(order_.begin() + t.first, order_.begin() + t.first + half, order_.begin() + t.first + t.count,
                     [&](int a, int b) {
                       return centroid[a][axis] != centroid[b][axis] ? centroid[a][axis] < centroid[b][axis] : a < b;
                     });
    const int left = static_cast<int>(nodes_.size());
    nodes_.push_back({Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 0, 0});
    nodes_.push_back({Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 0, 0});
    nodes_[t.node].first = left;
    nodes_[t.node].count = 0;
    stack.push_back({left, t.first, half});
    stack.push_back({left + 1, t.first + half, t.count - half});
  }
}

double TriangleTree::box_distance2(const Node& node, const Eigen::Vector3d& p) const {
  const Eigen::Vector3d d = (node.lo - p).cwiseMax(p - node.hi).cwiseMax(0.0);
  return d.squaredNorm();
}

SurfacePoint TriangleTree::closest(const Eigen::Vector3d& p) const {
  SurfacePoint best;
  if (nodes_.empty()) return best;
  const auto& P = mesh_.positions();
  const auto& F = mesh_.faces();
  double best2 = std::numeric_limits<double>::infinity();
  std::vector<int> stack{0};
  while (!stack.empty()) {
    const Node& node = nodes_[stack.back()];
    stack.pop_back();
    if (box_distance2(node, p) > best2) continue;
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        const int f = order_[i];
        const Eigen::Vector3d q =
            closest_point_on_triangle(p, P.row(F(f, 0)).transpose(), P.row(F(f, 1)).transpose(), P.row(F(f, 2)).transpose());
        const double d2 = (q - p).squaredNorm();
        if (d2 < best2 || (d2 == best2 && f < best.face)) best2 = d2, best.face = f, best.point = q;
      }
      continue;
    }
    // Visit the nearer child first (pushed last).
    const int a = node.first, b = node.first + 1;
    const bool a_first = box_distance2(nodes_[a], p) <= box_distance2(nodes_[b], p);
    stack.push_back(a_first ? b : a);
    stack.push_back(a_first ? a : b);
  }
  best.distance = std::sqrt(best2);
  return best;
}

}  // namespace nfield
