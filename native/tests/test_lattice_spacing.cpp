// The conformal scale of a cross field (remesh/lattice_spacing.hpp) against closed-form solutions:
// - on a flat square, the field of angle theta = k x turns without a singularity; a grid of spacing h e^u
//   follows it exactly when grad u = -J grad theta = (0, -k), so u = -k y + c. The 1-form is then exact
//   (omega = k dx on every edge), each triangle's fit exact and the linear u lies in the finite-element
//   space, so the solve reproduces it to rounding; u is then rounded to steps of 2^-20, so two vertices'
//   values of u + k y differ by at most 2^-20 (about 1e-6, against a range of 1 for u);
// - the face-count normalisation (sum area e^-2u = sum area) to 1e-12 relative, and the clamp;
// - on a cylinder, a helical field (constant angle to the axis) is parallel for the surface's connection:
//   omega = 0 and u = 0, though the field's directions turn in space (a scale read from extrinsic angles,
//   without the transport, would not be zero);
// - a field with one singularity (a quarter turn round a point): one singular triangle, u finite and bounded;
// - the per-vertex refinement: every edge ends below the mean of its ends' limits.
#include <cmath>
#include <vector>

#include "check.hpp"
#include "nfield/errors.hpp"
#include "nfield/mesh.hpp"
#include "nfield/remesh/lattice_spacing.hpp"
#include "nfield/remesh/remesh_surface.hpp"

using namespace nfield;
using namespace nfield::remesh;
using namespace nfield::test;

namespace {

constexpr int kN = 20;          // cells per side
constexpr double kSide = 10.0;  // the square [0, 10]^2

RemeshSurface square() {
  Positions P((kN + 1) * (kN + 1), 3);
  for (int j = 0; j <= kN; ++j)
    for (int i = 0; i <= kN; ++i) P.row(j * (kN + 1) + i) << kSide * i / kN, kSide * j / kN, 0;
  Triangles T(2 * kN * kN, 3);
  int t = 0;
  for (int j = 0; j < kN; ++j)
    for (int i = 0; i < kN; ++i) {
      const int a = j * (kN + 1) + i;
      T.row(t++) << a, a + 1, a + kN + 2;
      T.row(t++) << a, a + kN + 2, a + kN + 1;
    }
  return make_remesh_surface(TriangleMesh(P, T));
}

/// Radius-1 cylinder about the z axis, `around` x `up` cells, height 4.
RemeshSurface cylinder(int around, int up) {
  Positions P(around * (up + 1), 3);
  for (int j = 0; j <= up; ++j)
    for (int i = 0; i < around; ++i) {
      const double a = 2 * M_PI * i / around;
      P.row(j * around + i) << std::cos(a), std::sin(a), 4.0 * j / up;
    }
  Triangles T(2 * around * up, 3);
  int t = 0;
  for (int j = 0; j < up; ++j)
    for (int i = 0; i < around; ++i) {
      const int a = j * around + i, b = j * around + (i + 1) % around;
      T.row(t++) << a, b, b + around;
      T.row(t++) << a, b + around, a + around;
    }
  return make_remesh_surface(TriangleMesh(P, T));
}

/// The cross field of angle theta = k x on the flat surface s.
std::vector<Vec3> turning_field(const RemeshSurface& s, double k) {
  std::vector<Vec3> q(s.num_vertices());
  for (int v = 0; v < s.num_vertices(); ++v) q[v] = Vec3(std::cos(k * s.positions[v].x()), std::sin(k * s.positions[v].x()), 0);
  return q;
}

double weighted_exp_ratio(const RemeshSurface& s, const std::vector<double>& u) {
  double a = 0, w = 0;
  for (int v = 0; v < s.num_vertices(); ++v) {
    a += s.vertex_areas[v];
    w += s.vertex_areas[v] * std::exp(-2 * u[v]);
  }
  return w / a;
}

}  // namespace

int main() {
  run("theta = k x on a flat square gives u = -k y", [] {
    const RemeshSurface s = square();
    const double k = 0.1;  // theta turns by 1 radian across the square; |u| range 1 < log 4
    const std::vector<Vec3> q = turning_field(s, k);
    LatticeSpacingOptions o;
    o.max_ratio = 4;
    LatticeSpacingReport r;
    const std::vector<double> u = conformal_log_scale(s, q, 0.5, o, &r);
    CHECK_EQ(r.singular_triangles, 0);
    // u + k y is the same constant everywhere.
    const double c = u[0] + k * s.positions[0].y();
    double worst = 0;
    for (int v = 0; v < s.num_vertices(); ++v) worst = std::max(worst, std::abs(u[v] + k * s.positions[v].y() - c));
    CHECK_LE(worst, std::ldexp(1.0, -20));
    // The mean of e^-2u is 1 up to the rounding of u (|d e^-2u| <= 2 * 2^-21 e^-2u).
    CHECK_LE(std::abs(weighted_exp_ratio(s, u) - 1), 2e-6);
    CHECK_LE(r.clamped_area, 0.0);
    // The spacing ratio across the square: e^(k * side), up to the rounding.
    CHECK_LE(std::abs(std::log(r.max_ratio / r.min_ratio) - k * kSide), std::ldexp(1.0, -20));
  });

  run("the clamp bounds the spacing ratio", [] {
    const RemeshSurface s = square();
    const double k = 0.1;
    const std::vector<Vec3> q = turning_field(s, k);
    LatticeSpacingOptions o;
    o.max_ratio = 1.2;
    LatticeSpacingReport r;
    const std::vector<double> u = conformal_log_scale(s, q, 0.5, o, &r);
    for (double x : u) CHECK_LE(std::abs(x), std::log(1.2) + 1e-12);
    CHECK(r.clamped_area > 0.1);
    CHECK_LE(r.max_ratio, 1.2 + 1e-9);
    CHECK_LE(1 / 1.2 - 1e-9, r.min_ratio);
    // Off (ratio 1): zero everywhere.
    o.max_ratio = 1;
    for (double x : conformal_log_scale(s, q, 0.5, o)) CHECK_LE(std::abs(x), 0.0);
  });

  run("a helical field on a cylinder is parallel: u = 0", [] {
    const RemeshSurface s = cylinder(48, 16);
    const double alpha = 0.5;  // angle to the axis (radians)
    std::vector<Vec3> q(s.num_vertices());
    const Vec3 z = Vec3::UnitZ();
    for (int v = 0; v < s.num_vertices(); ++v)
      q[v] = std::cos(alpha) * z + std::sin(alpha) * s.vertex_normals[v].cross(z).normalized();
    const std::vector<double> omega = field_rotation_form(s, q);
    double worst = 0;
    for (double w : omega) worst = std::max(worst, std::abs(w));
    CHECK_LE(worst, 1e-12);
    LatticeSpacingOptions o;
    o.max_ratio = 4;
    for (double x : conformal_log_scale(s, q, 0.2, o)) CHECK_LE(std::abs(x), 0.0);  // 1e-9 before the rounding
  });

  run("one singularity: found, u finite and bounded", [] {
    const RemeshSurface s = square();
    const Vec3 c(5.1, 4.9, 0);
    std::vector<Vec3> q(s.num_vertices());
    for (int v = 0; v < s.num_vertices(); ++v) {
      const Vec3 d = s.positions[v] - c;
      const double theta = 0.25 * std::atan2(d.y(), d.x());  // index +1/4
      q[v] = Vec3(std::cos(theta), std::sin(theta), 0);
    }
    LatticeSpacingOptions o;
    LatticeSpacingReport r;
    const std::vector<double> u = conformal_log_scale(s, q, 0.5, o, &r);
    CHECK_EQ(r.singular_triangles, 1);
    for (double x : u) {
      CHECK(std::isfinite(x));
      CHECK_LE(std::abs(x), std::log(o.max_ratio) + 1e-12);
    }
  });

  run("refinement to a limit per vertex", [] {
    RemeshSurface s = square();
    std::vector<double> limit(s.num_vertices());
    for (int v = 0; v < s.num_vertices(); ++v) limit[v] = s.positions[v].x() < 5 ? 0.2 : 1.0;
    const int before = s.num_vertices();
    refine_long_edges(s, limit);
    CHECK(s.num_vertices() > before);
    CHECK_EQ(static_cast<long long>(limit.size()), s.num_vertices());
    for (const auto& e : s.edges)
      CHECK_LE((s.positions[e[0]] - s.positions[e[1]]).norm(), 0.5 * (limit[e[0]] + limit[e[1]]) + 1e-12);
    std::vector<double> wrong(3, 1.0);
    CHECK_THROWS(ParameterError, "one limit per vertex", refine_long_edges(s, wrong));
  });
  return finish();
}
