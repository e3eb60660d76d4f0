#include "hyperbolic_location.h"

#include <array>
#include <limits>
#include <memory>
#include <atomic>
#include <string>

#include "../concurrency.h"
#include "chart_elements.h"
#include "surfmap/error.h"
#include "surfmap/map/point_location.h"

namespace surfmap::detail {
namespace {

using hyperbolic::Mobius;

// Per target vertex its neighbours (CSR: neighbours of v at
// index[v]..index[v+1]).
struct VertexNeighbours {
  std::vector<int> index, list;
  explicit VertexNeighbours(const TriMesh& mesh) : index(mesh.num_vertices() + 1, 0) {
    for (int f = 0; f < mesh.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) index[mesh.F(f, k) + 1] += 2;
    for (int v = 0; v < mesh.num_vertices(); ++v) index[v + 1] += index[v];
    list.resize(index.back());
    std::vector<int> fill(index.begin(), index.end() - 1);
    for (int f = 0; f < mesh.num_faces(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int v = mesh.F(f, k);
        list[fill[v]++] = mesh.F(f, (k + 1) % 3), list[fill[v]++] = mesh.F(f, (k + 2) % 3);
      }
  }
};

}  // namespace

// The target's laid-out faces (the refined mesh of its system of loops) as
// a triangulation of the universal cover: a straight walk over them, from
// the face found for the previous vertex, crossing a cut edge by its deck
// map (so the walk never leaves the layout and does not depend on how the
// cut disk differs from P), with locate_in_cover as the fallback. Reads the
// target's layout and P and both surfaces' connectivity, not the class.
struct LocationCover {
  const DiskLayout* layout_ptr;
  const FundamentalPolygon* polygon;
  const int ntf;
  const Connectivity tconn;
  PlaneTriangles tpoints, ttris;  ///< #F refined target: Poincaré corners, Klein corners
  std::unique_ptr<TriangleGrid> grid;
  const VertexNeighbours neighbours;  ///< of the input target's vertices (the inverse's walks)
  const VertexNeighbours source_neighbours;  ///< of the source's vertices (the forward walks' starts)

  explicit LocationCover(const HyperbolicLocationInput& in)
      : layout_ptr(in.layout), polygon(in.polygon), ntf(in.target_loops->mesh.num_faces()),
        tconn(in.target_loops->mesh.F, in.target_loops->mesh.num_vertices()), tpoints(ntf), ttris(ntf),
        neighbours(*in.target), source_neighbours(*in.source) {
    for (int f = 0; f < ntf; ++f)
      for (int k = 0; k < 3; ++k) {
        tpoints[f][k] = in.layout->corners(f, k);
        ttris[f][k] = hyperbolic::poincare_to_klein(in.layout->corners(f, k));
      }
    grid = std::make_unique<TriangleGrid>(ttris, 1e-12);
  }
  /// Refined target face containing q (in P) with barycentrics, or -1;
  /// adds the faces the walk crossed to `steps`.
  int locate(int start_face, Complex q, Eigen::Vector3d* b, long* steps) const {
    const DiskLayout& layout = *layout_ptr;
    auto corners = [&](int f) {
      return std::array<Complex, 3>{layout.corners(f, 0), layout.corners(f, 1), layout.corners(f, 2)};
    };
    auto cross = [&](int f, int s, Complex& c, Complex& p, int* entry) {
      ++*steps;
      const int h = 3 * f + s, e = tconn.edge(h), t = tconn.twin(h);
      if (layout.cut_edge[e]) {
        const Mobius D = tconn.edge_halfedge(e) == h ? layout.edge_deck_mobius[e] : layout.edge_deck_mobius[e].inverse();
        c = D.apply(c), p = D.apply(p);
      }
      *entry = t % 3;
      return Connectivity::face(t);
    };
    int rf = straight_walk(start_face, q, corners, cross, 4 * ntf + 100, kInsideTolerance, b);
    if (rf < 0) rf = locate_in_cover(*grid, tpoints, *polygon, q, b);
    return rf;
  }
};

std::shared_ptr<const LocationCover> location_cover(const HyperbolicLocationInput& in) {
  return std::make_shared<const LocationCover>(in);
}

namespace {

// Per target vertex (#V of the input target, whose indices the refined mesh
// keeps) its copies in the cut disk: 1 inside, 2 on a loop, 4g at the base
// vertex (the corners of P).
std::vector<std::vector<Complex>> target_vertex_copies(const DiskLayout& layout, int num_vertices) {
  std::vector<std::vector<Complex>> copies(num_vertices);
  for (size_t d = 0; d < layout.disk_positions.size(); ++d) {
    const int v = layout.disk_vertex_origin[d];
    if (v >= 0 && v < num_vertices) copies[v].push_back(layout.disk_positions[d]);
  }
  return copies;
}

// (cosh d - 1) / 2 = |c - p|^2 / ((1 - |c|^2)(1 - |p|^2)): monotone in the
// hyperbolic distance d and free of transcendentals. A point that round-off
// put on or beyond |z| = 1 is infinitely far: a side map with entries of
// 1e4 applied to a point 1e-6 from |z| = 1 can land 3e-16 outside the disk,
// where the key came out negative and won every comparison (issue 13: the
// raw genus-11 wheel onto itself, 178 source vertices walked from that lift
// and located up to a third of the diagonal away).
double distance_key(Complex c, Complex p) {
  const double gc = 1.0 - std::norm(c), gp = 1.0 - std::norm(p);
  if (!(gc > 0) || !(gp > 0)) return std::numeric_limits<double>::infinity();
  return std::norm(c - p) / (gc * gp);
}

// The start of source vertex i's forward walk (issue 19) and the lift of its
// point q to walk to: of the face found for the previous vertex
// (`last_face`) and the faces found for i's located neighbours (`found`, -1
// when not located yet), and of q and its images under P's side maps, the
// pair with the face's corner 0 nearest to the lift in the layout's frame
// (ties: the earlier face, q before its images). Why: a walk from the
// previous index's face crosses O(sqrt #F) faces wherever the index order
// jumps (10% of a marching-cubes mesh's vertices), and one towards q itself
// crosses the whole disk when q lies in a part of P that the cut disk holds
// across a side (another 10%): 70 steps a vertex on average at 50k. A walk
// from next to the lift takes a step or two, and starting next to the query
// changes no chart (the reason the inverse's waves start next to theirs). A
// neighbour's face across a side of P is far from q in this frame and is
// not chosen, unlike a plain breadth-first start. When the best of these
// is still more than ~4 of its face's sides from its lift (1.6% of the
// walks at 50k crossed 32-2000 faces: next to a corner of P, where the lift
// needs a product of side maps, or after a jump with no located
// neighbour), the faces `grid` (over the layout's faces, Klein model)
// proposes at each lift are considered too.
int forward_walk_start(const DiskLayout& layout, const FundamentalPolygon& polygon, const TriangleGrid& grid,
                       const VertexNeighbours& neighbours, const std::vector<int>& found, int i, int last_face,
                       Complex& q, std::vector<Complex>& lifts) {
  lifts.assign(1, q);  // (scratch kept by the caller: no allocation per query)
  for (const hyperbolic::Mobius& S : polygon.side_maps()) lifts.push_back(S.apply(q));
  const int num_lifts = static_cast<int>(lifts.size());
  int start = -1, lift = 0;
  double nearest = std::numeric_limits<double>::infinity();
  auto consider = [&](int f) {
    const Complex c = layout.corners(f, 0);
    for (int l = 0; l < num_lifts; ++l) {
      const double d = distance_key(c, lifts[l]);
      if (d < nearest) nearest = d, start = f, lift = l;
    }
  };
  consider(last_face);
  if (start < 0) start = last_face;  // (q itself on |z| = 1: the walk and its fallback decide)
  for (int k = neighbours.index[i]; k < neighbours.index[i + 1]; ++k) {
    const int f = found[neighbours.list[k]];
    if (f >= 0 && f != start) consider(f);
  }
  // (cosh d - 1) / 2 grows like d^2 / 4: 16 x the key of a side is ~4 sides.
  if (nearest > 16 * distance_key(layout.corners(start, 0), layout.corners(start, 1)))
    for (int l = 0; l < num_lifts; ++l)
      for (int f : grid.candidates(hyperbolic::poincare_to_klein(lifts[l]))) {
        const double d = distance_key(layout.corners(f, 0), lifts[l]);
        if (d < nearest) nearest = d, start = f, lift = l;
      }
  q = lifts[lift];
  return start;
}

// The inverse of a map: per target vertex v the source face whose image, in
// its own frame (corner 0 in P), contains one of v's copies in the cut disk
// (no chart change needed; first pass, every vertex on its own). The
// vertices left over are located in waves outward from the located ones
// (issue 19): a vertex with a located neighbour walks towards its copy, or
// a copy's image under a side map of P, nearest to that neighbour's face,
// from that face (a start next to the
// query, found without a search), and once located puts its unlocated
// neighbours in the queue. Only a vertex no wave reaches (a component of
// left-over vertices with no located neighbour, or a failed walk) falls
// back, in index order: the walk from the grid candidate (of a copy's cell)
// whose corner 0 is nearest to a copy; then from the face whose corner 0 is
// nearest to a copy, over all faces (O(#F); before issue 19 every vertex
// whose neighbours came later in index order reached it); then
// the walk from the last located vertex's face towards v's reduced
// position, then locate_in_cover; a vertex so located seeds waves again.
// The result depends on nothing but the input (not on threads). Returns per
// vertex the face or -1, with the barycentrics in `bary`.
// Why walks start next to the query: while the query is far from the walk's
// current face, the chart changes (deck elements, with entries of 1e3 and
// more at a corner of a long, thin P where the 4g copies of the base vertex
// meet) send it to within 1e-10 of |z| = 1, where their round-off moves it by
// ~0.4 (hyperbolic): the walk then ends up to three triangles from the
// preimage (docs/verification.md). A walk that starts next to the query
// keeps it near the current face, where the chart changes are accurate.
// `stop`: give up (return what is located) when raised. `full_search`: no
// waves and no grid start, every left-over vertex from the scan over all
// faces (the reference, testing/map_hooks.h).
template <class Corners, class Cross>
std::vector<int> locate_target_vertices(const std::vector<std::vector<Complex>>& copies, const DiskLayout& layout,
                                        const VertexNeighbours& neighbours, const FundamentalPolygon& polygon,
                                        const TriangleGrid& grid, const PlaneTriangles& points, const Corners& corners,
                                        const Cross& cross, int max_steps, std::vector<Eigen::Vector3d>& bary,
                                        const std::atomic<bool>* stop, InverseLocationCounts* counts = nullptr,
                                        bool full_search = false) {
  const int nv = static_cast<int>(copies.size());
  InverseLocationCounts local;
  InverseLocationCounts& count = counts ? *counts : local;
  std::vector<int> face(nv, -1);
  bary.assign(nv, Eigen::Vector3d::Zero());
  for (int v = 0; v < nv; ++v) face[v] = locate_copies_in_frame(grid, points, copies[v], &bary[v]);
  for (int v = 0; v < nv; ++v) count.in_frame += face[v] >= 0;
  // Walk from the start face (among `starts`) whose corner 0 is nearest to
  // one of `targets` (v's copies, or also their side-map images), towards
  // that point; -1 when there is no start or the walk fails.
  auto walk_from_nearest_of = [&](int v, const std::vector<Complex>& targets, auto&& for_each_start) {
    double nearest = std::numeric_limits<double>::infinity();
    int start = -1;
    Complex towards;
    for_each_start([&](int g) {
      for (const Complex& c : targets) {
        const double d = distance_key(c, points[g][0]);
        if (d < nearest) nearest = d, start = g, towards = c;
      }
    });
    return start >= 0 ? straight_walk(start, towards, corners, cross, max_steps, kInsideTolerance, &bary[v]) : -1;
  };
  auto walk_from_nearest = [&](int v, auto&& for_each_start) { return walk_from_nearest_of(v, copies[v], for_each_start); };
  // Whether face f at barycentrics b holds a copy of v: the point within
  // half of f's longest side of one of v's copies in the cut disk, or of
  // one reduced into P when the point is too. A walk
  // whose chart changes lost their digits near a corner of P can end in a
  // face whose image holds the moved query, not v (one target vertex of a
  // genus-6 pair, 7.8 triangles away, certificate's inverse check); such a
  // result of the waves or of the grid start is dropped and the next fallback
  // runs. The later fallbacks (the scan from the nearest corner, the reference
  // of MapHooks::inverse_full_search, then the last face's walk and
  // locate_in_cover) are taken as they come: nothing is left after them. Hyperboloid barycentrics
  // (hyperbolic::triangle_barycentric): the point is Σ b_k X_k normalised.
  auto holds_copy = [&](int v, int f, const Eigen::Vector3d& b) {
    if (f < 0) return false;
    Eigen::Vector3d X = Eigen::Vector3d::Zero();
    double longest = 0;
    for (int k = 0; k < 3; ++k) {
      const Complex z = points[f][k];
      const double n = std::norm(z);
      X += b[k] * Eigen::Vector3d(2 * z.real(), 2 * z.imag(), 1 + n) / (1 - n);
      longest = std::max(longest, hyperbolic::distance(z, points[f][(k + 1) % 3]));
    }
    const double q = X[2] * X[2] - X[0] * X[0] - X[1] * X[1];
    if (!(q > 0) || !(X[2] > 0)) return false;
    X /= std::sqrt(q);
    const Complex p(X[0] / (1 + X[2]), X[1] / (1 + X[2]));
    Complex pr = p;
    polygon.reduce(pr);
    const double tol = std::max(1e-6, 0.5 * longest);
    for (Complex c : copies[v]) {  // (copies in the cut disk: reduced into P like the point)
      if (hyperbolic::distance(p, c) <= tol) return true;
      polygon.reduce(c);
      if (hyperbolic::distance(pr, c) <= tol) return true;
    }
    return false;
  };
  // The waves walk towards v's copies and their images under P's side maps
  // (issue 19): a left-over vertex lies next to a side of the cut disk, and
  // the copy next to its located neighbour is often the one across that
  // side, not a copy in the disk (whose walk crossed the whole disk: ~500
  // faces for each of the 6% left-over vertices at 50k).
  std::vector<Complex> lifts;
  auto from_neighbours = [&](int v) {
    lifts = copies[v];
    for (const Complex& c : copies[v])
      for (const hyperbolic::Mobius& S : polygon.side_maps()) lifts.push_back(S.apply(c));
    return walk_from_nearest_of(v, lifts, [&](auto&& visit) {
      for (int k = neighbours.index[v]; k < neighbours.index[v + 1]; ++k)
        if (face[neighbours.list[k]] >= 0) visit(face[neighbours.list[k]]);
    });
  };
  // Waves: a FIFO of unlocated vertices with a located neighbour.
  std::vector<char> queued(nv, 0);
  std::vector<int> queue;
  size_t head = 0;
  auto enqueue_neighbours = [&](int v) {
    for (int k = neighbours.index[v]; k < neighbours.index[v + 1]; ++k) {
      const int u = neighbours.list[k];
      if (face[u] < 0 && !queued[u]) queued[u] = 1, queue.push_back(u);
    }
  };
  for (int v = 0; v < nv && !full_search; ++v)
    if (face[v] >= 0) enqueue_neighbours(v);
  auto run_waves = [&] {
    for (; head < queue.size(); ++head) {
      if (stop && *stop) return;
      const int v = queue[head];
      const int f = from_neighbours(v);
      if (!holds_copy(v, f, bary[v])) continue;  // left to the fallbacks below
      face[v] = f, ++count.from_neighbour;
      enqueue_neighbours(v);
    }
  };
  run_waves();
  int last_face = 0;
  for (int v = 0; v < nv; ++v) {
    if (stop && *stop) break;
    if (face[v] >= 0) {
      last_face = face[v];
      continue;
    }
    Eigen::Vector3d& b = bary[v];
    // From the grid candidate (of a copy's cell) nearest to a copy.
    int f = full_search ? -1 : walk_from_nearest(v, [&](auto&& visit) {
      for (const Complex& c : copies[v])
        for (int g : grid.candidates(hyperbolic::poincare_to_klein(c))) visit(g);
    });
    if (f >= 0 && !holds_copy(v, f, b)) f = -1;
    if (f >= 0) ++count.from_grid;
    if (f < 0) {  // from the face whose corner 0 is nearest to a copy, over all faces
      ++count.full_scan;
      f = walk_from_nearest(v, [&](auto&& visit) {
        for (int g = 0; g < static_cast<int>(points.size()); ++g) visit(g);
      });
    }
    if (f < 0) {
      Complex q = layout.vertex_positions[v];
      polygon.reduce(q);
      f = straight_walk(last_face, q, corners, cross, max_steps, kInsideTolerance, &b);
    }
    if (f < 0) f = locate_in_cover(grid, points, polygon, layout.vertex_positions[v], &b);
    if (f < 0) break;  // the caller reports v
    face[v] = last_face = f;
    if (full_search) continue;
    enqueue_neighbours(v);
    run_waves();
  }
  return face;
}

// The initial map located like the optimum (its "before" morph and UVs); a
// vertex that cannot be located leaves that output empty, not an error.
// Gives up when `stop` is raised (the other task failed).
void locate_initial(const HyperbolicLocationInput& in, const LocationCover& cover, const std::atomic<bool>* stop,
                    HyperbolicLocationResult& out) {
  const TriMesh& source = *in.source;
  const Connectivity& sc = *in.sc;
  const DiskLayout& layout = *in.layout;
  const FundamentalPolygon& polygon = *in.polygon;
  const HyperbolicInitialMapResult& init = *in.init;
  std::vector<int> initial_face_origin(cover.ntf, -1);
  out.initial_forward.resize(source.num_vertices());
  int last_face = layout.root_face >= 0 ? layout.root_face : 0;
  std::vector<int> found(source.num_vertices(), -1);
  std::vector<Complex> lifts;
  for (int i = 0; i < source.num_vertices(); ++i) {
    if (*stop) return;
    Eigen::Vector3d b;
    Complex q = init.z[i];
    polygon.reduce(q);
    const int start = forward_walk_start(layout, polygon, *cover.grid, cover.source_neighbours, found, i, last_face, q, lifts);
    long steps = 0;
    const int rf = cover.locate(start, q, &b, &steps);
    if (rf < 0) {
      out.initial_forward.clear();
      break;
    }
    last_face = found[i] = rf;
    out.initial_forward[i] = point_on_input(*in.target, *in.tc, *in.target_loops, in.target_intrinsic, initial_face_origin, rf, b);
  }
  // The initial map's inverse (the "before" UV transfer): its image
  // triangles from its own chart elements, each moved into P by the
  // reduction of its corner 0, located by the grid; left empty (not an
  // error) when a target vertex is not covered.
  auto init_eff = [&](int h) { return effective_element(init, h, sc, *in.group, *in.halfedge_word, *in.halfedge_rho); };
  // Corner k of face f is init_corner[3f+k] applied to its vertex's point
  // (corner 0 reduced into P); the walk crosses into the neighbour g
  // through the shared vertex u by init_corner(g, u) init_corner(f, u)^-1.
  std::vector<Mobius> init_corner(3 * source.num_faces());
  PlaneTriangles ipoints(source.num_faces()), itris(source.num_faces());
  for (int f = 0; f < source.num_faces(); ++f) {
    Complex c0 = init.z[source.F(f, 0)];
    const Mobius R = in.group->evaluate_side_word(polygon.reduce(c0));
    init_corner[3 * f] = R;
    init_corner[3 * f + 1] = (R * init_eff(3 * f)).normalized();
    init_corner[3 * f + 2] = (R * init_eff(3 * f + 2).inverse()).normalized();
    ipoints[f] = {c0, init_corner[3 * f + 1].apply(init.z[source.F(f, 1)]),
                  init_corner[3 * f + 2].apply(init.z[source.F(f, 2)])};
    for (int k = 0; k < 3; ++k) itris[f][k] = hyperbolic::poincare_to_klein(ipoints[f][k]);
  }
  auto init_corners = [&](int f) { return ipoints[f]; };
  auto init_cross = [&](int f, int s, Complex& c, Complex& q, int* entry) {
    const int h = 3 * f + s, t = sc.twin(h), g = Connectivity::face(t);
    const int cg = (t % 3 + 1) % 3;
    const Mobius M = (init_corner[3 * g + cg] * init_corner[3 * f + s].inverse()).normalized();
    c = M.apply(c), q = M.apply(q);
    *entry = t % 3;
    return g;
  };
  const TriangleGrid igrid(itris, 1e-12);
  const std::vector<std::vector<Complex>> copies = target_vertex_copies(layout, in.target->num_vertices());
  std::vector<Eigen::Vector3d> bary;
  const std::vector<int> face = locate_target_vertices(copies, layout, cover.neighbours, polygon, igrid, ipoints,
                                                       init_corners, init_cross, 4 * source.num_faces() + 100, bary, stop);
  if (*stop) return;
  out.initial_inverse.resize(in.target->num_vertices());
  for (int v = 0; v < in.target->num_vertices(); ++v) {
    if (face[v] < 0) {
      out.initial_inverse.clear();
      break;
    }
    out.initial_inverse[v] = point_in_face(source, face[v], bary[v]);
  }
}

// The optimum's inverse: every target vertex located in the source's image
// triangles (locate_target_vertices). Gives up when `stop` is raised (the
// forward location failed on the calling thread); nullptr: never.
void locate_inverse(const HyperbolicLocationInput& in, const LocationCover& cover, const std::atomic<bool>* stop,
                    HyperbolicLocationResult& out) {
  const TriMesh& source = *in.source;
  const Connectivity& sc = *in.sc;
  const DiskLayout& layout = *in.layout;
  const FundamentalPolygon& polygon = *in.polygon;
  const auto& img = *in.image;
  auto eff = [&](int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? (*in.eff_edge)[e] : (*in.eff_edge)[e].inverse();
  };
  PlaneTriangles spoints(source.num_faces()), stris(source.num_faces());
  for (int f = 0; f < source.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) {
      spoints[f][k] = img(f, k);
      stris[f][k] = hyperbolic::poincare_to_klein(img(f, k));
    }
  const TriangleGrid sgrid(stris, 1e-12);
  // Inverse map: the same walk over the source's image triangles. Face f's
  // image is stored with corner k at γ_{f,k}(zp[F(f,k)]) (γ_{f,0} = id,
  // γ_{f,1} = eff(h0), γ_{f,2} = eff(h2)^-1); crossing into face g through
  // the vertex u they share maps the query by γ_{g,u} γ_{f,u}^-1 (identity
  // unless the edge straddles a side of P).
  auto corner_element = [&](int f, int k) {
    return k == 0 ? Mobius() : k == 1 ? eff(3 * f) : eff(3 * f + 2).inverse();
  };
  auto source_corners = [&](int f) { return std::array<Complex, 3>{img(f, 0), img(f, 1), img(f, 2)}; };
  auto source_cross = [&](int f, int s, Complex& c, Complex& q, int* entry) {
    ++out.inverse_walk_steps;
    const int h = 3 * f + s, t = sc.twin(h), g = Connectivity::face(t);
    // Shared vertex u = tail(h) = corner s of f = corner (t+1)%3 of g.
    const int cg = (t % 3 + 1) % 3;
    const Mobius M = (corner_element(g, cg) * corner_element(f, s).inverse()).normalized();
    c = M.apply(c), q = M.apply(q);
    *entry = t % 3;
    return g;
  };
  const std::vector<std::vector<Complex>> copies = target_vertex_copies(layout, in.target->num_vertices());
  std::vector<Eigen::Vector3d> bary;
  const std::vector<int> face = locate_target_vertices(copies, layout, cover.neighbours, polygon, sgrid, spoints,
                                                       source_corners, source_cross, 4 * source.num_faces() + 100,
                                                       bary, stop, &out.inverse_counts,
                                                       in.inverse_full_search);
  if (stop && *stop) return;  // (the forward location failed: its error is reported)
  out.inverse.resize(in.target->num_vertices());
  for (int v = 0; v < in.target->num_vertices(); ++v) {
    if (face[v] < 0) throw SolveError("target vertex " + std::to_string(v) + " could not be located in the source image");
    out.inverse[v] = point_in_face(source, face[v], bary[v]);
  }
}

}  // namespace

HyperbolicLocationResult locate_hyperbolic_map(const HyperbolicLocationInput& in, const StageDone& stage_done) {
  const TriMesh& source = *in.source;
  const DiskLayout& layout = *in.layout;
  const FundamentalPolygon& polygon = *in.polygon;
  const std::vector<Complex>& zp = *in.zp;
  // (built here unless the caller built it ahead: it does not depend on the class)
  const std::shared_ptr<const LocationCover> own_cover = in.cover ? nullptr : location_cover(in);
  const LocationCover& cover = in.cover ? *in.cover : *own_cover;
  HyperbolicLocationResult out;
  // Three independent tasks (concurrency.h): the optimum's forward location
  // on the calling thread, which reports the stage; its inverse (issue 19,
  // session 23: on the second thread beside the forward walks) and the
  // initial map's location (when asked for) taken in that order by
  // whichever thread is free. Each writes only its own outputs and reads
  // the shared cover, so the result does not depend on the threads.
  const std::atomic<bool> never{false};
  parallel_for(in.threads, in.locate_initial ? 3 : 2, [&](int task, const std::atomic<bool>* stop) {
    if (task == 2) return locate_initial(in, cover, stop ? stop : &never, out);
    if (task == 1) return locate_inverse(in, cover, stop, out);
    // Forward map: the walk over the target's faces.
    std::vector<int> refined_face_origin(cover.ntf, -1);
    out.forward.resize(source.num_vertices());
    int last_face = layout.root_face >= 0 ? layout.root_face : 0;
    std::vector<int> found(source.num_vertices(), -1);
    std::vector<Complex> lifts;
    for (int i = 0; i < source.num_vertices(); ++i) {
      Eigen::Vector3d b;
      Complex q = zp[i];
      const int start = in.forward_index_order
                            ? last_face
                            : forward_walk_start(layout, polygon, *cover.grid, cover.source_neighbours, found, i, last_face, q, lifts);
      const int rf = cover.locate(start, q, &b, &out.forward_walk_steps);
      if (rf < 0) throw SolveError("source vertex " + std::to_string(i) + " could not be located on the target");
      last_face = found[i] = rf;
      out.forward[i] = point_on_input(*in.target, *in.tc, *in.target_loops, in.target_intrinsic, refined_face_origin, rf, b);
    }
    stage_done("forward location", 0.9);
  });
  return out;
}

}  // namespace surfmap::detail
