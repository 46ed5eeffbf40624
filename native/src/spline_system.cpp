#include "nfield/spline_system.hpp"

#include <algorithm>

#include "nfield/energy_rows.hpp"

namespace nfield {
namespace {

/// (B + B^H) / 2 + diag(d) for a square compressed B with sorted rows in each column; compressed and sorted.
ComplexSparse hermitian_part_plus_diagonal(const ComplexSparse& B, const Eigen::VectorXd& d) {
  const ComplexSparse Bh = B.adjoint();  // compressed, rows sorted
  const int N = static_cast<int>(B.cols());
  ComplexSparse out(N, N);
  out.resizeNonZeros(B.nonZeros() + Bh.nonZeros() + N);
  int* outer = out.outerIndexPtr();
  int* inner = out.innerIndexPtr();
  Complex* value = out.valuePtr();
  int nnz = 0;
  for (int j = 0; j < N; ++j) {
    outer[j] = nnz;
    int p = B.outerIndexPtr()[j], q = Bh.outerIndexPtr()[j];
    const int p_end = B.outerIndexPtr()[j + 1], q_end = Bh.outerIndexPtr()[j + 1];
    bool diagonal_done = false;
    while (p < p_end || q < q_end || !diagonal_done) {
      int i = std::min(p < p_end ? B.innerIndexPtr()[p] : N, q < q_end ? Bh.innerIndexPtr()[q] : N);
      if (!diagonal_done && j <= i) i = j;
      Complex v = 0.0;
      if (p < p_end && B.innerIndexPtr()[p] == i) v += 0.5 * B.valuePtr()[p++];
      if (q < q_end && Bh.innerIndexPtr()[q] == i) v += 0.5 * Bh.valuePtr()[q++];
      if (i == j) v += Complex(d[j], 0.0), diagonal_done = true;
      inner[nnz] = i, value[nnz++] = v;
    }
  }
  outer[N] = nnz;
  out.resizeNonZeros(nnz);
  return out;
}

}  // namespace

SplineSystem assemble_spline_system(const FieldOperators& ops, int order, double lambda, const FrozenFaces& frozen,
                                    const std::vector<int>& anchors, const Eigen::VectorXd& weight) {
  const TriangleMesh& mesh = ops.mesh();
  SplineSystem sys;
  sys.order = order;
  sys.lambda = lambda;
  sys.fixed_faces = anchors;
  sys.fixed_of_face.assign(mesh.num_faces(), -1);
  for (size_t i = 0; i < anchors.size(); ++i) sys.fixed_of_face[anchors[i]] = static_cast<int>(i);
  sys.unknown_of_face.assign(mesh.num_faces(), -1);
  for (int u = 0; u < ops.num_unknowns(); ++u) {
    const int f = ops.face_of_unknown(u);
    if (frozen.held(f) || sys.fixed_of_face[f] >= 0) continue;
    sys.unknown_of_face[f] = static_cast<int>(sys.face_of_unknown.size());
    sys.face_of_unknown.push_back(f);
  }
  const int N = sys.num_unknowns();
  sys.mass.resize(N);
  for (int u = 0; u < N; ++u) sys.mass[u] = mesh.face_area(sys.face_of_unknown[u]);

  // Components that need the shift: lambda = 0 and no fixed face on them.
  const std::vector<int>& component = mesh.face_component();
  sys.shifted_component.assign(std::max(1, mesh.report().num_components), lambda == 0.0);
  if (lambda == 0.0) {
    for (int f : anchors) sys.shifted_component[component[f]] = false;
    frozen.for_each([&](int f, Complex) { sys.shifted_component[component[f]] = false; });
  }
  const bool any_shift = std::find(sys.shifted_component.begin(), sys.shifted_component.end(), true) !=
                         sys.shifted_component.end();
  sys.shift = any_shift ? kFreeComponentShift * ops.eigenvalue_unit(order) : 0.0;
  // The column of V_UF of a fixed face (numbered as met), -1 for an unknown.
  auto fixed_column = [&](int f) {
    int& x = sys.fixed_of_face[f];
    if (x < 0 && frozen.held(f)) {
      x = static_cast<int>(sys.fixed_faces.size());
      sys.fixed_faces.push_back(f);
    }
    return x;
  };

  // The diagonal of V - E_m: the (weighted) mass term and, on shifted components, the shift.
  Eigen::VectorXd diagonal(N);
  for (int u = 0; u < N; ++u) {
    const int f = sys.face_of_unknown[u];
    const bool shifted = sys.shifted_component[component[f]];
    const double w = weight.size() > 0 ? weight[f] : 1.0;
    diagonal[u] = ((shifted ? sys.shift : 0.0) - lambda * w) * sys.mass[u];
  }

  // E_m split into the blocks UU (the matrix) and UF (the coupling to fixed values).
  std::vector<Eigen::Triplet<Complex>> uf;
  if (2 * N < ops.num_unknowns()) {
    // A local solve: only the columns of E_m at the unknowns (energy_rows.hpp). Column j holds E_{U,u_j}, a
    // column of the block B = (E_m)_UU as computed, and E_{F,u_j}, whose adjoint is row j of V_UF (E_m is
    // Hermitian). V_UU = (B + B^H) / 2 is exactly Hermitian, as energy_matrix makes the whole matrix. The unknowns
    // are numbered in the order of ops' unknowns, so B keeps the sorted rows of the columns: no triplets, no sort.
    std::vector<int> columns(N);
    for (int u = 0; u < N; ++u) columns[u] = ops.unknown_of_face(sys.face_of_unknown[u]);
    const ComplexSparse C = energy_columns(ops, order, columns);  // ops.num_unknowns() x N
    ComplexSparse B(N, N);
    B.resizeNonZeros(C.nonZeros());
    int nnz = 0;
    for (int j = 0; j < N; ++j) {
      B.outerIndexPtr()[j] = nnz;
      for (ComplexSparse::InnerIterator it(C, j); it; ++it) {
        const int f = ops.face_of_unknown(static_cast<int>(it.row())), ur = sys.unknown_of_face[f];
        if (ur >= 0) {
          B.innerIndexPtr()[nnz] = ur;
          B.valuePtr()[nnz++] = it.value();
        } else if (const int xc = fixed_column(f); xc >= 0) {
          uf.emplace_back(j, xc, std::conj(it.value()));
        }
      }
    }
    B.outerIndexPtr()[N] = nnz;
    B.resizeNonZeros(nnz);
    sys.matrix = hermitian_part_plus_diagonal(B, diagonal);
  } else {
    const ComplexSparse E = ops.energy_matrix(order);
    std::vector<Eigen::Triplet<Complex>> uu;
    uu.reserve(E.nonZeros() + N);
    for (int col = 0; col < E.outerSize(); ++col) {
      const int fc = ops.face_of_unknown(col), uc = sys.unknown_of_face[fc];
      for (ComplexSparse::InnerIterator it(E, col); it; ++it) {
        const int ur = sys.unknown_of_face[ops.face_of_unknown(static_cast<int>(it.row()))];
        if (ur < 0) continue;
        if (uc >= 0)
          uu.emplace_back(ur, uc, it.value());
        else if (const int xc = fixed_column(fc); xc >= 0)
          uf.emplace_back(ur, xc, it.value());
      }
    }
    for (int u = 0; u < N; ++u) uu.emplace_back(u, u, Complex(diagonal[u], 0.0));
    sys.matrix.resize(N, N);
    sys.matrix.setFromTriplets(uu.begin(), uu.end());
    sys.matrix.makeCompressed();
  }
  sys.coupling.resize(N, static_cast<int>(sys.fixed_faces.size()));
  sys.coupling.setFromTriplets(uf.begin(), uf.end());
  sys.coupling.makeCompressed();
  return sys;
}

}  // namespace nfield
