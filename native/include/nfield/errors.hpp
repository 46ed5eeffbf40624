// Exception types of nfield. Every error the library raises derives from nfield::Error, so the Python
// binding can translate them: InputError -> ValueError, ParameterError -> ValueError,
// ConstraintError -> ValueError, SolverError -> RuntimeError, Cancelled -> KeyboardInterrupt-like.
#pragma once
#include <stdexcept>
#include <string>

namespace nfield {

/// Base of every exception nfield throws on purpose.
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};
/// Broken input data (mesh arrays, files): NaN/inf coordinates, out-of-range indices, parse errors.
struct InputError : Error {
  using Error::Error;
};
/// A parameter outside its admissible range (n < 1, order outside 1..4, strength <= 0, k too large ...).
struct ParameterError : Error {
  using Error::Error;
};
/// A constraint that cannot be imposed (face excluded or out of range, zero direction, index too large,
/// boundary vertex, contradictory or redundant set).
struct ConstraintError : Error {
  using Error::Error;
};
/// A numerical failure (factorization not positive definite, eigen solver did not converge ...).
struct SolverError : Error {
  using Error::Error;
};
/// A long computation was cancelled through its progress callback.
struct Cancelled : Error {
  using Error::Error;
};

}  // namespace nfield
