#include "homotopy_classes.h"

#include "other_basis.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "surfmap/error.h"
#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/topology/outer_automorphisms.h"

namespace surfmap::detail {

using hyperbolic::Mobius;

ClassSpace::ClassSpace(int genus, const SystemOfLoops& sl, const CanonicalSchema& scs, const CanonicalSchema& tcs,
                       const DiskLayout& layout, const DeckGroup& group)
    : genus_(genus), n_(2 * genus), scs_(scs), tcs_(tcs), group_(group), R_(canonical_relator(genus)),
      J_(symplectic_form(genus)), reduce_canonical_(R_), reduce_target_loops_(layout.word),
      lengths_(group, tcs.generators, layout.word) {
  loop_length_.assign(sl.loops.size(), 0.0);
  for (size_t k = 0; k < sl.loops.size(); ++k)
    for (size_t q = 0; q + 1 < sl.loops[k].size(); ++q)
      loop_length_[k] += (sl.mesh.V.row(sl.loops[k][q + 1]) - sl.mesh.V.row(sl.loops[k][q])).norm();
}

std::vector<Word> ClassSpace::loop_letter_images(const GroupMap& theta) const {
  std::vector<Word> images;
  for (const Word& w : scs_.letters)
    images.push_back(reduce_target_loops_(substitute(reduce_canonical_(substitute(w, theta)), tcs_.generators)));
  return images;
}

double ClassSpace::loop_image_length(const GroupMap& theta) const {
  double total = 0;
  for (const Word& w : loop_letter_images(theta)) total += static_cast<double>(w.size());
  return total;
}

std::vector<double> ClassSpace::fingerprint(const GroupMap& theta) const {
  std::vector<Word> probes;
  for (int i = 0; i < n_; ++i) {
    probes.push_back({i + 1});
    for (int j = i + 1; j < n_; ++j) probes.push_back({i + 1, j + 1}), probes.push_back({i + 1, -(j + 1)});
  }
  // Lengths through the one length function (cyclic reduction first: the
  // images are conjugates whose matrices, multiplied out, have entries far
  // beyond the determinant's precision, and dividing the trace by a
  // round-off determinant gave lengths of 697 for 6.41).
  std::vector<double> lengths;
  for (const Word& w : probes) lengths.push_back(target_length(reduce_canonical_(substitute(w, theta))));
  return lengths;
}

bool ClassSpace::same_fingerprint(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.empty() || x.size() != y.size()) return false;
  for (size_t k = 0; k < x.size(); ++k)
    if (!std::isfinite(x[k]) || !(std::abs(x[k] - y[k]) <= 1e-6 * std::max({1.0, x[k], y[k]}))) return false;
  return true;
}

double ClassSpace::screen(const GroupMap& theta) const {
  if (loop_image_length(theta) > max_image_letters()) return std::numeric_limits<double>::infinity();
  double score = 0;
  for (size_t k = 0; k < scs_.letters.size(); ++k) {
    // source loop letter k -> target canonical word -> its geodesic length
    const double l = target_length(reduce_canonical_(substitute(scs_.letters[k], theta)));
    if (!std::isfinite(l)) return std::numeric_limits<double>::infinity();  // beyond double range
    score += l * l / std::max(loop_length_[k] * loop_length_[k], 1e-300);
  }
  return std::isfinite(score) ? score : std::numeric_limits<double>::infinity();
}

GroupMap ClassSpace::through_loop_images(const std::vector<Word>& generators, const std::vector<Word>& loop_images) const {
  GroupMap theta(n_);
  for (int j = 0; j < n_; ++j) theta[j] = dehn_reduce(substitute(substitute(generators[j], loop_images), tcs_.letters), R_);
  return theta;
}

bool ClassSpace::is_isomorphism(const GroupMap& theta) const {
  const IntMatrix M = homology_matrix(theta, n_);
  return M.transpose() * J_ * M == J_ && dehn_reduce(substitute(R_, theta), R_).empty();
}

void ClassSpace::reduce(GroupMap& theta) const {
  for (Word& w : theta) w = dehn_reduce(w, R_);
}

std::vector<double> ClassSpace::loop_image_lengths(const GroupMap& theta) const {
  std::vector<double> l;
  for (const Word& w : scs_.letters) l.push_back(target_length(reduce_canonical_(substitute(w, theta))));
  return l;
}


namespace {

size_t total_letters(const GroupMap& theta) {
  size_t total = 0;
  for (const Word& w : theta) total += w.size();
  return total;
}

// `hc` (default: a new class) set to theta, with its homology and the
// handle correspondence it induces between shb and thb.
HomotopyClass described(const GroupMap& theta, int n, const HandleBasis& shb, const HandleBasis& thb,
                        const std::string& tag, HomotopyClass hc = {}) {
  hc.map = theta;
  hc.homology = homology_matrix(theta, n);
  std::string handles;
  handle_correspondence_of(shb, thb, hc.homology, &hc.permutation, &hc.sign, &handles);
  hc.description = handles + "  [" + tag + "]";
  return hc;
}

}  // namespace

CutLifter::CutLifter(const ClassSpace& space, const TriMesh& source, int default_base, const HandleBasis& shb,
                     const HandleBasis& thb, const LoopProjector& projector, bool strict_overlay,
                     const SurfaceMapOptions& options, SourceCuts& cuts, const std::vector<HomotopyClass>& classes,
                     const OtherBasis* other, const HandleBasis* thb_other)
    : space_(space), source_(source), shb_(shb), thb_(thb), other_(thb_other ? other : nullptr),
      thb_other_(thb_other ? *thb_other : HandleBasis{}), projector_(projector), strict_overlay_(strict_overlay),
      options_(options), cuts_(cuts), bases_used_{default_base} {
  size_t longest = 0;  // total word length of the longest lifted class from the default cut
  for (const HomotopyClass& hc : classes) {
    // (Classes too twisted to be evaluated get no fingerprint.)
    known_.push_back(space.loop_image_length(hc.map) <= space.max_image_letters() ? space.fingerprint(hc.map)
                                                                                   : std::vector<double>{});
    longest = std::max(longest, total_letters(hc.map));
  }
  // Classes from another cut whose words come out much longer than any
  // from the default cut are very twisted (their energies are orders of
  // magnitude above the others'): skipped, which also keeps the twist
  // reduction (Dehn's algorithm on every try) cheap. (Lengths seen: 14..144
  // letters in genus 2 where the default cut's longest is 86.)
  const size_t n = static_cast<size_t>(space.num_letters());
  word_cap_ = std::min(4 * longest + 16 * n, 48 * n);
}

bool CutLifter::is_new(const std::vector<double>& fp) {
  for (const auto& k : known_)
    if (ClassSpace::same_fingerprint(k, fp)) return false;
  known_.push_back(fp);
  return true;
}

std::vector<HomotopyClass> CutLifter::lift(const std::vector<int>& cut_bases) {
  const int n = space_.num_letters();
  std::vector<std::pair<double, HomotopyClass>> extra;  // new lifted classes and their screening scores
  std::vector<HomotopyClass> overlaid;                  // new overlay classes from the other cuts
  std::vector<int> bases;
  for (int b : cut_bases)
    if (std::find(bases_used_.begin(), bases_used_.end(), b) == bases_used_.end())
      bases.push_back(b), bases_used_.push_back(b);
  for (int base : bases) {
    CutPrep scratch;
    const CutPrep& cp = cuts_.prepare(base, scratch);
    if (!cp.ok) continue;
    // Without a strict overlay from the default cut, the other cuts' loops
    // are overlaid too (as posed, jumps joined): which loops jump depends on
    // the cut (n_hole_torus(3, 36) -> polycube(3, 36): the geometric class
    // from 5 of 12 cuts' loops, from neither the default cut nor the lifts).
    if (!strict_overlay_) {
      ProjectedLoopsOptions po;
      po.max_jump_box = kOverlayJumpBox;
      const ProjectedLoopsResult proj = projector_.project(source_, cp.loops, po);
      if (proj.ok_with_joins) {
        GroupMap theta = compose(space_.through_loop_images(cp.generators, proj.loop_images), cp.psi);
        space_.reduce(theta);
        if (space_.is_isomorphism(theta) && space_.loop_image_length(theta) <= space_.max_image_letters() &&
            is_new(space_.fingerprint(theta))) {
          overlaid.push_back(described(theta, n, shb_, thb_,
                                       "as the shapes overlap: the loops at source vertex " + std::to_string(base) +
                                           " carried to the nearest points" + (proj.ok ? "" : ", jumps joined")));
          // (The overlay is the same class in either basis: searched in the
          // short one, stages/other_basis.h.)
          overlaid.back().other_basis_map = OtherBasis::short_form(other_, theta);
        }
      }
    }
    // In both canonical bases (stages/other_basis.h), the short one first:
    // the lifts depend on the basis, and a class lifted in both is kept as
    // the short basis's (its twist search runs there, whichever basis the
    // run uses).
    const bool other_first = other_ && other_->name() == "short";
    for (const bool in_other : {other_first, !other_first}) {
      if (in_other && (!other_ || !cp.other_ok)) continue;
      const ClassSpace& sp = in_other ? other_->space() : space_;
      for (HomotopyClass hc :
           handle_candidates(in_other ? cp.shb_other : cp.shb, in_other ? thb_other_ : thb_, options_.homotopy.candidates)) {
        if (total_letters(hc.map) > 4 * word_cap_) continue;  // composing would only make it longer
        GroupMap theta = compose(hc.map, in_other ? cp.psi_other : cp.psi);
        sp.reduce(theta);
        if (total_letters(theta) > word_cap_ || !dehn_reduce(substitute(sp.relator(), theta), sp.relator()).empty())
          continue;
        theta = reduce_separating_twists(theta, sp.genus(), [&](const GroupMap& t) { return sp.loop_image_length(t); }, 10);
        std::string tag = "lifted from the loops at source vertex " + std::to_string(base);
        if (in_other) {
          hc.other_basis_map = theta;
          theta = other_->to_run(theta);
          space_.reduce(theta);
          if (!space_.is_isomorphism(theta) || space_.loop_image_length(theta) > space_.max_image_letters()) continue;
          tag += "; listed in the " + other_->name() + " canonical basis";
        }
        if (!is_new(space_.fingerprint(theta))) continue;
        const double score = space_.screen(theta);
        extra.push_back({score, described(theta, n, shb_, thb_, tag, std::move(hc))});
      }
    }
  }
  // Only the most promising new classes get homotopy data and a coarse
  // solve (each costs about as much as the cut itself).
  std::stable_sort(extra.begin(), extra.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  // The overlay classes go first (few: most cuts' overlays coincide).
  std::vector<HomotopyClass> kept = std::move(overlaid);
  for (size_t k = 0; k < extra.size() && static_cast<int>(k) < options_.homotopy.extra_cut_classes; ++k)
    kept.push_back(std::move(extra[k].second));
  return kept;
}

namespace {

/// A candidate class with its description and ClassSpace::fingerprint.
struct NamedClass {
  GroupMap theta;
  std::string tag;
  std::vector<double> fingerprint;
};

/// Source 1 of candidate_classes: the overlay classes, new by fingerprint.
struct OverlayClasses {
  std::vector<NamedClass> classes;
  GroupMap as_posed;           // the overlay class as posed, when have_as_posed
  bool have_as_posed = false;
  bool strict = false;         // some pose overlaps within the strict gap test
};

/// The classes induced by overlaying the two shapes
/// (topology/projected_loops.h): as posed, then after the rigid alignments
/// of rotation_overlay_poses for shapes not posed alike. For a remeshed
/// copy, as posed or turned, one of them is the identity; for shapes posed
/// alike up to a rotation they send handles to the handles they overlap.
/// Each must be an isomorphism; poses whose images jump are refused by
/// project_loops (but see the joined jumps below).
OverlayClasses overlay_classes(const ClassSpace& space, const TriMesh& source, const SystemOfLoops& sl,
                               const TriMesh& target, const LoopProjector& projector) {
  const int n = space.num_letters();
  OverlayClasses out;
  // As posed twice: in the per-axis unit box, then with the boxes in
  // proportion (ProjectedLoopsOptions::uniform_box: a jittered copy of a
  // flat genus-4 plate was refused in the per-axis box and mapped by the
  // overlay of a rotation, its symmetry, 48% of the diagonal from itself).
  std::vector<OverlayPose> poses{{Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity(), "as posed"},
                                 {Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity(), "as posed, boxes in proportion", true}};
  const size_t as_posed_poses = poses.size();
  for (OverlayPose& p : rotation_overlay_poses(source, target)) poses.push_back(std::move(p));
  // (Jumps are joined in the same pass, for the fallback below.)
  ProjectedLoopsOptions plo;
  plo.max_jump_box = kOverlayJumpBox;
  const std::vector<ProjectedLoopsResult> projections = projector.project(source, sl.loops, poses, plo);
  std::vector<NamedClass>& overlays = out.classes;
  GroupMap& overlay = out.as_posed;
  overlay = GroupMap(n);
  bool& have_overlay = out.have_as_posed;
  auto collect_overlays = [&](bool joined) {
    for (size_t p = 0; p < projections.size(); ++p) {
      const ProjectedLoopsResult& proj = projections[p];
      if (!(joined ? proj.ok_with_joins && !proj.ok : proj.ok)) continue;
      const GroupMap theta = space.through_loop_images(space.source_generators(), proj.loop_images);
      if (!space.is_isomorphism(theta)) continue;
      if (p < as_posed_poses && !have_overlay) have_overlay = true, overlay = theta;
      NamedClass c{theta,
                   (p == 0   ? "as the shapes overlap: loops carried to the nearest points"
                    : p == 1 ? "as the shapes overlap: loops carried to the nearest points, boxes in proportion"
                             : "as the shapes overlap after a rotation (" + poses[p].description + ")") +
                       (joined ? ", jumps joined" : ""),
                   space.fingerprint(theta)};
      bool seen = false;
      for (const NamedClass& o : overlays) seen = seen || ClassSpace::same_fingerprint(o.fingerprint, c.fingerprint);
      if (!seen) overlays.push_back(std::move(c));
    }
  };
  collect_overlays(false);
  // No pose overlaps within the strict gap test: shapes alike in layout but
  // not in cross-section (a round tube over a square one) send a loop to the
  // nearest points of a wall on one side, then of a wall on the other
  // (n_hole_torus(3) -> polycube(3): jumps of 0.14-0.3 of the unit box on
  // every pose, so no overlay, and the lifted classes reached 4e4-1e5
  // letters, unsolvable: mean D' 123 from a twist search stuck at E 229
  // against the bound 50.3; with 0.15 resolution 32 of that pair still had
  // no joined overlay from any cut). Jumps up to kOverlayJumpBox of the box
  // are then joined by the target's shortest path between the two images; a
  // wrong join gives a non-isomorphism (refused) or one more candidate,
  // ranked by its energy like the others.
  out.strict = !overlays.empty();
  if (!out.strict) collect_overlays(true);
  return out;
}

// A class given as words (HomotopyOptions::class_words, one class of
// given_class), checked and reduced: 2g words in letters +-1..+-2g that are
// an isomorphism of the surface groups. `which` names it in the errors.
GroupMap named_class(const ClassSpace& space, const std::vector<Word>& words, const std::string& which) {
  const int n = space.num_letters();
  if (static_cast<int>(words.size()) != n)
    throw InputError(which + " must be " + std::to_string(n) + " words (" + std::to_string(words.size()) + " given)");
  for (const Word& w : words)
    for (int x : w)
      if (x == 0 || std::abs(x) > n) throw InputError(which + " must be words in letters +-1..+-" + std::to_string(n));
  GroupMap theta = words;
  space.reduce(theta);
  if (!space.is_isomorphism(theta))
    throw SolveError(which + " is not an isomorphism of the surface groups (not symplectic on homology, "
                             "or the relator's image is not trivial)");
  return theta;
}

}  // namespace

CandidateClasses candidate_classes(const ClassSpace& space, const TriMesh& source, const SystemOfLoops& sl,
                                   const HandleBasis& shb, const SystemOfLoops& tl, const CanonicalSchema& tcs,
                                   const LoopProjector& projector, const SurfaceMapOptions& options, SourceCuts& cuts,
                                   const OtherBasis* other) {
  const int n = space.num_letters();
  CandidateClasses out;
  HandleBasis& thb = out.target_basis;
  thb = handle_basis(tl.mesh, tl.loops, tcs);
  // A class named by its words (homotopy.class_words, issue 14 session 24:
  // a class of an earlier run, named so that no list index is needed): it
  // alone.
  if (!options.homotopy.class_words.empty()) {
    out.classes.push_back(described(named_class(space, options.homotopy.class_words, "homotopy.class_words"), n, shb, thb,
                                    "the class given by its words"));
    return out;
  }
  // A caller that knows the class (homotopy.images_only): it alone.
  if (options.homotopy.images_only) {
    if (options.homotopy.source_images.size() == 0)
      throw InputError("homotopy.images_only needs homotopy.source_images (a point on the target per source vertex)");
    GroupMap theta;
    if (!carried_loops_class(space, source, sl, projector, options.homotopy.source_images, &theta, &out.carried_status,
                             true))
      throw SolveError("the class given by homotopy.source_images: " + out.carried_status);
    out.carried_class = 0;
    out.classes.push_back(described(theta, n, shb, thb, "the source's loops carried to the given images"));
    return out;
  }
  // Classes given as words (homotopy.given_class: the through-shape step,
  // issue 14), 2g words each: each that is an isomorphism and new by
  // fingerprint (ranked like any candidates).
  if (!options.homotopy.given_class.empty()) {
    const std::vector<Word>& words = options.homotopy.given_class;
    if (words.size() % n != 0)
      throw InputError("homotopy.given_class must be " + std::to_string(n) + " words per class (" +
                       std::to_string(words.size()) + " given)");
    const size_t count = words.size() / n;
    const std::vector<std::string>& names = options.homotopy.given_class_names;
    if (!names.empty() && names.size() != count)
      throw InputError("homotopy.given_class_names must name each of the " + std::to_string(count) +
                       " given classes (" + std::to_string(names.size()) + " names)");
    std::vector<std::vector<double>> fingerprints;
    for (size_t k = 0; k < count; ++k) {
      const std::string which = count == 1 ? std::string("homotopy.given_class")
                                           : "homotopy.given_class's class " + std::to_string(k + 1);
      const GroupMap theta =
          named_class(space, GroupMap(words.begin() + k * n, words.begin() + (k + 1) * n), which);
      const std::vector<double> fp = space.fingerprint(theta);
      if (std::any_of(fingerprints.begin(), fingerprints.end(),
                      [&](const std::vector<double>& other) { return ClassSpace::same_fingerprint(other, fp); }))
        continue;
      fingerprints.push_back(fp);
      out.classes.push_back(described(theta, n, shb, thb,
                                      !names.empty() ? names[k]
                                      : count == 1   ? std::string("the given class")
                                                     : "the given class " + std::to_string(k + 1)));
      out.classes.back().given_class = static_cast<int>(k);
    }
    return out;
  }
  // The other direction's class alone (homotopy.reverse_class_only: the
  // two-way run's cheap check), inverted algebraically.
  if (options.homotopy.reverse_class_only) {
    const GroupMap& psi = options.homotopy.reverse_class;
    bool well_formed = static_cast<int>(psi.size()) == n;
    for (const Word& w : psi)
      for (int x : w) well_formed = well_formed && x != 0 && std::abs(x) <= n;
    if (!well_formed)
      throw InputError("homotopy.reverse_class_only needs homotopy.reverse_class: " + std::to_string(n) +
                       " words in letters +-1..+-" + std::to_string(n));
    const AutomorphismInverse inv = invert_automorphism(psi, n / 2);
    if (!inv.ok) throw SolveError("the other direction's class (homotopy.reverse_class) could not be inverted: " + inv.why);
    out.inverted_class = 0;
    out.classes.push_back(described(inv.inverse, n, shb, thb, "the other direction's class, inverted algebraically"));
    return out;
  }
  // Source 1: the classes induced by overlaying the two shapes (overlay_classes).
  const OverlayClasses ov = overlay_classes(space, source, sl, tl.mesh, projector);
  const std::vector<NamedClass>& overlays = ov.classes;
  const bool have_overlay = ov.have_as_posed;
  out.strict_overlay = ov.strict;
  if (have_overlay) {
    // The target's handles are then the overlay's images of the source's:
    // the other candidates are the overlay composed with a signed handle
    // permutation of the source (no lift on the target side, so no Torelli
    // ambiguity there), and descriptions are consistent with it.
    HandleBasis moved = shb;
    moved.P = homology_matrix(ov.as_posed, n) * shb.P;
    moved.to_canonical.map = compose(ov.as_posed, shb.to_canonical.map);
    for (Word& w : moved.to_canonical.map) w = dehn_reduce(w, space.relator());
    moved.to_canonical.inverse.clear();  // not needed for a target basis
    thb = std::move(moved);
  }
  // Source 2: handle correspondences (topology/handle_basis.h): signed
  // handle permutations between meridian/longitude bases of both surfaces
  // from linking numbers, each lifted to an exact isomorphism of the
  // canonical surface groups; of the Torelli-equivalent versions of each,
  // the one whose source loops have the shortest images (least twisted).
  std::vector<HomotopyClass>& classes = out.classes;
  classes = handle_candidates(shb, thb, options.homotopy.candidates);
  // A meridian basis none of whose candidates can be evaluated (every one's
  // source-loop images beyond max_image_letters) is replaced by the
  // canonical handles, as when its lift is refused: its classes could
  // neither be solved nor seed the lifted and searched classes (g3_3holes ->
  // g3_block on the target's unrefined loops: 4855-9654 letters;
  // docs/uniformization.md "Handle classes on the flip path").
  if (!have_overlay && thb.geometric &&
      std::none_of(classes.begin(), classes.end(),
                   [&](const HomotopyClass& hc) { return space.loop_image_length(hc.map) <= space.max_image_letters(); })) {
    thb.geometric = false;
    thb.message = "meridian basis not used: none of its candidates' source-loop images is within " +
                  std::to_string(static_cast<int>(space.max_image_letters())) + " letters";
    thb.P = IntMatrix::Identity(n, n);
    thb.to_canonical = lift_symplectic(thb.P);
    classes = handle_candidates(shb, thb, options.homotopy.candidates);
  }
  auto loop_image_length = [&](const GroupMap& theta) { return space.loop_image_length(theta); };
  for (HomotopyClass& hc : classes)
    if (space.loop_image_length(hc.map) <= space.max_image_letters())
      hc.map = reduce_separating_twists(hc.map, space.genus(), loop_image_length);
  // Named classes go in front, in order: the overlay classes, then the
  // canonical one. A named class drops the lifted ones with its homology
  // (it is the more geometric or the shorter version of that Torelli
  // coset), and is itself dropped when an earlier named class has its
  // fingerprint (the same class).
  std::vector<std::vector<double>> named_fingerprints;
  int num_named = 0;
  auto add_named = [&](const GroupMap& theta, const std::string& tag, const std::vector<double>& fp) {
    for (const auto& other : named_fingerprints)
      if (ClassSpace::same_fingerprint(other, fp)) return false;
    HomotopyClass hc = described(theta, n, shb, thb, tag);
    classes.erase(std::remove_if(classes.begin() + num_named, classes.end(),
                                 [&](const HomotopyClass& c) { return c.homology == hc.homology; }),
                  classes.end());
    classes.insert(classes.begin() + num_named, hc);
    named_fingerprints.push_back(fp);
    ++num_named;
    return true;
  };
  for (const NamedClass& c : overlays) out.overlay_classes += add_named(c.theta, c.tag, c.fingerprint) ? 1 : 0;
  // Source 3: the class of the two canonical polygon schemata, a_i -> a'_i,
  // b_i -> b'_i: short words whatever the loops look like.
  GroupMap canonical(n);
  for (int j = 0; j < n; ++j) canonical[j] = {j + 1};
  add_named(canonical, "a_i -> a'_i, b_i -> b'_i of the canonical polygon schemata", space.fingerprint(canonical));
  // Sources 1-3 again in the other canonical basis (stages/other_basis.h;
  // docs/robustness.md "Canonical generators"): the canonical class and the lifts of
  // the signed handle permutations depend on which canonical generators
  // present the groups (3holes g3 -> block g3: the classical basis's best
  // class is not listed in the short one). Each new by fingerprint and
  // within the letters a solve can evaluate is appended, so both runs list
  // the union of the two bases' classes.
  HandleBasis thb_other;
  if (other) {
    std::vector<std::vector<double>> known;
    for (const HomotopyClass& hc : classes)
      known.push_back(space.loop_image_length(hc.map) <= space.max_image_letters() ? space.fingerprint(hc.map)
                                                                                   : std::vector<double>{});
    OtherBasisListing listing = classes_in_other_basis(*other, source, sl, tl, projector, options, cuts);
    thb_other = std::move(listing.target_basis);
    for (OtherBasisClass& c : listing.classes) {
      space.reduce(c.theta);
      if (!space.is_isomorphism(c.theta) || space.loop_image_length(c.theta) > space.max_image_letters()) continue;
      const std::vector<double> fp = space.fingerprint(c.theta);
      const auto same = std::find_if(known.begin(), known.end(),
                                     [&](const std::vector<double>& k) { return ClassSpace::same_fingerprint(k, fp); });
      if (same != known.end()) {
        // Listed in both: searched in the short basis whichever the run's
        // (class_search.h; the twists depend on the basis).
        HomotopyClass& both = classes[same - known.begin()];
        if (other->name() == "short" && both.other_basis_map.empty()) both.other_basis_map = c.theta_other;
        continue;
      }
      known.push_back(fp);
      HomotopyClass hc;
      hc.other_basis_map = std::move(c.theta_other);
      classes.push_back(
          described(c.theta, n, shb, thb, c.tag + "; listed in the " + other->name() + " canonical basis", std::move(hc)));
    }
  }
  // Source 4: lifted classes from homotopy.extra_cuts other source cuts
  // (CutLifter), new by fingerprint, at most homotopy.extra_cut_classes,
  // lowest screen first. Base vertices spread over the vertex list
  // (deterministic); not the farthest points: those are the shape's
  // extremities, where the loops come out long and skewed (the demo pair:
  // no geometric class from the two farthest; from 3 of 7 spread ones).
  if (options.homotopy.extra_cuts > 0) {
    out.lifter = std::make_unique<CutLifter>(space, source, sl.base_vertex, shb, thb, projector, out.strict_overlay,
                                             options, cuts, classes, other, other ? &thb_other : nullptr);
    for (HomotopyClass& hc : out.lifter->lift(spread_bases(source.num_vertices(), options.homotopy.extra_cuts)))
      classes.push_back(std::move(hc));
  }
  // Further candidate sources append their classes here (each new by
  // fingerprint; the ranking solves whatever is listed).
  // Source 5 (issue 14, the two-way run; docs/handle_classes.md): the
  // source's loops carried by the inverse of a target -> source map. Listed
  // even when its fingerprint is known: it must sit right after the one-way
  // candidates (a requested class index there is this class).
  if (options.homotopy.source_images.size() > 0) {
    GroupMap theta;
    if (carried_loops_class(space, source, sl, projector, options.homotopy.source_images, &theta, &out.carried_status)) {
      out.carried_class = static_cast<int>(classes.size());
      classes.push_back(described(theta, n, shb, thb, "the source's loops carried by the target -> source map"));
      classes.back().other_basis_map = OtherBasis::short_form(other, theta);
    }
  }
  // Source 6 (issue 14; docs/handle_classes.md "Both directions"): the
  // other direction's chosen class inverted algebraically (no map to carry
  // loops through: it works where the reverse map is too distorted).
  if (!options.homotopy.reverse_class.empty()) {
    const GroupMap& psi = options.homotopy.reverse_class;
    bool well_formed = static_cast<int>(psi.size()) == n;
    for (const Word& w : psi)
      for (int x : w) well_formed = well_formed && x != 0 && std::abs(x) <= n;
    if (!well_formed) {
      out.inverted_status = "homotopy.reverse_class must be " + std::to_string(n) + " words in letters +-1..+-" + std::to_string(n);
    } else {
      const AutomorphismInverse inv = invert_automorphism(psi, n / 2);
      if (!inv.ok) {
        out.inverted_status = "not inverted: " + inv.why;
      } else {
        out.inverted_class = static_cast<int>(classes.size());
        classes.push_back(described(inv.inverse, n, shb, thb, "the other direction's class, inverted algebraically"));
        classes.back().other_basis_map = OtherBasis::short_form(other, inv.inverse);
      }
    }
  }
  return out;
}

bool carried_loops_class(const ClassSpace& space, const TriMesh& source, const SystemOfLoops& sl,
                         const LoopProjector& projector, const Eigen::MatrixXd& images, GroupMap* theta, std::string* why,
                         bool on_target) {
  if (images.rows() != source.num_vertices() || images.cols() != 3) {
    *why = "homotopy.source_images must be #V x 3 (" + std::to_string(source.num_vertices()) + " rows), not " +
           std::to_string(images.rows()) + " x " + std::to_string(images.cols());
    return false;
  }
  try {
    TriMesh moved = source;
    moved.V = images;
    // The images of consecutive loop vertices are the ends of an edge's
    // image under a bijective map: however far apart a distorted map puts
    // them, nothing lies between them but that image, so every gap is
    // joined (by the target's shortest path; a wrong join gives a
    // non-isomorphism, refused below, or a class ranked like the others).
    ProjectedLoopsOptions plo;
    plo.max_gap_factor = 1e6;
    plo.max_jump_box = 2.0;
    plo.source_on_target = on_target;
    // Joined first by the fewest target edges; when that gives no
    // isomorphism, again by the shortest paths by length (issue 14: the
    // genus-4 sculpture's loops carried through an n-hole torus onto the
    // genus-4 CAD plate, whose faces are long fans, gave an isomorphism only
    // so; docs/history/handle_classes.md "Is a better class reachable").
    std::string failure;
    for (const bool by_length : {false, true}) {
      plo.join_by_length = by_length;
      const ProjectedLoopsResult proj = projector.project(moved, sl.loops, plo);
      if (!proj.ok_with_joins) {
        if (failure.empty()) failure = "the carried loops did not project onto the target: " + proj.message;
        continue;
      }
      const GroupMap t = space.through_loop_images(space.source_generators(), proj.loop_images);
      if (!space.is_isomorphism(t)) {
        if (failure.empty() || by_length) failure = "the carried loops do not give an isomorphism";
        continue;
      }
      *theta = t;
      return true;
    }
    *why = failure;
    return false;
  } catch (const Error& e) {
    *why = e.what();
    return false;
  }
}

}  // namespace surfmap::detail
