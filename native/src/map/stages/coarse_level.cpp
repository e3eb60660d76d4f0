#include "coarse_level.h"

#include <map>
#include <string>

namespace surfmap::detail {
namespace {

// Side word of source halfedge h in class data cd.
Word side_word_of(const ClassData& cd, const Connectivity& sc, int h) {
  const int e = sc.edge(h);
  return sc.edge_halfedge(e) == h ? cd.side_word_edge[e] : inverse(cd.side_word_edge[e]);
}

}  // namespace

CoarseLevel coarse_level(CoarseSource& cs, const Connectivity& sc, const std::vector<Word>& edge_word,
                         const SystemOfLoops& sl, const std::vector<ClassData>& data, const std::vector<char>& usable,
                         const DeckGroup& group, bool with_search_template) {
  CoarseLevel out;
  if (cs.ok) {
    const Connectivity cc(cs.mesh.F, cs.mesh.num_vertices());
    const IntrinsicDelaunayResult cidt = intrinsic_delaunay(cc, edge_lengths(cs.mesh, cc));
    if (with_search_template && cidt.delaunay) {
      const DehnReducer reduce_source_loops(sl.word);
      std::vector<Word> csw(cc.num_halfedges());
      for (int e = 0; e < cc.num_edges(); ++e) {
        Word w;
        for (int h : cs.edge_path[e]) {
          const int fe = sc.edge(h);
          w = concat(w, sc.edge_halfedge(fe) == h ? edge_word[fe] : inverse(edge_word[fe]));
        }
        const int h = cc.edge_halfedge(e);
        csw[h] = reduce_source_loops(w);
        csw[cc.twin(h)] = inverse(csw[h]);
      }
      for (const auto& ie : cidt.edges) {
        WeightedEdge we;
        we.i = ie.i, we.j = ie.j, we.w = ie.cot_weight;
        Word w;
        for (int h : ie.path) w = concat(w, csw[h]);
        out.edge_template.push_back(we);
        out.source_word.push_back(reduce_source_loops(w));
      }
    }
    for (size_t k = 0; k < data.size() && cs.ok; ++k) {
      if (!usable[k]) {  // no homotopy data (a class refused before its data was built)
        out.class_edges.emplace_back();
        continue;
      }
      std::vector<Word> ch(cc.num_halfedges());
      for (int e = 0; e < cc.num_edges(); ++e) {
        Word w;
        for (int h : cs.edge_path[e]) w = concat(w, side_word_of(data[k], sc, h));
        const int h = cc.edge_halfedge(e);
        ch[h] = group.reduce(w);
        ch[cc.twin(h)] = inverse(ch[h]);
      }
      // The fine paths around every coarse face must bound a disk: exactly
      // when the product of their deck elements is the identity.
      for (int f = 0; f < cc.num_faces() && cs.ok; ++f)
        if (!group.reduce(concat({ch[3 * f], ch[3 * f + 1], ch[3 * f + 2]})).empty())
          cs.ok = false, cs.why = "the fine paths around coarse face " + std::to_string(f) + " are not contractible";
      std::vector<WeightedEdge> edges(cidt.edges.size());
      for (size_t e = 0; e < cidt.edges.size() && cs.ok; ++e) {
        const auto& ie = cidt.edges[e];
        edges[e].i = ie.i, edges[e].j = ie.j, edges[e].w = ie.cot_weight;
        Word w;
        for (int h : ie.path) w = concat(w, ch[h]);
        edges[e].rho_word = group.reduce(w);
        edges[e].rho = group.evaluate_side_word(edges[e].rho_word);
      }
      out.class_edges.push_back(std::move(edges));
    }
    if (!cs.ok || !cidt.delaunay) cs.ok = false, out.class_edges.clear();
  }
  return out;
}

std::vector<WeightedEdge> CoarseLevel::edges_of(const ClassSpace& space, const GroupMap& theta, const DiskLayout& layout,
                                                const DeckGroup& group) const {
  const std::vector<Word> image = space.loop_letter_images(theta);
  std::vector<WeightedEdge> e = edge_template;
  std::map<Word, Word> memo;
  for (size_t k = 0; k < e.size(); ++k) {
    auto it = memo.find(source_word[k]);
    if (it == memo.end())
      it = memo.emplace(source_word[k], group.side_word(dehn_reduce(substitute(source_word[k], image), layout.word))).first;
    e[k].rho_word = it->second;
    e[k].rho = group.evaluate_side_word(e[k].rho_word);
  }
  return e;
}

std::vector<int> prolongation_order(const CoarseSource& cs, const Connectivity& sc) {
  const int nv = sc.num_vertices();
  std::vector<int> settle;  // fine vertices, parents first
  std::vector<char> seen(nv, 0);
  for (int v = 0; v < nv; ++v) {
    std::vector<int> chain;
    for (int u = v; u >= 0 && !seen[u]; u = cs.parent_halfedge[u] >= 0 ? sc.tail(cs.parent_halfedge[u]) : -1)
      chain.push_back(u), seen[u] = 1;
    settle.insert(settle.end(), chain.rbegin(), chain.rend());
  }
  return settle;
}

void prolong(const CoarseSource& cs, const Connectivity& sc, const std::vector<int>& order,
             const HyperbolicHarmonicResult& coarse, const ClassData& cd, const DeckGroup& group,
             std::vector<std::complex<double>>& z, std::vector<Word>& deck) {
  const int nv = sc.num_vertices();
  z.assign(nv, std::complex<double>(0.0));
  deck.assign(nv, Word{});
  for (int v : order) {
    const int c = cs.region[v], ph = cs.parent_halfedge[v];
    z[v] = coarse.z[c];
    deck[v] = ph < 0 ? coarse.vertex_deck_word[c] : group.reduce(concat(deck[sc.tail(ph)], side_word_of(cd, sc, ph)));
  }
}

}  // namespace surfmap::detail
