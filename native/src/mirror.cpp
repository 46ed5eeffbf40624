#include "nfield/mirror.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

#include "nfield/errors.hpp"

namespace nfield {
namespace {

/// Uniform grid over points for nearest-neighbour queries within a radius no larger than the cell size.
class PointGrid {
 public:
  PointGrid(const std::vector<Eigen::Vector3d>& points, const std::vector<int>& ids, double cell)
      : points_(points), cell_(cell) {
    for (int id : ids) cells_[key(cell_of(points_[id]))].push_back(id);
  }
  /// Nearest id within `radius` of p (ties: smaller id), or -1.
  int nearest(const Eigen::Vector3d& p, double radius, double& distance) const {
    const Eigen::Array3i c = cell_of(p);
    int best = -1;
    double best_d = std::numeric_limits<double>::infinity();
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = cells_.find(key(c + Eigen::Array3i(dx, dy, dz)));
          if (it == cells_.end()) continue;
          for (int id : it->second) {
            const double d = (points_[id] - p).norm();
            if (d <= radius && (d < best_d || (d == best_d && id < best))) best = id, best_d = d;
          }
        }
    distance = best_d;
    return best;
  }

 private:
  Eigen::Array3i cell_of(const Eigen::Vector3d& p) const {
    // Coordinates are bounded (TriangleMesh limits the extent), so the cell indices fit an int when the
    // cell is at least 1e-6 of the extent; the caller guarantees that.
    return (p.array() / cell_).floor().cast<int>();
  }
  static std::uint64_t key(const Eigen::Array3i& c) {
    const auto u = [](int v) { return static_cast<std::uint64_t>(static_cast<std::uint32_t>(v)) & 0x1fffffULL; };
    return (u(c[0]) << 42) | (u(c[1]) << 21) | u(c[2]);
  }
  const std::vector<Eigen::Vector3d>& points_;
  double cell_;
  std::unordered_map<std::uint64_t, std::vector<int>> cells_;
};

std::uint64_t triple_key(int a, int b, int c) {
  int v[3] = {a, b, c};
  std::sort(v, v + 3);
  return (static_cast<std::uint64_t>(v[0]) << 42) ^ (static_cast<std::uint64_t>(v[1]) << 21) ^
         static_cast<std::uint64_t>(v[2]) ^ (static_cast<std::uint64_t>(v[1]) * 0x9e3779b97f4a7c15ULL);
}

}  // namespace

int parse_mirror_axis(const std::string& name) {
  if (name == "x" || name == "X") return 0;
  if (name == "y" || name == "Y") return 1;
  if (name == "z" || name == "Z") return 2;
  throw ParameterError("unknown mirror axis '" + name + "' (expected 'x', 'y' or 'z')");
}

MirrorMap::MirrorMap(const TriangleMesh& mesh, const TangentFrames& frames, int axis, double offset, double tolerance)
    : axis_(axis), offset_(offset) {
  if (axis < 0 || axis > 2) throw ParameterError("mirror axis must be 0, 1 or 2 (x, y, z)");
  if (!(tolerance >= 0) || !std::isfinite(tolerance)) throw ParameterError("mirror tolerance must be a number >= 0");
  if (!std::isfinite(offset)) throw ParameterError("mirror plane offset must be finite");
  if (tolerance > 0.1 * mesh.bounding_box_diagonal())
    throw ParameterError("mirror tolerance must be at most 0.1 of the bounding-box diagonal (beyond, a vertex's "
                         "mirror image meets many candidates)");
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  const auto& P = mesh.positions();
  const auto& F = mesh.faces();
  partner_.assign(nf, -1);
  vertex_partner_.assign(nv, -1);
  phase_.assign(nf, Complex(1, 0));
  conjugate_.assign(nf, 0);

  // 1. Vertices of active faces, matched to the nearest vertex of their mirror image.
  std::vector<char> used(nv, 0);
  for (int f = 0; f < nf; ++f)
    if (mesh.face_active(f))
      for (int c = 0; c < 3; ++c) used[F(f, c)] = 1;
  std::vector<Eigen::Vector3d> points(nv);
  std::vector<int> ids;
  for (int v = 0; v < nv; ++v) {
    points[v] = P.row(v).transpose();
    if (used[v]) ids.push_back(v);
  }
  const double diag = mesh.bounding_box_diagonal();
  // Cells no smaller than 1e-6 of the extent (integer cell indices) and no smaller than the tolerance
  // (a 3x3x3 block of cells then covers every candidate).
  const double cell = std::max({tolerance, 1e-6 * diag, 1e-300});
  PointGrid grid(points, ids, cell);
  auto mirrored = [&](const Eigen::Vector3d& p) {
    Eigen::Vector3d q = p;
    q[axis] = 2 * offset - p[axis];
    return q;
  };
  for (int v : ids) {
    double d = 0;
    const int w = grid.nearest(mirrored(points[v]), tolerance, d);
    if (w < 0) continue;
    vertex_partner_[v] = w;
    max_mismatch_ = std::max(max_mismatch_, d);
  }

  // 2. Faces: the face whose vertex set is the image of f's.
  std::unordered_multimap<std::uint64_t, int> by_vertices;
  for (int f = 0; f < nf; ++f)
    if (mesh.face_active(f)) by_vertices.emplace(triple_key(F(f, 0), F(f, 1), F(f, 2)), f);
  for (int f = 0; f < nf; ++f) {
    if (!mesh.face_active(f)) continue;
    int img[3];
    bool ok = true;
    for (int c = 0; c < 3; ++c) ok &= (img[c] = vertex_partner_[F(f, c)]) >= 0;
    if (ok) {
      int wanted[3] = {img[0], img[1], img[2]};
      std::sort(wanted, wanted + 3);
      const auto range = by_vertices.equal_range(triple_key(img[0], img[1], img[2]));
      for (auto it = range.first; it != range.second; ++it) {
        int have[3] = {F(it->second, 0), F(it->second, 1), F(it->second, 2)};
        std::sort(have, have + 3);
        if (std::equal(have, have + 3, wanted)) {
          partner_[f] = it->second;
          break;
        }
      }
    }
  }
  // 3. Keep only mutual pairs (g = partner(f) and f = partner(g)) and compute the maps.
  for (int f = 0; f < nf; ++f) {
    if (!mesh.face_active(f)) continue;
    const int g = partner_[f];
    if (g < 0 || partner_[g] != f) {
      partner_[f] = -1;
      continue;
    }
    ++num_matched_;
    if (g < f) continue;  // computed with f's partner below
    auto reflect = [&](Eigen::Vector3d v) {
      v[axis] = -v[axis];
      return v;
    };
    const Eigen::Vector3d rx = reflect(frames.x_axis(f)), ry = reflect(frames.y_axis(f));
    const Complex p = frames.to_tangent(g, rx), q = frames.to_tangent(g, ry);
    const Complex pu = std::abs(p) > 0 ? p / std::abs(p) : Complex(1, 0);
    // R y_f = s i p: s = sign Im(conj(i p) q) ... i.e. the sign of Re(conj(i p) q).
    const bool conj = (std::conj(Complex(0, 1) * p) * q).real() < 0;
    phase_[f] = pu;
    conjugate_[f] = conj;
    // T_g = T_f^-1: z_f = p conj(z_g) (conjugate case) or conj(p) z_g.
    if (g != f) {
      phase_[g] = conj ? pu : std::conj(pu);
      conjugate_[g] = conj;
    }
  }
  for (int f = 0; f < nf; ++f)
    if (mesh.face_active(f) && partner_[f] < 0) unmatched_.push_back(f);
}

Complex MirrorMap::map(int f, Complex z, int n) const {
  const Complex pn = std::pow(phase_[f], n);
  return pn * (conjugate_[f] ? std::conj(z) : z);
}

ConstraintRow MirrorMap::symmetrized(const ConstraintRow& row, int n) const {
  ConstraintRow out;
  out.rhs = row.rhs;
  for (const auto& [f, c] : row.terms) {
    const int g = partner_[f];
    if (g < 0) {
      out.terms.emplace_back(f, c);
      continue;
    }
    out.terms.emplace_back(f, 0.5 * c);
    out.terms.emplace_back(g, 0.5 * map(f, c, n));
  }
  // Merge repeated faces (a face its own partner, or a row touching both faces of a pair).
  std::sort(out.terms.begin(), out.terms.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  ConstraintRow merged;
  merged.rhs = out.rhs;
  for (const auto& t : out.terms) {
    if (!merged.terms.empty() && merged.terms.back().first == t.first)
      merged.terms.back().second += t.second;
    else
      merged.terms.push_back(t);
  }
  return merged;
}

Eigen::VectorXcd MirrorMap::project(const Eigen::VectorXcd& z, int n) const {
  Eigen::VectorXcd out = z;
  for (int f = 0; f < static_cast<int>(partner_.size()); ++f) {
    const int g = partner_[f];
    if (g >= 0) out[g] = 0.5 * (z[g] + map(f, z[f], n));
  }
  return out;
}

double MirrorMap::asymmetry(const Eigen::VectorXcd& z, int n) const {
  double worst = 0, scale = 0;
  for (int f = 0; f < static_cast<int>(partner_.size()); ++f) {
    scale = std::max(scale, std::abs(z[f]));
    const int g = partner_[f];
    if (g >= 0) worst = std::max(worst, std::abs(z[g] - map(f, z[f], n)));
  }
  return scale > 0 ? worst / scale : 0.0;
}

}  // namespace nfield
