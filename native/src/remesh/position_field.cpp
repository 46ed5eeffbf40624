#include "nfield/remesh/position_field.hpp"

#include <cmath>

#include "nfield/errors.hpp"

namespace nfield::remesh {

namespace {

/// splitmix64: a small, fully specified generator (std:: distributions differ between libraries, and the
/// result must be the same for a seed everywhere).
struct SplitMix64 {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  double uniform() { return (next() >> 11) * (1.0 / 9007199254740992.0); }  // [0, 1)
};

void sweep(HierarchyLevel& L) {
  const int V = L.size();
  for (int i = 0; i < V; ++i) {
    const Vec3& v_i = L.v[i];
    const Vec3& n_i = L.n[i];
    const Vec3& q_i = L.q[i];
    Vec3 p_i = L.p[i];
    double weight_sum = 0;
    for (int k = L.adjacency_offsets[i]; k < L.adjacency_offsets[i + 1]; ++k) {
      const int j = L.adjacency[k];
      const double w = L.adjacency_weight[k];
      const Vec3 q_j = compatible_direction(q_i, L.q[j], L.n[j]);
      const LatticePair pair = closest_lattice_pair(v_i, n_i, q_i, p_i, L.v[j], L.n[j], q_j, L.p[j], L.pair_spacing(i, j));
      p_i = (pair.point_i * weight_sum + pair.point_j * w) / (weight_sum + w);
      weight_sum += w;
      p_i -= n_i * n_i.dot(p_i - v_i);
    }
    p_i = apply_position_constraint(L, i, p_i);
    L.p[i] = nearest_lattice_point(p_i, q_i, n_i, v_i, L.spacing[i]);
  }
}

}  // namespace

Vec3 apply_position_constraint(const HierarchyLevel& L, int i, const Vec3& p) {
  const char kind = L.constraint_kind.empty() ? 0 : L.constraint_kind[i];
  if (kind == 0) return p;
  const Vec3& n = L.n[i];
  const Vec3& c = L.constraint_point[i];
  if (kind >= 2) return c - n * n.dot(c - L.v[i]);
  const Vec3 q = L.q[i], t = n.cross(q);
  const Vec3& d = L.constraint_dir[i];
  const Vec3 axis = std::abs(q.dot(d)) >= std::abs(t.dot(d)) ? q : t;
  const Vec3 perp = n.cross(axis);
  return p + perp * perp.dot(c - p);
}

void optimise_positions(std::vector<HierarchyLevel>& levels, const PositionFieldOptions& options,
                        const Progress& progress) {
  const double s = options.scale;
  if (!(s > 0) || !std::isfinite(s)) throw ParameterError("position field: the lattice spacing must be positive");
  for (auto& L : levels) {
    if (L.spacing.empty()) L.spacing.assign(L.size(), s);
    for (double h : L.spacing)
      if (!(h > 0) || !std::isfinite(h)) throw ParameterError("position field: the lattice spacing must be positive");
  }
  SplitMix64 rng{options.seed * 0x2545F4914F6CDD1DULL + 0x1234567ULL};
  // Work is proportional to the number of vertices per level.
  double total = 0;
  for (const auto& L : levels) total += static_cast<double>(L.size()) * options.iterations;
  double done = 0;
  auto report = [&]() {
    if (progress && !progress(total > 0 ? done / total : 1.0)) throw Cancelled("quad remeshing cancelled");
  };
  HierarchyLevel& top = levels.back();
  top.p.resize(top.size());
  for (int i = 0; i < top.size(); ++i) {
    const Vec3 t = top.n[i].cross(top.q[i]);
    const double a = rng.uniform() - 0.5, b = rng.uniform() - 0.5;
    const double h = top.spacing[i];
    top.p[i] = nearest_lattice_point(top.v[i] + h * (a * top.q[i] + b * t), top.q[i], top.n[i], top.v[i], h);
  }
  for (int l = static_cast<int>(levels.size()) - 1; l >= 0; --l) {
    HierarchyLevel& L = levels[l];
    if (l + 1 < static_cast<int>(levels.size())) {
      const HierarchyLevel& C = levels[l + 1];
      L.p.resize(L.size());
      for (int i = 0; i < L.size(); ++i) {
        const Vec3& pc = C.p[L.parent[i]];
        const Vec3 p = pc - L.n[i] * L.n[i].dot(pc - L.v[i]);
        L.p[i] = nearest_lattice_point(p, L.q[i], L.n[i], L.v[i], L.spacing[i]);
      }
    }
    for (int it = 0; it < options.iterations; ++it) {
      sweep(L);
      done += L.size();
      report();
    }
  }
}

}  // namespace nfield::remesh
