// Comb strokes (a brush that paints guide directions, like Instant Meshes' orientation comb).
//
// The comb field is stored per face as a unit 3D tangent direction and a weight in [0, 1] (Blender keeps
// them as face attributes), independent of n, so a stroke survives a change of the symmetry order.
// A stroke is a sequence of samples (surface point, 3D direction of the drag). Each face within `radius`
// of a sample (through the surface) feels it with influence  a = strength * falloff(d / radius)  and with
// the sample's direction projected into the face; over one stroke a face takes the largest influence and
// the influence-weighted mean direction of the samples it felt (in representation space, so the n-symmetry
// is respected). The face then blends once per stroke, like paint of opacity a:
//   z   = (1 - a) * kappa * rep(old direction) + a * rep(stroke direction)      (representation vectors)
//   new direction = the first of the n directions of z,   kappa' = kappa + a (1 - kappa).
// Dense sampling therefore does not make a stroke stronger, and a stroke of strength 1 overwrites.
//
// What a stroke makes a face feel is a sum (of influence * representation vector) and a maximum (of the
// influence) over its samples: both are independent of the order and the grouping of the samples. A brush
// stroke in progress (CombStrokeState) therefore takes its samples in batches, as the mouse moves, and
// its field after every batch equals the field of one stroke of all the samples so far.
#pragma once
#include <Eigen/Core>
#include <string>
#include <unordered_map>
#include <vector>

#include "nfield/closest_point.hpp"
#include "nfield/guide_field.hpp"
#include "nfield/tangent_frames.hpp"

namespace nfield {

enum class Falloff { Smooth, Linear, Constant };
/// "smooth" (1 - t^2)^2, "linear" 1 - t, "constant" 1; ParameterError otherwise.
Falloff parse_falloff(const std::string& name);
double falloff_weight(Falloff falloff, double t);  ///< t = distance / radius in [0, 1]

struct CombField {
  std::vector<Eigen::Vector3d> direction;  ///< per face: unit tangent direction, or zero where never combed
  Eigen::VectorXd weight;                  ///< per face, in [0, 1]
};

struct CombStroke {
  std::vector<Eigen::Vector3d> points;      ///< samples on (or near) the surface
  std::vector<Eigen::Vector3d> directions;  ///< drag direction at each sample (any length > 0)
  double radius = 0;                        ///< mesh units, > 0
  Falloff falloff = Falloff::Smooth;
  double strength = 1.0;                    ///< in (0, 1]
};

/// A stroke in progress on a comb field: the field before the stroke, what the samples so far made each face
/// feel, and the field after them. add() takes the next samples; field() equals the field of one stroke of
/// every sample added so far, applied to the field before the stroke (see the file comment).
class CombStrokeState {
 public:
  /// `before`: the comb field before the stroke (sizes mesh.num_faces(), checked). The stroke's samples in
  /// `stroke` are ignored here (give them to add()); its radius, falloff and strength are checked: ParameterError
  /// for radius <= 0 or strength outside (0, 1].
  CombStrokeState(const TriangleMesh& mesh, int n, const CombStroke& stroke, CombField before);

  /// Adds samples (points, drag directions; InputError for mismatched sizes or non-finite values) and
  /// blends every face they reach again from its value before the stroke. Returns those faces, sorted (the
  /// faces whose value may have changed by this batch). Samples whose direction is (nearly) normal to the
  /// surface are skipped.
  std::vector<int> add(const TangentFrames& frames, const TriangleTree& tree, const std::vector<Eigen::Vector3d>& points,
                       const std::vector<Eigen::Vector3d>& directions);

  const CombField& field() const { return field_; }
  /// Every face the stroke has changed so far, sorted.
  std::vector<int> changed() const;

 private:
  struct Felt {
    Complex sum = 0;      ///< sum over samples of influence * representation vector of the drag direction
    double largest = 0;   ///< largest influence
  };
  void blend(const TangentFrames& frames, int f, const Felt& x);

  const TriangleMesh& mesh_;
  int n_;
  double radius_, strength_;
  Falloff falloff_;
  CombField before_, field_;
  std::unordered_map<int, Felt> felt_;
};

/// Applies one stroke to `field` (sizes num_faces); returns the faces it changed, sorted. InputError /
/// ParameterError for mismatched sizes, non-finite samples, radius <= 0 or strength outside (0, 1].
/// Samples whose direction is (nearly) normal to the surface are skipped.
std::vector<int> apply_comb_stroke(const TriangleMesh& mesh, const TangentFrames& frames, const TriangleTree& tree,
                                   int n, const CombStroke& stroke, CombField& field);

/// The comb field as a guide layer for symmetry n: value = weight * rep(direction).
GuideLayer comb_guide(const TriangleMesh& mesh, const TangentFrames& frames, int n, const CombField& field);

}  // namespace nfield
