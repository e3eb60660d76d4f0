#pragma once
// Points of the genus-0 uniformization carried back onto the user's faces
// (docs/uniformization.md, "Genus 0"; issue 13 item 5).
//
// spherical_uniformization with flips embeds its intrinsic triangulation
// (SphericalUniformization::intrinsic_faces) in the sphere, not the input
// faces: an input face drawn as the chord triangle of its vertices' images
// can be inverted. A point of the sphere located in an intrinsic face (the
// central projection onto its chord triangle, SphereLocator) is carried
// back through the recorded flips and frame changes (flip_log, frame_log)
// exactly as IntrinsicCorrespondence does for genus >= 1: the sphere's
// chord triangles are triangles of null vectors (x, 1) of R^{3,1} with the
// chord lengths as Penner coordinates, so a frame change multiplies the
// barycentrics by e^{g_v}, a Ptolemy flip is undone with the light-cone
// Gram matrix and an exact flip by unfolding the quad in the plane. The
// composition is continuous across edges and orientation-preserving: the
// located points form a bijection onto the input faces, with no vertex
// re-placed.
#include <vector>

#include <Eigen/Core>

#include "surfmap/uniformize/intrinsic_loops.h"
#include "surfmap/uniformize/spherical.h"

namespace surfmap {

class SphericalCorrespondence {
 public:
  /// s: a converged spherical_uniformization with flips (non-empty
  /// frame_log); input_faces: the mesh's faces. Throws InputError when the
  /// log does not lead from input_faces to s.intrinsic_faces.
  SphericalCorrespondence(const SphericalUniformization& s, const RowMatrixX3i& input_faces);

  /// The point with barycentrics b (central projection onto the chord
  /// triangle, summing to 1) in intrinsic face f, on the input faces.
  FacePoint to_input(int f, const Eigen::Vector3d& b) const;

 private:
  const std::vector<SphereFlip>& flips_;
  const std::vector<SphereFrameChange>& frames_;
  RowMatrixX3i final_;
  RowMatrixX3i rows_end_;         // the log's rows after its last flip
  std::vector<int> final_rot_;    // rows_end_(f, (c + r) % 3) == final_(f, c)
  std::vector<int> rot0_, rot1_;  // per flip: the faces' rows before it, rotated likewise
  std::vector<std::vector<int>> flips_of_face_;
};

}  // namespace surfmap
