#pragma once
// Halfedge connectivity of a closed, manifold, consistently oriented triangle
// mesh, derived from F alone. Halfedge h = 3*f + k runs from F(f,k) to
// F(f,(k+1)%3) inside face f; its twin runs the other way in the neighbouring
// face. Edges are numbered 0..#E-1; edge e has endpoints edge_vertices(e,0) <
// edge_vertices(e,1).
#include <vector>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

class Connectivity {
 public:
  /// Builds the structure. Throws InputError (naming the edge or vertex) if F
  /// is not a closed, manifold, consistently oriented triangle mesh.
  explicit Connectivity(const RowMatrixX3i& F, int num_vertices = -1);

  int num_vertices() const { return num_vertices_; }
  int num_faces() const { return static_cast<int>(F_.rows()); }
  int num_edges() const { return static_cast<int>(edge_vertices_.rows()); }
  int num_halfedges() const { return 3 * num_faces(); }
  int euler_characteristic() const { return num_vertices() - num_edges() + num_faces(); }
  /// (2 - chi) / 2 for a closed orientable surface.
  int genus() const { return (2 - euler_characteristic()) / 2; }

  static int face(int h) { return h / 3; }
  static int next(int h) { return 3 * (h / 3) + (h % 3 + 1) % 3; }
  static int prev(int h) { return 3 * (h / 3) + (h % 3 + 2) % 3; }
  int tail(int h) const { return F_(h / 3, h % 3); }
  int head(int h) const { return F_(h / 3, (h % 3 + 1) % 3); }
  /// The vertex of face(h) not on h.
  int opposite_vertex(int h) const { return F_(h / 3, (h % 3 + 2) % 3); }
  int twin(int h) const { return twin_[h]; }
  int edge(int h) const { return edge_of_[h]; }
  /// A halfedge of edge e, the one running from edge_vertices(e,0) to (e,1).
  int edge_halfedge(int e) const { return edge_halfedge_[e]; }
  /// One outgoing halfedge of v.
  int vertex_halfedge(int v) const { return vertex_out_[v]; }
  /// Next outgoing halfedge around tail(h), counter-clockwise.
  int rotate_ccw(int h) const { return twin_[prev(h)]; }
  /// Vertex endpoints of every edge, #E x 2, smaller index first.
  const Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor>& edge_vertices() const {
    return edge_vertices_;
  }
  int edge_vertex(int e, int k) const { return edge_vertices_(e, k); }
  /// The halfedge from a to b, or -1 if a and b are not adjacent. O(valence).
  int find_halfedge(int a, int b) const;
  /// Outgoing halfedges of v in counter-clockwise order.
  std::vector<int> outgoing(int v) const;
  int valence(int v) const;
  const RowMatrixX3i& faces() const { return F_; }

 private:
  RowMatrixX3i F_;
  int num_vertices_;
  std::vector<int> twin_, edge_of_, edge_halfedge_, vertex_out_;
  Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor> edge_vertices_;
};

}  // namespace surfmap
