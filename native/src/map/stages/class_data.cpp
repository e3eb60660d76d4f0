#include "class_data.h"

#include <map>
#include <string>

#include "surfmap/error.h"

namespace surfmap::detail {

using hyperbolic::Mobius;

std::vector<Mobius> ClassData::halfedge_rho(const Connectivity& sc) const {
  std::vector<Mobius> out(sc.num_halfedges());
  for (int h = 0; h < sc.num_halfedges(); ++h) {
    const int e = sc.edge(h);
    out[h] = sc.edge_halfedge(e) == h ? rho_edge[e] : rho_edge[e].inverse();
  }
  return out;
}

std::vector<Word> ClassData::halfedge_words(const Connectivity& sc) const {
  std::vector<Word> out(sc.num_halfedges());
  for (int h = 0; h < sc.num_halfedges(); ++h) {
    const int e = sc.edge(h);
    out[h] = sc.edge_halfedge(e) == h ? side_word_edge[e] : inverse(side_word_edge[e]);
  }
  return out;
}

void index_solver_edges(const Connectivity& sc, const IntrinsicDelaunayResult& idt, SolverEdgeIndex& index) {
  index.solver_edge.resize(sc.num_edges());
  index.forward.resize(sc.num_edges(), 1);
  int next = static_cast<int>(idt.edges.size());
  for (int e = 0; e < sc.num_edges(); ++e) {
    const int h = sc.edge_halfedge(e);
    if (idt.edges[e].path.size() == 1 && sc.edge(idt.edges[e].path[0]) == e) {
      index.solver_edge[e] = e;
      index.forward[e] = idt.edges[e].path[0] == h;
    } else {
      index.solver_edge[e] = next++;
    }
  }
}

std::vector<WeightedEdge> solver_edge_pattern(const Connectivity& sc, const IntrinsicDelaunayResult& idt,
                                             const SolverEdgeIndex& index) {
  std::vector<WeightedEdge> edges(idt.edges.size());
  for (size_t e = 0; e < idt.edges.size(); ++e) {
    edges[e].i = idt.edges[e].i;
    edges[e].j = idt.edges[e].j;
    edges[e].w = idt.edges[e].cot_weight;
  }
  for (int e = 0; e < sc.num_edges(); ++e) {
    if (index.solver_edge[e] < static_cast<int>(idt.edges.size())) continue;
    const int h = sc.edge_halfedge(e);
    WeightedEdge we;
    we.i = sc.tail(h);
    we.j = sc.head(h);
    we.w = 0;
    edges.push_back(we);
  }
  return edges;
}

ClassData class_data(const ClassSpace& space, const GroupMap& theta, const TriMesh& source, const Connectivity& sc,
                     const std::vector<Word>& edge_word, const IntrinsicDelaunayResult& idt,
                     const SolverEdgeIndex& index, const DiskLayout& layout, const DeckGroup& group,
                     bool solver_data) {
  const std::vector<Word> letter_image = space.loop_letter_images(theta);
  std::vector<Word> target_word(edge_word.size());
  // Shortest-form words keep the products of SU(1,1) matrices small. Few
  // distinct words occur (edges crossing the same loops share one), so
  // each is reduced once.
  std::map<Word, Word> memo;
  auto reduced = [&](const Word& w) -> const Word& {
    auto it = memo.find(w);
    if (it == memo.end()) it = memo.emplace(w, dehn_reduce(w, layout.word)).first;
    return it->second;
  };
  // Most edges cross no loop: their word is empty, and so is its image
  // (issue 19: one reduction, side word and matrix for all of them instead
  // of a memo lookup each; the same values).
  const Word reduced_empty = reduced(Word{});
  for (size_t e = 0; e < edge_word.size(); ++e)
    target_word[e] = edge_word[e].empty() ? reduced_empty : reduced(substitute(edge_word[e], letter_image));
  auto word_of = [&](int h) {
    const int e = sc.edge(h);
    return sc.edge_halfedge(e) == h ? target_word[e] : inverse(target_word[e]);
  };
  // Exact check (Dehn's algorithm solves the word problem of the surface
  // group): the product around every source face is the identity.
  for (int f = 0; f < source.num_faces(); ++f) {
    if (reduced_empty.empty() && target_word[sc.edge(3 * f)].empty() && target_word[sc.edge(3 * f + 1)].empty() &&
        target_word[sc.edge(3 * f + 2)].empty())
      continue;  // the empty product
    const Word around = concat({word_of(3 * f), word_of(3 * f + 1), word_of(3 * f + 2)});
    if (!reduced(around).empty())
      throw SolveError("homotopy data inconsistent around source face " + std::to_string(f));
  }
  ClassData cd;
  cd.side_word_edge.resize(edge_word.size());
  std::map<Word, Word> side_memo;
  auto side_word = [&](const Word& w) -> const Word& {
    auto it = side_memo.find(w);
    if (it == side_memo.end()) it = side_memo.emplace(w, group.side_word(w)).first;
    return it->second;
  };
  const Word empty_side = side_word(reduced_empty);
  for (size_t e = 0; e < edge_word.size(); ++e)
    cd.side_word_edge[e] = target_word[e].empty() ? empty_side : side_word(target_word[e]);
  if (!solver_data) return cd;
  const Mobius empty_rho = group.evaluate_side_word(empty_side);
  cd.rho_edge.resize(edge_word.size());
  for (size_t e = 0; e < edge_word.size(); ++e)
    cd.rho_edge[e] = target_word[e].empty() ? empty_rho : group.evaluate_side_word(cd.side_word_edge[e]);
  cd.edges = solver_edge_pattern(sc, idt, index);
  for (size_t e = 0; e < idt.edges.size(); ++e) {
    const auto& ie = idt.edges[e];
    bool empty = true;
    for (int h : ie.path) empty = empty && target_word[sc.edge(h)].empty();
    if (empty) {
      cd.edges[e].rho_word = empty_side;
      cd.edges[e].rho = empty_rho;
      continue;
    }
    Word w;
    for (int h : ie.path) w = concat(w, word_of(h));
    cd.edges[e].rho_word = side_word(reduced(w));
    cd.edges[e].rho = group.evaluate_side_word(cd.edges[e].rho_word);
  }
  // The source edges after idt's, in solver_edge_pattern's order.
  size_t next = idt.edges.size();
  for (int e = 0; e < sc.num_edges(); ++e) {
    if (index.solver_edge[e] < static_cast<int>(idt.edges.size())) continue;
    cd.edges[next].rho_word = cd.side_word_edge[e];
    cd.edges[next].rho = cd.rho_edge[e];
    ++next;
  }
  return cd;
}

HyperbolicHarmonicResult PatternSolver::solve(int n, const std::vector<WeightedEdge>& edges,
                                              const std::vector<Mobius>& generators, std::vector<Complex> z0,
                                              const HyperbolicHarmonicOptions& options) {
  std::shared_ptr<const HyperbolicHarmonicSolver> s;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!solver_ || !solver_->fits(n, edges)) solver_ = std::make_shared<const HyperbolicHarmonicSolver>(n, edges);
    s = solver_;
  }
  return s->solve(edges, generators, std::move(z0), options);
}

void PatternSolver::prepare(int n, const std::vector<WeightedEdge>& edges) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (solver_ && solver_->fits(n, edges)) return;
  try {
    solver_ = std::make_shared<const HyperbolicHarmonicSolver>(n, edges);
  } catch (const Error&) {
    // (built again by the first solve, which reports the failure)
  }
}

void PatternSolver::reset() {
  std::lock_guard<std::mutex> lock(mutex_);
  solver_.reset();
}

// A solve of `edges` (n vertices) from points `start` with vertex decks
// `deck_word` (side words): the edges are conjugated by the decks (as
// words, never as matrix products), and the decks are composed back, so
// the result is relative to `edges` as given.
HyperbolicHarmonicResult solve_with_decks(int n, const std::vector<WeightedEdge>& edges, const std::vector<Complex>& start,
                                          const std::vector<Word>& deck_word, const DeckGroup& group,
                                          const HyperbolicHarmonicOptions& o, PatternSolver* solver) {
  std::vector<WeightedEdge> e = edges;
  std::vector<Mobius> deck(n);
  bool any = false;
  for (int i = 0; i < n; ++i)
    if (!deck_word[i].empty()) any = true, deck[i] = group.evaluate_side_word(deck_word[i]);
  if (any)
    for (auto& ed : e) {
      if (deck_word[ed.i].empty() && deck_word[ed.j].empty()) continue;
      ed.rho_word = group.reduce(concat({deck_word[ed.i], ed.rho_word, inverse(deck_word[ed.j])}));
      ed.rho = group.evaluate_side_word(ed.rho_word);
    }
  HyperbolicHarmonicResult r = solver ? solver->solve(n, e, group.side_pairings(), start, o)
                                      : hyperbolic_harmonic_map(n, e, group.side_pairings(), start, o);
  if (any)
    for (int i = 0; i < n; ++i) {
      r.vertex_deck[i] = (r.vertex_deck[i] * deck[i]).normalized();
      r.vertex_deck_word[i] = group.reduce(concat(r.vertex_deck_word[i], deck_word[i]));
    }
  return r;
}

}  // namespace surfmap::detail
