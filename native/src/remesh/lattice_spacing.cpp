#include "nfield/remesh/lattice_spacing.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <queue>

#include "nfield/blas.hpp"

namespace nfield::remesh {

namespace {

constexpr double kQuarter = 1.5707963267948966;

/// v rotated by the smallest rotation taking unit `from` to unit `to` (Rodrigues; antiparallel normals,
/// which no manifold edge has, leave v as it is).
Vec3 rotate_between(const Vec3& v, const Vec3& from, const Vec3& to) {
  const Vec3 axis = from.cross(to);
  const double c = from.dot(to);
  if (c <= -1 + 1e-12) return v;
  return v * c + axis.cross(v) + axis * (axis.dot(v) / (1 + c));
}

/// Distance along the edges from the vertices of `sources` (multi-source Dijkstra), stopped at `limit`.
std::vector<double> distance_from(const RemeshSurface& s, const std::vector<int>& sources, double limit) {
  std::vector<double> d(s.num_vertices(), HUGE_VAL);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  for (int v : sources) {
    d[v] = 0;
    queue.push({0.0, v});
  }
  while (!queue.empty()) {
    const auto [dv, v] = queue.top();
    queue.pop();
    if (dv > d[v] || dv > limit) continue;
    for (int k = s.adjacency_offsets[v]; k < s.adjacency_offsets[v + 1]; ++k) {
      const int w = s.adjacency[k];
      const double dw = dv + (s.positions[w] - s.positions[v]).norm();
      if (dw < d[w]) {
        d[w] = dw;
        queue.push({dw, w});
      }
    }
  }
  return d;
}

}  // namespace

std::vector<double> field_rotation_form(const RemeshSurface& s, const std::vector<Vec3>& q) {
  std::vector<double> omega(s.edges.size(), 0.0);
  for (size_t e = 0; e < s.edges.size(); ++e) {
    const int a = s.edges[e][0], b = s.edges[e][1];
    const Vec3& nb = s.vertex_normals[b];
    const Vec3 carried = rotate_between(q[a], s.vertex_normals[a], nb);
    const double angle = std::atan2(nb.dot(carried.cross(q[b])), carried.dot(q[b]));
    omega[e] = std::remainder(angle, kQuarter);
  }
  return omega;
}

std::vector<double> conformal_log_scale(const RemeshSurface& s, const std::vector<Vec3>& q, double h,
                                        const LatticeSpacingOptions& options, LatticeSpacingReport* report) {
  const auto t0 = std::chrono::steady_clock::now();
  const int V = s.num_vertices(), T = static_cast<int>(s.triangles.size());
  std::vector<double> u(V, 0.0);
  LatticeSpacingReport r;
  auto finish = [&]() {
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (report) *report = r;
    return u;
  };
  if (V == 0 || T == 0) return finish();
  const std::vector<double> omega = field_rotation_form(s, q);
  std::vector<int> turns(s.edges.size());
  for (size_t e = 0; e < s.edges.size(); ++e)
    compatible_direction(q[s.edges[e][0]], q[s.edges[e][1]], s.vertex_normals[s.edges[e][1]], &turns[e]);
  // Directed edge m of triangle t (corner m -> m + 1): its edge index and whether it runs a -> b.
  auto edge_of = [&](int x, int y) {
    for (int k = s.adjacency_offsets[x]; k < s.adjacency_offsets[x + 1]; ++k)
      if (s.adjacency[k] == y) return s.adjacency_edge[k];
    return -1;
  };
  std::vector<std::array<int, 3>> fe(T);
  std::vector<int> cone_vertices;
  std::vector<char> singular(T, 0);
  for (int t = 0; t < T; ++t) {
    int index = 0;
    for (int m = 0; m < 3; ++m) {
      const int x = s.triangles[t][m], y = s.triangles[t][(m + 1) % 3];
      fe[t][m] = edge_of(x, y);
      index += x < y ? turns[fe[t][m]] : 4 - turns[fe[t][m]];
    }
    if (index % 4 != 0) {
      singular[t] = 1;
      ++r.singular_triangles;
      for (int v : s.triangles[t]) cone_vertices.push_back(v);
    }
  }
  const double radius = options.cone_radius * h;
  const std::vector<double> near_cone = distance_from(s, cone_vertices, radius);

  // Stiffness K and right-hand side b_i = sum_t area_t grad(phi_i) . X_t.
  double mean_area = 0;
  for (double a : s.face_areas) mean_area += a;
  mean_area /= T;
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(9 * static_cast<size_t>(T));
  Eigen::VectorXd b = Eigen::VectorXd::Zero(V);
  std::vector<double> diagonal(V, 0.0);
  for (int t = 0; t < T; ++t) {
    const auto& tri = s.triangles[t];
    const double area = s.face_areas[t];
    if (!(area > 1e-12 * mean_area)) continue;
    const Vec3& n = s.face_normals[t];
    Vec3 grad[3];
    for (int m = 0; m < 3; ++m)
      grad[m] = n.cross(s.positions[tri[(m + 2) % 3]] - s.positions[tri[(m + 1) % 3]]) / (2 * area);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const double k = area * grad[i].dot(grad[j]);
        trip.emplace_back(tri[i], tri[j], k);
        if (i == j) diagonal[tri[i]] += k;
      }
    bool excluded = singular[t];
    for (int v : tri) excluded = excluded || near_cone[v] < radius;
    if (excluded) continue;
    // g: least-squares fit of g . (x_{m+1} - x_m) = omega on the three directed edges, in the plane.
    const Vec3 e1 = (s.positions[tri[1]] - s.positions[tri[0]]).normalized(), e2 = n.cross(e1);
    Eigen::Matrix2d M = Eigen::Matrix2d::Zero();
    Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
    for (int m = 0; m < 3; ++m) {
      const int x = tri[m], y = tri[(m + 1) % 3];
      const Vec3 d = s.positions[y] - s.positions[x];
      const Eigen::Vector2d d2(d.dot(e1), d.dot(e2));
      const double w = x < y ? omega[fe[t][m]] : -omega[fe[t][m]];
      M += d2 * d2.transpose();
      rhs += w * d2;
    }
    const Eigen::Vector2d g = M.ldlt().solve(rhs);
    if (!g.allFinite()) continue;
    const Vec3 X = g.y() * e1 - g.x() * e2;  // -J g, J the quarter turn about n
    for (int m = 0; m < 3; ++m) b[tri[m]] += area * grad[m].dot(X);
  }
  // One vertex per component (and every vertex without a triangle) keeps u = 0.
  std::vector<int> index(V, -1);
  std::vector<char> pinned_component(std::max(s.num_components, 1), 0);
  int n = 0;
  for (int v = 0; v < V; ++v) {
    const int c = s.vertex_component.empty() ? 0 : s.vertex_component[v];
    if (!(diagonal[v] > 0)) continue;
    if (c >= 0 && c < static_cast<int>(pinned_component.size()) && !pinned_component[c]) {
      pinned_component[c] = 1;
      continue;
    }
    index[v] = n++;
  }
  if (n > 0) {
    std::vector<Eigen::Triplet<double>> reduced;
    reduced.reserve(trip.size());
    for (const auto& x : trip)
      if (index[x.row()] >= 0 && index[x.col()] >= 0) reduced.emplace_back(index[x.row()], index[x.col()], x.value());
    Eigen::SparseMatrix<double> K(n, n);
    K.setFromTriplets(reduced.begin(), reduced.end());
    Eigen::VectorXd rhs(n);
    for (int v = 0; v < V; ++v)
      if (index[v] >= 0) rhs[index[v]] = b[v];
    SingleThreadedBlas blas_guard;
    Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> solver;
    solver.compute(K);
    if (solver.info() != Eigen::Success) return finish();
    const Eigen::VectorXd x = solver.solve(rhs);
    if (solver.info() != Eigen::Success || !x.allFinite()) return finish();
    for (int v = 0; v < V; ++v)
      if (index[v] >= 0) u[v] = x[index[v]];
  }

  // Per component: the shift keeping sum area e^-2u = sum area, then the clamp (three rounds, clamp last).
  const double bound = std::log(std::max(options.max_ratio, 1.0));
  const int C = std::max(s.num_components, 1);
  auto component = [&](int v) { return s.vertex_component.empty() ? 0 : std::max(0, s.vertex_component[v]); };
  for (int round = 0; round < 3; ++round) {
    std::vector<double> weighted(C, 0.0), total(C, 0.0);
    for (int v = 0; v < V; ++v) {
      weighted[component(v)] += s.vertex_areas[v] * std::exp(-2 * u[v]);
      total[component(v)] += s.vertex_areas[v];
    }
    for (int v = 0; v < V; ++v) {
      const int c = component(v);
      if (weighted[c] > 0 && total[c] > 0) u[v] += 0.5 * std::log(weighted[c] / total[c]);
      u[v] = std::clamp(u[v], -bound, bound);
    }
  }
  // Rounded to steps of 2^-20 (a spacing change of 1e-6): the solve spreads a rounding-level difference of the
  // field (the same field given as directions or as a representation vector) over every vertex, and the
  // position field's discrete choices (nearest lattice points) then differ somewhere; rounded, the same field
  // gives the same spacing but where u sits within about 1e-12 of a step.
  for (double& x : u) x = std::clamp(std::ldexp(std::round(std::ldexp(x, 20)), -20), -bound, bound);
  double area = 0, clamped = 0;
  r.min_ratio = HUGE_VAL;
  r.max_ratio = 0;
  for (int v = 0; v < V; ++v) {
    area += s.vertex_areas[v];
    if (std::abs(u[v]) >= bound - std::ldexp(1.0, -20)) clamped += s.vertex_areas[v];  // at the bound, rounded
    r.min_ratio = std::min(r.min_ratio, std::exp(u[v]));
    r.max_ratio = std::max(r.max_ratio, std::exp(u[v]));
  }
  r.clamped_area = area > 0 ? clamped / area : 0;
  return finish();
}

}  // namespace nfield::remesh
