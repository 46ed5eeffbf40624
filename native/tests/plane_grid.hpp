// The flat square [0, n]^2 (z = 0) as an input surface for the remesher's native tests: two triangles per
// unit cell, its boundary kept as a feature curve (corners at the square's corners).
#pragma once
#include "nfield/mesh.hpp"
#include "nfield/remesh/quad_extraction.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::test {

/// Index of grid point (i, j) of the (n + 1) x (n + 1) points, row by row.
inline int plane_grid_vertex(int n, int i, int j) { return j * (n + 1) + i; }

/// Projection targets of the square: its surface and its boundary as feature edges.
inline remesh::ProjectionTargets plane_targets(int n) {
  Positions P((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) P.row(plane_grid_vertex(n, i, j)) << i, j, 0;
  Triangles T(2 * n * n, 3);
  int t = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      T.row(t++) << plane_grid_vertex(n, i, j), plane_grid_vertex(n, i + 1, j), plane_grid_vertex(n, i + 1, j + 1);
      T.row(t++) << plane_grid_vertex(n, i, j), plane_grid_vertex(n, i + 1, j + 1), plane_grid_vertex(n, i, j + 1);
    }
  const remesh::RemeshSurface surface = remesh::make_remesh_surface(TriangleMesh(P, T));
  const remesh::Features features = remesh::detect_features(surface, true, 0, 1.0);
  return remesh::make_projection_targets(surface, features);
}

}  // namespace nfield::test
