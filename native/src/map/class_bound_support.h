#pragma once
// Glue between the genus >= 2 pipeline (hyperbolic_map.cpp) and the class
// lower bound of map/class_lower_bound.h: the source in its own
// uniformization metric, the target's lengths, the per-candidate bounds and
// (docs/handle_classes.md). Not public API.
#include <atomic>
#include <memory>
#include <string>
#include <vector>

#include "map_support.h"
#include "surfmap/map/class_lower_bound.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/layout.h"

namespace surfmap::detail {

/// The source's lengths for the class bounds: the source uniformized like a
/// target (its own refined system of loops and hyperbolic layout), its
/// default system of loops `loops` carried onto that one by the identity
/// overlay (topology/projected_loops.h), so curves are words in the
/// default cut's canonical letters (`generators`: CanonicalSchema::generators
/// of the default loops `sl.loops`). `ok` false (with `why`) when any step fails; the pipeline
/// then reports no curve bounds.
/// The default cut's canonical generators as words in the canonical
/// letters the pipeline reads when this surface is the target (the class
/// loops' schema on the flip path, else the layout's), its inverse (up to
/// inner automorphisms; topology/outer_automorphisms.h), and why they are
/// missing (SurfaceMapResult::source_as_target).
struct SourceLetters {
  GroupMap as_target, as_target_inverse;
  std::string as_target_status;
};

struct SourceClassBounds {
  bool ok = false;
  std::string why;
  std::unique_ptr<SurfaceGroupLengths> source;
  std::unique_ptr<ClassBoundEvaluator> evaluator;
  /// The uniformized copy, its canonical schema, and the default cut's
  /// canonical generators as words in that schema's letters.
  UniformizedTarget uniformized;
  CanonicalSchema schema;
  GroupMap iota;
  /// The source's letters as a target, from the uniformized copy's class
  /// loops (or its layout's letters when it has none).
  SourceLetters letters;
  double time_s = 0;
  /// Vertices of the coarse copy the bounds were computed on
  /// (coarse_class_bounds), 0 for the source itself.
  int copy_vertices = 0;
};
/// `sl`: the pipeline's default (unrefined) source loops, source_loops of
/// `source`; their greedy basis is refined for the uniformized copy's class
/// loops rather than computed again (issue 19).
SourceClassBounds source_class_bounds(const TriMesh& source, const Connectivity& sc, const SystemOfLoops& sl,
                                      const std::vector<Word>& generators, int genus, const SurfaceMapOptions& options,
                                      const std::atomic<bool>* stop = nullptr);

/// The same bounds on a coarse copy `copy` of `source` (issue 19; its
/// vertices are source vertices at their own positions, map/coarse_source.h):
/// the copy uniformized, `sl`'s loops carried onto it by the overlay
/// (nearest copy vertices, shortest joins; checked to be an isomorphism).
/// The lengths are those of the copy's hyperbolic metric, so the curve
/// bounds bound the energy of maps from the copy, the surface the ranking's
/// coarse energies are measured on (docs/history/handle_classes.md "Bounds on the coarse copy").
/// `letters` are left empty (the copy's letters are not the
/// source's).
SourceClassBounds coarse_class_bounds(const TriMesh& copy, const TriMesh& source, const SystemOfLoops& sl,
                                      const std::vector<Word>& generators, int genus, const SurfaceMapOptions& options,
                                      const std::atomic<bool>* stop = nullptr);

/// SourceLetters without the source's uniformization (issue 19): on the flip
/// path (the default target metric) the letters the pipeline reads of a
/// target are its own loops' (map_support.h own_class_loops: no metric), so
/// the source's letters as a target are a function of its loops alone, the
/// same words source_class_bounds gives when its copy's class loops carry.
/// Only for the flip-path policies (automatic, intrinsic Delaunay); the
/// status says what failed.
SourceLetters source_letters_from_own_loops(const TriMesh& source, const Connectivity& sc, const SystemOfLoops& sl,
                                           const std::vector<Word>& generators, int genus,
                                           const SurfaceMapOptions& options);

/// Fills HomotopyCandidate::class_lower_bound, class_curve_bound and the
/// family's name of every genus >= 2 candidate k that has none yet, from
/// classes[k] (source canonical generator -> target canonical word); nothing
/// when `bounds` is not ok.
void fill_class_bounds(const SourceClassBounds& bounds, const SurfaceGroupLengths& target,
                       const std::vector<GroupMap>& classes, std::vector<HomotopyCandidate>& candidates);

/// The curve bound of class `theta` (ClassLowerBound::curve_bound), 0 when
/// `bounds` is not ok (so it never prunes then).
double class_curve_bound_of(const SourceClassBounds& bounds, const SurfaceGroupLengths& target, const GroupMap& theta);

}  // namespace surfmap::detail
