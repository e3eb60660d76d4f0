#include "surfmap/mesh/intake.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iomanip>
#include <memory>
#include <numeric>
#include <sstream>
#include <string>

#include <Eigen/Geometry>

#include "surfmap/error.h"
#include "surfmap/geometry/mollify.h"
#include "surfmap/mesh/connectivity.h"

namespace surfmap {
namespace {

std::string plural(size_t n, const std::string& word) {
  if (n == 1) return "1 " + word;
  return std::to_string(n) + " " + (word == "vertex" ? std::string("vertices") : word + "s");
}

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(int n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int find(int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void unite(int a, int b) { parent[find(a)] = find(b); }
};

// Fan triangulation of the soup, remembering each triangle's polygon. Only
// well-formed polygons (>= 3 distinct in-range indices) are triangulated.
struct Triangulation {
  std::vector<std::array<int, 3>> tris;
  std::vector<int> source_polygon;
};

// Mollifies the edge lengths of a valid closed mesh the way the solvers will
// (same lengths, same margin) and records what it touched.
void mollify_note(const RowMatrixX3d& V, const Connectivity& conn, const IntakeOptions& options, MeshInfo& info) {
  Eigen::VectorXd lengths(conn.num_edges());
  for (int e = 0; e < conn.num_edges(); ++e)
    lengths[e] = (V.row(conn.edge_vertex(e, 0)) - V.row(conn.edge_vertex(e, 1))).norm();
  if (!lengths.allFinite()) {
    info.problems.push_back("edge lengths overflow (coordinates too large); rescale the mesh");
    return;
  }
  const MollifyResult m = mollify_edge_lengths(lengths, conn, options.mollify_margin);
  info.mollified_faces = m.faces_touched;
  info.mollify_epsilon = m.epsilon;
  if (m.faces_touched == 0) return;
  std::ostringstream s;
  s << "mollified: " << plural(m.faces_touched, "face") << ", ε = " << std::setprecision(3) << m.epsilon
    << " (" << std::setprecision(3) << m.epsilon / lengths.mean() << " of the mean edge length) added to every "
    << "edge length so every triangle is strictly valid";
  if (info.zero_area_faces > 0) s << "; " << plural(info.zero_area_faces, "face") << " had zero area";
  info.notes.push_back(s.str());
}

// The analysis shared by inspect() and intake(): every check, each problem
// with its offending elements, in the order a user should fix them.
struct Analysis {
  MeshInfo info;
  Triangulation tri;
  bool usable_topology = false;  // triangles well-formed, closed, manifold, oriented
};

// Step 1: every coordinate finite. False (the problem recorded) when not:
// nothing geometric can be trusted after that.
bool check_coordinates(const PolygonSoup& soup, std::vector<std::string>& problems) {
  for (int v = 0; v < static_cast<int>(soup.V.rows()); ++v) {
    if (!soup.V.row(v).allFinite()) {
      std::ostringstream s;
      s << "vertex " << v << " has a non-finite coordinate (" << soup.V(v, 0) << ", " << soup.V(v, 1)
        << ", " << soup.V(v, 2) << ")";
      problems.push_back(s.str());
      return false;
    }
  }
  return true;
}

// Step 2: every polygon has >= 3 distinct in-range vertex indices. Records
// each offending face; true when all are well-formed.
bool check_face_indices(const PolygonSoup& soup, int nv, std::vector<std::string>& problems) {
  bool indices_ok = true;
  for (size_t p = 0; p < soup.polygons.size(); ++p) {
    const auto& poly = soup.polygons[p];
    if (poly.size() < 3) {
      problems.push_back("face " + std::to_string(p) + " has only " + plural(poly.size(), "vertex"));
      indices_ok = false;
      continue;
    }
    for (int idx : poly) {
      if (idx < 0 || idx >= nv) {
        problems.push_back("face " + std::to_string(p) + " refers to vertex " + std::to_string(idx) +
                           ", out of range (the mesh has " + plural(nv, "vertex") + ")");
        indices_ok = false;
        break;
      }
    }
    std::vector<int> sorted = poly;
    std::sort(sorted.begin(), sorted.end());
    auto dup = std::adjacent_find(sorted.begin(), sorted.end());
    if (dup != sorted.end()) {
      problems.push_back("face " + std::to_string(p) + " repeats vertex " + std::to_string(*dup));
      indices_ok = false;
    }
  }
  return indices_ok;
}

// Fan triangulation of well-formed polygons (step 2 passed).
Triangulation fan_triangulate(const PolygonSoup& soup) {
  Triangulation tri;
  for (size_t p = 0; p < soup.polygons.size(); ++p) {
    const auto& poly = soup.polygons[p];
    for (size_t k = 1; k + 1 < poly.size(); ++k) {
      tri.tris.push_back({poly[0], poly[k], poly[k + 1]});
      tri.source_polygon.push_back(static_cast<int>(p));
    }
  }
  return tri;
}

// Step 3: the mesh has a finite, non-zero extent; counts the exactly
// zero-area triangles relative to the bounding box so the test is
// scale-free. They are accepted (mollified in step 6, once the topology is
// known); only a mesh whose vertices all coincide has no geometry at all.
// False (the problem recorded) when there is no usable extent.
bool check_extent(const PolygonSoup& soup, const Triangulation& tri, const IntakeOptions& options,
                  MeshInfo& info) {
  const Eigen::Vector3d lo = soup.V.colwise().minCoeff(), hi = soup.V.colwise().maxCoeff();
  const double diag2 = (hi - lo).squaredNorm();
  if (!std::isfinite(diag2)) {
    info.problems.push_back("the coordinates are too large (the bounding box diagonal overflows); rescale the mesh");
    return false;
  }
  if (!(diag2 > 0)) {
    info.problems.push_back("all " + plural(info.num_vertices, "vertex") +
                            " are at the same position (the mesh has no extent)");
    return false;
  }
  for (const auto& f : tri.tris) {
    const Eigen::Vector3d e1 = soup.V.row(f[1]) - soup.V.row(f[0]);
    const Eigen::Vector3d e2 = soup.V.row(f[2]) - soup.V.row(f[0]);
    if (0.5 * e1.cross(e2).norm() <= options.area_tolerance * diag2) ++info.zero_area_faces;
  }
  return true;
}

// What step 4 found on the edges; vertices_uf joins the vertices of each
// edge (the components of step 5).
struct EdgeCheck {
  int nonmanifold = 0, boundary = 0, misoriented = 0;
  UnionFind vertices_uf;
  explicit EdgeCheck(int nv) : vertices_uf(nv) {}
};

// Step 4: edges grouped by their unordered vertex pair: non-manifold edges
// (> 2 faces), boundary edges and their loops, inconsistently oriented
// pairs; each kind recorded with its first offender.
EdgeCheck check_edges(const Triangulation& tri, const IntakeOptions& options, MeshInfo& info) {
  const int nv = info.num_vertices;
  const int nt = static_cast<int>(tri.tris.size());
  auto& problems = info.problems;
  std::vector<std::pair<long long, int>> keys(3 * nt);
  for (int h = 0; h < 3 * nt; ++h) {
    const int u = tri.tris[h / 3][h % 3], w = tri.tris[h / 3][(h % 3 + 1) % 3];
    keys[h] = {static_cast<long long>(std::min(u, w)) * nv + std::max(u, w), h};
  }
  std::sort(keys.begin(), keys.end());
  EdgeCheck c(nv);
  int num_edges = 0;
  std::string first_nonmanifold, first_boundary, first_misoriented;
  UnionFind boundary_uf(nv);
  std::vector<char> on_boundary(nv, 0);
  for (size_t i = 0; i < keys.size();) {
    size_t j = i;
    while (j < keys.size() && keys[j].first == keys[i].first) ++j;
    ++num_edges;
    const int h0 = keys[i].second;
    const int u = tri.tris[h0 / 3][h0 % 3], w = tri.tris[h0 / 3][(h0 % 3 + 1) % 3];
    const std::string name = "(" + std::to_string(std::min(u, w)) + ", " + std::to_string(std::max(u, w)) + ")";
    auto face_of = [&](size_t k) { return std::to_string(tri.source_polygon[keys[k].second / 3]); };
    c.vertices_uf.unite(u, w);
    if (j - i == 1) {
      if (c.boundary++ == 0) first_boundary = name + " of face " + face_of(i);
      on_boundary[u] = on_boundary[w] = 1;
      boundary_uf.unite(u, w);
    } else if (j - i > 2) {
      if (c.nonmanifold++ == 0) {
        first_nonmanifold = name + ", shared by faces ";
        for (size_t k = i; k < j; ++k) first_nonmanifold += (k > i ? ", " : "") + face_of(k);
      }
    } else {
      const int h1 = keys[i + 1].second;
      if (tri.tris[h1 / 3][h1 % 3] == u) {
        if (c.misoriented++ == 0)
          first_misoriented = "faces " + face_of(i) + " and " + face_of(i + 1) + " across edge " + name;
      }
    }
    i = j;
  }
  info.num_edges = num_edges;
  if (c.nonmanifold)
    problems.push_back(plural(c.nonmanifold, "non-manifold edge") + " (more than two faces), first: edge " +
                       first_nonmanifold);
  if (c.boundary) {
    int loops = 0;
    for (int v = 0; v < nv; ++v)
      if (on_boundary[v] && boundary_uf.find(v) == v) ++loops;
    info.num_boundary_loops = loops;
    if (!options.allow_boundary)  // open surfaces: mesh/open_surface.h
      problems.push_back("the surface is open: " + plural(c.boundary, "boundary edge") + " in " +
                       plural(loops, "boundary loop") + ", first: edge " + first_boundary +
                       "; this step needs a closed surface (open surfaces are mapped by `surfmap map` "
                       "and surfmap.surface_map; close the holes for the others)");
  }
  if (c.misoriented)
    problems.push_back(plural(c.misoriented, "edge") + " with inconsistently oriented faces, first: " +
                       first_misoriented);
  return c;
}

// Step 5: components (faces sharing a vertex belong together, so two
// surfaces touching at a vertex are one component with a non-manifold
// vertex) and loose vertices. Returns which vertices some face uses.
std::vector<char> check_components(const Triangulation& tri, UnionFind& vertices_uf, MeshInfo& info) {
  const int nv = info.num_vertices;
  std::vector<char> used(nv, 0);
  for (const auto& f : tri.tris) used[f[0]] = used[f[1]] = used[f[2]] = 1;
  int comps = 0;
  for (int v = 0; v < nv; ++v)
    if (used[v] && vertices_uf.find(v) == v) ++comps;
  info.num_components = comps;
  if (comps > 1)
    info.problems.push_back("the mesh has " + std::to_string(comps) +
                            " separate components; map one connected surface at a time");
  const auto unused = std::find(used.begin(), used.end(), 0);
  if (unused != used.end())
    info.problems.push_back("vertex " + std::to_string(unused - used.begin()) +
                            " is not used by any face (loose vertex)");
  return used;
}

// Step 6, closed manifold-edged surfaces: non-manifold vertices (with
// manifold edges, a vertex's faces must form one fan: Connectivity checks),
// genus, mollification and orientation (signed volume).
void check_closed_surface(const PolygonSoup& soup, const IntakeOptions& options, const std::vector<char>& used,
                          Analysis& a) {
  MeshInfo& info = a.info;
  auto& problems = info.problems;
  const int nv = info.num_vertices;
  const int nt = static_cast<int>(a.tri.tris.size());
  RowMatrixX3i F(nt, 3);
  for (int t = 0; t < nt; ++t) F.row(t) << a.tri.tris[t][0], a.tri.tris[t][1], a.tri.tris[t][2];
  if (std::find(used.begin(), used.end(), 0) != used.end()) return;
  std::unique_ptr<Connectivity> conn;
  try {
    conn = std::make_unique<Connectivity>(F, nv);
    info.euler_characteristic = conn->euler_characteristic();
  } catch (const InputError& e) {
    problems.push_back(e.what());
    return;
  }
  // Triangulated counts: the Euler characteristic is the same for polygons.
  if (info.num_components == 1) {
    info.genus = (2 - info.euler_characteristic) / 2;
    if (info.euler_characteristic % 2 != 0 || info.euler_characteristic > 2)
      problems.push_back("Euler characteristic " + std::to_string(info.euler_characteristic) +
                         " is impossible for a closed orientable surface");
  }

  mollify_note(soup.V, *conn, options, info);

  // Orientation: signed volume of the closed surface.
  double vol = 0.0;
  for (const auto& f : a.tri.tris)
    vol += soup.V.row(f[0]).dot(Eigen::Vector3d(soup.V.row(f[1])).cross(Eigen::Vector3d(soup.V.row(f[2])))) / 6.0;
  info.signed_volume = vol;
  if (vol < 0 && options.orient_outward)
    info.notes.push_back("faces were oriented inward (signed volume " + std::to_string(vol) +
                         "); all faces flipped to orient the surface outward");
  a.usable_topology = true;
  info.valid = problems.empty();
}

// The checks in order (steps 1-6 above); each returns early where later
// ones could not be trusted.
Analysis analyse(const PolygonSoup& soup, const IntakeOptions& options) {
  Analysis a;
  MeshInfo& info = a.info;
  const int nv = static_cast<int>(soup.V.rows());
  info.num_vertices = nv;
  auto& problems = info.problems;

  if (nv == 0 || soup.polygons.empty()) {
    problems.push_back("the mesh is empty (" + plural(nv, "vertex") + ", " +
                       plural(soup.polygons.size(), "face") + ")");
    return a;
  }
  if (!check_coordinates(soup, problems)) return a;
  const bool indices_ok = check_face_indices(soup, nv, problems);
  info.num_faces = static_cast<int>(soup.polygons.size());
  if (!indices_ok) return a;
  a.tri = fan_triangulate(soup);
  if (!check_extent(soup, a.tri, options, info)) return a;

  EdgeCheck edges = check_edges(a.tri, options, info);
  const std::vector<char> used = check_components(a.tri, edges.vertices_uf, info);
  info.euler_characteristic = info.num_vertices - info.num_edges + info.num_faces;

  if (edges.nonmanifold || (edges.boundary && !options.allow_boundary) || edges.misoriented) return a;
  if (edges.boundary) {  // open surface accepted (allow_boundary): mesh/open_surface.h checks the rest
    info.genus = (2 - info.euler_characteristic - info.num_boundary_loops) / 2;
    a.usable_topology = info.num_components == 1;
    info.valid = problems.empty();
    return a;
  }
  check_closed_surface(soup, options, used, a);
  return a;
}

}  // namespace

MeshInfo inspect(const PolygonSoup& soup, const IntakeOptions& options) {
  return analyse(soup, options).info;
}

IntakeResult intake(const PolygonSoup& soup, const IntakeOptions& options) {
  Analysis a = analyse(soup, options);
  if (!a.info.valid) {
    std::string msg = a.info.problems.empty() ? "invalid mesh" : a.info.problems.front();
    if (a.info.problems.size() > 1)
      msg += " (and " + plural(a.info.problems.size() - 1, "more problem") + ")";
    throw InputError(msg);
  }
  IntakeResult r;
  r.info = std::move(a.info);
  r.mesh.V = soup.V;
  const int nt = static_cast<int>(a.tri.tris.size());
  r.mesh.F.resize(nt, 3);
  r.flipped = options.orient_outward && r.info.signed_volume < 0;
  for (int t = 0; t < nt; ++t) {
    const auto& f = a.tri.tris[t];
    if (r.flipped)
      r.mesh.F.row(t) << f[0], f[2], f[1];
    else
      r.mesh.F.row(t) << f[0], f[1], f[2];
  }
  r.source_polygon = std::move(a.tri.source_polygon);
  return r;
}

IntakeResult intake(const RowMatrixX3d& V, const RowMatrixX3i& F, const IntakeOptions& options) {
  PolygonSoup soup;
  soup.V = V;
  soup.polygons.resize(F.rows());
  for (int f = 0; f < F.rows(); ++f) soup.polygons[f] = {F(f, 0), F(f, 1), F(f, 2)};
  return intake(soup, options);
}

IntakeResult load_mesh(const std::string& path, const IntakeOptions& options) {
  const PolygonSoup soup = read_polygon_soup(path);
  try {
    return intake(soup, options);
  } catch (const InputError& e) {
    throw InputError("'" + path + "': " + e.what());
  }
}

void check_same_genus(const MeshInfo& source, const MeshInfo& target) {
  if (source.genus != target.genus)
    throw InputError("the source has genus " + std::to_string(source.genus) + " but the target has genus " +
                     std::to_string(target.genus) + "; both surfaces must have the same genus");
}

}  // namespace surfmap
