#include "initial_map_stage.h"

#include "surfmap/error.h"

namespace surfmap::detail {

using hyperbolic::Mobius;

ClassInitialMap class_initial_map(const ClassData& cd, const TriMesh& source, const Connectivity& sc,
                                  const SystemOfLoops& sl, const DeckGroup& group, const FundamentalPolygon& polygon,
                                  const SurfaceMapOptions& options, const std::atomic<bool>* stop,
                                  std::vector<Complex> start_z, std::vector<Word> start_word) {
  ClassInitialMap r;
  r.halfedge_rho = cd.halfedge_rho(sc);
  r.halfedge_word = cd.halfedge_words(sc);
  try {
    HyperbolicInitialMapOptions io;
    io.cut_graph = options.initial.method == InitialMapMethod::CutGraph;
    io.polygon = options.initial.method != InitialMapMethod::UniformHarmonic;
    io.base_vertex = sl.base_vertex;
    io.source_loops = &sl.loops;
    io.reduce_point = [&](Complex& z) { return polygon.reduce(z); };
    if (stop) io.keep_going = [stop] { return !*stop; };
    io.start_z = std::move(start_z), io.start_word = std::move(start_word);
    r.init = hyperbolic_initial_map(source, sc, r.halfedge_rho, r.halfedge_word, group, io);
  } catch (const SolveError&) {
    // The start then is every vertex at the origin (as before the initial
    // map existed); the "before" figures report its degenerate triangles.
    r.init = HyperbolicInitialMapResult();
    r.init.z.assign(source.num_vertices(), Complex(0.0));
    r.init.vertex_deck.assign(source.num_vertices(), Mobius());
    r.init.vertex_deck_word.assign(source.num_vertices(), Word{});
    r.init.construction = "none (the uniform-weight solve failed; origin)";
  }
  return r;
}

DistortionStats initial_map_distortion(const TriMesh& source, const DeckGroup& group, const ClassInitialMap& initial) {
  const HyperbolicInitialMapResult& init = initial.init;
  return init.vertex_deck_word.size() == init.z.size()
             ? hyperbolic_distortion(source, group, initial.halfedge_word, init.z, init.vertex_deck_word)
             : hyperbolic_distortion(source, initial.halfedge_rho, init.z, init.vertex_deck);
}

}  // namespace surfmap::detail
