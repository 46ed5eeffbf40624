#include "nfield/remesh/quad_extraction.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

namespace nfield::remesh {

namespace {

int find(std::vector<int>& parent, int x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

inline long long key(int a, int b) { return (static_cast<long long>(a) << 32) | static_cast<unsigned int>(b); }

/// Splits a closed walk that revisits vertices into simple loops.
void split_walk(const std::vector<int>& walk, std::vector<std::vector<int>>& loops) {
  std::vector<int> stack;
  for (int v : walk) {
    auto it = std::find(stack.begin(), stack.end(), v);
    if (it != stack.end()) {
      std::vector<int> loop(it, stack.end());
      if (loop.size() >= 3) loops.push_back(loop);
      stack.erase(it + 1, stack.end());
    } else {
      stack.push_back(v);
    }
  }
  if (stack.size() >= 3) loops.push_back(stack);
}

}  // namespace

ProjectionTargets make_projection_targets(const RemeshSurface& s, const Features& f) {
  ProjectionTargets t;
  t.surface = TriangleTree(s.positions, s.triangles);
  std::vector<std::array<int, 3>> segs;
  for (size_t e = 0; e < s.edges.size(); ++e)
    if (f.edge_is_feature[e]) segs.push_back({s.edges[e][0], s.edges[e][1], s.edges[e][1]});
  t.feature_edges = TriangleTree(s.positions, segs);
  return t;
}

PolygonMesh extract_quad_mesh(const RemeshSurface& s, const Features& features, const HierarchyLevel& L,
                              const LatticeOffsets& offsets, double scale, const ProjectionTargets& targets, int max_face_size,
                              ExtractionReport& report, std::vector<char>* feature_kind_out) {
  const int V = s.num_vertices();
  const int E = static_cast<int>(s.edges.size());
  // 1. Classify edges.
  std::vector<int> parent(V);
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<std::array<int, 2>> unit_edges;
  for (int e = 0; e < E; ++e) {
    const int i = s.edges[e][0], j = s.edges[e][1];
    const Eigen::Vector2i& d = offsets.offset[e];
    const int l1 = std::abs(d[0]) + std::abs(d[1]);
    if (l1 == 0) parent[find(parent, i)] = find(parent, j);
    else if (l1 == 1) unit_edges.push_back({i, j});
  }
  // 2. Clusters and links; merge clusters joined by very short links (repeat until stable).
  auto cluster_positions = [&](std::vector<Vec3>& pos, std::vector<Vec3>& nrm, std::vector<int>& cluster_of,
                               int& C) {
    std::vector<int> id(V, -1);
    C = 0;
    cluster_of.assign(V, -1);
    for (int v = 0; v < V; ++v) {
      const int r = find(parent, v);
      if (id[r] < 0) id[r] = C++;
      cluster_of[v] = id[r];
    }
    pos.assign(C, Vec3::Zero());
    nrm.assign(C, Vec3::Zero());
    std::vector<double> w(C, 0.0);
    for (int v = 0; v < V; ++v) {
      const double a = L.area[v] > 0 ? L.area[v] : 1e-300;
      pos[cluster_of[v]] += a * L.p[v];
      nrm[cluster_of[v]] += a * L.n[v];
      w[cluster_of[v]] += a;
    }
    for (int c = 0; c < C; ++c) {
      pos[c] /= w[c];
      if (nrm[c].norm() > 0) nrm[c].normalize();
    }
  };
  std::vector<Vec3> pos, nrm;
  std::vector<int> cluster_of;
  int C = 0;
  for (int round = 0; round < 4; ++round) {
    cluster_positions(pos, nrm, cluster_of, C);
    int merged = 0;
    for (const auto& e : unit_edges) {
      const int a = cluster_of[e[0]], b = cluster_of[e[1]];
      if (a != b && (pos[a] - pos[b]).norm() < 0.25 * scale && find(parent, e[0]) != find(parent, e[1])) {
        parent[find(parent, e[0])] = find(parent, e[1]);
        ++merged;
      }
    }
    report.merged_short_links += merged;
    if (merged == 0) break;
  }
  cluster_positions(pos, nrm, cluster_of, C);
  report.clusters = C;

  std::vector<std::vector<int>> nbrs(C);
  {
    std::vector<long long> link_keys;
    for (const auto& e : unit_edges) {
      int a = cluster_of[e[0]], b = cluster_of[e[1]];
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      link_keys.push_back(key(a, b));
    }
    std::sort(link_keys.begin(), link_keys.end());
    link_keys.erase(std::unique(link_keys.begin(), link_keys.end()), link_keys.end());
    for (long long k : link_keys) {
      const int a = static_cast<int>(k >> 32), b = static_cast<int>(k & 0xffffffffLL);
      nbrs[a].push_back(b);
      nbrs[b].push_back(a);
    }
    report.links = static_cast<int>(link_keys.size());
  }
  // 3. Remove dangling vertices.
  {
    std::vector<int> queue;
    for (int c = 0; c < C; ++c)
      if (nbrs[c].size() == 1) queue.push_back(c);
    while (!queue.empty()) {
      const int c = queue.back();
      queue.pop_back();
      if (nbrs[c].size() != 1) continue;
      const int o = nbrs[c][0];
      nbrs[c].clear();
      ++report.removed_dangling;
      auto& on = nbrs[o];
      on.erase(std::remove(on.begin(), on.end(), c), on.end());
      if (on.size() == 1) queue.push_back(o);
    }
  }
  // Sort links by angle around each cluster's normal.
  for (int c = 0; c < C; ++c) {
    if (nbrs[c].size() < 2) continue;
    const Vec3& n = nrm[c];
    const Vec3 x = n.unitOrthogonal(), y = n.cross(x);
    std::vector<std::pair<double, int>> sorted;
    for (int o : nbrs[c]) {
      const Vec3 d = pos[o] - pos[c];
      sorted.emplace_back(std::atan2(d.dot(y), d.dot(x)), o);
    }
    std::sort(sorted.begin(), sorted.end());
    for (size_t k = 0; k < sorted.size(); ++k) nbrs[c][k] = sorted[k].second;
  }
  // Boundary clusters: containing a vertex of a boundary edge of the surface.
  std::vector<char> on_boundary(C, 0);
  for (int e = 0; e < E; ++e)
    if (s.edge_faces[e][1] < 0) on_boundary[cluster_of[s.edges[e][0]]] = on_boundary[cluster_of[s.edges[e][1]]] = 1;
  // Walk faces.
  std::unordered_map<long long, char> used;
  std::vector<std::vector<int>> faces;
  for (int a = 0; a < C; ++a)
    for (int b : nbrs[a]) {
      if (used.count(key(a, b))) continue;
      std::vector<int> walk;
      int u = a, w = b;
      bool closed = false;
      for (int step = 0; step < 4 * max_face_size + 8; ++step) {
        used[key(u, w)] = 1;
        walk.push_back(u);
        const auto& around = nbrs[w];
        const int k = static_cast<int>(std::find(around.begin(), around.end(), u) - around.begin());
        const int next = around[(k + static_cast<int>(around.size()) - 1) % around.size()];
        u = w;
        w = next;
        if (u == a && w == b) {
          closed = true;
          break;
        }
        if (used.count(key(u, w))) break;
      }
      if (!closed) {
        ++report.open_walks;
        continue;
      }
      std::vector<int> sorted = walk;
      std::sort(sorted.begin(), sorted.end());
      if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
        ++report.split_faces;
        split_walk(walk, faces);
      } else {
        faces.push_back(walk);
      }
    }
  // 4. Holes and large faces.
  PolygonMesh out;
  out.positions = pos;
  for (auto& face : faces) {
    const int k = static_cast<int>(face.size());
    bool all_boundary = true;
    Vec3 newell = Vec3::Zero(), mean_n = Vec3::Zero();
    for (int i = 0; i < k; ++i) {
      all_boundary = all_boundary && on_boundary[face[i]];
      newell += pos[face[i]].cross(pos[face[(i + 1) % k]]);
      mean_n += nrm[face[i]];
    }
    if (all_boundary && (newell.dot(mean_n) < 0 || k > 4)) {
      ++report.boundary_holes;
      continue;
    }
    if (k > max_face_size) {
      ++report.dropped_large_faces;
      continue;
    }
    out.add_face(face);
  }
  // 5. Manifold and oriented.
  report.removed_conflicting = remove_conflicting_faces(out);
  std::vector<int> copied_from;
  report.split_vertices = split_pinched_vertices(out, &copied_from);
  const std::vector<int> old_index = compact_vertices(out);

  // Feature kind per output vertex (strongest member), and projection.
  std::vector<char> cluster_kind(C, kNoFeature);
  for (int v = 0; v < V; ++v) cluster_kind[cluster_of[v]] = std::max(cluster_kind[cluster_of[v]], features.vertex_kind[v]);
  std::vector<char> kind(out.num_vertices());
  for (int v = 0; v < out.num_vertices(); ++v) kind[v] = cluster_kind[copied_from[old_index[v]]];
  // Corners: snap to the member corner vertex nearest to the cluster position.
  std::vector<int> corner_of(C, -1);
  for (int v = 0; v < V; ++v) {
    if (features.vertex_kind[v] != kCorner) continue;
    const int c = cluster_of[v];
    if (corner_of[c] < 0 || (s.positions[v] - pos[c]).norm() < (s.positions[corner_of[c]] - pos[c]).norm()) corner_of[c] = v;
  }
  project_vertices(out, kind, targets);
  for (int v = 0; v < out.num_vertices(); ++v) {
    const int c = copied_from[old_index[v]];
    if (corner_of[c] >= 0) out.positions[v] = s.positions[corner_of[c]];
  }
  if (feature_kind_out) *feature_kind_out = kind;
  return out;
}

void project_vertices(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets) {
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    const Vec3 p = mesh.positions[v];
    const bool on_feature = v < static_cast<int>(kind.size()) && kind[v] != kNoFeature && !targets.feature_edges.empty();
    const auto hit = on_feature ? targets.feature_edges.closest(p) : targets.surface.closest(p);
    if (hit.triangle >= 0) mesh.positions[v] = hit.point;
  }
}

}  // namespace nfield::remesh
