// Evenly spaced streamlines ("hatching strokes") of a face-based n-direction field (paper section 10).
//
// Field and directions. The field is one complex representation vector z_f per face (see
// tangent_frames.hpp): the n directions of face f are the angles
//     phi_{f,k} = arg(z_f) / n + offset + 2 pi k / n,   k = 0..n-1,
// in f's frame, with offset = 0 for the main family and offset = pi/2 for the cross-hatching family.
// The field is constant per face, so a streamline inside a face is a straight segment; it is integrated
// *exactly*: from the current point it runs along the face direction to the face boundary (or for at most
// one step h, see below). At an edge the curve continues into the neighbour across the dual edge: the
// incoming direction d is transported by unfolding the two faces about the shared edge e (hinge map
//     d' = (d . e) e + (d . (N_0 x e)) (N_1 x e),
// the discrete Levi-Civita transport of tangent_frames.hpp), and of the n directions of the neighbour the
// one closest to d' is taken (n-symmetric matching, so strokes never flip). The turn |angle(d', chosen)|
// measures how much the field rotates between the two faces; above `max_turn` the stroke stops (this is
// what happens next to a singularity).
//
// Points are kept as barycentric coordinates of their face; a point where a stroke crosses an edge has the
// exact barycentric coordinate 0 for the opposite corner, so every output point lies on its face (up to
// rounding of sum_i lambda_i P_i) and every segment lies inside one face: strokes never leave the surface.
//
// Stopping rules (the stroke ends at the last accepted point):
//   - a boundary edge, a cut (non-manifold / orientation cut) or an edge next to an inactive face;
//   - a face where the field vanishes (|z_f| <= 1e-12) or is not finite;
//   - a face incident to a singular vertex (index != 0, singularities.hpp) when stop_at_singularities, and
//     a turn between adjacent faces above max_turn (default 45 degrees);
//   - the field pointing back across the edge just crossed (a "sink" edge: the curve cannot enter);
//   - a point closer than d_test(p) to another stroke of the same family, or to a point of the same stroke
//     more than 2 d_sep(p) of arc length away (a stroke closing on itself);
//   - the stroke length reaching max_length, or the hard caps below.
//
// Even spacing in the spirit of Jobard & Lefer (1997), "Creating evenly-spaced streamlines of arbitrary
// density". Lengths are mesh units.
//   d_sep      separation between neighbouring strokes;
//   d_test     = test_ratio * d_sep (default 0.5): a stroke stops when closer than this to another;
//   h          = step_ratio * d_sep (default 0.2): sample spacing along a stroke. Each step moves by
//              min(h, distance to the face boundary), so a step never crosses more than one face; every
//              edge crossing is also a sample point. The distance test runs at every sample point against
//              the sample points of the other strokes (a 3D hash grid with cells of d_test).
//   Seeds: the first stroke starts at the centroid of a pseudo-random face; after a stroke is accepted, each
//   of its sample points proposes two seed candidates at geodesic distance d_sep(p) on either side (a
//   straight walk in the tangent plane along N x d, unfolded across edges, so candidates stay on the surface;
//   it fails at a boundary). A candidate is accepted if it is at least seed_ratio * d_sep (default 0.9, to
//   allow for chords being shorter than geodesic distances on curved surfaces) from every stroke of the
//   family. When no candidate is left, faces are tried in a pseudo-random order (their centroids, the
//   direction k = family), so every connected component gets strokes. The order comes from
//   std::mt19937_64(seed) with a hand-written Fisher-Yates shuffle: results are deterministic for a seed
//   (and identical across platforms up to floating-point differences).
//   Seed candidates carry the parent stroke's direction (transported along the walk) and start along the
//   matching direction of their face, so for n = 4 a family stays locally one direction. Face-centroid
//   seeds start perpendicular to the nearest main-family sample within 3 d_sep (cross family), else along
//   the nearest sample of their own family within 3 d_sep, else along the direction k = family.
//   Strokes shorter than min_length are discarded.
// Density modulation: an optional scalar rho in [0, 1] per vertex (interpolated barycentrically) or per face
// scales the local separation:  d_sep(p) = d_sep / max(rho(p), min_density)  (and d_test(p), the seed offset
// and the seed test scale with it), so rho = 1 gives the base spacing, rho = 0.5 twice the spacing, and
// rho <= min_density (default 0.1) the sparsest spacing d_sep / min_density. Stroke length per area is
// therefore roughly proportional to max(rho, min_density).
// Cross-hatching traces a second family (offset pi/2) with its own spacing test; strokes of different
// families cross. For n = 2 it is the perpendicular field. A 4-field cannot be split into two families
// globally, so for n = 4 with cross-hatching the field is first combed into a 2-field (a maximum-smoothness
// spanning forest over the dual edges picks, per face, which pair of directions is family 0); strokes then
// stop at the comb's seams (where the pair flips, the matched direction turns ~90 degrees > max_turn), and
// the two families are exactly perpendicular in every face. Without cross-hatching a 4-field is traced with
// 4-symmetric matching (strokes run through, family follows continuity).
//
// Hard caps (the tracer never loops forever): at most max_points_per_stroke points per stroke, at most
// max_total_points points in total (then `truncated` is set and tracing ends), a walk for a seed crosses at
// most 10000 faces, and a stroke stops after 16 consecutive zero-length moves (e.g. circling a vertex).
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <vector>

#include "nfield/operators.hpp"

namespace nfield {

struct StreamlineParams {
  double separation = 0.0;       ///< d_sep (mesh units), > 0
  double test_ratio = 0.5;       ///< d_test = test_ratio * d_sep, in (0, 1]
  double step_ratio = 0.2;       ///< h = step_ratio * d_sep, in (0, 1]
  double seed_ratio = 0.9;       ///< seeds need distance >= seed_ratio * d_sep(p) to strokes, in [test_ratio, 1]
  double max_length = std::numeric_limits<double>::infinity();  ///< per stroke (mesh units), > 0
  double min_length = 0.0;       ///< shorter strokes are discarded (mesh units), >= 0
  int family = 0;                ///< direction index k in 0..n-1 for seeds without a parent stroke
  bool cross_hatch = false;      ///< also trace the family rotated by pi/2 (family id 1)
  std::uint64_t seed = 0;        ///< RNG seed (face order)
  double max_turn = 0.7853981633974483;  ///< radians; stop when the matched direction turns more between faces
  bool stop_at_singularities = true;     ///< stop in faces incident to singular vertices
  std::vector<double> density;   ///< empty, or per vertex (density_per_vertex) / per face, values in [0, 1]
  bool density_per_vertex = true;
  double min_density = 0.1;      ///< in (0, 1]
  long long max_total_points = 5000000;  ///< ~100 bytes each while tracing
  long long max_points_per_stroke = 2000000;
};

struct Stroke {
  /// Polyline on the surface (mesh units). Segment i (points[i] -> points[i+1]) lies inside face faces[i];
  /// points[i] lies on faces[i] (edge-crossing points lie on both faces of the edge).
  std::vector<Eigen::Vector3d> points;
  std::vector<int> faces;
  int family = 0;  ///< 0: main family, 1: cross-hatching family
  double length = 0.0;
};

struct StreamlineStats {
  long long num_points = 0;
  int num_strokes = 0;
  int num_discarded = 0;         ///< traced but shorter than min_length
  long long num_candidates = 0;  ///< seed candidates examined
  int num_blocked_faces = 0;     ///< faces excluded as incident to singular vertices
  int num_singularities = 0;
  bool truncated = false;        ///< max_total_points was reached
  /// Per family: area fraction of the traceable faces (active, non-zero field) whose centroid is within
  /// d_sep(centroid) of a sample point of that family.
  std::vector<double> coverage;
};

struct Streamlines {
  std::vector<Stroke> strokes;
  StreamlineStats stats;
};

/// Trace evenly spaced strokes of `field` (complex, one value per face of ops.mesh()). Throws
/// ParameterError for invalid parameters and InputError for a field / density of the wrong size or
/// non-finite densities.
Streamlines trace_streamlines(const FieldOperators& ops, const ComplexVector& field, const StreamlineParams& params);

}  // namespace nfield
