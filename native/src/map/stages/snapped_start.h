#pragma once
// A start for the harmonic solve of one class of a genus >= 2 map that
// needs no development of the source in one chart (issue 13): every source
// vertex at the target vertex nearest to it in 3D (its copy in one face of
// the target's cut disk), the sheets chosen along a breadth-first tree of
// the solver's edges so that every tree edge's element is the snapped
// map's, read exactly off the target's triangulation (ExactEdgeElements:
// the cut edges crossed by the edge's image path). For a pair that overlays
// (a remeshed copy, a plate onto another triangulation of itself) the start
// is then the overlay map itself, and in the overlay's class every edge
// starts a few target edges long instead of as long as its deck element
// moves the origin (the genus-11 plate: 41 .. 70 units from the origin,
// where Newton stalled at 800 times the optimum energy). The tree fixes
// every vertex's deck up to one element at the root: the conjugator D with
// D L D^-1 = M for the loops the edges off the tree close (L the class's
// element of the loop, M the snapped map's), found from the fixed points of
// two such pairs and read as a side word by reducing D(0) into the polygon.
// When the class is not the snapped map's (no such D: its lengths differ),
// the edges off the tree come out long and the origin start (lower energy)
// is kept. Internal to src/map/hyperbolic_map.cpp.
#include <complex>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/fundamental_polygon.h"
#include "surfmap/map/hyperbolic_harmonic.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/deck_group.h"
#include "surfmap/uniformize/layout.h"

#include "../../mesh/dijkstra.h"

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
  /// Solver edges whose start element is not the snapped map's (their exact
  /// element): 0 in the snapped overlay's own class when the overlay is
  /// consistent.
  int disagreeing_edges = 0;
  /// Whether the root's conjugator came from the words (conjugator_from_words,
  /// when the fixed points gave none), and why not when neither gave one.
  bool conjugator_from_words = false;
  std::string conjugator_why;
  bool conjugator_found = false;  ///< a root conjugator was found (fixed points or words)
  /// Whether the solver edges' elements were read through the source's own
  /// edges (SnappedStartBuilder::use_source_paths) rather than each one's own
  /// image path: the second try, when the first found no conjugator.
  bool through_source_edges = false;
};

/// The snapped map's deck element of every source edge, read off the
/// target's triangulation (combinatorial, no point is compared): source
/// vertex v sits at the copy of its nearest target vertex t(v) in a face
/// f(v) around t(v); the image of edge (i, j) is a shortest path of target
/// edges from t(i) to t(j) (none when they coincide, one edge when they are
/// adjacent), walked face to face from f(i) to f(j) around each path vertex;
/// each crossing of a cut edge multiplies the sheet by that edge's side
/// pairing (inverse). The element of (i, j) is the sheet the walk ends in:
/// the lift of j next to i's copy is element(j's copy). Two walks around
/// one vertex differ by a loop around it, which is trivial in the group:
/// the element depends only on the path. (It replaced the nearest lift, the
/// short side word whose image of j's copy is nearest i's, which took the
/// wrong sheet across the genus-11 plate's short collars.) The path is a
/// shortest one in 3D chords of the layout's mesh, which on the flip path is
/// the flipped T': an edge of the input flipped away has no edge of its own
/// there, and its path can go round a collar (the genus-3 plate onto
/// itself: 2 of 808 source faces do not close).
struct ExactEdgeElements {
  bool ok = false;
  std::string why;            ///< when not ok
  std::vector<Word> element;  ///< #E source edges, edge_halfedge's tail -> head, reduced side words
  /// Per source edge, how doubtful its image path is: the path's 3D length
  /// over the source edge's (0 when both ends snap to one target vertex).
  std::vector<double> doubt;
  int longest_path = 0;  ///< target edges on the longest image path
  int long_paths = 0;    ///< source edges whose image path has 2 or more target edges
};

/// The snapped overlay's own class (issue 13): the deck elements the
/// snapped map gives the source's loops (each loop's edges' exact elements,
/// ExactEdgeElements, multiplied along it), per source loop letter, as side
/// words of the target's group.
struct SnappedLoops {
  bool ok = false;
  std::string why;  ///< when not ok
  std::vector<Word> letter_side_words;  ///< #loops: the image of source loop letter k+1
  /// Source faces around which the edges' elements do not close up: the
  /// image paths of the face's three edges bound no disk in the target (the
  /// snapped map is not one map of the surfaces there). The most doubtful
  /// edges are then derived from the others by closing the faces, and the
  /// loops' images read anyway.
  int inconsistent_faces = 0;
  int longest_path = 0, long_paths = 0;  ///< ExactEdgeElements's
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

/// A conjugator D with D L_k D^-1 = M_k for every pair (L_k, M_k), found on
/// the words alone (issue 13: at genus 11 the fixed points of the loops'
/// elements lie at round-off from |z| = 1, so D cannot be read off them).
/// `reduce`: Dehn's algorithm of the group (a one-relator surface group,
/// C'(1/6)), which decides equality exactly. How: the first pair with a
/// non-empty L is peeled to L = a l a^-1 and M = b m b^-1, l and m
/// cyclically Dehn-reduced (a rotation of l that Dehn's algorithm shortens
/// moves its prefix into a); conjugate cyclically reduced words of a
/// small-cancellation group are rotations of one another up to a short
/// conjugator, so x with x l x^-1 = m is a rotation's prefix (p^-1, or
/// y p^-1 for one letter y among the 2 * `letters` signed letters). D is
/// then b x l^k a^-1 for some k (the centralizer of l, taken as its
/// powers), fixed by the first pair whose L does not commute with the first
/// L, and every pair is checked exactly. False with `why` when no such D is
/// found (the classes differ, or the search misses it).
bool conjugator_from_words(const std::vector<std::pair<Word, Word>>& pairs,
                           const std::function<Word(const Word&)>& reduce, int letters, Word* D, std::string* why);

class SnappedStartBuilder {
 public:
  /// `layout`/`group`: the target's hyperbolic cut disk and deck group;
  /// `layout_mesh`: the mesh it lays out (SystemOfLoops::mesh of its loops),
  /// whose first target.num_vertices() vertices are the target's own (as
  /// every uniformized target keeps them).
  SnappedStartBuilder(const TriMesh& source, const TriMesh& target, const TriMesh& layout_mesh, const DiskLayout& layout,
                      const DeckGroup& group, const FundamentalPolygon& polygon);
  /// The start for the solver edges `edges` of one class (#V = source vertices).
  SnappedStart operator()(const std::vector<WeightedEdge>& edges) const;
  /// Every source edge's exact element (`sc`: Connectivity(source.F)).
  ExactEdgeElements exact_edge_elements(const Connectivity& sc) const;
  /// The snapped overlay's own class, read along the source's loops
  /// (`loops`: closed vertex paths of the source, SystemOfLoops::loops;
  /// `edge_word`: #E each source edge's element in the loop letters;
  /// `loop_relator`: the loops' boundary word).
  SnappedLoops loop_images(const Connectivity& sc, const std::vector<std::vector<int>>& loops,
                           const std::vector<Word>& edge_word, const Word& loop_relator) const;
  /// Lets the start read the solver's edges through the source's own edges
  /// (`sc`, `idt`: the energy's intrinsic triangulation, whose edge e joins
  /// idt.edges[e].i, j along its path of input halfedges; both must outlive
  /// the builder): each input edge's element is its exact element made
  /// consistent around every face (as loop_images reads the class), and an
  /// intrinsic edge's the product along its path, so the loops the tree
  /// closes are the snapped class's own. Without it (or when the source's
  /// elements cannot be read) every solver edge walks its own image path.
  void use_source_paths(const Connectivity& sc, const IntrinsicDelaunayResult& idt);

 private:
  /// The exact elements of the source's edges (ExactEdgeElements), made
  /// consistent where faces do not close: the most doubtful edges (a
  /// spanning tree of the dual graph, by doubt) derived from the others.
  struct ConsistentElements {
    bool ok = false;
    std::string why;
    std::vector<Word> element;  ///< #E, edge_halfedge's tail -> head
    int inconsistent_faces = 0, longest_path = 0, long_paths = 0;
  };
  ConsistentElements consistent_edge_elements(const Connectivity& sc) const;
  Word source_halfedge_element(int h) const;
  /// The snapped positions (each source vertex's home copy), every solver
  /// edge's exact element, and the target-side tree products T (and the
  /// class-side ones R of `edges`' elements) along a breadth-first tree.
  struct Tree {
    bool ok = false;
    std::string why;
    std::vector<std::complex<double>> z;
    std::vector<Word> T, R, element;
    std::vector<char> tree_edge;
  };
  /// `through_source_edges`: each solver edge's element read through the
  /// source's edges (use_source_paths) where it can be, else its image path.
  Tree tree(const std::vector<WeightedEdge>& edges, bool through_source_edges) const;
  /// The start from one tree (the root's conjugator, the decks, the energies).
  SnappedStart start_from(const Tree& t, const std::vector<WeightedEdge>& edges) const;
  /// Reused arrays of the shortest-path searches.
  struct PathScratch {
    DijkstraResult search;
    std::vector<int> path;
  };
  /// A shortest path of layout edges (3D chords) from a to b into s.path
  /// (just {a} when b is not reached).
  void shortest_path(int a, int b, PathScratch& s) const;
  /// The exact element of source vertices (i, j) (ExactEdgeElements), the
  /// image path's 3D length and its number of target edges.
  bool path_element(int i, int j, PathScratch& scratch, Word* element, double* length, int* edges_on_path,
                    std::string* why) const;
  /// Appends to `sheet` the cut-edge crossings of the shorter walk around
  /// layout vertex p from face `from` to face `to` (both around p).
  bool walk_around(int p, int from, int to, Word& sheet) const;
  const DeckGroup& group_;
  const FundamentalPolygon& polygon_;
  Connectivity layout_conn_;              ///< of the layout's mesh
  std::vector<Eigen::Vector3d> layout_points_;  ///< its vertices in 3D (shortest image paths)
  std::vector<Eigen::Vector3d> source_points_;  ///< the source's vertices (the paths' doubt)
  std::vector<int> halfedge_letter_;      ///< per layout halfedge: its side's letter (0: not cut)
  std::string layout_mismatch_;           ///< not empty: the layout's mesh is not its cut disk's (no exact elements)
  std::vector<int> nearest_;                   ///< #V source: target vertex
  std::vector<int> home_face_;                 ///< #V source: a layout face around its target vertex
  std::vector<std::complex<double>> home_point_;  ///< #V source: that vertex's copy in the face (cut disk)
  const Connectivity* source_conn_ = nullptr;              ///< use_source_paths's
  const IntrinsicDelaunayResult* source_paths_ = nullptr;  ///< use_source_paths's
  std::vector<Word> source_element_;                       ///< #E source edges (empty: not used)
};

}  // namespace surfmap::detail
