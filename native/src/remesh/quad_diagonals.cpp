#include "nfield/remesh/quad_diagonals.hpp"

#include <algorithm>
#include <cmath>

namespace nfield::remesh {

int choose_quad_diagonals(PolygonMesh& mesh, const TriangleTree& surface, double margin) {
  if (surface.empty() || mesh.num_faces() == 0) return 0;
  // The input points each output face serves (is the nearest face to), for the input -> output side.
  std::vector<int> tri_face;
  const auto tris = fan_triangulate(mesh, &tri_face);
  const TriangleTree output(mesh.positions, tris);
  const std::vector<Vec3>& points = surface.vertices();
  std::vector<std::vector<int>> served(mesh.num_faces());
  for (int i = 0; i < static_cast<int>(points.size()); ++i) {
    const auto hit = output.closest(points[i]);
    if (hit.triangle >= 0) served[tri_face[hit.triangle]].push_back(i);
  }
  auto to_input = [&](const Vec3& p) { return std::sqrt(surface.closest(p).squared_distance); };
  auto to_triangle = [](const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
    return (p - closest_point_on_triangle(p, a, b, c)).norm();
  };
  // Misfit of the split along (a, c): triangles (a, b, c) and (a, c, d).
  auto misfit = [&](int f, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    double worst = std::max({to_input(0.5 * (a + c)), to_input((a + b + c) / 3.0), to_input((a + c + d) / 3.0)});
    for (int i : served[f]) worst = std::max(worst, std::min(to_triangle(points[i], a, b, c), to_triangle(points[i], a, c, d)));
    return worst;
  };
  int rotated = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    if (mesh.face_size(f) != 4) continue;
    int* v = mesh.indices.data() + mesh.offsets[f];
    const Vec3 &a = mesh.positions[v[0]], &b = mesh.positions[v[1]], &c = mesh.positions[v[2]], &d = mesh.positions[v[3]];
    // The two splits of a quad lie within the distance of its diagonals' midpoints of each other: a quad
    // flat to within the margin cannot gain more than it.
    if ((a + c - b - d).norm() <= 2 * margin) continue;
    if (misfit(f, b, c, d, a) + margin < misfit(f, a, b, c, d)) {
      std::rotate(v, v + 1, v + 4);
      ++rotated;
    }
  }
  return rotated;
}

}  // namespace nfield::remesh
