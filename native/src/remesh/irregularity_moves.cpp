#include "nfield/remesh/irregularity_moves.hpp"

#include <algorithm>
#include <cmath>

#include "nfield/remesh/quad_cleanup.hpp"
#include "nfield/remesh/quad_stats.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

namespace {

/// Smallest cosine between a corner's normal (e1 x e2) and the polygon's Newell normal: 1 for a flat
/// polygon, low for one bent across a crease (its corners' Jacobians can all stay positive).
double polygon_flatness(const std::vector<Vec3>& P, const std::vector<int>& poly) {
  const int k = static_cast<int>(poly.size());
  const Vec3 n = polygon_normal(P, poly);
  if (n.isZero()) return -1;
  double worst = 1;
  for (int i = 0; i < k; ++i) {
    const Vec3 c = (P[poly[(i + 1) % k]] - P[poly[i]]).cross(P[poly[(i + k - 1) % k]] - P[poly[i]]);
    worst = std::min(worst, c.norm() > 0 ? c.dot(n) / c.norm() : -1.0);
  }
  return worst;
}

}  // namespace

int lower_irregularity(PolygonMesh& mesh, const std::vector<char>& kind, double min_jacobian, int max_rounds,
                       std::vector<char>* changed) {
  int done = 0;
  if (changed) changed->assign(mesh.num_vertices(), 0);
  for (int round = 0; round < max_rounds; ++round) {
    std::vector<std::vector<int>> faces = face_lists(mesh);
    auto dir = directed_face_map(faces);
    const VertexValence vv = vertex_valences(mesh);
    const int V = mesh.num_vertices();
    std::vector<std::vector<int>> neighbours(V), around(V);
    for (int f = 0; f < static_cast<int>(faces.size()); ++f)
      for (size_t i = 0; i < faces[f].size(); ++i) {
        const int a = faces[f][i], b = faces[f][(i + 1) % faces[f].size()];
        neighbours[a].push_back(b);
        neighbours[b].push_back(a);
        around[a].push_back(f);
      }
    for (auto& n : neighbours) {
      std::sort(n.begin(), n.end());
      n.erase(std::unique(n.begin(), n.end()), n.end());
    }
    // Only interior vertices off the feature curves change valence; irregularity counted as in quad_stats
    // (interior: valence != 4), with the excess |valence - 4| as the tie-break.
    // A face the moves make must be about as flat as the faces it replaces (or bent by less than about 25
    // degrees at a corner): next to a crease a rotated edge can join the two sides, and the face then cuts
    // across the crease (fandisk: 0.30 -> 0.33% one-sided distance without this guard).
    constexpr double kFlat = 0.9;
    auto free_vertex = [&](int v) { return !vv.boundary[v] && kind[v] == kNoFeature && vv.valence[v] > 0; };
    struct Candidate {
      int count_gain, excess_gain;
      double quality;
      std::vector<int> faces;                    // faces replaced (the first ones by `replacement`, the rest emptied)
      std::vector<std::vector<int>> replacement;
      int keep = -1, drop = -1;                  // diagonal collapse: `drop` merges into `keep`
      std::vector<int> vertices;                 // vertices whose valence changes
    };
    auto score = [&](const std::vector<std::pair<int, int>>& change, Candidate& c) {
      int count = 0, excess = 0;
      for (const auto& [v, dv] : change) {
        count += (vv.valence[v] != 4) - (vv.valence[v] + dv != 4);
        excess += std::abs(vv.valence[v] - 4) - std::abs(vv.valence[v] + dv - 4);
        c.vertices.push_back(v);
      }
      c.count_gain = count;
      c.excess_gain = excess;
      return count > 0 || (count == 0 && excess > 0);
    };
    std::vector<Candidate> cands;
    // Edge rotations: two quads sharing an interior edge (u, v) form a hexagon, re-split along one of its two
    // other diagonals: u and v lose an edge, the new diagonal's ends gain one.
    for (int f = 0; f < static_cast<int>(faces.size()); ++f) {
      if (faces[f].size() != 4) continue;
      for (int i = 0; i < 4; ++i) {
        const int u = faces[f][i], v = faces[f][(i + 1) % 4];
        auto it = dir.find((static_cast<long long>(v) << 32) | static_cast<unsigned int>(u));
        if (it == dir.end()) continue;
        const int g = it->second;
        if (g <= f || faces[g].size() != 4 || !free_vertex(u) || !free_vertex(v)) continue;
        const std::vector<int> h = merge_polygons_across(faces[f], faces[g], u, v);  // v a b u c d
        std::vector<int> sorted = h;
        std::sort(sorted.begin(), sorted.end());
        if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) continue;
        for (int j = 1; j <= 2; ++j) {
          const int x = h[j], y = h[j + 3];
          if (!free_vertex(x) || !free_vertex(y) || std::binary_search(neighbours[x].begin(), neighbours[x].end(), y)) continue;
          Candidate c;
          if (!score({{u, -1}, {v, -1}, {x, 1}, {y, 1}}, c)) continue;
          c.faces = {f, g};
          c.replacement = {{h[j], h[j + 1], h[j + 2], h[j + 3]}, {h[j + 3], h[(j + 4) % 6], h[(j + 5) % 6], h[j]}};
          c.quality = std::min(polygon_min_jacobian(mesh.positions, c.replacement[0]),
                               polygon_min_jacobian(mesh.positions, c.replacement[1]));
          if (std::min(polygon_flatness(mesh.positions, c.replacement[0]), polygon_flatness(mesh.positions, c.replacement[1])) <
              std::min({kFlat, polygon_flatness(mesh.positions, faces[f]), polygon_flatness(mesh.positions, faces[g])}))
            continue;
          if (c.quality > min_jacobian) cands.push_back(std::move(c));
        }
      }
    }
    // Diagonal collapses: a quad (a, b, c, d) loses its diagonal a-c (a and c merge at their midpoint): the
    // merged vertex has valence(a) + valence(c) - 2, b and d lose an edge.
    std::vector<Vec3> moved = mesh.positions;
    for (int f = 0; f < static_cast<int>(faces.size()); ++f) {
      if (faces[f].size() != 4) continue;
      for (int i = 0; i < 2; ++i) {
        const int a = faces[f][i], b = faces[f][i + 1], c2 = faces[f][i + 2], d = faces[f][(i + 3) % 4];
        if (!free_vertex(a) || !free_vertex(c2) || !free_vertex(b) || !free_vertex(d) ||
            std::binary_search(neighbours[a].begin(), neighbours[a].end(), c2))
          continue;
        // Link condition: a and c share no neighbour but b and d, so the merge keeps the mesh a manifold.
        std::vector<int> common;
        std::set_intersection(neighbours[a].begin(), neighbours[a].end(), neighbours[c2].begin(), neighbours[c2].end(),
                              std::back_inserter(common));
        if (common.size() != 2 || vv.valence[b] < 4 || vv.valence[d] < 4) continue;  // b, d keep valence >= 3
        Candidate c;
        const int merged = vv.valence[a] + vv.valence[c2] - 2;
        int count = (vv.valence[a] != 4) + (vv.valence[c2] != 4) - (merged != 4);
        int excess = std::abs(vv.valence[a] - 4) + std::abs(vv.valence[c2] - 4) - std::abs(merged - 4);
        for (int w : {b, d}) {
          count += (vv.valence[w] != 4) - (vv.valence[w] - 1 != 4);
          excess += std::abs(vv.valence[w] - 4) - std::abs(vv.valence[w] - 5);
        }
        if (!(count > 0 || (count == 0 && excess > 0))) continue;
        c.count_gain = count;
        c.excess_gain = excess;
        c.vertices = {a, b, c2, d};
        c.keep = a;
        c.drop = c2;
        // The faces around a and c (but f) with c renamed a; a degenerate face (a repeated) loses the repeat.
        std::vector<int> touched = around[a];
        touched.insert(touched.end(), around[c2].begin(), around[c2].end());
        std::sort(touched.begin(), touched.end());
        touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
        moved[a] = 0.5 * (mesh.positions[a] + mesh.positions[c2]);
        c.quality = 1;
        bool ok = true;
        double flat_before = kFlat, flat_after = 1;
        for (int t : touched) {
          c.faces.push_back(t);
          flat_before = std::min(flat_before, polygon_flatness(mesh.positions, faces[t]));
          if (t == f) {
            c.replacement.push_back({});
            continue;
          }
          std::vector<int> r = faces[t];
          std::replace(r.begin(), r.end(), c2, a);
          if (std::count(r.begin(), r.end(), a) > 1 || r.size() < 3) ok = false;
          c.quality = std::min(c.quality, polygon_min_jacobian(moved, r));
          flat_after = std::min(flat_after, polygon_flatness(moved, r));
          c.replacement.push_back(r);
        }
        ok = ok && flat_after >= flat_before;
        moved[a] = mesh.positions[a];
        if (ok && c.quality > min_jacobian) cands.push_back(std::move(c));
      }
    }
    std::sort(cands.begin(), cands.end(), [](const Candidate& x, const Candidate& y) {
      if (x.count_gain != y.count_gain) return x.count_gain > y.count_gain;
      if (x.excess_gain != y.excess_gain) return x.excess_gain > y.excess_gain;
      return x.quality > y.quality;
    });
    std::vector<char> used(faces.size(), 0), touched(V, 0);
    int applied = 0;
    for (auto& c : cands) {
      bool free = true;
      for (int f : c.faces) free = free && !used[f];
      for (int v : c.vertices) free = free && !touched[v];
      if (!free) continue;
      // The valences these vertices had when the candidate was scored change now: later candidates that
      // share one of them, or one of these faces, wait for the next round.
      for (int f : c.faces) {
        used[f] = 1;
        for (int w : faces[f]) touched[w] = 1;
      }
      for (int v : c.vertices) touched[v] = 1;
      if (c.drop >= 0) mesh.positions[c.keep] = 0.5 * (mesh.positions[c.keep] + mesh.positions[c.drop]);
      for (size_t i = 0; i < c.faces.size(); ++i) {
        faces[c.faces[i]] = c.replacement[i];
        if (changed)
          for (int w : c.replacement[i]) (*changed)[w] = 1;
      }
      ++applied;
    }
    set_faces(mesh, faces);
    done += applied;
    if (!applied) break;
  }
  return done;
}

}  // namespace nfield::remesh
