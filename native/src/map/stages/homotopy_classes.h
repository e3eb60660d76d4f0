#pragma once
// Stage "homotopy-class candidates" of the genus >= 2 map (docs/method.md §2.10 with
// the candidate sources of docs/method.md): which classes of maps
// source -> target are worth solving. Internal to the pipeline
// (src/map/hyperbolic_map.cpp).
#include <memory>
#include <string>
#include <vector>

#include "source_cuts.h"
#include "surfmap/map/class_lower_bound.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/topology/handle_basis.h"
#include "surfmap/topology/projected_loops.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/deck_group.h"
#include "surfmap/uniformize/layout.h"

namespace surfmap::detail {

class OtherBasis;

/// One candidate homotopy class of maps source -> target (genus >= 2):
/// `map` is the isomorphism theta of the canonical surface groups (2g
/// words: source canonical generator j -> word in the target's canonical
/// generators), `homology` its 2g x 2g action on H_1, `permutation`/`sign`
/// the handle correspondence it induces, `description` e.g. "handle 1 ->
/// handle 2, handle 2 -> handle 1 (half turn)  [how it was found]".
using HomotopyClass = HandleCandidate;

/// The two surfaces' groups and what every stage asks of a class: images of
/// the source's loops in the target's group, a fingerprint (which classes
/// are the same), a screening score (no solve), isomorphism checks.
/// Read-only after construction (safe to share between threads).
class ClassSpace {
 public:
  /// `sl`/`scs`: the source's system of loops and canonical schema;
  /// `tcs`/`layout`/`group`: the target's canonical schema, disk layout and
  /// deck group. tcs.generators are words in the letters of layout.word;
  /// tcs.letters are in the letters of the loops the projector reads (the
  /// layout's own loops, or on the flip path the target's own loops:
  /// map_support.h ClassLoops). All must outlive the ClassSpace.
  ClassSpace(int genus, const SystemOfLoops& sl, const CanonicalSchema& scs, const CanonicalSchema& tcs,
             const DiskLayout& layout, const DeckGroup& group);

  int genus() const { return genus_; }
  int num_letters() const { return n_; }  ///< 2g
  const Word& relator() const { return R_; }
  /// The source's 2g canonical generators as words in its loop letters.
  const std::vector<Word>& source_generators() const { return scs_.generators; }

  /// Source loop letter k (#loops) as a word in the target's loop letters
  /// under theta, reduced after each substitution (the unreduced product
  /// grows like the product of the substitutions' lengths).
  std::vector<Word> loop_letter_images(const GroupMap& theta) const;
  /// Total letters of loop_letter_images.
  double loop_image_length(const GroupMap& theta) const;
  /// Classes whose loops' images are longer than this (summed over the 2g
  /// loops) are not evaluated: their deck elements would be products of
  /// hundreds of side pairings per edge, far beyond double precision (the
  /// solve refuses points beyond ~70 hyperbolic units); the classes that
  /// solve have a few hundred letters at most.
  double max_image_letters() const { return 500.0 * n_; }
  /// Translation length in the target's metric of the closed geodesic
  /// freely homotopic to `canonical_word` (target canonical letters): the
  /// one length function of the pipeline (SurfaceGroupLengths::length:
  /// cyclically reduced, 2 arccosh(|tr|/2) of the SU(1,1) matrix); NaN when
  /// too long to evaluate.
  double target_length(const Word& canonical_word) const { return lengths_.length(canonical_word); }
  /// Fingerprint: target lengths of the images of x_j and x_i x_j^±1
  /// (conjugation invariant, so equal for every representative of an outer
  /// class; Torelli-different classes differ here). Equal fingerprints: the
  /// same class, or classes differing by an isometry of the target.
  std::vector<double> fingerprint(const GroupMap& theta) const;
  static bool same_fingerprint(const std::vector<double>& x, const std::vector<double>& y);
  /// Screening score: sum over the source's loops of (target length of its
  /// image / its source length)^2, a rough stand-in for the energy (a map's
  /// energy is at least the squared length of any curve's image over the
  /// curve's extremal length); +inf when the images are too long to
  /// evaluate. Measured to order the twist neighbours of a class like their
  /// coarse energies.
  double screen(const GroupMap& theta) const;
  /// theta_j = generators[j] with loop letters replaced by `loop_images`
  /// (words in the target's loop letters), in target canonical letters,
  /// Dehn-reduced.
  GroupMap through_loop_images(const std::vector<Word>& generators, const std::vector<Word>& loop_images) const;
  /// Symplectic on homology and the relator's image trivial.
  bool is_isomorphism(const GroupMap& theta) const;
  /// Dehn-reduces every word of theta (canonical relator).
  void reduce(GroupMap& theta) const;
  /// Translation lengths (target metric) of the images of the source's loop
  /// letters: a lower bound, over all conjugates of theta, of how far the
  /// deck elements of the edges crossing the cut move the origin (a solve
  /// from the origin refuses them beyond HyperbolicHarmonicOptions::
  /// max_start_edge_size).
  std::vector<double> loop_image_lengths(const GroupMap& theta) const;

 private:
  int genus_, n_;
  const CanonicalSchema& scs_;
  const CanonicalSchema& tcs_;
  const DeckGroup& group_;
  Word R_;
  IntMatrix J_;
  DehnReducer reduce_canonical_, reduce_target_loops_;
  std::vector<double> loop_length_;  ///< #loops 3D length of the source's loops
  SurfaceGroupLengths lengths_;      ///< the target's lengths (canonical letters)
};

/// Jumps of a projected loop up to this fraction of the unit box are
/// joined by the target's shortest path when no pose overlaps strictly
/// (topology/projected_loops.h; see candidate_classes).
constexpr double kOverlayJumpBox = 0.25;

/// Lifted classes from other source cuts (other Torelli representatives of
/// the same signed handle permutations, sometimes the geometric one where
/// the default cut gives none: double_torus_g2 -> vase_g2, energy 66.9 and
/// mean D' 5.4 from the default cut, 26.0 and 1.36 from the cut at vertex
/// 2000), carried to the default cut's generators by the identity overlay
/// of the source onto itself; without a strict overlay, the other cuts'
/// loops are overlaid too. Only classes new by fingerprint are returned.
class CutLifter {
 public:
  /// `classes`: the candidates so far (their fingerprints are known, and
  /// the longest of them caps the words accepted from other cuts).
  /// `other` (optional, with `thb_other`, the target's handle basis in it):
  /// each cut's signed handle permutations are lifted in the other
  /// canonical basis too (CutPrep::psi_other), written in the run's.
  CutLifter(const ClassSpace& space, const TriMesh& source, int default_base, const HandleBasis& shb,
            const HandleBasis& thb, const LoopProjector& projector, bool strict_overlay, const SurfaceMapOptions& options,
            SourceCuts& cuts, const std::vector<HomotopyClass>& classes, const OtherBasis* other = nullptr,
            const HandleBasis* thb_other = nullptr);
  /// The new classes from the cuts at `cut_bases` not lifted from before:
  /// overlay classes first, then at most homotopy.extra_cut_classes lifted
  /// ones, lowest screen first.
  std::vector<HomotopyClass> lift(const std::vector<int>& cut_bases);

 private:
  bool is_new(const std::vector<double>& fp);
  const ClassSpace& space_;
  const TriMesh& source_;
  const HandleBasis shb_;  // (copies: the caller's may move)
  const HandleBasis thb_;
  const OtherBasis* other_;
  HandleBasis thb_other_;
  const LoopProjector& projector_;
  bool strict_overlay_;
  const SurfaceMapOptions& options_;
  SourceCuts& cuts_;
  std::vector<std::vector<double>> known_;  ///< fingerprints of the classes listed so far
  size_t word_cap_ = 0;
  std::vector<int> bases_used_;
};

/// The candidate classes, in order (docs/method.md §2.10):
/// (0) the overlay classes (the source's loops carried to the nearest
/// target points, as posed and after rigid alignments; the identity for a
/// remeshed copy), (1) a_i -> a'_i, b_i -> b'_i of the canonical polygon
/// schemata, (2...) signed handle permutations lifted to isomorphisms and
/// shortened over separating twists, then lifted classes from
/// homotopy.extra_cuts other cuts. Classes with the homology of a named
/// (overlay / canonical) class are dropped.
struct CandidateClasses {
  std::vector<HomotopyClass> classes;
  /// The target's handle basis the descriptions use (the overlay's images
  /// of the source's handles when there is an overlay class).
  HandleBasis target_basis;
  /// An overlay within the strict jump test exists (else jumps were joined).
  bool strict_overlay = false;
  /// How many of the first classes are overlay classes (0: the shapes do not
  /// overlap, the canonical class is first).
  int overlay_classes = 0;
  /// Lifts from more cuts later (the class search); null when
  /// homotopy.extra_cuts is 0.
  std::unique_ptr<CutLifter> lifter;
  /// With homotopy.source_images (the two-way run, issue 14): the index of
  /// the carried loops' class (-1: none), or why there is none.
  int carried_class = -1;
  std::string carried_status;
  /// With homotopy.reverse_class (issue 14): the index of its algebraic
  /// inverse (-1: none), or why there is none.
  int inverted_class = -1;
  std::string inverted_status;
};

/// `sl`/`shb`: the source's default loops and handle basis; `tl`: the
/// target's (refined) loops; `projector`: the target's loop projector (must
/// outlive the result's lifter, as must everything else passed). `other`
/// (optional, stages/other_basis.h): the classes the same sources give in
/// the other canonical basis are listed too (after the canonical class,
/// before the other cuts' lifts), those new by fingerprint, so that the
/// list does not depend on which basis the run uses (docs/robustness.md
/// "Canonical generators").
CandidateClasses candidate_classes(const ClassSpace& space, const TriMesh& source, const SystemOfLoops& sl,
                                   const HandleBasis& shb, const SystemOfLoops& tl, const CanonicalSchema& tcs,
                                   const LoopProjector& projector, const SurfaceMapOptions& options, SourceCuts& cuts,
                                   const OtherBasis* other = nullptr);

/// The class of the source's loops `sl` carried to `images` (per source
/// vertex a point on the target, #V x 3: the inverse of a target -> source
/// map from another run), as an overlay onto the target's loops
/// (`projector`), every gap joined: the source's canonical generator ->
/// target canonical word. False with `why` when the loops do not carry or
/// the result is not an isomorphism. No inversion of words is needed: the
/// other run's map is a bijection, so its inverse carries loops without
/// jumps (docs/handle_classes.md). `on_target`: the images are exact
/// points of the target, projected in its own box frame
/// (ProjectedLoopsOptions::source_on_target; homotopy.images_only).
bool carried_loops_class(const ClassSpace& space, const TriMesh& source, const SystemOfLoops& sl,
                         const LoopProjector& projector, const Eigen::MatrixXd& images, GroupMap* theta, std::string* why,
                         bool on_target = false);

}  // namespace surfmap::detail
