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
  long long remaining_supply = 0, remaining_demand = 0;
  double cost_scale = 0;
  for (long long b : excess) (b > 0 ? remaining_supply : remaining_demand) += std::abs(b);
  for (const Arc& a : arcs_) cost_scale = std::max(cost_scale, std::abs(a.cost));
  // Arcs whose reduced cost is within this of zero are admissible (potentials are sums of costs).
  const double tolerance = 1e-9 * std::max(1.0, cost_scale);

  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> potential(n, 0.0), dist(n);
  std::vector<int> current(n), stack_arcs;
  std::vector<char> dead(n), on_path(n);
  using Entry = std::pair<double, int>;
  auto finish = [&]() {
    result.unrouted = remaining_supply;
    for (int a = 0; a < m; a += 2) result.cost += arcs_[a].cost * arcs_[a + 1].capacity;
    return result;
  };
  while (remaining_supply > 0 && remaining_demand > 0) {
    if (cancelled && cancelled()) return finish();
    // 1. Dijkstra from every node with remaining supply at once, stopped when the first node with remaining
    //    demand is settled (at distance D): row ends pair locally, so a phase explores a small ball
    //    instead of the whole network.
    std::fill(dist.begin(), dist.end(), kInf);
    std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap;
    for (int v = 0; v < n; ++v)
      if (excess[v] > 0) {
        dist[v] = 0;
        heap.push({0.0, v});
      }
    double farthest = 0;
    bool reached_demand = false;
    while (!heap.empty()) {
      const auto [d, u] = heap.top();
      heap.pop();
      if (d > dist[u]) continue;
      farthest = d;
      if (excess[u] < 0) {
        reached_demand = true;
        break;
      }
      for (int k = offsets[u]; k < offsets[u + 1]; ++k) {
        const Arc& arc = arcs_[out[k]];
        if (arc.capacity <= 0) continue;
        // Reduced costs are >= 0 up to rounding; clamp so that Dijkstra stays valid.
        const double nd = d + std::max(0.0, arc.cost + potential[u] - potential[arc.to]);
        if (nd < dist[arc.to]) {
          dist[arc.to] = nd;
          heap.push({nd, arc.to});
        }
      }
    }
    if (!reached_demand) break;  // no remaining supply reaches any remaining demand
    // 2. Potentials raised by min(dist, D) (dist: settled distances, tentative labels >= D, or infinity):
    //    every residual arc keeps a reduced cost >= 0 (an arc out of a settled node u was relaxed, so
    //    min(dist_v, D) <= dist_u + its reduced cost; out of any other node the raise D is the largest), and
    //    the shortest paths to the nearest demand get reduced cost 0.
    for (int v = 0; v < n; ++v) potential[v] += std::min(dist[v], farthest);
    // 3. Blocking flow on the admissible arcs (residual, reduced cost 0): every path found is a shortest
    //    path for the current potentials, so each augmentation keeps reduced-cost optimality.
    std::copy(offsets.begin(), offsets.end() - 1, current.begin());
    std::fill(dead.begin(), dead.end(), 0);
    bool augmented = false;
    for (int source = 0; source < n; ++source) {
      while (excess[source] > 0 && !dead[source] && remaining_demand > 0) {
        // Depth-first search for a deficit node along admissible arcs.
        stack_arcs.clear();
        int u = source;
        on_path[u] = 1;
        while (u >= 0 && excess[u] >= 0) {
          bool advanced = false;
          for (int& k = current[u]; k < offsets[u + 1]; ++k) {
            const int a = out[k];
            const Arc& arc = arcs_[a];
            if (arc.capacity <= 0 || dead[arc.to] || on_path[arc.to]) continue;
            if (std::abs(arc.cost + potential[u] - potential[arc.to]) > tolerance) continue;
            stack_arcs.push_back(a);
            on_path[arc.to] = 1;
            u = arc.to;
            advanced = true;
            break;
          }
          if (advanced) continue;
          dead[u] = 1;  // no admissible way on from u in this phase
          on_path[u] = 0;
          if (stack_arcs.empty()) {
            u = -1;
          } else {
            u = tail_[stack_arcs.back()];
            stack_arcs.pop_back();
            ++current[u];
          }
        }
        if (u < 0) break;
        // u is a deficit node: push the bottleneck along the path.
        long long push = std::min(excess[source], -excess[u]);
        for (int a : stack_arcs) push = std::min<long long>(push, arcs_[a].capacity);
        double path_cost = 0;
        for (int a : stack_arcs) {
          arcs_[a].capacity -= static_cast<int>(push);
          arcs_[a ^ 1].capacity += static_cast<int>(push);
          path_cost += arcs_[a].cost;
          on_path[arcs_[a].to] = 0;
        }
        on_path[source] = 0;
        excess[source] -= push;
        excess[u] += push;
        remaining_supply -= push;
        remaining_demand -= push;
        result.routed += push;
        ++result.augmentations;
        result.path_costs.push_back(path_cost);
        augmented = true;
      }
      on_path[source] = 0;
    }
    ++result.phases;
    if (!augmented) break;  // cannot happen (a shortest path to the nearest deficit is admissible)
  }
  return finish();
}

}  // namespace nfield::remesh
