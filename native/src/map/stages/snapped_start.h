#pragma once
// A start for the harmonic solve of one class of a genus >= 2 map that
// needs no development of the source in one chart (issue 13): every source
// vertex at the target vertex nearest to it in 3D (its position in the
// target's cut disk), the sheets chosen along a breadth-first tree of the
// solver's edges so that every tree edge's element is the shortest side
// word joining the two copies. For a pair that overlays (a remeshed copy, a
// plate onto another triangulation of itself) the start is then the overlay
// map itself, and in the overlay's class every edge starts a few target
// edges long instead of as long as its deck element moves the origin (the
// genus-11 plate: 41 .. 70 units from the origin, where Newton stalled at
// 800 times the optimum energy). The tree fixes every vertex's deck up to
// one element at the root: the conjugator D with D L D^-1 = M for the loops
// the edges off the tree close (L the class's element of the loop, M the
// snapped map's), found from the fixed points of two such pairs and read
// as a side word by reducing D(0) into the polygon. When the class is not
// the snapped map's (no such D: its lengths differ), the edges off the tree
// come out long and the origin start (lower energy) is kept. Internal to
// src/map/hyperbolic_map.cpp.
#include <complex>
#include <string>
#include <vector>

#include "surfmap/map/fundamental_polygon.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/deck_group.h"
#include "surfmap/uniformize/layout.h"

namespace surfmap::detail {

struct SnappedStart {
  std::vector<std::complex<double>> z;  ///< #V points of the target's cut disk
  std::vector<Word> deck;               ///< #V vertex decks (side words), as solve_with_decks reads them
  /// E at this start and at the origin start (every vertex at 0, no decks),
  /// and the longest start edge of each (hyperbolic units).
  double energy = 0, origin_energy = 0;
  double longest_edge = 0, origin_longest_edge = 0;
  /// Whether this start is the better one: lower energy than the origin's
  /// and no edge longer than the origin's longest (the start-edge limit of
  /// the solve, HyperbolicHarmonicOptions::max_start_edge_size, must not
  /// refuse a class the origin start would solve).
  bool better() const { return energy < origin_energy && longest_edge <= origin_longest_edge; }
  /// Solver edges whose start element is not their nearest lift (the
  /// snapped map's edge): 0 in the snapped overlay's own class when the
  /// overlay is consistent.
  int disagreeing_edges = 0;
};

/// The snapped overlay's own class (issue 13): the deck elements the
/// snapped map gives the source's loops (each loop's edges' nearest-lift
/// elements multiplied along it, the tree's gauge cancelling on a closed
/// path), per source loop letter, as side words of the target's group.
struct SnappedLoops {
  bool ok = false;
  std::string why;  ///< when not ok
  std::vector<Word> letter_side_words;  ///< #loops: the image of source loop letter k+1
  /// Source faces around which the edges' elements do not close up (the
  /// snapped map is then not one map of the surfaces there: a long image
  /// edge took the wrong sheet); the loops' images are read anyway.
  int inconsistent_faces = 0;
};

/// The snapped class as theta (source canonical generator j -> word in the
/// target's canonical letters, the ClassSpace's), from the loops' side words:
/// each side letter rewritten in the layout's loop letters (the side pairing
/// of the sides +k, -k at positions i, j of layout.word is
/// Psi_{j+1} Psi_i^-1, Psi_m the prefix of length m of the boundary word),
/// then each loop letter in canonical letters (`canonical_of_loop_letter`,
/// #2g: loop letter k+1 as a canonical word). `source_generators`: the
/// source's canonical generators in its loop letters. False with `why` when
/// a rewriting does not check out.
bool snapped_class_map(const SnappedLoops& loops, const DiskLayout& layout, const DeckGroup& group,
                       const std::vector<Word>& canonical_of_loop_letter, const std::vector<Word>& source_generators,
                       GroupMap* theta, std::string* why);

/// Each loop letter of `layout_word` as a word in the canonical letters of
/// `canonical_generators` (2g canonical generators as words in the loop
/// letters, generating the group): the inverse of that substitution, found
/// by Nielsen moves (u_i -> u_i u_k^+-1 or u_k^+-1 u_i while a word gets
/// shorter after Dehn reduction) until every generator is one letter, and
/// checked exactly, up to one common conjugation (the same class): moves
/// that conjugate every generator by one letter are taken too (generators
/// read from another base point). `hint`: a candidate inverse tried first
/// (e.g. the schema's own letters). False with `why` when the moves get
/// stuck.
bool invert_canonical_generators(const std::vector<Word>& canonical_generators, const Word& layout_word,
                                 const std::vector<Word>& hint, std::vector<Word>* loop_letters, std::string* why);

class SnappedStartBuilder {
 public:
  /// `layout`/`group`: the target's hyperbolic cut disk and deck group; the
  /// first target.num_vertices() vertices of the layout's mesh are the
  /// target's own (as every uniformized target keeps them).
  SnappedStartBuilder(const TriMesh& source, const TriMesh& target, const DiskLayout& layout, const DeckGroup& group,
                      const FundamentalPolygon& polygon);
  /// The start for the solver edges `edges` of one class (#V = source vertices).
  SnappedStart operator()(const std::vector<WeightedEdge>& edges) const;
  /// The snapped overlay's own class, read along the source's loops
  /// (`loops`: closed vertex paths of the source, SystemOfLoops::loops;
  /// `edge_word`: #E each source edge's element in the loop letters;
  /// `loop_relator`: the loops' boundary word). `edges`: any class's solver
  /// edges (only their ends are read: the tree).
  SnappedLoops loop_images(const std::vector<WeightedEdge>& edges, const Connectivity& sc,
                           const std::vector<std::vector<int>>& loops, const std::vector<Word>& edge_word,
                           const Word& loop_relator) const;

 private:
  /// The snapped positions and the target-side tree products T (and the
  /// class-side ones R of `edges`' elements) along the Prim tree.
  struct Tree {
    std::vector<std::complex<double>> z;
    std::vector<Word> T, R;
    std::vector<char> tree_edge;
  };
  Tree tree(const std::vector<WeightedEdge>& edges) const;
  /// The short element q (index into short_words_) with q(zj) nearest zi.
  size_t nearest_lift(std::complex<double> zi, std::complex<double> zj) const;
  const DeckGroup& group_;
  const FundamentalPolygon& polygon_;
  std::vector<int> nearest_;                              ///< #V source: target vertex
  std::vector<std::vector<std::complex<double>>> copies_;  ///< per target vertex: its disk copies
  std::vector<Word> short_words_;                          ///< side words of length <= 2 (and the empty word)
  std::vector<hyperbolic::Mobius> short_elements_;
};

}  // namespace surfmap::detail
