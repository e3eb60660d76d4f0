#pragma once
// The flattening step shared by the genus >= 2 polygon initial maps
// (map/initial_map.h, map/cut_graph_initial_map.h): a cut disk with its
// boundary fixed on a convex polygon in the Klein model, its interior placed
// by linear solves with positive weights (Tutte-type, mean value weights),
// so that the result embeds the disk.
#include <complex>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/words.h"
#include "surfmap/uniformize/deck_group.h"

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

/// A step of a polygon initial map that cannot build the map: the map's
/// function returns with applied = false and this reason (the caller's
/// fallbacks run).
struct GiveUp {
  std::string why;
};

/// Runs `build(out)` (the steps of a polygon initial map) and sets
/// out.applied; a GiveUp turns into applied = false with its reason and no
/// map (out.z, vertex_deck, vertex_deck_word cleared). Other errors pass.
template <class Result, class Build>
void build_or_give_up(Result& out, const Build& build) {
  try {
    build(out);
    out.applied = true;
  } catch (const GiveUp& g) {
    out.applied = false;
    out.reason = g.why;
    out.z.clear(), out.vertex_deck.clear(), out.vertex_deck_word.clear();
  }
}

/// Exterior angles (radians) of the polygon with Klein-model corners `kq`
/// in order: their total (2π for a simple counter-clockwise polygon), the
/// smallest and the largest (convex when the smallest is > 0 with total 2π).
struct KleinTurns {
  double total = 0, min = 10, max = -10;
};
KleinTurns klein_turns(const std::vector<std::complex<double>>& kq);

/// The development of a cut disk, breadth first from face 0 across the
/// edges not cut (cut[conn.edge(h)] == 0; `conn`: the connectivity whose
/// faces are the disk's faces): per face f its frame word b_f (b_0 = 1) and
/// per disk vertex d the deck word c_d = b_f corner_word(f, k) of that copy
/// (k: f's corner at d; an empty corner word leaves the reduced b_f as it
/// is), all reduced side words. Two faces that disagree on a copy's word
/// give `mismatch` (their elements' distance over size²: long words carry
/// round-off of size² times machine precision); a disk whose faces are not
/// all reached is not connected.
struct DiskDevelopment {
  std::vector<Word> c;  ///< #disk vertices
  std::vector<Word> b;  ///< #disk faces
  int faces_reached = 0;
  double mismatch = 0;
};
DiskDevelopment develop_disk(const TriMesh& disk, const Connectivity& conn, const std::vector<char>& cut,
                             const DeckGroup& group, const std::function<Word(int, int)>& corner_word);

/// The input vertices read off a flattened disk: vertex i (0 <= i <
/// #inputs) takes its first copy d (original_vertex[d] == i; #disk
/// vertices entries), whose Klein position k[d] in `chart` is taken back to
/// the global Poincaré frame, and that copy's deck word c[d]; both are moved
/// into the target's domain by `reduce_point` when it is set. Fills z,
/// vertex_deck and vertex_deck_word (#inputs each). Returns "" or why not;
/// `vertex_noun` and `disk_noun` name the vertices and the disk in that
/// message.
std::string read_disk_vertices(const std::vector<int>& original_vertex, int inputs,
                               const std::vector<std::complex<double>>& k, const std::vector<Word>& c,
                               const hyperbolic::Mobius& chart,
                               const std::function<Word(std::complex<double>&)>& reduce_point,
                               const DeckGroup& group, const std::string& vertex_noun,
                               const std::string& disk_noun, std::vector<std::complex<double>>& z,
                               std::vector<hyperbolic::Mobius>& vertex_deck, std::vector<Word>& vertex_deck_word);

}  // namespace surfmap::detail
