#include "nfield/remesh/position_singularities.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <queue>

#include "nfield/remesh/lattice_collapse.hpp"
#include "nfield/remesh/min_cost_flow.hpp"

namespace nfield::remesh {

namespace {

/// Component and sign of R^E e_x in Z^2: E = 0: +x, 1: +y, 2: -x, 3: -y.
inline void unit_of(int E, int& component, int& sign) {
  E = ((E % 4) + 4) % 4;
  component = E & 1;
  sign = E < 2 ? 1 : -1;
}

/// Which offset components the flow may not change, per surface edge: on a feature edge the component
/// across the curve (in a's lattice coordinates the edge runs mostly along one axis; the other is across),
/// so that the curve stays a lattice line. Bit c set: component c is fixed.
std::vector<unsigned char> feature_fixed_components(const RemeshSurface& s, const HierarchyLevel& L,
                                                    const std::vector<char>& feature_edge) {
  std::vector<unsigned char> fixed(s.edges.size(), 0);
  if (feature_edge.empty()) return fixed;
  for (size_t e = 0; e < s.edges.size(); ++e) {
    if (!feature_edge[e]) continue;
    const int a = s.edges[e][0], b = s.edges[e][1];
    const Vec3 d = s.positions[b] - s.positions[a];
    const int across = std::abs(d.dot(L.q[a])) >= std::abs(d.dot(L.n[a].cross(L.q[a]))) ? 1 : 0;
    fixed[e] = static_cast<unsigned char>(1 << across);
  }
  return fixed;
}

/// The flow of the header comment on any triangulated surface (the fine one or the collapsed lattice mesh),
/// `positions` in mesh units, `spacing` (mesh units) per vertex, `fixed` per edge. Changes `o` along the paths found; fills the flow figures of
/// `report`.
void route_residuals(const RemeshSurface& s, const std::vector<std::array<int, 3>>& fe,
                     const std::vector<unsigned char>& fixed, const std::vector<double>& spacing, LatticeOffsets& o,
                     const CancellationOptions& options, const std::function<bool()>& cancelled,
                     CancellationReport& report) {
  const auto t0 = std::chrono::steady_clock::now();
  const int T = static_cast<int>(s.triangles.size());
  const int E = static_cast<int>(s.edges.size());
  const FaceDefects before = face_defects(s, fe, o);
  if (before.position_singularities == 0) return;

  // Exponent of the quarter turn with which D_e enters the residual of triangle t (in its first corner's
  // coordinates), for each of its three edges.
  std::vector<std::array<int, 3>> exponent(T);
  for (int t = 0; t < T; ++t) {
    const auto& tri = s.triangles[t];
    int tau = 0;
    for (int m = 0; m < 3; ++m) {
      const int e = fe[t][m];
      const bool forward = tri[m] < tri[(m + 1) % 3];
      exponent[t][m] = forward ? -tau : 2 - tau + o.turns[e];
      tau += o.directed_turns(e, forward);
    }
  }
  auto slot_of = [&](int t, int e) {
    for (int m = 0; m < 3; ++m)
      if (fe[t][m] == e) return m;
    return -1;
  };
  // Equation frames by breadth-first search over the dual graph, expanding from regular triangles only:
  // across a dual edge, the neighbour's frame makes the shared offset enter both equations with opposite
  // signs.
  std::vector<int> g(T, -1);
  for (int root = 0; root < T; ++root) {
    if (g[root] >= 0) continue;
    g[root] = 0;
    std::queue<int> queue;
    queue.push(root);
    while (!queue.empty()) {
      const int f = queue.front();
      queue.pop();
      if (before.orientation_index[f] != 0) continue;
      for (int m = 0; m < 3; ++m) {
        const int e = fe[f][m];
        const auto& ef = s.edge_faces[e];
        const int h = ef[0] == f ? ef[1] : ef[0];
        if (h < 0 || g[h] >= 0) continue;
        g[h] = ((g[f] + exponent[f][m] + 2 - exponent[h][slot_of(h, e)]) % 4 + 4) % 4;
        queue.push(h);
      }
    }
  }

  // Network: nodes 2t + c (equation c of triangle t), node 2T is the free node S (boundary, cones).
  const int S = 2 * T;
  MinCostFlow flow(2 * T + 1);
  long long total = 0;
  for (int t = 0; t < T; ++t) {
    if (before.orientation_index[t] != 0) {
      for (int c = 0; c < 2; ++c) {
        flow.add_arc(2 * t + c, S, 1, options.cone_cost);
        flow.add_arc(S, 2 * t + c, 1, options.cone_cost);
      }
      continue;
    }
    const Eigen::Vector2i r = rotate_quarter(before.residual[t], g[t]);
    for (int c = 0; c < 2; ++c) {
      if (r[c] == 0) continue;
      flow.add_supply(2 * t + c, r[c]);
      total += r[c];
      // Leaving the unit where it is: through S at give_up_cost (never applied to an offset).
      const int units = std::abs(r[c]);
      flow.add_arc(2 * t + c, S, units, options.give_up_cost);
      flow.add_arc(S, 2 * t + c, units, options.give_up_cost);
    }
  }
  flow.add_supply(S, static_cast<int>(-total));

  // Length of the dual edge through each edge (face centroid - edge midpoint - face centroid), in
  // lattice steps: a path's cost is about its length on the surface, whatever the triangulation.
  std::vector<double> dual_length(E, 0.0);
  for (int e = 0; e < E; ++e) {
    const Vec3 mid = 0.5 * (s.positions[s.edges[e][0]] + s.positions[s.edges[e][1]]);
    const double scale = 0.5 * (spacing[s.edges[e][0]] + spacing[s.edges[e][1]]);
    for (int t : s.edge_faces[e]) {
      if (t < 0) continue;
      const auto& tri = s.triangles[t];
      const Vec3 centroid = (s.positions[tri[0]] + s.positions[tri[1]] + s.positions[tri[2]]) / 3.0;
      dual_length[e] += (centroid - mid).norm() / scale;
    }
    dual_length[e] = std::max(dual_length[e], 0.02);
  }
  struct Variable {
    int edge, component;
    std::vector<int> up, down;  ///< arcs raising / lowering the component
  };
  std::vector<Variable> variables;
  constexpr double kMinCost = 0.01;
  for (int e = 0; e < E; ++e) {
    for (int c = 0; c < 2; ++c) {
      if (fixed[e] >> c & 1) {
        ++report.fixed_offsets;
        continue;
      }
      int node[2], sign[2], count = 0;
      for (int side = 0; side < 2; ++side) {
        const int t = s.edge_faces[e][side];
        if (t < 0) continue;
        int comp, sg;
        unit_of(g[t] + exponent[t][slot_of(t, e)] + c, comp, sg);
        node[count] = 2 * t + comp;
        sign[count] = sg;
        ++count;
      }
      // A boundary edge: the other end is S (a row ending on the boundary), at boundary_cost more.
      const double extra = count == 1 ? options.boundary_cost : 0.0;
      if (count == 1) {
        node[1] = S;
        sign[1] = -sign[0];
        count = 2;
      }
      if (count != 2 || sign[0] == sign[1]) {
        ++report.fixed_offsets;
        continue;
      }
      const int plus = sign[0] > 0 ? node[0] : node[1], minus = sign[0] > 0 ? node[1] : node[0];
      const double m = o.mismatch[e][c];
      const double w = dual_length[e];
      Variable v{e, c, {}, {}};
      for (int u = 1; u <= options.max_change; ++u) {
        // Raising by one more unit (u - 1 -> u) moves a unit from `minus` to `plus`; lowering the reverse.
        v.up.push_back(flow.add_arc(minus, plus, 1, extra + w * std::max(kMinCost, 2.0 * u - 1.0 - 2.0 * m)));
        v.down.push_back(flow.add_arc(plus, minus, 1, extra + w * std::max(kMinCost, 2.0 * u - 1.0 + 2.0 * m)));
      }
      variables.push_back(std::move(v));
    }
  }
  const auto t1 = std::chrono::steady_clock::now();
  report.seconds_network = std::chrono::duration<double>(t1 - t0).count();
  const MinCostFlow::Result result = flow.solve(cancelled);
  report.seconds_solve = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  report.phases = result.phases;
  report.augmentations = result.augmentations;
  report.routed = result.routed;
  report.unrouted = result.unrouted;
  report.cost = result.cost;
  for (const Variable& v : variables) {
    int delta = 0;
    for (int a : v.up) delta += flow.flow(a);
    for (int a : v.down) delta -= flow.flow(a);
    if (delta != 0) {
      o.offset[v.edge][v.component] += delta;
      ++report.changed_offsets;
    }
  }
}

}  // namespace

CancellationReport cancel_position_singularities(const RemeshSurface& s, const HierarchyLevel& L,
                                                 const std::vector<std::array<int, 3>>& fe,
                                                 const std::vector<char>& feature_edge, LatticeOffsets& o, const CancellationOptions& options,
                                                 const std::function<bool()>& cancelled) {
  CancellationReport report;
  const FaceDefects before = face_defects(s, fe, o);
  report.orientation_singularities = before.orientation_singularities;
  report.position_singularities_before = before.position_singularities;
  report.folded_before = before.folded;
  report.position_singularities_after = before.position_singularities;
  if (before.position_singularities == 0) return report;
  const std::vector<unsigned char> fixed = feature_fixed_components(s, L, feature_edge);
  if (options.collapse) {
    // The flow on the lattice-level mesh (lattice_collapse.hpp); it must reproduce the fine offsets exactly
    // before the flow (a self-check: otherwise the fine network is used).
    const auto t0 = std::chrono::steady_clock::now();
    CoarseLattice coarse = collapse_zero_offsets(s, o, fixed, L.p);
    LatticeOffsets check = o;
    if (expand_offsets(s, coarse, check) == 0) {
      report.network_triangles = static_cast<int>(coarse.surface.triangles.size());
      report.seconds_collapse = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      // A coarse vertex's spacing: the mean of its fine vertices' (exactly theirs when they agree).
      const int CV = coarse.surface.num_vertices();
      std::vector<double> spacing(CV, 0.0), count(CV, 0.0), first(CV, -1.0);
      std::vector<char> same(CV, 1);
      for (int v = 0; v < s.num_vertices(); ++v) {
        const int c = coarse.vertex_of[v];
        if (c < 0) continue;
        if (first[c] < 0) first[c] = L.spacing[v];
        same[c] = same[c] && L.spacing[v] == first[c];
        spacing[c] += L.spacing[v];
        count[c] += 1;
      }
      for (int c = 0; c < CV; ++c)
        spacing[c] = count[c] == 0 ? L.spacing[0] : same[c] ? first[c] : spacing[c] / count[c];
      route_residuals(coarse.surface, triangle_edges(coarse.surface), coarse.fixed, spacing, coarse.offsets, options,
                      cancelled, report);
      report.changed_offsets = expand_offsets(s, coarse, o);
      report.position_singularities_after = face_defects(s, fe, o).position_singularities;
      return report;
    }
  }
  report.network_triangles = static_cast<int>(s.triangles.size());
  route_residuals(s, fe, fixed, L.spacing, o, options, cancelled, report);
  report.position_singularities_after = face_defects(s, fe, o).position_singularities;
  return report;
}

}  // namespace nfield::remesh
