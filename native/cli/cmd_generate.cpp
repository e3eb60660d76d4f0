// surfmap generate SHAPE --out FILE.obj: writes one of the procedural sample
// surfaces (samples/shapes.h), optionally jittered.
#include <iostream>
#include <memory>
#include <string>

#include "commands.h"
#include "surfmap/error.h"
#include "surfmap/mesh/connectivity.h"
#include "surfmap/mesh/mesh_io.h"
#include "surfmap/samples/shapes.h"

namespace surfmap::cli {

void register_generate(CLI::App& app) {
  struct Args {
    std::string shape, out;
    double R = 1.0, r = 0.5;
    int n_major = 64, n_minor = 32, variant = 0;
    int genus = 2, resolution = 64, subdivisions = 3;
    bool raw = false;
    double jitter = 0.0, thickness = 0.1, degenerate_t = 0.5;
    int segments = 64, degenerate = 0, rings = 30;
    double stretch = 10.0, bend = 0.3;
    unsigned seed = 0;
  };
  auto a = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("generate", "Write a procedural sample surface as OBJ");
  cmd->add_option("SHAPE", a->shape, "torus | n-hole-torus | wheel | vase | amphora | cup | polycube | sphere | bent-sphere | peanut | cad-plate")
      ->required()
      ->check(CLI::IsMember(
          {"torus", "n-hole-torus", "wheel", "vase", "amphora", "cup", "polycube", "sphere", "bent-sphere", "peanut", "cad-plate"}));
  cmd->add_option("--out,-o", a->out, "Output .obj file (written atomically)")->required();
  cmd->add_option("--R", a->R, "torus: major radius")->capture_default_str();
  cmd->add_option("--r", a->r, "torus: minor radius")->capture_default_str();
  cmd->add_option("--n-major", a->n_major, "torus: vertices around the major circle")->capture_default_str();
  cmd->add_option("--n-minor", a->n_minor, "torus: vertices around the minor circle")->capture_default_str();
  cmd->add_option("--variant", a->variant, "torus: connectivity variant (0, 1, 2, other = random)")
      ->capture_default_str();
  cmd->add_option("--genus", a->genus, "n-hole-torus: holes; cup: handles; polycube: holes (1..8); wheel: spokes (3..32); cad-plate: holes (1..64)")
      ->capture_default_str();
  cmd->add_option("--resolution", a->resolution, "implicit shapes: grid cells along the longest axis (>= 32)")
      ->capture_default_str();
  cmd->add_option("--subdivisions", a->subdivisions, "sphere: icosahedron subdivisions")->capture_default_str();
  cmd->add_flag("--raw", a->raw, "implicit shapes: keep the raw marching-tetrahedra mesh (slivers)");
  cmd->add_option("--jitter", a->jitter, "random tangential vertex offset, x local mean edge length (< 0.3)")
      ->capture_default_str();
  cmd->add_option("--seed", a->seed, "seed for --jitter and --degenerate")->capture_default_str();
  cmd->add_option("--segments", a->segments, "cad-plate: points on each hole's rim (multiple of 4); bent-sphere: vertices around")
      ->capture_default_str();
  cmd->add_option("--rings", a->rings, "bent-sphere: rings of the UV sphere")->capture_default_str();
  cmd->add_option("--stretch", a->stretch, "bent-sphere: length to width (>= 1)")->capture_default_str();
  cmd->add_option("--bend", a->bend, "bent-sphere: x += bend z^2 / stretch (0..1)")->capture_default_str();
  cmd->add_option("--thickness", a->thickness, "cad-plate: thickness (0.1 a plate, >= 1 a block)")
      ->capture_default_str();
  cmd->add_option("--degenerate", a->degenerate,
                  "insert this many exactly zero-area faces (samples::insert_degenerate_faces)")
      ->capture_default_str();
  cmd->add_option("--degenerate-t", a->degenerate_t,
                  "position of each inserted vertex on its edge: 0 coincident, 0.5 collinear midpoint")
      ->capture_default_str();
  cmd->callback([a] {
    namespace s = samples;
    const bool smooth = !a->raw;
    TriMesh m;
    int genus = a->genus;
    if (a->shape == "torus") {
      m = s::torus_of_revolution(a->R, a->r, a->n_major, a->n_minor, a->variant);
      genus = 1;
    } else if (a->shape == "n-hole-torus") {
      m = s::n_hole_torus(a->genus, a->resolution, smooth);
    } else if (a->shape == "wheel") {
      m = s::wheel(a->genus, a->resolution, smooth);
    } else if (a->shape == "vase") {
      m = s::vase(a->resolution, smooth);
      genus = 2;
    } else if (a->shape == "amphora") {
      m = s::amphora(a->resolution, smooth);
      genus = 2;
    } else if (a->shape == "cup") {
      m = s::cup(a->genus, a->resolution, smooth);
    } else if (a->shape == "polycube") {
      m = s::polycube(a->genus, a->resolution, smooth);
    } else if (a->shape == "peanut") {
      m = s::peanut(a->resolution, smooth);
      genus = 0;
    } else if (a->shape == "bent-sphere") {
      m = s::bent_tapered_sphere(a->rings, a->segments, a->stretch, a->bend);
      genus = 0;
    } else if (a->shape == "cad-plate") {
      m = s::cad_plate(a->genus, a->segments, a->thickness);
    } else {
      m = s::sphere(a->subdivisions);
      genus = 0;
    }
    if (a->jitter != 0.0) m = s::jitter(m, a->jitter, a->seed);
    if (a->degenerate != 0) m = s::insert_degenerate_faces(m, a->degenerate, a->degenerate_t, a->seed);
    write_obj(a->out, m.V, m.F);
    std::cout << a->out << ": " << a->shape << ", genus " << genus << ", " << m.num_vertices()
              << " vertices, " << m.num_faces() << " faces\n";
  });
}

}  // namespace surfmap::cli
