#include "nfield/remesh/far_point_fit.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>

#include "nfield/remesh/quad_stats.hpp"
#include "nfield/remesh/quad_untangle.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

namespace {

/// Moves must not take a face's worst corner below this, unless it was lower before. Below the relaxation's
/// 0.2: a quad wrapped round a tip has a poor corner wherever its vertices are, so 0.2 blocks the tips; 0.05
/// is the worst corner the untangling step leaves on the benchmark meshes.
constexpr double kFloor = 0.05;
/// A move must lower the local sum of squared excesses by at least this fraction (no churn on ties).
constexpr double kGain = 0.02;
/// Input points nearest to one output face tried before that face is given up for the pass.
constexpr int kAttempts = 8;
/// Of the moves that help, the smallest whose gain is at least this fraction of the best one's is made.
constexpr double kNearlyBest = 0.8;
/// Face neighbours tried as the second vertex of a pair move (nearest to the point the first one uncovered).
constexpr std::size_t kPartners = 3;

double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  return (p - closest_point_on_triangle(p, a, b, c)).norm();
}

/// Distance from p to the fan triangulation of the faces `faces`.
double distance_to_faces(const PolygonMesh& mesh, const std::vector<int>& faces, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (int f : faces) {
    const int* v = mesh.face(f);
    for (int i = 1; i + 1 < mesh.face_size(f); ++i)
      best = std::min(best, point_triangle_distance(p, mesh.positions[v[0]], mesh.positions[v[i]], mesh.positions[v[i + 1]]));
  }
  return best;
}

/// Local distance measure: the largest distance and the sum of squared excesses over `tolerance`.
struct Excess {
  double worst = 0, energy = 0;
  void add(double d, double tolerance) {
    worst = std::max(worst, d);
    if (d > tolerance) energy += (d - tolerance) * (d - tolerance);
  }
};

/// The points of face f where quad_stats.hpp samples the distance: its corners, then face_distance_samples.
std::vector<Vec3> face_samples(const PolygonMesh& mesh, int f) {
  std::vector<Vec3> out;
  for (int i = 0; i < mesh.face_size(f); ++i) out.push_back(mesh.positions[mesh.face(f)[i]]);
  const std::vector<Vec3> rest = face_distance_samples(mesh, f);
  out.insert(out.end(), rest.begin(), rest.end());
  return out;
}

/// Adds the distances to the input of the samples of `faces` quad_stats.hpp measures (vertices, centroid,
/// edge midpoints, half way from the vertices to the centroid).
void faces_to_input(const PolygonMesh& mesh, const std::vector<int>& faces, const TriangleTree& input, double tolerance,
                    Excess& e) {
  for (int f : faces)
    for (const Vec3& p : face_samples(mesh, f)) e.add(std::sqrt(input.closest(p).squared_distance), tolerance);
}

/// Per vertex of the projection surface: 1 when an edge at it joins two triangles whose normals differ by more
/// than `angle_degrees` (none when it is <= 0).
std::vector<char> crease_points(const ProjectionTargets& targets, double angle_degrees) {
  const auto& triangles = targets.surface.triangles();
  std::vector<char> out(targets.surface.vertices().size(), 0);
  if (!(angle_degrees > 0) || targets.surface_normals.face.size() != triangles.size()) return out;
  std::vector<std::array<int, 3>> edges;  // (smaller end, larger end, triangle)
  edges.reserve(3 * triangles.size());
  for (int t = 0; t < static_cast<int>(triangles.size()); ++t)
    for (int m = 0; m < 3; ++m) {
      const int a = triangles[t][m], b = triangles[t][(m + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b), t});
    }
  std::sort(edges.begin(), edges.end());
  const double cos_angle = std::cos(angle_degrees * 3.14159265358979323846 / 180);
  for (std::size_t i = 0; i + 1 < edges.size(); ++i) {
    if (edges[i][0] != edges[i + 1][0] || edges[i][1] != edges[i + 1][1]) continue;
    const Vec3& n0 = targets.surface_normals.face[edges[i][2]];
    const Vec3& n1 = targets.surface_normals.face[edges[i + 1][2]];
    if (n0.dot(n1) < cos_angle) out[edges[i][0]] = out[edges[i][1]] = 1;
  }
  return out;
}

}  // namespace

FarPointFitReport fit_far_points(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets,
                                 double s, double crease_angle_degrees, int passes, double threshold) {
  const auto start = std::chrono::steady_clock::now();
  FarPointFitReport report;
  const std::vector<Vec3>& points = targets.surface.vertices();
  if (points.empty() || mesh.num_faces() == 0 || !(s > 0)) return report;
  const std::vector<char> on_crease = crease_points(targets, crease_angle_degrees);
  std::vector<double> distance(points.size());
  std::vector<int> nearest_face(points.size());
  for (int pass = 0; pass <= passes; ++pass) {
    // Distances of the input vertices to the output, and the output face each is nearest to.
    std::vector<int> tri_face;
    const auto tris = fan_triangulate(mesh, &tri_face);
    const TriangleTree out(mesh.positions, tris);
    double farthest = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const auto hit = out.closest(points[i]);
      distance[i] = std::sqrt(hit.squared_distance);
      nearest_face[i] = hit.triangle >= 0 ? tri_face[hit.triangle] : -1;
      farthest = std::max(farthest, distance[i]);
    }
    if (pass == 0) report.farthest_before = farthest;
    report.farthest_after = farthest;
    if (pass == passes) break;
    ++report.passes;

    std::vector<std::vector<int>> served_by(mesh.num_faces());  // input points nearest to each face
    for (int i = 0; i < static_cast<int>(points.size()); ++i)
      if (nearest_face[i] >= 0) served_by[nearest_face[i]].push_back(i);
    std::vector<std::vector<int>> vertex_faces(mesh.num_vertices());
    for (int f = 0; f < mesh.num_faces(); ++f)
      for (int i = 0; i < mesh.face_size(f); ++i) vertex_faces[mesh.face(f)[i]].push_back(f);
    auto faces_around = [&](const std::vector<int>& vertices) {  // faces with a vertex in `vertices`
      std::vector<int> out_faces;
      for (int v : vertices) out_faces.insert(out_faces.end(), vertex_faces[v].begin(), vertex_faces[v].end());
      std::sort(out_faces.begin(), out_faces.end());
      out_faces.erase(std::unique(out_faces.begin(), out_faces.end()), out_faces.end());
      return out_faces;
    };
    auto vertices_of = [&](const std::vector<int>& faces) {
      std::vector<int> out_vertices;
      for (int f : faces) out_vertices.insert(out_vertices.end(), mesh.face(f), mesh.face(f) + mesh.face_size(f));
      std::sort(out_vertices.begin(), out_vertices.end());
      out_vertices.erase(std::unique(out_vertices.begin(), out_vertices.end()), out_vertices.end());
      return out_vertices;
    };

    // What is far: input points from the output (the output should reach them: a vertex moves towards the
    // point), and output faces from the input (the face's worst sample should come back: its vertices move
    // by the sample's offset to its nearest input point).
    struct Far {
      double distance;
      int face;        ///< output face nearest to it / the face itself
      bool toward;     ///< true: move towards `to`; false: move by to - from
      bool crease;     ///< `to` is an input point on a crease
      Vec3 from, to;
    };
    std::vector<Far> order;
    for (int i = 0; i < static_cast<int>(points.size()); ++i)
      if (distance[i] > threshold * s && nearest_face[i] >= 0)
        order.push_back({distance[i], nearest_face[i], true, on_crease[i] != 0, points[i], points[i]});
    for (int f = 0; f < mesh.num_faces(); ++f) {
      Far worst{0, f, false, false, Vec3::Zero(), Vec3::Zero()};
      for (const Vec3& y : face_samples(mesh, f)) {
        const auto hit = targets.surface.closest(y);
        const double d = std::sqrt(hit.squared_distance);
        if (hit.triangle >= 0 && d > worst.distance) worst.distance = d, worst.from = y, worst.to = hit.point;
      }
      if (worst.distance > threshold * s) order.push_back(worst);
    }
    std::sort(order.begin(), order.end(), [&](const Far& a, const Far& b) { return a.distance > b.distance; });
    std::vector<char> dirty(mesh.num_faces(), 0);
    std::vector<int> tried(mesh.num_faces(), 0);  // farther points near this face that found no move
    int moved = 0;
    for (const Far& item : order) {
      const Vec3& x = item.to;
      if (dirty[item.face] || tried[item.face] >= kAttempts) continue;
      // Candidate vertices: those of the faces around the nearest face, nearest to x first.
      // (for a far face, its own vertices, nearest to its far sample first).
      std::vector<int> cands =
          item.toward ? vertices_of(faces_around(vertices_of({item.face}))) : vertices_of({item.face});
      const Vec3& near = item.toward ? x : item.from;
      cands.erase(std::remove_if(cands.begin(), cands.end(), [&](int v) { return kind[v] != kNoFeature; }), cands.end());
      std::sort(cands.begin(), cands.end(), [&](int a, int b) {
        return (mesh.positions[a] - near).squaredNorm() < (mesh.positions[b] - near).squaredNorm();
      });
      if (cands.size() > 4) cands.resize(4);
      struct Option {
        double gain, displacement;
        std::vector<std::pair<int, Vec3>> moves;
        bool pair = false;  ///< a vertex on a crease point and a face neighbour towards what it uncovered
      };
      std::vector<Option> options;
      for (int v : cands) {
        // The vertex moves towards x; its neighbours (not on a feature) follow by `follow` of its move.
        std::vector<int> group = vertices_of(vertex_faces[v]);
        group.erase(std::remove_if(group.begin(), group.end(), [&](int u) { return kind[u] != kNoFeature; }), group.end());
        const std::vector<int> own = faces_around(group);        // faces that change
        const std::vector<int> ring = faces_around(vertices_of(own));  // and their neighbours
        if (std::any_of(ring.begin(), ring.end(), [&](int f) { return dirty[f]; })) continue;
        // Input points the ring serves (their nearest output face is in it).
        const Vec3 old = mesh.positions[v];
        const Vec3 reach = item.toward ? Vec3(x - old) : Vec3(item.to - item.from);  // the full move
        std::vector<int> served;
        for (int f : ring) served.insert(served.end(), served_by[f].begin(), served_by[f].end());
        auto local_j = [&]() {  // (input -> output, output -> input)
          std::pair<Excess, Excess> e;
          for (int p : served) e.first.add(distance_to_faces(mesh, ring, points[p]), threshold * s);
          faces_to_input(mesh, own, targets.surface, threshold * s, e.second);
          return e;
        };
        std::vector<double> quality_before(own.size());
        for (std::size_t k = 0; k < own.size(); ++k) quality_before[k] = worst_corner_on(mesh, own[k], targets);
        // No face may get a worst corner below kFloor, or below its own before if that was lower.
        auto corners_kept = [&]() {
          for (std::size_t k = 0; k < own.size(); ++k)
            if (worst_corner_on(mesh, own[k], targets) < std::min(kFloor, quality_before[k])) return false;
          return true;
        };
        std::vector<Vec3> saved(group.size());
        for (std::size_t k = 0; k < group.size(); ++k) saved[k] = mesh.positions[group[k]];
        const auto [in_before, out_before] = local_j();
        for (const double follow : {0.0, 0.5}) {
          for (const double t : {1.0, 0.5, 0.25}) {  // all, a half or a quarter of the way
            const auto hit = targets.surface.closest(old + t * reach);
            if (hit.triangle < 0) continue;
            const Vec3 step = hit.point - old;
            std::vector<std::pair<int, Vec3>> moves;
            for (int u : group) {
              if (u == v) {
                moves.emplace_back(u, hit.point);
              } else if (follow > 0) {
                const auto h = targets.surface.closest(mesh.positions[u] + follow * step);
                if (h.triangle >= 0) moves.emplace_back(u, h.point);
              }
            }
            for (const auto& [u, p] : moves) mesh.positions[u] = p;
            // Neither side may get a new worst point: the input side none above its old worst, the output side
            // none above its old worst or the tolerance.
            auto consider = [&](const std::vector<std::pair<int, Vec3>>& tried_moves, const Excess& in_after,
                                const Excess& out_after, bool pair) {
              const double gain = in_before.energy + out_before.energy - in_after.energy - out_after.energy;
              double displacement = 0;
              for (const auto& [u, p] : tried_moves)
                displacement += (p - saved[std::find(group.begin(), group.end(), u) - group.begin()]).norm();
              if (in_after.worst <= in_before.worst && out_after.worst <= std::max(out_before.worst, threshold * s) &&
                  gain > kGain * (in_before.energy + out_before.energy))
                options.push_back({gain, displacement, tried_moves, pair});
            };
            if (corners_kept()) {
              const auto [in_after, out_after] = local_j();
              consider(moves, in_after, out_after, false);
              // The vertex alone on the missed point can leave the points it reached before farther than the
              // missed one was (a ridge of creases: the vertex between the tip and the ridge's foot served
              // both): then a face neighbour of it moves towards the farthest of them, a pair move.
              if (item.toward && item.crease && follow == 0 && in_after.worst > in_before.worst &&
                  !served.empty()) {
                int uncovered = served.front();
                double farthest = -1;
                for (int p : served) {
                  const double d = distance_to_faces(mesh, ring, points[p]);
                  if (d > farthest) farthest = d, uncovered = p;
                }
                const Vec3& y = points[uncovered];
                std::vector<int> partners;
                for (int u : group)
                  if (u != v) partners.push_back(u);
                std::sort(partners.begin(), partners.end(), [&](int a, int b) {
                  return (mesh.positions[a] - y).squaredNorm() < (mesh.positions[b] - y).squaredNorm();
                });
                if (partners.size() > kPartners) partners.resize(kPartners);
                for (int u : partners) {
                  const Vec3 from = mesh.positions[u];
                  for (const double t2 : {1.0, 0.5, 0.25}) {
                    const auto h = targets.surface.closest(from + t2 * (y - from));
                    if (h.triangle < 0) continue;
                    mesh.positions[u] = h.point;
                    if (corners_kept()) {
                      const auto [in_pair, out_pair] = local_j();
                      std::vector<std::pair<int, Vec3>> pair = moves;
                      pair.emplace_back(u, h.point);
                      consider(pair, in_pair, out_pair, true);
                    }
                  }
                  mesh.positions[u] = from;
                }
              }
            }
            for (std::size_t k = 0; k < group.size(); ++k) mesh.positions[group[k]] = saved[k];
          }
        }
      }
      if (options.empty()) {
        ++tried[item.face];
        continue;
      }
      // The smallest move that gains nearly as much as the best (each move bends the rows near it).
      double best_gain = 0;
      for (const Option& o : options) best_gain = std::max(best_gain, o.gain);
      const Option* chosen = nullptr;
      for (const Option& o : options)
        if (o.gain >= kNearlyBest * best_gain && (!chosen || o.displacement < chosen->displacement)) chosen = &o;
      const auto& best_moves = chosen->moves;
      if (chosen->pair) ++report.pair_moves;
      std::vector<int> touched;
      for (const auto& [u, p] : best_moves) mesh.positions[u] = p, touched.push_back(u);
      for (int f : faces_around(vertices_of(faces_around(touched)))) dirty[f] = 1;
      ++moved;
    }
    report.moves += moved;
    if (moved == 0) break;
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace nfield::remesh
