#pragma once
// The flattening step shared by the genus >= 2 polygon initial maps
// (map/initial_map.h, map/cut_graph_initial_map.h): a cut disk with its
// boundary fixed on a convex polygon in the Klein model, its interior placed
// by linear solves with positive weights (Tutte / Floater), so that the
// result embeds the disk (Floater 2003, "Mean value coordinates").
#include <complex>
#include <string>
#include <unordered_map>
#include <vector>

#include "surfmap/mesh/tri_mesh.h"

namespace surfmap::detail {

/// One edge of a disk mesh: its symmetrised mean-value weight (from the 3D
/// geometry; positive on any triangle), the vertices opposite it and how
/// many faces it has (1: boundary edge, 2: interior).
struct DiskEdge {
  double w = 0;
  int opposite[2] = {-1, -1};
  int faces = 0;
};

/// Key of the edge {a, b} of a disk with `nd` vertices in the map below.
inline long long disk_edge_key(int a, int b, int nd) {
  return static_cast<long long>(std::min(a, b)) * nd + std::max(a, b);
}

/// The edges of `disk` keyed by disk_edge_key.
std::unordered_map<long long, DiskEdge> mean_value_disk_edges(const TriMesh& disk);

/// A weighted edge of the flattening's graph (node ids; nodes may be disk
/// vertices or extra points such as chord midpoints).
struct FlatteningEdge {
  int a, b;
  double w;
};

/// Solves the positions `k` (Klein model, #nodes) of the nodes with
/// fixed[node] == 0 from the fixed ones: round 0 the Tutte map with weights
/// w (each free node the w-weighted mean of its neighbours), rounds
/// 1..hyperboloid_rounds the hyperboloid barycentre condition X_i ∝ Σ_j w_ij
/// X_j (isometry-invariant; in Klein coordinates Σ_j w_ij γ_j (k_j − k_i) =
/// 0, γ = 1/sqrt(1 − |k|²) from the previous round, a Tutte map with
/// positive weights every round). Returns false (and `why`) when the
/// Laplacian cannot be factorised.
bool flatten_in_klein(const std::vector<FlatteningEdge>& graph, const std::vector<char>& fixed, int hyperboloid_rounds,
                      std::vector<std::complex<double>>& k, std::string* why);

}  // namespace surfmap::detail
