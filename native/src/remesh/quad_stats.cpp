#include "nfield/remesh/quad_stats.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "nfield/parallel_for.hpp"

namespace nfield::remesh {

namespace {
constexpr double kPi = 3.14159265358979323846;

double corner_angle(const Vec3& prev, const Vec3& v, const Vec3& next) {
  const Vec3 a = prev - v, b = next - v;
  const double na = a.norm(), nb = b.norm();
  if (na <= 0 || nb <= 0) return 0.0;
  return std::atan2(a.cross(b).norm(), a.dot(b));
}
}  // namespace

FaceCounts count_faces(const PolygonMesh& mesh) {
  FaceCounts c;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    if (k == 4) ++c.quads;
    else if (k == 3) ++c.triangles;
    else ++c.other;
  }
  return c;
}

VertexValence vertex_valences(const PolygonMesh& mesh) {
  VertexValence r;
  r.valence.assign(mesh.num_vertices(), 0);
  r.boundary.assign(mesh.num_vertices(), 0);
  std::unordered_map<long long, int> uses;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    for (int i = 0; i < k; ++i) {
      int a = v[i], b = v[(i + 1) % k];
      if (a > b) std::swap(a, b);
      ++uses[(static_cast<long long>(a) << 32) | static_cast<unsigned int>(b)];
    }
  }
  for (const auto& [key, count] : uses) {
    const int a = static_cast<int>(key >> 32), b = static_cast<int>(key & 0xffffffffLL);
    ++r.valence[a];
    ++r.valence[b];
    if (count == 1) r.boundary[a] = r.boundary[b] = 1;
  }
  return r;
}

IrregularVertices irregular_vertices(const PolygonMesh& mesh) {
  const VertexValence vv = vertex_valences(mesh);
  std::vector<double> angle(mesh.num_vertices(), 0.0);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    for (int i = 0; i < k; ++i)
      angle[v[i]] += corner_angle(mesh.positions[v[(i + k - 1) % k]], mesh.positions[v[i]],
                                  mesh.positions[v[(i + 1) % k]]);
  }
  IrregularVertices r;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    if (vv.valence[v] == 0) continue;
    if (!vv.boundary[v]) {
      if (vv.valence[v] != 4) r.interior.push_back(v);
    } else {
      const int expected = 1 + static_cast<int>(std::lround(angle[v] / (kPi / 2)));
      if (vv.valence[v] != std::max(expected, 2)) r.boundary.push_back(v);
    }
  }
  return r;
}

ReferenceSurface make_reference(const std::vector<Vec3>& vertices, const std::vector<std::array<int, 3>>& triangles,
                                const std::vector<Vec3>& directions) {
  ReferenceSurface r;
  r.normals = surface_normals(vertices, triangles);
  r.directions = directions;
  r.directions.resize(triangles.size(), Vec3::Zero());
  r.tree = TriangleTree(vertices, triangles);
  return r;
}

double corner_scaled_jacobian(const Vec3& p, const Vec3& next, const Vec3& prev, const TriangleTree* tree,
                              const SurfaceNormals* normals, const Vec3& own_normal, bool triangle) {
  const Vec3 e1 = next - p, e2 = prev - p;
  Vec3 n = own_normal;
  if (tree && normals && !tree->empty()) {
    const Vec3 m = tree->surface_normal(p + 0.05 * (e1 + e2), *normals);
    if (m.squaredNorm() > 0) n = m;
  }
  const double l = e1.norm() * e2.norm();
  const double j = l > 0 ? e1.cross(e2).dot(n) / l : 0.0;
  return triangle ? j * 2.0 / std::sqrt(3.0) : j;
}

std::vector<double> scaled_jacobians(const PolygonMesh& mesh, const ReferenceSurface* reference) {
  std::vector<double> out(mesh.num_faces(), 0.0);
  const bool use_reference = reference && !reference->tree.empty();
  parallel_for(mesh.num_faces(), [&](int f) {
    const int k = mesh.face_size(f);
    const int* v = mesh.face(f);
    const Vec3 own = polygon_normal(mesh, f);
    double worst = std::numeric_limits<double>::infinity();
    for (int i = 0; i < k; ++i)
      worst = std::min(worst, corner_scaled_jacobian(mesh.positions[v[i]], mesh.positions[v[(i + 1) % k]],
                                                     mesh.positions[v[(i + k - 1) % k]],
                                                     use_reference ? &reference->tree : nullptr,
                                                     use_reference ? &reference->normals : nullptr, own, k == 3));
    out[f] = std::isfinite(worst) ? worst : 0.0;
  });
  return out;
}

std::vector<double> edge_alignment_degrees(const PolygonMesh& mesh, const ReferenceSurface& reference) {
  const auto edges = unique_edges(mesh);
  std::vector<double> out(edges.size(), std::numeric_limits<double>::quiet_NaN());
  if (reference.tree.empty()) return out;
  parallel_for(static_cast<int>(edges.size()), [&](int e) {
    const Vec3& a = mesh.positions[edges[e][0]];
    const Vec3& b = mesh.positions[edges[e][1]];
    const auto hit = reference.tree.closest(0.5 * (a + b));
    if (hit.triangle < 0) return;
    const Vec3& n = reference.normals.face[hit.triangle];
    const Vec3& d = reference.directions[hit.triangle];
    if (d.squaredNorm() == 0 || n.squaredNorm() == 0) return;
    const Vec3 x = (d - n * n.dot(d)).normalized();
    const Vec3 y = n.cross(x);
    const Vec3 t = b - a;
    const double tx = t.dot(x), ty = t.dot(y);
    if (tx == 0 && ty == 0) return;
    // Angle modulo 90 degrees, folded into [0, 45].
    double ang = std::fmod(std::abs(std::atan2(ty, tx)), kPi / 2);
    ang = std::min(ang, kPi / 2 - ang);
    out[e] = ang * 180.0 / kPi;
  });
  return out;
}

std::vector<Vec3> face_distance_samples(const PolygonMesh& mesh, int f) {
  const int k = mesh.face_size(f);
  const int* v = mesh.face(f);
  const Vec3 c = polygon_centroid(mesh, f);
  std::vector<Vec3> out{c};
  for (int i = 0; i < k; ++i) {
    out.push_back(0.5 * (mesh.positions[v[i]] + mesh.positions[v[(i + 1) % k]]));
    out.push_back(0.5 * (mesh.positions[v[i]] + c));
  }
  return out;
}

double one_sided_distance(const PolygonMesh& mesh, const TriangleTree& tree) {
  if (tree.empty()) return std::numeric_limits<double>::infinity();
  // The farthest sample of each vertex and face, then the largest of those (a maximum does not depend on
  // the order, so splitting the queries over both cores changes nothing).
  std::vector<char> used(mesh.num_vertices(), 0);
  for (int i : mesh.indices) used[i] = 1;
  const int V = mesh.num_vertices();
  std::vector<double> worst2(V + mesh.num_faces(), 0.0);
  parallel_for(static_cast<int>(worst2.size()), [&](int i) {
    if (i < V) {
      if (used[i]) worst2[i] = tree.closest(mesh.positions[i]).squared_distance;
      return;
    }
    for (const Vec3& p : face_distance_samples(mesh, i - V))
      worst2[i] = std::max(worst2[i], tree.closest(p).squared_distance);
  });
  return worst2.empty() ? 0.0 : std::sqrt(*std::max_element(worst2.begin(), worst2.end()));
}

double hausdorff_distance(const PolygonMesh& mesh, const ReferenceSurface& reference) {
  const double forward = one_sided_distance(mesh, reference.tree);
  // Backward: samples of the reference triangles to the (fan-triangulated) polygon mesh.
  PolygonMesh ref;
  ref.positions = reference.tree.vertices();
  for (const auto& t : reference.tree.triangles()) ref.add_face({t[0], t[1], t[2]});
  const TriangleTree out_tree(mesh.positions, fan_triangulate(mesh));
  const double backward = one_sided_distance(ref, out_tree);
  return std::max(forward, backward);
}

}  // namespace nfield::remesh
