// Extraction of a quad-dominant mesh from an optimised position field (Jakob et al. 2015, section 6, in
// our own simplified form).
//
//  1. Every surface edge ij carries the integer offset D_ij of the lattice point of j from that of i
//     (lattice_offsets.hpp; after the position singularities were cancelled). D = 0: the same output
//     vertex; |D|_1 = 1: neighbouring output vertices; anything else: no relation (diagonals, jumps).
//  2. Vertices joined by D = 0 edges form clusters (union-find): the output vertices, at the area-weighted
//     mean of their members' lattice points. Clusters joined by a D = 1 edge are linked; links shorter
//     than a quarter of the spacing merge their clusters (two copies of one lattice point).
//  3. Faces: the output graph (clusters and links) is embedded in the surface, and its faces are the
//     connected regions it cuts out: surface triangles joined across every edge that is neither inside a
//     cluster, nor a link, nor on the boundary (lattice diagonals and longer jumps). Walking each region's
//     border with the surface's orientation gives the face loop; steps inside a cluster vanish and a step
//     out and straight back (a link ending inside a face, a sliver along a link) is cut off. The rotation
//     around every vertex is the surface's own, so the result is oriented and follows the surface even
//     where the lattice points are tangled (no geometric sorting of links).
//  4. A loop that revisits a vertex is split into simple loops; loops of fewer than 3 vertices are
//     dropped, and so are faces over `max_face_size`.
//  5. Faces that would make an edge non-manifold or inconsistently oriented are removed (with scraps of
//     fewer than 4 faces this cuts off), pinched vertices are split: the result is manifold and oriented by
//     construction.
//  6. Vertices are projected onto the input: corner clusters onto their corner, curve clusters onto the
//     nearest feature edge, all others onto the nearest surface point.
#pragma once
#include <vector>

#include "nfield/remesh/lattice_offsets.hpp"
#include "nfield/remesh/multires_hierarchy.hpp"
#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/remesh_surface.hpp"
#include "nfield/remesh/triangle_tree.hpp"

namespace nfield::remesh {

struct ExtractionReport {
  int clusters = 0;
  int links = 0;
  int merged_short_links = 0;
  int split_clusters = 0;       ///< clusters wrapped round a thin part, split in two (one per sheet)
  int removed_dangling = 0;     ///< spikes cut off face loops (links ending inside a face)
  int split_faces = 0;          ///< faces that revisited a vertex
  int dropped_large_faces = 0;  ///< faces over max_face_size
  int open_walks = 0;           ///< border walks that did not close (cannot happen on a valid surface)
  int removed_conflicting = 0;  ///< faces removed to keep edges manifold and oriented
  int dropped_scraps = 0;       ///< faces of pieces of fewer than 4 faces cut off by those removals
  int split_vertices = 0;       ///< copies made of pinched vertices
};

/// The surface's projection targets: the whole surface and its feature edges.
struct ProjectionTargets {
  TriangleTree surface;
  SurfaceNormals surface_normals;  ///< of `surface` (corner Jacobians, quad_stats.hpp)
  TriangleTree feature_edges;  ///< each feature edge as a degenerate triangle (a, b, b)
};
ProjectionTargets make_projection_targets(const RemeshSurface& surface, const Features& features);

/// `level0` is levels[0] after optimise_positions (one entry per surface vertex; its lattice points p give
/// the output positions, its spacings the distances below), `offsets` the integer offsets of its edges.
/// `feature_kind_out` (optional) receives the FeatureKind of each output vertex. `split_thin_clusters`: a
/// cluster whose surface points wrap round a part thinner than a lattice cell (normals against each other,
/// its lattice point off the surface by 0.08 lattice steps or more) is split into two output vertices, one
/// per side.
PolygonMesh extract_quad_mesh(const RemeshSurface& surface, const Features& features, const HierarchyLevel& level0,
                              const LatticeOffsets& offsets, const ProjectionTargets& targets, int max_face_size,
                              ExtractionReport& report, std::vector<char>* feature_kind_out = nullptr,
                              bool split_thin_clusters = true);

/// Moves each vertex onto the input: feature vertices (corner or curve) onto the nearest feature edge,
/// the others onto the nearest surface point. (Corners are snapped to their corner by the caller.)
void project_vertices(PolygonMesh& mesh, const std::vector<char>& feature_kind, const ProjectionTargets& targets);

}  // namespace nfield::remesh
