#include "nfield/remesh/lattice_offsets.hpp"

#include <Eigen/CholmodSupport>
#include <Eigen/Sparse>
#include <cmath>

#include "nfield/blas.hpp"

#include "nfield/remesh/lattice.hpp"

namespace nfield::remesh {

namespace {

using Mat32 = Eigen::Matrix<double, 3, 2>;

Mat32 frame(const HierarchyLevel& L, int i) {
  Mat32 A;
  A.col(0) = L.q[i];
  A.col(1) = L.n[i].cross(L.q[i]);
  return A;
}

}  // namespace

LatticeOffsets compute_lattice_offsets(const RemeshSurface& s, const HierarchyLevel& L) {
  LatticeOffsets out;
  const int E = static_cast<int>(s.edges.size());
  out.offset.resize(E);
  out.mismatch.resize(E);
  out.turns.resize(E);
  for (int e = 0; e < E; ++e) {
    const int i = s.edges[e][0], j = s.edges[e][1];
    int k = 0;
    const Vec3 q_j = compatible_direction(L.q[i], L.q[j], L.n[j], &k);
    const double scale = L.pair_spacing(i, j);
    const LatticePair pair = closest_lattice_pair(L.v[i], L.n[i], L.q[i], L.p[i], L.v[j], L.n[j], q_j, L.p[j], scale);
    out.offset[e] = pair.index_i - pair.index_j;
    const Vec3 gap = pair.point_j - pair.point_i;
    out.mismatch[e] = Eigen::Vector2d(gap.dot(L.q[i]), gap.dot(L.n[i].cross(L.q[i]))) / scale;
    out.turns[e] = static_cast<signed char>(k);
  }
  return out;
}

std::vector<std::array<int, 3>> triangle_edges(const RemeshSurface& s) {
  std::vector<std::array<int, 3>> fe(s.triangles.size());
  auto edge_of = [&](int a, int b) {
    for (int k = s.adjacency_offsets[a]; k < s.adjacency_offsets[a + 1]; ++k)
      if (s.adjacency[k] == b) return s.adjacency_edge[k];
    return -1;
  };
  for (size_t t = 0; t < s.triangles.size(); ++t)
    for (int m = 0; m < 3; ++m) fe[t][m] = edge_of(s.triangles[t][m], s.triangles[t][(m + 1) % 3]);
  return fe;
}

FaceDefects face_defects(const RemeshSurface& s, const std::vector<std::array<int, 3>>& fe, const LatticeOffsets& o) {
  FaceDefects d;
  const int T = static_cast<int>(s.triangles.size());
  d.orientation_index.assign(T, 0);
  d.residual.assign(T, Eigen::Vector2i::Zero());
  for (int t = 0; t < T; ++t) {
    const auto& tri = s.triangles[t];
    Eigen::Vector2i D[3];
    int k[3];
    for (int m = 0; m < 3; ++m) {
      const int e = fe[t][m];
      const bool forward = tri[m] < tri[(m + 1) % 3];
      D[m] = o.directed_offset(e, forward);
      k[m] = o.directed_turns(e, forward);
    }
    const int K = (k[0] + k[1] + k[2]) % 4;
    d.orientation_index[t] = static_cast<signed char>(K);
    if (K != 0) {
      ++d.orientation_singularities;
      continue;
    }
    // Lattice images of the corners in corner 0's coordinates.
    const Eigen::Vector2i z1 = D[0];
    const Eigen::Vector2i z2 = z1 + rotate_quarter(D[1], -k[0]);
    const Eigen::Vector2i r = z2 + rotate_quarter(D[2], -k[0] - k[1]);
    d.residual[t] = r;
    if (r != Eigen::Vector2i::Zero()) ++d.position_singularities;
    else if (z1.x() * z2.y() - z1.y() * z2.x() < 0) ++d.folded;
  }
  return d;
}

int normalize_representatives(const RemeshSurface& s, HierarchyLevel& L, LatticeOffsets& o) {
  const int V = s.num_vertices();
  std::vector<Eigen::Vector2i> shift(V);
  int changed = 0;
  for (int i = 0; i < V; ++i) {
    const Vec3 t = L.n[i].cross(L.q[i]);
    const Vec3 d = L.v[i] - L.p[i];
    const double scale = L.spacing[i];
    shift[i] = Eigen::Vector2i(static_cast<int>(std::lround(L.q[i].dot(d) / scale)),
                               static_cast<int>(std::lround(t.dot(d) / scale)));
    if (shift[i] != Eigen::Vector2i::Zero()) {
      L.p[i] += scale * (shift[i].x() * L.q[i] + shift[i].y() * t);
      ++changed;
    }
  }
  for (size_t e = 0; e < s.edges.size(); ++e) {
    const int a = s.edges[e][0], b = s.edges[e][1];
    o.offset[e] += rotate_quarter(shift[b], -o.turns[e]) - shift[a];
  }
  return changed;
}

bool resolve_positions(const RemeshSurface& s, HierarchyLevel& L, const LatticeOffsets& o, double lambda) {
  const int V = s.num_vertices();
  // Unknowns: the two tangent coordinates x_i of p_i = v_i + A_i x_i; fixed ones (feature constraints) get
  // index -1 and their value in `fixed_value`.
  std::vector<int> index(2 * V, -1);
  std::vector<double> fixed_value(2 * V, 0.0), old_value(2 * V, 0.0);
  int n = 0;
  for (int i = 0; i < V; ++i) {
    const Mat32 A = frame(L, i);
    const Eigen::Vector2d x0 = A.transpose() * (L.p[i] - L.v[i]);
    old_value[2 * i] = x0.x();
    old_value[2 * i + 1] = x0.y();
    const char kind = L.constraint_kind.empty() ? 0 : L.constraint_kind[i];
    const Eigen::Vector2d c = A.transpose() * (L.constraint_point.empty() ? L.v[i] - L.v[i] : L.constraint_point[i] - L.v[i]);
    bool fixed[2] = {false, false};
    if (kind >= 2) {
      fixed[0] = fixed[1] = true;
    } else if (kind == 1) {
      const Vec3& dir = L.constraint_dir[i];
      // The lattice line along the axis nearest the curve passes through the curve point: the other
      // coordinate is fixed.
      const bool along_q = std::abs(A.col(0).dot(dir)) >= std::abs(A.col(1).dot(dir));
      fixed[along_q ? 1 : 0] = true;
    }
    for (int c2 = 0; c2 < 2; ++c2) {
      if (fixed[c2]) fixed_value[2 * i + c2] = c[c2];
      else index[2 * i + c2] = n++;
    }
  }
  if (n == 0) return true;
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(s.edges.size()) * 16 + 2 * V);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
  // Adds h * x_col to row's equation (or moves it to the right-hand side when col is fixed).
  auto add = [&](int row, int col, double h) {
    if (index[row] < 0) return;
    if (index[col] >= 0) trip.emplace_back(index[row], index[col], h);
    else rhs[index[row]] -= h * fixed_value[col];
  };
  for (size_t e = 0; e < s.edges.size(); ++e) {
    const int a = s.edges[e][0], b = s.edges[e][1];
    const Mat32 A = frame(L, a), B = frame(L, b);
    int k = o.turns[e];
    Vec3 qb = L.q[b];
    for (int r = 0; r < k; ++r) qb = L.n[b].cross(qb);
    const Vec3 qbar = 0.5 * (A.col(0) + qb), tbar = 0.5 * (A.col(1) + L.n[b].cross(qb));
    const Vec3 g = L.pair_spacing(a, b) * (o.offset[e].x() * qbar + o.offset[e].y() * tbar);
    Vec3 nbar = L.n[a] + L.n[b];
    nbar = nbar.norm() > 0 ? Vec3(nbar.normalized()) : L.n[a];
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - nbar * nbar.transpose();
    // r = B x_b - A x_a + c, c = v_b - v_a - g; normal equations of |P r|^2.
    const Vec3 c = L.v[b] - L.v[a] - g;
    const Eigen::Matrix2d Haa = A.transpose() * P * A, Hbb = B.transpose() * P * B, Hab = -(A.transpose() * P * B);
    const Eigen::Vector2d ga = A.transpose() * P * c, gb = -(B.transpose() * P * c);
    for (int r = 0; r < 2; ++r) {
      if (index[2 * a + r] >= 0) rhs[index[2 * a + r]] += ga[r];
      if (index[2 * b + r] >= 0) rhs[index[2 * b + r]] += gb[r];
      for (int c2 = 0; c2 < 2; ++c2) {
        add(2 * a + r, 2 * a + c2, Haa(r, c2));
        add(2 * b + r, 2 * b + c2, Hbb(r, c2));
        add(2 * a + r, 2 * b + c2, Hab(r, c2));
        add(2 * b + r, 2 * a + c2, Hab(c2, r));
      }
    }
  }
  for (int u = 0; u < 2 * V; ++u)
    if (index[u] >= 0) {
      trip.emplace_back(index[u], index[u], lambda);
      rhs[index[u]] += lambda * old_value[u];
    }
  Eigen::SparseMatrix<double> H(n, n);
  H.setFromTriplets(trip.begin(), trip.end());
  // Small supernodes: OpenBLAS threads only spin against the other work on the machine (fandisk at 5k
  // quads, load 16 on 2 cores: 11.2 s multi-threaded, 2.0 s single-threaded).
  SingleThreadedBlas blas_guard;
  Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>, Eigen::Lower> solver;
  solver.compute(H);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::VectorXd x = solver.solve(rhs);
  if (solver.info() != Eigen::Success || !x.allFinite()) return false;
  for (int i = 0; i < V; ++i) {
    const Mat32 A = frame(L, i);
    Eigen::Vector2d xi;
    for (int c2 = 0; c2 < 2; ++c2) xi[c2] = index[2 * i + c2] >= 0 ? x[index[2 * i + c2]] : fixed_value[2 * i + c2];
    L.p[i] = L.v[i] + A * xi;
  }
  return true;
}

}  // namespace nfield::remesh
