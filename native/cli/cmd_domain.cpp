// surfmap domain --genus G --kind n-torus|polycube --out D.obj: a canonical
// surface of genus G (samples/canonical_domain.h) onto which shapes are
// mapped with `surfmap map SHAPE D.obj` and compared (docs/many_shapes.md).
#include <iostream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "surfmap/error.h"
#include "surfmap/mesh/mesh_io.h"
#include "surfmap/samples/canonical_domain.h"

namespace surfmap::cli {

void register_domain(CLI::App& app) {
  struct Args {
    std::string kind = "n-torus", layout = "row", out, report;
    int genus = 2, resolution = 24;
    bool keep_scale = false;
  };
  auto a = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("domain", "Write a canonical surface of a given genus (a common domain) as OBJ");
  cmd->add_option("--genus,-g", a->genus, "Genus 0..8 (0: icosphere)")->required();
  cmd->add_option("--kind", a->kind, "n-torus (round holes) or polycube (square holes in a row)")
      ->check(CLI::IsMember({"n-torus", "polycube"}))
      ->capture_default_str();
  cmd->add_option("--layout", a->layout, "n-torus: holes in a row or in a ring")
      ->check(CLI::IsMember({"row", "ring"}))
      ->capture_default_str();
  cmd->add_option("--resolution", a->resolution, "Grid cells per hole (>= 16); #V grows like genus x resolution^2")
      ->capture_default_str();
  cmd->add_flag("--keep-scale", a->keep_scale, "Keep the modelling units (default: scaled to total area 1)");
  cmd->add_option("--out,-o", a->out, "Output .obj file (written atomically)")->required();
  cmd->add_option("--report", a->report, "REPORT.json: genus, area, orientation and triangle quality");
  cmd->callback([a] {
    samples::CanonicalDomainOptions o;
    o.genus = a->genus;
    o.kind = a->kind == "polycube" ? samples::DomainKind::Polycube : samples::DomainKind::NTorus;
    o.layout = a->layout == "ring" ? samples::DomainLayout::Ring : samples::DomainLayout::Row;
    o.resolution = a->resolution;
    o.unit_area = !a->keep_scale;
    const samples::CanonicalDomainResult d = samples::canonical_domain(o);
    write_obj(a->out, d.mesh.V, d.mesh.F);
    if (!a->report.empty()) {
      const nlohmann::json report = {{"description", d.description},
                                     {"genus", d.genus},
                                     {"vertices", d.mesh.num_vertices()},
                                     {"faces", d.mesh.num_faces()},
                                     {"area", d.area},
                                     {"signed_volume", d.signed_volume},
                                     {"min_angle_deg", d.min_angle_deg},
                                     {"mean_min_angle_deg", d.mean_min_angle_deg},
                                     {"fraction_below_20_deg", d.fraction_below_20_deg}};
      write_text_file(a->report, report.dump(2) + "\n");
    }
    std::cout << a->out << ": " << d.description << ", " << d.mesh.num_vertices() << " vertices, "
              << d.mesh.num_faces() << " faces, min angle " << d.min_angle_deg << " deg\n";
  });
}

}  // namespace surfmap::cli
