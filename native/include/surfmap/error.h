#pragma once
// One exception hierarchy for the whole core. Python sees InputError as
// surfmap.InputError (a ValueError), SolveError as surfmap.SolveError (a
// RuntimeError), Cancelled as surfmap.Cancelled; all derive from surfmap.Error.
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

/// The user's progress callback asked to stop.
struct Cancelled : Error {
  using Error::Error;
};

}  // namespace surfmap
