#include "surfmap/topology/edge_words.h"

#include <string>

#include "surfmap/error.h"
#include "surfmap/topology/edge_homotopy.h"

namespace surfmap {

CutDiskEdgeWords::CutDiskEdgeWords(const SystemOfLoops& loops, const Connectivity& conn)
    : conn_(conn), dual_parent_(loops.dual_tree_parent_halfedge) {
  const int ne = conn.num_edges(), nh = conn.num_halfedges();
  if (static_cast<int>(dual_parent_.size()) != conn.num_faces() ||
      static_cast<int>(loops.tree_parent_halfedge.size()) != conn.num_vertices())
    throw SolveError("edge words: the trees do not match the mesh");
  cut_.assign(ne, 0);
  letter_.assign(nh, 0);
  for (int v = 0; v < conn.num_vertices(); ++v)
    if (loops.tree_parent_halfedge[v] >= 0) cut_[conn.edge(loops.tree_parent_halfedge[v])] = 1;
  // Generator k's letter on the orientation the loop walks it (from its
  // first vertex), as edge_group_elements with loop_values {k + 1}.
  const std::vector<int> first = loop_first_vertices(loops, conn);
  int num_cut = 0;
  for (char c : cut_) num_cut += c;
  for (size_t k = 0; k < loops.generator_edges.size(); ++k) {
    const int e = loops.generator_edges[k];
    if (cut_[e]) throw SolveError("edge words: generator edge " + std::to_string(e) + " is a tree edge");
    cut_[e] = 1;
    ++num_cut;
    const int h = conn.edge_halfedge(e);
    const int along = conn.tail(h) == first[k] ? h : conn.twin(h);
    letter_[along] = static_cast<int>(k) + 1;
    letter_[conn.twin(along)] = -(static_cast<int>(k) + 1);
  }
  if (loops.generator_edges.empty()) throw SolveError("edge words: no generator edges");
  // D's boundary: every halfedge of a cut edge, walked with D on the left.
  pos_.assign(nh, -1);
  const int start = conn.edge_halfedge(loops.generator_edges[0]);
  int h = start;
  do {
    if (length_ >= 2 * num_cut || pos_[h] >= 0)
      throw SolveError("edge words: the cut disk's boundary is not one cycle through the cut edges");
    pos_[h] = length_;
    if (letter_[h]) letters_.push_back({length_, letter_[h]});
    ++length_;
    h = arc_start(h);
  } while (h != start);
  if (length_ != 2 * num_cut)
    throw SolveError("edge words: the cut disk's boundary has " + std::to_string(length_) + " halfedges, expected " +
                     std::to_string(2 * num_cut));
  cache_.resize(ne);
  done_.assign(ne, 0);
}

// The first cut halfedge leaving head(h), turning inside D from face(h).
int CutDiskEdgeWords::arc_start(int h) const {
  int o = Connectivity::next(h);
  for (int turns = 0; !cut_[conn_.edge(o)]; ++turns) {
    if (turns > conn_.num_halfedges()) throw SolveError("edge words: a vertex has no cut edge");
    o = Connectivity::next(conn_.twin(o));
  }
  return o;
}

const Word& CutDiskEdgeWords::operator()(int e) const {
  if (done_[e]) return cache_[e];
  Word& w = cache_[e];
  const int h = conn_.edge_halfedge(e);
  if (letter_[h]) {
    w = {letter_[h]};
  } else if (!cut_[e]) {
    // The child side's halfedge hp (the sub-disk below e lies on its left):
    // its arc runs from the cut halfedge after hp to the one before twin(hp)'s
    // arc, and element(hp) = (product of the arc)^-1.
    const bool child_here = dual_parent_[Connectivity::face(h)] == h;
    const int hp = child_here ? h : conn_.twin(h);
    if (dual_parent_[Connectivity::face(hp)] != hp)
      throw SolveError("edge words: edge " + std::to_string(e) + " is in neither tree nor a generator");
    const int a = pos_[arc_start(hp)], b = pos_[arc_start(conn_.twin(hp))];
    const int span = ((b - a) % length_ + length_) % length_;
    if (span == 0) throw SolveError("edge words: edge " + std::to_string(e) + " bounds an empty arc");
    Word arc;  // the arc's letters in walk order from a
    for (int pass = 0; pass < 2; ++pass)
      for (const auto& [p, l] : letters_)
        if ((pass == 0) == (p >= a) && ((p - a) % length_ + length_) % length_ < span) arc.push_back(l);
    // element(hp) = reduce(arc)^-1; element(twin hp) = reduce(arc).
    w = child_here ? inverse(reduce(arc)) : reduce(arc);
  }
  done_[e] = 1;
  return w;
}

}  // namespace surfmap
