#include "nfield/remesh/quad_extraction.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include "nfield/parallel_for.hpp"

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

/// Splits the clusters that wrap round a part thinner than a lattice cell (a finger or claw whose surface
/// points all fall on one lattice point): projected, such a cluster's vertex lands on one sheet, and its
/// edges to the neighbours on the other sheets cut through the part (armadillo at 5,000 faces: a valence-12
/// vertex on a finger, edges 0.9% of the diagonal off the surface). A cluster is split when one of its
/// members' normals points against the cluster's mean normal (cosine below kStraddle), its lattice point
/// lies kOffSurface lattice steps or more off the surface (the members wrap round the part, so their common point
/// sits inside it; on a plate's rim the split only added irregular vertices) and it has no feature member:
/// two seeds, that member and the member whose normal is most against it, and every member goes to
/// the seed nearer in hops along the cluster's zero-offset edges; when both halves are connected they become
/// two clusters (the edges between them act as a link), each placed at the mean surface position of its
/// members (their lattice points coincide), so each is projected onto its own sheet. Returns the number of
/// clusters split; `parent` (union-find) and `own_place` (members placed by their positions) are updated.
int split_straddling_clusters(const Features& features, const HierarchyLevel& L,
                              const std::vector<std::array<int, 2>>& zero_edges, const std::vector<int>& cluster_of,
                              const std::vector<Vec3>& pos, const std::vector<Vec3>& nrm, int C,
                              const TriangleTree& surface, std::vector<int>& parent,
                              std::vector<char>& own_place) {
  constexpr double kStraddle = -0.3;
  constexpr double kOffSurface = 0.08;
  const int V = static_cast<int>(cluster_of.size());
  std::vector<int> opposite(C, -1);
  std::vector<double> lowest(C, kStraddle);
  for (int v = 0; v < V; ++v) {
    const double c = L.n[v].dot(nrm[cluster_of[v]]);
    if (c < lowest[cluster_of[v]]) {
      lowest[cluster_of[v]] = c;
      opposite[cluster_of[v]] = v;
    }
  }
  for (int v = 0; v < V; ++v)
    if (features.vertex_kind[v] != kNoFeature) opposite[cluster_of[v]] = -1;
  for (int c = 0; c < C; ++c) {
    if (opposite[c] < 0) continue;
    const double off = kOffSurface * L.spacing[opposite[c]];
    if (surface.closest(pos[c]).squared_distance < off * off) opposite[c] = -1;
  }
  std::vector<std::vector<int>> members(C);
  for (int v = 0; v < V; ++v)
    if (opposite[cluster_of[v]] >= 0) members[cluster_of[v]].push_back(v);
  std::vector<std::vector<std::array<int, 2>>> inner(C);
  for (const auto& e : zero_edges)
    if (opposite[cluster_of[e[0]]] >= 0 && cluster_of[e[0]] == cluster_of[e[1]]) inner[cluster_of[e[0]]].push_back(e);
  std::vector<char> group(V, 0);
  int split = 0;
  for (int c = 0; c < C; ++c) {
    if (opposite[c] < 0) continue;
    // Two seeds: the member whose normal is most against the mean, and the member most against that one;
    // every member goes to the seed nearer in hops along zero-offset edges (both halves stay connected).
    const int seed0 = opposite[c];
    int seed1 = seed0;
    for (int v : members[c])
      if (L.n[v].dot(L.n[seed0]) < L.n[seed1].dot(L.n[seed0])) seed1 = v;
    if (seed1 == seed0) continue;
    std::vector<int> saved;
    for (int v : members[c]) saved.push_back(parent[v]);
    std::unordered_map<int, std::vector<int>> nb;
    for (const auto& e : inner[c]) {
      nb[e[0]].push_back(e[1]);
      nb[e[1]].push_back(e[0]);
    }
    std::unordered_map<int, int> side;
    std::vector<int> queue = {seed0, seed1};
    side[seed0] = 0;
    side[seed1] = 1;
    for (std::size_t head = 0; head < queue.size(); ++head)
      for (int u : nb[queue[head]])
        if (!side.count(u)) {
          side[u] = side[queue[head]];
          queue.push_back(u);
        }
    for (int v : members[c]) {
      group[v] = side.count(v) ? side[v] : 0;
      parent[v] = v;
    }
    for (const auto& e : inner[c])
      if (group[e[0]] == group[e[1]]) parent[find(parent, e[0])] = find(parent, e[1]);
    std::vector<int> roots;
    for (int v : members[c]) roots.push_back(find(parent, v));
    std::sort(roots.begin(), roots.end());
    roots.erase(std::unique(roots.begin(), roots.end()), roots.end());
    if (roots.size() == 2) {
      ++split;
      for (int v : members[c]) own_place[v] = 1;
    } else {
      for (std::size_t k = 0; k < members[c].size(); ++k) parent[members[c][k]] = saved[k];
    }
  }
  return split;
}

}  // namespace

ProjectionTargets make_projection_targets(const RemeshSurface& s, const Features& f) {
  ProjectionTargets t;
  t.surface = TriangleTree(s.positions, s.triangles);
  t.surface_normals = surface_normals(s.positions, s.triangles);
  std::vector<std::array<int, 3>> segs;
  for (size_t e = 0; e < s.edges.size(); ++e)
    if (f.edge_is_feature[e]) segs.push_back({s.edges[e][0], s.edges[e][1], s.edges[e][1]});
  t.feature_edges = TriangleTree(s.positions, segs);
  return t;
}

PolygonMesh extract_quad_mesh(const RemeshSurface& s, const Features& features, const HierarchyLevel& L,
                              const LatticeOffsets& offsets, const ProjectionTargets& targets, int max_face_size,
                              ExtractionReport& report, std::vector<char>* feature_kind_out,
                              bool split_thin_clusters) {
  const int V = s.num_vertices();
  const int E = static_cast<int>(s.edges.size());
  // 1. Classify edges.
  std::vector<int> parent(V);
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<std::array<int, 2>> unit_edges, zero_edges;
  for (int e = 0; e < E; ++e) {
    const int i = s.edges[e][0], j = s.edges[e][1];
    const Eigen::Vector2i& d = offsets.offset[e];
    const int l1 = std::abs(d[0]) + std::abs(d[1]);
    if (l1 == 0) {
      parent[find(parent, i)] = find(parent, j);
      zero_edges.push_back({i, j});
    }
    else if (l1 == 1) unit_edges.push_back({i, j});
  }
  // 2. Clusters and links; merge clusters joined by very short links (repeat until stable).
  std::vector<char> own_place(V, 0);  // members of a split cluster: placed at their own positions
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
    // Only the members of the strongest feature kind place a cluster: their lattice points satisfy the
    // feature constraints (on the corner, on the curve), the other members' copies of the same lattice
    // point differ from them by their mismatch.
    std::vector<char> strongest(C, kNoFeature);
    for (int v = 0; v < V; ++v) strongest[cluster_of[v]] = std::max(strongest[cluster_of[v]], features.vertex_kind[v]);
    for (int v = 0; v < V; ++v) {
      const double a = L.area[v] > 0 ? L.area[v] : 1e-300;
      nrm[cluster_of[v]] += a * L.n[v];
      if (features.vertex_kind[v] != strongest[cluster_of[v]]) continue;
      pos[cluster_of[v]] += a * (own_place[v] ? s.positions[v] : L.p[v]);
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
      if (a != b && (pos[a] - pos[b]).norm() < 0.25 * L.pair_spacing(e[0], e[1]) &&
          find(parent, e[0]) != find(parent, e[1])) {
        parent[find(parent, e[0])] = find(parent, e[1]);
        ++merged;
      }
    }
    report.merged_short_links += merged;
    if (merged == 0) break;
  }
  cluster_positions(pos, nrm, cluster_of, C);
  if (split_thin_clusters)
    report.split_clusters = split_straddling_clusters(features, L, zero_edges, cluster_of, pos, nrm, C,
                                                      targets.surface, parent, own_place);
  if (report.split_clusters > 0) cluster_positions(pos, nrm, cluster_of, C);
  report.clusters = C;

  // 3. Faces: the output graph (clusters joined by unit-offset edges) is embedded in the surface, and its
  //    faces are the connected regions of the surface it cuts out: triangles joined across every edge that
  //    is neither inside a cluster nor a link nor on the boundary (the diagonals and longer jumps of the
  //    lattice). Each region's border, walked with the surface's orientation, is the face's loop; the
  //    rotation at every vertex is the surface's own, so no geometric sorting is needed.
  const std::vector<std::array<int, 3>> fe = triangle_edges(s);
  const int T = static_cast<int>(s.triangles.size());
  auto blocks = [&](int e) {
    const int a = s.edges[e][0], b = s.edges[e][1];
    if (s.edge_faces[e][1] < 0 || cluster_of[a] == cluster_of[b]) return true;
    // A zero offset between two clusters is the cut through a split cluster: a link between its halves.
    const Eigen::Vector2i& d = offsets.offset[e];
    return std::abs(d[0]) + std::abs(d[1]) <= 1;
  };
  std::vector<char> blocking(E);
  {
    std::vector<long long> link_keys;
    for (int e = 0; e < E; ++e) {
      blocking[e] = blocks(e);
      int a = cluster_of[s.edges[e][0]], b = cluster_of[s.edges[e][1]];
      if (!blocking[e] || a == b) continue;
      if (a > b) std::swap(a, b);
      link_keys.push_back(key(a, b));
    }
    std::sort(link_keys.begin(), link_keys.end());
    report.links = static_cast<int>(std::unique(link_keys.begin(), link_keys.end()) - link_keys.begin());
  }
  // The half-edge after (u -> v) of triangle t along its region's border: turn around v through the region
  // (across non-blocking edges) until the first blocking edge out of v.
  auto corner_index = [&](int t, int v) {
    const auto& x = s.triangles[t];
    return x[0] == v ? 0 : (x[1] == v ? 1 : 2);
  };
  auto next_border = [&](int t, int v) {  // returns (triangle, corner of the half-edge's start)
    for (int guard = 0; guard < 1 << 20; ++guard) {
      const int m = corner_index(t, v);  // half-edge v -> x[m + 1] is edge fe[t][m]
      const int e = fe[t][m];
      if (blocking[e]) return std::make_pair(t, m);
      t = s.edge_faces[e][0] == t ? s.edge_faces[e][1] : s.edge_faces[e][0];
    }
    return std::make_pair(-1, -1);
  };
  std::vector<char> walked(3 * static_cast<size_t>(T), 0);
  std::vector<std::vector<int>> faces;
  std::vector<int> walk;
  for (int t0 = 0; t0 < T; ++t0)
    for (int m0 = 0; m0 < 3; ++m0) {
      if (walked[3 * t0 + m0] || !blocking[fe[t0][m0]]) continue;
      walk.clear();
      int t = t0, m = m0;
      bool closed = false;
      for (int step = 0; step < 4 * T + 8; ++step) {
        walked[3 * t + m] = 1;
        walk.push_back(cluster_of[s.triangles[t][m]]);
        const auto nx = next_border(t, s.triangles[t][(m + 1) % 3]);
        if (nx.first < 0) break;
        t = nx.first;
        m = nx.second;
        if (t == t0 && m == m0) {
          closed = true;
          break;
        }
        if (walked[3 * t + m]) break;
      }
      if (!closed) {
        ++report.open_walks;
        continue;
      }
      // Steps inside a cluster vanish; a step out and straight back (a link that ends inside the face, or
      // a sliver of triangles along a link) is a spike and is cut off.
      std::vector<int> loop;
      for (int c : walk) {
        if (!loop.empty() && loop.back() == c) continue;
        loop.push_back(c);
        while (loop.size() >= 3 && loop[loop.size() - 3] == loop.back()) {
          loop.pop_back();
          loop.pop_back();
          ++report.removed_dangling;
        }
      }
      // the same at the seam of the cyclic walk
      for (bool changed = true; changed && loop.size() >= 2;) {
        changed = false;
        if (loop.front() == loop.back()) {
          loop.pop_back();
          changed = true;
        } else if (loop.size() >= 3 && loop[loop.size() - 2] == loop.front()) {
          loop.pop_back();
          loop.pop_back();
          ++report.removed_dangling;
          changed = true;
        } else if (loop.size() >= 3 && loop[1] == loop.back()) {
          loop.erase(loop.begin());
          loop.pop_back();
          ++report.removed_dangling;
          changed = true;
        }
      }
      if (loop.size() < 3) continue;
      std::vector<int> sorted = loop;
      std::sort(sorted.begin(), sorted.end());
      if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
        ++report.split_faces;
        split_walk(loop, faces);
      } else {
        faces.push_back(loop);
      }
    }
  // 4. Large faces.
  PolygonMesh out;
  out.positions = pos;
  for (auto& face : faces) {
    if (static_cast<int>(face.size()) > max_face_size) {
      ++report.dropped_large_faces;
      continue;
    }
    out.add_face(face);
  }
  // 5. Manifold and oriented.
  report.removed_conflicting = remove_conflicting_faces(out);
  std::vector<int> copied_from;
  report.split_vertices = split_pinched_vertices(out, &copied_from);
  // Scraps: pieces of fewer than 4 faces, cut off where conflicting faces were left out or pinched off at a
  // vertex (every component of the surface is a few lattice cells at least, so a piece this small is not
  // one of them).
  report.dropped_scraps = remove_small_pieces(out, 4);
  const std::vector<int> old_index = compact_vertices(out);

  // Feature kind per output vertex (strongest member), and projection.
  // A cluster lies on a feature when one of its members does and its lattice point is on the feature (the
  // constraints put the lattice points of a feature's vertices on it): a cluster that merely reaches a
  // feature with one member, its lattice point a row away, is not pulled onto it.
  std::vector<char> cluster_kind(C, kNoFeature);
  for (int v = 0; v < V; ++v) cluster_kind[cluster_of[v]] = std::max(cluster_kind[cluster_of[v]], features.vertex_kind[v]);
  // A cluster's lattice spacing: that of one of its members (they lie within a lattice cell).
  std::vector<double> cluster_spacing(C, 0.0);
  for (int v = V - 1; v >= 0; --v) cluster_spacing[cluster_of[v]] = L.spacing[v];
  auto on_feature = [&](int c) { return 0.45 * cluster_spacing[c]; };
  for (int c = 0; c < C; ++c)
    if (cluster_kind[c] != kNoFeature && !targets.feature_edges.empty() &&
        targets.feature_edges.closest(pos[c]).squared_distance > on_feature(c) * on_feature(c))
      cluster_kind[c] = kNoFeature;
  // Corners: snap to the member corner vertex nearest to the cluster position (when that is near).
  std::vector<int> corner_of(C, -1);
  for (int v = 0; v < V; ++v) {
    if (features.vertex_kind[v] != kCorner) continue;
    const int c = cluster_of[v];
    if ((s.positions[v] - pos[c]).norm() > on_feature(c)) continue;
    if (corner_of[c] < 0 || (s.positions[v] - pos[c]).norm() < (s.positions[corner_of[c]] - pos[c]).norm()) corner_of[c] = v;
  }
  // One output vertex per corner point: when two clusters claim corners closer than a quarter of the
  // spacing (the same corner, a copy of it made by the cut, or a tight group of feature ends), the one
  // nearer to its corner takes it and the other is not snapped (it would make a degenerate face).
  {
    std::vector<int> claimed;  // clusters owning a corner so far
    for (int c = 0; c < C; ++c) {
      if (corner_of[c] < 0) continue;
      const Vec3& x = s.positions[corner_of[c]];
      bool keep = true;
      for (int& other : claimed) {
        const Vec3& y = s.positions[corner_of[other]];
        if ((x - y).norm() >= 0.25 * cluster_spacing[c]) continue;
        if ((pos[c] - x).norm() < (pos[other] - y).norm()) {
          corner_of[other] = -1;
          other = c;
        } else {
          keep = false;
        }
        break;
      }
      if (!keep) corner_of[c] = -1;
      else if (std::find(claimed.begin(), claimed.end(), c) == claimed.end()) claimed.push_back(c);
    }
  }
  for (int c = 0; c < C; ++c)
    if (cluster_kind[c] == kCorner && corner_of[c] < 0) cluster_kind[c] = kCurve;
  std::vector<char> kind(out.num_vertices());
  for (int v = 0; v < out.num_vertices(); ++v) kind[v] = cluster_kind[copied_from[old_index[v]]];
  project_vertices(out, kind, targets);
  for (int v = 0; v < out.num_vertices(); ++v) {
    const int c = copied_from[old_index[v]];
    if (corner_of[c] >= 0) out.positions[v] = s.positions[corner_of[c]];
  }
  if (feature_kind_out) *feature_kind_out = kind;
  return out;
}

void project_vertices(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets) {
  // The side each vertex faces: the sum of its faces' Newell vectors (the mesh is consistently oriented).
  std::vector<Vec3> facing(mesh.num_vertices(), Vec3::Zero());
  std::vector<double> reach(mesh.num_vertices(), 0.0);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    Vec3 n = Vec3::Zero();
    for (int i = 0; i < k; ++i) n += mesh.positions[v[i]].cross(mesh.positions[v[(i + 1) % k]]);
    for (int i = 0; i < k; ++i) {
      facing[v[i]] += n;
      reach[v[i]] = std::max(reach[v[i]], (mesh.positions[v[(i + 1) % k]] - mesh.positions[v[i]]).norm());
    }
  }
  // Each vertex reads and writes only its own position: the vertices split over both cores.
  parallel_for(mesh.num_vertices(), [&](int v) {
    const Vec3 p = mesh.positions[v];
    const bool on_feature = v < static_cast<int>(kind.size()) && kind[v] != kNoFeature && !targets.feature_edges.empty();
    if (on_feature) {
      const auto hit = targets.feature_edges.closest(p);
      if (hit.triangle >= 0) mesh.positions[v] = hit.point;
      return;
    }
    auto hit = targets.surface.closest(p);
    if (hit.triangle < 0) return;
    const Vec3 side = facing[v].norm() > 0 ? Vec3(facing[v].normalized()) : Vec3::Zero();
    if (side.squaredNorm() > 0 && targets.surface.normal_at(hit, targets.surface_normals).dot(side) < 0.3) {
      // The nearest point is on a sheet facing the other way (a part thinner than a face): the nearest point
      // seen from a little outside or inside along the face side that does face this way is taken instead.
      double best = HUGE_VAL;
      for (double d : {0.25, 0.5, 1.0})
        for (double sign : {1.0, -1.0}) {
          const auto other = targets.surface.closest(p + sign * d * reach[v] * side);
          if (other.triangle < 0 || targets.surface.normal_at(other, targets.surface_normals).dot(side) < 0.3) continue;
          const double dist = (other.point - p).squaredNorm();
          if (dist < best) {
            best = dist;
            hit = other;
          }
        }
    }
    mesh.positions[v] = hit.point;
  });
}

}  // namespace nfield::remesh
