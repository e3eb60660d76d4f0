#pragma once
// The optimal map between two open surfaces of the same topology (issue 16;
// docs/open_surfaces.md). Supported: disks (genus 0, 1 boundary loop) and
// annuli (genus 0, 2 boundary loops).
//  - Disks: source and target are mapped conformally onto the unit disk and
//    area-centred (map/open_conformal.h); the map is the source's map
//    composed with the rotation of the disk that best aligns the shapes and
//    the target's inverse: conformal (D' -> 1 with refinement), the harmonic
//    energy equals the target's area for every such map, so like the genus-0
//    sphere case the remaining automorphism is fixed by the alignment.
//  - Annuli: both are mapped onto flat cylinders R/Z x [0, m]; the map is the
//    affine stretch (x, y) -> (x + c, y m_t / m_s) (boundary loop i -> loop
//    i, or swapped on request), the Teichmüller extremal map with constant
//    dilatation max(m_t/m_s, m_s/m_t), the shift c chosen by the alignment.
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "surfmap/map/ear_images.h"
#include "surfmap/map/open_conformal.h"
#include "surfmap/map/surface_map.h"
#include "surfmap/mesh/open_surface.h"

namespace surfmap {

struct OpenMapOptions {
  /// Annuli: map the source's loop 0 (the longer) onto the target's loop 1
  /// instead of loop 0 (default false).
  bool swap_annulus_loops = false;
  /// Boundary loop correspondence by index: boundary_pairing[i] is the
  /// target loop (index into the target topology's boundary_loops) that the
  /// source's loop i maps onto; a permutation of 0..b-1. Empty (default):
  /// loop i -> loop i (longest onto longest), or as swap_annulus_loops.
  /// Annuli: {1, 0} is the swap (orientation kept).
  std::vector<int> boundary_pairing;
  /// Rotation (disk, radians) or shift (cylinder, in [0, 1)) of the map
  /// between the canonical domains; NaN (default): chosen by aligning the
  /// shapes (least squares between the source's vertices and their images,
  /// both normalised to centroid 0 and unit area, over 64 samples and a
  /// golden-section refinement).
  double rotation = std::numeric_limits<double>::quiet_NaN();
  /// Annuli: the Dehn twist about the core curve, in whole turns of loop 0
  /// relative to loop 1 (the cylinder map x -> x + twist y / height), where
  /// the search over twists starts (default 0). With `twist_search` (default
  /// true) the twist moves to a neighbour (twist +- 1) while the morph's
  /// Dirichlet energy decreases; the free-boundary harmonic map is the
  /// untwisted one (a twist adds energy ~ twist^2), so the search ends at 0
  /// from any start (docs/open_surfaces.md "Twists about the boundary
  /// loops"); false: `twist` is used as given. Disks have no twist.
  int twist = 0;
  bool twist_search = true;
  /// Source vertices used for the alignment (default 400, spread evenly).
  int alignment_samples = 400;
  /// Landmarks (source vertex, target vertex), held exactly where the
  /// canonical map's group allows (docs/open_surfaces.md, "Landmarks"):
  /// disk, up to 3 boundary points or 1 interior and at most 1 boundary
  /// point (else InputError); annulus, the shift (exact for one landmark;
  /// its height follows the stretch). They replace the alignment of what
  /// they pin; boundary landmarks must lie on the paired loops.
  std::vector<std::pair<int, int>> landmarks;
  OpenConformalOptions conformal;
};

struct OpenMapResult {
  /// forward / inverse (face + barycentrics on the other input mesh),
  /// dilatation (D' of each source face onto its corners' 3D images, the
  /// morph's triangles; mean and max without the ears, see below), flipped_triangles (source faces whose images in
  /// the target's canonical domain are flipped), final_energy (Dirichlet
  /// energy of the morph with the source's cotangent weights), genus 0.
  SurfaceMapResult map;
  OpenSurfaceTopology source_topology, target_topology;
  OpenConformalResult source_domain, target_domain;
  /// "disk" or "annulus"; the rotation / shift used; annuli: the analytic
  /// extremal dilatation max(m_t/m_s, m_s/m_t) of the affine stretch.
  std::string domain;
  double rotation = 0;
  double extremal_dilatation = 1;
  /// Annuli: the twist used (OpenMapOptions::twist) and every twist the
  /// search evaluated with the morph's Dirichlet energy, in order.
  int twist = 0;
  std::vector<std::pair<int, double>> twist_energies;
  /// The target loop of each source loop (as OpenMapOptions::boundary_pairing).
  std::vector<int> boundary_pairing;
  /// Largest 3D distance between a landmark's image and its target vertex.
  double landmark_error = 0;
  /// Source faces with all three corners on the boundary ("ears"): their
  /// image is fixed by the boundary correspondence alone (annulus: three
  /// points on a straight boundary line of the cylinder, degenerate). Their
  /// D' is kept in map.dilatation but left out of the mean and max;
  /// `ear_triangles_degenerate` of them have a zero-area image in the
  /// target's domain (not counted as flipped).
  int ear_triangles = 0, ear_triangles_degenerate = 0;
  /// Ears of the source (forward map) and of the target (inverse map) whose
  /// chord images turned over, and how many of them had their middle
  /// corner's image slid along the other boundary (map/ear_images.h).
  EarImagesResult forward_ears, inverse_ears;
};

/// Maps `source` onto `target` (both passed through load_open_mesh or
/// intake_open; topologies from open_surface_topology). Throws InputError
/// naming (g, b) of both when they differ or are not (0, 1) or (0, 2).
OpenMapResult open_surface_map(const TriMesh& source, const OpenSurfaceTopology& source_topology,
                               const TriMesh& target, const OpenSurfaceTopology& target_topology,
                               const OpenMapOptions& options = {});

/// The report of an open map: the closed map's report (map/map_report.h,
/// to_json of result.map, with "method" "open") plus "boundary_loops", the
/// (g, b) of both sides ("source_topology" / "target_topology": {genus,
/// boundary_loops, description}) and an "open" block (domain, rotation,
/// extremal_dilatation, boundary_pairing, ears, both canonical domains).
/// The CLI's --report and the Python result dict are this JSON.
nlohmann::json to_json(const OpenMapResult& result, const OpenMapOptions& options);

}  // namespace surfmap
