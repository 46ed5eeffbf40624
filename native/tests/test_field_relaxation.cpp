// The relaxation along the field (remesh/field_relaxation.hpp) on a hand-made quad grid of a flat square
// with a constant field along x: the interior lattice, jittered, is pulled back straight (the off-axis
// energy falls to a small part of its value), the feature vertices (the square's boundary) do not move,
// no face folds, and two runs give the same positions bit for bit. The last pass (refine_along_field)
// holds the vertices it is told to hold exactly, and an edge far off its axis pulls none of its ends.
#include <cmath>
#include <vector>

#include "check.hpp"
#include "plane_grid.hpp"
#include "nfield/errors.hpp"
#include "nfield/mesh.hpp"
#include "nfield/remesh/field_relaxation.hpp"
#include "nfield/remesh/quad_untangle.hpp"
#include "nfield/remesh/remesh_surface.hpp"

using namespace nfield;
using namespace nfield::remesh;
using namespace nfield::test;

namespace {

constexpr int kN = 12;  // kN x kN unit cells on [0, kN]^2, z = 0

int grid_vertex(int i, int j) { return plane_grid_vertex(kN, i, j); }

/// The quad grid, vertices at least two cells from the boundary moved by a fixed pseudo-random offset of
/// up to 0.2 cells in each coordinate (every corner stays convex). Boundary vertices are features.
PolygonMesh jittered_grid(std::vector<char>& kind) {
  PolygonMesh m;
  unsigned state = 12345;
  auto jitter = [&] {
    state = state * 1103515245u + 12345u;
    return 0.4 * ((state >> 8) % 1000) / 999.0 - 0.2;
  };
  for (int j = 0; j <= kN; ++j)
    for (int i = 0; i <= kN; ++i) {
      const bool inner = i >= 2 && j >= 2 && i <= kN - 2 && j <= kN - 2;
      const double dx = inner ? jitter() : 0.0, dy = inner ? jitter() : 0.0;
      m.positions.emplace_back(i + dx, j + dy, 0);
    }
  for (int j = 0; j < kN; ++j)
    for (int i = 0; i < kN; ++i)
      m.add_face({grid_vertex(i, j), grid_vertex(i + 1, j), grid_vertex(i + 1, j + 1), grid_vertex(i, j + 1)});
  kind.assign(m.num_vertices(), kNoFeature);
  for (int j = 0; j <= kN; ++j)
    for (int i = 0; i <= kN; ++i)
      if (i == 0 || j == 0 || i == kN || j == kN) kind[grid_vertex(i, j)] = (i % kN == 0 && j % kN == 0) ? kCorner : kCurve;
  return m;
}

}  // namespace

int main() {
  const ProjectionTargets targets = plane_targets(kN);
  const std::vector<Eigen::Vector3d> along_x(2 * kN * kN, Eigen::Vector3d::UnitX());

  run("the solve straightens a jittered lattice along the field, features fixed, nothing folds", [&] {
    std::vector<char> kind;
    PolygonMesh m = jittered_grid(kind);
    const PolygonMesh start = m;
    const double before = off_axis_energy(m, targets, along_x);
    CHECK(before > 0.5);  // the jitter is real: 0.2-cell offsets on about 200 edges
    for (double q : scaled_jacobians_on(m, targets)) CHECK(q > 0.2);
    solve_along_field(m, kind, targets, along_x, 2);
    const double after = off_axis_energy(m, targets, along_x);
    // The straight lattice has no off-axis part; the solve also keeps each edge's extent along its axis
    // (weaker term) and its vertices near their start, so it stops short of zero: two iterations leave 2%
    // (4.02 -> 0.083). A local smoothing step removes a fixed share per step of the short-wavelength error
    // only; 5% would not be reached by two of the old quarter steps.
    CHECK_LE(after, 0.05 * before);
    for (int v = 0; v < m.num_vertices(); ++v)
      if (kind[v] != kNoFeature) CHECK((m.positions[v] - start.positions[v]).norm() == 0.0);
    for (double q : scaled_jacobians_on(m, targets)) CHECK(q > 0.2);
    // On the plane: the projection keeps z = 0.
    for (const auto& p : m.positions) CHECK(std::abs(p.z()) < 1e-12);
  });

  run("the solve is deterministic and zero iterations move nothing", [&] {
    std::vector<char> kind;
    PolygonMesh a = jittered_grid(kind), b = a;
    const PolygonMesh start = a;
    solve_along_field(a, kind, targets, along_x, 2);
    solve_along_field(b, kind, targets, along_x, 2);
    for (int v = 0; v < a.num_vertices(); ++v) CHECK(a.positions[v] == b.positions[v]);
    PolygonMesh c = start;
    solve_along_field(c, kind, targets, along_x, 0);
    for (int v = 0; v < c.num_vertices(); ++v) CHECK(c.positions[v] == start.positions[v]);
  });

  run("a straight lattice along the field stays where it is", [&] {
    std::vector<char> kind;
    PolygonMesh m = jittered_grid(kind);
    for (int j = 0; j <= kN; ++j)
      for (int i = 0; i <= kN; ++i) m.positions[grid_vertex(i, j)] = Eigen::Vector3d(i, j, 0);
    solve_along_field(m, kind, targets, along_x, 2);
    for (int j = 0; j <= kN; ++j)
      for (int i = 0; i <= kN; ++i) CHECK((m.positions[grid_vertex(i, j)] - Eigen::Vector3d(i, j, 0)).norm() < 1e-9);
  });

  run("the last pass holds the marked vertices exactly and straightens the others", [&] {
    std::vector<char> kind;
    PolygonMesh m = jittered_grid(kind);
    const PolygonMesh start = m;
    std::vector<char> held(m.num_vertices(), 0);
    for (int j = 2; j <= kN - 2; j += 3)
      for (int i = 2; i <= kN - 2; i += 4) held[grid_vertex(i, j)] = 1;  // 12 jittered vertices
    const double before = off_axis_energy(m, targets, along_x);
    refine_along_field(m, kind, targets, along_x, 6, held);
    for (int v = 0; v < m.num_vertices(); ++v)
      if (held[v] || kind[v] != kNoFeature) CHECK(m.positions[v] == start.positions[v]);
    // The held vertices keep their jitter, so their edges keep part of theirs; the rest straightens.
    // Measured: 4.02 -> 0.18 (4.6%; the solve alone without held vertices reaches 2%): 10% leaves a margin
    // of two, and the jitter alone is 4.02.
    CHECK_LE(off_axis_energy(m, targets, along_x), 0.1 * before);
    for (double q : scaled_jacobians_on(m, targets)) CHECK(q > 0.2);
    // A mask of the wrong size is refused with a message, not read past its end.
    CHECK_THROWS(ParameterError, "one entry per vertex",
                 refine_along_field(m, kind, targets, along_x, 6, std::vector<char>(3, 0)));
  });

  run("in the last pass an edge more than 18 degrees off its axis pulls neither end", [&] {
    // A straight lattice along the field with one boundary vertex slid along the boundary by 0.6 cells:
    // its edge into the square is 31 degrees off the y axis, all other edges are aligned. The solve holds
    // the faces touching a feature vertex (the whole first row), so only the local steps act there: each
    // pulls the inner end by a quarter of a quarter of that edge's off-axis part (its other three edges are
    // aligned), bending them; with the edge left out nothing moves at all.
    std::vector<char> kind;
    PolygonMesh m = jittered_grid(kind);
    for (int j = 0; j <= kN; ++j)
      for (int i = 0; i <= kN; ++i) m.positions[grid_vertex(i, j)] = Eigen::Vector3d(i, j, 0);
    m.positions[grid_vertex(6, 0)].x() += 0.6;
    const int inner = grid_vertex(6, 1);
    const std::vector<char> none(m.num_vertices(), 0);
    PolygonMesh skipping = m, pulling = m;
    refine_along_field(skipping, kind, targets, along_x, 6, none);
    refine_along_field(pulling, kind, targets, along_x, 6, none, 90.0);
    for (int v = 0; v < m.num_vertices(); ++v) CHECK((skipping.positions[v] - m.positions[v]).norm() < 1e-12);
    // Three steps of 0.6 / 16 each, less as the edge turns: 0.099 measured.
    CHECK((pulling.positions[inner] - m.positions[inner]).norm() > 0.05);
  });

  return finish();
}
