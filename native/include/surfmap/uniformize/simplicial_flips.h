#pragma once
// A simplicial triangulation of the flip-based metric by exact flips
// (docs/uniformization.md, "What is implemented").
//
// The intrinsic Delaunay triangulation T' that the flip-based flow returns
// is a Δ-complex: after Ptolemy flips two edges may join the same pair of
// vertices, or an edge may join a vertex to itself (the 128-segment CAD
// plate). The system of loops, the layout and the point supports of
// uniformize/intrinsic_loops.h identify an edge by its two vertices, so
// such a T' is first made simplicial here: each offending edge is flipped
// exactly in the FINAL metric (its quad unfolded: the metric, and so the
// uniformization, is unchanged; only the triangulation stops being
// Delaunay). The flips are appended to flow.flip_history with
// EdgeFlip::final_frame set, so the flip history still leads from the input
// faces to flow.faces (uniformize/carried_loops.h replays it) and
// IntrinsicCorrespondence undoes them in the final frame before the frame
// change.
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {

struct SimplicialFlipsOptions {
  /// Flips allowed in all (default 4 x the number of offending edges + 16).
  int max_flips = -1;
};

struct SimplicialFlipsResult {
  bool simplicial = false;  ///< no loop edge and no two edges with the same ends remain
  int flips = 0;            ///< flips made (appended to flow.flip_history)
  int loop_edges = 0;       ///< offending edges before: loops ...
  int multiple_edges = 0;   ///< ... and edges sharing both ends with an earlier one
};

/// True when no edge of flow's triangulation is a loop and no two edges join
/// the same two vertices.
bool is_simplicial(const RicciFlowResult& flow);

/// flow: a converged result of ricci_flow with intrinsic_delaunay (faces,
/// face_edges, edge_vertices, edge_lengths of the final metric). Flips edges
/// exactly in the final metric until the triangulation is simplicial or no
/// allowed flip is left: an edge is flipped when its two faces differ, its
/// quad is strictly convex at both ends of the edge (so the new diagonal is
/// a geodesic inside the quad with a valid length) and the new diagonal
/// neither is a loop nor duplicates an edge. Updates flow's triangulation,
/// lengths, flips and flip_history in place.
SimplicialFlipsResult make_simplicial(RicciFlowResult& flow, const SimplicialFlipsOptions& options = {});

}  // namespace surfmap
