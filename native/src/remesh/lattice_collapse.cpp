#include "nfield/remesh/lattice_collapse.hpp"

#include <algorithm>
#include <numeric>
#include <unordered_map>

namespace nfield::remesh {

namespace {

inline long long pair_key(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<long long>(a) << 32) | static_cast<unsigned int>(b);
}

/// R^k v for real vectors (R the quarter turn (x, y) -> (-y, x)).
Eigen::Vector2d rotate_quarter_real(const Eigen::Vector2d& v, int k) {
  switch (((k % 4) + 4) % 4) {
    case 0: return v;
    case 1: return {-v.y(), v.x()};
    case 2: return -v;
    default: return {v.y(), -v.x()};
  }
}

/// Fixed-component mask written in a frame turned by k quarter turns: an odd turn swaps the components.
inline unsigned char rotate_mask(unsigned char m, int k) {
  return (k & 1) ? static_cast<unsigned char>(((m & 1) << 1) | ((m >> 1) & 1)) : m;
}

/// An edge of the collapsing mesh seen from one end x towards the other y: D (y's lattice point relative
/// to x's, x's frame), k (coordinates in y's frame read R^-k c in x's frame), the summed real mismatch and
/// the fixed components, all in x's frame.
struct Directed {
  Eigen::Vector2i D;
  int k;
  Eigen::Vector2d mismatch_sum;
  unsigned char fixed;
};

Directed reversed(const Directed& d) {
  return {-rotate_quarter(d.D, d.k), (4 - d.k) % 4, -rotate_quarter_real(d.mismatch_sum, d.k), rotate_mask(d.fixed, d.k)};
}

struct Record {
  int a = -1, b = -1;  ///< current endpoints; the data is the edge seen from a
  Directed data{};
  int count = 0;       ///< fine edges merged into it (the mismatch is their sum)
  bool alive = false;
  Directed from(int x) const { return x == a ? data : reversed(data); }
};

}  // namespace

CoarseLattice collapse_zero_offsets(const RemeshSurface& fine, const LatticeOffsets& o, const std::vector<unsigned char>& fixed,
                                    const std::vector<Vec3>& lattice_points) {
  const int V = fine.num_vertices();
  const int T = static_cast<int>(fine.triangles.size());
  const int E = static_cast<int>(fine.edges.size());
  std::vector<Record> rec(E);
  std::unordered_map<long long, int> key_of;
  key_of.reserve(2 * static_cast<size_t>(E));
  for (int e = 0; e < E; ++e) {
    rec[e].a = fine.edges[e][0];
    rec[e].b = fine.edges[e][1];
    rec[e].data = {o.offset[e], o.turns[e], o.mismatch[e], fixed.empty() ? static_cast<unsigned char>(0) : fixed[e]};
    rec[e].count = 1;
    rec[e].alive = true;
    key_of[pair_key(rec[e].a, rec[e].b)] = e;
  }
  auto record_of = [&](int x, int y) {
    auto it = key_of.find(pair_key(x, y));
    return it == key_of.end() ? -1 : it->second;
  };
  std::vector<std::array<int, 3>> tri = fine.triangles;
  std::vector<char> alive(T, 1);
  std::vector<std::vector<int>> around(V);
  for (int t = 0; t < T; ++t)
    for (int c = 0; c < 3; ++c) around[tri[t][c]].push_back(t);
  std::vector<int> parent(V), rel(V, 0);
  std::iota(parent.begin(), parent.end(), 0);

  // Neighbours of x (sorted) over its live triangles; also drops dead triangles from its list.
  auto neighbours = [&](int x, std::vector<int>& out) {
    auto& list = around[x];
    list.erase(std::remove_if(list.begin(), list.end(), [&](int t) { return !alive[t]; }), list.end());
    out.clear();
    for (int t : list)
      for (int c = 0; c < 3; ++c)
        if (tri[t][c] != x) out.push_back(tri[t][c]);
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
  };
  // Regular (orientation index 0) with zero residual, around (x, y, z).
  auto consistent = [&](int x, int y, int z) {
    const int r0 = record_of(x, y), r1 = record_of(y, z), r2 = record_of(z, x);
    if (r0 < 0 || r1 < 0 || r2 < 0) return false;
    const Directed d0 = rec[r0].from(x), d1 = rec[r1].from(y), d2 = rec[r2].from(z);
    if ((d0.k + d1.k + d2.k) % 4 != 0) return false;
    const Eigen::Vector2i r = d0.D + rotate_quarter(d1.D + rotate_quarter(d2.D, -d1.k), -d0.k);
    return r == Eigen::Vector2i::Zero();
  };

  std::vector<int> nb_a, nb_b, shared, thirds, joined;
  std::vector<int> tris_ab;
  auto try_collapse = [&](int e) {
    Record& r = rec[e];
    const int a = r.a, b = r.b;
    tris_ab.clear();
    thirds.clear();
    neighbours(a, nb_a);
    neighbours(b, nb_b);
    for (int t : around[b]) {
      const auto& x = tri[t];
      if (x[0] != a && x[1] != a && x[2] != a) continue;
      tris_ab.push_back(t);
      thirds.push_back(x[0] != a && x[0] != b ? x[0] : (x[1] != a && x[1] != b ? x[1] : x[2]));
    }
    if (tris_ab.empty() || tris_ab.size() > 2) return false;
    for (size_t i = 0; i < tris_ab.size(); ++i)
      if (!consistent(a, b, thirds[i])) return false;
    // Link condition: the common neighbours are exactly the third corners.
    shared.clear();
    std::set_intersection(nb_a.begin(), nb_a.end(), nb_b.begin(), nb_b.end(), std::back_inserter(shared));
    std::sort(thirds.begin(), thirds.end());
    if (shared != thirds) return false;
    // An interior edge between two boundary vertices would pinch the surface (a fan is a boundary fan when
    // it has more neighbours than triangles).
    const bool a_boundary = nb_a.size() != around[a].size(), b_boundary = nb_b.size() != around[b].size();
    if (tris_ab.size() == 2 && a_boundary && b_boundary) return false;
    joined.clear();
    std::set_union(nb_a.begin(), nb_a.end(), nb_b.begin(), nb_b.end(), std::back_inserter(joined));
    if (static_cast<int>(joined.size()) - 2 < 3) return false;

    // Collapse b into a.
    const Directed ab = r.from(a);
    for (int t : tris_ab) alive[t] = 0;
    for (int c : nb_b) {
      if (c == a) continue;
      const int rb = record_of(b, c);
      const Directed bc = rec[rb].from(b);
      const Eigen::Vector2d mean_bc = bc.mismatch_sum / rec[rb].count;
      Directed ac{rotate_quarter(bc.D, -ab.k), (ab.k + bc.k) % 4,
                  rec[rb].count * (ab.mismatch_sum / r.count + rotate_quarter_real(mean_bc, -ab.k)),
                  rotate_mask(bc.fixed, ab.k)};
      key_of.erase(pair_key(b, c));
      const int rac = record_of(a, c);
      if (rac >= 0) {  // c is a third corner: the two edges become one (equal offsets, checked above)
        Record& into = rec[rac];
        const Directed add = into.a == a ? ac : reversed(ac);
        into.data.mismatch_sum += add.mismatch_sum;
        into.data.fixed |= add.fixed;
        into.count += rec[rb].count;
        rec[rb].alive = false;
      } else {
        rec[rb].a = a;
        rec[rb].b = c;
        rec[rb].data = ac;
        key_of[pair_key(a, c)] = rb;
      }
    }
    key_of.erase(pair_key(a, b));
    r.alive = false;
    for (int t : around[b]) {
      if (!alive[t]) continue;
      for (int c = 0; c < 3; ++c)
        if (tri[t][c] == b) tri[t][c] = a;
      around[a].push_back(t);
    }
    around[b].clear();
    parent[b] = a;
    rel[b] = ab.k;
    return true;
  };

  CoarseLattice out;
  for (int pass = 0; pass < 16; ++pass) {
    int done = 0;
    for (int e = 0; e < E; ++e)
      if (rec[e].alive && rec[e].data.D == Eigen::Vector2i::Zero() && try_collapse(e)) ++done;
    out.collapsed_edges += done;
    if (done == 0) break;
  }

  // Roots and turns (T_u: the sum of the turns along the chain to the root).
  out.vertex_of.assign(V, -1);
  out.turn_of.assign(V, 0);
  std::vector<int> root(V), turn(V);
  for (int v = 0; v < V; ++v) {
    int x = v, k = 0;
    while (parent[x] != x) {
      k += rel[x];
      x = parent[x];
    }
    root[v] = x;
    turn[v] = k % 4;
  }
  std::vector<int> index(V, -1);
  RemeshSurface& cs = out.surface;
  for (int t = 0; t < T; ++t) {
    if (!alive[t]) continue;
    std::array<int, 3> ct;
    for (int c = 0; c < 3; ++c) {
      const int x = tri[t][c];
      if (index[x] < 0) {
        index[x] = cs.num_vertices();
        cs.positions.push_back(lattice_points[x]);
        cs.source_vertex.push_back(x);
      }
      ct[c] = index[x];
    }
    cs.triangles.push_back(ct);
    cs.source_triangle.push_back(fine.source_triangle.empty() ? t : fine.source_triangle[t]);
  }
  for (int v = 0; v < V; ++v) {
    out.vertex_of[v] = index[root[v]];
    out.turn_of[v] = static_cast<signed char>(turn[v]);
  }
  finalize_surface(cs);
  const int CE = static_cast<int>(cs.edges.size());
  out.offsets.offset.resize(CE);
  out.offsets.mismatch.resize(CE);
  out.offsets.turns.resize(CE);
  out.fixed.assign(CE, 0);
  for (int e = 0; e < CE; ++e) {
    const int x = cs.source_vertex[cs.edges[e][0]], y = cs.source_vertex[cs.edges[e][1]];
    const int r = record_of(x, y);
    const Directed d = rec[r].from(x);
    out.offsets.offset[e] = d.D;
    out.offsets.turns[e] = static_cast<signed char>(d.k);
    out.offsets.mismatch[e] = d.mismatch_sum / rec[r].count;
    out.fixed[e] = d.fixed;
  }
  return out;
}

int expand_offsets(const RemeshSurface& fine, const CoarseLattice& coarse, LatticeOffsets& o) {
  const RemeshSurface& cs = coarse.surface;
  auto edge_between = [&](int a, int b) {
    for (int k = cs.adjacency_offsets[a]; k < cs.adjacency_offsets[a + 1]; ++k)
      if (cs.adjacency[k] == b) return cs.adjacency_edge[k];
    return -1;
  };
  int changed = 0;
  for (size_t e = 0; e < fine.edges.size(); ++e) {
    const int u = fine.edges[e][0], v = fine.edges[e][1];
    const int A = coarse.vertex_of[u], C = coarse.vertex_of[v];
    if (A < 0 || C < 0 || A == C) continue;
    const int ce = edge_between(A, C);
    if (ce < 0) continue;
    const Eigen::Vector2i D = rotate_quarter(coarse.offsets.directed_offset(ce, A < C), coarse.turn_of[u]);
    if (D != o.offset[e]) {
      o.offset[e] = D;
      ++changed;
    }
  }
  return changed;
}

}  // namespace nfield::remesh
