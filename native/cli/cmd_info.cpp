// surfmap info MESH: counts, genus and every problem found. Exit status 0 for
// a valid closed manifold mesh and for a valid open one (boundary loops, no
// other problem: `surfmap map` takes it through its double,
// docs/open_surfaces.md); 1 otherwise, with the first problem on stderr.
#include <iostream>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "surfmap/error.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/open_surface.h"

namespace surfmap::cli {

void register_info(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Counts, genus and problems of a mesh file");
  auto path = std::make_shared<std::string>();
  auto as_json = std::make_shared<bool>(false);
  cmd->add_option("MESH", *path, "Mesh file (.obj, .off, .ply, .stl)")->required();
  cmd->add_flag("--json", *as_json, "Print the report as JSON");
  cmd->callback([path, as_json] {
    const PolygonSoup soup = read_polygon_soup(*path);
    MeshInfo info = inspect(soup);
    // An open mesh: checked again as an open surface (its genus counts the
    // boundary loops, its vertices must each be one fan); the refusal of the
    // boundary itself is then no problem, any other is.
    std::optional<OpenSurfaceTopology> open;
    if (!info.valid && info.num_boundary_loops > 0) {
      IntakeOptions as_open;
      as_open.allow_boundary = true;
      MeshInfo open_info = inspect(soup, as_open);
      if (open_info.valid) {
        try {
          open = intake_open(soup).topology;
        } catch (const InputError& e) {
          open_info.problems = {e.what()};
        }
      }
      info.problems = open_info.problems;
      info.notes = open_info.notes;
    }
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
      if (open)
        j["open"] = {{"genus", open->genus},
                     {"boundary_loops", open->num_boundary_loops()},
                     {"boundary_lengths", open->boundary_lengths}};
      std::cout << j.dump(2) << "\n";
    } else {
      std::cout << *path << "\n"
                << "  vertices " << info.num_vertices << ", edges " << info.num_edges << ", faces "
                << info.num_faces << "\n"
                << "  components " << info.num_components << ", boundary loops " << info.num_boundary_loops
                << "\n"
                << "  Euler characteristic " << info.euler_characteristic << ", genus "
                << (open ? std::to_string(open->genus) + " (open)"
                        : info.genus >= 0 ? std::to_string(info.genus)
                                          : std::string("undefined"))
                << "\n";
      for (const auto& n : info.notes) std::cout << "  note: " << n << "\n";
      for (const auto& p : info.problems) std::cout << "  problem: " << p << "\n";
      if (open) {
        std::ostringstream lengths;
        for (size_t k = 0; k < open->boundary_lengths.size(); ++k)
          lengths << (k ? ", " : "") << open->boundary_lengths[k];
        std::cout << "  valid open manifold surface: " << open->describe() << " (loop lengths " << lengths.str()
                  << "); `surfmap map` maps it onto an open surface of the same genus and loop count, "
                     "uniformize, loops and domain need a closed surface\n";
      } else {
        std::cout << "  " << (info.valid ? "valid closed manifold surface" : "NOT a valid surface") << "\n";
      }
    }
    if (!info.valid && !open) throw InputError(*path + ": " + info.problems.front());
  });
}

}  // namespace surfmap::cli
