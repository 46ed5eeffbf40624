#include "nfield/singularities.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "nfield/errors.hpp"

namespace nfield {

double ring_holonomy(const FieldOperators& ops, int vertex) {
  const auto& faces = ops.mesh().vertex_ring_faces(vertex);
  const auto& edges = ops.mesh().vertex_ring_dual_edges(vertex);
  Complex product(1.0, 0.0);
  for (size_t j = 0; j < faces.size(); ++j) product *= ops.transport(edges[j], faces[j]);
  return std::arg(product);
}

/// Sum of the transport angles n * (a1 - a0) around the ring, unwrapped: equals -n * (sum of corner
/// angles) + 2 pi n, i.e. n K_v exactly; we use the mesh's angle defect directly.
static double ring_holonomy_angle(const FieldOperators& ops, int vertex) {
  return ops.n() * ops.mesh().angle_defect(vertex);
}

namespace {

/// arg(z) in (-pi, pi] to within 2e-6 rad (a least-squares odd polynomial of degree 11 for atan on [0, 1], max error
/// 1.8e-6, then the octant), and exactly (atan2) within 1e-3 of the cut at +-pi, so that the result is on the same
/// side of the cut as atan2's. An index only needs the sum of a ring's turnings to within pi of the exact one (it is
/// rounded to a multiple of 2 pi): 2e-6 per step leaves that margin for rings of any size, so the indices are those
/// of atan2, at a fraction of its cost.
double turning_angle(Complex z) {
  const double x = z.real(), y = z.imag(), ax = std::abs(x), ay = std::abs(y);
  const double big = std::max(ax, ay);
  if (!(big > 0) || !std::isfinite(big)) return std::atan2(y, x);
  const double a = std::min(ax, ay) / big, a2 = a * a;
  double t = a * (0.9999798316 +
                  a2 * (-0.3326554195 + a2 * (0.1936698883 + a2 * (-0.1166499788 + a2 * (0.05282219489 -
                                                                                    0.01176997409 * a2)))));
  if (ay > ax) t = M_PI / 2 - t;
  if (x < 0) t = M_PI - t;
  if (t > M_PI - 1e-3) return std::atan2(y, x);
  return std::signbit(y) ? -t : t;
}

/// The turning psi_e in (-pi, pi] of the field across dual edge e, face0 -> face1: the signed angle from the
/// carried value r_e z_0 to z_1. Crossed the other way (face1 -> face0) it is -psi_e (odd in Im, signed zeros
/// included), so every ring that crosses e uses this one value.
double edge_turning(const FieldOperators& ops, const ComplexVector& field, int e) {
  const DualEdge& d = ops.mesh().dual_edges()[e];
  return turning_angle(field[d.face1] * std::conj(ops.transport(e) * field[d.face0]));
}

bool usable(Complex z) { return z != 0.0 && std::isfinite(z.real()) && std::isfinite(z.imag()); }

/// (sum of the turnings around the ring + n K_v) / (2 pi), rounded: the index numerator (see the header).
template <class Turning>
int ring_numerator(const FieldOperators& ops, int v, Turning turning) {
  const TriangleMesh& mesh = ops.mesh();
  const auto& faces = mesh.vertex_ring_faces(v);
  const auto& edges = mesh.vertex_ring_dual_edges(v);
  double sum = 0.0;
  for (size_t j = 0; j < faces.size(); ++j) {
    const int e = edges[j];
    const double psi = turning(e);
    sum += mesh.dual_edges()[e].face0 == faces[j] ? psi : -psi;
  }
  return static_cast<int>(std::lround((sum + ring_holonomy_angle(ops, v)) / (2.0 * M_PI)));
}

bool ring_usable(const TriangleMesh& mesh, const ComplexVector& field, int v) {
  const auto& faces = mesh.vertex_ring_faces(v);
  if (faces.empty()) return false;
  for (int f : faces)
    if (!usable(field[f])) return false;  // a zero or non-finite value on the ring: no index
  return true;
}

}  // namespace

std::vector<VertexIndex> singularity_indices(const FieldOperators& ops, const ComplexVector& field) {
  const TriangleMesh& mesh = ops.mesh();
  if (field.size() != mesh.num_faces())
    throw InputError("field must have one value per face (" + std::to_string(mesh.num_faces()) + ")");
  // Each interior dual edge lies on the rings of both ends of its primal edge: its turning is computed once.
  const auto& dual = mesh.dual_edges();
  std::vector<double> turning(dual.size(), 0.0);
  for (size_t e = 0; e < dual.size(); ++e)
    if (usable(field[dual[e].face0]) && usable(field[dual[e].face1]))
      turning[e] = edge_turning(ops, field, static_cast<int>(e));
  std::vector<VertexIndex> out;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    if (!ring_usable(mesh, field, v)) continue;
    const int numerator = ring_numerator(ops, v, [&](int e) { return turning[e]; });
    if (numerator != 0) out.push_back({v, numerator});
  }
  return out;
}

std::vector<VertexIndex> singularity_indices_near(const FieldOperators& ops, const ComplexVector& field,
                                                  const std::vector<int>& faces) {
  const TriangleMesh& mesh = ops.mesh();
  if (field.size() != mesh.num_faces())
    throw InputError("field must have one value per face (" + std::to_string(mesh.num_faces()) + ")");
  std::vector<int> vertices;
  vertices.reserve(3 * faces.size());
  for (int f : faces) {
    if (f < 0 || f >= mesh.num_faces()) throw InputError("face " + std::to_string(f) + " is out of range");
    for (int c = 0; c < 3; ++c) vertices.push_back(mesh.faces()(f, c));
  }
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  std::vector<VertexIndex> out;
  for (int v : vertices) {
    int numerator = 0;
    if (ring_index_numerator(ops, field, v, numerator) && numerator != 0) out.push_back({v, numerator});
  }
  return out;
}

bool ring_index_numerator(const FieldOperators& ops, const ComplexVector& field, int v, int& numerator) {
  if (!ring_usable(ops.mesh(), field, v)) return false;
  numerator = ring_numerator(ops, v, [&](int e) { return edge_turning(ops, field, e); });
  return true;
}

std::pair<int, int> singularity_numerator_range(const FieldOperators& ops, int vertex) {
  const TriangleMesh& mesh = ops.mesh();
  if (vertex < 0 || vertex >= mesh.num_vertices())
    throw ConstraintError("singularity vertex " + std::to_string(vertex) + " is out of range (mesh has " +
                          std::to_string(mesh.num_vertices()) + " vertices)");
  const int k = static_cast<int>(mesh.vertex_ring_faces(vertex).size());
  if (k == 0)
    throw ConstraintError("vertex " + std::to_string(vertex) +
                          " cannot carry a singularity: it is on a boundary, non-manifold, unused, or next to "
                          "a degenerate face (only interior vertices have an index)");
  // Same admissibility test as singularity_constraint_rows: |delta| < pi (1 - 1e-9).
  const double nK = ops.n() * mesh.angle_defect(vertex), limit = k * M_PI * (1.0 - 1e-9);
  int lo = static_cast<int>(std::ceil((nK - limit) / (2 * M_PI)));
  int hi = static_cast<int>(std::floor((nK + limit) / (2 * M_PI)));
  while (std::abs(2 * M_PI * lo - nK) >= limit) ++lo;
  while (std::abs(2 * M_PI * hi - nK) >= limit) --hi;
  return {lo, hi};
}

std::vector<ConstraintRow> singularity_constraint_rows(const FieldOperators& ops, int vertex, int numerator) {
  const TriangleMesh& mesh = ops.mesh();
  const int n = ops.n();
  if (vertex < 0 || vertex >= mesh.num_vertices())
    throw ConstraintError("singularity vertex " + std::to_string(vertex) + " is out of range (mesh has " +
                          std::to_string(mesh.num_vertices()) + " vertices)");
  const auto& faces = mesh.vertex_ring_faces(vertex);
  if (faces.empty())
    throw ConstraintError("vertex " + std::to_string(vertex) +
                          " cannot carry a singularity: it is on a boundary, non-manifold, unused, or next to "
                          "a degenerate face (only interior vertices have an index)");
  const int k = static_cast<int>(faces.size());
  const double K = mesh.angle_defect(vertex);
  const double delta = (2.0 * M_PI * numerator - n * K) / k;
  if (std::abs(delta) >= M_PI * (1.0 - 1e-9)) {
    std::ostringstream msg;
    const double center = K / (2.0 * M_PI), half = k / (2.0 * n);
    msg.precision(4);
    msg << "vertex " << vertex << " cannot carry index " << numerator << "/" << n << ": its ring has " << k
        << " faces and angle defect " << K << " rad, so the index must lie strictly between "
        << center - half << " and " << center + half << " (|index - K/2pi| < k/(2n))";
    throw ConstraintError(msg.str());
  }
  const auto& edges = mesh.vertex_ring_dual_edges(vertex);
  const Complex twist = std::polar(1.0, delta);
  std::vector<ConstraintRow> rows;
  rows.reserve(2 * (k - 1));
  for (int j = 0; j + 1 < k; ++j) {
    const Complex rho = ops.transport(edges[j], faces[j]) * twist;
    auto [re, im] = complex_equation_rows({{faces[j + 1], Complex(1, 0)}, {faces[j], -rho}}, Complex(0, 0));
    rows.push_back(std::move(re));
    rows.push_back(std::move(im));
  }
  return rows;
}

}  // namespace nfield
