#pragma once
// The homotopy class "as the two shapes overlap" (docs/method.md §2.10: handles go
// to the geometrically corresponding handles when two objects are posed
// alike). Both shapes are normalised to the unit box (per-axis bounding-box
// scaling about the box centre); every vertex of each source loop is sent to
// the nearest target vertex, consecutive images are joined by shortest edge
// paths of the target, and the class of each closed image path is read off
// as the product of the target's edge elements (topology/edge_homotopy.h: a
// word in the target's loop letters, based at the target's base vertex up
// to one common conjugation). For a remeshed or jittered copy of a surface
// this is exactly the identity class; for two different shapes in the same
// pose it is the class a nearest-point correspondence induces. When the
// shapes do not overlap well the images jump and the result is refused
// (`ok` false) rather than guessed. The caller still verifies that the
// loop images define an isomorphism (relator image trivial, symplectic
// homology).
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/topology/words.h"

namespace surfmap {

struct ProjectedLoopsOptions {
  /// Longest edge path (in edges) allowed between the images of two
  /// consecutive loop vertices, relative to the ratio of mean edge lengths
  /// (default 6: images that jump further mean the shapes do not overlap).
  double max_gap_factor = 6.0;
  /// When > 0, consecutive images up to this far apart in the unit box are
  /// joined too (by the target's shortest path, at most about twice as
  /// long), whatever max_gap_factor allows (default 0: off; see
  /// ProjectedLoopsResult::ok_with_joins). The nearest point jumps where a
  /// loop crosses the target's medial axis (a round tube over a square one:
  /// from one wall to the opposite one); the join is then a guess that the
  /// caller must verify.
  double max_jump_box = 0.0;
  /// Linear maps applied to the source's and the target's vertices before
  /// the per-axis box normalisation (default identity: the shapes as posed).
  /// A rigid alignment of shapes not posed alike (rotation_overlay_poses)
  /// rotates the source into the target's frame of principal axes, and the
  /// target into that frame too, so that the boxes are taken along the
  /// principal axes.
  Eigen::Matrix3d source_transform = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d target_transform = Eigen::Matrix3d::Identity();
  /// Normalise both boxes by their longest side instead of per axis (default
  /// false), keeping each shape's proportions. The per-axis box stretches a
  /// flat shape's thickness to its length: on a genus-4 plate (9.7 x 2.8 x
  /// 0.9) a hole's inner wall and the plate's end wall, 0.76 apart, became
  /// one target edge apart, while the coarse target's vertices were a third
  /// of the box apart across the thickness, so a jittered loop vertex's
  /// nearest target vertex crossed the wall and the overlay as posed was
  /// refused (docs/handle_classes.md "Overlay in proportion").
  bool uniform_box = false;
  /// The source's vertices are already points of the target (a map's
  /// images): they are put in the target's box frame instead of their own,
  /// so a vertex placed exactly on a target vertex lands on it (default
  /// false). The doubles of open surfaces need it: their two sheets are
  /// 1e-6 of the diagonal apart (docs/open_surfaces.md "Doubling").
  bool source_on_target = false;
  /// Join consecutive images by the shortest path by length in the box
  /// frame (A*, within 2 x the straight line plus the ordinary gap) instead
  /// of the fewest edges (default false). For a surface carried onto a
  /// refinement of itself (the same vertices first, its edges split: the
  /// source's own uniformized copy, map/class_bound_support.h): a split edge
  /// is the shortest path between its ends, while the fewest edges can run
  /// around a hole of a CAD part (the genus-4 plate's loop came out
  /// contractible).
  bool join_by_length = false;
  /// The source is the target's own mesh (the same vertices at the same
  /// positions: another system of loops on one surface, e.g. the map's other
  /// cuts of the source): every loop vertex is its own image, with no box
  /// frame or nearest-vertex search (issue 19: those were most of a
  /// self-projection's cost). Checked (same vertex positions and face
  /// count) and used only with join_by_length, max_jump_box and
  /// source_on_target off; otherwise ignored. Default false.
  bool own_mesh = false;
};

struct ProjectedLoopsResult {
  /// Every gap passed the test of max_gap_factor.
  bool ok = false;
  /// Every gap passed it or was a jump joined under max_jump_box (then
  /// loop_images is filled but `ok` is false: a guess to verify).
  bool ok_with_joins = false;
  std::string message;
  /// Per source loop: its image's class as a Dehn-reduced word in the
  /// target's loop letters (relator: the target's boundary word); filled
  /// when ok_with_joins.
  std::vector<Word> loop_images;
  /// Longest edge path used to join consecutive images (within the
  /// ordinary gap test).
  int longest_gap = 0;
  /// Jumps beyond it joined under ProjectedLoopsOptions::max_jump_box.
  int joined_jumps = 0;
};

/// `source`: the mesh of `source_loops` (closed vertex paths); `target`: the
/// target's system of loops (its refined mesh carries the loops);
/// `target_word`: the boundary word used as the target's relator.
/// `target_conn` (optional): Connectivity(target.mesh.F), when the caller has
/// it (otherwise built here).
ProjectedLoopsResult project_loops(const TriMesh& source, const std::vector<std::vector<int>>& source_loops,
                                   const SystemOfLoops& target, const Word& target_word,
                                   const ProjectedLoopsOptions& options = {}, const Connectivity* target_conn = nullptr);

/// One rigid pose of the source relative to the target for project_loops.
struct OverlayPose {
  Eigen::Matrix3d source_transform, target_transform;
  std::string description;  ///< e.g. "principal axes, rotation 5 of 24"
  bool uniform_box = false;  ///< ProjectedLoopsOptions::uniform_box for this pose
};

/// project_loops for several poses (options.source_transform and
/// target_transform replaced by each pose's), sharing the target's edge
/// elements: one result per pose, in order.
std::vector<ProjectedLoopsResult> project_loops(const TriMesh& source, const std::vector<std::vector<int>>& source_loops,
                                                const SystemOfLoops& target, const Word& target_word,
                                                const std::vector<OverlayPose>& poses,
                                                const ProjectedLoopsOptions& options = {});

/// The same with the target's edge elements and box frame kept between
/// calls (poses sharing the target's frame, e.g. all the world-axis ones,
/// share one nearest-vertex grid; several source cuts projected onto one
/// target share everything). `target` must outlive it.
class LoopProjector {
 public:
  /// `target_conn` (optional, must outlive it): Connectivity(target.mesh.F)
  /// when the caller has it (otherwise built here).
  LoopProjector(const SystemOfLoops& target, const Word& target_word, const Connectivity* target_conn = nullptr);
  ~LoopProjector();
  ProjectedLoopsResult project(const TriMesh& source, const std::vector<std::vector<int>>& source_loops,
                               const ProjectedLoopsOptions& options = {}) const;
  std::vector<ProjectedLoopsResult> project(const TriMesh& source, const std::vector<std::vector<int>>& source_loops,
                                            const std::vector<OverlayPose>& poses,
                                            const ProjectedLoopsOptions& options = {}) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Poses to try when the shapes are not posed alike (docs/method.md §2.10): the 23
/// non-identity rotations of the cube group (signed permutation matrices of
/// determinant +1; reflections would make the overlay orientation-reversing)
/// acting on the world axes, for shapes posed along the axes but turned;
/// then, for shapes rotated by any angle, the source's principal axes
/// (eigenvectors of the area-weighted second moment of the surface, ordered
/// by eigenvalue) turned onto the target's, with the 4 right-handed sign
/// choices of the axes, boxes taken along the target's principal axes.
/// The identity pose (the plain overlay) is not included; principal-axis
/// poses are left out when a shape's eigenvalues are within
/// `axis_tolerance` (relative to the largest) of each other, as its axes
/// are then arbitrary, and when they coincide with world poses.
std::vector<OverlayPose> rotation_overlay_poses(const TriMesh& source, const TriMesh& target,
                                                double axis_tolerance = 0.05);

}  // namespace surfmap
