// Evenly spaced streamlines of a face-based n-direction field; see streamlines.hpp for the method.
#include "nfield/streamlines.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <queue>
#include <random>
#include <string>
#include <unordered_map>

#include "nfield/errors.hpp"
#include "nfield/singularities.hpp"
#include "nfield/stroke_points.hpp"

namespace nfield {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
constexpr int kMaxZeroMoves = 16;
constexpr int kMaxWalkFaces = 10000;

using strokes::HashGrid;
using strokes::PointSet;

struct Location {
  int face = -1;
  std::array<double, 3> bary{{1.0 / 3, 1.0 / 3, 1.0 / 3}};
};

/// One direction of one stroke as traced: points, the face of the segment starting at each point, and
/// the field direction (3D unit vector) of that face.
struct HalfStroke {
  std::vector<Eigen::Vector3d> points;
  std::vector<int> faces;
  std::vector<Eigen::Vector3d> dirs;
  double length = 0.0;
};

class Tracer {
 public:
  Tracer(const FieldOperators& ops, const ComplexVector& field, const StreamlineParams& p)
      : ops_(ops), mesh_(ops.mesh()), field_(field), p_(p), n_(ops.n()), k0_(((p.family % n_) + n_) % n_) {
    const int F = mesh_.num_faces();
    const auto& P = mesh_.positions();
    const auto& T = mesh_.faces();
    nbr_.assign(F, {{-1, -1, -1}});
    grad_.resize(F);
    active_.assign(F, 0);
    for (int f = 0; f < F; ++f) {
      if (!mesh_.face_active(f)) continue;
      active_[f] = 1;
      const Eigen::Vector3d& N = mesh_.face_normal(f);
      const double A2 = 2.0 * mesh_.face_area(f);
      for (int i = 0; i < 3; ++i) {
        const Eigen::Vector3d e = P.row(T(f, (i + 2) % 3)) - P.row(T(f, (i + 1) % 3));
        grad_[f][i] = N.cross(e) / A2;  // gradient of barycentric lambda_i (1 / length)
      }
    }
    for (const DualEdge& e : mesh_.dual_edges()) {
      for (int side = 0; side < 2; ++side) {
        const int f = side == 0 ? e.face0 : e.face1, g = side == 0 ? e.face1 : e.face0;
        for (int i = 0; i < 3; ++i)
          if (T(f, i) != e.vertex0 && T(f, i) != e.vertex1) nbr_[f][i] = g;
      }
    }
    // Faces incident to singular vertices.
    blocked_.assign(F, 0);
    if (p_.stop_at_singularities) {
      const auto sing = singularity_indices(ops_, field_);
      stats_.num_singularities = static_cast<int>(sing.size());
      for (const auto& s : sing)
        for (int f : mesh_.vertex_faces(s.vertex)) blocked_[f] = 1;
      for (int f = 0; f < F; ++f) stats_.num_blocked_faces += blocked_[f];
    }
    traceable_.assign(F, 0);
    base_angle_.assign(F, 0.0);
    for (int f = 0; f < F; ++f) {
      const double r = std::abs(field_[f]);
      if (active_[f] && std::isfinite(r) && r > 1e-12) {
        traceable_[f] = 1;
        base_angle_[f] = std::arg(field_[f]) / n_;
      }
    }
    if (n_ == 4 && p_.cross_hatch) comb();
  }

  /// Cross-hatching a 4-field: split each face's 4 directions into the main pair (family 0) and the
  /// perpendicular pair (family 1) consistently across dual edges, by a maximum-smoothness spanning forest
  /// (Prim, smallest matching turn first, from the lowest-index face of each component). Afterwards the
  /// tracer treats the field as a 2-field with base angle arg(z)/4 + c_f pi/2 (c_f in {0, 1}); at the
  /// forest's seams (edges where the split flips) the matched direction turns by ~90 degrees, more than
  /// max_turn, so strokes stop there instead of turning into the other family. Both families are then
  /// exactly perpendicular in every face. Independent of the seed.
  void comb() {
    const int F = mesh_.num_faces();
    const auto& T = mesh_.faces();
    const auto& edges = mesh_.dual_edges();
    std::vector<double> turn(edges.size(), 0.0);
    std::vector<int> label(F, -1);
    auto other = [&](int e, int f) { return edges[e].face0 == f ? edges[e].face1 : edges[e].face0; };
    // label of g given the label of f: the 4-direction of g closest to f's transported main direction
    auto matched = [&](int e, int f, int lf, double* t) {
      const int g = other(e, f);
      const DualEdge& de = edges[e];
      const Eigen::Vector3d d = direction(f, base_angle_[f] + lf * 0.5 * M_PI);
      const Eigen::Vector3d v = transport(f, g, de.vertex0, de.vertex1, d);
      const double theta = std::atan2(v.dot(ops_.frames().y_axis(g)), v.dot(ops_.frames().x_axis(g)));
      const double k = std::round((theta - base_angle_[g]) / (0.5 * M_PI));
      if (t) *t = std::abs(theta - base_angle_[g] - k * 0.5 * M_PI);
      return static_cast<int>(((static_cast<long long>(k) % 2) + 2) % 2);
    };
    (void)T;
    using Item = std::pair<double, std::pair<int, int>>;  // (turn, (edge, from face))
    for (int root = 0; root < F; ++root) {
      if (!traceable_[root] || label[root] >= 0) continue;
      label[root] = 0;
      std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
      auto push_edges = [&](int f) {
        for (int e : mesh_.face_dual_edges(f)) {
          const int g = other(e, f);
          if (!traceable_[g] || label[g] >= 0) continue;
          double t;
          matched(e, f, label[f], &t);
          heap.push({t, {e, f}});
        }
      };
      push_edges(root);
      while (!heap.empty()) {
        const auto [t, ef] = heap.top();
        heap.pop();
        const int e = ef.first, f = ef.second, g = other(e, f);
        if (label[g] >= 0) continue;
        label[g] = matched(e, f, label[f], nullptr);
        push_edges(g);
      }
    }
    for (int f = 0; f < F; ++f)
      if (label[f] > 0) base_angle_[f] += 0.5 * M_PI;
    for (int f = 0; f < F; ++f) base_angle_[f] += k0_ * 0.5 * M_PI;  // family k0 (odd: the other pair)
    n_ = 2;
    k0_ = 0;
  }

  Streamlines run() {
    Streamlines out;
    const int families = p_.cross_hatch ? 2 : 1;
    for (int fam = 0; fam < families && !stats_.truncated; ++fam) trace_family(fam, out);
    out.stats = stats_;
    out.stats.num_strokes = static_cast<int>(out.strokes.size());
    return out;
  }

 private:
  // ---- geometry helpers ----
  Eigen::Vector3d position(const Location& l) const {
    const auto& P = mesh_.positions();
    const auto& T = mesh_.faces();
    return l.bary[0] * P.row(T(l.face, 0)).transpose() + l.bary[1] * P.row(T(l.face, 1)).transpose() +
           l.bary[2] * P.row(T(l.face, 2)).transpose();
  }
  Eigen::Vector3d direction(int f, double angle) const {
    return std::cos(angle) * ops_.frames().x_axis(f) + std::sin(angle) * ops_.frames().y_axis(f);
  }
  /// The field direction of face f (family offset applied) closest to the tangent vector v; turn = angle.
  Eigen::Vector3d match(int f, const Eigen::Vector3d& v, double* turn) const {
    const double theta = std::atan2(v.dot(ops_.frames().y_axis(f)), v.dot(ops_.frames().x_axis(f)));
    const double base = base_angle_[f] + offset_;
    const double k = std::round((theta - base) * n_ / kTwoPi);
    const double a = base + kTwoPi * k / n_;
    if (turn) *turn = std::abs(std::remainder(theta - a, kTwoPi));
    return direction(f, a);
  }
  /// Hinge transport of tangent vector v of face f into face g across their shared edge (vertices a, b).
  Eigen::Vector3d transport(int f, int g, int a, int b, const Eigen::Vector3d& v) const {
    const auto& P = mesh_.positions();
    const Eigen::Vector3d e = (P.row(b) - P.row(a)).transpose().normalized();
    const Eigen::Vector3d pf = mesh_.face_normal(f).cross(e), pg = mesh_.face_normal(g).cross(e);
    return v.dot(e) * e + v.dot(pf) * pg;
  }
  double density_at(const Location& l) const {
    if (p_.density.empty()) return 1.0;
    double rho;
    if (p_.density_per_vertex) {
      const auto& T = mesh_.faces();
      rho = l.bary[0] * p_.density[T(l.face, 0)] + l.bary[1] * p_.density[T(l.face, 1)] +
            l.bary[2] * p_.density[T(l.face, 2)];
    } else {
      rho = p_.density[l.face];
    }
    return std::max(std::min(rho, 1.0), p_.min_density);
  }
  double dsep_at(const Location& l) const { return p_.separation / density_at(l); }

  /// Moves `loc` along direction m (unit, in the face plane) by at most `max_t`. Returns the distance
  /// moved; *exit_corner is the corner opposite the edge reached (-1 if the move ended inside the face).
  double advance(Location& loc, const Eigen::Vector3d& m, double max_t, int* exit_corner) const {
    const int f = loc.face;
    std::array<double, 3> dl;
    double t_exit = std::numeric_limits<double>::infinity();
    int ci = -1;
    for (int i = 0; i < 3; ++i) {
      dl[i] = grad_[f][i].dot(m);
      if (dl[i] < 0.0) {
        const double t = std::max(loc.bary[i], 0.0) / -dl[i];
        if (t < t_exit) {
          t_exit = t;
          ci = i;
        }
      }
    }
    double t = max_t;
    *exit_corner = -1;
    if (ci >= 0 && t_exit <= max_t) {
      t = t_exit;
      *exit_corner = ci;
    }
    double sum = 0.0;
    for (int i = 0; i < 3; ++i) {
      loc.bary[i] = (i == *exit_corner) ? 0.0 : std::max(loc.bary[i] + t * dl[i], 0.0);
      sum += loc.bary[i];
    }
    if (!(sum > 0.0) || !std::isfinite(sum)) {  // cannot happen for valid input; stay safe
      loc.bary = {{1.0 / 3, 1.0 / 3, 1.0 / 3}};
      *exit_corner = -1;
      return 0.0;
    }
    for (int i = 0; i < 3; ++i) loc.bary[i] /= sum;
    return t;
  }
  /// Moves loc across the edge opposite corner ci of its face into the neighbour (bary mapped by vertex).
  /// Returns false (loc unchanged) at a boundary / cut / inactive neighbour. *a, *b: the edge's vertices.
  bool cross(Location& loc, int ci, int* a, int* b, int* entry_corner) const {
    const int f = loc.face, g = nbr_[f][ci];
    if (g < 0 || !active_[g]) return false;
    const auto& T = mesh_.faces();
    Location next;
    next.face = g;
    next.bary = {{0.0, 0.0, 0.0}};
    *entry_corner = -1;
    for (int j = 0; j < 3; ++j) {
      const int v = T(g, j);
      bool found = false;
      for (int i = 0; i < 3; ++i)
        if (i != ci && T(f, i) == v) {
          next.bary[j] = loc.bary[i];
          found = true;
        }
      if (!found) *entry_corner = j;
    }
    *a = T(f, (ci + 1) % 3);
    *b = T(f, (ci + 2) % 3);
    loc = next;
    return true;
  }

  // ---- proximity tests ----
  bool too_close(const PointSet& ps, const Eigen::Vector3d& p, double r, int self, double arc,
                 double window) const {
    const double r2 = r * r;
    return ps.any_in_ball(p, r, [&](int id) {
      if ((ps.pos[id] - p).squaredNorm() >= r2) return false;
      return ps.stroke[id] != self || std::abs(ps.arc[id] - arc) > window;
    });
  }

  // ---- tracing ----
  /// Traces from `start` (already accepted and inserted) along sign * field direction `dir`.
  void trace_half(PointSet& ps, int stroke_id, Location loc, Eigen::Vector3d dir, double sign, double budget,
                  HalfStroke& hs) {
    const double h = p_.step_ratio * p_.separation;
    hs.points.push_back(position(loc));
    hs.faces.push_back(loc.face);
    hs.dirs.push_back(dir);
    int zero_moves = 0;
    while (true) {
      if (hs.length >= budget) break;
      if (static_cast<long long>(hs.points.size()) >= half_cap_) break;
      if (total_points_ >= p_.max_total_points) {
        stats_.truncated = true;
        break;
      }
      const Eigen::Vector3d m = sign * dir;
      int ci;
      const double t = advance(loc, m, std::min(h, budget - hs.length), &ci);
      const Eigen::Vector3d q = position(loc);
      if (t > 1e-9 * h) {
        const double arc = sign * (hs.length + t);
        const double ds = dsep_at(loc);
        if (too_close(ps, q, p_.test_ratio * ds, stroke_id, arc, 2.0 * ds)) break;
        hs.points.push_back(q);
        hs.faces.push_back(loc.face);
        hs.dirs.push_back(dir);
        hs.length += t;
        ps.add(q, stroke_id, arc, dir);
        ++total_points_;
        zero_moves = 0;
      } else {
        if (ci < 0) break;  // no progress and no edge: degenerate direction
        hs.points.back() = q;  // snap the last point onto the edge (moved by < 1e-9 h)
        if (++zero_moves > kMaxZeroMoves) break;
      }
      if (ci < 0) continue;
      int a, b, entry;
      const int f = loc.face;
      Location next = loc;
      if (!cross(next, ci, &a, &b, &entry)) break;
      const int g = next.face;
      if (!traceable_[g] || blocked_[g]) break;
      double turn;
      const Eigen::Vector3d nd = match(g, transport(f, g, a, b, dir), &turn);
      if (turn > p_.max_turn) break;
      if (grad_[g][entry].dot(sign * nd) <= 0.0) break;  // the field flows back across this edge
      loc = next;
      dir = nd;
      hs.faces.back() = g;
      hs.dirs.back() = dir;
    }
  }

  /// Traces a stroke through the seed; returns true if kept (points stay in ps), false if discarded.
  bool trace_stroke(PointSet& ps, const Location& seed, const Eigen::Vector3d& dir, int family,
                    Streamlines& out) {
    const int id = static_cast<int>(out.strokes.size());
    const size_t first_point = ps.pos.size();
    const Eigen::Vector3d p0 = position(seed);
    ps.add(p0, id, 0.0, dir);
    ++total_points_;
    HalfStroke fwd, bwd;
    const double L = p_.max_length;
    trace_half(ps, id, seed, dir, 1.0, std::isfinite(L) ? 0.5 * L : L, fwd);
    trace_half(ps, id, seed, dir, -1.0, std::isfinite(L) ? L - fwd.length : L, bwd);
    const double length = fwd.length + bwd.length;
    const size_t npts = fwd.points.size() + bwd.points.size() - 1;
    if (npts < 2 || length < p_.min_length || length <= 0.0) {
      while (ps.pos.size() > first_point) ps.pop();
      total_points_ -= static_cast<long long>(npts);
      ++stats_.num_discarded;
      return false;
    }
    Stroke s;
    s.family = family;
    s.length = length;
    s.points.reserve(npts);
    s.faces.reserve(npts);
    // Backward half reversed: segment bwd[i] -> bwd[i-1] lies in the face recorded at bwd[i-1].
    for (size_t i = bwd.points.size() - 1; i >= 1; --i) {
      s.points.push_back(bwd.points[i]);
      s.faces.push_back(bwd.faces[i - 1]);
    }
    for (size_t i = 0; i < fwd.points.size(); ++i) {
      s.points.push_back(fwd.points[i]);
      s.faces.push_back(fwd.faces[i]);
    }
    // Seed directions for the queue: per point, the field direction of the point's segment face.
    std::vector<Eigen::Vector3d> dirs;
    dirs.reserve(npts);
    for (size_t i = bwd.points.size() - 1; i >= 1; --i) dirs.push_back(bwd.dirs[i - 1]);
    for (size_t i = 0; i < fwd.points.size(); ++i) dirs.push_back(fwd.dirs[i]);
    // Barycentric locations are needed for seeding; recompute them from the faces (cheap, exact enough).
    queue_.push_back({static_cast<int>(out.strokes.size()), std::move(dirs)});
    stats_.num_points += static_cast<long long>(npts);
    out.strokes.push_back(std::move(s));
    return true;
  }

  /// Barycentric coordinates of p in face f (p assumed on the face plane).
  Location locate(int f, const Eigen::Vector3d& p) const {
    const auto& P = mesh_.positions();
    const auto& T = mesh_.faces();
    Location l;
    l.face = f;
    double sum = 0.0;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d c = P.row(T(f, (i + 1) % 3)).transpose();
      l.bary[i] = std::max(0.0, grad_[f][i].dot(p - c));
      sum += l.bary[i];
    }
    for (int i = 0; i < 3; ++i) l.bary[i] /= sum;
    return l;
  }

  /// Straight walk in the tangent plane from loc along w for distance `dist`, carrying the tangent vector
  /// v. Returns false at a boundary / inactive face or after kMaxWalkFaces crossings.
  bool walk(Location& loc, Eigen::Vector3d w, Eigen::Vector3d& v, double dist) const {
    double left = dist;
    int zero_moves = 0;
    for (int crossings = 0; crossings < kMaxWalkFaces; ++crossings) {
      int ci;
      const double t = advance(loc, w, left, &ci);
      left -= t;
      if (ci < 0) return true;
      zero_moves = t > 1e-12 * dist ? 0 : zero_moves + 1;
      if (zero_moves > kMaxZeroMoves) return false;
      int a, b, entry;
      const int f = loc.face;
      if (!cross(loc, ci, &a, &b, &entry)) return false;
      w = transport(f, loc.face, a, b, w).normalized();
      v = transport(f, loc.face, a, b, v);
      if (left <= 0.0) return true;
    }
    return false;
  }

  bool seed_ok(const PointSet& ps, const Location& l, Eigen::Vector3d* q) const {
    if (!traceable_[l.face] || blocked_[l.face]) return false;
    *q = position(l);
    return !too_close(ps, *q, p_.seed_ratio * dsep_at(l), -1, 0.0, 0.0);
  }

  /// Direction (3D) of the sample point of `ps` nearest to q within radius r; false if there is none.
  static bool nearest_direction(const PointSet& ps, const Eigen::Vector3d& q, double r, Eigen::Vector3d* d) {
    double best = r * r;
    int id_best = -1;
    ps.any_in_ball(q, r, [&](int id) {
      const double d2 = (ps.pos[id] - q).squaredNorm();
      if (d2 < best) {
        best = d2;
        id_best = id;
      }
      return false;
    });
    if (id_best < 0) return false;
    *d = ps.dir[id_best];
    return true;
  }

  /// Start direction of a stroke seeded at a face centroid without a parent stroke: for the cross family,
  /// perpendicular to the nearest main-family stroke within 3 d_sep; otherwise along the nearest stroke of
  /// the same family within 3 d_sep; otherwise the direction k = family. Keeps families locally coherent
  /// for n = 4 (where a family cannot be defined globally).
  Eigen::Vector3d seed_direction(const PointSet& own, const Location& l, const Eigen::Vector3d& q, int k0) const {
    const int f = l.face;
    const double r = 3.0 * dsep_at(l);
    Eigen::Vector3d d;
    if (offset_ != 0.0 && !sets_.empty() && nearest_direction(*sets_[0], q, r, &d)) {
      const Eigen::Vector3d t = d - d.dot(mesh_.face_normal(f)) * mesh_.face_normal(f);
      if (t.norm() > 1e-6 * d.norm()) return match(f, mesh_.face_normal(f).cross(t), nullptr);
    }
    if (nearest_direction(own, q, r, &d)) {
      const Eigen::Vector3d t = d - d.dot(mesh_.face_normal(f)) * mesh_.face_normal(f);
      if (t.norm() > 1e-6 * d.norm()) return match(f, t, nullptr);
    }
    return direction(f, base_angle_[f] + offset_ + kTwoPi * k0 / n_);
  }

  void trace_family(int family, Streamlines& out) {
    offset_ = family == 0 ? 0.0 : 0.5 * M_PI;
    sets_.push_back(std::make_unique<PointSet>(p_.separation));  // fine cells of d_sep: a d_test ball meets <= 8
    PointSet& ps = *sets_.back();
    queue_.clear();
    // Pseudo-random face order (hand-written Fisher-Yates: portable and deterministic for the seed).
    std::mt19937_64 rng(p_.seed * 0x9E3779B97F4A7C15ULL + static_cast<std::uint64_t>(family) * 0xD1B54A32D192ED03ULL +
                        0x2545F4914F6CDD1DULL);
    std::vector<int> order;
    for (int f = 0; f < mesh_.num_faces(); ++f)
      if (traceable_[f] && !blocked_[f]) order.push_back(f);
    for (size_t i = order.size(); i > 1; --i) std::swap(order[i - 1], order[rng() % i]);
    const int k0 = k0_;
    size_t next_face = 0, qi = 0, qpoint = 0;
    int qside = 0;
    while (!stats_.truncated) {
      bool traced = false;
      // 1) seed candidates next to accepted strokes (breadth-first over strokes)
      while (qi < queue_.size() && !traced && !stats_.truncated) {
        const Stroke& s = out.strokes[queue_[qi].stroke];
        if (qpoint >= s.points.size()) {
          ++qi;
          qpoint = 0;
          qside = 0;
          continue;
        }
        const int f = s.faces[qpoint];
        const Eigen::Vector3d d = queue_[qi].dirs[qpoint];
        const Eigen::Vector3d p = s.points[qpoint];
        const double side = qside == 0 ? 1.0 : -1.0;
        if (++qside == 2) {
          qside = 0;
          ++qpoint;
        }
        ++stats_.num_candidates;
        Location loc = locate(f, p);
        Eigen::Vector3d carried = d;
        if (!walk(loc, side * mesh_.face_normal(f).cross(d).normalized(), carried, dsep_at(loc))) continue;
        Eigen::Vector3d q;
        if (!seed_ok(ps, loc, &q)) continue;
        const Eigen::Vector3d sd = match(loc.face, carried, nullptr);
        traced = trace_stroke(ps, loc, sd, family, out) || traced;
      }
      if (traced) continue;
      if (qi < queue_.size()) continue;
      // 2) otherwise the next face in the pseudo-random order
      if (next_face >= order.size()) break;
      const int f = order[next_face++];
      ++stats_.num_candidates;
      Location loc;
      loc.face = f;
      Eigen::Vector3d q;
      if (!seed_ok(ps, loc, &q)) continue;
      trace_stroke(ps, loc, seed_direction(ps, loc, q, k0), family, out);
    }
    // Coverage: area fraction of traceable faces whose centroid has a sample point within d_sep.
    double covered = 0.0, total = 0.0;
    for (int f = 0; f < mesh_.num_faces(); ++f) {
      if (!traceable_[f]) continue;
      Location l;
      l.face = f;
      const double a = mesh_.face_area(f);
      total += a;
      const Eigen::Vector3d c = position(l);
      const double r = dsep_at(l);
      if (ps.any_in_ball(c, r, [&](int id) { return (ps.pos[id] - c).squaredNorm() < r * r; })) covered += a;
    }
    stats_.coverage.push_back(total > 0 ? covered / total : 0.0);
  }

  struct QueuedStroke {
    int stroke;
    std::vector<Eigen::Vector3d> dirs;
  };

  const FieldOperators& ops_;
  const TriangleMesh& mesh_;
  const ComplexVector& field_;
  const StreamlineParams& p_;
  int n_;   // symmetry used for matching (2 for a combed 4-field)
  int k0_;  // direction index of seeds without a neighbour
  double offset_ = 0.0;
  std::vector<std::array<int, 3>> nbr_;
  std::vector<std::array<Eigen::Vector3d, 3>> grad_;
  std::vector<char> active_, traceable_, blocked_;
  std::vector<double> base_angle_;
  std::vector<QueuedStroke> queue_;
  std::vector<std::unique_ptr<PointSet>> sets_;  // per family traced so far
  StreamlineStats stats_;
  long long total_points_ = 0;
  long long half_cap_ = 0;

 public:
  void set_half_cap(long long c) { half_cap_ = c; }
};

void check(bool ok, const std::string& what) {
  if (!ok) throw ParameterError(what);
}

}  // namespace

Streamlines trace_streamlines(const FieldOperators& ops, const ComplexVector& field, const StreamlineParams& p) {
  const TriangleMesh& mesh = ops.mesh();
  if (field.size() != mesh.num_faces())
    throw InputError("field must have one value per face (" + std::to_string(mesh.num_faces()) + "), got " +
                     std::to_string(field.size()));
  check(std::isfinite(p.separation) && p.separation > 0.0, "separation must be a positive finite length");
  check(p.test_ratio > 0.0 && p.test_ratio <= 1.0, "test_ratio must be in (0, 1]");
  check(p.step_ratio > 0.0 && p.step_ratio <= 1.0, "step_ratio must be in (0, 1]");
  check(p.seed_ratio >= p.test_ratio && p.seed_ratio <= 1.0, "seed_ratio must be in [test_ratio, 1]");
  check(!(p.max_length <= 0.0) && !std::isnan(p.max_length), "max_length must be positive");
  check(std::isfinite(p.min_length) && p.min_length >= 0.0, "min_length must be a finite length >= 0");
  check(p.max_turn > 0.0 && p.max_turn <= M_PI, "max_turn must be in (0, pi] radians");
  check(p.min_density > 0.0 && p.min_density <= 1.0, "min_density must be in (0, 1]");
  check(p.max_total_points >= 1 && p.max_points_per_stroke >= 2, "point caps must be positive");
  // Keep the spatial hash meaningful: at most ~2^20 cells of d_test along the bounding box.
  check(p.separation * p.test_ratio >= mesh.bounding_box_diagonal() * 1e-6,
        "separation is too small relative to the mesh size (below 2e-6 of the bounding-box diagonal)");
  if (!p.density.empty()) {
    const size_t want = p.density_per_vertex ? static_cast<size_t>(mesh.num_vertices())
                                             : static_cast<size_t>(mesh.num_faces());
    if (p.density.size() != want)
      throw InputError(std::string("density must have one value per ") + (p.density_per_vertex ? "vertex" : "face") +
                       " (" + std::to_string(want) + "), got " + std::to_string(p.density.size()));
    for (double d : p.density)
      if (!std::isfinite(d)) throw InputError("density values must be finite");
  }
  Tracer tracer(ops, field, p);
  tracer.set_half_cap(std::max<long long>(2, p.max_points_per_stroke / 2));
  return tracer.run();
}

}  // namespace nfield
