#include "dijkstra.h"

#include <stdexcept>

namespace surfmap::detail {

void prepare_dijkstra(int num_nodes, const DijkstraOptions& options, DijkstraResult& result) {
  const size_t n = static_cast<size_t>(num_nodes);
  const bool sized = result.distance.size() == n;
  const bool arcs_sized = result.parent_arc.size() == n, nodes_sized = result.parent_node.size() == n;
  const bool parents_ready = (arcs_sized || !options.want_parents) && (nodes_sized || !options.want_parent_nodes);
  if (!(options.keep_distances && sized && parents_ready)) {
    constexpr double inf = std::numeric_limits<double>::infinity();
    if (sized && result.lists_hold_reached) {
      // Only what the last search reached differs from a fresh result.
      auto reset = [&](int v) {
        result.distance[v] = inf;
        if (arcs_sized) result.parent_arc[v] = -1;
        if (nodes_sized) result.parent_node[v] = -1;
      };
      for (int v : result.settled) reset(v);
      for (const auto& item : result.heap) reset(item.second);
    } else {
      result.distance.assign(n, inf);
      if (arcs_sized) result.parent_arc.assign(n, -1);
      if (nodes_sized) result.parent_node.assign(n, -1);
    }
    if (options.want_parents && !arcs_sized) result.parent_arc.assign(n, -1);
    if (options.want_parent_nodes && !nodes_sized) result.parent_node.assign(n, -1);
    result.num_reached = 0;
  }
  result.lists_hold_reached = !options.keep_distances;
  result.settled.clear();
  result.heap.clear();
  result.reached_target = false;
}

std::vector<int> arcs_back_to_source(const DijkstraResult& result, int node) {
  if (result.parent_node.size() != result.distance.size())
    throw std::logic_error("arcs_back_to_source: the search kept no parent nodes (want_parent_nodes)");
  std::vector<int> arcs;
  for (int v = node; result.parent_arc[v] >= 0; v = result.parent_node[v]) arcs.push_back(result.parent_arc[v]);
  return arcs;
}

}  // namespace surfmap::detail
