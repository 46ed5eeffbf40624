// Curve guides: a 3D polyline projected onto the surface, whose tangents guide the field (soft, with a
// falloff width) or constrain it (hard, on the faces it crosses).
//
// The polyline is resampled with spacing h (midpoints of equal pieces of each segment, so every sample
// has one well-defined tangent, its segment's direction); each sample moves to its closest point on the
// surface (TriangleTree). Samples farther than `tolerance` from the surface are dropped and counted: the
// curve "misses" the surface there. The tangent at a sample is its segment direction projected into the
// face it landed on (a curve drawn slightly off the surface still gives tangent directions).
#pragma once
#include <Eigen/Core>
#include <vector>

#include "nfield/closest_point.hpp"
#include "nfield/guide_field.hpp"
#include "nfield/tangent_frames.hpp"

namespace nfield {

struct ProjectedCurve {
  std::vector<int> faces;                 ///< face of each kept sample, in curve order
  std::vector<Eigen::Vector3d> points;    ///< closest surface point of each kept sample
  std::vector<Eigen::Vector3d> tangents;  ///< unit 3D segment direction of each kept sample
  int num_samples = 0;                    ///< samples taken (kept + missed)
  int num_missed = 0;                     ///< samples farther than the tolerance from the surface
  double max_distance = 0;                ///< largest sample-to-surface distance (kept or missed), mesh units
};

/// points: (k, 3) polyline, k >= 2, finite (InputError otherwise); spacing > 0 and tolerance >= 0 in mesh
/// units (ParameterError otherwise). Zero-length segments are skipped.
ProjectedCurve project_curve(const TriangleTree& tree, const std::vector<Eigen::Vector3d>& points, double spacing,
                             double tolerance);

/// Soft curve guide: faces within `width` (mesh units, >= 0) of a kept sample, through the surface, get the
/// sample's tangent with weight `weight` (1 - (d / width)^2)^2 (smooth falloff, full on the curve); width 0:
/// only the faces the samples land on. Several curves accumulate into one layer.
void add_curve_band(const TriangleMesh& mesh, const TangentFrames& frames, int n, const ProjectedCurve& curve,
                    double width, double weight, GuideAccumulator& into);

/// Hard curve guide: the faces the curve crosses, in order (consecutive repeats merged), every k-th of them,
/// each with the mean tangent of the samples that landed on it.
std::vector<HardDirection> curve_hard_directions(const TangentFrames& frames, int n, const ProjectedCurve& curve,
                                                 int every, int source);

}  // namespace nfield
