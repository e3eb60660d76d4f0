#pragma once
// The input's system of loops carried onto the flipped intrinsic
// triangulation T' (docs/uniformization.md, "Handle classes on the flip
// path"). The loops are combinatorial: they need no metric, so the
// handle-class machinery can read them on the user's own connectivity, as
// the fixed-connectivity path does, while the layout, deck group and harmonic
// solve run on T' (uniformize/intrinsic_loops.h). This gives each input loop
// as a word in the loop letters of T''s system of loops, so that a class
// written on the input's loops is evaluated with the deck group of T'.
//
// How: each flip of RicciFlowResult::flip_history replaces edge s–t of the
// quad (k, s, m, t) by k–m; the old edge s->t is homotopic (rel. ends) to
// s->k->t across the old triangle (k, s, t), so an edge path of the input
// becomes an edge path of T' by replaying the flips. An edge a->b of T' is
// homotopic to any path from a to b inside one of its faces, so its word is
// read off a path through the refined faces of T''s loops mesh that lie in
// that face (their words: topology/edge_homotopy.h).
#include <vector>

#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/topology/words.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {

struct CarriedLoops {
  /// One word per loop of the input's system of loops (2g), in the loop
  /// letters of T''s system of loops (±(k+1) for its loop k), freely
  /// reduced: the element path(x', x) · loop · path(x, x') of π1(T', x'),
  /// with x, x' the two base vertices and path(x', x) one fixed path (the
  /// same for every loop, so the words form a homomorphism).
  std::vector<Word> words;
  /// Flips replayed (== flow.flip_history.size()) and how many of them
  /// rewrote a loop.
  int flips_replayed = 0;
  int flips_on_loops = 0;
  /// Longest carried loop on T' (halfedges, after free reduction).
  int longest_edge_path = 0;
};

/// input: the mesh the flow ran on (#V, #F x 3); input_loops: a system of
/// loops of `input` (refined or not; origins on input faces); flow: the
/// flip-based flow's result on Connectivity(input.F) (faces, flip_history);
/// tprime_loops: IntrinsicLoops::loops of that flow (origins and
/// face_origin on flow.faces, its first #V vertices those of T'). Throws
/// SolveError when the replayed flips do not reproduce flow.faces or a path
/// cannot be followed (both would be bugs).
CarriedLoops carry_loops_through_flips(const TriMesh& input, const SystemOfLoops& input_loops,
                                       const RicciFlowResult& flow, const SystemOfLoops& tprime_loops);

}  // namespace surfmap
