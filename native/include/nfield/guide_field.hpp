// Guide layers: per-face guide directions with weights, how several sources combine, and the merging of
// hard guide directions (feature and curve constraints) into one constraint per face.
//
// A soft guide source (features, curves, the comb) gives each face a weight w_f >= 0 and a unit
// representation vector g_f; it is stored as the complex value w_f * c_f * g_f, where c_f in [0, 1] is the
// coherence of the contributions the face received (the length of their weighted mean in representation
// space: 1 when they agree, less where directions that the n-symmetry cannot identify meet, 0 where they
// cancel). How the sources then enter the spline is decided in nfield.core (docs/guides.md): for
// n-direction splines only the sum of the values matters (the alignment term is linear in the guide).
#pragma once
#include <Eigen/Core>
#include <utility>
#include <vector>

#include "nfield/tangent_frames.hpp"

namespace nfield {

/// The unit representation vector (symmetry n) of the 3D vector v projected into face f's tangent plane:
/// (t / |t|)^n with t the tangent part of v, or 0 where v is (nearly) normal to the face (|t| <= 1e-9 |v|).
/// Powers by squaring instead of exp(i n arg t): no trigonometry per face and sample of a guide (the same value
/// to a few ulp).
Complex unit_representation(const TangentFrames& frames, int f, const Eigen::Vector3d& v, int n);

/// One soft guide source, per face (size num_faces; zero on inactive faces and where the source is silent).
struct GuideLayer {
  Eigen::VectorXcd value;  ///< weight * coherence * unit representation vector
  Eigen::VectorXd weight;  ///< >= 0
};

/// Collects weighted unit representation vectors per face and turns them into a GuideLayer:
/// weight = the largest contribution, value = weight * (sum w d) / (sum w).
class GuideAccumulator {
 public:
  explicit GuideAccumulator(int num_faces);
  /// d: unit representation vector (or zero: ignored), w > 0.
  void add(int face, Complex d, double w);
  GuideLayer finish() const;

 private:
  Eigen::VectorXcd sum_;
  Eigen::VectorXd total_, largest_;
};

/// A direction constraint proposed by a hard guide.
struct HardDirection {
  int face;
  Complex direction;  ///< unit representation vector in the face frame
  int source;         ///< which feature chain / curve proposed it (for reports)
};

/// A face whose proposals contradict each other: the worst pair and the angle between them.
struct DroppedDirection {
  int face;
  int source_a, source_b;
  double degrees;  ///< field angle between the two proposals, modulo the n-symmetry (0 .. 180/n)
};

struct MergedDirections {
  std::vector<std::pair<int, Complex>> constraints;  ///< one unit representation vector per face, sorted by face
  std::vector<DroppedDirection> dropped;             ///< faces whose proposals contradict each other
};

/// Faces proposed more than once keep the mean direction if every pair of proposals agrees to within
/// `tolerance` radians of field angle (n * tolerance in representation space); otherwise the face gets no
/// constraint and is reported (two features meeting at a corner at an angle the n-symmetry cannot absorb:
/// the face next to both cannot follow both).
MergedDirections merge_hard_directions(std::vector<HardDirection> proposals, int n, double tolerance);

}  // namespace nfield
