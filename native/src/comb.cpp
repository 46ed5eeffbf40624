#include "nfield/comb.hpp"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "nfield/errors.hpp"
#include "nfield/face_regions.hpp"

namespace nfield {

Falloff parse_falloff(const std::string& name) {
  if (name == "smooth") return Falloff::Smooth;
  if (name == "linear") return Falloff::Linear;
  if (name == "constant") return Falloff::Constant;
  throw ParameterError("unknown falloff '" + name + "' (expected 'smooth', 'linear' or 'constant')");
}

double falloff_weight(Falloff falloff, double t) {
  t = std::clamp(t, 0.0, 1.0);
  switch (falloff) {
    case Falloff::Smooth: return (1 - t * t) * (1 - t * t);
    case Falloff::Linear: return 1 - t;
    case Falloff::Constant: return 1;
  }
  return 0;
}

std::vector<int> apply_comb_stroke(const TriangleMesh& mesh, const TangentFrames& frames, const TriangleTree& tree,
                                   int n, const CombStroke& stroke, CombField& field) {
  const int nf = mesh.num_faces();
  if (static_cast<int>(field.direction.size()) != nf || field.weight.size() != nf)
    throw InputError("comb field must have one direction and one weight per face (" + std::to_string(nf) + ")");
  if (stroke.points.size() != stroke.directions.size())
    throw InputError("a comb stroke needs one direction per point (" + std::to_string(stroke.points.size()) +
                     " points, " + std::to_string(stroke.directions.size()) + " directions)");
  if (!(stroke.radius > 0) || !std::isfinite(stroke.radius)) throw ParameterError("comb radius must be a positive number");
  if (!(stroke.strength > 0 && stroke.strength <= 1)) throw ParameterError("comb strength must lie in (0, 1]");
  for (std::size_t i = 0; i < stroke.points.size(); ++i)
    if (!stroke.points[i].allFinite() || !stroke.directions[i].allFinite())
      throw InputError("comb sample " + std::to_string(i) + " is not finite");

  // Per face over the stroke: sum of influence * representation, largest influence.
  struct Felt {
    Complex sum = 0;
    double largest = 0;
  };
  std::unordered_map<int, Felt> felt;
  FaceWalker walker(mesh);
  for (std::size_t i = 0; i < stroke.points.size(); ++i) {
    const Eigen::Vector3d& dir = stroke.directions[i];
    if (!(dir.norm() > 0)) continue;
    const SurfacePoint hit = tree.closest(stroke.points[i]);
    if (hit.face < 0) continue;
    walker.ball(hit.face, hit.point, stroke.radius, [&](int f, double d) {
      const Complex t = frames.to_tangent(f, dir);
      if (!(std::abs(t) > 1e-6 * dir.norm())) return;  // drag along the normal: no tangent direction
      const double a = stroke.strength * falloff_weight(stroke.falloff, d / stroke.radius);
      if (!(a > 0)) return;
      Felt& x = felt[f];
      x.sum += a * std::polar(1.0, n * std::arg(t));
      x.largest = std::max(x.largest, a);
    });
  }
  std::vector<int> changed;
  for (const auto& [f, x] : felt) {
    if (!(std::abs(x.sum) > 0)) continue;
    const Complex stroke_rep = x.sum / std::abs(x.sum);
    const double a = x.largest, kappa = field.weight[f];
    Complex old_rep = 0;
    if (field.direction[f].norm() > 0) {
      const Complex t = frames.to_tangent(f, field.direction[f]);
      if (std::abs(t) > 0) old_rep = std::polar(1.0, n * std::arg(t));
    }
    Complex z = (1 - a) * kappa * old_rep + a * stroke_rep;
    if (!(std::abs(z) > 1e-12)) z = stroke_rep;  // exact cancellation: the stroke wins
    field.direction[f] = frames.to_3d(f, std::polar(1.0, std::arg(z) / n));
    field.weight[f] = std::min(1.0, kappa + a * (1 - kappa));
    changed.push_back(f);
  }
  std::sort(changed.begin(), changed.end());
  return changed;
}

GuideLayer comb_guide(const TriangleMesh& mesh, const TangentFrames& frames, int n, const CombField& field) {
  const int nf = mesh.num_faces();
  if (static_cast<int>(field.direction.size()) != nf || field.weight.size() != nf)
    throw InputError("comb field must have one direction and one weight per face (" + std::to_string(nf) + ")");
  GuideLayer out{Eigen::VectorXcd::Zero(nf), Eigen::VectorXd::Zero(nf)};
  for (int f = 0; f < nf; ++f) {
    const double w = field.weight[f];
    if (!mesh.face_active(f) || !(w > 0) || !std::isfinite(w)) continue;
    const Complex t = frames.to_tangent(f, field.direction[f]);
    if (!(std::abs(t) > 0)) continue;
    out.weight[f] = w;
    out.value[f] = w * std::polar(1.0, n * std::arg(t));
  }
  return out;
}

}  // namespace nfield
