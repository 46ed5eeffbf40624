// Memory guard: refuse a factorization or an eigenbasis run that would not fit in memory, before it
// starts, with a message that says what would fit, instead of letting the machine swap or the host
// application (Blender) be killed by the kernel's OOM killer.
//
// Available memory is the smallest of
//   * MemAvailable of /proc/meminfo (what can be allocated without swapping),
//   * the cgroup v2 limit minus current usage (/sys/fs/cgroup/memory.max - memory.current), for containers,
//   * the environment variable NFIELD_MEMORY_LIMIT_MB, if set (a cap chosen by the user; the tests use it).
// When none of them can be read the guard does not refuse anything.
#pragma once
#include <cstddef>
#include <string>

#include "nfield/errors.hpp"
#include "nfield/operators.hpp"

namespace nfield {

/// Not enough memory for a computation; the message says how much it needs, how much is available and
/// what would fit. Python: nfield._native.InsufficientMemory (a MemoryError).
struct MemoryLimitError : Error {
  using Error::Error;
};

/// Bytes that may still be allocated (see above); 0 if unknown.
std::size_t available_memory_bytes();

/// Fraction of the available memory a single computation may use: the rest stays for the host
/// application, the caches and the result conversions.
constexpr double kMemoryHeadroom = 0.85;

/// Throws MemoryLimitError("<what> needs X MB but only Y MB are available; <advice>") when
/// `bytes` > kMemoryHeadroom x available_memory_bytes().
void require_memory(std::size_t bytes, const std::string& what, const std::string& advice);

/// Bytes of a complex (std::complex<double>) Cholesky factor with `lnz` nonzeros, as reported by
/// CHOLMOD's symbolic analysis (cholmod_common::lnz), including the supernodal padding and workspace.
std::size_t cholesky_factor_bytes(double lnz, std::size_t n);

/// "123 MB" (for messages).
std::string megabytes(std::size_t bytes);

}  // namespace nfield
