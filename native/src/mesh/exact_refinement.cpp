// Exact refinement by altitude-foot edge splits (mesh/exact_refinement.h).
#include "surfmap/mesh/exact_refinement.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <queue>
#include <unordered_map>

#include <Eigen/Geometry>

#include "surfmap/error.h"

namespace surfmap {
namespace {

constexpr double kDeg = 180.0 / M_PI;

double angle_at(const Eigen::Vector3d& p, const Eigen::Vector3d& q, const Eigen::Vector3d& r) {
  const Eigen::Vector3d u = q - p, v = r - p;
  return std::atan2(u.cross(v).norm(), u.dot(v));
}

}  // namespace

Eigen::Vector3d barycentric_in_input_face(const TriMesh& input, int f, const Eigen::Vector3d& p) {
  const Eigen::Vector3d p0 = input.V.row(input.F(f, 0)), p1 = input.V.row(input.F(f, 1)), p2 = input.V.row(input.F(f, 2));
  const Eigen::Vector3d n = (p1 - p0).cross(p2 - p0);
  const double n2 = n.squaredNorm();
  Eigen::Vector3d b((p1 - p).cross(p2 - p).dot(n) / n2, (p2 - p).cross(p0 - p).dot(n) / n2,
                    (p0 - p).cross(p1 - p).dot(n) / n2);
  // Points made on the face's own edges or inside it: negatives are round-off.
  b = b.cwiseMax(0.0);
  return b / b.sum();
}

ExactRefinementResult refine_obtuse_triangles(const TriMesh& mesh, const ExactRefinementOptions& options) {
  if (!(options.max_angle_deg > 90 && options.max_angle_deg < 180))
    throw InputError("refine_obtuse_triangles: max_angle_deg must be in (90, 180), not " +
                     std::to_string(options.max_angle_deg));
  const double threshold = options.max_angle_deg / kDeg;
  const int nf0 = mesh.num_faces(), nv0 = mesh.num_vertices();
  const int max_splits = options.max_splits > 0 ? options.max_splits : 2 * nf0;

  std::vector<Eigen::Vector3d> V(nv0);
  for (int v = 0; v < nv0; ++v) V[v] = mesh.V.row(v).transpose();
  std::vector<std::array<int, 3>> F(nf0);
  std::vector<int> origin(nf0), version(nf0, 0);
  double mean_edge = 0;
  for (int f = 0; f < nf0; ++f)
    for (int k = 0; k < 3; ++k) mean_edge += (mesh.V.row(mesh.F(f, k)) - mesh.V.row(mesh.F(f, (k + 1) % 3))).norm();
  mean_edge /= std::max(1, 3 * nf0);
  for (int f = 0; f < nf0; ++f) F[f] = {mesh.F(f, 0), mesh.F(f, 1), mesh.F(f, 2)}, origin[f] = f;
  // Directed halfedge (a, b) -> 3 f + k with F[f][k] = a, F[f][k+1] = b.
  std::unordered_map<std::uint64_t, int> half;
  auto key = [](int a, int b) { return (static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b); };
  auto add_face = [&](int f) {
    for (int k = 0; k < 3; ++k) half[key(F[f][k], F[f][(k + 1) % 3])] = 3 * f + k;
  };
  half.reserve(6 * nf0);
  for (int f = 0; f < nf0; ++f) add_face(f);

  // Largest angle of a face and its corner.
  auto worst = [&](int f, int* corner) {
    double best = -1;
    for (int k = 0; k < 3; ++k) {
      const double a = angle_at(V[F[f][k]], V[F[f][(k + 1) % 3]], V[F[f][(k + 2) % 3]]);
      if (a > best) best = a, *corner = k;
    }
    return best;
  };
  struct Item {
    double angle;
    int face, version;
    bool operator<(const Item& o) const { return angle < o.angle; }
  };
  std::priority_queue<Item> queue;
  ExactRefinementResult r;
  auto push = [&](int f) {
    int k = 0;
    const double a = worst(f, &k);
    r.max_angle_after = std::max(r.max_angle_after, a);
    if (a > threshold) queue.push({a, f, version[f]});
  };
  for (int f = 0; f < nf0; ++f) push(f);
  r.max_angle_before = r.max_angle_after * kDeg;

  // New vertices: the input face holding them (the face whose piece is split).
  std::vector<int> vertex_origin;
  // The face across the side opposite corner k of f, and that side's corner there.
  auto across = [&](int f, int k, int* j) {
    const int a = F[f][(k + 1) % 3], b = F[f][(k + 2) % 3];
    const auto tw = half.find(key(b, a));
    if (tw == half.end())
      throw SolveError("refine_obtuse_triangles: the mesh is not closed at an edge of input face " +
                       std::to_string(origin[f]));
    *j = (tw->second % 3 + 2) % 3;  // corner of g opposite the shared side
    return tw->second / 3;
  };
  // Splits the side a -> b opposite corner k of f at a + t (b − a), in both faces.
  auto split = [&](int f, int k, double t) {
    const int c = F[f][k], a = F[f][(k + 1) % 3], b = F[f][(k + 2) % 3];
    int j;
    const int g = across(f, k, &j);
    const int d = F[g][j];
    const int m = static_cast<int>(V.size());
    V.push_back(V[a] + t * (V[b] - V[a]));
    vertex_origin.push_back(origin[f]);
    r.split_log.push_back({a, b, m, t});
    for (int q = 0; q < 3; ++q) {
      half.erase(key(F[f][q], F[f][(q + 1) % 3]));
      half.erase(key(F[g][q], F[g][(q + 1) % 3]));
    }
    // f = (c, a, b) -> (c, a, m) + (c, m, b); g = (d, b, a) -> (d, b, m) + (d, m, a).
    const int f2 = static_cast<int>(F.size()), g2 = f2 + 1;
    F[f] = {c, a, m};
    F.push_back({c, m, b});
    F[g] = {d, b, m};
    F.push_back({d, m, a});
    origin.push_back(origin[f]);
    origin.push_back(origin[g]);
    version.push_back(0);
    version.push_back(0);
    ++version[f];
    ++version[g];
    for (int h : {f, f2, g, g2}) add_face(h);
    for (int h : {f, f2, g, g2}) push(h);
    ++r.splits;
  };
  while (!queue.empty() && r.splits < max_splits) {
    const Item it = queue.top();
    queue.pop();
    if (it.version != version[it.face]) continue;
    // The foot of the altitude from the large angle: both halves of the face
    // get a right angle there. (Midpoint bisection, even with Rivara's
    // longest-edge propagation, needs ~log(length / height) levels per cap
    // and on g3_block drove edges to zero length near back-to-back caps.)
    int k = 0;
    worst(it.face, &k);
    const Eigen::Vector3d c = V[F[it.face][k]], a = V[F[it.face][(k + 1) % 3]], b = V[F[it.face][(k + 2) % 3]];
    // Never below a millionth of the mean input edge: a cascade that got
    // there (caps on caps) is left as it is rather than driven to zero.
    if ((b - a).norm() < 1e-6 * mean_edge) continue;
    const double t = (c - a).dot(b - a) / (b - a).squaredNorm();
    split(it.face, k, std::clamp(t, options.foot_clamp, 1 - options.foot_clamp));
  }

  const int nv = static_cast<int>(V.size()), nf = static_cast<int>(F.size());
  r.mesh.V.resize(nv, 3);
  for (int v = 0; v < nv; ++v) r.mesh.V.row(v) = V[v].transpose();
  r.mesh.F.resize(nf, 3);
  for (int f = 0; f < nf; ++f) r.mesh.F.row(f) << F[f][0], F[f][1], F[f][2];
  r.face_origin = origin;
  r.origin_face.assign(nv, -1);
  r.origin_barycentric = RowMatrixX3d::Zero(nv, 3);
  for (int f = 0; f < nf0; ++f)
    for (int k = 0; k < 3; ++k)
      if (r.origin_face[mesh.F(f, k)] < 0) r.origin_face[mesh.F(f, k)] = f, r.origin_barycentric(mesh.F(f, k), k) = 1;
  for (int v = nv0; v < nv; ++v) {
    r.origin_face[v] = vertex_origin[v - nv0];
    r.origin_barycentric.row(v) = barycentric_in_input_face(mesh, r.origin_face[v], V[v]).transpose();
  }
  r.max_angle_after = 0;
  r.obtuse_after = 0;
  for (int f = 0; f < nf; ++f) {
    int k = 0;
    const double a = worst(f, &k);
    r.max_angle_after = std::max(r.max_angle_after, a * kDeg);
    if (a > threshold) ++r.obtuse_after;
  }
  return r;
}

}  // namespace surfmap
