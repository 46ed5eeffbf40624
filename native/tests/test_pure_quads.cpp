// Pure quads at full resolution (remesh/pure_quads.hpp) on hand-made meshes of the unit square grid: the
// odd faces are paired, every face becomes a quad, the mesh stays manifold and oriented with its Euler
// characteristic, nothing folds, and a straight pair costs no interior irregular vertex beyond its ends.
#include <algorithm>
#include <map>
#include <set>
#include <vector>

#include "check.hpp"
#include "plane_grid.hpp"
#include "nfield/mesh.hpp"
#include "nfield/remesh/pure_quads.hpp"
#include "nfield/remesh/quad_cleanup.hpp"
#include "nfield/remesh/remesh_surface.hpp"

using namespace nfield;
using namespace nfield::remesh;
using namespace nfield::test;

namespace {

constexpr int kN = 8;  // the grid has kN x kN unit cells on [0, kN]^2, z = 0

int grid_vertex(int i, int j) { return plane_grid_vertex(kN, i, j); }

/// The quad grid with the cells in `split` cut along their diagonal into two triangles.
PolygonMesh grid_with_triangles(const std::set<std::pair<int, int>>& split, std::vector<char>& kind) {
  PolygonMesh m;
  for (int j = 0; j <= kN; ++j)
    for (int i = 0; i <= kN; ++i) m.positions.emplace_back(i, j, 0);
  for (int j = 0; j < kN; ++j)
    for (int i = 0; i < kN; ++i) {
      const int a = grid_vertex(i, j), b = grid_vertex(i + 1, j), c = grid_vertex(i + 1, j + 1), d = grid_vertex(i, j + 1);
      if (split.count({i, j})) {
        m.add_face({a, b, c});
        m.add_face({a, c, d});
      } else {
        m.add_face({a, b, c, d});
      }
    }
  kind.assign(m.num_vertices(), kNoFeature);
  for (int j = 0; j <= kN; ++j)
    for (int i = 0; i <= kN; ++i)
      if (i == 0 || j == 0 || i == kN || j == kN) kind[grid_vertex(i, j)] = (i % kN == 0 && j % kN == 0) ? kCorner : kCurve;
  return m;
}

long long euler(const PolygonMesh& m) { return static_cast<long long>(m.num_vertices()) - unique_edges(m).size() + m.num_faces(); }

/// Faces around each interior vertex (boundary vertices: -1).
std::vector<int> interior_valence(const PolygonMesh& m) {
  std::map<std::pair<int, int>, int> uses;
  std::vector<int> count(m.num_vertices(), 0);
  for (int f = 0; f < m.num_faces(); ++f)
    for (int i = 0; i < m.face_size(f); ++i) {
      const int a = m.face(f)[i], b = m.face(f)[(i + 1) % m.face_size(f)];
      ++uses[{std::min(a, b), std::max(a, b)}];
      ++count[a];
    }
  for (const auto& [e, n] : uses)
    if (n == 1) count[e.first] = count[e.second] = -1;
  return count;
}

void check_all_quads_valid(const PolygonMesh& m, long long chi) {
  for (int f = 0; f < m.num_faces(); ++f) CHECK_EQ(m.face_size(f), 4);
  const ManifoldReport r = check_manifold(m);
  CHECK(r.manifold());
  CHECK(r.oriented());
  CHECK_EQ(euler(m), chi);
  // Raw positions (midpoints and centroids, before any relaxation): no corner folds past flat. A
  // midpoint between the two halves of a straight edge is exactly flat (scaled Jacobian 0) until relaxed.
  for (int f = 0; f < m.num_faces(); ++f) {
    const std::vector<int> quad(m.face(f), m.face(f) + 4);
    CHECK(polygon_min_jacobian(m.positions, quad) >= -1e-12);
  }
}

}  // namespace

int main() {
  const ProjectionTargets targets = plane_targets(kN);

  run("a cell cut into two triangles is merged back (the cheapest path: one step)", [&] {
    std::vector<char> kind;
    // Two cells split into two triangles each: four odd faces.
    PolygonMesh m = grid_with_triangles({{2, 4}, {5, 4}}, kind);
    const long long chi = euler(m);
    const int faces_before = m.num_faces();
    const PureQuadReport r = convert_to_pure_quads(m, kind, targets);
    CHECK_EQ(r.odd_faces, 4);
    CHECK_EQ(r.paths, 2);
    CHECK_EQ(r.unpaired, 0);
    check_all_quads_valid(m, chi);
    CHECK_EQ(static_cast<long long>(kind.size()), m.num_vertices());
    // Each triangle pair of one cell is the cheapest path (one step): merged back into a quad.
    CHECK_EQ(r.merged_ends, 2);
    CHECK_EQ(m.num_faces(), faces_before - 2);
    for (int v : interior_valence(m)) CHECK(v == -1 || v == 4);
  });

  /// The grid with a vertex inserted at the midpoint of edge (i0, j0) - (i1, j1): its one or two faces
  /// become pentagons.
  auto grid_with_split_edge = [](int i0, int j0, int i1, int j1, std::vector<char>& kind, char mid_kind) {
    PolygonMesh m = grid_with_triangles({}, kind);
    const int mid = m.num_vertices();
    m.positions.push_back(0.5 * (m.positions[grid_vertex(i0, j0)] + m.positions[grid_vertex(i1, j1)]));
    kind.push_back(mid_kind);
    std::vector<std::vector<int>> faces = face_lists(m);
    for (auto& f : faces)
      for (size_t i = 0; i < f.size(); ++i) {
        const int a = f[i], b = f[(i + 1) % f.size()];
        const int u = grid_vertex(i0, j0), v = grid_vertex(i1, j1);
        if ((a == u && b == v) || (a == v && b == u)) {
          f.insert(f.begin() + i + 1, mid);
          break;
        }
      }
    set_faces(m, faces);
    return m;
  };

  run("a split edge (two pentagons with a straight corner) becomes a half-width column, all regular", [&] {
    // Each pentagon is a quad with a T-junction: its half row goes on from the straight corner, straight
    // to the boundary (4 steps), rather than into the other pentagon across a half of the split edge (whose
    // hexagons would need centre vertices; merging them would give a loop through a vertex twice).
    std::vector<char> kind;
    PolygonMesh m = grid_with_split_edge(3, 4, 4, 4, kind, kNoFeature);
    const long long chi = euler(m);
    const PureQuadReport r = convert_to_pure_quads(m, kind, targets);
    CHECK_EQ(r.odd_faces, 2);
    CHECK_EQ(r.paths, 2);
    CHECK_EQ(r.boundary_paths, 2);
    CHECK_EQ(r.centres, 0);
    check_all_quads_valid(m, chi);
    for (int v : interior_valence(m)) CHECK(v == -1 || v == 4);
    // the column x in [3, 4] is split at x = 3.5 from the bottom to the top boundary: one midpoint per
    // horizontal edge of the column besides the split edge's own vertex (9 edges, y = 0..8, less y = 4)
    CHECK_EQ(r.midpoints, 8);
  });

  run("a pentagon on the boundary is joined to the boundary", [&] {
    std::vector<char> kind;
    PolygonMesh m = grid_with_split_edge(3, 0, 4, 0, kind, kCurve);
    const long long chi = euler(m);
    const PureQuadReport r = convert_to_pure_quads(m, kind, targets);
    CHECK_EQ(r.odd_faces, 1);
    CHECK_EQ(r.paths, 1);
    CHECK_EQ(r.boundary_paths, 1);
    check_all_quads_valid(m, chi);
    // The pentagon is a cell with a straight corner on the boundary: its half row goes on from that corner
    // (a midpoint on the boundary itself would leave it a flat corner) and out to the nearest boundary,
    // here 1 step up, a turn (3) and 3 steps to the left boundary, as cheap as 7 steps straight up. A turn
    // costs a centre vertex of valence 3 and a cell corner of valence 5; nothing else is irregular.
    int irregular = 0;
    for (int v : interior_valence(m)) irregular += v != -1 && v != 4;
    CHECK_LE(irregular, 2);
    CHECK_LE(r.centres, 1);
    // the new midpoint on the boundary, a feature curve, is a curve vertex; the others are free
    CHECK_EQ(static_cast<long long>(kind.size()), m.num_vertices());
    int on_boundary = 0;
    for (int v = (kN + 1) * (kN + 1) + 1; v < m.num_vertices(); ++v) {
      const Vec3& p = m.positions[v];
      const bool boundary = p.x() == 0 || p.y() == 0 || p.x() == kN || p.y() == kN;
      on_boundary += boundary;
      CHECK(kind[v] == (boundary ? kCurve : kNoFeature));
    }
    CHECK_EQ(on_boundary, 1);
  });

  run("triangles beside pentagons: all quads", [&] {
    std::vector<char> kind;
    // Cells (1, 1) and (6, 5) cut into two triangles, one triangle of each merged with the cell to its
    // right (a pentagon): four odd faces in two touching pairs.
    PolygonMesh m = grid_with_triangles({{1, 1}, {6, 5}}, kind);
    std::vector<std::vector<int>> faces = face_lists(m);
    auto merge_with_right_neighbour = [&](int i, int j) {
      // the triangle (a, b, c) of cell (i, j) and the quad of cell (i + 1, j) share the edge b -> c
      const int b = grid_vertex(i + 1, j), c = grid_vertex(i + 1, j + 1);
      int tri = -1, quad = -1;
      for (int f = 0; f < static_cast<int>(faces.size()); ++f) {
        const auto& p = faces[f];
        for (size_t k = 0; k < p.size(); ++k) {
          if (p[k] == b && p[(k + 1) % p.size()] == c) tri = f;
          if (p[k] == c && p[(k + 1) % p.size()] == b) quad = f;
        }
      }
      faces[tri] = merge_polygons_across(faces[tri], faces[quad], b, c);
      faces[quad].clear();
    };
    merge_with_right_neighbour(1, 1);
    merge_with_right_neighbour(6, 5);
    set_faces(m, faces);
    const long long chi = euler(m);
    const PureQuadReport r = convert_to_pure_quads(m, kind, targets);
    CHECK_EQ(r.odd_faces, 4);
    CHECK_EQ(r.unpaired, 0);
    check_all_quads_valid(m, chi);
  });

  run("split_even_polygon: a hexagon by a diagonal, an L-shaped turn around a centre", [&] {
    // A 2 x 1 rectangle with midpoints on its long sides: the straight split joins the midpoints.
    std::vector<Vec3> P = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {0, 1, 0}};
    bool centre = true;
    auto quads = split_even_polygon(P, {0, 1, 2, 3, 4, 5}, &centre);
    CHECK(!centre);
    CHECK_EQ(quads.size(), 2);
    CHECK_EQ(P.size(), 6);
    for (const auto& q : quads) CHECK_LE(1 - polygon_min_jacobian(P, q), 1e-12);  // two unit squares
    // The unit square with midpoints on two adjacent sides (a half row turning by 90 degrees): every
    // diagonal leaves a flat corner at a midpoint, so a centre vertex makes three quads.
    std::vector<Vec3> Q = {{0, 0, 0}, {0.5, 0, 0}, {1, 0, 0}, {1, 0.5, 0}, {1, 1, 0}, {0, 1, 0}};
    quads = split_even_polygon(Q, {0, 1, 2, 3, 4, 5}, &centre);
    CHECK(centre);
    CHECK_EQ(quads.size(), 3);
    CHECK_EQ(Q.size(), 7);
    for (const auto& q : quads) CHECK(polygon_min_jacobian(Q, q) > 0.15);
  });

  return finish();
}
