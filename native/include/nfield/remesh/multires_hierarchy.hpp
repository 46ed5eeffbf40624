// The multiresolution hierarchy on which the position field is optimised (Jakob et al. 2015, section 5).
//
// Level 0 is the vertex graph of the surface (unit edge weights). Each coarser level merges disjoint pairs
// of neighbouring vertices, chosen greedily by a score that prefers similar normals and small combined
// area (so that clusters grow evenly); a vertex left without a partner is carried over alone. A merged
// vertex gets the area-weighted mean position, normal and lattice spacing, the summed area (length^2), the children's cross
// directions averaged n-symmetrically (we do NOT smooth the cross field: it is the designed one, only
// restricted), and the strongest feature constraint of its children. Edge weights of a coarse level are
// the summed weights of the fine edges between the two clusters. Levels stop when a level no longer
// shrinks by 10% or has at most `min_vertices` vertices.
#pragma once
#include <vector>

#include "nfield/remesh/lattice.hpp"

namespace nfield::remesh {

struct HierarchyLevel {
  std::vector<Vec3> v, n, q, p;  ///< position, unit normal, cross direction, lattice position
  std::vector<double> area;
  /// Lattice spacing per vertex (mesh units): the target edge length, or it times e^u with the conformal
  /// log-scale u of lattice_spacing.hpp. A pair of vertices uses the mean of theirs (pair_spacing).
  std::vector<double> spacing;
  std::vector<int> adjacency_offsets, adjacency;
  std::vector<double> adjacency_weight;
  std::vector<int> parent;  ///< vertex of the next coarser level (empty on the coarsest level)
  /// Feature constraint (FeatureKind of remesh_surface.hpp): 1 curve, 2 corner, 0 none. For curves the
  /// lattice line along the cross direction nearest `constraint_dir` must pass through `constraint_point`;
  /// for corners a lattice point must sit on `constraint_point`.
  std::vector<char> constraint_kind;
  std::vector<Vec3> constraint_point, constraint_dir;
  int size() const { return static_cast<int>(v.size()); }
  double pair_spacing(int i, int j) const { return 0.5 * (spacing[i] + spacing[j]); }
};

/// Builds levels[1..] from levels[0] (which must have v, n, q, area, adjacency and constraints filled).
void build_hierarchy(std::vector<HierarchyLevel>& levels, int min_vertices = 16);

}  // namespace nfield::remesh
