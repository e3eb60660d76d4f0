// The target's own loops carried onto the flipped triangulation T'
// (uniformize/carried_loops.h, docs/uniformization.md "Handle classes on the
// flip path"): the carried canonical generators are the same curves as on
// the fixed-connectivity path, so their closed geodesics have the lengths
// the fixed-connectivity metric gives them (two discretizations of one
// conformal structure), and the handle classes are the same objects on both
// paths.
#include "surfmap/uniformize/carried_loops.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "surfmap/map/class_lower_bound.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/samples/shapes.h"
#include "surfmap/topology/canonical_schema.h"
#include "surfmap/uniformize/deck_group.h"
#include "../src/map/map_support.h"

namespace surfmap {
namespace {

// Probe words in canonical letters: every generator and every product of two.
std::vector<Word> probes(int genus) {
  std::vector<Word> out;
  for (int i = 1; i <= 2 * genus; ++i) {
    out.push_back({i});
    for (int j = i + 1; j <= 2 * genus; ++j) out.push_back({i, j}), out.push_back({i, -j});
  }
  return out;
}

double max_relative_length_difference(const TriMesh& t, int* flips_on_loops) {
  SurfaceMapOptions o;
  o.uniformization.target_metric = UniformizationMetric::IntrinsicDelaunay;
  const detail::UniformizedTarget flip = detail::uniformized_target(t, Background::Hyperbolic, o);
  o.uniformization.target_metric = UniformizationMetric::FixedConnectivity;
  const detail::UniformizedTarget fixed = detail::uniformized_target(t, Background::Hyperbolic, o);
  EXPECT_EQ(flip.metric, "intrinsic Delaunay");
  EXPECT_EQ(fixed.refinement_splits, 0);
  if (!flip.class_loops) {
    ADD_FAILURE() << flip.class_loops_status;
    return INFINITY;
  }
  *flips_on_loops = flip.class_loops->flips_on_loops;
  // The same loops as the fixed path's: the same boundary word, so the same
  // canonical schema.
  EXPECT_EQ(flip.class_loops->word, fixed.layout.word);
  const SurfaceGroupLengths on_flip(DeckGroup(flip.layout), flip.class_loops->generators_in_layout_letters,
                                    flip.layout.word);
  const SurfaceGroupLengths on_fixed(DeckGroup(fixed.layout), canonical_schema(fixed.layout.word).generators,
                                     fixed.layout.word);
  double worst = 0;
  for (const Word& w : probes(flip.class_loops->schema.genus)) {
    const double a = on_flip.length(w), b = on_fixed.length(w);
    EXPECT_TRUE(std::isfinite(a) && a > 0) << "probe of " << w.size() << " letters";
    EXPECT_TRUE(std::isfinite(b) && b > 0);
    worst = std::max(worst, std::abs(a - b) / b);
  }
  return worst;
}

// A jittered genus-2 surface: the flip-based flow flips edges the loops run
// along, and the carried generators keep the fixed path's geodesic lengths.
TEST(CarriedLoops, CarriedGeneratorsHaveTheFixedPathsGeodesicLengths) {
  const TriMesh t = samples::jitter(samples::n_hole_torus(2, 26, true), 0.25, 7);
  int flips_on_loops = 0;
  const double worst = max_relative_length_difference(t, &flips_on_loops);
  EXPECT_GT(flips_on_loops, 0);  // the carrying is not the identity
  // Measured 6.8e-5 (14 flips rewrote a loop); a wrong word is a different
  // curve, whose geodesic differs by far more.
  EXPECT_LT(worst, 1e-3);
}

}  // namespace
}  // namespace surfmap
