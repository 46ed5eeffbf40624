// Shared by the libFuzzer harnesses: what counts as a finding besides crashes and sanitizer reports.
//
// The harnesses accept every nfield::Error (the library's documented way to refuse input). When an input
// *is* accepted, the result must satisfy what the headers promise (indices in range, finite geometry,
// dual edges between active faces ...): a violated promise is as much a bug as a crash, because the
// Python layer and the solvers index with these values without re-checking them. FUZZ_CHECK prints the
// broken promise and aborts, which libFuzzer records as a crash with the input that caused it.
#pragma once
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "nfield/mesh.hpp"
#include "nfield/mesh_io.hpp"
#include "nfield/operators.hpp"

#define FUZZ_CHECK(condition)                                                                 \
  do {                                                                                        \
    if (!(condition)) {                                                                       \
      std::fprintf(stderr, "nfield fuzz: broken invariant at %s:%d: %s\n", __FILE__, __LINE__, \
                   #condition);                                                               \
      std::abort();                                                                           \
    }                                                                                         \
  } while (0)

namespace nfield_fuzz {

/// What parse_mesh promises about a successful parse (mesh_io.hpp): at least one vertex and face, finite
/// coordinates, indices in [0, V), one polygon number per triangle, numbering 0..P-1 in input order.
inline void check_mesh_data(const nfield::MeshData& data) {
  const auto nv = data.positions.rows();
  const auto nt = data.triangles.rows();
  FUZZ_CHECK(nv > 0 && nt > 0 && data.num_polygons > 0);
  FUZZ_CHECK(data.positions.allFinite());
  FUZZ_CHECK(data.triangles.minCoeff() >= 0 && data.triangles.maxCoeff() < nv);
  FUZZ_CHECK(static_cast<Eigen::Index>(data.triangle_polygon.size()) == nt);
  FUZZ_CHECK(data.triangle_polygon.front() == 0 && data.triangle_polygon.back() == data.num_polygons - 1);
  for (std::size_t t = 1; t < data.triangle_polygon.size(); ++t) {
    const int step = data.triangle_polygon[t] - data.triangle_polygon[t - 1];
    FUZZ_CHECK(step == 0 || step == 1);
  }
}

/// True if face f of `faces` (oriented winding) contains the directed edge a -> b.
inline bool has_directed_edge(const nfield::Triangles& faces, int f, int a, int b) {
  for (int c = 0; c < 3; ++c)
    if (faces(f, c) == a && faces(f, (c + 1) % 3) == b) return true;
  return false;
}

/// What TriangleMesh promises (mesh.hpp): geometry of active faces is finite and non-degenerate, dual edges
/// join two active faces of one component through a consistently oriented shared edge, rings close.
inline void check_mesh_invariants(const nfield::TriangleMesh& mesh) {
  const int nf = mesh.num_faces();
  const int nv = mesh.num_vertices();
  const nfield::Triangles& faces = mesh.faces();
  const nfield::MeshReport& report = mesh.report();
  FUZZ_CHECK(mesh.num_active_faces() > 0 && mesh.num_active_faces() <= nf);
  FUZZ_CHECK(faces.minCoeff() >= 0 && faces.maxCoeff() < nv);
  FUZZ_CHECK(std::isfinite(mesh.total_area()) && mesh.total_area() > 0);
  FUZZ_CHECK(report.num_components >= 1);
  for (int f = 0; f < nf; ++f) {
    FUZZ_CHECK(mesh.face_dual_edges(f).size() <= 3);
    if (!mesh.face_active(f)) {
      FUZZ_CHECK(mesh.face_area(f) == 0 && mesh.face_dual_edges(f).empty());
      FUZZ_CHECK(mesh.face_component()[static_cast<std::size_t>(f)] == -1);
      continue;
    }
    FUZZ_CHECK(std::isfinite(mesh.face_area(f)) && mesh.face_area(f) > 0);
    FUZZ_CHECK(std::abs(mesh.face_normal(f).norm() - 1.0) < 1e-9);
    const int component = mesh.face_component()[static_cast<std::size_t>(f)];
    FUZZ_CHECK(component >= 0 && component < report.num_components);
    for (int c = 0; c < 3; ++c) FUZZ_CHECK(std::isfinite(mesh.corner_angle(f, c)));
  }
  for (const nfield::DualEdge& d : mesh.dual_edges()) {
    FUZZ_CHECK(d.face0 >= 0 && d.face0 < d.face1 && d.face1 < nf);
    FUZZ_CHECK(mesh.face_active(d.face0) && mesh.face_active(d.face1));
    FUZZ_CHECK(has_directed_edge(faces, d.face0, d.vertex0, d.vertex1));
    FUZZ_CHECK(has_directed_edge(faces, d.face1, d.vertex1, d.vertex0));
    FUZZ_CHECK(mesh.face_component()[static_cast<std::size_t>(d.face0)] ==
               mesh.face_component()[static_cast<std::size_t>(d.face1)]);
  }
  const auto num_dual = static_cast<int>(mesh.dual_edges().size());
  for (int v = 0; v < nv; ++v) {
    FUZZ_CHECK(std::isfinite(mesh.angle_defect(v)));
    const std::vector<int>& ring = mesh.vertex_ring_faces(v);
    const std::vector<int>& ring_dual = mesh.vertex_ring_dual_edges(v);
    FUZZ_CHECK(ring.size() == ring_dual.size());
    for (std::size_t j = 0; j < ring.size(); ++j) {
      const int e = ring_dual[j];
      FUZZ_CHECK(e >= 0 && e < num_dual);
      const nfield::DualEdge& d = mesh.dual_edges()[static_cast<std::size_t>(e)];
      const int a = ring[j], b = ring[(j + 1) % ring.size()];
      FUZZ_CHECK((d.face0 == a && d.face1 == b) || (d.face0 == b && d.face1 == a));
    }
  }
  for (int f : report.degenerate_faces) FUZZ_CHECK(f >= 0 && f < nf && !mesh.face_active(f));
  for (int f : report.duplicate_faces) FUZZ_CHECK(f >= 0 && f < nf && !mesh.face_active(f));
  for (int v : report.unused_vertices) FUZZ_CHECK(v >= 0 && v < nv);
}

/// What FieldOperators promises (operators.hpp): one unknown per active face, positive finite masses,
/// a finite energy matrix whose diagonal (sums of edge weights) is non-negative.
inline void check_operator_invariants(const nfield::FieldOperators& ops) {
  FUZZ_CHECK(ops.num_unknowns() == ops.mesh().num_active_faces());
  FUZZ_CHECK(ops.mass().size() == ops.num_unknowns());
  for (Eigen::Index u = 0; u < ops.mass().size(); ++u) FUZZ_CHECK(std::isfinite(ops.mass()[u]) && ops.mass()[u] > 0);
  const nfield::ComplexSparse& S = ops.harmonic_matrix();
  FUZZ_CHECK(S.rows() == ops.num_unknowns() && S.cols() == ops.num_unknowns());
  for (int k = 0; k < S.outerSize(); ++k)
    for (nfield::ComplexSparse::InnerIterator it(S, k); it; ++it) {
      FUZZ_CHECK(std::isfinite(it.value().real()) && std::isfinite(it.value().imag()));
      if (it.row() == it.col()) FUZZ_CHECK(it.value().real() >= 0);
    }
  for (std::size_t e = 0; e < ops.mesh().dual_edges().size(); ++e)
    FUZZ_CHECK(std::isfinite(ops.edge_weight(static_cast<int>(e))) && ops.edge_weight(static_cast<int>(e)) > 0);
}

}  // namespace nfield_fuzz
