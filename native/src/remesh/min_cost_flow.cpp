#include "nfield/remesh/min_cost_flow.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <queue>
#include <string>

#include "nfield/errors.hpp"

namespace nfield::remesh {

MinCostFlow::MinCostFlow(int num_nodes) {
  if (num_nodes < 0) throw ParameterError("min-cost flow: the node count must be >= 0");
  supply_.assign(num_nodes, 0);
}

int MinCostFlow::add_arc(int from, int to, int capacity, double cost) {
  const int n = num_nodes();
  if (from < 0 || from >= n || to < 0 || to >= n)
    throw ParameterError("min-cost flow: arc " + std::to_string(from) + " -> " + std::to_string(to) +
                         " has a node out of range [0, " + std::to_string(n) + ")");
  if (capacity < 0) throw ParameterError("min-cost flow: arc capacities must be >= 0");
  if (!(cost >= 0) || !std::isfinite(cost)) throw ParameterError("min-cost flow: arc costs must be finite and >= 0");
  arcs_.push_back({to, capacity, cost});
  arcs_.push_back({from, 0, -cost});
  tail_.push_back(from);
  tail_.push_back(to);
  return static_cast<int>(arcs_.size() / 2) - 1;
}

void MinCostFlow::add_supply(int node, int amount) {
  if (node < 0 || node >= num_nodes()) throw ParameterError("min-cost flow: supply node out of range");
  supply_[node] += amount;
}

MinCostFlow::Result MinCostFlow::solve(const std::function<bool()>& cancelled) {
  if (solved_) throw ParameterError("min-cost flow: solve() may be called once");
  solved_ = true;
  Result result;
  const int n = num_nodes();
  const int m = static_cast<int>(arcs_.size());
  // Residual arcs out of each node (CSR over arc indices).
  std::vector<int> offsets(n + 1, 0), out(m);
  for (int a = 0; a < m; ++a) ++offsets[tail_[a] + 1];
  for (int v = 0; v < n; ++v) offsets[v + 1] += offsets[v];
  {
    std::vector<int> fill(offsets.begin(), offsets.end() - 1);
    for (int a = 0; a < m; ++a) out[fill[tail_[a]]++] = a;
  }
  std::vector<long long> excess = supply_;
  long long remaining_demand = 0;
  std::vector<int> sources;
  for (int v = 0; v < n; ++v) {
    if (excess[v] > 0) sources.push_back(v);
    else remaining_demand -= excess[v];
  }

  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> potential(n, 0.0), dist(n, kInf);
  std::vector<int> pred(n, -1), touched;
  std::vector<char> settled(n, 0);
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap;
  auto finish = [&]() {
    for (int s : sources) result.unrouted += std::max<long long>(excess[s], 0);
    for (int a = 0; a < m; a += 2) result.cost += arcs_[a].cost * arcs_[a + 1].capacity;
    return result;
  };
  for (int source : sources) {
    while (excess[source] > 0 && remaining_demand > 0) {
      if (cancelled && cancelled()) return finish();
      // 1. Dijkstra from `source` on reduced costs, stopped when the first node with remaining demand is
      //    settled (at distance D): only the ball of radius D around the source is explored.
      for (int v : touched) {
        dist[v] = kInf;
        pred[v] = -1;
        settled[v] = 0;
      }
      touched.clear();
      heap = {};
      dist[source] = 0;
      touched.push_back(source);
      heap.push({0.0, source});
      int sink = -1;
      double D = 0;
      while (!heap.empty()) {
        const auto [d, u] = heap.top();
        heap.pop();
        if (settled[u] || d > dist[u]) continue;
        settled[u] = 1;
        if (excess[u] < 0) {
          sink = u;
          D = d;
          break;
        }
        for (int k = offsets[u]; k < offsets[u + 1]; ++k) {
          const int a = out[k];
          const Arc& arc = arcs_[a];
          if (arc.capacity <= 0 || settled[arc.to]) continue;
          // Reduced costs are >= 0 up to rounding; clamp so that Dijkstra stays valid.
          const double nd = d + std::max(0.0, arc.cost + potential[u] - potential[arc.to]);
          if (nd < dist[arc.to]) {
            if (dist[arc.to] == kInf) touched.push_back(arc.to);
            dist[arc.to] = nd;
            pred[arc.to] = a;
            heap.push({nd, arc.to});
          }
        }
      }
      ++result.phases;
      if (sink < 0) break;  // no remaining demand is reachable from this source: its supply stays
      // 2. Potentials of the settled nodes lowered by D - dist (all others unchanged, which equals raising
      //    every potential by min(dist, D) and then lowering all by D): reduced costs stay >= 0 on every
      //    residual arc and are 0 along the shortest path found.
      for (int v : touched)
        if (settled[v]) potential[v] += dist[v] - D;
      // 3. Push the bottleneck along the path.
      long long push = std::min(excess[source], -excess[sink]);
      for (int v = sink; v != source; v = tail_[pred[v]]) push = std::min<long long>(push, arcs_[pred[v]].capacity);
      double path_cost = 0;
      for (int v = sink; v != source; v = tail_[pred[v]]) {
        arcs_[pred[v]].capacity -= static_cast<int>(push);
        arcs_[pred[v] ^ 1].capacity += static_cast<int>(push);
        path_cost += arcs_[pred[v]].cost;
      }
      excess[source] -= push;
      excess[sink] += push;
      remaining_demand -= push;
      result.routed += push;
      ++result.augmentations;
      result.path_costs.push_back(path_cost);
    }
  }
  return finish();
}

}  // namespace nfield::remesh
