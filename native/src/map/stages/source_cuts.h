#pragma once
// Other systems of loops on the source ("cuts"), for lifting homotopy
// classes from them (stages/homotopy_classes.h, docs/method.md §2.10; the Torelli
// representatives in docs/handle_classes.md): the loops at another base vertex,
// the default cut's canonical generators as words in that cut's, and its
// handle basis. Source-only (~0.2 s per cut at 50k vertices), so prepared
// on the second thread while the target is uniformized. Internal.
#include <atomic>
#include <memory>
#include <mutex>
#include <vector>

#include "surfmap/map/surface_map.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/system_of_loops.h"

namespace surfmap::detail {

/// One prepared cut.
struct CutPrep {
  bool ok = false;  ///< false: no system of loops there, or its overlay onto the default cut is not an isomorphism
  GroupMap psi;     ///< 2g: default canonical generator -> word in this cut's canonical generators
  HandleBasis shb;  ///< this cut's handle basis (topology/handle_basis.h)
  std::vector<std::vector<int>> loops;  ///< this cut's loops (vertex paths) and canonical generators (for its overlay)
  std::vector<Word> generators;
  /// The same in the other canonical basis (stages/other_basis.h), when the
  /// default cut's other generators were given (SourceCuts::set_default):
  /// the default's other canonical generators -> words in this cut's other
  /// canonical generators, and this cut's handle basis in them.
  bool other_ok = false;
  GroupMap psi_other;
  HandleBasis shb_other;
};

/// The cuts the class search may ask for, in the order it asks: the
/// options' homotopy.extra_cuts first, then (default class with the search
/// on) homotopy.search.cuts, base vertices spread evenly over the vertex
/// list. Whichever thread prepares a cut, the result is the same; each
/// planned cut is prepared once.
class SourceCuts {
 public:
  /// `sc`: Connectivity(source.F).
  SourceCuts(const TriMesh& source, const Connectivity& sc, const SurfaceMapOptions& options, int genus);
  /// The default cut's loops and canonical generators: set once, before
  /// any cut is prepared. `other_generators` (optional): its canonical
  /// generators in the other basis (other_schema_options), for the cuts'
  /// CutPrep::psi_other.
  void set_default(const std::vector<std::vector<int>>& loops, const std::vector<Word>& generators,
                   const std::vector<Word>& other_generators = {});
  /// The planned cuts' base vertices (#planned, in order).
  const std::vector<int>& planned_bases() const { return bases_; }
  /// Prepares planned cut k (once; thread-safe).
  const CutPrep& prepare_planned(int k);
  /// Prepares the cut at `base`: the first planned cut there, else an
  /// unplanned one prepared afresh into `scratch`.
  const CutPrep& prepare(int base, CutPrep& scratch);
  /// The source's greedy graph (topology/system_of_loops.h), built once
  /// when cuts are planned (issue 19: shared by every cut's loops and the
  /// default loops); nullptr otherwise.
  const GreedyGraph* graph() const { return graph_.get(); }
  /// Raised when no more speculative preparation is wanted (the second
  /// thread stops preparing ahead).
  std::atomic<bool> stop{false};

 private:
  CutPrep build(int base) const;
  struct Slot {
    std::once_flag once;
    CutPrep prep;
  };
  const TriMesh& source_;
  const Connectivity& sc_;
  const SurfaceMapOptions& options_;
  int genus_;
  std::vector<int> bases_;
  std::unique_ptr<const GreedyGraph> graph_;
  std::vector<Slot> slots_;
  std::vector<std::vector<int>> default_loops_;
  std::vector<Word> default_generators_;
  std::vector<Word> default_other_generators_;
};

/// Base vertices c * nv / (count + 1), c = 1..count (deterministic spread).
std::vector<int> spread_bases(int num_vertices, int count);

}  // namespace surfmap::detail
