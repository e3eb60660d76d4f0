#pragma once
// One-call uniformization (paper §IV-A, §V; DESIGN.md §2.2-2.5): system of
// loops -> discrete Ricci flow on the (refined) mesh -> isometric layout of
// the cut disk with its deck group. Genus 0 goes to the unit sphere
// (spherical.h), genus 1 to a flat torus (lattice, modulus τ), genus >= 2 to
// a hyperbolic surface (Fuchsian group in SU(1,1)).
#include <complex>
#include <functional>
#include <string>
#include <vector>

#include "surfmap/geometry/hyperbolic.h"
#include "surfmap/mesh/tri_mesh.h"
#include "surfmap/topology/system_of_loops.h"
#include "surfmap/uniformize/layout.h"
#include "surfmap/uniformize/ricci_flow.h"
#include "surfmap/uniformize/spherical.h"

namespace surfmap {

struct UniformizeOptions {
  /// Discrete conformal scheme (default vertex scaling / discrete Yamabe).
  RicciScheme scheme = RicciScheme::VertexScaling;
  /// Newton (default) or the paper's explicit flow.
  RicciMethod method = RicciMethod::Newton;
  /// Max curvature error of the metric (default 1e-10).
  double tolerance = 1e-10;
  /// 0 (default): the solver's own limit.
  int max_iterations = 0;
  /// Base vertex of the loops (genus >= 1) / vertex sent to the pole
  /// (genus 0); -1 (default): chosen automatically.
  int base_vertex = -1;
  /// Called per flow iteration with the max curvature error; return false to
  /// cancel (throws Cancelled).
  std::function<bool(int iteration, double residual)> progress;
  LayoutOptions layout;
};

struct UniformizeResult {
  int genus = 0;
  /// "spherical" (genus 0), "flat" (genus 1) or "hyperbolic" (genus >= 2).
  std::string kind;
  bool converged = false;
  int iterations = 0;
  double max_curvature_error = 0;
  std::vector<double> residual_history;
  /// Area in the uniformization metric before any normalisation: flat, the
  /// area of the fundamental domain; hyperbolic, 4π(g−1) up to the
  /// tolerance; spherical, 4π.
  double area = 0;
  double time_s = 0;
  /// Genus 1: lattice vectors (loop generators a, b), τ = ω2/ω1 with Im τ > 0
  /// and τ reduced to the modular fundamental domain (modulus.sl2z).
  TorusModulus modulus;
  Complex tau, tau_reduced;
  /// Genus >= 2: the 2g loop generators (layout.h conventions) and the
  /// distance of the boundary-word product from ±identity.
  std::vector<hyperbolic::Mobius> generators;
  double product_relation_error = 0;
  DiskLayout layout;
  /// The loops' mesh (refined further when the fixed-connectivity metric did
  /// not exist: refinement_splits exact splits, uniformize/feasible_metric.h).
  SystemOfLoops loops;
  int refinement_splits = 0;
  RicciFlowResult ricci;
  /// Genus 0: #V positions on the unit sphere (input vertex order).
  SphericalUniformization sphere;
};

/// mesh: closed, manifold, outward-oriented (after intake). Throws
/// SolveError (with the solver's message) when the metric does not converge
/// or the layout is inconsistent; never reports an unconverged result as a
/// success.
UniformizeResult uniformize(const TriMesh& mesh, const UniformizeOptions& options = {});

}  // namespace surfmap
