// The irregularity-lowering moves of the quad clean-up (remesh/quad_cleanup.hpp, lower_irregularity) on
// hand-made quad meshes of the unit square grid: a cone cluster made by splitting a regular vertex along a
// quad diagonal (two valence-3 and two valence-5 vertices) collapses back to a regular grid, a rotated
// edge (the same four irregular vertices, in the other arrangement) rotates back, the mesh stays manifold,
// oriented, unfolded and of the same Euler characteristic, and a vertex on a feature curve keeps its
// valence (the collapse is refused).
#include <algorithm>
#include <vector>

#include "check.hpp"
#include "nfield/remesh/irregularity_moves.hpp"
#include "nfield/remesh/quad_cleanup.hpp"
#include "nfield/remesh/quad_stats.hpp"
#include "nfield/remesh/remesh_surface.hpp"

using namespace nfield::remesh;
using namespace nfield::test;

namespace {

constexpr int kN = 8;  // kN x kN unit cells on [0, kN]^2, z = 0

int grid_vertex(int i, int j) { return j * (kN + 1) + i; }

/// The regular grid as vertex lists (counter-clockwise seen from +z).
std::vector<std::vector<int>> grid_faces(PolygonMesh& m) {
  for (int j = 0; j <= kN; ++j)
    for (int i = 0; i <= kN; ++i) m.positions.emplace_back(i, j, 0);
  std::vector<std::vector<int>> faces;
  for (int j = 0; j < kN; ++j)
    for (int i = 0; i < kN; ++i)
      faces.push_back({grid_vertex(i, j), grid_vertex(i + 1, j), grid_vertex(i + 1, j + 1), grid_vertex(i, j + 1)});
  return faces;
}

/// The grid with its vertex p = (4, 4) split into a = (3.7, 4) and c = (4.3, 4) and a new quad
/// (a, (4, 3), c, (4, 5)) between them: a and c have valence 3, (4, 3) and (4, 5) valence 5.
PolygonMesh split_vertex_grid(int& a, int& c) {
  PolygonMesh m;
  std::vector<std::vector<int>> faces = grid_faces(m);
  const int p = grid_vertex(4, 4);
  a = p;
  m.positions[a] = Vec3(3.7, 4, 0);
  c = m.num_vertices();
  m.positions.emplace_back(4.3, 4, 0);
  for (auto& f : faces) {
    const bool right = std::count(f.begin(), f.end(), grid_vertex(5, 4)) > 0;  // the two cells right of p
    if (right) std::replace(f.begin(), f.end(), p, c);
  }
  faces.push_back({a, grid_vertex(4, 3), c, grid_vertex(4, 5)});
  set_faces(m, faces);
  return m;
}

long long euler(const PolygonMesh& m) { return static_cast<long long>(m.num_vertices()) - unique_edges(m).size() + m.num_faces(); }

int irregular_count(const PolygonMesh& m) {
  const IrregularVertices r = irregular_vertices(m);
  return static_cast<int>(r.interior.size() + r.boundary.size());
}

void check_valid(PolygonMesh m, long long chi) {
  compact_vertices(m);
  const ManifoldReport r = check_manifold(m);
  CHECK(r.manifold());
  CHECK(r.oriented());
  CHECK_EQ(euler(m), chi);
  for (int f = 0; f < m.num_faces(); ++f) {
    const std::vector<int> poly(m.face(f), m.face(f) + m.face_size(f));
    CHECK(polygon_min_jacobian(m.positions, poly) > 0.2);  // the moves' own guard
  }
}

}  // namespace

int main() {
  run("a vertex split along a quad diagonal collapses back", [] {
    int a, c;
    PolygonMesh m = split_vertex_grid(a, c);
    const long long chi = euler(m);
    CHECK_EQ(irregular_count(m), 4);
    std::vector<char> kind(m.num_vertices(), kNoFeature);
    const int moves = lower_irregularity(m, kind);
    CHECK_EQ(moves, 1);
    CHECK_EQ(irregular_count(m), 0);
    CHECK_EQ(m.num_faces(), kN * kN);
    check_valid(m, chi);
  });

  run("a rotated edge between two quads rotates back", [] {
    PolygonMesh m;
    std::vector<std::vector<int>> faces = grid_faces(m);
    // Cells (3, 3) and (4, 3) share the edge (4, 3)-(4, 4); their hexagon is re-split along the diagonal
    // (3, 3)-(5, 4): (4, 3) and (4, 4) drop to valence 3, (3, 3) and (5, 4) rise to 5.
    const int h0 = grid_vertex(3, 3), h1 = grid_vertex(4, 3), h2 = grid_vertex(5, 3), h3 = grid_vertex(5, 4),
              h4 = grid_vertex(4, 4), h5 = grid_vertex(3, 4);
    faces[3 * kN + 3] = {h0, h1, h2, h3};
    faces[3 * kN + 4] = {h0, h3, h4, h5};
    set_faces(m, faces);
    const long long chi = euler(m);
    CHECK_EQ(irregular_count(m), 4);
    std::vector<char> kind(m.num_vertices(), kNoFeature);
    CHECK(lower_irregularity(m, kind) >= 1);
    CHECK_EQ(irregular_count(m), 0);
    check_valid(m, chi);
  });

  run("a vertex on a feature curve keeps its valence", [] {
    int a, c;
    PolygonMesh m = split_vertex_grid(a, c);
    std::vector<char> kind(m.num_vertices(), kNoFeature);
    kind[c] = kCurve;  // c may not merge away, and the rotations around it may not change its valence
    const long long chi = euler(m);
    const std::vector<int> before = vertex_valences(m).valence;
    std::vector<char> changed;
    lower_irregularity(m, kind, 0.2, 8, &changed);
    CHECK_EQ(vertex_valences(m).valence[c], before[c]);
    CHECK(m.positions[c].isApprox(Vec3(4.3, 4, 0)));
    CHECK_EQ(static_cast<long long>(changed.size()), static_cast<long long>(before.size()));
    check_valid(m, chi);
  });

  return finish();
}
