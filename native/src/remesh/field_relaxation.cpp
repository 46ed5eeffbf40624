#include "nfield/remesh/field_relaxation.hpp"

#include <algorithm>
#include <cmath>

#include "nfield/remesh/quad_untangle.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

namespace {

/// Moves must not take a face's worst corner (scaled Jacobian) below this, unless it was lower before.
constexpr double kFloor = 0.2;

}  // namespace

void relax_along_field(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets,
                       const std::vector<Vec3>& surface_directions, int iterations) {
  const int V = mesh.num_vertices();
  const std::vector<std::array<int, 2>> edges = unique_edges(mesh);
  for (int it = 0; it < iterations; ++it) {
    std::vector<Vec3> move(V, Vec3::Zero());
    std::vector<int> count(V, 0);
    // The field at each edge's midpoint (where the alignment of an edge is measured).
    for (const auto& e : edges) {
      const Vec3 mid = 0.5 * (mesh.positions[e[0]] + mesh.positions[e[1]]);
      const auto hit = targets.surface.closest(mid);
      if (hit.triangle < 0 || hit.triangle >= static_cast<int>(surface_directions.size())) continue;
      const Vec3 n = targets.surface.normal_at(hit, targets.surface_normals);
      if (n.norm() <= 0) continue;
      Vec3 q = surface_directions[hit.triangle];
      q -= n.normalized() * n.normalized().dot(q);
      if (q.norm() <= 0) continue;
      q.normalize();
      const Vec3 t = n.normalized().cross(q);
      const Vec3 d = mesh.positions[e[1]] - mesh.positions[e[0]];
      const double a = d.dot(q), b = d.dot(t);
      const Vec3 along = std::abs(a) >= std::abs(b) ? Vec3(a * q) : Vec3(b * t);
      const Vec3 off = d - along;  // in the tangent plane at the midpoint
      // e[0] moves by +off (its edge becomes d - off), e[1] by -off.
      move[e[0]] += off;
      move[e[1]] -= off;
      ++count[e[0]];
      ++count[e[1]];
    }
    const std::vector<Vec3> before = mesh.positions;
    const std::vector<double> worst_before = scaled_jacobians_on(mesh, targets);
    std::vector<char> frozen(V, 0);  // vertices of faces already poor: left to the untangling step
    for (int f = 0; f < mesh.num_faces(); ++f)
      if (worst_before[f] < kFloor)
        for (int i = 0; i < mesh.face_size(f); ++i) frozen[mesh.face(f)[i]] = 1;
    for (int v = 0; v < V; ++v)
      if (count[v] && kind[v] == kNoFeature && !frozen[v]) mesh.positions[v] += 0.25 * move[v] / count[v];
    project_vertices(mesh, kind, targets);
    // Guard: a face whose worst corner dropped below kFloor (and below where it was) gets its vertices back,
    // until no face does.
    for (int pass = 0; pass < 10; ++pass) {
      bool reverted = false;
      const std::vector<double> worst = scaled_jacobians_on(mesh, targets);
      for (int f = 0; f < mesh.num_faces(); ++f) {
        if (worst[f] >= kFloor || worst[f] >= worst_before[f]) continue;
        for (int i = 0; i < mesh.face_size(f); ++i) {
          const int v = mesh.face(f)[i];
          if (mesh.positions[v] != before[v]) mesh.positions[v] = before[v], reverted = true;
        }
      }
      if (!reverted) break;
    }
  }
}

}  // namespace nfield::remesh
