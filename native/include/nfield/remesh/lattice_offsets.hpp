// Integer lattice offsets on the edges of the surface, the defects they reveal, and the position re-solve
// with the offsets held fixed.
//
// After the position field (position_field.hpp) every surface vertex i represents the lattice point p_i of
// its lattice L_i nearest to it. For an edge (a, b), a < b, the *offset* D_ab in Z^2 says where b's lattice
// point sits relative to a's, in lattice steps and in a's lattice coordinates (q_a, t_a):
// p_b ~ p_a + s (D_ab.x q_a + D_ab.y t_a) (Jakob et al. 2015 use it to extract the mesh; QuadriFlow, Huang
// et al. 2018, makes it the unknown of its integer step). The cross at b is matched to a's by k_ab quarter
// turns (rot^k(q_b) is the direction of b's cross nearest q_a, rot = n_b x .); coordinates c_b in b's frame
// read R^-k c_b in a's frame, R(x, y) = (-y, x) the quarter turn of Z^2.
//
// Around a triangle (a, b, c) the quarter turns add up to the *orientation index* K = k_ab + k_bc + k_ca
// (mod 4): K != 0 marks a singularity of the cross field in the triangle (our designed singularities,
// moved to vertices, land in such triangles). Around a regular triangle (K = 0) the offsets, carried into
// a's coordinates, must add up to zero for a consistent lattice:
//     r = D_ab + R^-k_ab (D_bc + R^-k_bc D_ca).
// A regular triangle with r != 0 holds a *position singularity* (a dislocation, r its Burgers vector): a
// lattice row ends there, and the extracted mesh gets a triangle next to a valence-5 vertex (or a pentagon
// next to a valence-3 one).
#pragma once
#include <Eigen/Core>
#include <array>
#include <vector>

#include "nfield/remesh/multires_hierarchy.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

/// R^k v for the quarter turn R(x, y) = (-y, x) of the integer plane (k taken mod 4).
inline Eigen::Vector2i rotate_quarter(const Eigen::Vector2i& v, int k) {
  switch (((k % 4) + 4) % 4) {
    case 0: return v;
    case 1: return {-v.y(), v.x()};
    case 2: return -v;
    default: return {v.y(), -v.x()};
  }
}

struct LatticeOffsets {
  std::vector<Eigen::Vector2i> offset;    ///< D_ab per surface edge (a, b) = surface.edges[e], a < b
  std::vector<Eigen::Vector2d> mismatch;  ///< real remainder per edge (lattice steps, a's coordinates): the
                                          ///< matched lattice points differ by s * mismatch
  std::vector<signed char> turns;         ///< k_ab per edge, 0..3
  /// D and k of the directed edge x -> y (edge e joins them): for x > y, D_yx = -R^k_xy D_xy, k_yx = -k_xy.
  Eigen::Vector2i directed_offset(int e, bool forward) const {
    return forward ? offset[e] : Eigen::Vector2i(-rotate_quarter(offset[e], turns[e]));
  }
  int directed_turns(int e, bool forward) const { return forward ? turns[e] : (4 - turns[e]) % 4; }
};

/// The offsets of level0's position field (p, q, n, v and spacing of every surface vertex) on every surface
/// edge; an edge's lattice points are matched at the mean spacing of its ends.
LatticeOffsets compute_lattice_offsets(const RemeshSurface& surface, const HierarchyLevel& level0);

/// The three edges of every triangle: face_edges[t][m] joins corners m and m + 1.
std::vector<std::array<int, 3>> triangle_edges(const RemeshSurface& surface);

struct FaceDefects {
  std::vector<signed char> orientation_index;  ///< K per triangle, 0..3 (0: regular)
  std::vector<Eigen::Vector2i> residual;       ///< r per triangle, in its first corner's coordinates
                                               ///< (meaningful on regular triangles only)
  int orientation_singularities = 0;           ///< triangles with K != 0
  int position_singularities = 0;              ///< regular triangles with r != 0
  int folded = 0;                              ///< regular triangles whose lattice image turns clockwise
};
FaceDefects face_defects(const RemeshSurface& surface, const std::vector<std::array<int, 3>>& face_edges,
                         const LatticeOffsets& offsets);

/// Moves every vertex's lattice point to the one nearest the vertex (a change of representative, not of
/// the lattice) and updates the offsets to match: D_ab <- D_ab - c_a + R^-k_ab c_b for the integer shifts
/// c (in steps of the vertex's own spacing). Face residuals do not change. Returns the number of vertices
/// whose representative changed.
int normalize_representatives(const RemeshSurface& surface, HierarchyLevel& level0, LatticeOffsets& offsets);

/// Re-solves the lattice positions with the offsets held fixed: minimises, over p_i in the tangent plane of
/// v_i,
///     sum over edges ab of |P_ab (p_b - p_a - s_ab (D.x qbar + D.y tbar))|^2 + lambda sum_i |p_i - p_i_old|^2,
/// s_ab the mean spacing of a and b, qbar, tbar the mean of a's frame and b's matched frame, P_ab the projection onto the plane orthogonal to
/// the mean normal; lambda (dimensionless, per vertex, against unit edge weights) only pins the free
/// translation. Feature constraints are exact: a corner's lattice point stays on the corner, a curve
/// vertex keeps its lattice line through the curve point. One sparse Cholesky factorization (CHOLMOD).
/// Returns false (positions unchanged) if the factorization fails.
bool resolve_positions(const RemeshSurface& surface, HierarchyLevel& level0, const LatticeOffsets& offsets,
                       double lambda = 1e-3);

}  // namespace nfield::remesh
