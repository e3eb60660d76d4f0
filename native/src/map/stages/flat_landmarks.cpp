#include "flat_landmarks.h"

#include <cmath>
#include <tuple>

#include "surfmap/error.h"
#include "surfmap/map/distortion.h"

namespace surfmap::detail {

FlatHold hold_flat_landmarks(const FlatLandmarkProblem& problem, const std::vector<Complex>& t,
                             const std::vector<Complex>& te) {
  const TriMesh& source = *problem.source;
  const IntrinsicDelaunayResult& idt = *problem.idt;
  const std::vector<int>& lm_source = problem.lm_source;
  const int n = source.num_vertices();
  FlatHold h;
  const std::vector<Complex> free = problem.free_optimum(t);
  const std::vector<Complex> lifts = flat_landmark_lifts(free, lm_source, problem.lm_target, problem.w1, problem.w2);
  std::vector<std::pair<int, int>> ends(idt.edges.size());
  for (size_t e = 0; e < idt.edges.size(); ++e) ends[e] = {idt.edges[e].i, idt.edges[e].j};
  h.held = lm_source, h.values = lifts;
  h.rings.assign(lm_source.size(), 0);
  h.held_count = static_cast<int>(lm_source.size());
  std::tie(h.z, h.energy) = problem.pinned->solve(t, lifts);
  auto folds = [&](const std::vector<Complex>& zz) {
    const DistortionStats q = planar_distortion(source.V, source.F, problem.image_corners(te, zz));
    return q.flipped > 0 || q.degenerate > 0;
  };
  if (!folds(h.z)) return h;
  if (problem.folds_allowed) {
    h.method = "pinned (folds allowed)";
    return h;
  }
  const FlatBarrierResult br =
      flat_barrier_landmarks(n, idt.edges, t, source.F, problem.image_corners(te, std::vector<Complex>(n, Complex(0.0))),
                             free, lm_source, lifts);
  h.solves += br.steps;
  h.steps = br.steps;
  if (br.ok && !folds(br.z)) {
    h.z = br.z, h.energy = br.energy;
    h.method = "barrier continuation";
    return h;
  }
  h.method = "carried neighbourhoods";
  try {
    const LandmarkPatchSearch search = grow_landmark_patches(
        n, ends, source.F, *problem.landmarks, [&](const std::vector<LandmarkPatch>& patches) {
          h.held.clear(), h.values.clear();
          for (size_t a = 0; a < patches.size(); ++a)
            for (size_t r = 0; r < patches[a].vertex.size(); ++r) {
              const int v = patches[a].vertex[r];
              h.held.push_back(v);
              h.values.push_back(r == 0 ? lifts[a] : free[v] + (lifts[a] - free[lm_source[a]]));
            }
          std::tie(h.z, h.energy) = PinnedFlatHarmonic(n, idt.edges, h.held, false).solve(t, h.values);
          const DistortionStats q = planar_distortion(source.V, source.F, problem.image_corners(te, h.z));
          std::vector<int> bad;
          for (int f = 0; f < source.num_faces(); ++f)
            if (!std::isfinite(q.per_face[f])) bad.push_back(f);
          return bad;
        });
    h.rings = search.rings;
    h.solves += search.solves;
    h.held_count = search.held_vertices;
  } catch (const SolveError& e) {
    throw SolveError("the landmarks cannot be held bijectively: the interior-point continuation stalled " +
                     std::to_string(static_cast<int>(100 * br.reached)) + "% of the way to them, and " + e.what());
  }
  return h;
}

}  // namespace surfmap::detail
