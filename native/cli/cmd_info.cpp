// surfmap info MESH: counts, genus and every problem found. Exit status 0 only
// for a valid closed manifold mesh.
#include <iostream>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "surfmap/error.h"
#include "surfmap/mesh/intake.h"

namespace surfmap::cli {

void register_info(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Counts, genus and problems of a mesh file");
  auto path = std::make_shared<std::string>();
  auto as_json = std::make_shared<bool>(false);
  cmd->add_option("MESH", *path, "Mesh file (.obj, .off, .ply, .stl)")->required();
  cmd->add_flag("--json", *as_json, "Print the report as JSON");
  cmd->callback([path, as_json] {
    const PolygonSoup soup = read_polygon_soup(*path);
    const MeshInfo info = inspect(soup);
    if (*as_json) {
      nlohmann::json j = {{"file", *path},
                          {"vertices", info.num_vertices},
                          {"edges", info.num_edges},
                          {"faces", info.num_faces},
                          {"components", info.num_components},
                          {"boundary_loops", info.num_boundary_loops},
                          {"euler_characteristic", info.euler_characteristic},
                          {"genus", info.genus},
                          {"valid", info.valid},
                          {"zero_area_faces", info.zero_area_faces},
                          {"mollified_faces", info.mollified_faces},
                          {"mollify_epsilon", info.mollify_epsilon},
                          {"problems", info.problems},
                          {"notes", info.notes}};
      std::cout << j.dump(2) << "\n";
    } else {
      std::cout << *path << "\n"
                << "  vertices " << info.num_vertices << ", edges " << info.num_edges << ", faces "
                << info.num_faces << "\n"
                << "  components " << info.num_components << ", boundary loops " << info.num_boundary_loops
                << "\n"
                << "  Euler characteristic " << info.euler_characteristic << ", genus "
                << (info.genus >= 0 ? std::to_string(info.genus) : std::string("undefined")) << "\n";
      for (const auto& n : info.notes) std::cout << "  note: " << n << "\n";
      for (const auto& p : info.problems) std::cout << "  problem: " << p << "\n";
      std::cout << "  " << (info.valid ? "valid closed manifold surface" : "NOT a valid closed surface")
                << "\n";
    }
    if (!info.valid) throw InputError(*path + ": " + info.problems.front());
  });
}

}  // namespace surfmap::cli
