#include "surfmap/map/cut_graph_initial_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <string>
#include <unordered_map>

#include <Eigen/Geometry>

#include "../seconds_since.h"
#include "disk_flattening.h"
#include "surfmap/error.h"
#include "surfmap/topology/cut_mesh.h"
#include "surfmap/topology/system_of_loops.h"

namespace surfmap {

using hyperbolic::Mobius;
using Complex = std::complex<double>;

namespace {

using detail::seconds_since;

// One chain of the cut graph, seen from one of its banks: from branch
// vertex a (corner copy with deck word c_a) to branch vertex b (c_b); its
// term is w d(p_a, M p_b)² with M = c_a^-1 c_b.
struct Chain {
  int a, b;
  Mobius M, Mi;
  double w;
};

// The minimiser of Σ_chains w d(p_a, M p_b)² by Gauss-Seidel: each branch point moved
// to the weighted Karcher-mean step of its chains' far ends, halved until
// the energy does not increase (chains from a branch vertex to itself make
// the one-point problem non-quadratic). A convex function: the sweeps
// converge to the unique minimiser.
int minimise_network(const std::vector<Chain>& chains, std::vector<Complex>& p, int sweeps, double tolerance) {
  const int nb = static_cast<int>(p.size());
  std::vector<std::vector<int>> at(nb);
  for (int c = 0; c < static_cast<int>(chains.size()); ++c) {
    at[chains[c].a].push_back(c);
    if (chains[c].b != chains[c].a) at[chains[c].b].push_back(c);
  }
  auto local_energy = [&](int v) {
    double e = 0;
    for (int c : at[v]) {
      const double d = hyperbolic::distance(p[chains[c].a], chains[c].M.apply(p[chains[c].b]));
      e += chains[c].w * d * d;
    }
    return e;
  };
  int sweep = 0;
  for (; sweep < sweeps; ++sweep) {
    double largest = 0;
    for (int v = 0; v < nb; ++v) {
      Complex step(0.0);
      double wsum = 0;
      for (int c : at[v]) {
        const Chain& ch = chains[c];
        if (ch.a == v) step += ch.w * hyperbolic::log_map(p[v], ch.M.apply(p[ch.b])), wsum += ch.w;
        if (ch.b == v) step += ch.w * hyperbolic::log_map(p[v], ch.Mi.apply(p[ch.a])), wsum += ch.w;
      }
      if (wsum <= 0) continue;
      step /= wsum;
      const double e0 = local_energy(v);
      const Complex p0 = p[v];
      for (int back = 0; back < 30; ++back, step *= 0.5) {
        p[v] = hyperbolic::exp_map(p0, step);
        if (local_energy(v) <= e0) break;
        p[v] = p0;
      }
      const double moved = hyperbolic::distance(p0, p[v]);
      if (!std::isfinite(moved)) return sweep;  // no digits left: the caller gives up
      largest = std::max(largest, moved);
    }
    if (largest < tolerance) break;
  }
  return sweep;
}

// Cut degree of every vertex (the number of cut edges at it).
std::vector<int> cut_degrees(const Connectivity& sc, const std::vector<char>& cut, int nv) {
  std::vector<int> degree(nv, 0);
  for (int e = 0; e < sc.num_edges(); ++e)
    if (cut[e]) ++degree[sc.edge_vertex(e, 0)], ++degree[sc.edge_vertex(e, 1)];
  return degree;
}

using detail::GiveUp;

// Step 1. The cut graph: the unrefined loops' edges (options.loops, or the
// source's own system of loops), dangling edges pruned. One flag per edge.
std::vector<char> cut_graph(const TriMesh& source, const Connectivity& sc, const CutGraphInitialMapOptions& options) {
  const int nv = source.num_vertices();
  SystemOfLoops own;
  const std::vector<std::vector<int>>* loops = options.loops;
  if (!loops) {
    SystemOfLoopsOptions lo;
    lo.base_vertex = options.base_vertex;
    lo.refine = false;
    try {
      own = system_of_loops(source, lo);
    } catch (const Error& e) {
      throw GiveUp{std::string("loops: ") + e.what()};
    }
    loops = &own.loops;
  }
  std::vector<char> cut(sc.num_edges(), 0);
  for (const auto& loop : *loops)
    for (size_t q = 0; q + 1 < loop.size(); ++q) {
      const int h = sc.find_halfedge(loop[q], loop[q + 1]);
      if (h < 0) throw GiveUp{"a loop is not an edge path of the source"};
      cut[sc.edge(h)] = 1;
    }
  std::vector<int> degree = cut_degrees(sc, cut, nv);
  std::vector<int> leaves;
  for (int v = 0; v < nv; ++v)
    if (degree[v] == 1) leaves.push_back(v);
  while (!leaves.empty()) {
    const int v = leaves.back();
    leaves.pop_back();
    if (degree[v] != 1) continue;
    for (int h : sc.outgoing(v))
      if (cut[sc.edge(h)]) {
        cut[sc.edge(h)] = 0;
        --degree[v];
        if (--degree[sc.head(h)] == 1) leaves.push_back(sc.head(h));
        break;
      }
  }
  return cut;
}

// The source cut into a disk along the cut graph: its boundary loop `bl`
// rotated to start at a corner (a copy of a branch vertex, cut degree >= 3)
// and closed (bl[nb] = bl[0]), the boundary positions of the ns corners
// (corner_pos[ns] = nb), each side's partner side, and the cut degrees.
struct CutDisk {
  CutMesh cm;
  std::vector<int> bl, corner_pos, partner, degree;
  int nd = 0, ns = 0;
};

// A chord: an interior edge (not cut) joining two copies on one side, at
// offsets from..to along side `side`.
struct Chord {
  int side, from, to, edge;
};

// The chords of the disk `d` (sides read, bl not yet closed); side_at and
// edge_at: each boundary position's side and source edge.
std::vector<Chord> disk_chords(const Connectivity& sc, const std::vector<char>& cut, const CutDisk& d,
                               const std::vector<int>& side_at) {
  const int nb = static_cast<int>(d.bl.size()), ns = d.ns, nf = sc.num_faces();
  const std::vector<int>& corner_pos = d.corner_pos;
  // Offsets along side s of boundary position i (-1: not on side s).
  std::vector<int> pos_of(d.nd, -1);
  for (int i = 0; i < nb; ++i) pos_of[d.bl[i]] = i;
  auto offset_on = [&](int i, int s) {
    if (i >= corner_pos[s] && i <= corner_pos[s + 1]) return i - corner_pos[s];
    if (i == 0 && s == ns - 1) return nb - corner_pos[s];
    return -1;
  };
  std::vector<Chord> chords;
  for (int f = 0; f < nf; ++f)
    for (int q = 0; q < 3; ++q) {
      const int h = 3 * f + q, e = sc.edge(h);
      if (cut[e] || sc.edge_halfedge(e) != h) continue;  // once per interior edge
      const int i = pos_of[d.cm.mesh.F(f, q)], j = pos_of[d.cm.mesh.F(f, (q + 1) % 3)];
      if (i < 0 || j < 0) continue;
      for (int s : {side_at[i], (side_at[i] + ns - 1) % ns}) {
        const int oi = offset_on(i, s), oj = offset_on(j, s);
        if (oi >= 0 && oj >= 0) {
          chords.push_back({s, std::min(oi, oj), std::max(oi, oj), e});
          break;
        }
      }
    }
  return chords;
}

// Steps 2.-4. Cut, read the sides, reroute chords (the longest first, one
// per chain, i.e. a side and its partner, per round) until there is none.
// `cut` is updated by the reroutings (counted in *rerouted).
CutDisk cut_into_disk(const TriMesh& source, const Connectivity& sc, std::vector<char>& cut, int max_reroutes,
                      int* rerouted) {
  CutDisk d;
  for (int reroute = 0;; ++reroute) {
    d.degree = cut_degrees(sc, cut, source.num_vertices());
    d.cm = cut_mesh_along_edges(source, sc, cut);
    if (d.cm.euler_characteristic != 1 || d.cm.boundary_loops.size() != 1)
      throw GiveUp{"the cut graph does not cut the source into a disk"};
    d.nd = static_cast<int>(d.cm.original_vertex.size());
    d.bl = d.cm.boundary_loops[0];
    std::vector<int>& bl = d.bl;
    std::vector<int>& corner_pos = d.corner_pos;
    const int nb = static_cast<int>(bl.size());
    corner_pos.clear();
    for (int i = 0; i < nb; ++i)
      if (d.degree[d.cm.original_vertex[bl[i]]] >= 3) corner_pos.push_back(i);
    const int ns = d.ns = static_cast<int>(corner_pos.size());
    if (ns < 3) throw GiveUp{"the cut graph has fewer than 3 corners"};
    std::rotate(bl.begin(), bl.begin() + corner_pos[0], bl.end());
    for (int i = ns - 1; i >= 0; --i) corner_pos[i] -= corner_pos[0];
    corner_pos.push_back(nb);
    // Every cut edge occurs twice along the boundary; a side's partner is
    // the side holding the other occurrence of its first edge, reversed.
    std::vector<int> side_at(nb), edge_at(nb);
    std::unordered_map<int, std::vector<int>> positions;
    for (int s = 0; s < ns; ++s)
      for (int i = corner_pos[s]; i < corner_pos[s + 1]; ++i) {
        side_at[i] = s;
        const int h = sc.find_halfedge(d.cm.original_vertex[bl[i]], d.cm.original_vertex[bl[(i + 1) % nb]]);
        if (h < 0 || !cut[sc.edge(h)]) throw GiveUp{"a boundary edge of the cut disk is not a cut edge"};
        edge_at[i] = sc.edge(h);
        positions[edge_at[i]].push_back(i);
      }
    d.partner.assign(ns, -1);
    for (int s = 0; s < ns; ++s) {
      const auto& ps = positions[edge_at[corner_pos[s]]];
      if (ps.size() != 2) throw GiveUp{"a cut edge is not on the boundary twice"};
      const int other = ps[0] == corner_pos[s] ? ps[1] : ps[0];
      const int t = side_at[other];
      // Reversed: the first edge of s is the last of t, and the lengths agree.
      if (other != corner_pos[t + 1] - 1 || corner_pos[t + 1] - corner_pos[t] != corner_pos[s + 1] - corner_pos[s])
        throw GiveUp{"the sides of the cut disk are not paired"};
      d.partner[s] = t;
    }
    std::vector<Chord> chords = disk_chords(sc, cut, d, side_at);
    if (chords.empty()) break;
    if (reroute >= max_reroutes)
      throw GiveUp{"chords of the cut disk remain after " + std::to_string(reroute) + " reroutings"};
    std::sort(chords.begin(), chords.end(), [](const Chord& x, const Chord& y) { return x.to - x.from > y.to - y.from; });
    std::vector<char> used(ns, 0);
    for (const Chord& c : chords) {
      if (used[c.side] || used[d.partner[c.side]]) continue;
      used[c.side] = used[d.partner[c.side]] = 1;
      for (int o = c.from; o < c.to; ++o) cut[edge_at[(corner_pos[c.side] + o) % nb]] = 0;
      cut[c.edge] = 1;
      ++*rerouted;
    }
  }
  d.bl.push_back(d.bl[0]);
  return d;
}

// Step 3. The corner points: the harmonic map of the metric cut graph.
// Dynamic charts (the algebraic form of docs/method.md §2.6): branch vertex
// b's point is H_b(q_b) with q_b kept in the target's domain by
// options.reduce_point, so corner d of b sits at (c_d H_b)(q_b). In a
// twisted class the development's words are long (chain elements displacing
// the origin by 35 on the 50k genus-2 bench pair) and the chains' far ends
// lie where the matrices have no digits left; in these charts every chain
// element is short. Fills p (a point per branch vertex) and H; counts the
// sweeps in out.network_sweeps.
struct BranchNetwork {
  std::vector<Complex> p;
  std::vector<Word> H;
};

BranchNetwork branch_points(const CutDisk& d, const std::vector<Word>& c, const std::vector<int>& branch_index,
                            const std::vector<double>& side_length_3d, const DeckGroup& group,
                            const CutGraphInitialMapOptions& options, CutGraphInitialMapResult& out) {
  const std::vector<int>& bl = d.bl;
  const std::vector<int>& corner_pos = d.corner_pos;
  BranchNetwork net;
  std::vector<Word>& H = net.H;
  H.resize(out.branch_vertices);
  auto corner_word = [&](int dc) { return group.reduce(concat(c[dc], H[branch_index[d.cm.original_vertex[dc]]])); };
  std::vector<Chain> chains;
  std::vector<int> chain_side;
  for (int s = 0; s < d.ns; ++s) {
    if (d.partner[s] < s) continue;
    const int da = bl[corner_pos[s]], db = bl[corner_pos[s + 1]];
    Chain ch;
    ch.a = branch_index[d.cm.original_vertex[da]];
    ch.b = branch_index[d.cm.original_vertex[db]];
    if (ch.a < 0 || ch.b < 0) throw GiveUp{"a corner of the cut disk is not a branch vertex"};
    ch.w = 1.0 / std::max(side_length_3d[s], 1e-300);
    chains.push_back(ch);
    chain_side.push_back(s);
  }
  auto chain_elements = [&] {
    for (size_t q = 0; q < chains.size(); ++q) {
      const int s = chain_side[q];
      chains[q].M = group.evaluate_side_word(
          group.reduce(concat(inverse(corner_word(bl[corner_pos[s]])), corner_word(bl[corner_pos[s + 1]]))));
      chains[q].Mi = chains[q].M.inverse();
    }
  };
  chain_elements();
  std::vector<Complex>& p = net.p;
  p.assign(out.branch_vertices, Complex(0.0));
  for (int round = 0; round < 100; ++round) {
    const int budget = options.network_sweeps - out.network_sweeps;
    if (budget <= 0) break;
    const int used = minimise_network(chains, p, std::min(budget, 25), options.network_tolerance);
    out.network_sweeps += used;
    if (!std::all_of(p.begin(), p.end(), [](Complex q) { return std::isfinite(q.real()) && std::isfinite(q.imag()); }))
      break;
    bool moved = false;
    if (options.reduce_point)
      for (int v = 0; v < out.branch_vertices; ++v) {
        if (!(std::isfinite(p[v].real()) && std::isfinite(p[v].imag()) && std::abs(p[v]) < 1)) break;
        const Word w = options.reduce_point(p[v]);  // p_new = w(p_old)
        if (w.empty()) continue;
        H[v] = group.reduce(concat(H[v], inverse(w)));
        moved = true;
      }
    if (moved) chain_elements();
    else if (used < std::min(budget, 25)) break;  // converged in these charts
  }
  for (const Complex& q : p)
    if (!(std::isfinite(q.real()) && std::isfinite(q.imag()) && std::abs(q) < 1))
      throw GiveUp{"the cut graph's harmonic map has no digits left (a branch point at the disk's boundary)"};
  return net;
}

// The polygon of the corner points: the whole development (c) moved by one
// deck element so that corner 0 lies in the target's domain, the corners in
// the chart centred near the centre of their smallest enclosing disk
// (qc: Poincaré, kq: Klein), perimeter, turns and convexity in `out`.
// GiveUp when a side has no length or the polygon is not strictly convex.
struct CornerPolygon {
  Mobius chart;
  std::vector<Complex> qc, kq;
};

CornerPolygon corner_polygon(const CutDisk& d, std::vector<Word>& c, const std::vector<int>& branch_index,
                             const BranchNetwork& net, const DeckGroup& group,
                             const CutGraphInitialMapOptions& options, CutGraphInitialMapResult& out) {
  const std::vector<int>& bl = d.bl;
  const std::vector<int>& corner_pos = d.corner_pos;
  const int ns = d.ns;
  const std::vector<Complex>& p = net.p;
  auto corner_word = [&](int dc) {
    return group.reduce(concat(c[dc], net.H[branch_index[d.cm.original_vertex[dc]]]));
  };
  // The whole development moved by one deck element g so that corner 0
  // lies in the target's domain: the polygon then sits near the origin,
  // where the final points keep their digits.
  if (options.reduce_point) {
    const int d0 = bl[corner_pos[0]];
    Complex q0 = group.evaluate_side_word(corner_word(d0)).apply(p[branch_index[d.cm.original_vertex[d0]]]);
    if (std::isfinite(q0.real()) && std::isfinite(q0.imag()) && std::abs(q0) < 1) {
      const Word g = options.reduce_point(q0);
      if (!g.empty())
        for (Word& w : c) w = group.reduce(concat(g, w));
    }
  }
  std::vector<Mobius> C(ns);
  std::vector<Complex> Q(ns);
  for (int s = 0; s < ns; ++s) {
    const int dc = bl[corner_pos[s]];
    C[s] = group.evaluate_side_word(corner_word(dc));
    Q[s] = C[s].apply(p[branch_index[d.cm.original_vertex[dc]]]);
  }
  out.corners = Q;
  for (int s = 0; s < ns; ++s) {
    const double len = hyperbolic::distance(Q[s], Q[(s + 1) % ns]);
    out.perimeter += len;
    if (!(len > 1e-9))
      throw GiveUp{"side " + std::to_string(s) +
                   " of the polygon has no length (a chain collapsed, or the polygon is too large for double precision)"};
  }
  // The chart centred near the centre of the corners' smallest enclosing
  // disk (steps towards the farthest corner, each shorter): long, thin
  // polygons (many sides, genus >= 5) keep every corner as far from the
  // Klein boundary as they can, which the Klein centroid does not.
  Complex centre = Q[0];
  for (int it = 1; it <= 400; ++it) {
    int far = 0;
    double dfar = -1;
    for (int s = 0; s < ns; ++s)
      if (const double dist = hyperbolic::distance(centre, Q[s]); dist > dfar) dfar = dist, far = s;
    centre = hyperbolic::geodesic_point(centre, Q[far], 1.0 / (it + 1));
  }
  CornerPolygon poly;
  poly.chart = Mobius::centring(centre);
  poly.qc.resize(ns), poly.kq.resize(ns);
  std::vector<Complex>&qc = poly.qc, &kq = poly.kq;
  for (int s = 0; s < ns; ++s) {
    // Through the corner's deck element, where the digits are.
    const int dc = bl[corner_pos[s]];
    qc[s] = (poly.chart * C[s]).normalized().apply(p[branch_index[d.cm.original_vertex[dc]]]);
    kq[s] = hyperbolic::poincare_to_klein(qc[s]);
    // |k| = tanh d: 1 - 1e-12 is 14 units from the centre, where a triangle
    // of size 0.05 still spans ~1e-13 in k (the flattening's result is
    // checked for flips from reduced words all the same).
    if (!(std::isfinite(kq[s].real()) && std::isfinite(kq[s].imag()) && std::abs(kq[s]) < 1 - 1e-12))
      throw GiveUp{"the polygon is too large for double precision (corner " + std::to_string(s) + ")"};
  }
  const detail::KleinTurns turns = detail::klein_turns(kq);
  const double total_turn = turns.total;
  out.min_turn = turns.min, out.max_turn = turns.max;
  out.convex = out.min_turn > options.min_turn && std::abs(total_turn - 2 * M_PI) < 1e-6;
  if (!out.convex)
    throw GiveUp{std::abs(total_turn - 2 * M_PI) < 1e-6
                     ? "the polygon is simple but not strictly convex (smallest turn " + std::to_string(out.min_turn) + ")"
                     : "the polygon is not simple (total turn " + std::to_string(total_turn / (2 * M_PI)) + " x 2pi)"};
  return poly;
}

// Step 5. Klein-model points of every disk copy: boundary copies at the
// fraction of their chain's 3D length (measured from the side's start; the
// partner runs the other way, so both copies of a vertex get the same point
// of the chain), interior ones by the mean-value (Floater) flattening.
std::vector<Complex> flatten_cut_disk(const Connectivity& sc, const std::vector<char>& cut, const CutDisk& d,
                                      const CornerPolygon& poly, const std::vector<double>& side_length_3d,
                                      int hyperboloid_rounds) {
  const std::vector<int>& bl = d.bl;
  const std::vector<int>& corner_pos = d.corner_pos;
  const TriMesh& disk = d.cm.mesh;
  const int ns = d.ns, nf = sc.num_faces();
  std::vector<Complex> k(d.nd, Complex(0.0));
  std::vector<char> on_boundary(d.nd, 0);
  for (int s = 0; s < ns; ++s) {
    double along = 0;
    for (int i = corner_pos[s]; i < corner_pos[s + 1]; ++i) {
      k[bl[i]] = hyperbolic::poincare_to_klein(hyperbolic::geodesic_point(
          poly.qc[s], poly.qc[(s + 1) % ns], along / std::max(side_length_3d[s], 1e-300)));
      on_boundary[bl[i]] = 1;
      along += (disk.V.row(bl[i + 1]) - disk.V.row(bl[i])).norm();
    }
    k[bl[corner_pos[s]]] = poly.kq[s];
  }
  // Mean-value weights (disk_flattening.h) per interior edge of the disk,
  // i.e. per source edge not cut, between the copies its faces see.
  std::vector<detail::FlatteningEdge> graph(sc.num_edges(), detail::FlatteningEdge{-1, -1, 0.0});
  auto half_tan = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return a.cross(b).norm() / std::max(a.norm() * b.norm() + a.dot(b), 1e-300);
  };
  for (int f = 0; f < nf; ++f)
    for (int q = 0; q < 3; ++q) {
      const int e = sc.edge(3 * f + q);
      if (cut[e]) continue;
      const int i = disk.F(f, q), j = disk.F(f, (q + 1) % 3), o = disk.F(f, (q + 2) % 3);
      const Eigen::Vector3d pi = disk.V.row(i), pj = disk.V.row(j), po = disk.V.row(o);
      graph[e].a = i, graph[e].b = j;
      graph[e].w += (half_tan(pj - pi, po - pi) + half_tan(pi - pj, po - pj)) / std::max((pj - pi).norm(), 1e-300);
    }
  graph.erase(std::remove_if(graph.begin(), graph.end(), [](const detail::FlatteningEdge& g) { return g.a < 0; }),
              graph.end());
  std::string why;
  if (!detail::flatten_in_klein(graph, on_boundary, hyperboloid_rounds, k, &why)) throw GiveUp{why};
  return k;
}

// The steps of the header's comment in order; a step that cannot build the
// map throws GiveUp, turned here into applied = false with its reason.
void build_cut_graph_map(const TriMesh& source, const Connectivity& sc, const std::vector<Word>& halfedge_word,
                         const DeckGroup& group, const CutGraphInitialMapOptions& options,
                         CutGraphInitialMapResult& out) {
  const int nv = source.num_vertices(), nf = source.num_faces();
  std::vector<char> cut = cut_graph(source, sc, options);
  const CutDisk d = cut_into_disk(source, sc, cut, options.max_reroutes, &out.chords_rerouted);
  std::vector<int> branch_index(nv, -1);
  for (int v = 0; v < nv; ++v)
    if (d.degree[v] >= 3) branch_index[v] = out.branch_vertices++;
  out.chains = d.ns / 2;

  // Development: the frame element b_f of every face (the frame of its
  // corner 0), and per disk copy d the deck word c_d = b_f phi(f, k).
  auto phi = [&](int f, int k) -> Word {
    return k == 0 ? Word{} : k == 1 ? halfedge_word[3 * f] : inverse(halfedge_word[3 * f + 2]);
  };
  detail::DiskDevelopment dev = detail::develop_disk(d.cm.mesh, sc, cut, group, phi);
  std::vector<Word>& c = dev.c;  // re-centred by corner_polygon
  if (dev.faces_reached != nf) throw GiveUp{"the cut disk is not connected"};
  if (dev.mismatch > 1e-6)
    throw GiveUp{"the class's deck elements are not flat (" + std::to_string(dev.mismatch) + ")"};

  std::vector<double> side_length_3d(d.ns, 0);
  for (int s = 0; s < d.ns; ++s)
    for (int i = d.corner_pos[s]; i < d.corner_pos[s + 1]; ++i)
      side_length_3d[s] += (d.cm.mesh.V.row(d.bl[i + 1]) - d.cm.mesh.V.row(d.bl[i])).norm();
  const BranchNetwork net = branch_points(d, c, branch_index, side_length_3d, group, options, out);
  const CornerPolygon poly = corner_polygon(d, c, branch_index, net, group, options, out);
  const std::vector<Complex> k = flatten_cut_disk(sc, cut, d, poly, side_length_3d, options.hyperboloid_rounds);

  // The input vertices: one copy's point (global frame) and its deck word,
  // then moved into the target's domain.
  const std::string unread = detail::read_disk_vertices(d.cm.original_vertex, nv, k, c, poly.chart, options.reduce_point,
                                                        group, "vertex", "the cut disk", out.z, out.vertex_deck,
                                                        out.vertex_deck_word);
  if (!unread.empty()) throw GiveUp{unread};
}

}  // namespace

CutGraphInitialMapResult cut_graph_initial_map(const TriMesh& source, const Connectivity& sc,
                                               const std::vector<Word>& halfedge_word, const DeckGroup& group,
                                               const CutGraphInitialMapOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  CutGraphInitialMapResult out;
  const int nv = source.num_vertices(), nf = source.num_faces();
  if (static_cast<int>(halfedge_word.size()) != 3 * nf || sc.num_vertices() != nv || sc.num_faces() != nf)
    throw InputError("cut_graph_initial_map: one side word per source halfedge (3 x #F) needed");
  detail::build_or_give_up(out, [&](auto& o) { build_cut_graph_map(source, sc, halfedge_word, group, options, o); });
  out.time_s = seconds_since(t0);
  return out;
}

}  // namespace surfmap
