#pragma once
// One exception hierarchy for the whole core. Python sees InputError as
// surfmap.InputError (a ValueError), SolveError as surfmap.SolveError (a
// RuntimeError), UniformizationError as surfmap.UniformizationError (a
// SolveError), Cancelled as surfmap.Cancelled; all derive from surfmap.Error.
#include <stdexcept>
#include <string>

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

/// The user's progress callback asked to stop.
struct Cancelled : Error {
  using Error::Error;
};

}  // namespace surfmap
