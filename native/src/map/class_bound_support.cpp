// Class lower bounds in the genus >= 2 pipeline and the quality signal
// (docs/handle_classes.md).
#include "class_bound_support.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "../seconds_since.h"
#include "map_support.h"
#include "surfmap/error.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/outer_automorphisms.h"
#include "surfmap/topology/projected_loops.h"
#include "surfmap/uniformize/deck_group.h"

namespace surfmap::detail {

namespace {

/// The source carried onto a copy of itself whose mesh refines its own (the
/// same vertices first, edges split by the metric's and the loops'
/// refinements): joins by length follow the split edges exactly.
ProjectedLoopsOptions self_carry_options() {
  ProjectedLoopsOptions o;
  o.join_by_length = true;
  return o;
}

/// SourceLetters: on the flip path the pipeline reads a
/// target's classes in its own loops' canonical letters (map_support.h
/// ClassLoops), so the default cut is carried onto those loops as well (the
/// identity overlay); on the fixed path they are the layout's, `iota`.
void as_target_letters(const TriMesh& source, const std::vector<std::vector<int>>& loops,
                       const std::vector<Word>& generators, int genus, const ClassLoops* cl, const GroupMap& iota,
                       SourceLetters& b) {
  const int n = 2 * genus;
  const Word R = canonical_relator(genus);
  GroupMap m = cl ? GroupMap(n) : iota;
  if (cl) {
    const ProjectedLoopsResult self = project_loops(source, loops, cl->loops, cl->word, self_carry_options());
    if (!self.ok) {
      b.as_target_status = "the source's loops did not carry onto its own class loops: " + self.message;
      return;
    }
    for (int j = 0; j < n; ++j) m[j] = dehn_reduce(substitute(substitute(generators[j], self.loop_images), cl->schema.letters), R);
    const IntMatrix M = homology_matrix(m, n), J = symplectic_form(genus);
    if (!(M.transpose() * J * M == J) || !dehn_reduce(substitute(R, m), R).empty()) {
      b.as_target_status = "the source's loops carried onto its own class loops do not give an isomorphism";
      return;
    }
  }
  const AutomorphismInverse inv = invert_automorphism(m, genus);
  if (!inv.ok) {
    b.as_target_status = "the source's letters as a target could not be inverted: " + inv.why;
    return;
  }
  b.as_target = std::move(m);
  b.as_target_inverse = inv.inverse;
}

}  // namespace

namespace {

/// source_class_bounds on `surface` (the source itself, or a coarse copy of
/// it: `copy`), the default loops `sl` of `source` carried onto it.
SourceClassBounds class_bounds_on(const TriMesh& surface, const Connectivity& surface_conn, bool copy,
                                  const TriMesh& source, const SystemOfLoops& sl, const std::vector<Word>& generators,
                                  int genus, const SurfaceMapOptions& options, const std::atomic<bool>* stop) {
  const auto t0 = std::chrono::steady_clock::now();
  SourceClassBounds b;
  b.copy_vertices = copy ? surface.num_vertices() : 0;
  const std::vector<std::vector<int>>& loops = sl.loops;
  try {
    SurfaceMapOptions o = options;
    // (A copy's vertex numbers are its own: its loops' base vertex is left
    // to the loop construction.)
    o.loops.target_base_vertex = copy ? -1 : options.loops.source_base_vertex;
    // (A copy's handle-class loops are never read: as_target_letters runs on
    // the source itself only.)
    b.uniformized = uniformized_target(surface, Background::Hyperbolic, o, &surface_conn, stop, "source",
                                       copy ? nullptr : &sl, !copy);
    const UniformizedTarget& xu = b.uniformized;
    b.schema = canonical_schema(xu.layout.word, schema_options(options));
    const CanonicalSchema& xcs = b.schema;
    // The default cut's loops onto the uniformized copy's: on the source
    // itself every loop vertex's nearest point is itself (joins by length
    // follow the split edges); on a coarse copy, whose vertices are source
    // vertices at their own positions, each loop vertex goes to the nearest
    // copy vertex and consecutive images are joined by the copy's shortest
    // paths (the overlay of a remeshed surface; checked below).
    const ProjectedLoopsResult self =
        project_loops(source, loops, xu.loops, xu.layout.word, copy ? ProjectedLoopsOptions{} : self_carry_options());
    if (!self.ok)
      throw SolveError(std::string("the source's loops did not carry onto its own ") +
                       (copy ? "coarse copy's uniformization: " : "uniformized copy: ") + self.message);
    const int n = 2 * genus;
    const Word R = canonical_relator(genus);
    GroupMap iota(n);
    for (int j = 0; j < n; ++j) iota[j] = dehn_reduce(substitute(substitute(generators[j], self.loop_images), xcs.letters), R);
    const IntMatrix M = homology_matrix(iota, n), J = symplectic_form(genus);
    if (!(M.transpose() * J * M == J) || !dehn_reduce(substitute(R, iota), R).empty())
      throw SolveError(std::string("the source's loops carried onto its ") + (copy ? "coarse copy" : "uniformized copy") +
                       " do not give an isomorphism");
    b.source = std::make_unique<SurfaceGroupLengths>(DeckGroup(xu.layout), xcs.generators, xu.layout.word, iota);
    b.iota = iota;
    if (copy)
      b.letters.as_target_status = "the class bounds were computed on the source's coarse copy, whose letters are not "
                                   "the source's";
    else
      as_target_letters(source, loops, generators, genus, xu.class_loops.get(), iota, b.letters);
    b.evaluator = std::make_unique<ClassBoundEvaluator>(*b.source, disjoint_curve_families(genus));
    b.ok = true;
  } catch (const Error& e) {
    b.ok = false;
    b.why = e.what();
  }
  b.time_s = seconds_since(t0);
  return b;
}

}  // namespace

SourceClassBounds source_class_bounds(const TriMesh& source, const Connectivity& sc, const SystemOfLoops& sl,
                                      const std::vector<Word>& generators, int genus, const SurfaceMapOptions& options,
                                      const std::atomic<bool>* stop) {
  return class_bounds_on(source, sc, false, source, sl, generators, genus, options, stop);
}

SourceClassBounds coarse_class_bounds(const TriMesh& copy, const TriMesh& source, const SystemOfLoops& sl,
                                      const std::vector<Word>& generators, int genus, const SurfaceMapOptions& options,
                                      const std::atomic<bool>* stop) {
  return class_bounds_on(copy, Connectivity(copy.F, copy.num_vertices()), true, source, sl, generators, genus, options,
                         stop);
}

SourceLetters source_letters_from_own_loops(const TriMesh& source, const Connectivity& sc, const SystemOfLoops& sl,
                                           const std::vector<Word>& generators, int genus,
                                           const SurfaceMapOptions& options) {
  SourceLetters b;
  // The lo of uniformized_target for this mesh as a target (its base vertex
  // is the source's, as in source_class_bounds).
  SystemOfLoopsOptions lo;
  lo.base_vertex = options.loops.source_base_vertex;
  try {
    const ClassLoops cl = own_class_loops(source, sc, lo, &sl, schema_options(options));
    as_target_letters(source, sl.loops, generators, genus, &cl, GroupMap{}, b);
  } catch (const Error& e) {
    b.as_target_status = std::string("the source's own loops failed: ") + e.what();
  }
  return b;
}

void fill_class_bounds(const SourceClassBounds& bounds, const SurfaceGroupLengths& target,
                       const std::vector<GroupMap>& classes, std::vector<HomotopyCandidate>& candidates) {
  if (!bounds.ok) return;
  for (size_t k = 0; k < candidates.size() && k < classes.size(); ++k) {
    if (!std::isnan(candidates[k].class_lower_bound)) continue;
    const ClassLowerBound lb = (*bounds.evaluator)(target, classes[k]);
    candidates[k].class_lower_bound = lb.bound;
    candidates[k].class_curve_bound = lb.curve_bound;
    candidates[k].class_bound_curves = lb.family_name;
  }
}

double class_curve_bound_of(const SourceClassBounds& bounds, const SurfaceGroupLengths& target, const GroupMap& theta) {
  return bounds.ok ? (*bounds.evaluator)(target, theta).curve_bound : 0.0;
}

}  // namespace surfmap::detail
