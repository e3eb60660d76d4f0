#pragma once
// A coarse copy of a source mesh for ranking homotopy classes cheaply
// (docs/method.md §2.10): the harmonic energy of a class is a property of the
// continuous surfaces, so a converged solve on a few thousand vertices
// estimates it, and the fine mesh is then solved only in the best classes.
//
// The coarse mesh is the dual of geodesic Voronoi regions (Dijkstra over the
// fine edges) of farthest-point samples: its vertices are a subset of the
// fine ones at their original positions, a coarse face stands for every fine
// triangle with corners in three regions, and every coarse edge has a path
// of fine halfedges (tree path, bridging fine edge, tree path) between
// its ends. Fine homotopy data (a deck element per fine edge) is carried to
// the coarse mesh by multiplying along these paths, which keeps the fine
// mesh's conventions: a coarse vertex is the same point as its fine vertex,
// with the same deck element, so a coarse solution is a start for the fine
// solve. That a path triangle around every coarse face is contractible is not
// assumed: the caller checks that its product is the identity, exactly.
#include <functional>
#include <string>
#include <vector>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"

namespace surfmap {

struct CoarseSourceOptions {
  /// Vertices of the coarse copy (default 3000: at genus 2-6 the class
  /// energies on it are within a few percent of the fine ones, see
  /// map/hyperbolic_map.cpp; a converged Newton solve there costs tens of ms).
  int target_vertices = 3000;
  /// Called every 64 seeds of the sampling (the copy's longest part) with the
  /// fraction of the seeds placed; false stops the copy with Cancelled.
  std::function<bool(double)> keep_going;
};

struct CoarseSource {
  /// False when no valid coarse mesh of the same genus was found
  /// (the reason in `why`); the other fields are then empty.
  bool ok = false;
  std::string why;
  /// The coarse mesh: #Vc x 3 positions (fine vertices' own), #Fc x 3 faces.
  TriMesh mesh;
  /// #Vc: the fine vertex each coarse vertex is.
  std::vector<int> fine_vertex;
  /// #V (fine): the coarse vertex whose region holds the fine vertex.
  std::vector<int> region;
  /// #V (fine): the fine halfedge from the vertex's parent in its region's
  /// shortest-path tree to the vertex; -1 at the coarse vertices themselves.
  std::vector<int> parent_halfedge;
  /// #Ec (coarse edges, Connectivity(mesh.F) numbering): fine halfedges from
  /// the tail to the head of the coarse edge's edge_halfedge, in order.
  std::vector<std::vector<int>> edge_path;
  /// Seconds spent (sampling, regions, dual and paths).
  double seconds = 0;
};

/// `fine`, `fc`: a closed manifold mesh and its connectivity.
CoarseSource coarse_source(const TriMesh& fine, const Connectivity& fc, const CoarseSourceOptions& options = {});

/// The fine halfedges from coarse vertex region[v] to fine vertex v along the
/// region's tree (empty at a coarse vertex).
std::vector<int> path_from_region_centre(const CoarseSource& cs, const Connectivity& fc, int v);

}  // namespace surfmap
