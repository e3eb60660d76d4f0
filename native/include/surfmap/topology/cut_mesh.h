#pragma once
// Cutting a closed mesh open along a set of edges (docs/method.md §2.3): every
// vertex on the cut is duplicated once per wedge of faces between consecutive
// cut edges around it, so that cutting along a system of loops gives a
// topological disk whose boundary is the 4g-gon of the polygon schema.
#include <vector>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

struct CutMesh {
  /// The cut-open mesh: same faces in the same order as the input (#F x 3),
  /// vertices duplicated along the cut (#V_cut x 3 positions).
  TriMesh mesh;
  /// For every vertex of `mesh`, the input vertex it is a copy of (#V_cut).
  std::vector<int> original_vertex;
  /// Boundary cycles of `mesh` as vertex indices of `mesh`, each traversed
  /// with the mesh on its left (counter-clockwise seen from outside).
  std::vector<std::vector<int>> boundary_loops;
  int num_edges = 0;
  /// V - E + F of `mesh`, counted from its faces (1 for a disk).
  int euler_characteristic = 0;
};

/// Cuts `mesh` along the edges with cut_edge[e] != 0 (edge numbering of
/// `conn`, which must be Connectivity(mesh.F)).
CutMesh cut_mesh_along_edges(const TriMesh& mesh, const Connectivity& conn,
                             const std::vector<char>& cut_edge);

/// Cuts `mesh` along closed vertex paths (each loop [x, v1, ..., x] must
/// follow edges of the mesh; throws InputError naming the first pair of
/// consecutive vertices that is not an edge).
CutMesh cut_mesh(const TriMesh& mesh, const std::vector<std::vector<int>>& loops);

}  // namespace surfmap
