#include "surfmap/topology/projected_loops.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <unordered_map>

#include <Eigen/Eigenvalues>

#include "surfmap/geometry/nearest_point.h"
#include "surfmap/topology/edge_homotopy.h"
#include "surfmap/topology/edge_words.h"

#include "../mesh/dijkstra.h"

namespace surfmap {
namespace {

// Linear map T, then per-axis bounding-box normalisation to [-1/2, 1/2]^3,
// or (`uniform`) the box centred and divided by its longest side, keeping the
// shape's proportions (ProjectedLoopsOptions::uniform_box).
struct BoxFrame {
  Eigen::Matrix3d T;
  Eigen::Vector3d centre, scale;
  BoxFrame(const RowMatrixX3d& V, const Eigen::Matrix3d& transform, bool uniform = false) : T(transform) {
    const RowMatrixX3d W = V * T.transpose();
    const Eigen::Vector3d lo = W.colwise().minCoeff(), hi = W.colwise().maxCoeff();
    centre = 0.5 * (lo + hi);
    const double longest = (hi - lo).maxCoeff();
    for (int d = 0; d < 3; ++d) scale[d] = 1.0 / std::max(uniform ? longest : hi[d] - lo[d], 1e-3 * longest);
  }
  Eigen::Vector3d operator()(const Eigen::Vector3d& p) const { return (T * p - centre).cwiseProduct(scale); }
};

// Every vertex of m in `frame` (issue 19, session 23: each vertex framed
// once, not once per face corner and loop visit).
std::vector<Eigen::Vector3d> framed_points(const TriMesh& m, const BoxFrame& frame) {
  std::vector<Eigen::Vector3d> p(m.num_vertices());
  for (int v = 0; v < m.num_vertices(); ++v) p[v] = frame(m.V.row(v).transpose());
  return p;
}

// The mean edge length of m, its vertices at `points` (framed_points).
double mean_edge_length(const TriMesh& m, const std::vector<Eigen::Vector3d>& points) {
  double s = 0;
  for (int f = 0; f < m.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) s += (points[m.F(f, k)] - points[m.F(f, (k + 1) % 3)]).norm();
  return s / std::max(1, 3 * m.num_faces());
}

}  // namespace

namespace {

// Target edge elements in the free group on its loop letters.
std::vector<Word> target_edge_words(const SystemOfLoops& target, const Connectivity& conn) {
  std::vector<Word> letters;
  for (size_t k = 0; k < target.generator_edges.size(); ++k) letters.push_back({static_cast<int>(k) + 1});
  const GroupOps<Word> free_group{Word{}, [](const Word& u, const Word& v) { return concat(u, v); },
                                  [](const Word& u) { return inverse(u); }};
  return edge_group_elements(conn, target.tree_parent_halfedge, target.dual_tree_parent_halfedge,
                             target.generator_edges, loop_first_vertices(target, conn), letters, free_group);
}

// The target in one box frame: its points, mean edge length and nearest-
// vertex index. All the world-axis poses share the target's frame
// (identity), so one is built for them all (28 grids of a 73k-vertex target
// were most of the overlays' 0.73 s CPU on the 50k genus-2 bench pair). The
// index is a k-d tree (geometry/nearest_point.h): the uniform grid it
// replaced searched (distance / cell)^3 cells for a loop vertex off the
// target, which made this overlay grow like V^2 (issue 19, docs/benchmarks.md).
struct TargetFrame {
  Eigen::Matrix3d transform;
  bool uniform = false;
  std::vector<Eigen::Vector3d> tp;
  double t_edge = 0;
  std::unique_ptr<NearestPointIndex> nearest_vertex;
  TargetFrame(const TriMesh& tm, const Eigen::Matrix3d& transform, bool uniform) : transform(transform), uniform(uniform) {
    tp = framed_points(tm, BoxFrame(tm.V, transform, uniform));
    t_edge = mean_edge_length(tm, tp);
    nearest_vertex = std::make_unique<NearestPointIndex>(tp);
  }
};

// The target's edge words: read one edge at a time from the cut disk's
// boundary (topology/edge_words.h: the projections read ~1% of the edges),
// or every edge's by edge_group_elements when that reading failed.
struct EdgeWordSource {
  const CutDiskEdgeWords* lazy = nullptr;
  const std::vector<Word>* all = nullptr;
  const Word& operator()(int e) const { return lazy ? (*lazy)(e) : (*all)[e]; }
};

// The source in its box frame (the target's box with source_on_target) and
// its mean edge length there. Issue 19: kept by the LoopProjector, which
// projects the same source in the same few poses for every lifted cut (30
// frames and mean edge lengths for a few distinct ones on the 5k bench pair).
struct SourceFrame {
  RowMatrixX3d V;  ///< #V x 3: the source it was built for (with F, compared by value)
  RowMatrixX3i F;
  Eigen::Matrix3d transform;
  bool uniform = false;
  BoxFrame frame;
  std::vector<Eigen::Vector3d> points;  ///< #V: the source's vertices in `frame`
  double s_edge = 0;
  SourceFrame(const TriMesh& source, const TriMesh& target, const TargetFrame& tf, const ProjectedLoopsOptions& options)
      : V(source.V), F(source.F), transform(options.source_on_target ? tf.transform : options.source_transform),
        uniform(options.source_on_target ? tf.uniform : options.uniform_box),
        frame(options.source_on_target ? target.V : source.V, transform, uniform), points(framed_points(source, frame)),
        s_edge(mean_edge_length(source, points)) {}
  bool is_for(const TriMesh& source, const Eigen::Matrix3d& t, bool u) const {
    return t == transform && u == uniform && source.V.rows() == V.rows() && source.F.rows() == F.rows() && source.V == V &&
           source.F == F;
  }
};

ProjectedLoopsResult project_with(const TriMesh& source, const std::vector<std::vector<int>>& source_loops,
                                  const SystemOfLoops& target, const Word& target_word, const Connectivity& conn,
                                  const EdgeWordSource& edge_word, const TargetFrame* frame, const SourceFrame* source_frame,
                                  const ProjectedLoopsOptions& options) {
  ProjectedLoopsResult out;
  const TriMesh& tm = target.mesh;
  // Without a frame (LoopProjector::project with options.own_mesh): the
  // source is the target's mesh, every loop vertex its own image, and the
  // mean edge lengths are equal.
  const double s_edge = frame ? source_frame->s_edge : 1.0, t_edge = frame ? frame->t_edge : 1.0;
  const int max_gap = static_cast<int>(std::ceil(options.max_gap_factor * std::max(1.0, s_edge / t_edge)));

  // Halfedge from a to b, or -1.
  std::vector<int> parent_h(tm.num_vertices(), -1), stamp(tm.num_vertices(), -1);
  detail::DijkstraResult path_search;  // the A* searches' (shortest path by length)
  int search = 0;
  // Issue 19 (session 23): each source vertex's nearest target vertex found
  // once, not once per loop through it (the loops of a system share their
  // tree paths to the base vertex); the points framed once per source frame.
  std::unordered_map<int, int> nearest;
  auto image_of = [&](int v) {
    auto [it, added] = nearest.try_emplace(v, -1);
    if (added) it->second = frame->nearest_vertex->nearest(source_frame->points[v]);
    return it->second;
  };
  for (const auto& loop : source_loops) {
    const size_t m = loop.size() >= 2 && loop.front() == loop.back() ? loop.size() - 1 : loop.size();
    std::vector<int> img(m);
    for (size_t i = 0; i < m; ++i) img[i] = frame ? image_of(loop[i]) : loop[i];
    Word w;
    for (size_t i = 0; i < m; ++i) {
      const int a = img[i], b = img[(i + 1) % m];
      if (a == b) continue;
      // Breadth-first shortest edge path a -> b, at most max_gap edges.
      ++search;
      std::vector<int> frontier{a}, next;
      stamp[a] = search;
      parent_h[a] = -1;
      bool found = false;
      for (int depth = 0; depth < max_gap && !found && !frontier.empty() && !options.join_by_length; ++depth) {
        next.clear();
        for (int v : frontier) {
          const int first_out = conn.vertex_halfedge(v);  // (conn.outgoing(v) without its vector)
          for (int h = first_out, more = 1; more; h = conn.rotate_ccw(h), more = h != first_out) {
            const int u = conn.head(h);
            if (stamp[u] == search) continue;
            stamp[u] = search;
            parent_h[u] = h;
            if (u == b) {
              found = true;
              break;
            }
            next.push_back(u);
          }
          if (found) break;
        }
        frontier.swap(next);
        out.longest_gap = std::max(out.longest_gap, depth + 1);
      }
      // A jump the options accept: the shortest path by length in the box
      // (A* with the straight-line bound, so only a band around the segment
      // is explored), at most twice the jump plus the ordinary gap.
      // With join_by_length every gap takes this path (the shortest by
      // length, not by edge count).
      const double jump = frame ? (frame->tp[a] - frame->tp[b]).norm() : 0.0;
      // Images no farther apart than the two loop vertices themselves plus
      // two target edges (each point's nearest vertex is within about an
      // edge) did not jump across the target's medial axis; only the edge
      // count was long, through clustered vertices and slivers (raw
      // marching-tetrahedra output: the genus-2 r40 loops on the r32 mesh
      // had images 1.2 mean edges apart and 1.3 long by path, but 13 edges,
      // so the identity overlay was refused and the overlay of a rotation,
      // the shape's symmetry, was mapped: 53% of the diagonal from the
      // identity, issue 13). Joined by the shortest path by length, and not
      // counted as a jump. (A tube's wall-to-wall jump: 4 edges for a
      // 0.34-edge step.)
      bool near_in_space = false;
      if (!found && frame) {
        const double step = (source_frame->points[loop[i]] - source_frame->points[loop[(i + 1) % m]]).norm();
        near_in_space = jump <= step + 2 * t_edge;
      }
      if (!found && frame &&
          (near_in_space || options.join_by_length || (options.max_jump_box > 0 && jump <= options.max_jump_box))) {
        const std::vector<Eigen::Vector3d>& tp = frame->tp;
        detail::DijkstraOptions by_length;
        by_length.target = b;
        by_length.max_key = 2 * jump + max_gap * t_edge;
        auto arcs = detail::rotation_arcs(conn, [&](int h) { return (tp[conn.head(h)] - tp[conn.tail(h)]).norm(); });
        auto straight_to_b = [&](int v) { return (tp[v] - tp[b]).norm(); };  // the potential: A*
        detail::dijkstra(tm.num_vertices(), arcs, {a}, by_length, path_search, straight_to_b);
        found = path_search.reached_target;
        if (found)
          for (int v = b; v != a; v = conn.tail(parent_h[v])) parent_h[v] = path_search.parent_arc[v];
        if (found && !options.join_by_length && !near_in_space) ++out.joined_jumps;
        if (found && options.join_by_length) {
          int edges = 0;
          for (int v = b; v != a; v = conn.tail(parent_h[v])) ++edges;
          out.longest_gap = std::max(out.longest_gap, edges);
        }
      }
      if (!found) {
        out.message = "the shapes do not overlap: consecutive loop vertices land more than " + std::to_string(max_gap) +
                      " target edges apart";
        out.loop_images.clear();
        return out;
      }
      Word seg;
      for (int v = b; v != a;) {
        const int h = parent_h[v];
        const int e = conn.edge(h);
        seg = concat(conn.edge_halfedge(e) == h ? edge_word(e) : inverse(edge_word(e)), seg);
        v = conn.tail(h);
      }
      w = concat(w, seg);
    }
    out.loop_images.push_back(dehn_reduce(w, target_word));
  }
  out.ok = out.joined_jumps == 0;
  out.ok_with_joins = true;
  if (!out.ok)
    out.message = "consecutive loop vertices land more than " + std::to_string(max_gap) + " target edges apart " +
                  std::to_string(out.joined_jumps) + " times (joined)";
  return out;
}

// Unit eigenvectors of the area-weighted second moment of the surface about
// its area centroid (columns, ascending eigenvalues, right-handed) and
// whether the eigenvalues are separated by more than `tol` relative.
bool principal_axes(const TriMesh& m, double tol, Eigen::Matrix3d* axes) {
  double area = 0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d p0 = m.V.row(m.F(f, 0)), p1 = m.V.row(m.F(f, 1)), p2 = m.V.row(m.F(f, 2));
    const double a = 0.5 * (p1 - p0).cross(p2 - p0).norm();
    const Eigen::Vector3d s = p0 + p1 + p2;
    // Exact ∫ x x^T dA over a triangle: A/12 (Σ p_i p_i^T + s s^T).
    S += a / 12.0 * (p0 * p0.transpose() + p1 * p1.transpose() + p2 * p2.transpose() + s * s.transpose());
    c += a * s / 3.0;
    area += a;
  }
  if (!(area > 0)) return false;
  c /= area;
  const Eigen::Matrix3d C = S / area - c * c.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
  const Eigen::Vector3d l = es.eigenvalues();
  *axes = es.eigenvectors();
  if (axes->determinant() < 0) axes->col(2) *= -1;
  const double top = std::max(l[2], 1e-300);
  return l[1] - l[0] > tol * top && l[2] - l[1] > tol * top;
}

bool is_signed_permutation(const Eigen::Matrix3d& M, double tol) {
  for (int r = 0; r < 3; ++r) {
    int big = 0;
    for (int c = 0; c < 3; ++c) {
      const double a = std::abs(M(r, c));
      if (std::abs(a - 1) < tol) ++big;
      else if (a > tol) return false;
    }
    if (big != 1) return false;
  }
  return true;
}

}  // namespace

struct LoopProjector::Impl {
  const SystemOfLoops& target;
  Word target_word;
  std::optional<Connectivity> own_conn;  // built here unless the caller's was given
  const Connectivity& conn;
  std::unique_ptr<CutDiskEdgeWords> lazy_words;
  std::vector<Word> all_words;  // (only when lazy_words could not be built)
  EdgeWordSource edge_word;
  // The target frames used so far, at most kFrames (the overlays' poses use
  // three: as posed in the per-axis box, which the world rotations and the
  // lifted cuts share, in proportion, and along the principal axes; with
  // one kept, the lifted cuts after them built the first again; issue 19).
  static constexpr size_t kFrames = 4;
  std::vector<std::unique_ptr<TargetFrame>> frames;
  // The source frames used so far (SourceFrame), at most kSourceFrames.
  static constexpr size_t kSourceFrames = 8;
  std::vector<std::unique_ptr<SourceFrame>> source_frames;
  Impl(const SystemOfLoops& t, const Word& w, const Connectivity* c)
      : target(t), target_word(w), own_conn(c ? std::nullopt : std::make_optional<Connectivity>(t.mesh.F, t.mesh.num_vertices())),
        conn(c ? *c : *own_conn) {
    // Issue 19: the edge words on demand (the same words; a cut of the
    // source spent a third of its time peeling every edge's word).
    try {
      lazy_words = std::make_unique<CutDiskEdgeWords>(target, conn);
      edge_word.lazy = lazy_words.get();
    } catch (const SolveError&) {
      all_words = target_edge_words(target, conn);  // (reports the inconsistency)
      edge_word.all = &all_words;
    }
  }
};

LoopProjector::LoopProjector(const SystemOfLoops& target, const Word& target_word, const Connectivity* target_conn)
    : impl_(std::make_unique<Impl>(target, target_word, target_conn)) {}
LoopProjector::~LoopProjector() = default;

ProjectedLoopsResult LoopProjector::project(const TriMesh& source, const std::vector<std::vector<int>>& source_loops,
                                            const ProjectedLoopsOptions& options) const {
  Impl& m = *impl_;
  // The source is the target's own mesh: no frame, every loop vertex is its
  // own nearest vertex (ProjectedLoopsOptions::own_mesh).
  if (options.own_mesh && !options.join_by_length && !(options.max_jump_box > 0) && !options.source_on_target &&
      source.F.rows() == m.target.mesh.F.rows() && source.V == m.target.mesh.V)
    return project_with(source, source_loops, m.target, m.target_word, m.conn, m.edge_word, nullptr, nullptr, options);
  const TargetFrame* frame = nullptr;
  for (const auto& f : m.frames)
    if (f->transform == options.target_transform && f->uniform == options.uniform_box) frame = f.get();
  if (!frame) {
    if (m.frames.size() >= Impl::kFrames) m.frames.erase(m.frames.begin());
    m.frames.push_back(std::make_unique<TargetFrame>(m.target.mesh, options.target_transform, options.uniform_box));
    frame = m.frames.back().get();
  }
  const Eigen::Matrix3d& st = options.source_on_target ? frame->transform : options.source_transform;
  const bool su = options.source_on_target ? frame->uniform : options.uniform_box;
  const SourceFrame* source_frame = nullptr;
  for (const auto& f : m.source_frames)
    if (f->is_for(source, st, su)) source_frame = f.get();
  if (!source_frame) {
    if (m.source_frames.size() >= Impl::kSourceFrames) m.source_frames.erase(m.source_frames.begin());
    m.source_frames.push_back(std::make_unique<SourceFrame>(source, m.target.mesh, *frame, options));
    source_frame = m.source_frames.back().get();
  }
  return project_with(source, source_loops, m.target, m.target_word, m.conn, m.edge_word, frame, source_frame, options);
}

std::vector<ProjectedLoopsResult> LoopProjector::project(const TriMesh& source,
                                                         const std::vector<std::vector<int>>& source_loops,
                                                         const std::vector<OverlayPose>& poses,
                                                         const ProjectedLoopsOptions& options) const {
  std::vector<ProjectedLoopsResult> out;
  for (const OverlayPose& pose : poses) {
    ProjectedLoopsOptions o = options;
    o.source_transform = pose.source_transform;
    o.target_transform = pose.target_transform;
    o.uniform_box = pose.uniform_box;
    out.push_back(project(source, source_loops, o));
  }
  return out;
}

ProjectedLoopsResult project_loops(const TriMesh& source, const std::vector<std::vector<int>>& source_loops,
                                   const SystemOfLoops& target, const Word& target_word,
                                   const ProjectedLoopsOptions& options, const Connectivity* target_conn) {
  return LoopProjector(target, target_word, target_conn).project(source, source_loops, options);
}

std::vector<ProjectedLoopsResult> project_loops(const TriMesh& source, const std::vector<std::vector<int>>& source_loops,
                                                const SystemOfLoops& target, const Word& target_word,
                                                const std::vector<OverlayPose>& poses,
                                                const ProjectedLoopsOptions& options) {
  return LoopProjector(target, target_word).project(source, source_loops, poses, options);
}

std::vector<OverlayPose> rotation_overlay_poses(const TriMesh& source, const TriMesh& target, double axis_tolerance) {
  // The cube group: signed permutation matrices of determinant +1.
  std::vector<Eigen::Matrix3d> cube;
  const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& p : perms)
    for (int signs = 0; signs < 8; ++signs) {
      Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
      for (int r = 0; r < 3; ++r) M(r, p[r]) = (signs >> r) & 1 ? -1.0 : 1.0;
      if (M.determinant() > 0) cube.push_back(M);
    }
  std::vector<OverlayPose> poses;
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  for (size_t k = 0; k < cube.size(); ++k) {
    if (cube[k].isApprox(I)) continue;
    poses.push_back({cube[k], I, "world axes, cube rotation " + std::to_string(k + 1) + " of 24"});
  }
  // Principal axes: source frame -> target frame, with the four sign
  // choices of the axes that keep them right-handed (the order of the
  // axes is fixed by the eigenvalues, so the other 20 rotations would send
  // a long axis to a short one).
  Eigen::Matrix3d Fs, Ft;
  if (principal_axes(source, axis_tolerance, &Fs) && principal_axes(target, axis_tolerance, &Ft)) {
    int k = 0;
    for (int signs = 0; signs < 8; ++signs) {
      Eigen::Matrix3d D = Eigen::Matrix3d::Zero();
      for (int r = 0; r < 3; ++r) D(r, r) = (signs >> r) & 1 ? -1.0 : 1.0;
      if (D.determinant() < 0) continue;
      ++k;
      const Eigen::Matrix3d relative = Ft * D * Fs.transpose();  // the rotation applied to the source
      // Already among the world poses (shapes aligned with the axes).
      if (is_signed_permutation(Ft, 1e-3) && is_signed_permutation(relative, 1e-3)) continue;
      poses.push_back({D * Fs.transpose(), Ft.transpose(), "principal axes, sign choice " + std::to_string(k) + " of 4"});
    }
  }
  return poses;
}

}  // namespace surfmap
