// Genus-0 uniformization: v0 at infinity -> flat punctured disk ->
// stereographic projection -> Möbius centring. See spherical.h.
#include "surfmap/uniformize/spherical.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <deque>
#include <functional>
#include <limits>
#include <queue>
#include <tuple>
#include <sstream>
#include <unordered_map>

#include <Eigen/Geometry>

#include "../seconds_since.h"
#include "ricci_core.h"
#include "surfmap/error.h"
#include "surfmap/geometry/intrinsic_delaunay.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/uniformize/simplicial_flips.h"

namespace surfmap {
namespace {


/// Ball automorphism of the unit ball sending c to 0 (keeps the unit sphere).
Eigen::Vector3d mobius(const Eigen::Vector3d& c, const Eigen::Vector3d& x) {
  const double c2 = c.squaredNorm(), x2 = x.squaredNorm();
  const Eigen::Vector3d d = x - c;
  return ((1.0 - c2) * d - d.squaredNorm() * c) / (1.0 - 2.0 * c.dot(x) + c2 * x2);
}

/// Twice the area of the triangle with side lengths a, b, c divided by c:
/// its height over side c, by Kahan's stable Heron formula (0 when the
/// lengths violate the triangle inequality by round-off).
double height_over(double a, double b, double c) {
  double s[3] = {a, b, c};
  std::sort(s, s + 3, std::greater<double>());
  const double p = (s[0] + (s[1] + s[2])) * (s[2] - (s[0] - s[1])) * (s[2] + (s[0] - s[1])) * (s[0] + (s[1] - s[2]));
  return p > 0 ? 0.5 * std::sqrt(p) / c : 0.0;
}

/// The punctured disk laid out in the plane from the faces `FL` (edges
/// `FEL`) of the (possibly flipped) triangulation the flat metric `lengths`
/// lives on; boundary edges never flip. #V' x 2. The vertex `origin` is
/// placed at exactly 0 and the layout grows outward from it, so each
/// vertex's rounding error stays relative to its distance from the origin:
/// the far end of a long shape, crowded towards 0 by a conformal factor of
/// e^-40 (a sphere stretched 20:1), keeps its shape.
///
/// Order (issue 13 item 5): a vertex r is placed from a face (s, t, r)
/// whose s and t are placed, at the foot x and height y computed from the
/// metric's three lengths alone (stable Heron), along the laid-out
/// direction of s -> t. An error of that direction then moves r by about
/// max(|sr|, |tr|) / |st| times as much, so the faces are taken cheapest
/// first (Dijkstra on the accumulated log of 1 + that ratio) instead of
/// breadth first: a breadth-first layout of the bent, tapered 10:1 sphere
/// went through chains of 179.9° slivers at its crowded end, each
/// multiplying the error, and laid out 395 faces inverted although the
/// metric was flat with a convex boundary.
Eigen::MatrixX2d lay_out_flat_disk(const RowMatrixX3i& FL, const RowMatrixX3i& FEL, const Eigen::VectorXd& lengths,
                                   int n2, int origin) {
  const int nf2 = static_cast<int>(FL.rows());
  std::vector<std::vector<int>> faces_of_vertex(n2);
  for (int f = 0; f < nf2; ++f)
    for (int k = 0; k < 3; ++k) faces_of_vertex[FL(f, k)].push_back(f);
  Eigen::MatrixX2d P = Eigen::MatrixX2d::Zero(n2, 2);
  std::vector<char> placed(n2, 0);
  std::vector<double> cost(n2, std::numeric_limits<double>::infinity());
  auto side = [&](int f, int k) { return lengths[FEL(f, k)]; };  // opposite corner k
  auto place_third = [&](int f, int k) {  // corner k from corners k+1, k+2 (ccw)
    const int s = FL(f, (k + 1) % 3), t = FL(f, (k + 2) % 3), r = FL(f, k);
    const Eigen::Vector2d ps = P.row(s).transpose(), pt = P.row(t).transpose();
    const double c = side(f, k), a = side(f, (k + 2) % 3), b = side(f, (k + 1) % 3);  // |st|, |sr|, |tr|
    const double x = (a * a - b * b + c * c) / (2.0 * c), y = height_over(a, b, c);
    const Eigen::Vector2d e = (pt - ps).normalized(), nrm(-e.y(), e.x());
    P.row(r) = (ps + x * e + y * nrm).transpose();
    placed[r] = 1;
  };
  // Candidates (cost, face, corner to place).
  using Candidate = std::tuple<double, int, int>;
  std::priority_queue<Candidate, std::vector<Candidate>, std::greater<Candidate>> queue;
  auto offer = [&](int f) {
    int missing = -1, count = 0;
    for (int k = 0; k < 3; ++k)
      if (!placed[FL(f, k)]) missing = k, ++count;
    if (count != 1) return;
    const int s = FL(f, (missing + 1) % 3), t = FL(f, (missing + 2) % 3);
    const double c = side(f, missing), far = std::max(side(f, (missing + 1) % 3), side(f, (missing + 2) % 3));
    queue.emplace(std::max(cost[s], cost[t]) + std::log1p(far / c), f, missing);
  };
  int f0 = 0, k0 = 0;  // a face at the origin, its corner there
  for (int f = 0; f < nf2 && FL(f0, k0) != origin; ++f)
    for (int k = 0; k < 3; ++k)
      if (FL(f, k) == origin) f0 = f, k0 = k;
  const int a0 = FL(f0, k0), a1 = FL(f0, (k0 + 1) % 3);
  P.row(a0) << 0, 0;
  P.row(a1) << side(f0, (k0 + 2) % 3), 0;
  placed[a0] = placed[a1] = 1;
  cost[a0] = cost[a1] = 0;
  offer(f0);
  while (!queue.empty()) {
    const auto [c, f, k] = queue.top();
    queue.pop();
    const int r = FL(f, k);
    if (placed[r]) continue;
    place_third(f, k);
    cost[r] = c;
    for (int g : faces_of_vertex[r]) offer(g);
  }
  return P;
}

/// The planar disk `P` (its layout origin at 0) onto the unit sphere: the
/// inverse stereographic projection of P / radius from the north pole,
/// where v0 goes; y is mirrored because a counter-clockwise layout seen
/// from +z would face inward on the southern hemisphere. `old_id`: input
/// vertex of each disk vertex.
RowMatrixX3d project_to_sphere(const Eigen::MatrixX2d& P, double radius, const std::vector<int>& old_id, int v0,
                               int nv) {
  const int n2 = static_cast<int>(P.rows());
  RowMatrixX3d positions(nv, 3);
  for (int i = 0; i < n2; ++i) {
    const double x = P(i, 0) / radius, y = -P(i, 1) / radius;
    const double q = x * x + y * y;
    // 2x / (q + 1) and 2 / (q + 1) keep their relative precision for tiny
    // and huge |x| alike (q - 1 would not, near the south pole).
    if (q > 1) positions.row(old_id[i]) << 2 * x / (q + 1), 2 * y / (q + 1), 1 - 2 / (q + 1);
    else positions.row(old_id[i]) << 2 * x / (q + 1), 2 * y / (q + 1), (q - 1) / (q + 1);
  }
  positions.row(v0) << 0, 0, 1;
  return positions;
}

/// Input vertex areas, normalised to sum 1: the weights of the centre of mass.
Eigen::VectorXd vertex_area_weights(const TriMesh& mesh) {
  Eigen::VectorXd w = Eigen::VectorXd::Zero(mesh.num_vertices());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose(),
                          b = mesh.V.row(mesh.F(f, 1)).transpose(),
                          c = mesh.V.row(mesh.F(f, 2)).transpose();
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) w[mesh.F(f, k)] += area / 3.0;
  }
  return w / w.sum();
}

/// The scale of the planar layout (origin at 0) whose projection has its
/// weighted centre of mass on the equator's plane (z = 0): the axial part of
/// the Möbius centring done as an exact dilation of the plane (bisection on
/// log radius; z of the centre falls monotonically from +1 to -1 as the
/// radius grows). Then only the small remaining Möbius step moves points
/// by arithmetic on unit vectors, which would round away the crowded ends
/// of a long shape (docs/robustness.md, "Genus 0").
double axial_centring_radius(const Eigen::MatrixX2d& P, const std::vector<int>& old_id, int v0,
                             const Eigen::VectorXd& w) {
  auto centre_z = [&](double log_r) {
    const double r2 = std::exp(2 * log_r);
    double z = w[v0];
    for (int i = 0; i < static_cast<int>(P.rows()); ++i) {
      const double q = P.row(i).squaredNorm();
      z += w[old_id[i]] * (q - r2) / (q + r2);
    }
    return z;
  };
  double lo = std::log(std::numeric_limits<double>::min()) / 2, hi = std::log(std::numeric_limits<double>::max()) / 2;
  double rmax = 0;
  for (int i = 0; i < static_cast<int>(P.rows()); ++i) rmax = std::max(rmax, P.row(i).norm());
  if (rmax > 0) lo = std::max(lo, std::log(rmax) - 300), hi = std::min(hi, std::log(rmax) + 300);
  for (int it = 0; it < 200 && hi - lo > 1e-14 * std::max(1.0, std::abs(lo)); ++it) {
    const double mid = 0.5 * (lo + hi);
    (centre_z(mid) > 0 ? lo : hi) = mid;
  }
  return std::exp(0.5 * (lo + hi));
}

/// Möbius centring of `positions` with the input's vertex areas w as
/// weights: Newton on the centre of mass m(c) of the points moved by the
/// ball automorphism sending c to 0. At c = 0 a unit point x moves by
/// −2 (I − x xᵀ) c, so dm/dc = −2 A with A = Σ_v w_v (I − x_v x_vᵀ) and the
/// step is c = A⁻¹ m / 2 (backtracking, |c| <= 1/2). The former fixed-point
/// step c = m assumed A = I/2: where the mass sits in two nearly antipodal
/// clusters (thin tubes crowded towards points of the sphere), A's smallest
/// eigenvalue is ~0.03 and that step gained only 3.5% per iteration, so
/// 500 iterations stopped at |m| ~ 1e-10 far above the rounding floor.
/// Fills out.centre_of_mass_norm, centring_iterations, centring_floor and
/// centring_stopped_at_floor; returns true when |m| reached
/// max(centring_tolerance, centring_floor), or stalled (no step decreases
/// it) below centring_floor_tolerance.
int count_inward_faces(const RowMatrixX3d& X, const RowMatrixX3i& F, int* first);

/// axial_only: c on the z axis only (it keeps the tangential coordinates'
/// relative precision at both poles); converged when the axial component
/// of the centre of mass reaches the stop, centre_of_mass_norm keeps the
/// whole residual (out.centring_axial_only). attempt() uses it when the
/// full centring inverted faces: a long shape's ends, crowded at the poles
/// to chords far below the spacing of unit vectors at a general point of
/// the sphere (e^-80 at 40:1), are rounded away by a step off the axis
/// (docs/robustness.md, "Genus 0").
bool mobius_centre(const TriMesh& mesh, const SphericalUniformizationOptions& options, RowMatrixX3d& positions,
                   SphericalUniformization& out, Eigen::VectorXd* log_scale = nullptr,
                   bool axial_only = false) {
  const int nv = mesh.num_vertices();
  const Eigen::VectorXd w = vertex_area_weights(mesh);
  auto centre_of = [&](const RowMatrixX3d& X) {
    return Eigen::Vector3d((w.transpose() * X).transpose());
  };
  // The rounding floor of |m|: every coordinate of a normalised unit vector
  // carries ~2ε (after a Möbius step, ~4ε), and the weighted sum of #V terms
  // adds up to ~ε log2(#V) (Eigen's blocked reduction), times √3 for the
  // norm of three coordinates.
  constexpr double eps = std::numeric_limits<double>::epsilon();
  out.centring_floor = std::sqrt(3.0) * eps * (4.0 + std::log2(std::max(2, nv)));
  const double stop = std::max(options.centring_tolerance, out.centring_floor);
  Eigen::Vector3d cm = centre_of(positions);
  int it = 0;
  bool stalled = false;
  const bool axial = axial_only;
  out.centring_axial_only = axial_only;
  auto residual = [&](const Eigen::Vector3d& m) { return axial ? std::abs(m.z()) : m.norm(); };
  for (; it < options.max_centring_iterations && residual(cm) > stop; ++it) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    for (int v = 0; v < nv; ++v) {
      const Eigen::Vector3d x = positions.row(v).transpose();
      A += w[v] * (Eigen::Matrix3d::Identity() - x * x.transpose());
    }
    Eigen::Vector3d step = 0.5 * A.ldlt().solve(cm);
    if (!step.allFinite()) step = cm;  // A singular (all mass at one point): the plain step
    if (axial) step = Eigen::Vector3d(0, 0, A(2, 2) > 0 ? 0.5 * cm.z() / A(2, 2) : cm.z());
    if (step.norm() > 0.5) step *= 0.5 / step.norm();
    bool improved = false;
    for (double t = 1.0; t > 1e-4 && !improved; t *= 0.5) {
      const Eigen::Vector3d c = t * step;
      RowMatrixX3d X(nv, 3);
      for (int v = 0; v < nv; ++v)
        X.row(v) = mobius(c, positions.row(v).transpose()).normalized().transpose();
      const Eigen::Vector3d cn = centre_of(X);
      if (residual(cn) < residual(cm)) {
        // The ball automorphism scales chords by sqrt(λ_x λ_y), λ_x =
        // (1 − |c|²) / |x − c|²: a frame change of the light-cone picture.
        if (log_scale)
          for (int v = 0; v < nv; ++v)
            (*log_scale)[v] += std::log1p(-c.squaredNorm()) - std::log((positions.row(v).transpose() - c).squaredNorm());
        positions = X;
        cm = cn;
        improved = true;
      }
    }
    if (!improved) {
      stalled = true;
      break;
    }
    stalled = false;
  }
  out.centring_iterations = it;
  out.centre_of_mass_norm = cm.norm();
  if (residual(cm) <= stop) return true;
  out.centring_stopped_at_floor = stalled && residual(cm) <= options.centring_floor_tolerance;
  return out.centring_stopped_at_floor;
}

int count_inward_faces(const RowMatrixX3d& X, const RowMatrixX3i& F, int* first);

/// Orientation checks on the sphere: out.flipped_faces counts the inward
/// chordal triangles of the intrinsic triangulation (the embedding; any ->
/// failure, naming the first, unless an earlier step already failed),
/// out.input_flipped_faces those of the input faces drawn as chords between
/// their vertices' images (information: with flips the input faces are
/// images of unions of pieces of intrinsic triangles, not chords).
void check_sphere_orientation(const TriMesh& mesh, SphericalUniformization& out) {
  int first_flipped = -1, first_input = -1;
  out.flipped_faces = count_inward_faces(out.positions, out.intrinsic_faces, &first_flipped);
  out.input_flipped_faces = count_inward_faces(out.positions, mesh.F, &first_input);
  if (!out.positions.allFinite()) {
    out.message = "non-finite positions on the sphere";
  } else if (out.flipped_faces > 0 && out.message.empty()) {
    out.message = "intrinsic face (" + std::to_string(out.intrinsic_faces(first_flipped, 0)) + ", " +
                  std::to_string(out.intrinsic_faces(first_flipped, 1)) + ", " +
                  std::to_string(out.intrinsic_faces(first_flipped, 2)) + ") is flipped on the sphere (" +
                  std::to_string(out.flipped_faces) + " flipped faces)";
  }
}

}  // namespace

namespace {

/// The punctured sphere during the flattening, in disk vertex ids (the
/// input's vertices without v0, renumbered; v0 itself is `pole` = #V − 1):
/// the intrinsic disk faces and the star of v0 (rows (pole, a, b)).
struct PuncturedTriangulation {
  int pole = 0;
  RowMatrixX3i disk;
  std::vector<std::array<int, 3>> star;
  /// Ring vertices' length to v0 in the current frame, scaled by the
  /// vertex-at-infinity limit (1 at the start of every round; a ring flip
  /// gives the new ring vertex its Ptolemy value).
  std::unordered_map<int, double> ring_y;
  /// Global face id (SphereFlip) of every disk row and star entry, and the
  /// input vertex id of every disk vertex (the pole: v0).
  std::vector<int> disk_gid, star_gid, input_id;
  std::vector<SphereFlip>* log = nullptr;
};

/// Appends a flip of the punctured sphere (disk ids) to pt.log: quad
/// (k, s, m, t), the rows of g0 and g1 before and after as slots.
void log_flip(PuncturedTriangulation& pt, int g0, int g1, std::array<int, 4> quad, std::array<int, 3> before0,
              std::array<int, 3> before1, std::array<int, 3> after0, std::array<int, 3> after1,
              const std::array<double, 6>& lengths, bool exact) {
  if (!pt.log) return;
  SphereFlip fl;
  fl.face0 = g0, fl.face1 = g1;
  for (int q = 0; q < 4; ++q) fl.quad[q] = pt.input_id[quad[q]];
  fl.before0 = before0, fl.before1 = before1, fl.after0 = after0, fl.after1 = after1;
  fl.lengths = lengths;
  fl.exact = exact;
  pt.log->push_back(fl);
}

/// The flips of one flow result (EdgeFlip: rows of `rows`, face ids mapped
/// by gid, vertex ids by pt.input_id) appended to pt.log; `rows` is replayed.
void log_edge_flips(PuncturedTriangulation& pt, const std::vector<EdgeFlip>& history, RowMatrixX3i rows,
                    const std::vector<int>& gid) {
  for (const EdgeFlip& rec : history) {
    const int f0 = rec.face0, f1 = rec.face1, a0 = rec.corner0, a1 = rec.corner1;
    const int k = rows(f0, a0), s = rows(f0, (a0 + 1) % 3), t = rows(f0, (a0 + 2) % 3), m = rows(f1, a1);
    std::array<int, 3> b0{}, b1{};
    b0[a0] = 0, b0[(a0 + 1) % 3] = 1, b0[(a0 + 2) % 3] = 3;
    b1[a1] = 2, b1[(a1 + 1) % 3] = 3, b1[(a1 + 2) % 3] = 1;
    log_flip(pt, gid[f0], gid[f1], {k, s, m, t}, b0, b1, {0, 1, 2}, {2, 3, 0}, rec.base_lengths,
             rec.exact || rec.final_frame);
    rows.row(f0) << k, s, m;
    rows.row(f1) << m, t, k;
  }
}

/// Ring flips of the degenerate disk triangles of `flat` that lean on the
/// ring (docs/uniformization.md, "Genus 0"): triangle (c, s1, s2) with ring
/// edge s1–s2 opposite an interior vertex c whose angle at c reached π.
/// Flipping s1–s2 in the quad (c, s1, v0, s2) gives the edge v0–c, i.e. the
/// triangle joins the star and c the ring, with the Ptolemy length
/// y_c = (l_cs1 y_s2 + l_cs2 y_s1) / l_s1s2 (the limit of the Ptolemy flip
/// with v0 at infinity; Ptolemy commutes with vertex scaling, so this is a
/// flip of the conformal class, as in the rest of the flow). Updates `pt`
/// (disk := the remaining faces of flat.faces) and returns the number of
/// flips; 0 when a degenerate triangle cannot be flipped this way.
int flip_ring_edges(const RicciFlowResult& flat, PuncturedTriangulation& pt, std::vector<int>& disk_face_kept) {
  const int nf = static_cast<int>(flat.faces.rows()), ne = static_cast<int>(flat.edge_vertices.rows());
  std::vector<int> faces_on_edge(ne, 0);
  for (int f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) ++faces_on_edge[flat.face_edges(f, k)];
  std::vector<char> removed(nf, 0);
  int count = 0;
  // Sweeps until nothing flips: a flip makes the triangle's other two edges
  // ring edges, so a degenerate neighbour behind one of them (a chain of
  // degenerate triangles reaching into the disk, as at the capped artery's
  // apex) becomes flippable in the next sweep; a single sweep left such
  // chains degenerate in the next round's input lengths.
  for (int sweep_count = -1; sweep_count != count;) {
    sweep_count = count;
    for (int f = 0; f < nf; ++f) {
      if (removed[f]) continue;
      double l[3];
      for (int k = 0; k < 3; ++k) l[k] = flat.edge_lengths[flat.face_edges(f, k)];
      const int k = static_cast<int>(std::max_element(l, l + 3) - l);
      if (l[k] < l[(k + 1) % 3] + l[(k + 2) % 3]) continue;  // not degenerate
      const int c = flat.faces(f, k), s1 = flat.faces(f, (k + 1) % 3), s2 = flat.faces(f, (k + 2) % 3);
      if (faces_on_edge[flat.face_edges(f, k)] != 1 || pt.ring_y.count(c) || !pt.ring_y.count(s1) ||
          !pt.ring_y.count(s2))
        continue;
      auto it = std::find(pt.star.begin(), pt.star.end(), std::array<int, 3>{pt.pole, s2, s1});
      if (it == pt.star.end()) continue;
      // Sides: l[(k+2)%3] joins c–s1, l[(k+1)%3] joins s2–c.
      const double ys1 = pt.ring_y[s1], ys2 = pt.ring_y[s2];
      pt.ring_y[c] = (l[(k + 2) % 3] * ys2 + l[(k + 1) % 3] * ys1) / l[k];
      // The log: quad (c, s1, v0, s2); the disk face's id goes to the new
      // star row (v0, s2, c), the old star row's to (v0, c, s1).
      const size_t star_index = static_cast<size_t>(it - pt.star.begin());
      {
        std::array<int, 3> b0{};
        b0[k] = 0, b0[(k + 1) % 3] = 1, b0[(k + 2) % 3] = 3;
        log_flip(pt, pt.disk_gid[f], pt.star_gid[star_index], {c, s1, pt.pole, s2}, b0, {2, 3, 1}, {2, 3, 0},
                 {2, 0, 1}, {l[(k + 2) % 3], ys1, ys2, l[(k + 1) % 3], l[k], pt.ring_y[c]}, false);
      }
      *it = {pt.pole, c, s1};
      pt.star.push_back({pt.pole, s2, c});
      pt.star_gid.push_back(pt.disk_gid[f]);
      removed[f] = 1;
      for (int q = 0; q < 3; ++q) --faces_on_edge[flat.face_edges(f, q)];
      ++count;
    }
  }
  disk_face_kept.clear();
  for (int f = 0; f < nf; ++f)
    if (!removed[f]) disk_face_kept.push_back(f);
  std::vector<int> kept_gid;
  for (int f : disk_face_kept) kept_gid.push_back(pt.disk_gid[f]);
  pt.disk_gid = kept_gid;
  pt.disk.resize(static_cast<int>(disk_face_kept.size()), 3);
  for (int i = 0; i < static_cast<int>(disk_face_kept.size()); ++i) pt.disk.row(i) = flat.faces.row(disk_face_kept[i]);
  return count;
}

/// Star flips at the reflex ring vertices of a converged flattening
/// (docs/uniformization.md, "Genus 0"): with v0 at infinity the edge v0–a
/// is Delaunay iff the disk's angle at the ring vertex a is at most π (the
/// two star triangles at a are the half-planes beyond the ring edges; a
/// reflex corner puts a neighbour beyond the other's line, and the star's
/// chordal triangles fold on the sphere). Flipping v0–a in the quad
/// (v0, p, a, q) gives the disk triangle (p, a, q) and the ring edge p–q of
/// Ptolemy length (l_pa y_q + l_aq y_p) / y_a = l_pa + l_aq (all y = 1 after
/// a solve): a degenerate triangle, so the next round's input frame scales
/// a's edges by vertex_scale[a] > 1 (a vertex scaling: the same conformal
/// class) to give it a strict triangle inequality. a becomes interior. Appends
/// the new faces to pt.disk and their p–q lengths to `new_sides`; returns the
/// number of flips.
int flip_star_edges(const RicciFlowResult& flat, PuncturedTriangulation& pt, std::vector<double>& vertex_scale,
                    std::vector<double>& new_sides) {
  const int nf = static_cast<int>(flat.faces.rows());
  std::vector<double> angle(pt.pole, 0.0), slack(pt.pole, 1.0);
  std::unordered_map<long long, double> length_of;
  auto key = [&](int a, int b) { return static_cast<long long>(std::min(a, b)) * pt.pole + std::max(a, b); };
  for (int f = 0; f < nf; ++f) {
    double l[3];
    for (int k = 0; k < 3; ++k) l[k] = flat.edge_lengths[flat.face_edges(f, k)];
    for (int k = 0; k < 3; ++k) {
      const double a = l[k], b = l[(k + 1) % 3], c = l[(k + 2) % 3];
      angle[flat.faces(f, k)] += std::acos(std::clamp((b * b + c * c - a * a) / (2 * b * c), -1.0, 1.0));
      // Scaling this corner's edges b, c by s keeps b + c > a; what it can
      // break is s |b - c| < a, so the relative room is (a - |b - c|) / |b - c|.
      const double spread = std::abs(b - c);
      if (spread > 0) slack[flat.faces(f, k)] = std::min(slack[flat.faces(f, k)], (a - spread) / spread);
      length_of[key(flat.faces(f, (k + 1) % 3), flat.faces(f, (k + 2) % 3))] = a;
    }
  }
  std::vector<char> touched(pt.pole, 0);
  std::vector<std::array<int, 3>> added;
  std::vector<int> added_gid;
  int count = 0;
  for (auto it = pt.star.begin(); it != pt.star.end(); ++it) {
    const int p = (*it)[1], a = (*it)[2];  // star row (pole, p, a)
    if (!(angle[a] > detail::kPi + 1e-9) || touched[a] || touched[p]) continue;
    auto next = std::find_if(pt.star.begin(), pt.star.end(), [&](const auto& r) { return r[1] == a; });
    if (next == pt.star.end()) continue;
    const int q = (*next)[2];
    if (q == p || touched[q] || length_of.count(key(p, q)) || !length_of.count(key(p, a)) ||
        !length_of.count(key(a, q)))
      continue;
    const double s = 1.0 + std::min(1e-2, 0.25 * slack[a]);
    if (!(s > 1.0)) continue;
    vertex_scale[a] = s;
    new_sides.push_back(length_of[key(p, a)] + length_of[key(a, q)]);
    added.push_back({p, a, q});
    touched[a] = touched[p] = touched[q] = 1;
    // The log: quad (p, a, q, v0), old triangles (p, a, v0) and (q, v0, a);
    // the erased star row's id goes to the new disk face (p, a, q), the
    // kept one's to (v0, p, q). All y are 1 after a solve.
    const size_t it_index = static_cast<size_t>(it - pt.star.begin()),
                 next_index = static_cast<size_t>(next - pt.star.begin());
    const int g_it = pt.star_gid[it_index], g_next = pt.star_gid[next_index];
    log_flip(pt, g_it, g_next, {p, a, q, pt.pole}, {3, 0, 1}, {3, 1, 2}, {3, 0, 2}, {0, 1, 2},
             {length_of[key(p, a)], length_of[key(a, q)], 1.0, 1.0, 1.0, new_sides.back()}, false);
    added_gid.push_back(g_next);
    *it = {pt.pole, p, q};
    pt.star.erase(next);
    pt.star_gid.erase(pt.star_gid.begin() + static_cast<std::ptrdiff_t>(next_index));
    pt.ring_y.erase(a);
    it = pt.star.begin();  // erase invalidated the iterators; touched[] keeps each vertex to one flip
    ++count;
  }
  const int old_rows = static_cast<int>(pt.disk.rows());
  pt.disk.conservativeResize(old_rows + static_cast<int>(added.size()), 3);
  for (size_t i = 0; i < added.size(); ++i) pt.disk.row(old_rows + static_cast<int>(i)) << added[i][0], added[i][1], added[i][2];
  pt.disk_gid.insert(pt.disk_gid.end(), added_gid.begin(), added_gid.end());
  return count;
}

/// The disk vertex (of `faces`, #V' = n2) farthest from v0's ring in
/// edges: where the planar layout should start (lay_out_flat_disk).
int farthest_from_ring(const RowMatrixX3i& faces, const PuncturedTriangulation& pt, int n2) {
  std::vector<std::vector<int>> nbr(n2);
  for (int f = 0; f < faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) nbr[faces(f, k)].push_back(faces(f, (k + 1) % 3));
  std::vector<int> dist(n2, -1);
  std::deque<int> queue;
  for (const auto& [v, y] : pt.ring_y) dist[v] = 0, queue.push_back(v);
  int last = queue.empty() ? 0 : queue.front();
  while (!queue.empty()) {
    last = queue.front();
    queue.pop_front();
    for (int u : nbr[last])
      if (dist[u] < 0) dist[u] = dist[last] + 1, queue.push_back(u);
  }
  return last;
}

/// Orientation of the chordal triangles `F` (vertex ids of `X`) on the
/// sphere: number of faces whose normal does not point away from the origin;
/// `first` receives the first one (-1 if none).
int count_inward_faces(const RowMatrixX3d& X, const RowMatrixX3i& F, int* first) {
  int n = 0;
  *first = -1;
  for (int f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = X.row(F(f, 0)).transpose(), b = X.row(F(f, 1)).transpose(),
                          c = X.row(F(f, 2)).transpose();
    if (!((b - a).cross(c - a).dot(a + b + c) > 0.0)) {
      ++n;
      if (*first < 0) *first = f;
    }
  }
  return n;
}

}  // namespace

namespace {

/// The sphere with v0 removed: the punctured disk pt (vertices renumbered
/// without v0, which becomes the pole n2 = #V - 1), the sides of its faces
/// (disk_sides, per pt.disk row, side opposite corner k) and the start u
/// (#V - 1) of the Dirichlet flow.
struct PuncturedDisk {
  int v0 = 0, n2 = 0;
  std::vector<int> new_id, old_id;  // input id -> disk id (-1 at v0), disk id -> input id
  PuncturedTriangulation pt;
  std::vector<std::array<double, 3>> disk_sides;
  Eigen::VectorXd u;
  const std::vector<SphereFlip>* start_log = nullptr;
};

/// The triangulation every pole starts from (#F faces, input vertex ids,
/// sides opposite corner k): the input's, or with options.intrinsic_delaunay
/// its intrinsic Delaunay triangulation made simplicial. It does not depend
/// on the removed vertex, so it is built once, before the poles are tried,
/// and its failure (a SolveError) is the whole mesh's, not one pole's.
struct SphereStart {
  RowMatrixX3i faces;
  RowMatrixX3d sides;
  int edge_flips = 0, simplicial_flips = 0;
  /// Its flips from the input faces (global face id = input face id).
  std::vector<SphereFlip> log;
};

SphereStart sphere_start(const TriMesh& mesh, const Connectivity& conn, const SphericalUniformizationOptions& options) {
  SphereStart st;
  RowMatrixX3i& start_faces = st.faces;
  RowMatrixX3d& start_sides = st.sides;
  // The input's lengths, mollified like every other path (intake notes the
  // faces touched; nearly degenerate faces get a strict triangle inequality).
  // With flips, the start is the intrinsic Delaunay triangulation of the
  // input metric on the whole sphere (exact flips, the pole's star
  // included): it fixes the discrete conformal class independently of the
  // removed vertex, so that every pole gives the same sphere up to Möbius
  // maps (the disk flow could not flip the star's edges exactly).
  const Eigen::VectorXd input_lengths = edge_lengths(mesh, conn);
  start_faces = mesh.F;
  start_sides.resize(conn.num_faces(), 3);  // side opposite corner k
  for (int f = 0; f < conn.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) start_sides(f, k) = input_lengths[conn.edge(3 * f + (k + 1) % 3)];
  if (options.intrinsic_delaunay) {
    IntrinsicDelaunayOptions ido;
    ido.record_flips = true;
    const IntrinsicDelaunayResult idt = intrinsic_delaunay(conn, input_lengths, ido);
    for (const IntrinsicFlip& r : idt.flip_history) {
      // Quad (k, i, l, j): slots k, s, m, t; before face0 = (i, j, k) from
      // column0, face1 = (j, i, l) from column1.
      SphereFlip fl;
      fl.face0 = r.face0, fl.face1 = r.face1;
      fl.quad = {r.k, r.i, r.l, r.j};
      fl.before0[r.column0] = 1, fl.before0[(r.column0 + 1) % 3] = 3, fl.before0[(r.column0 + 2) % 3] = 0;
      fl.before1[r.column1] = 3, fl.before1[(r.column1 + 1) % 3] = 1, fl.before1[(r.column1 + 2) % 3] = 2;
      fl.after0 = {0, 1, 2};
      fl.after1 = {2, 3, 0};
      std::copy(r.lengths, r.lengths + 6, fl.lengths.begin());
      fl.exact = true;
      st.log.push_back(fl);
    }
    st.edge_flips += idt.flips;
    // The intrinsic Delaunay triangulation is a Δ-complex: on a long, thin
    // shape (a bent, tapered 40:1 sphere) two of its edges can join the same
    // two vertices, which the disk's domain cannot name ("non-manifold
    // edge"). Exact flips in the same metric make it simplicial
    // (uniformize/simplicial_flips.h, as for the hyperbolic T'): the metric
    // and so the conformal class are unchanged, only a few edges stop being
    // Delaunay, and this happens before v0 is chosen, so every pole still
    // starts from the same triangulation.
    RicciFlowResult start;
    start.background = Background::Euclidean;
    start.faces = idt.F;
    start.face_edges.resize(idt.F.rows(), 3);
    for (int f = 0; f < idt.F.rows(); ++f)
      for (int k = 0; k < 3; ++k) start.face_edges(f, k) = idt.face_edges(f, (k + 1) % 3);  // side opposite corner k
    start.edge_vertices.resize(static_cast<int>(idt.edges.size()), 2);
    start.edge_lengths.resize(static_cast<int>(idt.edges.size()));
    for (size_t e = 0; e < idt.edges.size(); ++e) {
      start.edge_vertices(static_cast<int>(e), 0) = std::min(idt.edges[e].i, idt.edges[e].j);
      start.edge_vertices(static_cast<int>(e), 1) = std::max(idt.edges[e].i, idt.edges[e].j);
      start.edge_lengths[static_cast<int>(e)] = idt.edges[e].length;
    }
    if (!is_simplicial(start)) {
      const SimplicialFlipsResult sf = make_simplicial(start);
      {  // its exact flips into the log (vertex and face ids are the input's)
        PuncturedTriangulation ids;
        ids.input_id.resize(conn.num_vertices());
        for (int v = 0; v < conn.num_vertices(); ++v) ids.input_id[v] = v;
        ids.log = &st.log;
        std::vector<int> gid(idt.F.rows());
        for (int f = 0; f < idt.F.rows(); ++f) gid[f] = f;
        log_edge_flips(ids, start.flip_history, idt.F, gid);
      }
      st.edge_flips += sf.flips;
      st.simplicial_flips += sf.flips;
      if (!sf.simplicial)
        throw SolveError("the whole sphere's intrinsic Delaunay triangulation has " +
                         std::to_string(sf.loop_edges) + " loop and " + std::to_string(sf.multiple_edges) +
                         " multiple edges, and " + std::to_string(sf.flips) +
                         " exact flips did not make it simplicial");
    }
    start_faces = start.faces;
    for (int f = 0; f < start.faces.rows(); ++f)
      for (int k = 0; k < 3; ++k) start_sides(f, k) = start.edge_lengths[start.face_edges(f, k)];
  }
  return st;
}

/// The punctured disk of `mesh` without v0, on the input's lengths (with
/// options.intrinsic_delaunay, on their intrinsic Delaunay triangulation;
/// its flips are added to out.edge_flips). Throws InputError when v0's link
/// is not a simple cycle.
PuncturedDisk punctured_disk(const TriMesh& mesh, const Connectivity& conn, int v0, const SphereStart& start,
                             SphericalUniformization& out) {
  const int nv = conn.num_vertices();
  PuncturedDisk d;
  d.v0 = v0;
  std::vector<int>& new_id = d.new_id;
  std::vector<int>& old_id = d.old_id;
  PuncturedTriangulation& pt = d.pt;
  // Punctured disk, vertices renumbered without v0 (v0 itself: n2).
  new_id.assign(nv, -1);
  for (int v = 0; v < nv; ++v)
    if (v != v0) {
      new_id[v] = static_cast<int>(old_id.size());
      old_id.push_back(v);
    }
  const int n2 = d.n2 = nv - 1;
  pt.pole = n2;
  // The start triangulation (sphere_start), shared by every pole.
  const RowMatrixX3i& start_faces = start.faces;
  const RowMatrixX3d& start_sides = start.sides;
  out.edge_flips += start.edge_flips;
  out.simplicial_flips += start.simplicial_flips;
  Eigen::VectorXd& u = d.u;
  u.resize(n2);
  for (int i = 0; i < n2; ++i) u[i] = -2.0 * std::log((mesh.V.row(old_id[i]) - mesh.V.row(v0)).norm());
  std::vector<std::array<int, 3>> disk_rows;
  for (int f = 0; f < start_faces.rows(); ++f) {
    int row[3], at = -1, count = 0;
    for (int k = 0; k < 3; ++k) {
      row[k] = start_faces(f, k) == v0 ? n2 : new_id[start_faces(f, k)];
      if (start_faces(f, k) == v0) at = k, ++count;
    }
    if (count > 1)
      throw InputError("the link of vertex " + std::to_string(v0) +
                       " is not a simple cycle; choose another removed_vertex");
    if (at < 0) {
      disk_rows.push_back({row[0], row[1], row[2]});
      pt.disk_gid.push_back(f);
      d.disk_sides.push_back({start_sides(f, 0), start_sides(f, 1), start_sides(f, 2)});
    } else {
      pt.star.push_back({n2, row[(at + 1) % 3], row[(at + 2) % 3]});
      pt.star_gid.push_back(f);
      pt.ring_y[row[(at + 1) % 3]] = 1.0;
      u[row[(at + 1) % 3]] = -2.0 * std::log(start_sides(f, (at + 2) % 3));  // side v0–row[at+1]
    }
  }
  pt.disk.resize(static_cast<int>(disk_rows.size()), 3);
  for (int r = 0; r < pt.disk.rows(); ++r) pt.disk.row(r) << disk_rows[r][0], disk_rows[r][1], disk_rows[r][2];
  pt.input_id = old_id;
  pt.input_id.push_back(v0);
  out.flip_log = start.log;  // the sphere's Delaunay start, then this pole's flips
  pt.log = &out.flip_log;
  d.start_log = &start.log;
  return d;
}

/// The rounds of flatten_punctured_disk: the current disk's domain and
/// lengths, and the flow result of the last round.
struct DiskFlow {
  PuncturedDisk& d;
  const RicciFlowOptions fo;
  SphericalUniformization& out;
  RicciFlowResult flat;
  detail::RicciDomain dom;
  Eigen::VectorXd lengths;

  // One round: the Dirichlet flow on the current disk (throws InputError
  // when v0's link is not a simple cycle).
  void solve_round(int round) {
    const int n2 = d.n2;
    PuncturedTriangulation& pt = d.pt;
    Eigen::VectorXd& u = d.u;
    dom = detail::domain_from_faces(n2, pt.disk);
    int boundary_count = 0;
    for (int v = 0; v < n2; ++v) boundary_count += dom.full_angle[v] < 4.0;
    if (boundary_count != static_cast<int>(pt.star.size()))
      throw InputError("the link of vertex " + std::to_string(d.v0) +
                       " is not a simple cycle; choose another removed_vertex");
    if (round == 0) {
      lengths.resize(dom.EV.rows());
      for (int f = 0; f < dom.F.rows(); ++f)
        for (int k = 0; k < 3; ++k) lengths[dom.FE(f, k)] = d.disk_sides[f][k];
    }
    std::vector<char> fixed(n2, 0);
    for (auto& [v, y] : pt.ring_y) {
      fixed[v] = 1;
      if (round > 0) u[v] = -2.0 * std::log(y);
      y = 1.0;  // the solve keeps every ring vertex at y = 1 in its final frame
    }
    flat = detail::ricci_solve(dom, lengths, Background::Euclidean, fo, Eigen::VectorXd::Zero(n2), &u, &fixed);
    // The log: this round's flips in its base frame, then its conformal
    // factors (v0 keeps its frame: the ring's lengths to it are 1 after).
    log_edge_flips(pt, flat.flip_history, dom.F, pt.disk_gid);
    SphereFrameChange frame;
    frame.time = static_cast<int>(out.flip_log.size());
    frame.log_scale.setZero(static_cast<int>(d.new_id.size()));
    for (int i = 0; i < n2; ++i) frame.log_scale[d.old_id[i]] = flat.u[i];
    out.frame_log.push_back(std::move(frame));
    out.edge_flips += flat.flips;
    out.flow_iterations += flat.iterations;
  }

  /// Ring or star flips after a round, and the next round's input: the
  /// metric reached (u = 0), except at the new ring vertices, whose y is not
  /// 1. False when there is nothing to flip or the flips left no valid disk
  /// (out.message says which).
  bool prepare_next_round() {
    const int n2 = d.n2;
    PuncturedTriangulation& pt = d.pt;
    std::vector<int> kept;
    std::vector<double> vertex_scale(n2, 1.0), new_sides;
    if (flat.converged) {
      for (int f = 0; f < flat.faces.rows(); ++f) kept.push_back(f);
      pt.disk = flat.faces;
      const int flipped = flip_star_edges(flat, pt, vertex_scale, new_sides);
      if (flipped == 0) return false;
      out.ring_flips += flipped;
    } else {
      const int flipped = flip_ring_edges(flat, pt, kept);
      if (flipped == 0) return false;
      out.ring_flips += flipped;
    }
    detail::RicciDomain nd;
    try {
      nd = detail::domain_from_faces(n2, pt.disk);
    } catch (const Error& e) {  // a non-simplicial disk after the flips
      out.message = "ring flips left an invalid disk: " + std::string(e.what());
      return false;
    }
    Eigen::VectorXd next(nd.EV.rows());
    for (int i = 0; i < static_cast<int>(kept.size()); ++i)
      for (int k = 0; k < 3; ++k) next[nd.FE(i, k)] = flat.edge_lengths[flat.face_edges(kept[i], k)];
    for (size_t i = 0; i < new_sides.size(); ++i)  // star flips: the new ring edge, opposite corner 1
      next[nd.FE(static_cast<int>(kept.size() + i), 1)] = new_sides[i];
    for (int e = 0; e < nd.EV.rows(); ++e) next[e] *= vertex_scale[nd.EV(e, 0)] * vertex_scale[nd.EV(e, 1)];
    // The log: scaling a's edges by s is the frame change g_a = 2 log s.
    if (std::any_of(vertex_scale.begin(), vertex_scale.end(), [](double x) { return x != 1.0; })) {
      SphereFrameChange frame;
      frame.time = static_cast<int>(out.flip_log.size());
      frame.log_scale.setZero(static_cast<int>(d.new_id.size()));
      for (int i = 0; i < n2; ++i) frame.log_scale[d.old_id[i]] = 2.0 * std::log(vertex_scale[i]);
      out.frame_log.push_back(std::move(frame));
    }
    // Degenerate triangles the ring flips could not reach (their angle π is
    // at a ring vertex, or behind an edge that never reached the ring): the
    // next round has no valid start; say so instead of failing in its input
    // check. Star flips' new triangles start strict (vertex_scale).
    int degenerate = 0, first = -1;
    for (int f = 0; f < nd.F.rows(); ++f) {
      const double a = next[nd.FE(f, 0)], b = next[nd.FE(f, 1)], c = next[nd.FE(f, 2)];
      if (!(a < b + c && b < c + a && c < a + b)) {
        if (first < 0) first = f;
        ++degenerate;
      }
    }
    if (degenerate > 0) {
      out.message = "ring flips left " + std::to_string(degenerate) + " degenerate disk triangles (first: (" +
                    std::to_string(d.old_id[nd.F(first, 0)]) + ", " + std::to_string(d.old_id[nd.F(first, 1)]) + ", " +
                    std::to_string(d.old_id[nd.F(first, 2)]) + "), input vertex ids)";
      return false;
    }
    lengths = next;
    d.u.setZero();
    return true;
  }
};

/// Flatten with v0 at infinity. Sending v0 to ∞ keeps the length cross
/// ratios only if l̃(v0, j) / l̃(v0, k) -> 1 for all ring vertices, i.e.
/// e^{u_j/2} l(v0, j) is the same for all j: a Dirichlet condition
/// u_j = −2 log l(v0, j) on the ring, with K = 0 at the interior vertices.
/// Projecting the planar layout stereographically then gives chord lengths
/// that are a vertex scaling of the input lengths, edges to v0 included: a
/// discrete conformal map onto an inscribed polyhedron.
/// Start: u_i = −2 log |x_i − x_{v0}| everywhere, the conformal factor of
/// the inversion in the unit sphere around v0 — so the initial metric is the
/// (valid, 3D) edge lengths of the inverted mesh, already satisfying the
/// ring condition; the flow then only has to flatten it.
/// The ring's edges are the disk's boundary and cannot flip inside the
/// flow; when a disk triangle against the ring degenerates, the ring edge
/// is flipped (flip_ring_edges) and the flow runs again from the metric it
/// reached (the next round's input lengths), with the ring's Dirichlet
/// values given by the flipped lengths to v0.
/// Returns the last round's flow result (d.pt: the final star and ring).
RicciFlowResult flatten_punctured_disk(PuncturedDisk& d, const SphericalUniformizationOptions& options,
                                       SphericalUniformization& out) {
  RicciFlowOptions fo = options.flow;
  fo.intrinsic_delaunay = options.intrinsic_delaunay;
  const int max_rounds = options.intrinsic_delaunay ? options.max_ring_flip_rounds : 1;
  DiskFlow flow{d, fo, out, {}, {}, {}};
  for (int round = 0; round < max_rounds; ++round) {
    if (round == 0) {
      flow.solve_round(round);
    } else {
      try {
        flow.solve_round(round);
      } catch (const Error& e) {  // e.g. the ring flips pinched the disk
        out.message = "flattening the punctured disk failed after " + std::to_string(out.ring_flips) +
                      " ring flips: " + e.what();
        break;
      }
    }
    if (round + 1 == max_rounds) break;
    if (!flow.prepare_next_round()) break;
  }
  return std::move(flow.flat);
}

}  // namespace

/// One attempt with v0 removed (spherical.h): the punctured disk flattened
/// with v0 at infinity (rounds of the Dirichlet flow, ring flips between
/// them), laid out, projected to the sphere, Möbius-centred and checked.
static SphericalUniformization attempt(const TriMesh& mesh, const Connectivity& conn, int v0,
                                       const SphereStart& start, const SphericalUniformizationOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  const int nv = conn.num_vertices();
  SphericalUniformization out;
  out.removed_vertex = v0;
  PuncturedDisk d = punctured_disk(mesh, conn, v0, start, out);
  const RicciFlowResult flat = flatten_punctured_disk(d, options, out);
  const int n2 = d.n2;
  const PuncturedTriangulation& pt = d.pt;
  const std::vector<int>& old_id = d.old_id;
  out.max_curvature_error = flat.max_curvature_error;
  out.stopped_at_floor = flat.stopped_at_floor;
  out.circle_error = 0.0;
  if (!flat.converged && out.message.empty()) out.message = "flattening the punctured disk failed: " + flat.message;

  // The layout grows from the disk vertex farthest from the ring (in edges):
  // the far end of the shape, which the projection crowds towards the south pole.
  const Eigen::MatrixX2d P =
      lay_out_flat_disk(flat.faces, flat.face_edges, flat.edge_lengths, n2, farthest_from_ring(flat.faces, pt, n2));
  const double radius = axial_centring_radius(P, old_id, v0, vertex_area_weights(mesh));
  out.positions = project_to_sphere(P, radius, old_id, v0, nv);
  // The last frame change of the log: the inverse stereographic projection
  // of P / radius scales the flat lengths to chords by e^{(g_i + g_j)/2}
  // with e^{g_i} = 2 radius / (radius² + |P_i|²), and v0's (its flat
  // lengths to the ring are 1) by e^{g_v0} = 2 radius; the Möbius centring
  // adds its own factors.
  SphereFrameChange to_sphere;
  to_sphere.time = static_cast<int>(out.flip_log.size());
  to_sphere.log_scale.setZero(nv);
  const double log_r = std::log(radius);
  for (int i = 0; i < n2; ++i)
    to_sphere.log_scale[old_id[i]] = std::log(2.0) - log_r - std::log1p(P.row(i).squaredNorm() / (radius * radius));
  to_sphere.log_scale[v0] = std::log(2.0) + log_r;
  RowMatrixX3i disk_faces(flat.faces.rows(), 3);
  for (int f = 0; f < flat.faces.rows(); ++f)
    for (int k = 0; k < 3; ++k) disk_faces(f, k) = old_id[flat.faces(f, k)];
  int unused = -1;
  const int inward_before = count_inward_faces(out.positions, disk_faces, &unused);
  const RowMatrixX3d projected = out.positions;
  const Eigen::VectorXd projected_scale = to_sphere.log_scale;
  bool centred = mobius_centre(mesh, options, out.positions, out, &to_sphere.log_scale);
  if (count_inward_faces(out.positions, disk_faces, &unused) > inward_before) {
    out.positions = projected;
    to_sphere.log_scale = projected_scale;
    centred = mobius_centre(mesh, options, out.positions, out, &to_sphere.log_scale, true);
  }
  if (!centred && out.message.empty())
    out.message = "Möbius centring stalled at |centre| = " + detail::fmt(out.centre_of_mass_norm) + " after " +
                  std::to_string(out.centring_iterations) + " iterations (tolerance " +
                  detail::fmt(std::max(options.centring_tolerance, out.centring_floor)) + ", floor " +
                  detail::fmt(out.centring_floor) + ")";

  // The spherical embedding: the intrinsic triangulation (disk faces of the
  // flow and the star of v0) in input vertex ids.
  // Row g is the face of global id g (the flip log's), when the ids of the
  // last round's disk and the star are a permutation; otherwise (an attempt
  // that failed between rounds) disk rows first, then the star, and no log.
  const int nrows = static_cast<int>(flat.faces.rows()) + static_cast<int>(pt.star.size());
  out.intrinsic_faces.resize(nrows, 3);
  auto input_id = [&](int v) { return v == n2 ? v0 : old_id[v]; };
  std::vector<int> row_of(nrows);
  bool by_gid = static_cast<int>(pt.disk_gid.size()) == flat.faces.rows() && pt.star_gid.size() == pt.star.size() &&
                options.intrinsic_delaunay;
  {
    std::vector<char> used(nrows, 0);
    for (int f = 0; f < nrows; ++f) {
      const int g = !by_gid ? f : f < flat.faces.rows() ? pt.disk_gid[f] : pt.star_gid[f - flat.faces.rows()];
      if (g < 0 || g >= nrows || used[g]) by_gid = false;
      else used[g] = 1, row_of[f] = g;
    }
  }
  for (int f = 0; f < nrows; ++f) {
    const int g = by_gid ? row_of[f] : f;
    for (int k = 0; k < 3; ++k)
      out.intrinsic_faces(g, k) =
          input_id(f < flat.faces.rows() ? flat.faces(f, k) : pt.star[f - flat.faces.rows()][k]);
  }
  out.frame_log.push_back(std::move(to_sphere));
  check_sphere_orientation(mesh, out);
  if (!by_gid || !out.message.empty()) out.flip_log.clear(), out.frame_log.clear();
  out.converged = out.message.empty();
  out.time_s = detail::seconds_since(t0);
  return out;
}

SphericalUniformization spherical_uniformization(const TriMesh& mesh,
                                                 const SphericalUniformizationOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  const Connectivity conn(mesh.F, mesh.num_vertices());
  if (conn.euler_characteristic() != 2)
    throw InputError("spherical_uniformization needs a genus-0 surface; this one has genus " +
                     std::to_string(conn.genus()));
  const int nv = conn.num_vertices();
  if (nv < 4) throw InputError("spherical_uniformization needs at least 4 vertices");
  if (options.removed_vertex >= nv)
    throw InputError("removed_vertex " + std::to_string(options.removed_vertex) + " is out of range");
  const SphereStart start = sphere_start(mesh, conn, options);  // the whole mesh's: a failure here is final
  if (options.removed_vertex >= 0) return attempt(mesh, conn, options.removed_vertex, start, options);
  // Default: the highest-valence vertex; when that fails (the flat metric of
  // the punctured disk can degenerate next to the fixed boundary), a few more
  // candidates spread over the vertex order, keeping the best result.
  int best_v = 0;
  for (int v = 1; v < nv; ++v)
    if (conn.valence(v) > conn.valence(best_v)) best_v = v;
  std::vector<int> candidates{best_v};
  for (int k = 1; k <= 6; ++k) candidates.push_back(static_cast<int>((static_cast<long long>(nv) * k) / 7));
  // Then the vertices whose neighbourhood is best shaped: the punctured
  // disk's boundary (v0's ring) is Dirichlet and its edges cannot flip, so a
  // sliver next to it can degenerate; rank by the smallest corner angle of
  // the faces touching the ring (coarse, low-quality meshes: g0 bunny).
  {
    std::vector<double> min_angle_at(nv, M_PI);
    for (int f = 0; f < conn.num_faces(); ++f) {
      const Eigen::Vector3d p[3] = {mesh.V.row(mesh.F(f, 0)), mesh.V.row(mesh.F(f, 1)), mesh.V.row(mesh.F(f, 2))};
      double m = M_PI;
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d a = p[(k + 1) % 3] - p[k], b = p[(k + 2) % 3] - p[k];
        m = std::min(m, std::atan2(a.cross(b).norm(), a.dot(b)));
      }
      for (int k = 0; k < 3; ++k) min_angle_at[mesh.F(f, k)] = std::min(min_angle_at[mesh.F(f, k)], m);
    }
    std::vector<std::pair<double, int>> score(nv);
    for (int v = 0; v < nv; ++v) {
      double m = min_angle_at[v];
      for (int h : conn.outgoing(v)) m = std::min(m, min_angle_at[conn.head(h)]);
      score[v] = {-m, v};
    }
    const int extra = std::min(nv, 12);
    std::partial_sort(score.begin(), score.begin() + extra, score.end());
    for (int i = 0; i < extra; ++i)
      if (std::find(candidates.begin(), candidates.end(), score[i].second) == candidates.end())
        candidates.push_back(score[i].second);
  }
  SphericalUniformization best;
  bool have = false, have_axial = false;
  SphericalUniformization axial;
  std::string tried;
  for (int v0 : candidates) {
    SphericalUniformization r;
    try {
      r = attempt(mesh, conn, v0, start, options);
    } catch (const InputError& e) {  // e.g. a link that is not a simple cycle: try the next vertex
      tried += (tried.empty() ? "" : "; ") + std::to_string(v0) + ": " + e.what();
      continue;
    } catch (const SolveError& e) {
      // This pole's flow failed (e.g. its Ptolemy flips cycled on a long
      // 40:1 shape): another pole gives another disk and may well succeed.
      // The whole mesh's checks and start (sphere_start) ran before the
      // loop; Cancelled is no SolveError and still ends the run at once.
      tried += (tried.empty() ? "" : "; ") + std::to_string(v0) + ": " + e.what();
      continue;
    }
    if (r.converged && r.centring_axial_only) {
      // Embedded but centred along the axis only: kept as a last resort, a
      // pole that centres fully is preferred.
      if (!have_axial) axial = std::move(r), have_axial = true;
      continue;
    }
    if (r.converged) {
      r.time_s = detail::seconds_since(t0);
      return r;
    }
    tried += (tried.empty() ? "" : "; ") + std::to_string(v0) + ": " + r.message;
    if (!have || r.flipped_faces < best.flipped_faces) {
      best = r;
      have = true;
    }
  }
  if (have_axial) {
    axial.time_s = detail::seconds_since(t0);
    return axial;
  }
  best.message = "no removed vertex gave a valid map (" + tried + ")";
  best.time_s = detail::seconds_since(t0);
  return best;
}

}  // namespace surfmap
