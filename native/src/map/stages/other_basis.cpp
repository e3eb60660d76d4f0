#include "other_basis.h"

#include "surfmap/topology/outer_automorphisms.h"

namespace surfmap::detail {

OtherBasis::OtherBasis(int genus, const SystemOfLoops& sl, const CanonicalSchema& scs, const CanonicalSchema& tcs,
                       const CanonicalSchema& tloop, const Word& target_word, const DiskLayout& layout, const DeckGroup& group,
                       const CanonicalSchemaOptions& other)
    : n_(2 * genus), name_(other.short_generators ? "short" : "classical"),
      scs_(canonical_schema(sl.word, other)), tloop_(canonical_schema(target_word, other)), tcs_(tloop_),
      reduce_(canonical_relator(genus)) {
  // The other target generators in the layout's letters, through the
  // run's: target loop letter -> run canonical word (tcs.letters) -> layout
  // letters (tcs.generators), Dehn-reduced by the layout's word. On the
  // layout's own loops this is the same element as the other schema's own
  // generator (the loops are the layout's letters).
  const DehnReducer reduce_layout(layout.word);
  for (Word& g : tcs_.generators) g = reduce_layout(substitute(reduce_(substitute(g, tcs.letters)), tcs.generators));
  // S: the run's source generator j (source loop letters) in the other's
  // canonical letters; T: the other's target generator i (target loop
  // letters) in the run's canonical letters.
  for (const Word& g : scs.generators) run_source_in_other_.push_back(reduce_(substitute(g, scs_.letters)));
  for (const Word& g : tloop_.generators) other_target_in_run_.push_back(reduce_(substitute(g, tcs.letters)));
  for (const Word& g : scs_.generators) other_source_in_run_.push_back(reduce_(substitute(g, scs.letters)));
  for (const Word& g : tloop.generators) run_target_in_other_.push_back(reduce_(substitute(g, tloop_.letters)));
  space_ = std::make_unique<ClassSpace>(genus, sl, scs_, tcs_, layout, group);
}

GroupMap OtherBasis::to_run(const GroupMap& theta_other) const {
  GroupMap theta(n_);
  for (int j = 0; j < n_; ++j)
    theta[j] = reduce_(substitute(reduce_(substitute(run_source_in_other_[j], theta_other)), other_target_in_run_));
  return theta;
}

GroupMap OtherBasis::from_run(const GroupMap& theta_run) const {
  GroupMap theta(n_);
  for (int j = 0; j < n_; ++j)
    theta[j] = reduce_(substitute(reduce_(substitute(other_source_in_run_[j], theta_run)), run_target_in_other_));
  return theta;
}

SurfaceAutomorphism OtherBasis::automorphism_from_run(const SurfaceAutomorphism& phi, bool source) const {
  // (other letter -> run word, then phi, then back in the other letters.)
  const GroupMap& in = source ? other_source_in_run_ : other_target_in_run_;
  const GroupMap& back = source ? run_source_in_other_ : run_target_in_other_;
  SurfaceAutomorphism r{GroupMap(n_), GroupMap(n_), phi.moves};
  for (int j = 0; j < n_; ++j) {
    r.map[j] = reduce_(substitute(reduce_(substitute(in[j], phi.map)), back));
    r.inverse[j] = reduce_(substitute(reduce_(substitute(in[j], phi.inverse)), back));
  }
  return r;
}

GroupMap OtherBasis::short_form(const OtherBasis* other, const GroupMap& theta_run) {
  return other && other->name() == "short" ? other->from_run(theta_run) : GroupMap{};
}

OtherBasisListing classes_in_other_basis(const OtherBasis& other, const TriMesh& source, const SystemOfLoops& sl,
                                         const SystemOfLoops& tl, const LoopProjector& projector,
                                         const SurfaceMapOptions& options, SourceCuts& cuts) {
  // The one-way sources only: the other cuts' classes are lifted in the
  // run's basis (SourceCuts carries them to its generators), the carried
  // and inverted classes are given in the run's basis.
  SurfaceMapOptions o = options;
  o.homotopy.extra_cuts = 0;
  o.homotopy.source_images.resize(0, 3);
  o.homotopy.reverse_class.clear();
  const HandleBasis shb = handle_basis(source, sl.loops, other.source_schema());
  const CandidateClasses listed =
      candidate_classes(other.space(), source, sl, shb, tl, other.target_loop_schema(), projector, o, cuts);
  OtherBasisListing out;
  out.target_basis = listed.target_basis;
  for (const HomotopyClass& hc : listed.classes) {
    // (The description is "handles  [how it was found]"; the handles are
    // described again in the run's bases.)
    const size_t open = hc.description.find("  [");
    std::string tag = open == std::string::npos ? hc.description : hc.description.substr(open + 3);
    if (!tag.empty() && tag.back() == ']') tag.pop_back();
    out.classes.push_back({other.to_run(hc.map), hc.map, tag});
  }
  return out;
}

}  // namespace surfmap::detail
