#pragma once
// The common subdivision of a genus-0 mesh's input faces and the intrinsic
// triangulation its spherical uniformization embeds (docs/uniformization.md,
// "Genus 0", "The common subdivision"; issue 13 items 2 and 5).
//
// spherical_uniformization with flips embeds intrinsic_faces in the sphere,
// not the input faces. The conformal map φ from the input faces to the
// sphere is the flip log (SphericalUniformization::flip_log / frame_log)
// read forwards: every step is projective on the triangles it touches (a
// Ptolemy flip in the light-cone picture, an exact flip by unfolding the quad
// in the plane, a frame change by scaling the vertex vectors), so an input
// edge is a straight segment inside every intrinsic triangle it crosses and
// an intrinsic edge a straight segment inside every input face. Replaying the
// log once and keeping, per current triangle, the pieces of input edges that
// cross it (their ends: a corner, or a crossing with a current edge, with the
// crossing's parameter t along the input edge and its weights on the current
// edge's two vertex vectors) gives every crossing of an input edge with an
// intrinsic edge exactly, without tracing or point location:
//   * a frame change g multiplies a crossing's weights by e^{-g} (the same
//     ray in the new vertex vectors);
//   * a flip of s–t in the quad (k, s, m, t) merges the two pieces of an
//     input edge that met on s–t, and splits the merged piece where it meets
//     the new diagonal k–m (the ray picture of the quad is one projective
//     plane: the point λ on the segment between the two ends' rays with
//     zero determinant against k and m);
//   * t is affine in the unnormalised ray along an input edge (its point t is
//     the ray (1 − t) v_A + t v_B of the input frame), so the split's t is
//     the same combination of its ends' t.
// At the end each crossing lies on an edge (a, b) of intrinsic_faces with
// weights (w_a, w_b): on the sphere it is the central projection of
// w_a x_a + w_b x_b (x: the sphere positions).
#include <vector>

#include <Eigen/Core>

#include "surfmap/uniformize/spherical.h"

namespace surfmap {

/// One crossing of an input edge (A, B), A < B, with an intrinsic edge
/// (a, b) of intrinsic_faces: the input edge's point (1 − t) A + t B, and
/// the ray w_a x_a + w_b x_b on the sphere.
struct SubdivisionCrossing {
  int A = -1, B = -1;
  double t = 0;
  int a = -1, b = -1;
  double wa = 0, wb = 0;
  int flip = -1;  ///< the flip of the log that made it (diagnostics)
};

/// One end of a piece of an input edge inside an intrinsic face: an input
/// vertex (a corner of that face) or a crossing.
struct SubdivisionEnd {
  int vertex = -1;    ///< input vertex id, or -1
  int crossing = -1;  ///< index into SphericalSubdivision::crossings, or -1
};

/// The piece of input edge (A, B) (A < B) inside one intrinsic face, from
/// ends[0] (the smaller t) to ends[1].
struct SubdivisionSegment {
  int A = -1, B = -1;
  SubdivisionEnd ends[2];
};

struct SphericalSubdivision {
  std::vector<SubdivisionCrossing> crossings;
  /// Per intrinsic face (row of intrinsic_faces, #F): the pieces of input
  /// edges crossing it (none: the face lies inside one input face).
  std::vector<std::vector<SubdivisionSegment>> segments;
  /// Per input edge (A, B) with A < B: its crossings sorted by t (empty: the
  /// input edge is an edge of intrinsic_faces).
  std::vector<std::vector<int>> crossings_of_edge;  ///< indexed by the input Connectivity's edge id
  int flips_replayed = 0;
};

/// s: a converged spherical_uniformization with flips (non-empty frame_log);
/// input_faces: the mesh's faces. crossings_of_edge is indexed by the edge
/// ids of Connectivity(input_faces). Throws SolveError when the log does not match the faces or a flip's quad
/// has a repeated corner (a Δ-complex quad; no common subdivision then).
SphericalSubdivision spherical_common_subdivision(const SphericalUniformization& s, const RowMatrixX3i& input_faces);

/// A face of the common subdivision: a convex polygon inside one input face
/// and one intrinsic face, its corners counter-clockwise (input vertices and
/// crossings).
struct SubdivisionPiece {
  int input_face = -1;
  int intrinsic_face = -1;
  std::vector<SubdivisionEnd> corners;
};

/// Every piece of the common subdivision: each intrinsic face (row of
/// intrinsic_faces) cut along the input edges' segments inside it, each
/// piece named by the input face on its side of those segments (the face to
/// the left of A -> B holds the halfedge A -> B). Throws SolveError when the
/// segments do not cut a face consistently.
std::vector<SubdivisionPiece> subdivision_pieces(const SphericalSubdivision& sub, const RowMatrixX3i& intrinsic_faces,
                                                 const RowMatrixX3i& input_faces, int num_vertices);

}  // namespace surfmap
