#include "nfield/remesh/pure_quads.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <unordered_map>
#include <unordered_set>

#include "nfield/remesh/quad_cleanup.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

namespace {

/// Below this worst corner (scaled Jacobian) a split along a diagonal leaves a nearly flat or folded
/// corner (a midpoint between two straight halves of an edge scores 0); a centre vertex is then tried.
constexpr double kFlatCorner = 0.15;
/// A path end whose fixed corners (old vertices, feature midpoints) score at most this is taken only when
/// every choice does.
constexpr double kFlatEnd = 0.02;
/// Extra path costs, in face steps: a turn inside a quad adds a centre vertex of valence 3 and raises a
/// corner to valence 5; a midpoint on a feature edge is a T-junction on the feature curve.
constexpr double kTurnCost = 3, kFeatureCost = 2, kFeatureEndCost = 20, kNonQuadCost = 1;
/// A pentagon left or entered where its split needs a centre vertex: two irregular vertices, as a turn,
/// and no clean alternative nearby (so twice a turn: a straight half row several faces longer is better).
constexpr double kUncleanEndCost = 6;

inline long long directed_key(int a, int b) { return (static_cast<long long>(a) << 32) | static_cast<unsigned int>(b); }

bool has_repeated_vertex(std::vector<int> p) {
  std::sort(p.begin(), p.end());
  return std::adjacent_find(p.begin(), p.end()) != p.end();
}

double worst_corner(const std::vector<Vec3>& P, const std::vector<std::vector<int>>& quads) {
  double q = 1;
  for (const auto& f : quads) q = std::min(q, polygon_min_jacobian(P, f));
  return q;
}

/// The quads around a centre vertex c joined to every other corner of p, starting at corner `parity`.
std::vector<std::vector<int>> fan_around(const std::vector<int>& p, int c, int parity) {
  const int n = static_cast<int>(p.size());
  std::vector<std::vector<int>> out;
  for (int j = parity; j < n + parity; j += 2) out.push_back({c, p[j % n], p[(j + 1) % n], p[(j + 2) % n]});
  return out;
}

/// Quads cut off one at a time (the cut with the best worst corner of the quad and the rest), down to 4.
std::vector<std::vector<int>> shed_quads(const std::vector<Vec3>& P, std::vector<int> p) {
  std::vector<std::vector<int>> out;
  while (p.size() > 4) {
    const int n = static_cast<int>(p.size());
    int best = 0;
    double best_q = -std::numeric_limits<double>::infinity();
    for (int i = 0; i < n; ++i) {
      const std::vector<int> quad = {p[i], p[(i + 1) % n], p[(i + 2) % n], p[(i + 3) % n]};
      std::vector<int> rest;
      for (int t = 0; t < n - 2; ++t) rest.push_back(p[(i + 3 + t) % n]);
      const double q = std::min(polygon_min_jacobian(P, quad), polygon_min_jacobian(P, rest));
      if (q > best_q) best_q = q, best = i;
    }
    out.push_back({p[best], p[(best + 1) % n], p[(best + 2) % n], p[(best + 3) % n]});
    std::vector<int> rest;
    for (int t = 0; t < n - 2; ++t) rest.push_back(p[(best + 3 + t) % n]);
    p = std::move(rest);
  }
  out.push_back(p);
  return out;
}

/// Whether a pentagon given a midpoint on its side j splits along a diagonal into two quads without a flat
/// corner (a pentagon with a straight corner, a quad with a T-junction, does so only from the side opposite
/// that corner).
bool pentagon_splits_cleanly(const std::vector<Vec3>& positions, const std::vector<int>& face, int j) {
  std::vector<Vec3> P;
  for (size_t t = 0; t < face.size(); ++t) {
    P.push_back(positions[face[t]]);
    if (static_cast<int>(t) == j) P.push_back(0.5 * (positions[face[t]] + positions[face[(t + 1) % face.size()]]));
  }
  for (int i = 0; i < 3; ++i) {
    const std::vector<std::vector<int>> q = {{i, i + 1, i + 2, i + 3}, {i + 3, (i + 4) % 6, (i + 5) % 6, i}};
    if (worst_corner(P, q) >= kFlatCorner) return true;
  }
  return false;
}

}  // namespace

std::vector<std::vector<int>> split_even_polygon(std::vector<Vec3>& P, const std::vector<int>& p, bool* added_centre,
                                                 const std::vector<int>* valence) {
  if (added_centre) *added_centre = false;
  if (p.size() <= 4) return {p};
  if (p.size() > 8) return shed_quads(P, p);
  // Candidates: the cuts into quads along diagonals (every split of a hexagon; for an octagon the greedy
  // one) and the fans around a centre vertex. Among those without a flat or folded corner the one adding
  // the fewest irregular vertices wins (then the best worst corner); if none, the best worst corner.
  auto cost_of_edge_to = [&](int v) {  // change of |valence - 4| when v gains an edge
    if (!valence || v >= static_cast<int>(valence->size())) return -1;  // a new midpoint: wants its edge
    return (*valence)[v] >= 4 ? 1 : -1;
  };
  struct Candidate {
    std::vector<std::vector<int>> quads;
    bool centre;
    double worst;
    int cost;
  };
  std::vector<Candidate> cands;
  const int n = static_cast<int>(p.size());
  if (n == 6) {
    for (int i = 0; i < 3; ++i) {
      std::vector<std::vector<int>> q = {{p[i], p[i + 1], p[i + 2], p[i + 3]}, {p[i + 3], p[(i + 4) % 6], p[(i + 5) % 6], p[i]}};
      const double w = worst_corner(P, q);
      cands.push_back({std::move(q), false, w, cost_of_edge_to(p[i]) + cost_of_edge_to(p[i + 3])});
    }
  } else {
    std::vector<std::vector<int>> q = shed_quads(P, p);
    const double w = worst_corner(P, q);
    cands.push_back({std::move(q), false, w, 0});
  }
  Vec3 c = Vec3::Zero();
  for (int v : p) c += P[v];
  P.push_back(c / static_cast<double>(n));
  const int centre = static_cast<int>(P.size()) - 1;
  for (int parity = 0; parity < 2; ++parity) {
    std::vector<std::vector<int>> q = fan_around(p, centre, parity);
    int cost = std::abs(n / 2 - 4);
    for (int j = parity; j < n; j += 2) cost += cost_of_edge_to(p[j]);
    const double w = worst_corner(P, q);
    cands.push_back({std::move(q), true, w, cost});
  }
  auto better = [](const Candidate& a, const Candidate& b) {
    const bool fa = a.worst >= kFlatCorner, fb = b.worst >= kFlatCorner;
    if (fa != fb) return fa;
    if (!fa) return a.worst > b.worst;
    if (a.cost != b.cost) return a.cost < b.cost;
    return a.worst > b.worst;
  };
  const Candidate* best = &cands[0];
  for (const auto& k : cands)
    if (better(k, *best)) best = &k;
  if (!best->centre) P.pop_back();
  if (added_centre) *added_centre = best->centre;
  return best->quads;
}

PureQuadReport convert_to_pure_quads(PolygonMesh& mesh, std::vector<char>& kind, const ProjectionTargets& targets) {
  PureQuadReport report;
  std::vector<std::vector<int>> faces = face_lists(mesh);
  auto odd = [&](int f) { return faces[f].size() % 2 == 1; };
  for (int f = 0; f < static_cast<int>(faces.size()); ++f) report.odd_faces += odd(f);
  std::unordered_map<long long, char> feature_cache;
  auto is_feature = [&](int a, int b) {
    if (!kind[a] || !kind[b] || targets.feature_edges.empty()) return false;
    auto [it, fresh] = feature_cache.emplace(undirected_edge_key(a, b), 0);
    if (fresh) {
      const Vec3 m = 0.5 * (mesh.positions[a] + mesh.positions[b]);
      const double length = (mesh.positions[a] - mesh.positions[b]).norm();
      it->second = std::sqrt(targets.feature_edges.closest(m).squared_distance) < 0.25 * length;
    }
    return it->second != 0;
  };
  std::vector<char> unpaired;
  for (;;) {
    unpaired.resize(faces.size(), 0);
    int f0 = -1;
    for (int f = 0; f < static_cast<int>(faces.size()) && f0 < 0; ++f)
      if (odd(f) && !unpaired[f]) f0 = f;
    if (f0 < 0) break;
    std::vector<int> valence(mesh.num_vertices(), 0);
    for (const auto& f : faces)
      for (size_t j = 0; j < f.size(); ++j) ++valence[f[j]];  // faces around a vertex: its valence inside
    std::unordered_map<long long, std::pair<int, int>> side_of;  // directed edge -> (face, side)
    for (int f = 0; f < static_cast<int>(faces.size()); ++f)
      for (size_t j = 0; j < faces[f].size(); ++j)
        side_of[directed_key(faces[f][j], faces[f][(j + 1) % faces[f].size()])] = {f, static_cast<int>(j)};
    std::vector<char> boundary(mesh.num_vertices(), 0);
    for (const auto& f : faces)
      for (size_t j = 0; j < f.size(); ++j)
        if (!side_of.count(directed_key(f[(j + 1) % f.size()], f[j]))) boundary[f[j]] = boundary[f[(j + 1) % f.size()]] = 1;

    // Dijkstra on the faces from each odd face to the nearest other odd face or out across the boundary;
    // the cheapest of these paths is made first (a greedy matching: short straight pairs before long
    // bent ones).
    const int F = static_cast<int>(faces.size());
    std::vector<double> dist(F, std::numeric_limits<double>::infinity());
    std::vector<int> entry(F, -1), pred_face(F, -1), pred_side(F, -1);
    double boundary_cost = 0;
    int boundary_face = -1, boundary_side = -1, target = -1;
    std::vector<int> touched;
    auto search = [&](int from) {
      for (int f : touched) dist[f] = std::numeric_limits<double>::infinity(), entry[f] = pred_face[f] = pred_side[f] = -1;
      touched.assign(1, from);
      boundary_cost = std::numeric_limits<double>::infinity();
      boundary_face = boundary_side = target = -1;
      using Item = std::pair<double, int>;
      std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
      dist[from] = 0;
      queue.push({0, from});
      while (!queue.empty()) {
        const auto [d, f] = queue.top();
        queue.pop();
        if (d > dist[f]) continue;
        if (d >= boundary_cost) break;
        if (f != from && odd(f)) {
          target = f;
          return d;
        }
        const int k = static_cast<int>(faces[f].size());
        for (int j = 0; j < k; ++j) {
          if (j == entry[f]) continue;
          const int a = faces[f][j], b = faces[f][(j + 1) % k];
          double step = 1;
          if (f != from && k == 4 && j != (entry[f] + 2) % 4) step += kTurnCost;
          if (f != from && k != 4) step += kNonQuadCost;
          auto it = side_of.find(directed_key(b, a));
          // A feature edge is crossed at a cost; as the first or last step of a path it cannot be merged
          // across, and its midpoint, held on the feature, would leave a flat corner in the odd face.
          const bool at_end = f == from || (it != side_of.end() && odd(it->second.first));
          if (is_feature(a, b)) step += at_end ? kFeatureEndCost : kFeatureCost;
          // Leaving or entering a pentagon by a side whose midpoint leaves it no clean split costs extra.
          if (f == from && k == 5 && !pentagon_splits_cleanly(mesh.positions, faces[f], j)) step += kUncleanEndCost;
          if (it != side_of.end() && odd(it->second.first) && faces[it->second.first].size() == 5 &&
              !pentagon_splits_cleanly(mesh.positions, faces[it->second.first], it->second.second))
            step += kUncleanEndCost;
          if (it == side_of.end()) {
            if (d + step < boundary_cost) boundary_cost = d + step, boundary_face = f, boundary_side = j;
            continue;
          }
          const auto [g, jg] = it->second;
          if (d + step < dist[g]) {
            if (std::isinf(dist[g])) touched.push_back(g);
            dist[g] = d + step;
            entry[g] = jg;
            pred_face[g] = f;
            pred_side[g] = j;
            queue.push({dist[g], g});
          }
        }
      }
      return boundary_cost;
    };
    double cheapest = std::numeric_limits<double>::infinity();
    for (int f = 0; f < F; ++f) {
      if (!odd(f) || unpaired[f]) continue;
      const double c = search(f);
      if (c < cheapest) cheapest = c, f0 = f;
    }
    if (std::isinf(cheapest)) {  // no odd face reaches another or the boundary (impossible on a valid mesh)
      for (int f = 0; f < F; ++f)
        if (odd(f) && !unpaired[f]) unpaired[f] = 1, ++report.unpaired;
      continue;
    }
    search(f0);
    // The path P[0] = f0 .. P[k]; exit[i] the side of P[i] it leaves by (-1: the end at a face).
    std::vector<int> P, exit_side;
    int last = target >= 0 ? target : boundary_face;
    P.push_back(last);
    exit_side.push_back(target >= 0 ? -1 : boundary_side);
    while (last != f0) {
      exit_side.push_back(pred_side[last]);
      last = pred_face[last];
      P.push_back(last);
    }
    std::reverse(P.begin(), P.end());
    std::reverse(exit_side.begin(), exit_side.end());
    const int k = static_cast<int>(P.size()) - 1;  // faces crossed into
    int boundary_midpoint = -1;
    auto edge_of = [&](int i) {  // the crossing edge i (1..k) as P[i-1]'s directed side (u, v)
      const auto& p = faces[P[i - 1]];
      const int j = exit_side[i - 1];
      return std::pair<int, int>(p[j], p[(j + 1) % p.size()]);
    };
    auto build = [&](bool merge_first, bool merge_last, std::vector<Vec3>& positions, std::vector<char>& new_kind,
                     int& midpoints, int& merged) {
      std::unordered_map<long long, int> midpoint;
      auto midpoint_of = [&](int a, int b) {
        auto [it, fresh] = midpoint.emplace(undirected_edge_key(a, b), static_cast<int>(positions.size()));
        if (fresh) {
          positions.push_back(0.5 * (positions[a] + positions[b]));
          new_kind.push_back(is_feature(a, b) ? kCurve : kNoFeature);
          ++midpoints;
        }
        return it->second;
      };
      auto merges = [&](int i) { return (i == 1 && merge_first) || (i == k && merge_last && target >= 0); };
      std::vector<std::vector<int>> groups;
      for (int i = 0; i <= k; ++i) {
        const auto& p = faces[P[i]];
        const int n = static_cast<int>(p.size());
        const int in = i > 0 ? entry[P[i]] : -1;
        const int out = exit_side[i];
        const bool split_in = i > 0 && !merges(i), split_out = out >= 0 && (i == k || !merges(i + 1));
        std::vector<int> poly;
        for (int t = 0; t < n; ++t) {
          poly.push_back(p[t]);
          if ((t == in && split_in) || (t == out && split_out)) poly.push_back(midpoint_of(p[t], p[(t + 1) % n]));
          if (t == out && i == k && target < 0) boundary_midpoint = poly.back();
        }
        if (i > 0 && merges(i)) {
          const auto [u, v] = edge_of(i);
          groups.back() = merge_polygons_across(groups.back(), poly, u, v);
          ++merged;
        } else {
          groups.push_back(std::move(poly));
        }
      }
      return groups;
    };
    auto may_merge = [&](int i) {
      if (k < 1) return false;
      const auto [u, v] = edge_of(i);
      return !is_feature(u, v);
    };
    // Each end either merged or given a midpoint: the choice adding the fewest irregular vertices (the
    // sum of |faces around - regular| over the vertices touched: 4 inside, 2 on the boundary), among those
    // whose fixed corners are not flat or folded, wins; then the best worst corner.
    struct Option {
      std::vector<Vec3> positions;
      std::vector<char> kind;
      std::vector<std::vector<int>> quads;
      int midpoints = 0, merged = 0, centres = 0, cost = 0;
      double worst = -2;
      bool valid = false;
    };
    const int V0 = mesh.num_vertices();
    auto make_option = [&](bool merge_first, bool merge_last) {
      Option o;
      o.positions = mesh.positions;
      o.kind = kind;
      const std::vector<std::vector<int>> groups = build(merge_first, merge_last, o.positions, o.kind, o.midpoints, o.merged);
      for (const auto& g : groups)
        if (g.size() % 2 == 1 || has_repeated_vertex(g)) return o;
      for (const auto& g : groups) {
        bool centre = false;
        for (auto& q : split_even_polygon(o.positions, g, &centre, &valence)) o.quads.push_back(std::move(q));
        if (centre) o.kind.push_back(kNoFeature), ++o.centres;
      }
      std::unordered_map<int, int> change;
      for (int f : P)
        for (int v : faces[f]) --change[v];
      for (const auto& q : o.quads)
        for (int v : q) ++change[v];
      for (const auto& [v, d] : change) {
        if (v < V0) {
          const int regular = boundary[v] ? 2 : 4;
          o.cost += std::abs(valence[v] + d - regular) - std::abs(valence[v] - regular);
        } else if (!(target < 0 && v == boundary_midpoint)) {
          o.cost += std::abs(d - 4);
        }
      }
      // Corners at new midpoints off the features may be flat (a triangle's end given a midpoint): the
      // relaxation moves them out. Elsewhere (old vertices, midpoints that must stay on a feature edge) a
      // flat corner would stay flat or flipped.
      std::vector<char> movable(o.positions.size(), 0);
      for (size_t v = V0; v < o.positions.size(); ++v) movable[v] = o.kind[v] == kNoFeature;
      o.worst = 1;
      for (const auto& q : o.quads) o.worst = std::min(o.worst, polygon_min_jacobian(o.positions, q, movable));
      o.valid = true;
      return o;
    };
    auto better = [](const Option& a, const Option& b) {
      if (a.valid != b.valid) return a.valid;
      const bool fa = a.worst > kFlatEnd, fb = b.worst > kFlatEnd;
      if (fa != fb) return fa;
      if (a.cost != b.cost) return a.cost < b.cost;
      return a.worst > b.worst;
    };
    Option best = make_option(false, false);
    for (int first = 0; first < 2; ++first)
      for (int second = 0; second < 2; ++second) {
        if ((first && !may_merge(1)) || (second && (target < 0 || !may_merge(k))) || (!first && !second)) continue;
        Option o = make_option(first, second);
        if (better(o, best)) best = std::move(o);
      }
    for (int f : P) faces[f].clear();
    for (auto& q : best.quads) faces.push_back(std::move(q));
    mesh.positions = std::move(best.positions);
    kind = std::move(best.kind);
    const int midpoints = best.midpoints, merged = best.merged;
    report.centres += best.centres;
    report.midpoints += midpoints;
    report.merged_ends += merged;
    ++report.paths;
    if (target < 0) ++report.boundary_paths;
  }
  // Even faces other than quads (none are expected from the quad-dominant steps) are split the same way.
  for (size_t f = 0, n = faces.size(); f < n; ++f) {
    if (faces[f].size() == 4 || faces[f].size() % 2 == 1 || faces[f].empty()) continue;
    bool centre = false;
    std::vector<std::vector<int>> quads = split_even_polygon(mesh.positions, faces[f], &centre);
    if (centre) kind.push_back(kNoFeature), ++report.centres;
    faces[f] = quads[0];
    for (size_t i = 1; i < quads.size(); ++i) faces.push_back(quads[i]);
  }
  set_faces(mesh, faces);
  return report;
}

}  // namespace nfield::remesh
