// The last, guarded step of the quad remesher: moving the vertices of flipped faces until no face is
// flipped.
//
// A face is *flipped* when one of its corners has a scaled Jacobian <= 0 against the input's normal at
// that corner (quad_stats.hpp: turned against the surface, folded over, or a dart). The pipeline's own
// steps avoid the known causes (faces are cut out of the surface with its own orientation, clusters sit on
// the lattice points their feature members satisfy, creases the field crosses are not forced); what is
// left comes from lattice points that the position field could not separate: a few faces per mesh, next
// to cones or on parts about one lattice cell thick.
//
// Each round visits the vertices of the faces whose worst corner is below `margin` (and, from the third
// round on, their neighbours too) and moves each to the best of a few candidates, if that raises the
// smallest corner Jacobian of its faces: the mean of its neighbours, the mean of the positions that would
// make each of its quads a parallelogram, and points a quarter, half and three quarters of the way to
// them, each projected back onto the input (a curve vertex onto its feature; corners stay). Rounds stop
// when no face is below the margin or nothing improved. Only if faces are still flipped then, the same
// rounds run again with corners sliding along the features, and then once more with every vertex free
// on the surface: a feature vertex a little off its feature is the lesser evil. The topology does not
// change, so the mesh stays manifold and oriented.
#pragma once
#include <vector>

#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/quad_extraction.hpp"

namespace nfield::remesh {

struct UntangleReport {
  int flipped_before = 0;  ///< faces with a corner Jacobian <= 0 before (pure quads: before and after the subdivision)
  int flipped_after = 0;   ///< and after
  int moved_vertices = 0;  ///< vertex moves made
  int released_features = 0;  ///< moves of feature vertices off their corner / feature (stages 1 and 2)
  int rounds = 0;
  int split_faces = 0;     ///< faces split by split_flipped_faces (set by the caller)
  int removed_doublets = 0;  ///< valence-2 vertices of flipped faces removed (set by the caller)
  int collapsed_edges = 0;   ///< vertices merged with another at (nearly) the same point (set by the caller)
  int dropped_scraps = 0;    ///< faces of pieces of fewer than 4 faces those changes left (set by the caller)
};

UntangleReport untangle_flipped_faces(PolygonMesh& mesh, const std::vector<char>& feature_kind,
                                      const ProjectionTargets& targets, double margin = 0.05, int max_rounds = 30);

/// For faces still flipped after untangle_flipped_faces (worst corner <= `below`; quad-dominant output, or
/// the quad-dominant mesh before the pure-quad subdivision): splits each along the diagonal whose two parts
/// have the best worst corner, when that is better than the face's own and both parts are unflipped. This is for corners
/// that cannot move (a feature corner met by two faces, one of them wrapping round a corner of the
/// surface): the face becomes a triangle and a quad, or two triangles. Returns the number of faces split.
int split_flipped_faces(PolygonMesh& mesh, const ProjectionTargets& targets, double below = 0);

/// Minimum corner scaled Jacobian per face against the projection surface (as quad_stats.hpp's, with the
/// remesher's own cut surface as the reference).
std::vector<double> scaled_jacobians_on(const PolygonMesh& mesh, const ProjectionTargets& targets);

/// The same for one face f (-2 for a face with an edge of (nearly) zero length).
double worst_corner_on(const PolygonMesh& mesh, int f, const ProjectionTargets& targets);

}  // namespace nfield::remesh
