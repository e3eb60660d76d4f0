// The input's system of loops carried onto T' through the flip history
// (uniformize/carried_loops.h).
#include "surfmap/uniformize/carried_loops.h"

#include <algorithm>
#include <string>
#include <unordered_map>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/topology/edge_homotopy.h"

namespace surfmap {
namespace {

// Halfedges are labelled 2e and 2e + 1 (the two orientations of edge e), so
// that label ^ 1 is the reverse. label[3f + q] is the label of the halfedge
// F(f, q) -> F(f, q + 1). Labels survive flips (a flipped edge keeps its
// pair of labels), the face slots holding them do not.
struct LabelledTriangulation {
  RowMatrixX3i F;
  std::vector<int> label;
};

// Appends x to a freely reduced path of labels, cancelling x against a
// preceding reverse.
void push_reduced(std::vector<int>& path, int x) {
  if (!path.empty() && path.back() == (x ^ 1))
    path.pop_back();
  else
    path.push_back(x);
}

// Loop k of `loops` (a vertex path of the refined input mesh) as a closed
// path of input halfedges: every refined vertex is moved to a corner of the
// smallest input simplex holding it (the corner with the largest barycentric
// weight); two consecutive refined vertices lie in one closed input face, so
// their corners are equal or the ends of an edge of that face, and the
// straight moves inside the simplices make the two paths homotopic.
std::vector<int> input_edge_path(const SystemOfLoops& loops, const RowMatrixX3i& F, const Connectivity& ic,
                                 const std::vector<int>& label, int k) {
  const int nv = ic.num_vertices();
  auto snap = [&](int v) {
    if (v < nv) return v;
    int corner = 0;
    loops.origin_barycentric.row(v).maxCoeff(&corner);
    return F(loops.origin_face[v], corner);
  };
  std::vector<int> path;
  const std::vector<int>& loop = loops.loops[k];
  for (size_t q = 0; q + 1 < loop.size(); ++q) {
    const int a = snap(loop[q]), b = snap(loop[q + 1]);
    if (a == b) continue;
    const int h = ic.find_halfedge(a, b);
    if (h < 0)
      throw SolveError("carry_loops_through_flips: loop " + std::to_string(k) + " steps from input vertex " +
                       std::to_string(a) + " to " + std::to_string(b) + ", not an input edge");
    push_reduced(path, label[h]);
  }
  return path;
}

// Replays the flips on t, rewriting every path through a flipped edge.
// Returns how many flips rewrote a path.
int replay_flips(const std::vector<EdgeFlip>& history, LabelledTriangulation& t, std::vector<std::vector<int>>& paths) {
  std::vector<int> uses(t.label.size() / 2, 0);  // per edge: occurrences in the paths
  for (const auto& p : paths)
    for (int x : p) ++uses[x >> 1];
  int rewrites = 0;
  for (size_t i = 0; i < history.size(); ++i) {
    const EdgeFlip& r = history[i];
    const int f0 = r.face0, f1 = r.face1, a0 = r.corner0, a1 = r.corner1;
    const int k = t.F(f0, a0), s = t.F(f0, (a0 + 1) % 3), tt = t.F(f0, (a0 + 2) % 3), m = t.F(f1, a1);
    const int h_ks = t.label[3 * f0 + a0], h_st = t.label[3 * f0 + (a0 + 1) % 3], h_tk = t.label[3 * f0 + (a0 + 2) % 3];
    const int h_mt = t.label[3 * f1 + a1], h_ts = t.label[3 * f1 + (a1 + 1) % 3], h_sm = t.label[3 * f1 + (a1 + 2) % 3];
    if (t.F(f1, (a1 + 1) % 3) != tt || t.F(f1, (a1 + 2) % 3) != s || h_ts != (h_st ^ 1))
      throw SolveError("carry_loops_through_flips: flip " + std::to_string(i) + " (faces " + std::to_string(f0) +
                       ", " + std::to_string(f1) + ") does not match the replayed triangulation");
    const int d = h_st >> 1;
    if (uses[d] > 0) {
      ++rewrites;
      for (auto& p : paths) {
        if (std::find_if(p.begin(), p.end(), [&](int x) { return (x >> 1) == d; }) == p.end()) continue;
        for (int x : p) --uses[x >> 1];
        std::vector<int> q;
        q.reserve(p.size() + 8);
        for (int x : p) {
          if (x == h_st) {  // s->t ~ s->k->t across the old face (k, s, t)
            push_reduced(q, h_ks ^ 1);
            push_reduced(q, h_tk ^ 1);
          } else if (x == h_ts) {  // t->s ~ t->k->s
            push_reduced(q, h_tk);
            push_reduced(q, h_ks);
          } else {
            push_reduced(q, x);
          }
        }
        p = std::move(q);
        for (int x : p) ++uses[x >> 1];
      }
    }
    // As ricci_flow writes them: f0 = (k, s, m), f1 = (m, t, k); the old
    // diagonal's labels now name m->k and k->m.
    t.F.row(f0) << k, s, m;
    t.F.row(f1) << m, tt, k;
    t.label[3 * f0 + 0] = h_ks, t.label[3 * f0 + 1] = h_sm, t.label[3 * f0 + 2] = h_st;
    t.label[3 * f1 + 0] = h_mt, t.label[3 * f1 + 1] = h_tk, t.label[3 * f1 + 2] = h_ts;
  }
  return rewrites;
}

// Words of the halfedges of T' (halfedge 3f + q of flow.faces), read on the
// refined mesh of T''s system of loops, computed on demand.
class TPrimeHalfedgeWords {
 public:
  TPrimeHalfedgeWords(const RowMatrixX3i& tprime_faces, const SystemOfLoops& tl)
      : F_(tprime_faces), rc_(tl.mesh.F, tl.mesh.num_vertices()), region_(tprime_faces.rows()) {
    std::vector<Word> letters;
    for (size_t k = 0; k < tl.generator_edges.size(); ++k) letters.push_back({static_cast<int>(k) + 1});
    const GroupOps<Word> free_group{Word{}, [](const Word& u, const Word& v) { return concat(u, v); },
                                    [](const Word& u) { return inverse(u); }};
    edge_word_ = edge_group_elements(rc_, tl.tree_parent_halfedge, tl.dual_tree_parent_halfedge, tl.generator_edges,
                                     loop_first_vertices(tl, rc_), letters, free_group);
    if (static_cast<int>(tl.face_origin.size()) != tl.mesh.num_faces())
      throw SolveError("carry_loops_through_flips: the loops' mesh of T' has no face origins");
    for (int rf = 0; rf < tl.mesh.num_faces(); ++rf) region_.at(tl.face_origin[rf]).push_back(rf);
  }

  const Word& operator()(int h) {
    auto it = cache_.find(h);
    if (it != cache_.end()) return it->second;
    return cache_[h] = compute(h);
  }

 private:
  // A path from a to b through the refined faces inside face f of T' (a
  // disk holding the edge a->b), by breadth-first search; its word.
  Word compute(int h) const {
    const int f = h / 3, a = F_(f, h % 3), b = F_(f, (h % 3 + 1) % 3);
    std::unordered_map<int, int> reached_by;  // refined vertex -> refined halfedge into it (-1 at a)
    std::vector<int> queue{a};
    reached_by[a] = -1;
    for (size_t q = 0; q < queue.size() && !reached_by.count(b); ++q)
      for (int rf : region_[f])
        for (int c = 0; c < 3; ++c) {
          const int rh = 3 * rf + c;
          const int from = rc_.tail(rh), to = rc_.head(rh);
          // Either direction of the refined edge; the reverse of rh is its
          // twin when the twin lies in the region, else marked by ~rh.
          if (from == queue[q] && !reached_by.count(to)) reached_by[to] = rh, queue.push_back(to);
          if (to == queue[q] && !reached_by.count(from)) reached_by[from] = ~rh, queue.push_back(from);
        }
    if (!reached_by.count(b))
      throw SolveError("carry_loops_through_flips: no path inside face " + std::to_string(f) + " of T' from " +
                       std::to_string(a) + " to " + std::to_string(b));
    std::vector<Word> parts;
    for (int v = b; v != a;) {
      const int rh = reached_by.at(v);
      const int e = rc_.edge(rh >= 0 ? rh : ~rh);
      const bool along = rh >= 0 ? rc_.edge_halfedge(e) == rh : rc_.edge_halfedge(e) != ~rh;
      parts.push_back(along ? edge_word_[e] : inverse(edge_word_[e]));
      v = rh >= 0 ? rc_.tail(rh) : rc_.head(~rh);
    }
    Word w;
    for (auto p = parts.rbegin(); p != parts.rend(); ++p) w = concat(w, *p);
    return w;
  }

  const RowMatrixX3i& F_;
  Connectivity rc_;
  std::vector<std::vector<int>> region_;  // per face of T': refined faces inside it
  std::vector<Word> edge_word_;
  std::unordered_map<int, Word> cache_;
};

}  // namespace

CarriedLoops carry_loops_through_flips(const TriMesh& input, const SystemOfLoops& input_loops,
                                       const RicciFlowResult& flow, const SystemOfLoops& tprime_loops) {
  const int nv = input.num_vertices();
  const Connectivity ic(input.F, nv);
  LabelledTriangulation t;
  t.F = input.F;
  t.label.resize(3 * static_cast<size_t>(input.num_faces()));
  for (int h = 0; h < 3 * input.num_faces(); ++h)
    t.label[h] = 2 * ic.edge(h) + (ic.edge_halfedge(ic.edge(h)) == h ? 0 : 1);
  std::vector<std::vector<int>> paths;
  for (size_t k = 0; k < input_loops.loops.size(); ++k)
    paths.push_back(input_edge_path(input_loops, input.F, ic, t.label, static_cast<int>(k)));
  CarriedLoops out;
  out.flips_on_loops = replay_flips(flow.flip_history, t, paths);
  out.flips_replayed = static_cast<int>(flow.flip_history.size());
  if (t.F != flow.faces)
    throw SolveError("carry_loops_through_flips: the replayed flips do not give the flow's triangulation");
  std::vector<int> halfedge_of_label(t.label.size(), -1);
  for (size_t h = 0; h < t.label.size(); ++h) halfedge_of_label[t.label[h]] = static_cast<int>(h);
  TPrimeHalfedgeWords word_of(flow.faces, tprime_loops);
  for (const auto& p : paths) {
    out.longest_edge_path = std::max(out.longest_edge_path, static_cast<int>(p.size()));
    Word w;
    for (int x : p) w = concat(w, word_of(halfedge_of_label[x]));
    out.words.push_back(std::move(w));
  }
  return out;
}

}  // namespace surfmap
