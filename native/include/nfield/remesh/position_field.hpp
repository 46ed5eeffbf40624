// Optimisation of the 4-PoSy position field on the hierarchy (Jakob et al. 2015, sections 4 and 5).
//
// Energy: sum over edges ij of w_ij |P_ij - P_ji|^2, where (P_ij, P_ji) is the pair of lattice points of
// L_i and L_j nearest to each other near the edge (closest_lattice_pair). It is minimised by the paper's
// Gauss-Seidel sweeps: vertex i moves its lattice origin to the weighted running mean of the matched
// points, projects it onto its tangent plane, and finally takes the lattice point nearest to v_i as its
// new origin (so p_i always represents the output vertex closest to v_i). The cross directions q are
// fixed (our designed field); only positions move.
//
// Coarse to fine: random origins (from `seed`) on the coarsest level, `iterations` sweeps per level,
// then each fine vertex starts from its parent's origin projected onto its own tangent plane.
//
// Feature constraints, applied after each update: at a corner the origin is moved onto the corner
// point; at a curve vertex the origin moves perpendicular to the lattice axis most parallel to the curve
// until that lattice line passes through the constraint point.
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include "nfield/remesh/multires_hierarchy.hpp"

namespace nfield::remesh {

/// progress(fraction in [0, 1]) -> false cancels (the optimiser then throws nfield::Cancelled).
using Progress = std::function<bool(double)>;

struct PositionFieldOptions {
  double scale = 1.0;           ///< lattice spacing s (mesh units) of the levels without their own `spacing`
  int iterations = 10;          ///< Gauss-Seidel sweeps per level
  std::uint64_t seed = 0;
};

/// Fills p on every level (levels[0].p is the result). `progress` covers the whole optimisation.
void optimise_positions(std::vector<HierarchyLevel>& levels, const PositionFieldOptions& options,
                        const Progress& progress = {});

/// The constraint step alone (exposed for tests): returns p moved to satisfy vertex i's constraint.
Vec3 apply_position_constraint(const HierarchyLevel& level, int i, const Vec3& p);

}  // namespace nfield::remesh
