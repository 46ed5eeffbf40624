#include "nfield/remesh/quad_untangle.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "nfield/parallel_for.hpp"
#include "nfield/remesh/quad_stats.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

namespace {

double face_quality_of(const PolygonMesh& m, const std::vector<int>& poly, const ProjectionTargets& t) {
  const int k = static_cast<int>(poly.size());
  Vec3 own = Vec3::Zero();
  for (int i = 0; i < k; ++i) own += m.positions[poly[i]].cross(m.positions[poly[(i + 1) % k]]);
  if (own.norm() > 0) own.normalize();
  // A face with an edge of (nearly) zero length is degenerate: worse than any flipped face, so that no move
  // trades a flipped face for a collapsed one (its Jacobian would be 0).
  double perimeter = 0, shortest = std::numeric_limits<double>::infinity();
  for (int i = 0; i < k; ++i) {
    const double l = (m.positions[poly[(i + 1) % k]] - m.positions[poly[i]]).norm();
    perimeter += l;
    shortest = std::min(shortest, l);
  }
  if (!(shortest > 0.02 * perimeter / k)) return -2.0;
  double worst = std::numeric_limits<double>::infinity();
  for (int i = 0; i < k; ++i)
    worst = std::min(worst, corner_scaled_jacobian(m.positions[poly[i]], m.positions[poly[(i + 1) % k]],
                                                   m.positions[poly[(i + k - 1) % k]], &t.surface, &t.surface_normals,
                                                   own, k == 3));
  return worst;
}

double face_quality(const PolygonMesh& m, int f, const ProjectionTargets& t) {
  return face_quality_of(m, std::vector<int>(m.face(f), m.face(f) + m.face_size(f)), t);
}

Vec3 project(const Vec3& p, char kind, const ProjectionTargets& t) {
  const bool on_feature = kind != kNoFeature && !t.feature_edges.empty();
  const auto hit = on_feature ? t.feature_edges.closest(p) : t.surface.closest(p);
  return hit.triangle >= 0 ? hit.point : p;
}

}  // namespace

UntangleReport untangle_flipped_faces(PolygonMesh& mesh, const std::vector<char>& kind,
                                      const ProjectionTargets& targets, double margin, int max_rounds) {
  UntangleReport report;
  const int V = mesh.num_vertices(), F = mesh.num_faces();
  std::vector<double> quality(F);
  for (int f = 0; f < F; ++f) quality[f] = face_quality(mesh, f, targets);
  for (double q : quality) report.flipped_before += q <= 0;
  // Faces around each vertex (CSR) and neighbours along edges.
  std::vector<int> offsets(V + 1, 0), faces_of;
  std::vector<std::vector<int>> neighbours(V);
  for (int f = 0; f < F; ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    for (int i = 0; i < k; ++i) {
      ++offsets[v[i] + 1];
      neighbours[v[i]].push_back(v[(i + 1) % k]);
      neighbours[v[i]].push_back(v[(i + k - 1) % k]);
    }
  }
  for (int v = 0; v < V; ++v) {
    offsets[v + 1] += offsets[v];
    std::sort(neighbours[v].begin(), neighbours[v].end());
    neighbours[v].erase(std::unique(neighbours[v].begin(), neighbours[v].end()), neighbours[v].end());
  }
  faces_of.resize(offsets[V]);
  {
    std::vector<int> fill(offsets.begin(), offsets.end() - 1);
    for (int f = 0; f < F; ++f)
      for (int i = 0; i < mesh.face_size(f); ++i) faces_of[fill[mesh.face(f)[i]]++] = f;
  }
  auto local_quality = [&](int v) {
    double q = std::numeric_limits<double>::infinity();
    for (int k = offsets[v]; k < offsets[v + 1]; ++k) q = std::min(q, face_quality(mesh, faces_of[k], targets));
    return q;
  };

  std::vector<char> active(V);
  std::vector<Vec3> goals;
  // Stage 0 keeps the features: corners stay, curve vertices slide along their feature. Only if faces are
  // still flipped, stage 1 lets corners slide along the features too, and stage 2 lets every vertex move on
  // the surface (a flipped face is worse than a feature vertex a little off its feature).
  for (int stage = 0; stage < 3; ++stage) {
    // Later stages only for faces that are flipped or nearly so (the input's normals differ a little from the
    // cut surface's, so a face just above zero here could be just below against the input).
    const double threshold = stage == 0 ? margin : 0.4 * margin;
    if (stage > 0 && std::none_of(quality.begin(), quality.end(), [&](double q) { return q < threshold; })) break;
    auto kind_now = [&](int v) -> char {
      if (stage == 0) return kind[v];
      if (stage == 1) return kind[v] == kNoFeature ? kNoFeature : kCurve;
      return kNoFeature;
    };
    for (int round = 0; round < max_rounds; ++round) {
      std::fill(active.begin(), active.end(), 0);
      bool any = false;
      for (int f = 0; f < F; ++f) {
        if (quality[f] >= threshold) continue;
        any = true;
        for (int i = 0; i < mesh.face_size(f); ++i) {
          const int v = mesh.face(f)[i];
          active[v] = 1;
          if (round >= 2)
            for (int w : neighbours[v]) active[w] = 1;
        }
      }
      if (!any) break;
      ++report.rounds;
      bool improved = false;
      for (int v = 0; v < V; ++v) {
        if (!active[v] || kind_now(v) == kCorner || neighbours[v].empty()) continue;
        const Vec3 start = mesh.positions[v];
        const Vec3 start_normal = targets.surface.surface_normal(start, targets.surface_normals);
        // A candidate counts only on the vertex's own sheet of the surface: a step in the tangent plane of a
        // part thinner than the step projects onto its other side (normal turned by more than 60 degrees).
        auto try_at = [&](const Vec3& candidate, double& best, Vec3& best_position) {
          const Vec3 p = project(candidate, kind_now(v), targets);
          if (targets.surface.surface_normal(p, targets.surface_normals).dot(start_normal) < 0.5) return false;
          mesh.positions[v] = p;
          const double q = local_quality(v);
          if (!(q > best + 1e-9)) return false;
          best = q;
          best_position = p;
          return true;
        };
        double best = local_quality(v);
        Vec3 best_position = start;
        // Goals: the mean of the neighbours; the mean of the positions that make each quad a parallelogram.
        goals.clear();
        Vec3 mean = Vec3::Zero();
        for (int w : neighbours[v]) mean += mesh.positions[w];
        goals.push_back(mean / static_cast<double>(neighbours[v].size()));
        Vec3 parallelogram = Vec3::Zero();
        int quads = 0;
        for (int k = offsets[v]; k < offsets[v + 1]; ++k) {
          const int f = faces_of[k];
          if (mesh.face_size(f) != 4) continue;
          const int* x = mesh.face(f);
          const int i = static_cast<int>(std::find(x, x + 4, v) - x);
          parallelogram += mesh.positions[x[(i + 1) % 4]] + mesh.positions[x[(i + 3) % 4]] - mesh.positions[x[(i + 2) % 4]];
          ++quads;
        }
        if (quads) goals.push_back(parallelogram / quads);
        for (const Vec3& goal : goals)
          for (double t : {0.25, 0.5, 0.75, 1.0}) try_at(start + t * (goal - start), best, best_position);
        // Then a pattern search around the best point so far, in its tangent plane: eight directions, the
        // step halved when none of them improves (from half the mean edge length, four times).
        if (best < threshold) {
          double reach = 0;
          for (int w : neighbours[v]) reach += (mesh.positions[w] - start).norm();
          double step = 0.5 * reach / static_cast<double>(neighbours[v].size());
          const Vec3 normal = targets.surface.surface_normal(best_position, targets.surface_normals);
          const Vec3 x = normal.squaredNorm() > 0 ? normal.unitOrthogonal() : Vec3::UnitX();
          const Vec3 y = normal.cross(x);
          for (int halving = 0; halving < 4 && best < threshold;) {
            bool better = false;
            const Vec3 centre = best_position;
            for (int d = 0; d < 8; ++d) {
              const double a = d * 0.785398163397448;
              better = try_at(centre + step * (std::cos(a) * x + std::sin(a) * y), best, best_position) || better;
            }
            if (!better) {
              step *= 0.5;
              ++halving;
            }
          }
        }
        mesh.positions[v] = best_position;
        if (best_position != start) {
          ++report.moved_vertices;
          if (stage > 0 && kind[v] != kNoFeature) ++report.released_features;
          improved = true;
          for (int k = offsets[v]; k < offsets[v + 1]; ++k) quality[faces_of[k]] = face_quality(mesh, faces_of[k], targets);
        }
      }
      if (!improved) break;
    }
  }
  for (double q : quality) report.flipped_after += q <= 0;
  return report;
}

std::vector<double> scaled_jacobians_on(const PolygonMesh& mesh, const ProjectionTargets& targets) {
  std::vector<double> q(mesh.num_faces());
  // Each face's corners query the surface tree (read only): the faces split over both cores.
  parallel_for(mesh.num_faces(), [&](int f) { q[f] = face_quality(mesh, f, targets); });
  return q;
}

double worst_corner_on(const PolygonMesh& mesh, int f, const ProjectionTargets& targets) {
  return face_quality(mesh, f, targets);
}

int split_flipped_faces(PolygonMesh& mesh, const ProjectionTargets& targets, double below) {
  std::vector<std::vector<int>> faces(mesh.num_faces());
  for (int f = 0; f < mesh.num_faces(); ++f) faces[f].assign(mesh.face(f), mesh.face(f) + mesh.face_size(f));
  auto quality = [&](const std::vector<int>& poly) { return face_quality_of(mesh, poly, targets); };
  int split = 0;
  std::vector<std::vector<int>> out;
  for (auto& poly : faces) {
    const int k = static_cast<int>(poly.size());
    const double q0 = face_quality_of(mesh, poly, targets);
    if (k < 4 || q0 > below) {
      out.push_back(poly);
      continue;
    }
    // The diagonal (i, j) whose two parts have the best worst corner (better than the face's own).
    double best = std::max(q0, 0.0);
    int bi = -1, bj = -1;
    for (int i = 0; i < k; ++i)
      for (int j = i + 2; j < k; ++j) {
        if (i == 0 && j == k - 1) continue;
        std::vector<int> a(poly.begin() + i, poly.begin() + j + 1), b(poly.begin() + j, poly.end());
        b.insert(b.end(), poly.begin(), poly.begin() + i + 1);
        const double q = std::min(quality(a), quality(b));
        if (q > best) {
          best = q;
          bi = i;
          bj = j;
        }
      }
    if (bi < 0) {
      out.push_back(poly);
      continue;
    }
    out.emplace_back(poly.begin() + bi, poly.begin() + bj + 1);
    std::vector<int> b(poly.begin() + bj, poly.end());
    b.insert(b.end(), poly.begin(), poly.begin() + bi + 1);
    out.push_back(b);
    ++split;
  }
  if (split) {
    mesh.offsets.assign(1, 0);
    mesh.indices.clear();
    for (const auto& f : out) mesh.add_face(f);
  }
  return split;
}

}  // namespace nfield::remesh
