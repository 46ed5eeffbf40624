#include "nfield/comb.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

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

CombStrokeState::CombStrokeState(const TriangleMesh& mesh, int n, const CombStroke& stroke, CombField before)
    : mesh_(mesh), n_(n), radius_(stroke.radius), strength_(stroke.strength), falloff_(stroke.falloff),
      before_(std::move(before)) {
  const int nf = mesh.num_faces();
  if (static_cast<int>(before_.direction.size()) != nf || before_.weight.size() != nf)
    throw InputError("comb field must have one direction and one weight per face (" + std::to_string(nf) + ")");
  if (!(radius_ > 0) || !std::isfinite(radius_)) throw ParameterError("comb radius must be a positive number");
  if (!(strength_ > 0 && strength_ <= 1)) throw ParameterError("comb strength must lie in (0, 1]");
  field_ = before_;
}

std::vector<int> CombStrokeState::add(const TangentFrames& frames, const TriangleTree& tree,
                                      const std::vector<Eigen::Vector3d>& points,
                                      const std::vector<Eigen::Vector3d>& directions) {
  if (points.size() != directions.size())
    throw InputError("a comb stroke needs one direction per point (" + std::to_string(points.size()) + " points, " +
                     std::to_string(directions.size()) + " directions)");
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!points[i].allFinite() || !directions[i].allFinite())
      throw InputError("comb sample " + std::to_string(i) + " is not finite");
  std::vector<int> reached;
  FaceWalker walker(mesh_);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d& dir = directions[i];
    if (!(dir.norm() > 0)) continue;
    const SurfacePoint hit = tree.closest(points[i]);
    if (hit.face < 0) continue;
    walker.ball(hit.face, hit.point, radius_, [&](int f, double d) {
      const Complex t = frames.to_tangent(f, dir);
      if (!(std::abs(t) > 1e-6 * dir.norm())) return;  // drag along the normal: no tangent direction
      const double a = strength_ * falloff_weight(falloff_, d / radius_);
      if (!(a > 0)) return;
      Felt& x = felt_[f];
      x.sum += a * std::polar(1.0, n_ * std::arg(t));
      x.largest = std::max(x.largest, a);
      reached.push_back(f);
    });
  }
  std::sort(reached.begin(), reached.end());
  reached.erase(std::unique(reached.begin(), reached.end()), reached.end());
  for (int f : reached) blend(frames, f, felt_.at(f));
  return reached;
}

void CombStrokeState::blend(const TangentFrames& frames, int f, const Felt& x) {
  if (!(std::abs(x.sum) > 0)) {  // the samples cancel: the face keeps its value from before the stroke
    field_.direction[f] = before_.direction[f];
    field_.weight[f] = before_.weight[f];
    return;
  }
  const Complex stroke_rep = x.sum / std::abs(x.sum);
  const double a = x.largest, kappa = before_.weight[f];
  Complex old_rep = 0;
  if (before_.direction[f].norm() > 0) {
    const Complex t = frames.to_tangent(f, before_.direction[f]);
    if (std::abs(t) > 0) old_rep = std::polar(1.0, n_ * std::arg(t));
  }
  Complex z = (1 - a) * kappa * old_rep + a * stroke_rep;
  if (!(std::abs(z) > 1e-12)) z = stroke_rep;  // exact cancellation: the stroke wins
  field_.direction[f] = frames.to_3d(f, std::polar(1.0, std::arg(z) / n_));
  field_.weight[f] = std::min(1.0, kappa + a * (1 - kappa));
}

std::vector<int> CombStrokeState::changed() const {
  std::vector<int> out;
  out.reserve(felt_.size());
  for (const auto& [f, x] : felt_)
    if (std::abs(x.sum) > 0) out.push_back(f);
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<int> apply_comb_stroke(const TriangleMesh& mesh, const TangentFrames& frames, const TriangleTree& tree,
                                   int n, const CombStroke& stroke, CombField& field) {
  CombStrokeState state(mesh, n, stroke, field);  // a copy: `field` stays as it was if a sample is refused
  state.add(frames, tree, stroke.points, stroke.directions);
  field = state.field();
  return state.changed();
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
