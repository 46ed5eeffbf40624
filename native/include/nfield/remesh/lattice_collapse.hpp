// The lattice-level triangle mesh: the surface with every edge of zero integer offset collapsed.
//
// The surface the position field lives on is finer than the lattice (edges below half a lattice step), so
// most of its edges join two vertices that represent the same lattice point (offset D = 0, lattice_offsets.hpp).
// Collapsing those edges leaves a triangle mesh whose vertices are lattice points (about one per output
// vertex) and whose triangles are lattice triangles (about two per output quad), with the same residuals
// wherever they are not zero: the minimum-cost flow of position_singularities.hpp runs on it, on about a
// tenth of the nodes, where one step of a path is one lattice step.
//
// An edge (a, b) is collapsed (b into a) only when nothing is lost:
//  - its offset is zero and its one or two triangles are regular (orientation index 0) with zero residual,
//    so the two edges (a, c), (b, c) of each such triangle carry the same offset once written in a's frame;
//  - the link condition holds (the common neighbours of a and b are the third corners of those triangles),
//    an interior edge does not join two boundary vertices, and a keeps at least three neighbours: the
//    collapsed mesh is a manifold of the same topology.
// Frames: coordinates in b's frame read R^-k_ab c in a's frame (lattice_offsets.hpp), so an edge (b, c)
// becomes (a, c) with D_ac = R^-k_ab D_bc and k_ac = k_ab + k_bc. Every fine vertex u keeps the turn T_u
// to its coarse vertex A (coordinates in u's frame read R^-T_u c in A's frame); a fine edge (u, v) between
// different coarse vertices A, C then has D_uv = R^T_u D_AC, and a fine edge inside one coarse vertex has
// D = 0 and stays so.
#pragma once
#include <array>
#include <vector>

#include "nfield/remesh/lattice_offsets.hpp"

namespace nfield::remesh {

struct CoarseLattice {
  RemeshSurface surface;               ///< coarse triangles; positions: the lattice points of the coarse vertices
  LatticeOffsets offsets;              ///< per coarse edge (a < b, a's frame); mismatch: mean over its fine edges
  std::vector<unsigned char> fixed;    ///< per coarse edge: bit c set = offset component c may not change
  std::vector<int> vertex_of;          ///< fine vertex -> coarse vertex (-1: in no triangle)
  std::vector<signed char> turn_of;    ///< fine vertex -> T_u (0..3)
  int collapsed_edges = 0;
};

/// Collapses the zero-offset edges of `fine` as described above. `fixed` per fine edge (bit c: component c of the offset may not change; may be empty); `lattice_points`
/// per fine vertex (the coarse positions).
CoarseLattice collapse_zero_offsets(const RemeshSurface& fine, const LatticeOffsets& offsets, const std::vector<unsigned char>& fixed,
                                    const std::vector<Vec3>& lattice_points);

/// Writes the coarse offsets back onto the fine edges between different coarse vertices (D_uv = R^T_u D_AC);
/// edges inside a coarse vertex keep theirs. Returns the number of fine offsets that changed.
int expand_offsets(const RemeshSurface& fine, const CoarseLattice& coarse, LatticeOffsets& fine_offsets);

}  // namespace nfield::remesh
