// The local quad lattices of the 4-PoSy position field (Jakob et al. 2015, "Instant Field-Aligned Meshes",
// section 4), as small inline functions.
//
// Every vertex i carries a point v_i with unit normal n_i, a cross direction q_i (unit, tangent; the cross
// is {q_i, t_i, -q_i, -t_i} with t_i = n_i x q_i) and a position p_i in its tangent plane. Together they
// define the lattice L_i = { p_i + s (a q_i + b t_i) : a, b integers } of spacing s (the target edge
// length, mesh units). The position field is optimised so that neighbouring lattices agree; the output
// vertices are the lattice points.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace nfield::remesh {

using Vec3 = Eigen::Vector3d;

/// Among the four directions of the cross at j ({q_j, n_j x q_j, -q_j, -n_j x q_j}), the one most
/// parallel to q_i (extrinsic comparison: plain dot products in R^3). Returns it and writes the number of
/// quarter turns (0..3) from q_j to it.
inline Vec3 compatible_direction(const Vec3& q_i, const Vec3& q_j, const Vec3& n_j, int* quarter_turns = nullptr) {
  const Vec3 t_j = n_j.cross(q_j);
  const double a = q_i.dot(q_j), b = q_i.dot(t_j);
  int k;
  Vec3 r;
  if (std::abs(a) >= std::abs(b)) {
    k = a >= 0 ? 0 : 2;
    r = a >= 0 ? q_j : Vec3(-q_j);
  } else {
    k = b >= 0 ? 1 : 3;
    r = b >= 0 ? t_j : Vec3(-t_j);
  }
  if (quarter_turns) *quarter_turns = k;
  return r;
}

/// A point on both tangent planes (n_i . (x - v_i) = 0, n_j . (x - v_j) = 0) nearest to the midpoint of
/// v_i and v_j; the midpoint itself when the planes are (nearly) parallel.
inline Vec3 middle_point(const Vec3& v_i, const Vec3& n_i, const Vec3& v_j, const Vec3& n_j) {
  const Vec3 m = 0.5 * (v_i + v_j);
  const double a = n_i.dot(n_i), b = n_i.dot(n_j), c = n_j.dot(n_j);
  const double det = a * c - b * b;
  if (det < 1e-4) return m;  // planes within ~0.6 degrees: any point between works
  // x = m + lambda n_i + mu n_j, with n_i.(x - v_i) = 0 and n_j.(x - v_j) = 0.
  const double r1 = n_i.dot(v_i - m), r2 = n_j.dot(v_j - m);
  const double lambda = (c * r1 - b * r2) / det, mu = (a * r2 - b * r1) / det;
  return m + lambda * n_i + mu * n_j;
}

/// The lattice point of (p, q, t = n x q, spacing s) nearest to x.
inline Vec3 nearest_lattice_point(const Vec3& p, const Vec3& q, const Vec3& n, const Vec3& x, double s) {
  const Vec3 t = n.cross(q);
  const Vec3 d = x - p;
  return p + s * (std::round(q.dot(d) / s) * q + std::round(t.dot(d) / s) * t);
}

/// The pair of lattice points, one of L_i and one of L_j, nearest to each other near the common point
/// of the two tangent planes (the four lattice points around that point are tried on each side).
/// q_j must already be the direction of j's cross compatible with q_i. index_i / index_j are the
/// integer lattice coordinates (a, b) of the two points relative to p_i and p_j.
struct LatticePair {
  Vec3 point_i, point_j;
  Eigen::Vector2i index_i, index_j;
};

inline LatticePair closest_lattice_pair(const Vec3& v_i, const Vec3& n_i, const Vec3& q_i, const Vec3& p_i,
                                        const Vec3& v_j, const Vec3& n_j, const Vec3& q_j, const Vec3& p_j,
                                        double s) {
  const Vec3 t_i = n_i.cross(q_i), t_j = n_j.cross(q_j);
  const Vec3 x = middle_point(v_i, n_i, v_j, n_j);
  const Vec3 di = x - p_i, dj = x - p_j;
  const Eigen::Vector2i base_i(static_cast<int>(std::floor(q_i.dot(di) / s)), static_cast<int>(std::floor(t_i.dot(di) / s)));
  const Eigen::Vector2i base_j(static_cast<int>(std::floor(q_j.dot(dj) / s)), static_cast<int>(std::floor(t_j.dot(dj) / s)));
  LatticePair best;
  double best_d2 = HUGE_VAL;
  for (int ci = 0; ci < 4; ++ci) {
    const Eigen::Vector2i ii = base_i + Eigen::Vector2i(ci & 1, ci >> 1);
    const Vec3 a = p_i + s * (ii[0] * q_i + ii[1] * t_i);
    for (int cj = 0; cj < 4; ++cj) {
      const Eigen::Vector2i jj = base_j + Eigen::Vector2i(cj & 1, cj >> 1);
      const Vec3 b = p_j + s * (jj[0] * q_j + jj[1] * t_j);
      const double d2 = (a - b).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best = {a, b, ii, jj};
      }
    }
  }
  return best;
}

}  // namespace nfield::remesh
