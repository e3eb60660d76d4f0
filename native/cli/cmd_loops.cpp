// surfmap loops MESH --out LOOPS.json --mesh-out REFINED.obj: the system of
// loops (docs/method.md §2.2) of a closed surface of genus >= 1, refined so that the
// 2g loops are simple and meet only at the base vertex. Vertex indices in the
// JSON are 0-based indices into REFINED.obj.
#include <chrono>
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "../src/seconds_since.h"
#include "commands.h"
#include "surfmap/error.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/mesh_io.h"
#include "surfmap/topology/system_of_loops.h"

namespace surfmap::cli {

using detail::seconds_since;

void register_loops(CLI::App& app) {
  auto* cmd = app.add_subcommand("loops", "System of loops (2g simple loops through one base vertex)");
  struct Args {
    std::string mesh, out, mesh_out;
    int base_vertex = -1;
    bool no_refine = false;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("MESH", a->mesh, "Closed mesh of genus >= 1 (.obj, .off, .ply, .stl)")->required();
  cmd->add_option("--out", a->out, "Output JSON with the loops and the boundary word")->required();
  cmd->add_option("--mesh-out", a->mesh_out, "Output OBJ of the refined mesh the loops live on")->required();
  cmd->add_option("--base-vertex", a->base_vertex, "Base vertex x (index into MESH; default: chosen)");
  cmd->add_flag("--no-refine", a->no_refine,
                "Keep the greedy shortest-path loops as they are (they may share vertices away from x)");
  cmd->callback([a] {
    const IntakeResult in = load_mesh(a->mesh);
    for (const auto& n : in.info.notes) std::cerr << "surfmap: note: " << n << "\n";
    if (in.info.genus == 0)
      throw InputError(a->mesh + ": the surface has genus 0; a system of loops needs genus >= 1");
    SystemOfLoopsOptions opt;
    opt.base_vertex = a->base_vertex;
    opt.refine = !a->no_refine;
    const auto t0 = std::chrono::steady_clock::now();
    const SystemOfLoops s = system_of_loops(in.mesh, opt);
    const double seconds = seconds_since(t0);
    const int n_in = in.mesh.num_vertices();
    nlohmann::json j;
    j["input"] = a->mesh;
    j["genus"] = s.genus;
    j["base_vertex"] = s.base_vertex;
    j["refined"] = opt.refine;
    j["loops"] = s.loops;
    j["word"] = s.word_text;
    j["word_letters"] = s.word;
    j["num_vertices"] = s.mesh.num_vertices();
    j["num_faces"] = s.mesh.num_faces();
    j["input_num_vertices"] = n_in;
    j["input_num_faces"] = in.mesh.num_faces();
    nlohmann::json gens = nlohmann::json::array();
    const Connectivity conn(s.mesh.F, s.mesh.num_vertices());
    for (int e : s.generator_edges) gens.push_back({conn.edge_vertex(e, 0), conn.edge_vertex(e, 1)});
    j["generator_edges"] = gens;
    nlohmann::json lengths = nlohmann::json::array();
    for (const auto& L : s.loops) {
      double len = 0;
      for (size_t i = 0; i + 1 < L.size(); ++i) len += (s.mesh.V.row(L[i]) - s.mesh.V.row(L[i + 1])).norm();
      lengths.push_back(len);
    }
    j["loop_lengths"] = lengths;
    // Split vertices (index >= input_num_vertices): where they lie on the input.
    std::vector<int> of(s.origin_face.begin() + n_in, s.origin_face.end());
    nlohmann::json bc = nlohmann::json::array();
    for (int v = n_in; v < s.mesh.num_vertices(); ++v)
      bc.push_back({s.origin_barycentric(v, 0), s.origin_barycentric(v, 1), s.origin_barycentric(v, 2)});
    j["split_vertex_origin_face"] = of;
    j["split_vertex_origin_barycentric"] = bc;
    j["seconds"] = seconds;
    write_obj(a->mesh_out, s.mesh.V, s.mesh.F);
    write_text_file(a->out, j.dump(1) + "\n");
    std::cout << a->mesh << ": genus " << s.genus << ", " << s.loops.size() << " loops through vertex "
              << s.base_vertex << ", word " << s.word_text << "\n  " << n_in << " -> "
              << s.mesh.num_vertices() << " vertices, " << in.mesh.num_faces() << " -> " << s.mesh.num_faces()
              << " faces, " << seconds << " s\n";
  });
}

}  // namespace surfmap::cli
