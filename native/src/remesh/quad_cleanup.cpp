#include "nfield/remesh/quad_cleanup.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "nfield/remesh/quad_stats.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

namespace {

inline long long edge_key(int a, int b) { return undirected_edge_key(a, b); }

/// Removes interior doublets (valence-2 vertices: two faces that share both edges of a vertex cannot both
/// be unfolded there on a smooth surface), repeatedly, since removing one lowers its neighbours' valences.
/// Feature corners stay (the tip of a wedge is two faces meeting at a valence-2 corner) unless their two
/// edges are nearly straight (within about 30 degrees: a corner of a feature on a smooth part, where the
/// two faces would each have a straight angle), or listed in `corners_too`. Returns the number removed.
int remove_doublets(PolygonMesh& mesh, const std::vector<char>& kind, const std::vector<char>* corners_too) {
  std::vector<std::vector<int>> faces = face_lists(mesh);
  int removed = 0;
  for (int round = 0; round < 8; ++round) {
    const int before = removed;
    set_faces(mesh, faces);
    faces = face_lists(mesh);
    const VertexValence vv = vertex_valences(mesh);
    auto dir = directed_face_map(faces);
    for (int v = 0; v < mesh.num_vertices(); ++v) {
      if (vv.valence[v] != 2) continue;
      if (vv.boundary[v]) {
        // A boundary vertex in one face where the boundary runs straight: the face has a straight angle
        // there (a corner turned by less than 30 degrees), and loses the vertex (unless it is a triangle).
        for (auto& face : faces) {
          const int k = static_cast<int>(face.size());
          const int i = static_cast<int>(std::find(face.begin(), face.end(), v) - face.begin());
          if (i == k) continue;
          const Vec3 ea = mesh.positions[face[(i + k - 1) % k]] - mesh.positions[v];
          const Vec3 eb = mesh.positions[face[(i + 1) % k]] - mesh.positions[v];
          if (k >= 4 && ea.dot(eb) < -0.85 * ea.norm() * eb.norm()) {
            face.erase(face.begin() + i);
            ++removed;
          }
          break;
        }
        continue;
      }
      // Faces around v: find a face containing v, its neighbours a (prev) and b (next).
      int f1 = -1;
      for (int f = 0; f < static_cast<int>(faces.size()) && f1 < 0; ++f)
        if (std::find(faces[f].begin(), faces[f].end(), v) != faces[f].end()) f1 = f;
      if (f1 < 0) continue;
      const auto& p = faces[f1];
      const int k = static_cast<int>(p.size());
      const int i = static_cast<int>(std::find(p.begin(), p.end(), v) - p.begin());
      const int b = p[(i + 1) % k];
      if (kind[v] == kCorner && !(corners_too && (*corners_too)[v])) {  // stays unless its edges run straight
        const Vec3 ea = mesh.positions[p[(i + k - 1) % k]] - mesh.positions[v], eb = mesh.positions[b] - mesh.positions[v];
        if (!(ea.dot(eb) < -0.85 * ea.norm() * eb.norm())) continue;
      }
      auto it = dir.find((static_cast<long long>(b) << 32) | static_cast<unsigned int>(v));
      if (it == dir.end()) continue;
      const int f2 = it->second;
      if (f2 == f1) continue;
      std::vector<int> merged = merge_polygons_across(faces[f1], faces[f2], v, b);
      // merged reads b .. a v a ..: drop v and the repeated a. Other valence-2 vertices the two faces share
      // (a chain of doublets along their common border) go with it.
      merged.erase(std::remove_if(merged.begin(), merged.end(), [&](int w) {
                     return w == v || (vv.valence[w] == 2 && !vv.boundary[w] &&
                                       std::count(faces[f1].begin(), faces[f1].end(), w) &&
                                       std::count(faces[f2].begin(), faces[f2].end(), w));
                   }), merged.end());
      std::vector<int> dedup;
      for (size_t j = 0; j < merged.size(); ++j)
        if (merged[j] != merged[(j + 1) % merged.size()]) dedup.push_back(merged[j]);
      merged = dedup;
      std::vector<int> sorted = merged;
      std::sort(sorted.begin(), sorted.end());
      if (merged.size() < 3 || std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) continue;
      for (int f : {f1, f2})
        for (size_t j = 0; j < faces[f].size(); ++j)
          dir.erase((static_cast<long long>(faces[f][j]) << 32) | static_cast<unsigned int>(faces[f][(j + 1) % faces[f].size()]));
      faces[f1] = merged;
      faces[f2].clear();
      for (size_t j = 0; j < merged.size(); ++j)
        dir[(static_cast<long long>(merged[j]) << 32) | static_cast<unsigned int>(merged[(j + 1) % merged.size()])] = f1;
      ++removed;
    }
    if (removed == before) break;
  }
  set_faces(mesh, faces);
  return removed;
}

}  // namespace

int split_cone_vertices(PolygonMesh& mesh, std::vector<char>& kind) {
  std::vector<std::vector<int>> faces = face_lists(mesh);
  auto dir = directed_face_map(faces);
  const VertexValence vv = vertex_valences(mesh);
  auto face_of = [&](int a, int b) {  // the face containing a -> b
    auto it = dir.find((static_cast<long long>(a) << 32) | static_cast<unsigned int>(b));
    return it == dir.end() ? -1 : it->second;
  };
  auto slot = [](const std::vector<int>& f, int v) { return static_cast<int>(std::find(f.begin(), f.end(), v) - f.begin()); };
  std::vector<char> touched(faces.size(), 0);
  int split = 0;
  const int V0 = mesh.num_vertices();
  for (int v = 0; v < V0; ++v) {
    if (vv.valence[v] != 6 || vv.boundary[v] || kind[v] != kNoFeature) continue;
    // The fan of faces around v in order: f_k = (.., prev_k, v, next_k, ..) and f_{k+1} holds next_k -> v.
    int start = -1;
    for (size_t f = 0; f < faces.size() && start < 0; ++f)
      if (!touched[f] && slot(faces[f], v) < static_cast<int>(faces[f].size())) start = static_cast<int>(f);
    if (start < 0) continue;
    std::vector<int> fan, next;
    int f = start;
    bool closed = false;
    for (int step = 0; step < 6; ++step) {
      const auto& x = faces[f];
      const int n = x[(slot(x, v) + 1) % x.size()];
      fan.push_back(f);
      next.push_back(n);
      f = face_of(n, v);
      if (f < 0) break;
      if (f == start) {
        closed = step == 5;
        break;
      }
    }
    if (!closed) continue;
    bool free = true;
    for (int g : fan) free = free && !touched[g];
    if (!free) continue;
    // A triangle in the fan, preferring one whose opposite face is a triangle too.
    int t = -1;
    for (int k = 0; k < 6; ++k)
      if (faces[fan[k]].size() == 3 && faces[fan[(k + 3) % 6]].size() <= 4 &&
          (t < 0 || faces[fan[(k + 3) % 6]].size() == 3))
        t = k;
    if (t < 0) continue;
    // v1 takes the edges to next_t, next_{t+1}, next_{t+2}; v2 the other three.
    const int v1 = mesh.num_vertices(), v2 = v1 + 1;
    Vec3 m1 = Vec3::Zero(), m2 = Vec3::Zero();
    for (int k = 0; k < 3; ++k) {
      m1 += mesh.positions[next[(t + k) % 6]];
      m2 += mesh.positions[next[(t + 3 + k) % 6]];
    }
    const Vec3 p = mesh.positions[v];
    mesh.positions.push_back(p + 0.3 * (m1 / 3.0 - p));
    mesh.positions.push_back(p + 0.3 * (m2 / 3.0 - p));
    kind.push_back(kNoFeature);
    kind.push_back(kNoFeature);
    for (int k = 1; k <= 2; ++k) std::replace(faces[fan[(t + k) % 6]].begin(), faces[fan[(t + k) % 6]].end(), v, v1);
    for (int k = 4; k <= 5; ++k) std::replace(faces[fan[(t + k) % 6]].begin(), faces[fan[(t + k) % 6]].end(), v, v2);
    auto& tri = faces[fan[t]];  // (.., prev_t, v, next_t, ..): v becomes v2, v1
    tri.insert(tri.begin() + slot(tri, v) + 1, v1);
    *std::find(tri.begin(), tri.end(), v) = v2;
    auto& opp = faces[fan[(t + 3) % 6]];  // (.., next_{t+2}, v, prev_{t+4}, ..): v becomes v1, v2
    opp.insert(opp.begin() + slot(opp, v) + 1, v2);
    *std::find(opp.begin(), opp.end(), v) = v1;
    for (int g : fan) touched[g] = 1;
    ++split;
  }
  if (split) set_faces(mesh, faces);
  return split;
}

int merge_cone_vertices(PolygonMesh& mesh, const std::vector<char>& kind) {
  std::vector<std::vector<int>> faces = face_lists(mesh);
  auto dir = directed_face_map(faces);
  const VertexValence vv = vertex_valences(mesh);
  std::vector<std::vector<int>> neighbours(mesh.num_vertices());
  for (const auto& f : faces)
    for (size_t i = 0; i < f.size(); ++i) {
      neighbours[f[i]].push_back(f[(i + 1) % f.size()]);
      neighbours[f[i]].push_back(f[(i + f.size() - 1) % f.size()]);
    }
  for (auto& n : neighbours) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
  auto face_of = [&](int a, int b) {
    auto it = dir.find((static_cast<long long>(a) << 32) | static_cast<unsigned int>(b));
    return it == dir.end() ? -1 : it->second;
  };
  std::vector<char> touched(faces.size(), 0), gone(mesh.num_vertices(), 0);
  int merged = 0;
  for (int u = 0; u < mesh.num_vertices(); ++u) {
    if (vv.valence[u] != 3 || vv.boundary[u] || kind[u] != kNoFeature || gone[u]) continue;
    for (int w : neighbours[u]) {
      if (w < u || vv.valence[w] != 3 || vv.boundary[w] || kind[w] != kNoFeature || gone[w]) continue;
      const int f = face_of(u, w), g = face_of(w, u);
      if (f < 0 || g < 0 || touched[f] || touched[g]) continue;
      const size_t a = faces[f].size(), b = faces[g].size();
      // a pentagon and a quad (-> a quad and a triangle) or two pentagons (-> two quads)
      if (!((a == 5 && b == 4) || (a == 4 && b == 5) || (a == 5 && b == 5))) continue;
      // link condition: u and w have no other common neighbour
      std::vector<int> common;
      std::set_intersection(neighbours[u].begin(), neighbours[u].end(), neighbours[w].begin(), neighbours[w].end(),
                            std::back_inserter(common));
      if (!common.empty()) continue;
      bool free = true;
      for (size_t k = 0; k < faces.size() && free; ++k)
        if (touched[k] && (std::count(faces[k].begin(), faces[k].end(), u) || std::count(faces[k].begin(), faces[k].end(), w)))
          free = false;
      if (!free) continue;
      // w goes into u, at the middle of the edge
      mesh.positions[u] = 0.5 * (mesh.positions[u] + mesh.positions[w]);
      for (auto& face : faces) {
        if (!std::count(face.begin(), face.end(), w)) continue;
        std::replace(face.begin(), face.end(), w, u);
        std::vector<int> dedup;
        for (size_t i = 0; i < face.size(); ++i)
          if (face[i] != face[(i + 1) % face.size()]) dedup.push_back(face[i]);
        face = dedup;
        touched[&face - faces.data()] = 1;
      }
      for (auto& face : faces)
        if (std::count(face.begin(), face.end(), u)) touched[&face - faces.data()] = 1;
      gone[w] = 1;
      ++merged;
      break;
    }
  }
  if (merged) set_faces(mesh, faces);
  return merged;
}

int remove_doublets_at(PolygonMesh& mesh, const std::vector<char>& kind, const std::vector<char>& vertices) {
  return remove_doublets(mesh, kind, &vertices);
}

int pair_triangles_through_strips(PolygonMesh& mesh, double min_jacobian, int max_quads) {
  std::vector<std::vector<int>> faces = face_lists(mesh);
  auto dir = directed_face_map(faces);
  std::vector<int> valence = vertex_valences(mesh).valence;
  auto face_across = [&](int u, int v) {  // the face containing v -> u (across the edge u -> v)
    auto it = dir.find((static_cast<long long>(v) << 32) | static_cast<unsigned int>(u));
    return it == dir.end() ? -1 : it->second;
  };
  struct Candidate {
    int gain;
    double quality;
    std::vector<int> strip;                   // faces: T1, quads..., T2
    std::vector<std::vector<int>> replacement;
    int v0, v1;                               // the two vertices losing an edge
  };
  std::vector<Candidate> cands;
  const int F = static_cast<int>(faces.size());
  for (int t1 = 0; t1 < F; ++t1) {
    if (faces[t1].size() != 3) continue;
    for (int c = 0; c < 3; ++c) {
      const int a = faces[t1][c];
      std::vector<int> A = {faces[t1][(c + 1) % 3]}, B = {faces[t1][(c + 2) % 3]};  // T1 = (a, A0, B0)
      std::vector<int> strip = {t1};
      int b = -1;
      for (int step = 0; step <= max_quads; ++step) {
        const int g = face_across(A.back(), B.back());  // contains B -> A
        if (g < 0 || std::find(strip.begin(), strip.end(), g) != strip.end()) break;
        const auto& fg = faces[g];
        const int kg = static_cast<int>(fg.size());
        const int ib = static_cast<int>(std::find(fg.begin(), fg.end(), B.back()) - fg.begin());
        if (ib == kg || fg[(ib + 1) % kg] != A.back()) break;
        if (kg == 3) {
          if (step == 0 || g < t1) break;  // adjacent triangles are merged elsewhere; each strip once
          b = fg[(ib + 2) % 3];
          strip.push_back(g);
          break;
        }
        if (kg != 4) break;
        // g = (B_i, A_i, A_{i+1}, B_{i+1})
        A.push_back(fg[(ib + 2) % 4]);
        B.push_back(fg[(ib + 3) % 4]);
        strip.push_back(g);
      }
      if (b < 0) continue;
      const int k = static_cast<int>(A.size()) - 1;
      std::vector<int> all = {a, b};
      all.insert(all.end(), A.begin(), A.end());
      all.insert(all.end(), B.begin(), B.end());
      std::sort(all.begin(), all.end());
      if (std::adjacent_find(all.begin(), all.end()) != all.end()) continue;
      for (int variant = 0; variant < 2; ++variant) {
        std::vector<std::vector<int>> rep;
        int v0, v1;
        if (variant == 0) {  // rungs A_i - B_{i+1}
          rep.push_back({a, A[0], B[1], B[0]});
          for (int i = 1; i < k; ++i) rep.push_back({A[i - 1], A[i], B[i + 1], B[i]});
          rep.push_back({A[k - 1], A[k], b, B[k]});
          v0 = A[k];
          v1 = B[0];
        } else {  // rungs B_i - A_{i+1}
          rep.push_back({a, A[0], A[1], B[0]});
          for (int i = 1; i < k; ++i) rep.push_back({B[i - 1], A[i], A[i + 1], B[i]});
          rep.push_back({B[k - 1], A[k], b, B[k]});
          v0 = A[0];
          v1 = B[k];
        }
        const int gain = std::abs(valence[v0] - 4) + std::abs(valence[v1] - 4) - std::abs(valence[v0] - 5) -
                         std::abs(valence[v1] - 5);
        if (gain <= 0) continue;
        double q = 1;
        for (const auto& f : rep) q = std::min(q, polygon_min_jacobian(mesh.positions, f));
        if (q > min_jacobian) cands.push_back({gain, q, strip, rep, v0, v1});
      }
    }
  }
  std::sort(cands.begin(), cands.end(), [](const Candidate& x, const Candidate& y) {
    return x.gain != y.gain ? x.gain > y.gain : (x.strip.size() != y.strip.size() ? x.strip.size() < y.strip.size()
                                                                                   : x.quality > y.quality);
  });
  std::vector<char> used(F, 0), touched(mesh.num_vertices(), 0);
  int done = 0;
  for (auto& c : cands) {
    bool free = !touched[c.v0] && !touched[c.v1];
    for (int f : c.strip) free = free && !used[f];
    if (!free) continue;
    for (int f : c.strip) used[f] = 1;
    touched[c.v0] = touched[c.v1] = 1;  // their valences change: later candidates computed them before
    for (size_t i = 0; i < c.strip.size(); ++i) faces[c.strip[i]] = i < c.replacement.size() ? c.replacement[i] : std::vector<int>{};
    ++done;
  }
  set_faces(mesh, faces);
  return done;
}

double polygon_min_jacobian(const std::vector<Vec3>& P, const std::vector<int>& poly) {
  return polygon_min_jacobian(P, poly, std::vector<char>());
}

double polygon_min_jacobian(const std::vector<Vec3>& P, const std::vector<int>& poly, const std::vector<char>& skip) {
  const int k = static_cast<int>(poly.size());
  const Vec3 n = polygon_normal(P, poly);
  if (n.isZero()) return -1;
  double worst = 1;
  for (int i = 0; i < k; ++i) {
    if (poly[i] < static_cast<int>(skip.size()) && skip[poly[i]]) continue;
    const Vec3 e1 = P[poly[(i + 1) % k]] - P[poly[i]], e2 = P[poly[(i + k - 1) % k]] - P[poly[i]];
    const double l = e1.norm() * e2.norm();
    worst = std::min(worst, l > 0 ? e1.cross(e2).dot(n) / l : -1.0);
  }
  return worst;
}

CleanupReport clean_up_quads(PolygonMesh& mesh, std::vector<char>& kind, double min_jacobian) {
  CleanupReport report;
  std::vector<std::vector<int>> faces = face_lists(mesh);
  set_faces(mesh, faces);
  report.doublets = remove_doublets(mesh, kind, nullptr);
  faces = face_lists(mesh);
  // Triangle pairs and triangle + pentagon pairs, best first.
  set_faces(mesh, faces);
  faces = face_lists(mesh);
  {
    const VertexValence vv = vertex_valences(mesh);
    std::vector<int> valence = vv.valence;
    auto dir = directed_face_map(faces);
    struct Candidate {
      double quality;
      int f, g;
      std::vector<int> a, b;  // replacement faces (b empty: one face)
      int bonus;
    };
    std::vector<Candidate> cands;
    for (int f = 0; f < static_cast<int>(faces.size()); ++f) {
      if (faces[f].size() != 3) continue;
      const auto& p = faces[f];
      for (int i = 0; i < 3; ++i) {
        const int u = p[i], v = p[(i + 1) % 3];
        auto it = dir.find((static_cast<long long>(v) << 32) | static_cast<unsigned int>(u));
        if (it == dir.end()) continue;
        const int g = it->second;
        const size_t kg = faces[g].size();
        if (g == f || (kg != 3 && kg != 5) || (kg == 3 && g < f)) continue;
        const std::vector<int> un = merge_polygons_across(p, faces[g], u, v);
        if (kg == 3) {
          const double q = polygon_min_jacobian(mesh.positions, un);
          if (q > min_jacobian) cands.push_back({q + 1.0, f, g, un, {}, 0});
          continue;
        }
        // Hexagon: try the three diagonals (j, j + 3).
        for (int j = 0; j < 3; ++j) {
          std::vector<int> qa = {un[j], un[j + 1], un[j + 2], un[j + 3]};
          std::vector<int> qb = {un[j + 3], un[(j + 4) % 6], un[(j + 5) % 6], un[j]};
          // Valence change: edge (u, v) removed, edge (un[j], un[j+3]) added.
          auto irr = [&](int x, int dv) { return std::abs(valence[x] + dv - 4); };
          int before = 0, after = 0;
          std::vector<int> touched = {u, v, un[j], un[j + 3]};
          std::sort(touched.begin(), touched.end());
          touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
          for (int x : touched) {
            const int dv = (x == un[j] || x == un[j + 3] ? 1 : 0) - (x == u || x == v ? 1 : 0);
            before += irr(x, 0);
            after += irr(x, dv);
          }
          if (after > before) continue;
          const double q = std::min(polygon_min_jacobian(mesh.positions, qa), polygon_min_jacobian(mesh.positions, qb));
          if (q > min_jacobian) cands.push_back({q, f, g, qa, qb, before - after});
        }
      }
    }
    std::sort(cands.begin(), cands.end(), [](const Candidate& x, const Candidate& y) { return x.quality > y.quality; });
    std::vector<char> done(faces.size(), 0);
    for (auto& c : cands) {
      if (done[c.f] || done[c.g]) continue;
      // Valences may have changed since the candidate was made only through faces already done; the
      // touched faces are fresh, so the candidate still stands.
      done[c.f] = done[c.g] = 1;
      faces[c.f] = c.a;
      faces[c.g] = c.b;
      (c.b.empty() ? report.triangle_pairs : report.triangle_pentagon_pairs)++;
    }
  }
  set_faces(mesh, faces);
  report.triangle_strips = pair_triangles_through_strips(mesh, min_jacobian);
  report.doublets += remove_doublets(mesh, kind, nullptr);  // merging triangle pairs can leave valence-2 vertices
  report.split_cones = split_cone_vertices(mesh, kind);
  report.merged_cones = merge_cone_vertices(mesh, kind);
  const std::vector<int> old = compact_vertices(mesh);
  std::vector<char> k2(old.size());
  for (size_t i = 0; i < old.size(); ++i) k2[i] = kind[old[i]];
  kind = std::move(k2);
  return report;
}

int split_large_faces(PolygonMesh& mesh, std::vector<char>& kind, const ProjectionTargets& targets, int min_size) {
  std::vector<std::vector<int>> faces = face_lists(mesh);
  std::vector<std::vector<int>> out;
  int split = 0;
  for (auto& f : faces) {
    const int k = static_cast<int>(f.size());
    if (k < min_size) {
      out.push_back(f);
      continue;
    }
    Vec3 c = Vec3::Zero();
    for (int v : f) c += mesh.positions[v];
    c /= k;
    const auto hit = targets.surface.closest(c);
    const int centre = mesh.num_vertices();
    mesh.positions.push_back(hit.triangle >= 0 ? hit.point : c);
    kind.push_back(kNoFeature);
    for (int i = 0; i + 2 <= k; i += 2) {
      if (i + 2 < k || k % 2 == 0) out.push_back({centre, f[i], f[i + 1], f[(i + 2) % k]});
    }
    if (k % 2 == 1) out.push_back({centre, f[k - 1], f[0]});
    ++split;
  }
  set_faces(mesh, out);
  return split;
}

void relax_vertices(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets, int iterations,
                    const std::vector<char>* movable) {
  const int V = mesh.num_vertices();
  for (int it = 0; it < iterations; ++it) {
    const std::vector<Vec3> before = movable ? mesh.positions : std::vector<Vec3>();
    std::vector<Vec3> sum(V, Vec3::Zero()), normal(V, Vec3::Zero());
    std::vector<int> count(V, 0);
    for (int f = 0; f < mesh.num_faces(); ++f) {
      const Vec3 c = polygon_centroid(mesh, f);
      const Vec3 n = polygon_normal(mesh, f);
      for (int i = 0; i < mesh.face_size(f); ++i) {
        sum[mesh.face(f)[i]] += c;
        normal[mesh.face(f)[i]] += n;
        ++count[mesh.face(f)[i]];
      }
    }
    for (int v = 0; v < V; ++v) {
      if (count[v] == 0 || kind[v] == kCorner || (movable && !(*movable)[v])) continue;
      // Tangential: the move keeps no part along the vertex's normal, so the vertex stays near the surface
      // and its projection near where it was (on a fingertip the centroids lie inside the part, and their
      // nearest surface point would be the tip for every vertex around it).
      Vec3 d = 0.5 * (sum[v] / count[v] - mesh.positions[v]);
      if (normal[v].norm() > 0) d -= normal[v].normalized() * normal[v].normalized().dot(d);
      mesh.positions[v] += d;
    }
    project_vertices(mesh, kind, targets);
    if (movable)
      for (int v = 0; v < V; ++v)
        if (!(*movable)[v]) mesh.positions[v] = before[v];
  }
}

}  // namespace nfield::remesh
