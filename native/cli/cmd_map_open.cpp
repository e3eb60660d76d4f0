// `surfmap map` for open pairs (see map_open.h).
#include <iomanip>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "map_open.h"
#include "surfmap/error.h"
#include "surfmap/map/open_map.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/mesh_io.h"
#include "surfmap/mesh/open_surface.h"

namespace surfmap::cli {

bool map_open_pair(const OpenMapCliArgs& a) {
  const PolygonSoup src_soup = read_polygon_soup(a.src), dst_soup = read_polygon_soup(a.dst);
  if (inspect(src_soup).num_boundary_loops == 0 && inspect(dst_soup).num_boundary_loops == 0) return false;
  auto load = [](const PolygonSoup& soup, const std::string& path) {
    try {
      return intake_open(soup);
    } catch (const InputError& e) {
      throw InputError("'" + path + "': " + e.what());
    }
  };
  const OpenIntakeResult src = load(src_soup, a.src), dst = load(dst_soup, a.dst);
  try {
    check_same_open_topology(src.topology, dst.topology);
  } catch (const InputError& e) {
    throw InputError("'" + a.src + "' onto '" + a.dst + "': " + e.what() + " (open surfaces: docs/open_surfaces.md)");
  }
  if (a.landmarks) throw InputError("--landmarks: not supported for open surfaces yet");
  if (!a.initial_out.empty()) throw InputError("--initial-out: open surfaces have no initial map");
  if (!a.quiet) std::cerr << "surfmap: open surfaces, " << src.topology.describe() << "\n";
  const OpenMapResult r = open_surface_map(src.intake.mesh, src.topology, dst.intake.mesh, dst.topology);
  const SurfaceMapResult& m = r.map;

  RowMatrixX3d morph(src.intake.mesh.num_vertices(), 3);
  for (int i = 0; i < morph.rows(); ++i) morph.row(i) = m.forward[i].position.transpose();
  nlohmann::json notes = nlohmann::json::array();
  for (const auto* x : {&src, &dst})
    for (const auto& n : x->intake.info.notes) notes.push_back((x == &src ? "source: " : "target: ") + n);
  auto domain_json = [](const OpenConformalResult& d) {
    return nlohmann::json{{"modulus", d.modulus},          {"modulus_from_u", d.modulus_from_u},
                          {"modulus_from_theta", d.modulus_from_theta}, {"pole", d.pole},
                          {"centring_iterations", d.centring_iterations}, {"flipped_faces", d.flipped_faces},
                          {"degenerate_faces", d.degenerate_faces}};
  };
  const nlohmann::json report = {
      {"source", a.src},
      {"target", a.dst},
      {"genus", src.topology.genus},
      {"boundary_loops", src.topology.num_boundary_loops()},
      {"open",
       {{"domain", r.domain},
        {"rotation", r.rotation},
        {"extremal_dilatation", r.extremal_dilatation},
        {"ear_triangles", r.ear_triangles},
        {"ear_triangles_degenerate", r.ear_triangles_degenerate},
        {"source", domain_json(r.source_domain)},
        {"target", domain_json(r.target_domain)},
        {"description", m.candidates.empty() ? std::string() : m.candidates[0].description}}},
      {"converged", m.converged},
      {"energy", {{"final", m.final_energy}}},
      {"distortion", {{"mean", m.mean_dilatation}, {"max", m.max_dilatation}}},
      {"flipped_triangles", m.flipped_triangles},
      {"degenerate_triangles", m.degenerate_triangles},
      {"time_s", {{"total", m.total_time}}},
      {"notes", notes}};
  std::string corr;
  if (!a.correspondence.empty()) {
    std::ostringstream s;
    s << std::setprecision(17);
    for (const auto& p : m.forward)
      s << p.face << ' ' << p.barycentric[0] << ' ' << p.barycentric[1] << ' ' << p.barycentric[2] << '\n';
    corr = s.str();
  }
  write_obj(a.out, morph, src.intake.mesh.F);
  write_text_file(a.report, report.dump(2) + "\n");
  if (!a.correspondence.empty()) write_text_file(a.correspondence, corr);
  if (!a.quiet)
    std::cerr << "surfmap: mean dilatation " << m.mean_dilatation << ", max " << m.max_dilatation
              << ", flipped triangles " << m.flipped_triangles << ", " << m.total_time << " s\n";
  return true;
}

}  // namespace surfmap::cli
