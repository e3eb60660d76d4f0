#pragma once
// The homotopy data of one class (docs/method.md §2.6, §2.8): a deck element of the
// target per source edge and per edge of the energy's triangulation, the
// input of every harmonic solve in that class. Internal to the genus >= 2
// pipeline (src/map/hyperbolic_map.cpp).
#include <memory>
#include <mutex>
#include <vector>

#include "homotopy_classes.h"
#include "hyperbolic_quality.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/map/hyperbolic_harmonic.h"

namespace surfmap::detail {

struct ClassData {
  /// #E source edges (along edge_halfedge); empty until the solver data are
  /// built (class_data with solver_data false leaves them out).
  std::vector<hyperbolic::Mobius> rho_edge;
  std::vector<Word> side_word_edge;  ///< #E rho_edge as reduced side words (always built)
  /// The solver's edges: #idt edges with their cotangent weights, then every
  /// source edge the intrinsic triangulation flipped away (weight 0), so the
  /// image triangles of the source's own faces come out of the solve in
  /// local charts (SolverEdgeIndex). Empty until the solver data are built.
  std::vector<WeightedEdge> edges;
  /// Whether rho_edge and edges are built (a full-resolution solve's input).
  bool has_solver_data() const { return !edges.empty(); }
  /// #3F halfedge elements (a twin carries the inverse): matrices, side words.
  std::vector<hyperbolic::Mobius> halfedge_rho(const Connectivity& sc) const;
  std::vector<Word> halfedge_words(const Connectivity& sc) const;
};

/// Which solver edge carries each source edge, for the triangulation `idt`
/// (edges of idt that are source edges keep their index; the others get
/// indices after idt's). `index` (#E) is updated in place: a source edge
/// that is not an idt edge keeps its previous `forward`.
void index_solver_edges(const Connectivity& sc, const IntrinsicDelaunayResult& idt, SolverEdgeIndex& index);

/// The class data of theta. `edge_word` (#E): each source edge's element as
/// a word in the source's loop letters; `idt` the energy's triangulation;
/// the products around every source face are checked exactly (Dehn's
/// algorithm solves the word problem): a SolveError names the face.
/// `solver_data` false: only the side words (all the coarse copy and the
/// prolongation read), not the matrices and solver edges (issue 19: ~30 MB
/// per class at 50k source vertices, for ~15 classes of which a few are ever
/// solved at full resolution); a later call with true builds the same side
/// words again and the rest, so the data are the same either way.
ClassData class_data(const ClassSpace& space, const GroupMap& theta, const TriMesh& source, const Connectivity& sc,
                     const std::vector<Word>& edge_word, const IntrinsicDelaunayResult& idt,
                     const SolverEdgeIndex& index, const DiskLayout& layout, const DeckGroup& group,
                     bool solver_data = true);

/// The solver's edges of every class without their elements (rho and
/// rho_word left empty): #idt edges with their cotangent weights, then every
/// source edge `index` places after them (weight 0), as in ClassData::edges.
/// Their endpoints and positive weights are the sparsity pattern every
/// class's Newton system shares (PatternSolver::prepare).
std::vector<WeightedEdge> solver_edge_pattern(const Connectivity& sc, const IntrinsicDelaunayResult& idt,
                                             const SolverEdgeIndex& index);

/// One HyperbolicHarmonicSolver (map/hyperbolic_harmonic.h) per sparsity
/// pattern: built at the first solve, on that solve's edges (so an analysis
/// failure is that solve's error, as for hyperbolic_harmonic_map), unless
/// prepare() built it for that pattern earlier; then serving every solve of
/// every class on the pattern (a solve on another pattern builds its own).
/// Thread-safe. reset() when the pattern changes (other source weights).
class PatternSolver {
 public:
  HyperbolicHarmonicResult solve(int n, const std::vector<WeightedEdge>& edges,
                                 const std::vector<hyperbolic::Mobius>& generators, std::vector<Complex> z0,
                                 const HyperbolicHarmonicOptions& options);
  /// Issue 19: the analysis of `edges`' pattern (n vertices) now, ahead of
  /// the first solve (the pipeline's second thread, next to the target's
  /// uniformization); nothing when the solver has it. A failure is dropped:
  /// the first solve builds it again and reports it.
  void prepare(int n, const std::vector<WeightedEdge>& edges);
  void reset();

 private:
  std::mutex mutex_;
  std::shared_ptr<const HyperbolicHarmonicSolver> solver_;
};

/// A harmonic solve of `edges` (n vertices) from points `start` (#n) with
/// vertex decks `deck_word` (#n side words of `group`): the edges are
/// conjugated by the decks as words (never as matrix products), and the
/// decks are composed back, so the result is relative to `edges` as given.
HyperbolicHarmonicResult solve_with_decks(int n, const std::vector<WeightedEdge>& edges,
                                          const std::vector<Complex>& start, const std::vector<Word>& deck_word,
                                          const DeckGroup& group, const HyperbolicHarmonicOptions& o,
                                          PatternSolver* solver = nullptr);

}  // namespace surfmap::detail
