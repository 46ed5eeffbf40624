// Feature edges (boundary, sharp, user-marked) and the guides they give a field.
//
// A feature edge is an edge the field should follow: its direction (and, for n = 4, its perpendicular,
// which the cross contains anyway) at the faces next to it. detect_features() collects
//   - boundary edges (one active face),
//   - sharp edges: two faces whose normals differ by more than `sharp_angle` (the bend angle, 0 = flat),
//   - edges the caller marks (Blender: sharp or seam edges, borders of face sets or material slots),
// and links them into chains: maximal paths of feature edges through vertices where exactly two feature
// edges meet without turning by more than `corner_angle`. The other feature vertices are corners (three or
// more features meet, or one feature turns sharply) or ends. A chain's walking order orients its edges,
// which matters for odd n only (an n-direction field with even n cannot tell an edge from its reverse).
//
// Two ways to use them:
//   soft: feature_band_guide() gives every face within `width` edge rings of a feature a guide direction
//         (the nearest feature edges' direction projected into the face) with a weight falling linearly
//         from 1 at the faces next to the edge to 1/width at the last ring;
//   hard: feature_hard_directions() gives one direction constraint per face next to every k-th edge of each
//         chain; merge_hard_directions() (guide_field.hpp) then removes contradictions where features meet.
#pragma once
#include <array>
#include <vector>

#include "nfield/guide_field.hpp"
#include "nfield/mesh_edges.hpp"
#include "nfield/tangent_frames.hpp"

namespace nfield {

struct FeatureOptions {
  bool boundary = true;
  /// Bend angle in degrees above which an edge is sharp; negative: no sharp edges.
  double sharp_angle = -1.0;
  /// Further feature edges as vertex pairs (any order). Pairs that are not edges of an active face are
  /// an InputError naming them.
  std::vector<std::array<int, 2>> edges;
  /// A chain breaks (the vertex is a corner) where it turns by more than this many degrees.
  double corner_angle = 45.0;
};

struct FeatureChain {
  std::vector<int> vertices;  ///< in walking order; edges.size() + 1 entries (closed: last == first)
  std::vector<int> edges;     ///< MeshEdges ids in walking order
  bool closed = false;
};

struct FeatureSet {
  std::vector<int> edges;  ///< feature edge ids (MeshEdges), sorted
  std::vector<FeatureChain> chains;
  std::vector<int> corners;  ///< vertices where three or more features meet or a feature turns sharply
  int num_boundary = 0, num_sharp = 0, num_marked = 0;  ///< edges by reason (an edge counts once, first reason)
};

/// ParameterError for sharp_angle outside [-inf, 180) or corner_angle outside [0, 180].
FeatureSet detect_features(const TriangleMesh& mesh, const MeshEdges& edges, const FeatureOptions& options);

/// Soft feature guide: weight in (0, 1] within `width` (>= 1) edge rings of a feature, 0 elsewhere; the value
/// is weight times the mean unit representation vector of the feature edges that reach the face at its
/// smallest ring (so features that disagree at a face pull less there).
GuideLayer feature_band_guide(const TriangleMesh& mesh, const TangentFrames& frames, int n, const MeshEdges& edges,
                              const FeatureSet& features, int width);

/// Hard feature guide: for every chain, the faces next to its edges 0, k, 2k, ... (every = k >= 1) get the
/// edge's direction as a unit representation vector. A face next to several chosen edges appears once per edge.
std::vector<HardDirection> feature_hard_directions(const TriangleMesh& mesh, const TangentFrames& frames, int n,
                                                   const MeshEdges& edges, const FeatureSet& features, int every);

}  // namespace nfield
