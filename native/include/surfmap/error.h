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

/// A numerical solve did not reach its tolerance, or produced an invalid result.
struct SolveError : Error {
  using Error::Error;
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
