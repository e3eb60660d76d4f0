#include "surfmap/map/cut_graph_initial_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <string>
#include <unordered_map>

#include <Eigen/Geometry>

#include "disk_flattening.h"
#include "surfmap/error.h"
#include "surfmap/topology/cut_mesh.h"
#include "surfmap/topology/system_of_loops.h"

namespace surfmap {

using hyperbolic::Mobius;
using Complex = std::complex<double>;

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

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

}  // namespace

CutGraphInitialMapResult cut_graph_initial_map(const TriMesh& source, const Connectivity& sc,
                                               const std::vector<Word>& halfedge_word, const DeckGroup& group,
                                               const CutGraphInitialMapOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  CutGraphInitialMapResult out;
  const int nv = source.num_vertices(), nf = source.num_faces();
  if (static_cast<int>(halfedge_word.size()) != 3 * nf || sc.num_vertices() != nv || sc.num_faces() != nf)
    throw InputError("cut_graph_initial_map: one side word per source halfedge (3 x #F) needed");
  auto give_up = [&](const std::string& why) {
    out.applied = false;
    out.reason = why;
    out.z.clear(), out.vertex_deck.clear(), out.vertex_deck_word.clear();
    out.time_s = seconds_since(t0);
    return out;
  };

  // 1. The cut graph: the unrefined loops' edges, dangling edges pruned.
  SystemOfLoops own;
  const std::vector<std::vector<int>>* loops = options.loops;
  if (!loops) {
    SystemOfLoopsOptions lo;
    lo.base_vertex = options.base_vertex;
    lo.refine = false;
    try {
      own = system_of_loops(source, lo);
    } catch (const Error& e) {
      return give_up(std::string("loops: ") + e.what());
    }
    loops = &own.loops;
  }
  std::vector<char> cut(sc.num_edges(), 0);
  for (const auto& loop : *loops)
    for (size_t q = 0; q + 1 < loop.size(); ++q) {
      const int h = sc.find_halfedge(loop[q], loop[q + 1]);
      if (h < 0) return give_up("a loop is not an edge path of the source");
      cut[sc.edge(h)] = 1;
    }
  std::vector<int> degree(nv, 0);
  auto count_degrees = [&] {
    std::fill(degree.begin(), degree.end(), 0);
    for (int e = 0; e < sc.num_edges(); ++e)
      if (cut[e]) ++degree[sc.edge_vertex(e, 0)], ++degree[sc.edge_vertex(e, 1)];
  };
  count_degrees();
  {
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
  }

  // 2.-4. Cut, read the sides, reroute chords, until there is none.
  CutMesh cm;
  std::vector<int> bl, corner_pos, partner;
  int nd = 0, ns = 0;
  for (int reroute = 0;; ++reroute) {
    count_degrees();
    cm = cut_mesh_along_edges(source, sc, cut);
    if (cm.euler_characteristic != 1 || cm.boundary_loops.size() != 1) return give_up("the cut graph does not cut the source into a disk");
    nd = static_cast<int>(cm.original_vertex.size());
    bl = cm.boundary_loops[0];
    const int nb = static_cast<int>(bl.size());
    corner_pos.clear();
    for (int i = 0; i < nb; ++i)
      if (degree[cm.original_vertex[bl[i]]] >= 3) corner_pos.push_back(i);
    ns = static_cast<int>(corner_pos.size());
    if (ns < 3) return give_up("the cut graph has fewer than 3 corners");
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
        const int h = sc.find_halfedge(cm.original_vertex[bl[i]], cm.original_vertex[bl[(i + 1) % nb]]);
        if (h < 0 || !cut[sc.edge(h)]) return give_up("a boundary edge of the cut disk is not a cut edge");
        edge_at[i] = sc.edge(h);
        positions[edge_at[i]].push_back(i);
      }
    partner.assign(ns, -1);
    for (int s = 0; s < ns; ++s) {
      const auto& ps = positions[edge_at[corner_pos[s]]];
      if (ps.size() != 2) return give_up("a cut edge is not on the boundary twice");
      const int other = ps[0] == corner_pos[s] ? ps[1] : ps[0];
      const int t = side_at[other];
      // Reversed: the first edge of s is the last of t, and the lengths agree.
      if (other != corner_pos[t + 1] - 1 || corner_pos[t + 1] - corner_pos[t] != corner_pos[s + 1] - corner_pos[s])
        return give_up("the sides of the cut disk are not paired");
      partner[s] = t;
    }
    // Chords: interior edges (not cut) joining two copies on one side.
    // Offsets along side s of boundary position i (-1: not on side s).
    std::vector<int> pos_of(nd, -1);
    for (int i = 0; i < nb; ++i) pos_of[bl[i]] = i;
    auto offset_on = [&](int i, int s) {
      if (i >= corner_pos[s] && i <= corner_pos[s + 1]) return i - corner_pos[s];
      if (i == 0 && s == ns - 1) return nb - corner_pos[s];
      return -1;
    };
    struct Chord {
      int side, from, to, edge;
    };
    std::vector<Chord> chords;
    for (int f = 0; f < nf; ++f)
      for (int q = 0; q < 3; ++q) {
        const int h = 3 * f + q, e = sc.edge(h);
        if (cut[e] || sc.edge_halfedge(e) != h) continue;  // once per interior edge
        const int i = pos_of[cm.mesh.F(f, q)], j = pos_of[cm.mesh.F(f, (q + 1) % 3)];
        if (i < 0 || j < 0) continue;
        for (int s : {side_at[i], (side_at[i] + ns - 1) % ns}) {
          const int oi = offset_on(i, s), oj = offset_on(j, s);
          if (oi >= 0 && oj >= 0) {
            chords.push_back({s, std::min(oi, oj), std::max(oi, oj), e});
            break;
          }
        }
      }
    if (chords.empty()) break;
    if (reroute >= options.max_reroutes) return give_up("chords of the cut disk remain after " + std::to_string(reroute) + " reroutings");
    // The longest chords first, one per chain (a side and its partner) per round.
    std::sort(chords.begin(), chords.end(), [](const Chord& x, const Chord& y) { return x.to - x.from > y.to - y.from; });
    std::vector<char> used(ns, 0);
    for (const Chord& c : chords) {
      if (used[c.side] || used[partner[c.side]]) continue;
      used[c.side] = used[partner[c.side]] = 1;
      for (int o = c.from; o < c.to; ++o) cut[edge_at[(corner_pos[c.side] + o) % nb]] = 0;
      cut[c.edge] = 1;
      ++out.chords_rerouted;
    }
  }
  const int nb = static_cast<int>(bl.size());
  bl.push_back(bl[0]);
  std::vector<int> branch_index(nv, -1);
  for (int v = 0; v < nv; ++v)
    if (degree[v] >= 3) branch_index[v] = out.branch_vertices++;
  out.chains = ns / 2;

  // 2. Development: the frame element b_f of every face (the frame of its
  // corner 0), and per disk copy d the deck word c_d = b_f phi(f, k).
  auto phi = [&](int f, int k) -> Word {
    return k == 0 ? Word{} : k == 1 ? halfedge_word[3 * f] : inverse(halfedge_word[3 * f + 2]);
  };
  detail::DiskDevelopment dev = detail::develop_disk(cm.mesh, sc, cut, group, phi);
  std::vector<Word>& c = dev.c;  // re-centred below
  if (dev.faces_reached != nf) return give_up("the cut disk is not connected");
  if (dev.mismatch > 1e-6) return give_up("the class's deck elements are not flat (" + std::to_string(dev.mismatch) + ")");

  // 3. The corner points: the harmonic map of the metric cut graph.
  std::vector<double> side_length_3d(ns, 0);
  for (int s = 0; s < ns; ++s)
    for (int i = corner_pos[s]; i < corner_pos[s + 1]; ++i)
      side_length_3d[s] += (cm.mesh.V.row(bl[i + 1]) - cm.mesh.V.row(bl[i])).norm();
  // Dynamic charts (the algebraic form of the paper's, §VI-A): branch
  // vertex b's point is H_b(q_b) with q_b kept in the target's domain by
  // options.reduce_point, so corner d of b sits at (c_d H_b)(q_b). In a
  // twisted class the development's words are long (chain elements
  // displacing the origin by 35 on the 50k genus-2 bench pair) and the
  // chains' far ends lie where the matrices have no digits left; in these
  // charts every chain element is short.
  std::vector<Word> H(out.branch_vertices);
  auto corner_word = [&](int d) { return group.reduce(concat(c[d], H[branch_index[cm.original_vertex[d]]])); };
  std::vector<Chain> chains;
  std::vector<int> chain_side;
  for (int s = 0; s < ns; ++s) {
    if (partner[s] < s) continue;
    const int da = bl[corner_pos[s]], db = bl[corner_pos[s + 1]];
    Chain ch;
    ch.a = branch_index[cm.original_vertex[da]];
    ch.b = branch_index[cm.original_vertex[db]];
    if (ch.a < 0 || ch.b < 0) return give_up("a corner of the cut disk is not a branch vertex");
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
  std::vector<Complex> p(out.branch_vertices, Complex(0.0));
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
      return give_up("the cut graph's harmonic map has no digits left (a branch point at the disk's boundary)");
  // The whole development moved by one deck element g so that corner 0
  // lies in the target's domain: the polygon then sits near the origin,
  // where the final points keep their digits.
  if (options.reduce_point) {
    const int d0 = bl[corner_pos[0]];
    Complex q0 = group.evaluate_side_word(corner_word(d0)).apply(p[branch_index[cm.original_vertex[d0]]]);
    if (std::isfinite(q0.real()) && std::isfinite(q0.imag()) && std::abs(q0) < 1) {
      const Word g = options.reduce_point(q0);
      if (!g.empty())
        for (Word& w : c) w = group.reduce(concat(g, w));
    }
  }
  std::vector<Mobius> C(ns);
  std::vector<Complex> Q(ns);
  for (int s = 0; s < ns; ++s) {
    const int d = bl[corner_pos[s]];
    C[s] = group.evaluate_side_word(corner_word(d));
    Q[s] = C[s].apply(p[branch_index[cm.original_vertex[d]]]);
  }
  out.corners = Q;
  for (int s = 0; s < ns; ++s) {
    const double len = hyperbolic::distance(Q[s], Q[(s + 1) % ns]);
    out.perimeter += len;
    if (!(len > 1e-9)) return give_up("side " + std::to_string(s) +
                                          " of the polygon has no length (a chain collapsed, or the polygon is too large for double precision)");
  }
  // The chart centred near the centre of the corners' smallest enclosing
  // disk (Badoiu-Clarkson steps towards the farthest corner): long, thin
  // polygons (many sides, genus >= 5) keep every corner as far from the
  // Klein boundary as they can, which the Klein centroid does not.
  Complex centre = Q[0];
  for (int it = 1; it <= 400; ++it) {
    int far = 0;
    double dfar = -1;
    for (int s = 0; s < ns; ++s)
      if (const double d = hyperbolic::distance(centre, Q[s]); d > dfar) dfar = d, far = s;
    centre = hyperbolic::geodesic_point(centre, Q[far], 1.0 / (it + 1));
  }
  const Mobius chart = Mobius::centring(centre);
  std::vector<Complex> qc(ns), kq(ns);
  for (int s = 0; s < ns; ++s) {
    // Through the corner's deck element, where the digits are.
    const int d = bl[corner_pos[s]];
    qc[s] = (chart * C[s]).normalized().apply(p[branch_index[cm.original_vertex[d]]]);
    kq[s] = hyperbolic::poincare_to_klein(qc[s]);
    // |k| = tanh d: 1 - 1e-12 is 14 units from the centre, where a triangle
    // of size 0.05 still spans ~1e-13 in k (the flattening's result is
    // checked for flips from reduced words all the same).
    if (!(std::isfinite(kq[s].real()) && std::isfinite(kq[s].imag()) && std::abs(kq[s]) < 1 - 1e-12))
      return give_up("the polygon is too large for double precision (corner " + std::to_string(s) + ")");
  }
  double total_turn = 0;
  out.min_turn = 10, out.max_turn = -10;
  for (int s = 0; s < ns; ++s) {
    const Complex e0 = kq[s] - kq[(s + ns - 1) % ns], e1 = kq[(s + 1) % ns] - kq[s];
    const double turn = std::arg(e1 / e0);
    total_turn += turn;
    out.min_turn = std::min(out.min_turn, turn);
    out.max_turn = std::max(out.max_turn, turn);
  }
  out.convex = out.min_turn > options.min_turn && std::abs(total_turn - 2 * M_PI) < 1e-6;
  if (!out.convex)
    return give_up(std::abs(total_turn - 2 * M_PI) < 1e-6
                       ? "the polygon is simple but not strictly convex (smallest turn " + std::to_string(out.min_turn) + ")"
                       : "the polygon is not simple (total turn " + std::to_string(total_turn / (2 * M_PI)) + " x 2pi)");

  // 5. Boundary copies at the fraction of their chain's 3D length (measured
  // from the side's start; the partner runs the other way, so both copies
  // of a vertex get the same point of the chain), interior ones by Floater.
  std::vector<Complex> k(nd, Complex(0.0));
  std::vector<char> on_boundary(nd, 0);
  for (int s = 0; s < ns; ++s) {
    double along = 0;
    for (int i = corner_pos[s]; i < corner_pos[s + 1]; ++i) {
      k[bl[i]] = hyperbolic::poincare_to_klein(
          hyperbolic::geodesic_point(qc[s], qc[(s + 1) % ns], along / std::max(side_length_3d[s], 1e-300)));
      on_boundary[bl[i]] = 1;
      along += (cm.mesh.V.row(bl[i + 1]) - cm.mesh.V.row(bl[i])).norm();
    }
    k[bl[corner_pos[s]]] = kq[s];
  }
  (void)nb;
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
      const int i = cm.mesh.F(f, q), j = cm.mesh.F(f, (q + 1) % 3), o = cm.mesh.F(f, (q + 2) % 3);
      const Eigen::Vector3d pi = cm.mesh.V.row(i), pj = cm.mesh.V.row(j), po = cm.mesh.V.row(o);
      graph[e].a = i, graph[e].b = j;
      graph[e].w += (half_tan(pj - pi, po - pi) + half_tan(pi - pj, po - pj)) / std::max((pj - pi).norm(), 1e-300);
    }
  graph.erase(std::remove_if(graph.begin(), graph.end(), [](const detail::FlatteningEdge& g) { return g.a < 0; }),
              graph.end());
  std::string why;
  if (!detail::flatten_in_klein(graph, on_boundary, options.hyperboloid_rounds, k, &why)) return give_up(why);

  // The input vertices: one copy's point (global frame) and its deck word,
  // then moved into the target's domain.
  const std::string unread = detail::read_disk_vertices(cm.original_vertex, nv, k, c, chart, options.reduce_point, group,
                                                        "vertex", "the cut disk", out.z, out.vertex_deck,
                                                        out.vertex_deck_word);
  if (!unread.empty()) return give_up(unread);
  out.applied = true;
  out.time_s = seconds_since(t0);
  return out;
}

}  // namespace surfmap
