// Minimum-cost flow on a sparse directed graph by successive shortest paths (Ahuja, Magnanti, Orlin,
// "Network Flows", section 9.7), our own small implementation for the quad remesher's integer offsets.
//
// Problem: integer arc capacities u_a >= 0 and costs c_a >= 0 (any unit; the remesher uses squared lattice
// steps), integer node supplies b_v (positive: flow must leave v, negative: flow must arrive at v). Find an
// integer flow x with 0 <= x_a <= u_a in which every node sends at most its supply, receives at most its
// demand and transit nodes balance, routing as many units as possible; when every supply can be routed,
// the flow found is one of least total cost sum c_a x_a.
//
// Method: successive shortest paths with node potentials pi (the primal-dual form, as for the Hungarian
// method): reduced costs c_a + pi(tail) - pi(head) of residual arcs stay >= 0 (pi = 0 at the start, since
// every cost is >= 0), which certifies that the flow is a cheapest one for the amounts it has moved. Each
// phase runs one Dijkstra from all nodes with remaining supply at once, stopped when the nearest node with
// remaining demand is settled at distance D, and raises every potential by min(distance, D) (reduced costs
// stay >= 0 and the shortest paths to that demand get reduced cost 0), then pushes flow along as many
// admissible paths (residual arcs of reduced cost 0) from supply to demand nodes as a depth-first search
// finds (a blocking flow). Augmenting along arcs of reduced cost 0 keeps every reduced cost >= 0, so the
// final flow is optimal when all supply is routed; phases stop when no demand is reachable (the routed
// amount is then the maximum, but the cost need not be the least among maximum flows). Few phases are
// needed when many sources have a demand nearby; a phase costs O(A_D log V_D) for the ball of radius D it
// explores, plus O(V) to update the potentials.
#pragma once
#include <functional>
#include <vector>

namespace nfield::remesh {

class MinCostFlow {
 public:
  explicit MinCostFlow(int num_nodes);

  /// Adds an arc (ParameterError for a node out of range, a negative capacity or a negative or non-finite
  /// cost). Returns its index for flow().
  int add_arc(int from, int to, int capacity, double cost);
  /// Adds to the supply of `node` (negative: demand).
  void add_supply(int node, int amount);

  struct Result {
    long long routed = 0;    ///< units moved from supply to demand nodes
    long long unrouted = 0;  ///< supply left (no path to any remaining demand)
    double cost = 0;         ///< sum over arcs of cost * flow
    int augmentations = 0;
    int phases = 0;                  ///< Dijkstra runs
    std::vector<double> path_costs;  ///< cost of each augmenting path, in order (non-decreasing)
  };
  /// Solves (once). `cancelled` (optional) is polled between augmentations; when it returns true the
  /// solver stops early with a partial flow (every arc within capacity, some supply left).
  Result solve(const std::function<bool()>& cancelled = {});

  int flow(int arc) const { return arcs_[2 * arc + 1].capacity; }  ///< flow on an arc added by add_arc
  int num_nodes() const { return static_cast<int>(supply_.size()); }
  int num_arcs() const { return static_cast<int>(arcs_.size() / 2); }

 private:
  struct Arc {
    int to;
    int capacity;  ///< residual capacity
    double cost;
  };
  // arcs_[2a] is arc a, arcs_[2a + 1] its reverse (residual capacity = flow on a).
  std::vector<Arc> arcs_;
  std::vector<int> tail_;
  std::vector<long long> supply_;
  bool solved_ = false;
};

}  // namespace nfield::remesh
