// `surfmap map` for open pairs (see map_open.h).
#include <iostream>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "map_open.h"
#include "surfmap/error.h"
#include "surfmap/map/open_map.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/mesh/mesh_io.h"
#include "surfmap/mesh/open_surface.h"
#include "surfmap/verify/correspondence_file.h"

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
  if (!a.initial_out.empty()) throw InputError("--initial-out: open surfaces have no initial map");
  if (!a.quiet) std::cerr << "surfmap: open surfaces, " << src.topology.describe() << "\n";
  OpenMapOptions options;
  if (a.boundary_swap && !a.boundary_pairing.empty())
    throw InputError("--boundary-swap and --boundary-pairing: give one of them");
  // Beyond disks and annuli: through the doubles, in Python
  // (surfmap/open_double.py; docs/open_surfaces.md "Doubling"), which
  // writes the same files.
  const int g = src.topology.genus, b = src.topology.num_boundary_loops();
  if (!(g == 0 && (b == 1 || b == 2))) {
    std::vector<std::string> args = {a.src, a.dst, "--out", a.out, "--report", a.report};
    if (!a.correspondence.empty()) args.insert(args.end(), {"--correspondence", a.correspondence});
    if (a.quiet) args.push_back("--quiet");
    if (a.boundary_swap) args.push_back("--boundary-swap");
    args.insert(args.end(), {"--refine-rings", std::to_string(a.refine_rings), "--refine-levels",
                             std::to_string(a.refine_levels)});
    if (!a.reflection_solve) args.push_back("--no-reflection-solve");
    if (!a.landmarks.empty()) {
      read_landmarks(a.landmarks);  // the file's errors as for the other pairs
      args.insert(args.end(), {"--landmarks", a.landmarks});
    }
    if (!a.boundary_pairing.empty()) {
      std::string p;
      for (int k : a.boundary_pairing) p += (p.empty() ? "" : ",") + std::to_string(k);
      args.insert(args.end(), {"--boundary-pairing", p});
    }
    std::cout.flush();
    std::cerr.flush();
    exec_python_module("open_double", args);
  }
  options.swap_annulus_loops = a.boundary_swap;
  if (a.boundary_swap && src.topology.num_boundary_loops() != 2)
    throw InputError("--boundary-swap: only for annuli (2 boundary loops); the surfaces have " +
                     src.topology.describe() + "; use --boundary-pairing");
  options.boundary_pairing = a.boundary_pairing;
  if (!a.landmarks.empty()) options.landmarks = read_landmarks(a.landmarks);
  const OpenMapResult r = open_surface_map(src.intake.mesh, src.topology, dst.intake.mesh, dst.topology, options);
  const SurfaceMapResult& m = r.map;

  RowMatrixX3d morph(src.intake.mesh.num_vertices(), 3);
  for (int i = 0; i < morph.rows(); ++i) morph.row(i) = m.forward[i].position.transpose();
  nlohmann::json notes = nlohmann::json::array();
  for (const auto* x : {&src, &dst})
    for (const auto& n : x->intake.info.notes) notes.push_back((x == &src ? "source: " : "target: ") + n);
  // The one serializer (map/open_map.h), plus the files and intake notes.
  nlohmann::json report = to_json(r, options);
  report["source"] = a.src;
  report["target"] = a.dst;
  report["notes"] = notes;
  std::string corr;
  if (!a.correspondence.empty()) {
    // Forward lines, then the inverse section, as the closed maps write it
    // (verify/correspondence_file.h), so `surfmap verify` checks both ways.
    std::vector<SurfacePoint> forward, inverse;
    for (const auto& p : m.forward) forward.push_back({p.face, p.barycentric});
    for (const auto& p : m.inverse) inverse.push_back({p.face, p.barycentric});
    corr = correspondence_text(forward, inverse);
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
