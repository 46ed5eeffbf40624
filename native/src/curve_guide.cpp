#include "nfield/curve_guide.hpp"

#include <cmath>
#include <cstdint>

#include "nfield/errors.hpp"
#include "nfield/face_regions.hpp"

namespace nfield {

ProjectedCurve project_curve(const TriangleTree& tree, const std::vector<Eigen::Vector3d>& points, double spacing,
                             double tolerance) {
  if (points.size() < 2) throw InputError("a curve needs at least 2 points, got " + std::to_string(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!points[i].allFinite()) throw InputError("curve point " + std::to_string(i) + " is not finite");
  if (!(spacing > 0) || !std::isfinite(spacing)) throw ParameterError("curve sample spacing must be a positive number");
  if (!(tolerance >= 0) || !std::isfinite(tolerance)) throw ParameterError("curve tolerance must be a number >= 0");
  ProjectedCurve out;
  for (std::size_t i = 0; i + 1 < points.size(); ++i) {
    const Eigen::Vector3d seg = points[i + 1] - points[i];
    const double len = seg.norm();
    if (!(len > 0)) continue;
    const double pieces = std::ceil(len / spacing);
    if (pieces > 1e7) throw ParameterError("curve segment " + std::to_string(i) + " is more than 1e7 sample spacings long");
    const int m = std::max(1, static_cast<int>(pieces));
    const Eigen::Vector3d tangent = seg / len;
    for (int j = 0; j < m; ++j) {
      const Eigen::Vector3d p = points[i] + ((j + 0.5) / m) * seg;
      const SurfacePoint q = tree.closest(p);
      ++out.num_samples;
      if (q.face < 0) {
        ++out.num_missed;
        continue;
      }
      out.max_distance = std::max(out.max_distance, q.distance);
      if (q.distance > tolerance) {
        ++out.num_missed;
        continue;
      }
      out.faces.push_back(q.face);
      out.points.push_back(q.point);
      out.tangents.push_back(tangent);
    }
  }
  return out;
}

void add_curve_band(const TriangleMesh& mesh, const TangentFrames& frames, int n, const ProjectedCurve& curve,
                    double width, double weight, GuideAccumulator& into) {
  if (!(width >= 0) || !std::isfinite(width)) throw ParameterError("curve width must be a number >= 0");
  if (!(weight >= 0) || !std::isfinite(weight)) throw ParameterError("curve weight must be a number >= 0");
  FaceWalker walker(mesh);
  // The samples of one polyline segment share its tangent, and neighbouring samples reach mostly the same
  // faces: a face keeps the representation of the last tangent it was given (keyed by the first sample of
  // that tangent's run) instead of computing it again for every sample.
  std::vector<std::size_t> cached_run(width > 0 ? mesh.num_faces() : 0, SIZE_MAX);
  std::vector<Complex> cached_rep(cached_run.size());
  std::size_t run = 0;
  for (std::size_t i = 0; i < curve.faces.size(); ++i) {
    const Eigen::Vector3d& t = curve.tangents[i];
    if (width == 0) {
      into.add(curve.faces[i], unit_representation(frames, curve.faces[i], t, n), weight);
      continue;
    }
    if (i > 0 && t != curve.tangents[i - 1]) run = i;
    walker.ball(curve.faces[i], curve.points[i], width, [&](int f, double d) {
      if (cached_run[f] != run) cached_run[f] = run, cached_rep[f] = unit_representation(frames, f, t, n);
      const double s = d / width, w = weight * (1 - s * s) * (1 - s * s);
      into.add(f, cached_rep[f], w);
    });
  }
}

std::vector<HardDirection> curve_hard_directions(const TangentFrames& frames, int n, const ProjectedCurve& curve,
                                                 int every, int source) {
  if (every < 1) throw ParameterError("'every' must be at least 1 (every k-th crossed face), got " + std::to_string(every));
  std::vector<HardDirection> out;
  int crossed = 0;
  for (std::size_t i = 0; i < curve.faces.size();) {
    const int f = curve.faces[i];
    Complex sum = 0;
    std::size_t j = i;
    for (; j < curve.faces.size() && curve.faces[j] == f; ++j) sum += unit_representation(frames, f, curve.tangents[j], n);
    if (crossed++ % every == 0 && std::abs(sum) > 1e-12) out.push_back({f, sum / std::abs(sum), source});
    i = j;
  }
  return out;
}

}  // namespace nfield
