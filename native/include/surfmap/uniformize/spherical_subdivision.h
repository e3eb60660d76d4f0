#pragma once
// The common subdivision of a genus-0 mesh's input faces and the intrinsic
// triangulation its spherical uniformization embeds (docs/uniformization.md,
// "Genus 0", "The map on the common subdivision"; issue 13 items 2 and 5).
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
// intrinsic edge exactly, without tracing or point location. One exception
// is kept as a point of its own: an input edge is straight across an edge of
// the exact (Euclidean) Delaunay start, but in the light-cone picture it
// bends there, so when a Ptolemy flip removes that edge the crossing stays as
// a bend of the piece (SubdivisionCrossing::bend()); a Ptolemy flip's own
// crossings join straight (one hyperbolic picture for the whole Ptolemy part
// of the log: frame changes only rescale the vertex vectors):
//   * a frame change g multiplies a crossing's weights by e^{-g} (the same
//     ray in the new vertex vectors);
//   * a flip of s–t in the quad (k, s, m, t) merges the two pieces of an
//     input edge that met on s–t, and splits the merged piece where it meets
//     the new diagonal k–m (the ray picture of the quad is one projective
//     plane: the point λ on a straight part between two rays with zero
//     determinant against k and m); positions in the quad are corner slots,
//     not vertex ids, so a quad with a repeated corner (a Δ-complex) is
//     replayed like any other;
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
/// the ray w_a x_a + w_b x_b on the sphere. With c >= 0 it is a bend of the
/// input edge inside the intrinsic face (a, b, c) instead, the ray
/// w_a x_a + w_b x_b + w_c x_c: where the input edge crossed an edge of the
/// exact (Euclidean) Delaunay start that a Ptolemy flip removed, it is
/// straight on either side in the light-cone picture but not across.
struct SubdivisionCrossing {
  int A = -1, B = -1;
  double t = 0;
  int a = -1, b = -1;
  double wa = 0, wb = 0;
  int c = -1;      ///< >= 0: a bend inside the intrinsic face (a, b, c)
  double wc = 0;
  int flip = -1;  ///< the flip of the log that made it (diagnostics)
  bool bend() const { return c >= 0; }
};

/// One end of a piece of an input edge inside an intrinsic face: an input
/// vertex (a corner of that face) or a crossing.
struct SubdivisionEnd {
  int vertex = -1;    ///< input vertex id, or -1
  int crossing = -1;  ///< index into SphericalSubdivision::crossings, or -1
  /// Where it sits in its intrinsic face's row (a Δ-complex face can hold a
  /// vertex twice, so ids alone do not say): a vertex end's corner, or the
  /// side (corner, corner + 1) a crossing lies on; -1 when not known.
  int corner = -1;
  /// A crossing whose vertex a (SubdivisionCrossing) is at corner + 1.
  bool reversed = false;
};

/// The piece of input edge (A, B) (A < B) inside one intrinsic face, from
/// ends[0] (the smaller t) to ends[1], through its bends (crossings with
/// bend() set, in order of t): a polyline, straight between them.
struct SubdivisionSegment {
  int A = -1, B = -1;
  SubdivisionEnd ends[2];
  std::vector<int> bends;
};

struct SphericalSubdivision {
  /// The crossings and the bends (SubdivisionCrossing::bend()): every point
  /// of an input edge that is a vertex of the common subdivision.
  std::vector<SubdivisionCrossing> crossings;
  /// Per intrinsic face (row of intrinsic_faces, #F): the pieces of input
  /// edges crossing it (none: the face lies inside one input face).
  std::vector<std::vector<SubdivisionSegment>> segments;
  /// Per input edge (A, B) with A < B: its crossings and bends sorted by t
  /// (empty: the input edge is an edge of intrinsic_faces).
  std::vector<std::vector<int>> crossings_of_edge;  ///< indexed by the input Connectivity's edge id
  int flips_replayed = 0;
  int bends = 0;  ///< crossings with bend()
};

/// s: a converged spherical_uniformization with flips (non-empty frame_log);
/// input_faces: the mesh's faces. crossings_of_edge is indexed by the edge
/// ids of Connectivity(input_faces). Throws SolveError when the log does not
/// match the faces or a flip's quad is degenerate.
SphericalSubdivision spherical_common_subdivision(const SphericalUniformization& s, const RowMatrixX3i& input_faces);

/// A face of the common subdivision: a polygon inside one input face and one
/// intrinsic face, its corners counter-clockwise (input vertices, crossings
/// and bends). Convex in the intrinsic face's chart unless a bend is one of
/// its corners; in the input face every corner lies on the face's boundary.
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
