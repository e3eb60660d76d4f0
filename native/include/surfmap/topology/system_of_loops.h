#pragma once
// Greedy system of loops (the greedy homotopy basis: a shortest-path tree T
// and a maximum spanning tree T* of the dual; docs/method.md §2.2) and the refinement that makes the 2g loops simple and
// disjoint except at the base vertex.
#include <string>
#include <vector>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

struct SystemOfLoopsOptions {
  /// Base vertex x of the loops. -1 (default): a well-chosen vertex (high
  /// valence, near the middle of the shape).
  int base_vertex = -1;
  /// Split edges so that loops are simple and meet only at x (default: true).
  bool refine = true;
  /// Refinement: arcs that pass a whole branch of the tree cross the
  /// branch's root edge instead of running around it (default: true; much
  /// shorter loops and fewer split points). false: every arc follows the
  /// full Euler tour of the tree (also the automatic fallback).
  bool shortcut_branches = true;
  /// Edge weights (#E, edge order of Connectivity(mesh.F)); empty (default):
  /// 3D lengths, greedy loops (T* the dual's maximum spanning tree by loop
  /// length). Given the uniformization metric: T is its shortest-path tree from
  /// its centre (metric_centre_vertex unless base_vertex is set) and T* a
  /// shortest-path tree of the dual (edges not in T) from its centre face:
  /// the disk is the faces glued along T*, so a shallow T* keeps the domain
  /// compact (issue 13: the genus-24 wheel's domain reached 32 from the centre
  /// with loops of 15 on the maximum T*; 14 on this one, loops still ~15).
  std::vector<double> edge_weights;
};

/// Everything refers to `mesh` (the refined mesh when refinement ran).
struct SystemOfLoops {
  /// Refined mesh. Its first #V(input) vertices are the input vertices, at
  /// the same positions; the others lie on input edges or inside input faces.
  TriMesh mesh;
  /// For every vertex of `mesh`: the input face containing it and its
  /// barycentric coordinates there (#V x 1 and #V x 3), so that split points
  /// can be mapped back onto the input surface exactly.
  std::vector<int> origin_face;
  RowMatrixX3d origin_barycentric;
  /// For every face of `mesh`: the input face that contains it (#F; the
  /// identity without refinement). Refined faces lie inside input faces.
  std::vector<int> face_origin;
  int genus = 0;
  int base_vertex = -1;
  /// Spanning tree T rooted at x: per vertex, the halfedge from its parent to
  /// it (-1 at x). Halfedge numbering as in Connectivity(mesh.F). Without
  /// refinement it is the shortest-path (Dijkstra) tree; after refinement it
  /// is the tree of the refined mesh made of both halves of every loop plus
  /// the edges that neither T* crosses nor are generators (T, T* and the 2g
  /// generator edges partition the edges).
  std::vector<int> tree_parent_halfedge;
  /// Cut tree T*: per face, the halfedge of that face across which its parent
  /// face lies (-1 at the root face). Faces of the disk obtained by cutting
  /// along the loops are exactly connected through these dual edges.
  std::vector<int> dual_tree_parent_halfedge;
  /// The 2g edges in neither T nor crossed by T*, one per loop (loop k uses
  /// generator_edges[k]; after refinement, the middle edge of the loop).
  std::vector<int> generator_edges;
  /// 2g closed vertex paths [x, v1, ..., x] along edges of `mesh`; loop k is
  /// path(x, a) + (a, b) + path(b, x) for generator edge k. Simple, pairwise
  /// disjoint except at x when refined.
  std::vector<std::vector<int>> loops;
  /// Cyclic boundary word of the 4g-gon obtained by cutting along the loops,
  /// read counter-clockwise: letters are loop indices, +k+1 for loop k in its
  /// own direction and -(k+1) reversed (so each of ±1..±2g occurs once).
  std::vector<int> word;
  /// The same word as text, loops named a1 b1 a2 b2 ... by index order
  /// (loop 2i -> a_{i+1}, loop 2i+1 -> b_{i+1}); inverse written with "^-1".
  std::string word_text;
  /// True when the refinement used the short construction
  /// (SystemOfLoopsOptions::shortcut_branches) rather than the fallback.
  bool shortcut_used = false;
};

/// The per-mesh part of the greedy basis (issue 19): every vertex's
/// neighbours in the order of its rotation (Connectivity::rotate_ccw from
/// vertex_halfedge) with the lengths of the edges to them, and the two faces
/// of every edge. The pipeline computes systems of loops of the source at
/// 16 base vertices (its default cut and the class search's cuts); this is
/// built once and shared by all of them, and the loops are the same as
/// without it.
struct GreedyGraph {
  /// 3D edge lengths of `mesh`; `conn` must be Connectivity(mesh.F).
  GreedyGraph(const TriMesh& mesh, const Connectivity& conn);
  /// Given lengths (#E, edge order of conn); InputError on a size mismatch.
  GreedyGraph(const Connectivity& conn, std::vector<double> lengths);
  int num_vertices = 0, num_edges = 0;
  std::vector<double> length;  ///< #E
  /// Neighbours of v: entries first_out[v] .. first_out[v + 1] - 1 of
  /// out_head (the neighbour), out_halfedge (v -> it) and out_length.
  std::vector<int> first_out, out_head, out_halfedge;
  std::vector<double> out_length;
  std::vector<int> edge_faces;  ///< #2E: face(edge_halfedge(e)), face(twin)
};

/// Computes the system of loops of a closed, manifold, oriented mesh of genus
/// g >= 1 (throws InputError for genus 0: there are no loops to cut, or for a
/// base vertex out of range).
///
/// Greedy basis: Dijkstra tree T from x by edge length; maximum spanning tree
/// T* of the dual graph of the non-tree edges, weighted by |sigma(e)|; the 2g
/// remaining edges are the generators, loops sorted by length.
/// Refinement (see system_of_loops.cpp): the 4g halves of the greedy loops
/// are redrawn as arcs fanning out from x inside a thin neighbourhood of the
/// tree paths, through split points on input edges (and bend points inside
/// input faces); the refined loops are homotopic to the greedy ones (same
/// boundary word up to rotation). The result is verified (edge paths, simple,
/// disjoint except at x, one disk with a 4g-gon word, T and T* spanning
/// trees); a failed verification throws SolveError. O(n log n) plus the
/// number of split points.
SystemOfLoops system_of_loops(const TriMesh& mesh, const SystemOfLoopsOptions& options = {});
/// The same with the caller's `conn`, which must be Connectivity(mesh.F)
/// (built once per mesh per run: issue 19).
/// `graph` (nullptr: built here): GreedyGraph(mesh, conn), shared by calls
/// on the same mesh; not read when options.edge_weights are given.
SystemOfLoops system_of_loops(const TriMesh& mesh, const Connectivity& conn, const SystemOfLoopsOptions& options = {},
                              const GreedyGraph* graph = nullptr);

/// The refined system of loops of `unrefined`, a system_of_loops of this
/// mesh with refine = false: the same result as system_of_loops(mesh, conn,
/// options) with refine = true, the same base vertex and the same edge
/// weights (the greedy basis is read off `unrefined`'s trees and generators
/// instead of being computed again; issue 19: the map's source loops are
/// built unrefined, and the source's own uniformization wants them refined).
/// `conn` must be Connectivity(mesh.F); options.base_vertex and
/// edge_weights are not read (they made `unrefined`). InputError when
/// `unrefined` is not an unrefined system of loops of `mesh`.
SystemOfLoops refine_system_of_loops(const TriMesh& mesh, const Connectivity& conn, const SystemOfLoops& unrefined,
                                     const SystemOfLoopsOptions& options = {});

/// A central vertex of the metric `edge_weights` (#E, edge order of conn):
/// the vertex of least eccentricity estimated by farthest-point sampling
/// (`samples` Dijkstra sweeps; the eccentricity max_v d(x, v) is bounded
/// below by the distance to the sampled far points), the one of highest
/// valence among the 64 best (room for the 4g arcs to fan out, as
/// default). O(samples · n log n). InputError on a size mismatch or a
/// non-positive weight.
int metric_centre_vertex(const Connectivity& conn, const std::vector<double>& edge_weights, int samples = 6);

/// After s.mesh was refined further and s.loops updated to match (simple,
/// disjoint except at s.base_vertex, edge paths of s.mesh): recomputes the
/// word, T*, T and the generator edges from the loops, with the same checks
/// as system_of_loops (throws SolveError). Origins are the caller's.
void rebuild_system_of_loops(SystemOfLoops& s);

}  // namespace surfmap
