// Fitting the output to the input where it is farthest from it: thin tips (toes, claws, fingers) that the
// lattice cuts off at one or two quads across, rounded edges that its faces cross as chords, faces that
// bulge away from the surface.
//
// The lattice has one spacing s everywhere, so where the input turns within about a quad (the tip of a toe
// one quad thick) no lattice point lies on the far end and the output ends short of it; the Hausdorff
// distance of a whole result is such one spot. Each pass lists what is farther than `threshold` s:
// vertices of the projection surface far from the (fan-triangulated) output (the output should reach
// them: a nearby output vertex moves towards the point), and output faces whose farthest sample (the
// samples of quad_stats.hpp) is far from the input (its vertices move by that sample's offset to the
// input). Farthest first, each tries up to four vertices not on a feature (those stay on their curve),
// moved all, half or a quarter of the way and projected onto the input, alone or with their face
// neighbours following by half of the move. Measured on the vertex's 2-ring of faces L (input points whose
// nearest output face is in L, by their distance to L; samples of the faces that move, by their distance
// to the input), a move is kept when
//   - it lowers the sum of squared excesses over threshold s of both sides by at least 2%,
//   - no input point of L ends farther than the farthest was, and no sample farther than its farthest or
//     threshold s (neither side of the Hausdorff distance grows),
//   - no face gets a worst corner (scaled Jacobian, quad_untangle.hpp) below 0.05, or below its own before
//     if that was lower (it runs after the untangling step, so no face flips).
// At a crease point (an input vertex on an edge whose faces' normals differ by more than
// `crease_angle_degrees`: the tip where creases meet, a corner of a ridge) that the output misses, one
// vertex put on the point can leave the points it reached before farther than the point was (it served
// both the tip and the ridge's foot). Then, for a move alone (no neighbours following) that keeps the
// corners but fails the input side, up to three face neighbours of the vertex, nearest first, try moving
// all, half or a quarter of the way to the farthest point the ring serves after the move, and the pair is
// judged as one move, by the same tests. (Rocker arm at 5,000 faces: a tip of three creases, 96-136 degrees,
// 0.43 s from the output; its nearest vertex alone left a point of the ridge below it 0.55 s away, the pair
// brings both within 0.40 s.)
// Of the moves that qualify, the smallest whose gain is at least 80% of the best one's is made (every move
// bends the rows near it). Points not served by L keep their nearest output triangle, so no input point
// gets farther; after a move its faces' 2-ring waits for the next pass (the distances were measured before).
#pragma once
#include <vector>

#include "nfield/remesh/polygon_mesh.hpp"
#include "nfield/remesh/quad_extraction.hpp"

namespace nfield::remesh {

struct FarPointFitReport {
  int passes = 0;                ///< passes that looked for moves (each is followed by a measurement)
  int moves = 0;                 ///< accepted moves (a vertex, or a vertex and its neighbours), over all passes
  int pair_moves = 0;            ///< of these, pairs: a vertex put on a crease point and a neighbour following
  double farthest_before = 0;    ///< largest input-vertex -> output distance before (mesh units)
  double farthest_after = 0;     ///< and after
  double seconds = 0;            ///< wall-clock seconds of the step
};

/// `scale`: the target edge length s (mesh units). `crease_angle_degrees`: dihedral angle above which an
/// input edge makes its ends crease points (<= 0: none, no pair moves). `threshold`: fraction of s above
/// which a distance is worked on. Only vertices of kind kNoFeature move. At most `passes` passes (fewer when one moves nothing).
FarPointFitReport fit_far_points(PolygonMesh& mesh, const std::vector<char>& feature_kind,
                                 const ProjectionTargets& targets, double scale, double crease_angle_degrees = 40,
                                 int passes = 6,
                                 double threshold = 0.4);

}  // namespace nfield::remesh
