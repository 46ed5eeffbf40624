#include "nfield/spline_system.hpp"

#include <algorithm>

#include "nfield/energy_rows.hpp"

namespace nfield {

SplineSystem assemble_spline_system(const FieldOperators& ops, int order, double lambda,
                                    const std::vector<int>& fixed_faces, const Eigen::VectorXd& weight) {
  const TriangleMesh& mesh = ops.mesh();
  SplineSystem sys;
  sys.order = order;
  sys.lambda = lambda;
  sys.fixed_faces = fixed_faces;
  sys.fixed_of_face.assign(mesh.num_faces(), -1);
  for (size_t i = 0; i < fixed_faces.size(); ++i) sys.fixed_of_face[fixed_faces[i]] = static_cast<int>(i);
  sys.unknown_of_face.assign(mesh.num_faces(), -1);
  for (int u = 0; u < ops.num_unknowns(); ++u) {
    const int f = ops.face_of_unknown(u);
    if (sys.fixed(f)) continue;
    sys.unknown_of_face[f] = static_cast<int>(sys.face_of_unknown.size());
    sys.face_of_unknown.push_back(f);
  }
  const int N = sys.num_unknowns();
  sys.mass.resize(N);
  for (int u = 0; u < N; ++u) sys.mass[u] = mesh.face_area(sys.face_of_unknown[u]);

  // Components that need the shift: lambda = 0 and no fixed face on them.
  const std::vector<int>& component = mesh.face_component();
  sys.shifted_component.assign(std::max(1, mesh.report().num_components), lambda == 0.0);
  for (int f : fixed_faces) sys.shifted_component[component[f]] = false;
  const bool any_shift = std::find(sys.shifted_component.begin(), sys.shifted_component.end(), true) !=
                         sys.shifted_component.end();
  sys.shift = any_shift ? kFreeComponentShift * ops.eigenvalue_unit(order) : 0.0;

  // E_m split into the blocks UU (the matrix) and UF (the coupling to fixed values).
  std::vector<Eigen::Triplet<Complex>> uu, uf;
  if (2 * N < ops.num_unknowns()) {
    // A local solve: only the rows of the unknowns (averaged with their adjoint within UU, so that V_UU is
    // exactly Hermitian, as energy_matrix makes the whole matrix).
    std::vector<int> rows(N);
    for (int u = 0; u < N; ++u) rows[u] = ops.unknown_of_face(sys.face_of_unknown[u]);
    const ComplexSparse E = energy_rows(ops, order, rows);  // N x ops.num_unknowns()
    for (int col = 0; col < E.outerSize(); ++col) {
      const int fc = ops.face_of_unknown(col), uc = sys.unknown_of_face[fc], xc = sys.fixed_of_face[fc];
      for (ComplexSparse::InnerIterator it(E, col); it; ++it) {
        const int ur = static_cast<int>(it.row());
        if (uc >= 0) {
          uu.emplace_back(ur, uc, 0.5 * it.value());
          uu.emplace_back(uc, ur, 0.5 * std::conj(it.value()));
        } else if (xc >= 0) {
          uf.emplace_back(ur, xc, it.value());
        }
      }
    }
  } else {
    const ComplexSparse E = ops.energy_matrix(order);
    uu.reserve(E.nonZeros() + N);
    for (int col = 0; col < E.outerSize(); ++col) {
      const int fc = ops.face_of_unknown(col), uc = sys.unknown_of_face[fc], xc = sys.fixed_of_face[fc];
      for (ComplexSparse::InnerIterator it(E, col); it; ++it) {
        const int ur = sys.unknown_of_face[ops.face_of_unknown(static_cast<int>(it.row()))];
        if (ur < 0) continue;
        if (uc >= 0)
          uu.emplace_back(ur, uc, it.value());
        else if (xc >= 0)
          uf.emplace_back(ur, xc, it.value());
      }
    }
  }
  for (int u = 0; u < N; ++u) {
    const int f = sys.face_of_unknown[u];
    const bool shifted = sys.shifted_component[component[f]];
    const double w = weight.size() > 0 ? weight[f] : 1.0;
    uu.emplace_back(u, u, ((shifted ? sys.shift : 0.0) - lambda * w) * sys.mass[u]);
  }
  sys.matrix.resize(N, N);
  sys.matrix.setFromTriplets(uu.begin(), uu.end());
  sys.matrix.makeCompressed();
  sys.coupling.resize(N, static_cast<int>(fixed_faces.size()));
  sys.coupling.setFromTriplets(uf.begin(), uf.end());
  sys.coupling.makeCompressed();
  return sys;
}

}  // namespace nfield
