#include "source_cuts.h"

#include "../map_support.h"
#include "surfmap/error.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/projected_loops.h"

namespace surfmap::detail {

std::vector<int> spread_bases(int num_vertices, int count) {
  std::vector<int> bases;
  for (int c = 1; c <= count; ++c)
    bases.push_back(static_cast<int>((static_cast<long long>(num_vertices) * c) / (count + 1)));
  return bases;
}

SourceCuts::SourceCuts(const TriMesh& source, const Connectivity& sc, const SurfaceMapOptions& options, int genus)
    : source_(source), sc_(sc), options_(options), genus_(genus) {
  const int nv = source.num_vertices();
  if (options.homotopy.extra_cuts > 0) {
    bases_ = spread_bases(nv, options.homotopy.extra_cuts);
    if (options.homotopy.search.enabled && options.homotopy.class_index < 0)
      for (int b : spread_bases(nv, options.homotopy.search.cuts)) bases_.push_back(b);
  }
  if (!bases_.empty()) graph_ = std::make_unique<const GreedyGraph>(source, sc);
  slots_ = std::vector<Slot>(bases_.size());
}

void SourceCuts::set_default(const std::vector<std::vector<int>>& loops, const std::vector<Word>& generators,
                             const std::vector<Word>& other_generators) {
  default_loops_ = loops;
  default_generators_ = generators;
  default_other_generators_ = other_generators;
}

CutPrep SourceCuts::build(int base) const {
  CutPrep cp;
  const int n2 = 2 * genus_;
  SurfaceMapOptions o2 = options_;
  o2.loops.source_base_vertex = base;
  SystemOfLoops sl2;
  try {
    sl2 = source_loops(source_, sc_, o2, graph_.get());
  } catch (const Error&) {
    return cp;  // no system of loops at that vertex: the default one is enough
  }
  const CanonicalSchema scs2 = canonical_schema(sl2.word, schema_options(options_));
  // The default loops onto this cut's: the same mesh (source_loops does not
  // refine), so each loop vertex is its own image and sc_ is the cut's
  // connectivity (issue 19: no box frame, k-d tree or Connectivity per cut).
  ProjectedLoopsOptions self_options;
  self_options.own_mesh = true;
  const ProjectedLoopsResult self = project_loops(source_, default_loops_, sl2, sl2.word, self_options, &sc_);
  if (self.ok) {
    const Word R2 = canonical_relator(genus_);
    const IntMatrix J2 = symplectic_form(genus_);
    cp.psi.assign(n2, Word{});
    for (int j = 0; j < n2; ++j)
      cp.psi[j] = dehn_reduce(substitute(substitute(default_generators_[j], self.loop_images), scs2.letters), R2);
    const IntMatrix Mpsi = homology_matrix(cp.psi, n2);
    if (Mpsi.transpose() * J2 * Mpsi == J2 && dehn_reduce(substitute(R2, cp.psi), R2).empty()) {
      cp.shb = handle_basis(source_, sl2.loops, scs2);
      cp.loops = sl2.loops;
      cp.generators = scs2.generators;
      cp.ok = true;
      // The other canonical basis (stages/other_basis.h): the same overlay
      // read through both bases' schemata.
      if (!default_other_generators_.empty()) {
        const CanonicalSchema other2 = canonical_schema(sl2.word, other_schema_options(options_));
        cp.psi_other.assign(n2, Word{});
        for (int j = 0; j < n2; ++j)
          cp.psi_other[j] =
              dehn_reduce(substitute(substitute(default_other_generators_[j], self.loop_images), other2.letters), R2);
        const IntMatrix M = homology_matrix(cp.psi_other, n2);
        if (M.transpose() * J2 * M == J2 && dehn_reduce(substitute(R2, cp.psi_other), R2).empty()) {
          cp.shb_other = handle_basis(source_, sl2.loops, other2);
          cp.other_ok = true;
        }
      }
    }
  }
  return cp;
}

const CutPrep& SourceCuts::prepare_planned(int k) {
  Slot& slot = slots_[k];
  std::call_once(slot.once, [&] { slot.prep = build(bases_[k]); });
  return slot.prep;
}

const CutPrep& SourceCuts::prepare(int base, CutPrep& scratch) {
  for (size_t k = 0; k < bases_.size(); ++k)
    if (bases_[k] == base) return prepare_planned(static_cast<int>(k));
  // (every cut asked for is planned; this keeps a mismatch harmless)
  scratch = build(base);
  return scratch;
}

}  // namespace surfmap::detail
