#include "surfmap/uniformize/deck_group.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/layout.h"
#include "surfmap/uniformize/ricci_flow.h"

namespace surfmap {
namespace {

using hyperbolic::Mobius;

DiskLayout hyperbolic_layout(const TriMesh& mesh) {
  const SystemOfLoops loops = system_of_loops(mesh);
  const Connectivity conn(loops.mesh.F);
  const RicciFlowResult flow = ricci_flow(conn, edge_lengths(loops.mesh, conn), Background::Hyperbolic);
  EXPECT_TRUE(flow.converged) << flow.message;
  return layout_disk(conn, flow.edge_lengths, Background::Hyperbolic, loops);
}

// Relative matrix distance (entries of size s carry round-off ~ s * eps).
double relative_distance(const Mobius& m, const Mobius& n) { return hyperbolic::mobius_distance(m, n) / n.size(); }

TEST(DeckGroup, SidePairingPresentationOfALongFundamentalDomain) {
  // The genus-5 wheel: its base corner sits ~9 units from the centre and the
  // loop generators have entries up to ~1e5; products of them lose all digits
  // (on the 11k-vertex version in bench_map the word relation multiplied out
  // in the layout's frame was off by O(1)), which made the map's Hessian NaN.
  const DiskLayout L = hyperbolic_layout(samples::n_hole_torus(5, 32, true));
  const int g = L.genus;
  ASSERT_EQ(g, 5);
  const DeckGroup G(L);
  // Vertex-cycle relator: 4g letters, every side letter once with each sign.
  ASSERT_EQ(static_cast<int>(G.side_relator().size()), 4 * g);
  std::vector<int> plus(2 * g, 0), minus(2 * g, 0);
  for (int x : G.side_relator()) ++(x > 0 ? plus : minus)[std::abs(x) - 1];
  for (int k = 0; k < 2 * g; ++k) EXPECT_TRUE(plus[k] == 1 && minus[k] == 1) << "letter " << k + 1;
  // It holds numerically: its partial products are tiles around one vertex
  // of P, so the product is the identity to the layout's accuracy.
  EXPECT_LT(hyperbolic::distance_from_identity(G.evaluate_side_word(G.side_relator())), 1e-5);
  // The loop relation becomes the empty side word (exactly, by Dehn's
  // algorithm), and each loop generator is the same element as its side word.
  EXPECT_TRUE(G.side_word(L.word).empty());
  double largest = 0;
  for (int k = 0; k < 2 * g; ++k) {
    largest = std::max(largest, L.generators[k].size());
    EXPECT_LT(relative_distance(G.evaluate(Word{k + 1}), L.generators[k]), 1e-8) << "generator " << k;
  }
  EXPECT_GT(largest, 1e3);  // the case this is about: large generator matrices
  // Side words of the generators are short (a handful of tiles).
  for (const Word& w : L.generator_side_words) EXPECT_LE(static_cast<int>(w.size()), 4 * g);
  // Side pairings take their side onto the partner side, reversed
  // (Poincaré's theorem: c_i -> c_{j+1}, c_{i+1} -> c_j).
  const int n = static_cast<int>(L.side_start.size());
  auto corner = [&](int i) {
    const int h = L.boundary_halfedges[L.side_start[(i + n) % n]];
    return L.corners(h / 3, h % 3);
  };
  for (int i = 0; i < n; ++i) {
    if (L.word[i] < 0) continue;
    int j = 0;
    while (L.word[j] != -L.word[i]) ++j;
    const Mobius& D = G.side_pairings()[L.word[i] - 1];
    EXPECT_LT(hyperbolic::distance(D.apply(corner(i)), corner(j + 1)), 1e-6);
    EXPECT_LT(hyperbolic::distance(D.apply(corner(i + 1)), corner(j)), 1e-6);
  }
  // Random words: w w^-1 reduces to nothing; w and its Dehn-reduced form
  // are the same element.
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> letter(1, 2 * g), sign(0, 1);
  for (int trial = 0; trial < 50; ++trial) {
    Word w;
    for (int k = 0; k < 6; ++k) w.push_back(sign(rng) ? letter(rng) : -letter(rng));
    EXPECT_TRUE(G.reduce(concat(w, inverse(w))).empty());
    const Word r = G.reduce(w);
    EXPECT_LE(r.size(), w.size());
    EXPECT_LT(relative_distance(G.evaluate_side_word(r), G.evaluate_side_word(w)), 1e-9);
  }
}

TEST(DeckGroup, RejectsFlatLayouts) {
  const TriMesh torus = samples::torus_of_revolution(2.0, 1.0, 30, 15);
  const SystemOfLoops loops = system_of_loops(torus);
  const Connectivity conn(loops.mesh.F);
  const RicciFlowResult flow = ricci_flow(conn, edge_lengths(loops.mesh, conn), Background::Euclidean);
  const DiskLayout L = layout_disk(conn, flow.edge_lengths, Background::Euclidean, loops);
  EXPECT_THROW(DeckGroup{L}, InputError);
}

}  // namespace
}  // namespace surfmap
