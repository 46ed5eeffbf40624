#include "nfield/remesh/field_relaxation.hpp"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <string>

#include "nfield/errors.hpp"
#include "nfield/remesh/quad_untangle.hpp"
#include "nfield/remesh/remesh_surface.hpp"

namespace nfield::remesh {

namespace {

/// Moves must not take a face's worst corner (scaled Jacobian) below this, unless it was lower before.
constexpr double kFloor = 0.2;
/// Outer iterations of the global solve (at most; `iterations` if fewer).
constexpr int kGlobalIterations = 3;
/// The energy's weights (field_relaxation.hpp), relative to the off-axis term of an edge.
struct EnergyWeights {
  double length;     ///< the change of an edge's part along its axis (keeps the rows from sliding together)
  double proximity;  ///< each vertex's displacement, in median edge lengths (keeps the system definite)
  double robust;     ///< eps of the reweighting: an edge at angle a counts eps / sqrt(sin^2 a + eps^2)
};
constexpr EnergyWeights kWeights{0.1, 0.02, 0.2};
/// A face may leave the input by up to this share of the largest distance of any face before the step (or
/// by its own distance before, if larger): the solve must not raise the distance to the input.
constexpr double kDeviationShare = 0.7;
/// cos of the largest turn of the input's normal between a vertex's old and new place (30 degrees).
constexpr double kMaxTurn = 0.8660254037844386;
/// A vertex moves at most this many median edge lengths per iteration (the linearisation's range).
constexpr double kMaxMove = 0.5;

/// The field's axes at the point of the input nearest to `p`: `axis` the one nearer to `d`, `across` the
/// other one (both unit, tangent to the input there). False where the field is zero.
bool field_axes_near(const ProjectionTargets& targets, const std::vector<Vec3>& surface_directions, const Vec3& p,
                     const Vec3& d, Vec3& axis, Vec3& across) {
  const auto hit = targets.surface.closest(p);
  if (hit.triangle < 0 || hit.triangle >= static_cast<int>(surface_directions.size())) return false;
  Vec3 n = targets.surface.normal_at(hit, targets.surface_normals);
  if (!(n.norm() > 0)) return false;
  n.normalize();
  Vec3 q = surface_directions[hit.triangle];
  q -= n * n.dot(q);
  if (!(q.norm() > 0)) return false;
  q.normalize();
  const Vec3 t = n.cross(q);
  const bool along_q = std::abs(d.dot(q)) >= std::abs(d.dot(t));
  axis = along_q ? q : t;
  across = along_q ? t : q;
  return true;
}

/// The largest distance to the input of face f's centroid and edge midpoints (its vertices lie on the
/// input): how far the face leaves the surface.
double face_deviation(const PolygonMesh& mesh, int f, const ProjectionTargets& targets) {
  const int k = mesh.face_size(f);
  const int* v = mesh.face(f);
  Vec3 c = Vec3::Zero();
  double worst = 0;
  for (int i = 0; i < k; ++i) {
    c += mesh.positions[v[i]];
    worst = std::max(worst, targets.surface.closest(0.5 * (mesh.positions[v[i]] + mesh.positions[v[(i + 1) % k]])).squared_distance);
  }
  worst = std::max(worst, targets.surface.closest(c / k).squared_distance);
  return std::sqrt(worst);
}

/// Per face, its worst corner (scaled Jacobian) and, if `deviation` is given, face_deviation. Only the faces
/// with a vertex marked in `changed` are measured again (the others keep their values: each depends on its
/// own vertices only); all of them when `changed` is null.
void measure_faces(const PolygonMesh& mesh, const ProjectionTargets& targets, const std::vector<char>* changed,
                   std::vector<double>& worst, std::vector<double>* deviation) {
  worst.resize(mesh.num_faces());
  if (deviation) deviation->resize(mesh.num_faces());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int* v = mesh.face(f);
    if (changed && std::none_of(v, v + mesh.face_size(f), [&](int u) { return (*changed)[u] != 0; })) continue;
    worst[f] = worst_corner_on(mesh, f, targets);
    if (deviation) (*deviation)[f] = face_deviation(mesh, f, targets);
  }
}

double median_edge_length(const PolygonMesh& mesh, const std::vector<std::array<int, 2>>& edges) {
  std::vector<double> lengths;
  lengths.reserve(edges.size());
  for (const auto& e : edges) lengths.push_back((mesh.positions[e[1]] - mesh.positions[e[0]]).norm());
  if (lengths.empty()) return 0;
  std::nth_element(lengths.begin(), lengths.begin() + lengths.size() / 2, lengths.end());
  return lengths[lengths.size() / 2];
}

/// `iterations` Jacobi steps (field_relaxation.hpp). Vertices marked in `fixed` (if given) stay; edges whose
/// off-axis part exceeds `skip_sine` times their length (if below 1) pull neither end.
void local_steps(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets,
                 const std::vector<Vec3>& surface_directions, int iterations, const std::vector<char>* fixed,
                 double skip_sine) {
  const int V = mesh.num_vertices();
  const std::vector<std::array<int, 2>> edges = unique_edges(mesh);
  std::vector<double> worst;  // each face's worst corner at the current positions
  for (int it = 0; it < iterations; ++it) {
    std::vector<Vec3> move(V, Vec3::Zero());
    std::vector<int> count(V, 0);
    // The field at each edge's midpoint (where the alignment of an edge is measured).
    for (const auto& e : edges) {
      const Vec3 d = mesh.positions[e[1]] - mesh.positions[e[0]];
      Vec3 axis, across;
      if (!field_axes_near(targets, surface_directions, 0.5 * (mesh.positions[e[0]] + mesh.positions[e[1]]), d, axis,
                           across))
        continue;
      const Vec3 off = d - d.dot(axis) * axis;  // the edge less its part along the nearer axis
      if (off.norm() > skip_sine * d.norm()) continue;
      // e[0] moves by +off (its edge becomes d - off), e[1] by -off.
      move[e[0]] += off;
      move[e[1]] -= off;
      ++count[e[0]];
      ++count[e[1]];
    }
    const std::vector<Vec3> before = mesh.positions;
    if (it == 0) measure_faces(mesh, targets, nullptr, worst, nullptr);
    const std::vector<double> worst_before = worst;
    std::vector<char> frozen(V, 0);  // vertices of faces already poor: left to the untangling step
    for (int f = 0; f < mesh.num_faces(); ++f)
      if (worst_before[f] < kFloor)
        for (int i = 0; i < mesh.face_size(f); ++i) frozen[mesh.face(f)[i]] = 1;
    for (int v = 0; v < V; ++v)
      if (count[v] && kind[v] == kNoFeature && !frozen[v] && !(fixed && (*fixed)[v]))
        mesh.positions[v] += 0.25 * move[v] / count[v];
    project_vertices(mesh, kind, targets);
    std::vector<char> changed(V, 0);
    for (int v = 0; v < V; ++v) changed[v] = mesh.positions[v] != before[v];
    // Guard: a face whose worst corner dropped below kFloor (and below where it was) gets its vertices back,
    // until no face does.
    for (int pass = 0; pass < 10; ++pass) {
      measure_faces(mesh, targets, &changed, worst, nullptr);
      std::fill(changed.begin(), changed.end(), 0);
      bool reverted = false;
      for (int f = 0; f < mesh.num_faces(); ++f) {
        if (worst[f] >= kFloor || worst[f] >= worst_before[f]) continue;
        for (int i = 0; i < mesh.face_size(f); ++i) {
          const int v = mesh.face(f)[i];
          if (mesh.positions[v] != before[v]) mesh.positions[v] = before[v], changed[v] = 1, reverted = true;
        }
      }
      if (!reverted) break;
    }
    // After the last pass reverted vertices, the faces around them are measured again for the next step.
    measure_faces(mesh, targets, &changed, worst, nullptr);
  }
}

}  // namespace

double off_axis_energy(const PolygonMesh& mesh, const ProjectionTargets& targets,
                       const std::vector<Vec3>& surface_directions) {
  double energy = 0;
  for (const auto& e : unique_edges(mesh)) {
    const Vec3 d = mesh.positions[e[1]] - mesh.positions[e[0]];
    const double length2 = d.squaredNorm();
    Vec3 axis, across;
    if (!(length2 > 0) ||
        !field_axes_near(targets, surface_directions, 0.5 * (mesh.positions[e[0]] + mesh.positions[e[1]]), d, axis, across))
      continue;
    energy += d.dot(across) * d.dot(across) / length2;
  }
  return energy;
}

void relax_along_field(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets,
                       const std::vector<Vec3>& surface_directions, int iterations) {
  solve_along_field(mesh, kind, targets, surface_directions, std::min(iterations, kGlobalIterations));
  local_steps(mesh, kind, targets, surface_directions, iterations, nullptr, 1.0);
}

void refine_along_field(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets,
                        const std::vector<Vec3>& surface_directions, int iterations, const std::vector<char>& fixed,
                        double skip_degrees) {
  if (static_cast<int>(fixed.size()) != mesh.num_vertices())
    throw ParameterError("refine_along_field: `fixed` needs one entry per vertex (" +
                         std::to_string(mesh.num_vertices()) + "), got " + std::to_string(fixed.size()));
  const int n = std::min(iterations, kGlobalIterations);
  if (n <= 0) return;
  // Both parts keep every face at least as valid as it was or above kFloor; as nothing runs after this
  // pass to untangle, a face it would still flip (none on the benchmark meshes) undoes the whole pass.
  const std::vector<Vec3> start = mesh.positions;
  const std::vector<double> worst_start = scaled_jacobians_on(mesh, targets);
  solve_along_field(mesh, kind, targets, surface_directions, n, &fixed);
  const double skip_sine = skip_degrees < 45 ? std::sin(skip_degrees * 3.14159265358979323846 / 180) : 1.0;
  local_steps(mesh, kind, targets, surface_directions, n, &fixed, skip_sine);
  const std::vector<double> worst = scaled_jacobians_on(mesh, targets);
  for (int f = 0; f < mesh.num_faces(); ++f)
    if (worst[f] <= 0 && worst_start[f] > 0) {
      mesh.positions = start;
      return;
    }
}

void solve_along_field(PolygonMesh& mesh, const std::vector<char>& kind, const ProjectionTargets& targets,
                       const std::vector<Vec3>& surface_directions, int iterations, const std::vector<char>* fixed) {
  const int V = mesh.num_vertices();
  const std::vector<std::array<int, 2>> edges = unique_edges(mesh);
  if (edges.empty()) return;
  const double s = median_edge_length(mesh, edges);
  if (!(s > 0)) return;
  // Each face's worst corner and distance from the input at the current positions, kept up to date.
  std::vector<double> worst, deviation;
  measure_faces(mesh, targets, nullptr, worst, &deviation);
  for (int it = 0; it < iterations; ++it) {
    const std::vector<Vec3> before = mesh.positions;
    const std::vector<double> worst_before = worst;
    const std::vector<double> deviation_before = deviation;
    const double deviation_allowed = kDeviationShare * *std::max_element(deviation_before.begin(), deviation_before.end());
    // Free vertices: on an edge, not on a face with a feature vertex (next to a crease a move along the field
    // can fold a face over it), not on a face already poor (worst corner below kFloor: those are the
    // untangling step's), nor on a face next to a flipped one.
    std::vector<char> free(V, 0);
    for (const auto& e : edges) free[e[0]] = free[e[1]] = 1;
    if (fixed)
      for (int v = 0; v < V; ++v)
        if ((*fixed)[v]) free[v] = 0;
    for (int f = 0; f < mesh.num_faces(); ++f)
      if (std::any_of(mesh.face(f), mesh.face(f) + mesh.face_size(f), [&](int v) { return kind[v] != kNoFeature; }))
        for (int i = 0; i < mesh.face_size(f); ++i) free[mesh.face(f)[i]] = 0;
    std::vector<char> flipped(V, 0);
    for (int f = 0; f < mesh.num_faces(); ++f) {
      if (worst_before[f] >= kFloor) continue;
      for (int i = 0; i < mesh.face_size(f); ++i) free[mesh.face(f)[i]] = 0;
      if (worst_before[f] <= 0)
        for (int i = 0; i < mesh.face_size(f); ++i) flipped[mesh.face(f)[i]] = 1;
    }
    // The faces around a flipped face stay too: the untangling step moves their vertices as well, from where
    // the mesh had them.
    for (int f = 0; f < mesh.num_faces(); ++f)
      if (std::any_of(mesh.face(f), mesh.face(f) + mesh.face_size(f), [&](int v) { return flipped[v] != 0; }))
        for (int i = 0; i < mesh.face_size(f); ++i) free[mesh.face(f)[i]] = 0;
    // Two unknowns per free vertex: its displacement in the tangent plane of the input at it (frame b1, b2).
    std::vector<int> index(V, -1);
    std::vector<std::array<Vec3, 2>> frame(V);
    int n = 0;
    for (int v = 0; v < V; ++v) {
      if (!free[v]) continue;
      Vec3 normal = targets.surface.surface_normal(mesh.positions[v], targets.surface_normals);
      if (!(normal.norm() > 0)) continue;
      normal.normalize();
      Vec3 b1 = normal.unitOrthogonal();
      frame[v] = {b1, normal.cross(b1)};
      index[v] = n;
      n += 2;
    }
    if (n == 0) return;
    // Least squares: each edge contributes w_e (across . (d + u_j - u_i))^2 and w_e kWeights.length
    // (axis . (u_j - u_i))^2, lengths in units of s; each vertex kWeights.proximity |u|^2.
    std::vector<Eigen::Triplet<double>> triplets;
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
    for (int i = 0; i < n; ++i) triplets.emplace_back(i, i, kWeights.proximity);
    auto add_row = [&](const Vec3& direction, const std::array<int, 2>& e, double target, double weight) {
      // Row r . x = target with r having -direction . b on e[0]'s unknowns and +direction . b on e[1]'s;
      // fixed vertices contribute nothing (their displacement is zero).
      int col[4];
      double val[4];
      int m = 0;
      for (int end = 0; end < 2; ++end) {
        const int v = e[end];
        if (index[v] < 0) continue;
        const double sign = end == 0 ? -1.0 : 1.0;
        for (int c = 0; c < 2; ++c) col[m] = index[v] + c, val[m] = sign * direction.dot(frame[v][c]), ++m;
      }
      for (int a = 0; a < m; ++a) {
        rhs[col[a]] += weight * val[a] * target;
        for (int b = 0; b < m; ++b) triplets.emplace_back(col[a], col[b], weight * val[a] * val[b]);
      }
    };
    for (const auto& e : edges) {
      if (index[e[0]] < 0 && index[e[1]] < 0) continue;
      const Vec3 d = (mesh.positions[e[1]] - mesh.positions[e[0]]) / s;
      Vec3 axis, across;
      if (!(d.norm() > 0) ||
          !field_axes_near(targets, surface_directions, 0.5 * (mesh.positions[e[0]] + mesh.positions[e[1]]), d, axis, across))
        continue;
      // The alignment is an angle: the off-axis part counts relative to the edge's length (short edges capped),
      // and an edge already far off its axis (next to a cone, where no lattice follows the field) pulls less
      // than one nearly aligned: iteratively reweighted least squares, towards the sum of |sin a|.
      const double length = std::max(d.norm(), 0.3);
      const double sine = std::abs(d.dot(across)) / d.norm();
      const double eps = kWeights.robust;
      const double w = eps / std::sqrt(sine * sine + eps * eps) / (length * length);
      add_row(across, e, -d.dot(across), w);
      add_row(axis, e, 0.0, kWeights.length * w);
    }
    Eigen::SparseMatrix<double> H(n, n);
    H.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(H);
    if (solver.info() != Eigen::Success) return;
    const Eigen::VectorXd x = solver.solve(rhs);
    if (solver.info() != Eigen::Success || !x.allFinite()) return;
    for (int v = 0; v < V; ++v) {
      if (index[v] < 0) continue;
      Vec3 u = s * (x[index[v]] * frame[v][0] + x[index[v] + 1] * frame[v][1]);
      if (u.norm() > kMaxMove * s) u *= kMaxMove * s / u.norm();
      mesh.positions[v] += u;
    }
    project_vertices(mesh, kind, targets);
    // A vertex that landed where the input turns away from where it was (across a crease, on the other sheet
    // of a thin part) goes back.
    for (int v = 0; v < V; ++v) {
      if (index[v] < 0) continue;
      const Vec3 normal = targets.surface.surface_normal(mesh.positions[v], targets.surface_normals);
      if (!(normal.normalized().dot(frame[v][0].cross(frame[v][1])) >= kMaxTurn)) mesh.positions[v] = before[v];
    }
    // Guard: the vertices of a face whose worst corner dropped below kFloor (and below where it was), or that
    // left the input further than allowed, take half their step (projected again), down to an eighth, then
    // none, until no face does (it ends: each vertex is shortened at most four times, and a face whose
    // vertices are all back is as it was).
    const std::vector<Vec3> goal = mesh.positions;
    std::vector<double> share(V, 1.0);
    std::vector<char> shortened(V, 0);
    for (int v = 0; v < V; ++v) shortened[v] = mesh.positions[v] != before[v];  // to measure again
    while (true) {
      measure_faces(mesh, targets, &shortened, worst, &deviation);
      std::fill(shortened.begin(), shortened.end(), 0);
      bool any = false;
      for (int f = 0; f < mesh.num_faces(); ++f) {
        const bool folds = worst[f] < kFloor && worst[f] < worst_before[f];
        const bool leaves = deviation[f] > std::max(deviation_before[f], deviation_allowed);
        if (!folds && !leaves) continue;
        for (int i = 0; i < mesh.face_size(f); ++i) {
          const int v = mesh.face(f)[i];
          if (mesh.positions[v] != before[v] && !shortened[v]) shortened[v] = 1, any = true;
        }
      }
      if (!any) break;
      for (int v = 0; v < V; ++v) {
        if (!shortened[v]) continue;
        share[v] = share[v] > 0.2 ? 0.5 * share[v] : 0.0;
        if (share[v] == 0.0) {
          mesh.positions[v] = before[v];
        } else {
          const auto hit = targets.surface.closest(before[v] + share[v] * (goal[v] - before[v]));
          mesh.positions[v] = hit.triangle >= 0 ? hit.point : before[v];
        }
      }
    }
  }
}

}  // namespace nfield::remesh
