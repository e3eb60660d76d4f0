// surfmap verify SRC DST --correspondence CORR.txt: the independent
// certificate of a stored map (verify/map_certificate.h, docs/verification.md).
// Prints the certificate on stdout; exit status 1 when any check fails.
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "surfmap/error.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/mesh_io.h"
#include "surfmap/verify/correspondence_file.h"
#include "surfmap/verify/map_certificate.h"

namespace surfmap::cli {

void register_verify(CLI::App& app) {
  auto* cmd = app.add_subcommand("verify", "Certify a stored map SRC -> DST (CORR.txt of surfmap map) as a bijection");
  struct Args {
    std::string src, dst, correspondence, json;
    MapCertificateOptions opt;
  };
  auto a = std::make_shared<Args>();
  cmd->add_option("SRC", a->src, "Source mesh (as given to surfmap map)")->required();
  cmd->add_option("DST", a->dst, "Target mesh (as given to surfmap map)")->required();
  cmd->add_option("--correspondence", a->correspondence, "CORR.txt written by surfmap map --correspondence")->required();
  cmd->add_option("--json", a->json, "CERT.json: the certificate's figures");
  cmd->add_option("--barycentric-tolerance", a->opt.barycentric_tolerance,
                  "Barycentrics may be below 0, and their sum off 1, by this much")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  cmd->add_option("--area-tolerance", a->opt.area_tolerance, "Allowed |signed image area / target area - 1| (< 0.5)")
      ->check(CLI::Range(1e-12, 0.4999))->capture_default_str();
  cmd->add_option("--inverse-tolerance", a->opt.inverse_tolerance,
                  "Allowed composition error, relative to the image triangle's longest edge")
      ->check(CLI::PositiveNumber)->capture_default_str();
  cmd->add_flag("--strict", a->opt.strict,
               "Fail also on checks that fail only on unresolved images (whose corners' target normals differ by more "
               "than 60 degrees)");
  cmd->callback([a] {
    const IntakeResult src = load_mesh(a->src), dst = load_mesh(a->dst);
    const CorrespondenceFile corr = read_correspondence(a->correspondence);
    if (!corr.has_inverse)
      throw InputError(a->correspondence + ": no inverse section (written by an older surfmap map; map again)");
    const MapCertificate c = certify_map(src.mesh, dst.mesh, corr.forward, corr.inverse, a->opt);
    std::cout << "surfmap verify " << a->src << " -> " << a->dst << "\n" << c.summary() << "\n";
    if (!a->json.empty()) {
      const nlohmann::json j = {{"certified", c.certified},
                                {"failures", c.failures},
                                {"undecided", c.undecided},
                                {"source", {{"vertices", c.source_vertices}, {"triangles", c.source_triangles}}},
                                {"target", {{"vertices", c.target_vertices}, {"triangles", c.target_triangles}}},
                                {"invalid_forward", c.invalid_forward},
                                {"invalid_inverse", c.invalid_inverse},
                                {"min_barycentric", c.min_barycentric},
                                {"max_barycentric_sum_error", c.max_barycentric_sum_error},
                                {"negative_triangles", c.negative_triangles},
                                {"degenerate_triangles", c.degenerate_triangles},
                                {"min_relative_area", c.min_relative_area},
                                {"winding_failures", c.winding_failures},
                                {"signed_image_area", c.signed_image_area},
                                {"target_area", c.target_area},
                                {"area_ratio", c.area_ratio},
                                {"degree", c.degree},
                                {"max_inverse_error", c.max_inverse_error},
                                {"max_forward_error", c.max_forward_error},
                                {"inverse_failures", c.inverse_failures},
                                {"forward_failures", c.forward_failures},
                                {"unresolved_triangles", c.unresolved_triangles},
                                {"negative_unresolved", c.negative_unresolved},
                                {"winding_failures_unresolved", c.winding_failures_unresolved},
                                {"inverse_failures_unresolved", c.inverse_failures_unresolved},
                                {"forward_failures_unresolved", c.forward_failures_unresolved}};
      write_text_file(a->json, j.dump(2) + "\n");
    }
    if (!c.certified)
      throw SolveError("the map is not certified: " + std::to_string(c.failures.size()) + " check(s) failed");
  });
}

}  // namespace surfmap::cli
