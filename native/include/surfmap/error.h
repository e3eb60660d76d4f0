#pragma once
// One exception hierarchy for the whole core. Python sees InputError as
// surfmap.InputError (a ValueError), SolveError as surfmap.SolveError (a
// RuntimeError), UniformizationError as surfmap.UniformizationError (a
// SolveError), SingleChartError as surfmap.SingleChartError (a SolveError),
// Cancelled as surfmap.Cancelled; all derive from surfmap.Error.
#include <stdexcept>
#include <string>
#include <utility>

namespace surfmap {

/// Base of every error the core throws on purpose.
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The input is unusable; the message names the problem and the offending
/// element (vertex, edge or face index).
struct InputError : Error {
  using Error::Error;
};

/// Why a SolveError was thrown, for callers that act on the kind of failure
/// (the map's automatic retries, map/surface_map.cpp) instead of reading
/// messages, whose wording may change.
enum class SolveFailure {
  /// Any other failure.
  unspecified,
  /// A harmonic map solve refused its start: an edge starts longer than the
  /// solve's start-edge limit (HyperbolicHarmonicOptions::max_start_edge_size),
  /// or a map failed in every class and some solve of its run was refused so.
  start_edges,
  /// The map folds: flipped or degenerate image triangles in the class
  /// mapped ("the optimised map has N flipped ..."). A default-class run
  /// that fails so is made again by the retry after folds
  /// (LoopOptions::fold_fallback; map/surface_map.cpp reads `is_fold_failure`).
  folds,
  /// A default-class run mapped two or more candidate classes and none gave
  /// a bijective map ("no candidate class gave a bijective map ..."; the
  /// last ones may have been refused on their solves). A kind of folds
  /// (`is_fold_failure`: the retry after folds reads it too); the one reason that
  /// starts the two-way run's rescue by the other direction
  /// (map/surface_map.cpp; docs/handle_classes.md "The two directions
  /// today"), which a single class's fold does not start.
  no_bijective_class,
};

/// Whether a failure of this reason means the map folds (folds,
/// no_bijective_class).
inline bool is_fold_failure(SolveFailure why) {
  return why == SolveFailure::folds || why == SolveFailure::no_bijective_class;
}

/// A numerical solve did not reach its tolerance, or produced an invalid result.
/// `reason()` says which kind of failure when the thrower knows it.
struct SolveError : Error {
  explicit SolveError(const std::string& message, SolveFailure why = SolveFailure::unspecified)
      : Error(message), reason_(why) {}
  SolveFailure reason() const { return reason_; }

 private:
  SolveFailure reason_;
};

/// A uniformization metric could not be delivered: the flow did not converge
/// (on the fixed connectivity: the metric does not exist on these edges), or
/// its layout is inconsistent (flipped triangles, deck maps that disagree).
/// Thrown by uniformize() and by the map's target uniformization, so that a
/// caller choosing between metrics (SurfaceMapOptions::uniformization.
/// target_metric, docs/uniformization.md "Which target metric runs") catches
/// this type instead of reading messages.
struct UniformizationError : SolveError {
  using SolveError::SolveError;
};

/// A hyperbolic metric exists and its layout is valid (checked in per-face
/// charts), but the fundamental domain reaches so far from the centre of
/// the Poincare disk that double coordinates in the one chart the map reads
/// (location, harmonic map) cannot resolve its triangles: CAD plates of
/// genus 13 .. 24 (docs/robustness.md). The distance is a property of the
/// surface's metric, so no other metric path helps: the map stops here
/// instead of falling back (a SolveError, not a UniformizationError, so
/// that callers choosing between metrics do not catch it). `mesh`: "source"
/// or "target"; `layout_radius`: the domain's hyperbolic distance from the
/// centre.
struct SingleChartError : SolveError {
  SingleChartError(const std::string& message, std::string which, double radius)
      : SolveError(message), mesh(std::move(which)), layout_radius(radius) {}
  std::string mesh;
  double layout_radius = 0;
};

/// The user's progress callback asked to stop.
struct Cancelled : Error {
  using Error::Error;
};

}  // namespace surfmap
