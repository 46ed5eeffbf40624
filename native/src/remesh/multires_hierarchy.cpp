#include "nfield/remesh/multires_hierarchy.hpp"

#include <algorithm>
#include <tuple>

namespace nfield::remesh {

namespace {

HierarchyLevel coarsen(HierarchyLevel& fine) {
  const int V = fine.size();
  struct Candidate {
    double score;
    int i, j;
  };
  std::vector<Candidate> candidates;
  for (int i = 0; i < V; ++i)
    for (int k = fine.adjacency_offsets[i]; k < fine.adjacency_offsets[i + 1]; ++k) {
      const int j = fine.adjacency[k];
      if (j <= i) continue;
      const double area = fine.area[i] + fine.area[j];
      candidates.push_back({fine.n[i].dot(fine.n[j]) / (area > 0 ? area : 1.0), i, j});
    }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
  fine.parent.assign(V, -1);
  HierarchyLevel coarse;
  auto add_parent = [&](std::initializer_list<int> children) {
    const int c = coarse.size();
    Vec3 v = Vec3::Zero(), n = Vec3::Zero(), q = Vec3::Zero();
    double area = 0, spacing = 0;
    bool same_spacing = true;  // then the parent takes it exactly (a uniform lattice stays bit-identical)
    int first = -1;
    char kind = 0;
    Vec3 cpoint = Vec3::Zero(), cdir = Vec3::Zero();
    for (int child : children) {
      fine.parent[child] = c;
      const double w = fine.area[child] > 0 ? fine.area[child] : 1e-300;
      v += w * fine.v[child];
      n += w * fine.n[child];
      if (!fine.spacing.empty()) {
        spacing += w * fine.spacing[child];
        same_spacing = same_spacing && fine.spacing[child] == fine.spacing[*children.begin()];
      }
      area += fine.area[child];
      if (first < 0) {
        first = child;
        q = w * fine.q[child];
      } else {
        q += w * compatible_direction(fine.q[first], fine.q[child], fine.n[child]);
      }
      if (fine.constraint_kind[child] > kind) {
        kind = fine.constraint_kind[child];
        cpoint = fine.constraint_point[child];
        cdir = fine.constraint_dir[child];
      }
    }
    double total = 0;
    for (int child : children) total += fine.area[child] > 0 ? fine.area[child] : 1e-300;
    v /= total;
    n = n.norm() > 0 ? Vec3(n.normalized()) : fine.n[first];
    q -= n * n.dot(q);
    if (q.norm() <= 0) q = n.unitOrthogonal();
    coarse.v.push_back(v);
    coarse.n.push_back(n);
    coarse.q.push_back(q.normalized());
    coarse.area.push_back(area);
    if (!fine.spacing.empty()) coarse.spacing.push_back(same_spacing ? fine.spacing[first] : spacing / total);
    coarse.constraint_kind.push_back(kind);
    coarse.constraint_point.push_back(cpoint);
    coarse.constraint_dir.push_back(cdir);
  };
  for (const Candidate& c : candidates)
    if (fine.parent[c.i] < 0 && fine.parent[c.j] < 0) add_parent({c.i, c.j});
  for (int i = 0; i < V; ++i)
    if (fine.parent[i] < 0) add_parent({i});

  // Coarse adjacency: summed weights of fine edges between different parents.
  std::vector<std::tuple<int, int, double>> links;
  for (int i = 0; i < V; ++i)
    for (int k = fine.adjacency_offsets[i]; k < fine.adjacency_offsets[i + 1]; ++k) {
      const int a = fine.parent[i], b = fine.parent[fine.adjacency[k]];
      if (a != b) links.emplace_back(a, b, fine.adjacency_weight[k]);
    }
  std::sort(links.begin(), links.end(), [](const auto& x, const auto& y) {
    return std::get<0>(x) != std::get<0>(y) ? std::get<0>(x) < std::get<0>(y) : std::get<1>(x) < std::get<1>(y);
  });
  const int C = coarse.size();
  coarse.adjacency_offsets.assign(C + 1, 0);
  for (size_t k = 0; k < links.size();) {
    size_t e = k;
    double w = 0;
    while (e < links.size() && std::get<0>(links[e]) == std::get<0>(links[k]) && std::get<1>(links[e]) == std::get<1>(links[k]))
      w += std::get<2>(links[e++]);
    coarse.adjacency.push_back(std::get<1>(links[k]));
    coarse.adjacency_weight.push_back(w);
    ++coarse.adjacency_offsets[std::get<0>(links[k]) + 1];
    k = e;
  }
  for (int c = 0; c < C; ++c) coarse.adjacency_offsets[c + 1] += coarse.adjacency_offsets[c];
  return coarse;
}

}  // namespace

void build_hierarchy(std::vector<HierarchyLevel>& levels, int min_vertices) {
  levels.resize(1);
  while (levels.back().size() > min_vertices && levels.size() < 64) {
    HierarchyLevel coarse = coarsen(levels.back());
    if (coarse.size() > 0.9 * levels.back().size()) {
      levels.back().parent.clear();
      break;
    }
    levels.push_back(std::move(coarse));
  }
  levels.back().parent.clear();
}

}  // namespace nfield::remesh
