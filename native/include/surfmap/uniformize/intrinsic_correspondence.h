#pragma once
// Points of the flip-based uniformization metric expressed on the user's
// input mesh (docs/uniformization.md, "Points back on the input faces":
// projective interpolation across the flips).
//
// The flow with RicciFlowOptions::intrinsic_delaunay returns a metric on a
// flipped triangulation T' of the input's vertices, with its flips recorded
// (RicciFlowResult::flip_history). A point of T' is carried back to an input
// face in two steps, each a bijection that is continuous across edges:
//  1. Frame change. In the light-cone picture (Penner) a triangle with
//     Penner lengths x_ij (Euclidean: the lengths; hyperbolic: the chords
//     2 sinh(l/2), for which the triangle of chords is the Klein-projective
//     image of the hyperbolic triangle) is the affine plane through null
//     vectors v_i with −2<v_i, v_j> = x_ij², and a point is the ray Σ b_i v_i.
//     Vertex scaling x_ij = e^{(u_i+u_j)/2} x⁰_ij multiplies v_i by e^{u_i},
//     so the point with barycentrics b in the final metric has barycentrics
//     b⁰_i ∝ b_i e^{u_i} in the u = 0 frame of the same face.
//  2. The flips undone, newest first: a point of a new triangle of a flip's
//     quad is written in the old triangle that contains it, by solving
//     G_T c = G_{T,T'} b with the Gram matrices of the quad's four corner
//     vectors (Ptolemy flips: null vectors, G_ij = −x⁰_ij²/2; exact
//     hyperbolic flips: hyperboloid points, G_ij = −1 − x⁰_ij²/2, G_ii = −1;
//     exact Euclidean flips: the quad unfolded in the plane).
// Flips made after the solve in the final metric (EdgeFlip::final_frame,
// uniformize/simplicial_flips.h) come last and are undone first, before
// the frame change, as exact flips of the final metric.
// The flips a point passes through are found per face id (flips reuse the
// ids of the two faces they replace), so carrying a point costs the flips
// it crosses, not the length of the history.
#include <vector>

#include <Eigen/Core>

#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/uniformize/intrinsic_loops.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {

namespace detail {
/// One flip undone for a point: slot weights w (k, s, m, t) of a point of
/// the flip's quad written as barycentrics of its old triangle `side`
/// (0: (k, s, t), 1: (m, t, s); slot order), summing to 1 (negative outside
/// it). plane: exact Euclidean flip (the quad unfolded in the plane);
/// otherwise the Gram matrix of the corner vectors (fl.exact: hyperboloid
/// points, else null vectors of a Ptolemy flip).
Eigen::Vector3d old_triangle_weights(const EdgeFlip& fl, bool plane, int side, const Eigen::Vector4d& w);
}  // namespace detail

class IntrinsicCorrespondence {
 public:
  /// flow: a result of ricci_flow with intrinsic_delaunay (its faces, u,
  /// flip_history and background; flips == flip_history.size()); the input
  /// faces are flow's faces before the first flip. Throws InputError when
  /// the flip history does not match flow.flips.
  explicit IntrinsicCorrespondence(const RicciFlowResult& flow);

  /// A point of face f of the final triangulation (flow.faces), barycentric
  /// in the final metric's triangle (hyperbolic: the chord triangle, as
  /// uniformize/intrinsic_loops.h places points), expressed on the input
  /// faces. Weights are clamped to >= 0 and sum to 1.
  FacePoint to_input(int f, const Eigen::Vector3d& barycentric) const;

  /// The same for a point given in the u = 0 frame of face f of the
  /// solve's final triangulation (before any final-frame flip; no frame
  /// change): only the solve's flips are undone.
  FacePoint undo_flips(int f, const Eigen::Vector3d& barycentric) const;

  int num_flips() const { return static_cast<int>(flips_.size()); }

 private:
  /// Undoes the flips with index in [stop, time) that the point crosses.
  FacePoint undo_range(FacePoint p, int stop, int time) const;

  std::vector<EdgeFlip> flips_;
  int solve_flips_ = 0;     // flips_[solve_flips_..] are final-frame flips
  RowMatrixX3i solve_faces_;  // the faces before the final-frame flips
  std::vector<std::vector<int>> flips_of_face_;  // per face id: flips that rewrote it, ascending
  RowMatrixX3i faces_;
  Eigen::VectorXd u_;
  Background background_;
};

}  // namespace surfmap
