#pragma once
// Issue 13/14 (docs/robustness.md "Canonical generators"): the genus >= 2 candidate
// classes listed in both canonical bases, so that which basis presents the
// surface groups (LoopOptions::short_canonical_generators) does not change
// the classes the ranking sees. Internal to src/map/hyperbolic_map.cpp and
// stages/homotopy_classes.cpp.
#include <memory>
#include <string>
#include <vector>

#include "homotopy_classes.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/topology/words.h"
#include "surfmap/uniformize/deck_group.h"
#include "surfmap/uniformize/layout.h"

namespace surfmap::detail {

/// The canonical basis the run does not use (the classical one when the run
/// uses the short generators, and the other way round), on the same two
/// systems of loops, with its own ClassSpace, and the change of basis into
/// the run's. A class theta' of the other basis (source canonical generator
/// j -> word in the target's canonical generators, both of the other basis)
/// is the same homomorphism of the surface groups as
/// to_run(theta') = T . theta' . S in the run's letters, where S writes the
/// run's source generators in the other's and T the other's target
/// generators in the run's (every word Dehn-reduced).
class OtherBasis {
 public:
  /// `sl`, `scs`: the source's loops and the run's schema of them; `tcs`:
  /// the run's target schema as the ClassSpace reads it (generators in
  /// `layout`'s letters, letters of the loops the projector reads);
  /// `tloop`: the run's target schema in those loops' letters (tcs itself
  /// on the layout's loops); `target_word`: the word of those loops (the
  /// layout's, or on the flip path the target's own class loops');
  /// `other`: the other basis's options. All references must outlive the
  /// object.
  OtherBasis(int genus, const SystemOfLoops& sl, const CanonicalSchema& scs, const CanonicalSchema& tcs,
             const CanonicalSchema& tloop, const Word& target_word, const DiskLayout& layout, const DeckGroup& group,
             const CanonicalSchemaOptions& other);

  /// "classical" or "short": the basis these classes are listed in.
  const std::string& name() const { return name_; }
  const ClassSpace& space() const { return *space_; }
  /// The other basis's source schema (for its handle basis) and target
  /// schema in the target loops' letters (for the target's handle basis).
  const CanonicalSchema& source_schema() const { return scs_; }
  const CanonicalSchema& target_loop_schema() const { return tloop_; }
  /// theta' (other basis) as the same homomorphism in the run's basis.
  GroupMap to_run(const GroupMap& theta_other) const;
  /// A run class as the same homomorphism in the other basis.
  GroupMap from_run(const GroupMap& theta_run) const;
  /// Issue 13 (session 27): an automorphism of the run's source letters
  /// (`source`) or target letters as the same automorphism in the other
  /// basis's letters (S phi S^-1, T^-1 psi T), so that theta' composed
  /// with it is to_run's theta composed with `phi` (a one-sided move of the
  /// twist search, TwistSearchOptions::source_moves).
  SurfaceAutomorphism automorphism_from_run(const SurfaceAutomorphism& phi, bool source) const;
  /// A run class in the short basis when `other` is the short one (where
  /// its twist search runs: HomotopyClass::other_basis_map), else empty
  /// (no other basis, or the run's own basis is the short one).
  static GroupMap short_form(const OtherBasis* other, const GroupMap& theta_run);

 private:
  int n_;
  std::string name_;
  CanonicalSchema scs_;    ///< the other source schema (source loop letters)
  CanonicalSchema tloop_;  ///< the other target schema (the target loops' letters)
  CanonicalSchema tcs_;    ///< tloop_ with its generators in the layout's letters (ClassSpace)
  DehnReducer reduce_;     ///< canonical relator
  GroupMap run_source_in_other_, other_target_in_run_;  ///< S and T above
  GroupMap other_source_in_run_, run_target_in_other_;  ///< their inverses (from_run)
  std::unique_ptr<ClassSpace> space_;
};

/// A class listed in the other basis, written in the run's, with the tag
/// of how it was found.
struct OtherBasisClass {
  GroupMap theta;        ///< in the run's basis
  GroupMap theta_other;  ///< in the other basis
  std::string tag;
};

/// The other basis's listing: its classes and the target handle basis its
/// signed handle permutations were lifted with (for the other cuts' lifts).
struct OtherBasisListing {
  std::vector<OtherBasisClass> classes;
  HandleBasis target_basis;
};

/// The classes candidate_classes lists in `other`'s basis (overlay,
/// canonical schemata's class, signed handle permutations; no other cuts,
/// no carried or inverted class), written in the run's basis: the caller
/// keeps those new by fingerprint. `options`: the run's.
OtherBasisListing classes_in_other_basis(const OtherBasis& other, const TriMesh& source,
                                                  const SystemOfLoops& sl, const SystemOfLoops& tl,
                                                  const LoopProjector& projector, const SurfaceMapOptions& options,
                                                  SourceCuts& cuts);

}  // namespace surfmap::detail
