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
// every cost is >= 0), which certifies that the flow is a cheapest one for the amounts it has moved. The
// sources are served one after the other: a Dijkstra search from the source on reduced costs stops when the
// first node with remaining demand is settled (at distance D), the potentials of the settled nodes drop by
// D - dist (the others keep theirs; this equals raising every potential by min(dist, D), up to a common
// shift, so reduced costs stay >= 0 and the path found gets reduced cost 0), and the bottleneck is pushed
// along the path. A search only explores the ball of radius D around its source, so when supplies have
// demands nearby (the remesher's row ends pair locally) the whole solve costs about the sum of those balls,
// not one pass over the network per unit. A source from which no demand is reachable keeps its supply
// (routed is then the maximum, but the cost need not be the least among maximum flows).
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
    std::vector<double> path_costs;  ///< cost of each augmenting path, in order
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
