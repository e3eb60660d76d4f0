#pragma once
// Homotopy data on a mesh's edges (docs/method.md §2.6 and §7): every oriented
// edge i->j gets the group element of the loop path_T(x,i) + (i,j) +
// path_T(j,x), where T is the shortest-path tree of a system of loops. Tree
// edges get the identity, the generator edge of loop k gets loop k's value,
// and every other edge follows from "the product around each face is the
// identity", peeling the cut tree T* from its leaves to its root.
//
// The group is a template parameter so the same code serves the free group
// (words, for tests), the homology group (integer vectors), lattice
// translations (flat targets) and SU(1,1) deck maps (hyperbolic targets).
#include <string>
#include <vector>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/topology/system_of_loops.h"

namespace surfmap {

/// For each loop k of `loops`, the endpoint of its generator edge that the
/// loop reaches first when walked from the base vertex (the
/// `loop_first_vertex` argument of edge_group_elements). `conn` must be
/// Connectivity(loops.mesh.F). Throws SolveError if a loop misses its edge.
std::vector<int> loop_first_vertices(const SystemOfLoops& loops, const Connectivity& conn);

/// Group operations for edge_group_elements.
template <class G>
struct GroupOps {
  G identity;
  G (*multiply)(const G&, const G&);
  G (*inverse)(const G&);
};

/// Returns one element per edge e of `conn`, for the orientation of
/// conn.edge_halfedge(e) (the reverse orientation carries the inverse).
///  tree_parent_halfedge: #V, halfedge from parent to vertex in T (-1 at the root);
///  dual_tree_parent_halfedge: #F, halfedge of the face across which its
///    parent face lies in T* (-1 at the root face);
///  generator_edges: 2g edges, neither in T nor dual to T*;
///  loop_values: 2g elements, the value of the loop through generator edge k
///    traversed in the direction of the loop, i.e. from the endpoint whose tree
///    path starts the loop: `loop_first_vertex[k]` -> other endpoint.
/// Throws SolveError when the trees are inconsistent with the mesh.
template <class G>
std::vector<G> edge_group_elements(const Connectivity& conn, const std::vector<int>& tree_parent_halfedge,
                                   const std::vector<int>& dual_tree_parent_halfedge,
                                   const std::vector<int>& generator_edges,
                                   const std::vector<int>& loop_first_vertex, const std::vector<G>& loop_values,
                                   const GroupOps<G>& ops) {
  const int ne = conn.num_edges(), nf = conn.num_faces();
  std::vector<G> value(ne, ops.identity);
  std::vector<char> known(ne, 0);
  for (int v = 0; v < conn.num_vertices(); ++v) {
    const int h = tree_parent_halfedge[v];
    if (h >= 0) known[conn.edge(h)] = 1;  // identity
  }
  if (generator_edges.size() != loop_values.size() || loop_first_vertex.size() != loop_values.size())
    throw InputError("edge_group_elements: one value and one first vertex per generator edge needed");
  for (size_t k = 0; k < generator_edges.size(); ++k) {
    const int e = generator_edges[k];
    if (known[e]) throw SolveError("edge_group_elements: generator edge " + std::to_string(e) + " is a tree edge");
    const bool along = conn.tail(conn.edge_halfedge(e)) == loop_first_vertex[k];
    value[e] = along ? loop_values[k] : ops.inverse(loop_values[k]);
    known[e] = 1;
  }
  // Element of halfedge h (orientation-aware).
  auto of = [&](int h) {
    const int e = conn.edge(h);
    return conn.edge_halfedge(e) == h ? value[e] : ops.inverse(value[e]);
  };
  // Peel T* from the leaves: count children per face; a face whose children
  // are all done has exactly one unknown edge left, the one to its parent.
  std::vector<int> pending_children(nf, 0), order;
  order.reserve(nf);
  for (int f = 0; f < nf; ++f) {
    const int h = dual_tree_parent_halfedge[f];
    if (h >= 0) ++pending_children[conn.face(conn.twin(h))];
  }
  for (int f = 0; f < nf; ++f)
    if (pending_children[f] == 0) order.push_back(f);
  for (size_t q = 0; q < order.size(); ++q) {
    const int f = order[q];
    const int hp = dual_tree_parent_halfedge[f];
    if (hp < 0) continue;  // root: all its edges are known from its children
    // Around the face: of(h0) of(h1) of(h2) = identity, with h0 = hp unknown.
    const int h1 = Connectivity::next(hp), h2 = Connectivity::next(h1);
    if (!known[conn.edge(h1)] || !known[conn.edge(h2)])
      throw SolveError("edge_group_elements: face " + std::to_string(f) + " has more than one unknown edge");
    const G x = ops.inverse(ops.multiply(of(h1), of(h2)));  // value of hp
    const int e = conn.edge(hp);
    value[e] = conn.edge_halfedge(e) == hp ? x : ops.inverse(x);
    known[e] = 1;
    const int parent = conn.face(conn.twin(hp));
    if (--pending_children[parent] == 0) order.push_back(parent);
  }
  for (int e = 0; e < ne; ++e)
    if (!known[e]) throw SolveError("edge_group_elements: edge " + std::to_string(e) + " was not reached");
  return value;
}

}  // namespace surfmap
