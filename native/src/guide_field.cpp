#include "nfield/guide_field.hpp"

#include <algorithm>
#include <cmath>

namespace nfield {

Complex unit_representation(const TangentFrames& frames, int f, const Eigen::Vector3d& v, int n) {
  const Complex t = frames.to_tangent(f, v);
  const double len = std::abs(t);
  if (!(len > 1e-9 * v.norm())) return 0.0;
  Complex base = t / len, out = 1.0;
  for (int k = n; k > 0; k >>= 1) {
    if (k & 1) out *= base;
    if (k > 1) base *= base;
  }
  return out;
}

GuideAccumulator::GuideAccumulator(int num_faces)
    : sum_(Eigen::VectorXcd::Zero(num_faces)),
      total_(Eigen::VectorXd::Zero(num_faces)),
      largest_(Eigen::VectorXd::Zero(num_faces)) {}

void GuideAccumulator::add(int face, Complex d, double w) {
  if (!(w > 0) || !(std::norm(d) > 0)) return;  // (not std::abs: a hypot per face and sample of a curve band)
  sum_[face] += w * d;
  total_[face] += w;
  largest_[face] = std::max(largest_[face], w);
}

GuideLayer GuideAccumulator::finish() const {
  GuideLayer out{Eigen::VectorXcd::Zero(sum_.size()), Eigen::VectorXd::Zero(sum_.size())};
  for (Eigen::Index f = 0; f < sum_.size(); ++f) {
    if (!(total_[f] > 0)) continue;
    out.weight[f] = largest_[f];
    out.value[f] = largest_[f] * sum_[f] / total_[f];
  }
  return out;
}

MergedDirections merge_hard_directions(std::vector<HardDirection> proposals, int n, double tolerance) {
  std::stable_sort(proposals.begin(), proposals.end(),
                   [](const HardDirection& a, const HardDirection& b) { return a.face < b.face; });
  MergedDirections out;
  const double limit = n * tolerance;  // representation angle
  for (std::size_t i = 0; i < proposals.size();) {
    std::size_t j = i;
    while (j < proposals.size() && proposals[j].face == proposals[i].face) ++j;
    double worst = 0;
    std::size_t wi = i, wj = i;
    Complex sum = 0;
    for (std::size_t a = i; a < j; ++a) {
      sum += proposals[a].direction;
      for (std::size_t b = a + 1; b < j; ++b) {
        const double angle = std::abs(std::arg(proposals[a].direction * std::conj(proposals[b].direction)));
        if (angle > worst) worst = angle, wi = a, wj = b;
      }
    }
    if (worst <= limit && std::abs(sum) > 0) {
      out.constraints.emplace_back(proposals[i].face, sum / std::abs(sum));
    } else {
      out.dropped.push_back({proposals[i].face, proposals[wi].source, proposals[wj].source, worst / n * 180.0 / M_PI});
    }
    i = j;
  }
  return out;
}

}  // namespace nfield
