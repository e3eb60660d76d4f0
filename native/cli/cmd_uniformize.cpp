// surfmap uniformize MESH --report REPORT.json [--layout LAYOUT.obj]:
// the uniformization metric (docs/method.md §2.2-2.5) — sphere, flat torus
// (lattice, τ) or hyperbolic surface (Fuchsian generators) — with a JSON
// report and optionally the laid-out cut disk (or the sphere) as OBJ.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "commands.h"
#include "surfmap/error.h"
#include "surfmap/mesh/intake.h"
#include "surfmap/map/map_option_names.h"
#include "surfmap/mesh/mesh_io.h"
#include "surfmap/uniformize/uniformize.h"

namespace surfmap::cli {
namespace {

nlohmann::json cplx(Complex z) { return nlohmann::json::array({z.real(), z.imag()}); }

nlohmann::json mobius(const hyperbolic::Mobius& m) {
  return nlohmann::json::array({m.a.real(), m.a.imag(), m.b.real(), m.b.imag()});
}

struct Args {
  std::string mesh, report, layout, scheme = "yamabe", method = "newton", metric = "flips", loops = "auto";
  bool refine = false;
  int base_vertex = -1;
  double tolerance = 1e-10, floor_tolerance = 1e-7;
  bool quiet = false;
};

void run(const Args& a) {
  const IntakeResult in = load_mesh(a.mesh);
  UniformizeOptions opt;
  opt.scheme = a.scheme == "inversive" ? RicciScheme::InversiveDistance : RicciScheme::VertexScaling;
  opt.method = a.method == "flow" ? RicciMethod::GradientFlow : RicciMethod::Newton;
  opt.tolerance = a.tolerance;
  opt.metric = parse_enum<UniformizationMetric>(a.metric, "--metric");
  opt.loops = parse_enum<LoopMetric>(a.loops, "--loops");
  // The altitude-foot refinement of the fixed-connectivity path is opt-in.
  opt.fixed_connectivity_refinement = a.refine;
  opt.floor_tolerance = a.floor_tolerance;
  if (a.base_vertex >= in.mesh.num_vertices())
    throw InputError("--base-vertex " + std::to_string(a.base_vertex) + " is out of range (mesh has " +
                     std::to_string(in.mesh.num_vertices()) + " vertices)");
  opt.base_vertex = a.base_vertex;
  if (!a.quiet)
    opt.progress = [](int it, double residual) {
      std::cerr << "  iteration " << it << ": max curvature error " << residual << "\n";
      return true;
    };
  const UniformizeResult r = uniformize(in.mesh, opt);

  nlohmann::json j = {{"file", a.mesh},
                      {"vertices", in.mesh.num_vertices()},
                      {"faces", in.mesh.num_faces()},
                      {"flipped_on_input", in.flipped},
                      {"genus", r.genus},
                      {"kind", r.kind},
                      {"scheme", a.scheme},
                      {"method", a.method},
                      {"tolerance", a.tolerance},
                      {"converged", r.converged},
                      {"metric", r.metric},
                      {"edge_flips", r.edge_flips},
                      {"refinement_splits", r.refinement_splits},
                      {"iterations", r.iterations},
                      {"max_curvature_error", r.max_curvature_error},
                      {"stopped_at_floor", r.stopped_at_floor},
                      {"floor_estimate", r.floor_estimate},
                      {"floor_tolerance", a.floor_tolerance},
                      {"area", r.area},
                      {"time_s", r.time_s},
                      {"residual_history", r.residual_history},
                      {"notes", in.info.notes},
                      {"mollified_faces", in.info.mollified_faces},
                      {"mollify_epsilon", in.info.mollify_epsilon}};
  if (r.genus == 0) {
    j["removed_vertex"] = r.sphere.removed_vertex;
    j["flipped_faces"] = r.sphere.flipped_faces;
    j["input_flipped_faces"] = r.sphere.input_flipped_faces;
    j["ring_flips"] = r.sphere.ring_flips;
    j["simplicial_flips"] = r.sphere.simplicial_flips;
    j["centre_of_mass_norm"] = r.sphere.centre_of_mass_norm;
    j["centring_floor"] = r.sphere.centring_floor;
    j["centring_iterations"] = r.sphere.centring_iterations;
    j["centring_stopped_at_floor"] = r.sphere.centring_stopped_at_floor;
    j["centring_axial_only"] = r.sphere.centring_axial_only;
    j["circle_error"] = r.sphere.circle_error;
  } else {
    const DiskLayout& L = r.layout;
    j["base_vertex"] = r.loops.base_vertex;
    j["loop_metric"] = r.loop_metric;
    j["refined_vertices"] = r.loops.mesh.num_vertices();
    j["refined_faces"] = r.loops.mesh.num_faces();
    j["word"] = L.word;
    j["loop_edges"] = nlohmann::json::array();
    for (const auto& l : r.loops.loops) j["loop_edges"].push_back(static_cast<int>(l.size()) - 1);
    j["num_flipped"] = L.num_flipped;
    j["num_unresolved"] = L.num_unresolved;
    j["num_flipped_above_roundoff"] = L.num_flipped_above_roundoff;
    j["num_flipped_local"] = L.num_flipped_local;
    j["max_vertex_holonomy"] = L.max_vertex_holonomy;
    j["vertex_holonomy_tolerance"] = vertex_holonomy_tolerance(r.max_curvature_error);
    j["single_chart"] = r.single_chart;
    j["layout_checks"] = r.layout_checks;
    j["max_interior_mismatch"] = L.max_interior_mismatch;
    j["interior_roundoff"] = L.interior_roundoff;
    j["max_interior_excess"] = L.max_interior_excess;
    j["max_deck_inconsistency"] = L.max_deck_inconsistency;
    j["deck_roundoff"] = L.deck_roundoff;
    j["max_deck_excess"] = L.max_deck_excess;
    j["coordinate_roundoff"] = L.coordinate_roundoff;
    {
      // How far out the layout reaches: the largest hyperbolic distance of a
      // corner from 0 (flat: |z|), read off the face charts (DiskLayout::
      // layout_radius; the coordinates saturate at |z| = 1 beyond about 37),
      // and the smallest 1 − |z| of the coordinates (hyperbolic).
      double margin = 1;
      for (int f = 0; f < L.corners.rows(); ++f)
        for (int k = 0; k < 3; ++k) margin = std::min(margin, 1.0 - std::abs(L.corners(f, k)));
      j["layout_radius"] = L.layout_radius;
      if (r.genus >= 2) j["min_distance_to_unit_circle"] = margin;
    }
    j["max_corner_inconsistency"] = L.max_corner_inconsistency;
    j["corner_condition"] = L.corner_condition;
    j["gluing_tolerance"] = r.gluing_tolerance;
    j["product_relation_error"] = r.product_relation_error;
    j["layout_time_s"] = L.time_s;
    j["ricci_time_s"] = r.ricci.time_s;
    if (r.genus == 1) {
      j["tau"] = cplx(r.tau);
      j["tau_reduced"] = cplx(r.tau_reduced);
      j["sl2z"] = {r.modulus.sl2z[0], r.modulus.sl2z[1], r.modulus.sl2z[2], r.modulus.sl2z[3]};
      j["lattice"] = {cplx(r.modulus.omega1), cplx(r.modulus.omega2)};
      j["max_holonomy_rotation"] = L.max_holonomy_rotation;
    } else {
      j["generators"] = nlohmann::json::array();
      for (const auto& g : r.generators) j["generators"].push_back(mobius(g));
      j["side_pairings"] = nlohmann::json::array();
      for (const auto& g : L.side_pairings) j["side_pairings"].push_back(mobius(g));
      j["relation_condition"] = L.relation_condition;
    }
  }
  write_text_file(a.report, j.dump(2) + "\n");

  if (!a.layout.empty()) {
    if (r.genus == 0) {
      write_obj(a.layout, r.sphere.positions, in.mesh.F);
    } else {
      const DiskLayout& L = r.layout;
      // The cut disk is written in the one Poincaré chart; a layout checked
      // in per-face charts only has corners there without digits.
      if (!r.single_chart)
        throw InputError("--layout: the cut disk reaches " + std::to_string(L.layout_radius) +
                         " from the centre, beyond what double coordinates resolve (" + r.layout_checks +
                         "); the report is written, the layout is not");
      RowMatrixX3d V(static_cast<int>(L.disk_positions.size()), 3);
      for (int i = 0; i < V.rows(); ++i) V.row(i) << L.disk_positions[i].real(), L.disk_positions[i].imag(), 0.0;
      write_obj(a.layout, V, L.disk_faces);
    }
  }
  if (!a.quiet) {
    for (const auto& n : in.info.notes) std::cout << a.mesh << ": note: " << n << "\n";
    std::cout << a.mesh << ": genus " << r.genus << ", " << r.kind << ", " << r.iterations
              << " iterations, max curvature error " << r.max_curvature_error << ", area " << r.area << ", "
              << r.time_s << " s\n";
    if (r.genus == 1)
      std::cout << "  tau " << r.tau << ", reduced " << r.tau_reduced << "\n";
    else if (r.genus >= 2)
      std::cout << "  " << r.generators.size() << " generators, product relation error "
                << r.product_relation_error << "\n";
  }
}

}  // namespace

void register_uniformize(CLI::App& app) {
  auto* cmd = app.add_subcommand("uniformize",
                                 "Uniformization metric: sphere (genus 0), flat torus (genus 1) or "
                                 "hyperbolic surface (genus >= 2), with a JSON report");
  auto a = std::make_shared<Args>();
  cmd->add_option("MESH", a->mesh, "Closed triangle mesh (.obj, .off, .ply, .stl)")->required();
  cmd->add_option("--report", a->report, "Write the JSON report here")->required();
  cmd->add_option("--layout", a->layout,
                  "Write the laid-out cut disk (plane / Poincaré disk, z = 0) or, for genus 0, the "
                  "unit-sphere mesh as OBJ");
  cmd->add_option("--scheme", a->scheme, "yamabe (vertex scaling, default) or inversive (circle packing)")
      ->check(CLI::IsMember({"yamabe", "inversive"}));
  cmd->add_option("--method", a->method, "newton (default) or flow (the paper's explicit flow)")
      ->check(CLI::IsMember({"newton", "flow"}));
  cmd->add_option("--metric", a->metric,
                  "flips (default: Newton with intrinsic Delaunay / Ptolemy flips; a metric always exists; auto "
                  "is the same), fixed (the input connectivity, which can fail on slivers) or fixed-first (fixed, "
                  "flips when it fails; report: metric)")
      ->check(CLI::IsMember(enum_name_list<UniformizationMetric>()));
  cmd->add_flag("--refine", a->refine,
                "With --metric fixed: refine exactly (altitude-foot splits) when the metric does not exist");
  cmd->add_option("--loops", a->loops,
                  "Lengths the loops are shortest in (flip path, genus >= 2): auto (default: 3D, the metric when that "
                  "layout fails or crowds |z| = 1), embedding (3D) or metric (report: loop_metric)")
      ->check(CLI::IsMember(enum_name_list<LoopMetric>()));
  cmd->add_option("--base-vertex", a->base_vertex, "Base vertex of the loops (default: automatic)");
  cmd->add_option("--tolerance", a->tolerance, "Max curvature error (default 1e-10)");
  cmd->add_option("--floor-tolerance", a->floor_tolerance,
                  "Residual accepted when Newton stops at the floating-point floor above --tolerance "
                  "(default 1e-7; reported as stopped_at_floor)");
  cmd->add_flag("--quiet", a->quiet, "No progress or summary output");
  cmd->callback([a] { run(*a); });
}

}  // namespace surfmap::cli
