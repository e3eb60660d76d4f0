// Ears whose images turn over: the middle corner's image slid along the
// other boundary (map/ear_images.h; docs/open_surfaces.md, "Ears").
#include "surfmap/map/ear_images.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <unordered_map>

#include <Eigen/Geometry>

#include "surfmap/map/distortion.h"

namespace surfmap {
namespace {

// Where a point lies on a boundary polyline: loop, edge (from vertex `edge`
// to the next one in the loop's order) and the fraction along it.
struct OnLoop {
  int loop = -1, edge = -1;
  double t = 0;
};

OnLoop nearest_on_boundary(const TriMesh& mesh, const OpenSurfaceTopology& topology, const Eigen::Vector3d& p) {
  OnLoop best;
  double best_d = std::numeric_limits<double>::infinity();
  for (int l = 0; l < topology.num_boundary_loops(); ++l) {
    const auto& loop = topology.boundary_loops[l];
    const int n = static_cast<int>(loop.size());
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d a = mesh.V.row(loop[i]), b = mesh.V.row(loop[(i + 1) % n]);
      const Eigen::Vector3d d = b - a;
      const double t = std::clamp((p - a).dot(d) / std::max(d.squaredNorm(), 1e-300), 0.0, 1.0);
      const double dist = (a + t * d - p).squaredNorm();
      if (dist < best_d) best_d = dist, best = {l, i, t};
    }
  }
  return best;
}

}  // namespace

EarImagesResult slide_ear_images(const TriMesh& mesh, const OpenSurfaceTopology& mesh_topology, const TriMesh& other,
                                 const OpenSurfaceTopology& other_topology, std::vector<PointOnSurface>& images,
                                 const EarImagesOptions& options) {
  EarImagesResult r;
  const int nv = mesh.num_vertices();
  // Each boundary vertex's loop and its place in it.
  std::vector<int> loop_of(nv, -1), place(nv, -1);
  for (int l = 0; l < mesh_topology.num_boundary_loops(); ++l)
    for (int i = 0; i < static_cast<int>(mesh_topology.boundary_loops[l].size()); ++i)
      loop_of[mesh_topology.boundary_loops[l][i]] = l, place[mesh_topology.boundary_loops[l][i]] = i;
  // u -> w is a boundary edge in the loop's direction (the surface on its left).
  auto boundary_edge = [&](int u, int w) {
    if (loop_of[u] < 0 || loop_of[u] != loop_of[w]) return false;
    const int n = static_cast<int>(mesh_topology.boundary_loops[loop_of[u]].size());
    return (place[u] + 1) % n == place[w];
  };
  // The other mesh's face across each of its halfedges u -> w, and its normals.
  std::unordered_map<long long, int> halfedge_face;
  const long long no = other.num_vertices();
  for (int f = 0; f < other.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) halfedge_face[other.F(f, k) * no + other.F(f, (k + 1) % 3)] = f;
  auto normal = [&](int f) -> Eigen::Vector3d {
    const Eigen::Vector3d a = other.V.row(other.F(f, 0)), b = other.V.row(other.F(f, 1)),
                          c = other.V.row(other.F(f, 2));
    return (b - a).cross(c - a);
  };
  const double sign = options.reversing ? -1.0 : 1.0;
  std::vector<char> held(nv, 0);
  for (int v : options.held)
    if (v >= 0 && v < nv) held[v] = 1;
  // The image's signed area against the other's normals at its corners'
  // faces, over the squared longest side (<= 1e-12: turned or degenerate).
  auto orientation = [&](const PointOnSurface& p, const PointOnSurface& q, const PointOnSurface& s) {
    const Eigen::Vector3d n = normal(p.face) + normal(q.face) + normal(s.face);
    const double longest = std::max({(q.position - p.position).squaredNorm(), (s.position - q.position).squaredNorm(),
                                     (p.position - s.position).squaredNorm()});
    return sign * n.normalized().dot((q.position - p.position).cross(s.position - p.position)) /
           std::max(longest, 1e-300);
  };
  std::vector<std::vector<int>> star(nv);
  for (int f = 0; f < mesh.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) star[mesh.F(f, k)].push_back(f);
  std::vector<int> ears;
  for (int f = 0; f < mesh.num_faces(); ++f)
    if (loop_of[mesh.F(f, 0)] >= 0 && loop_of[mesh.F(f, 1)] >= 0 && loop_of[mesh.F(f, 2)] >= 0) ears.push_back(f);
  r.ears = static_cast<int>(ears.size());
  auto face_orientation = [&](int f) {
    return orientation(images[mesh.F(f, 0)], images[mesh.F(f, 1)], images[mesh.F(f, 2)]);
  };
  auto turned = [&](int f) { return face_orientation(f) <= 1e-12; };
  auto sides_of = [&](int f, bool image) {
    Eigen::Vector3d p[3];
    for (int k = 0; k < 3; ++k)
      p[k] = image ? images[mesh.F(f, k)].position : Eigen::Vector3d(mesh.V.row(mesh.F(f, k)));
    return Eigen::Vector3d((p[1] - p[0]).norm(), (p[2] - p[1]).norm(), (p[0] - p[2]).norm());
  };
  // Rights the ear `ear` whose middle corner is b by sliding the images of
  // the 2 w + 1 vertices of b's loop centred on b along the other boundary,
  // within the arc from the image of the vertex before them to that of the
  // vertex after them (at most half the other loop), each image kept or put
  // on a vertex of that arc (the middle corner alone: any of up to
  // `max_arc_alone`; a window, whose choices multiply: up to `max_arc`
  // evenly spaced along a longer arc), all in the same order
  // along it (held vertices keep theirs). The choice where the ear and every
  // face of their stars that was not turned are positively oriented and the
  // largest D' among those faces is least; none: nothing moves.
  const int max_arc = 32, max_arc_alone = 1024;
  auto right_ear = [&](int ear, int b, int w) {
    const auto& own = mesh_topology.boundary_loops[loop_of[b]];
    const int m = static_cast<int>(own.size());
    if (2 * w + 3 > m) return false;  // the window would wrap around the loop
    std::vector<int> corner;
    for (int k = -w; k <= w; ++k) corner.push_back(own[((place[b] + k) % m + m) % m]);
    const int before = own[((place[b] - w - 1) % m + m) % m], after = own[(place[b] + w + 1) % m];
    const OnLoop lp = nearest_on_boundary(other, other_topology, images[before].position),
                 ln = nearest_on_boundary(other, other_topology, images[after].position),
                 lb = nearest_on_boundary(other, other_topology, images[b].position);
    if (lp.loop < 0 || lp.loop != ln.loop || lb.loop != lp.loop) return false;
    const auto& loop = other_topology.boundary_loops[lp.loop];
    const int n = static_cast<int>(loop.size());
    auto ahead = [&](const OnLoop& from, const OnLoop& to) {
      double d = to.edge + to.t - (from.edge + from.t);
      return d < 0 ? d + n : d;
    };
    // Places along the arc from `before`'s image, in whichever direction holds b's.
    const bool forward = ahead(lp, lb) <= ahead(lp, ln);
    auto along = [&](const OnLoop& l) { return forward ? ahead(lp, l) : ahead(l, lp); };
    const double end = along(ln);
    // Not a short arc (past half the loop and 32 vertices: the images run
    // the other way round): leave it. A
    // dense other boundary (a scan's rim under a coarse mask's ear) has long
    // arcs: every vertex for the middle corner alone, a sample for a window.
    if (end > std::max(0.5 * n, static_cast<double>(max_arc))) return false;
    const int limit = w == 0 ? max_arc_alone : max_arc;
    const int stride = std::max(1, static_cast<int>(std::ceil(end / limit)));
    struct Option {
      PointOnSurface point;
      double s;
    };
    std::vector<Option> vertices;
    for (int step = 1; step <= n; step += stride) {
      const int j = forward ? (lp.edge + step) % n : ((lp.edge + (lp.t > 0 ? 1 : 0) - step) % n + n) % n;
      // Not onto (or within 1e-6 of an edge from) the images the arc runs between.
      const double sj = along(OnLoop{lp.loop, j, 0.0});
      if (sj >= end - 1e-6) break;
      if (sj <= 1e-6) continue;
      const auto it = halfedge_face.find(loop[j] * no + loop[(j + 1) % n]);
      if (it == halfedge_face.end()) continue;
      PointOnSurface q;
      q.face = it->second;
      q.barycentric.setZero();
      for (int k = 0; k < 3; ++k)
        if (other.F(q.face, k) == loop[j]) q.barycentric[k] = 1.0;
      q.position = other.V.row(loop[j]);
      vertices.push_back({q, sj});
    }
    const int count = static_cast<int>(corner.size());
    std::vector<std::vector<Option>> choices(count);
    std::vector<PointOnSurface> kept(count), chosen(count);
    for (int k = 0; k < count; ++k) {
      kept[k] = chosen[k] = images[corner[k]];
      const OnLoop lk = nearest_on_boundary(other, other_topology, images[corner[k]].position);
      if (lk.loop != lp.loop) return false;
      choices[k].push_back({images[corner[k]], along(lk)});
      if (!held[corner[k]]) choices[k].insert(choices[k].end(), vertices.begin(), vertices.end());
    }
    // The faces of the window's stars, each checked as soon as its last
    // window corner has its image (so that a partial choice that turns a
    // face, or is already worse than the best, is cut off early).
    std::vector<int> faces;
    for (int x : corner) faces.insert(faces.end(), star[x].begin(), star[x].end());
    std::sort(faces.begin(), faces.end());
    faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
    std::vector<std::vector<int>> settled(count);
    for (int f : faces) {
      int last = 0;
      for (int k = 0; k < count; ++k)
        for (int i = 0; i < 3; ++i)
          if (mesh.F(f, i) == corner[k]) last = std::max(last, k);
      // Faces already turned (another ear not righted) may stay so; the ear
      // itself and every other face must come out positively oriented.
      if (f == ear || !turned(f)) settled[last].push_back(f);
    }
    // A window moves the ear's neighbours too: only below the D' bound.
    double best = w > 0 ? options.window_max_dilatation : std::numeric_limits<double>::infinity();
    bool found = false;
    // Every assignment strictly increasing along the arc (depth first).
    std::function<void(int, double, double)> assign = [&](int k, double after_s, double worst) {
      if (k == count) {
        best = worst;
        found = true;
        for (int i = 0; i < count; ++i) chosen[i] = images[corner[i]];
        return;
      }
      for (const Option& o : choices[k]) {
        if (o.s <= after_s || o.s >= end) continue;
        images[corner[k]] = o.point;
        double w_here = worst;
        bool ok = true;
        for (int f : settled[k]) {
          if (turned(f)) {
            ok = false;
            break;
          }
          w_here = std::max(w_here, triangle_dilatation(sides_of(f, false), sides_of(f, true)));
          if (w_here >= best) {
            ok = false;
            break;
          }
        }
        if (ok) assign(k + 1, o.s, w_here);
      }
      images[corner[k]] = kept[k];
    };
    assign(0, 0.0, 0.0);
    for (int k = 0; k < count; ++k) images[corner[k]] = found ? chosen[k] : kept[k];
    return found;
  };
  for (int f : ears) {
    if (!turned(f)) continue;
    ++r.turned;
    // The middle corner (between the ear's two boundary edges) alone first;
    // windows of its neighbours too only when that fails (header).
    for (int j = 0; j < 3; ++j) {
      const int a = mesh.F(f, (j + 2) % 3), b = mesh.F(f, j), c = mesh.F(f, (j + 1) % 3);
      if (boundary_edge(a, b) && boundary_edge(b, c)) {
        for (int w = 0; w <= std::max(0, options.max_half_window); ++w)
          if (right_ear(f, b, w)) {
            ++r.moved;
            r.moved_with_neighbours += w > 0;
            break;
          }
        break;
      }
    }
  }
  for (int f : ears) r.turned_after += turned(f);
  return r;
}

}  // namespace surfmap
