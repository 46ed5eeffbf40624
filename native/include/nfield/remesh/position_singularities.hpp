// Cancelling position singularities with a minimum-cost flow on the integer offsets (the idea of
// QuadriFlow, Huang, Zhou, Niessner, Shewchuk, Guibas 2018, section 4, in our own formulation; the
// orientation field stays ours and fixed).
//
// Every regular triangle f gives two integer equations: its residual r_f (lattice_offsets.hpp), written in
// an *equation frame* R^g_f of its first corner's coordinates, must vanish. Each component of an edge offset
// D_e enters the equations of the two triangles of e with a coefficient +-1 (a quarter turn may move it
// from the x to the y equation). When the two coefficients have opposite signs, raising that component by
// one moves one unit of residual from one equation to the other: it is an arc of a flow network whose
// nodes are the equations and whose supplies are the residuals. The frames g_f are chosen by a
// breadth-first search over the dual graph so that this holds on every dual edge except along the seams
// the search leaves through the field's rotation; offsets that enter two equations with the same sign
// stay as they are.
//
// Sinks besides opposite residuals: the boundary (an offset of a boundary edge enters one equation; the
// other end is a free node S: a lattice row may end on the boundary, at an extra cost, see
// CancellationOptions::boundary_cost) and the orientation singularities
// (a triangle with K != 0 absorbs a unit at a fixed cost: the lattice around a cone may be centred on a
// vertex or a cell, and may shift its centre). On feature edges the offset component across the curve is
// fixed (the curve stays a lattice line).
//
// Costs: changing a component of D_e by delta costs ((m - delta)^2 - m^2) (m the real remainder of that
// component, mismatch in lattice_offsets.hpp), the growth of the position energy on that edge, so each
// unit costs about one and a path costs about the number of edges it crosses; at most two units per
// component and direction. The minimum-cost flow (min_cost_flow.hpp) pairs every dislocation with an
// opposite one, a cone or the boundary along the cheapest set of paths at once (not greedily), and the
// offsets change along those paths. The positions are then re-solved with the offsets fixed
// (resolve_positions), which spreads the inserted or removed half-rows over the surface.
//
// The flow runs on the lattice-level mesh (lattice_collapse.hpp: the surface with its zero-offset edges
// collapsed, about two triangles per output quad instead of twenty), where a path step is a lattice step;
// its offsets are then written back onto the surface's edges. A unit of residual then moves by whole
// lattice edges (as in QuadriFlow, whose flow runs on the graph of the extracted vertices).
#pragma once
#include <functional>
#include <vector>

#include "nfield/remesh/lattice_offsets.hpp"

namespace nfield::remesh {

struct CancellationOptions {
  double cone_cost = 1.0;      ///< cost of one unit absorbed by an orientation singularity (lattice steps)
  double give_up_cost = 20.0;  ///< cost of leaving one unit where it is (lattice steps): pairs further
                               ///< apart than twice this stay
  /// Extra cost of one unit leaving (or entering) through the boundary (lattice steps). A row that ends on
  /// the boundary leaves a boundary vertex of the wrong valence there (4 edges on a straight boundary, as a
  /// T-junction), one irregular vertex per unit, while two opposite row ends paired inside vanish: without
  /// this cost the flow sent every row end within a few steps of a hole's rim to the rim (the bunny's base
  /// at 5,000 faces: 106 irregular vertices with 0, 96 with 3, 85 with 5). Not higher: from 4 on, the
  /// changed pairing left 3 flipped faces on the bunny's ears in pure-quad mode by subdivision at 3,000
  /// faces (a lattice twice as coarse, the ears one cell across), which the untangling could not repair.
  double boundary_cost = 3.0;
  int max_change = 2;          ///< at most this many units per offset component and direction
  bool collapse = true;        ///< solve on the lattice-level mesh (lattice_collapse.hpp) instead of the surface
};

struct CancellationReport {
  int orientation_singularities = 0;
  int position_singularities_before = 0, position_singularities_after = 0;
  int folded_before = 0;
  long long routed = 0, unrouted = 0;  ///< residual units paired / left
  int changed_offsets = 0;            ///< edge offset components changed
  int fixed_offsets = 0;              ///< offset components the network cannot change (seams, features)
  double cost = 0;
  int phases = 0, augmentations = 0;  ///< of the flow solver (min_cost_flow.hpp)
  int network_triangles = 0;          ///< triangles of the mesh the flow ran on (two equations each)
  double seconds_collapse = 0, seconds_network = 0, seconds_solve = 0;  ///< collapsing / building / solving
};

/// Changes `offsets` so that as many regular triangles as possible have zero residual, at least total
/// cost. level0 holds the vertex frames (q, n) and spacings (a path's cost counts lattice steps of the
/// local spacing). `feature_edge` (per surface edge, may be empty) marks feature edges. `cancelled` is polled.
CancellationReport cancel_position_singularities(const RemeshSurface& surface, const HierarchyLevel& level0,
                                                 const std::vector<std::array<int, 3>>& face_edges,
                                                 const std::vector<char>& feature_edge, LatticeOffsets& offsets, const CancellationOptions& options = {},
                                                 const std::function<bool()>& cancelled = {});

}  // namespace nfield::remesh
