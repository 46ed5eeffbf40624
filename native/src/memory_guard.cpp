#include "nfield/memory_guard.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

namespace nfield {
namespace {

constexpr std::size_t kUnknown = std::numeric_limits<std::size_t>::max();

std::size_t meminfo_available() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  std::size_t value = 0;
  std::string unit;
  while (in >> key >> value) {
    std::getline(in, unit);
    if (key == "MemAvailable:") return value * 1024;  // kB
  }
  return kUnknown;
}

std::size_t read_number(const char* path) {
  std::ifstream in(path);
  std::string s;
  if (!(in >> s) || s == "max") return kUnknown;
  try {
    return static_cast<std::size_t>(std::stoull(s));
  } catch (...) {
    return kUnknown;
  }
}

std::size_t cgroup_available() {
  const std::size_t limit = read_number("/sys/fs/cgroup/memory.max");
  if (limit == kUnknown) return kUnknown;
  const std::size_t used = read_number("/sys/fs/cgroup/memory.current");
  if (used == kUnknown) return limit;
  return limit > used ? limit - used : 0;
}

std::size_t user_limit() {
  const char* env = std::getenv("NFIELD_MEMORY_LIMIT_MB");
  if (env == nullptr || *env == '\0') return kUnknown;
  char* end = nullptr;
  const double mb = std::strtod(env, &end);
  if (end == env || !(mb >= 0) || !std::isfinite(mb)) return kUnknown;  // unparsable: ignored
  return static_cast<std::size_t>(mb * 1024.0 * 1024.0);
}

}  // namespace

std::size_t available_memory_bytes() {
  const std::size_t a = std::min({meminfo_available(), cgroup_available(), user_limit()});
  return a == kUnknown ? 0 : a;
}

std::string megabytes(std::size_t bytes) {
  std::ostringstream s;
  s << static_cast<long long>(std::ceil(static_cast<double>(bytes) / (1024.0 * 1024.0))) << " MB";
  return s.str();
}

void require_memory(std::size_t bytes, const std::string& what, const std::string& advice) {
  const std::size_t available = available_memory_bytes();
  if (available == 0) return;  // unknown: do not guess
  const double budget = kMemoryHeadroom * static_cast<double>(available);
  if (static_cast<double>(bytes) <= budget) return;
  throw MemoryLimitError(what + " needs about " + megabytes(bytes) + " of memory but only " +
                         megabytes(static_cast<std::size_t>(budget)) + " are available" +
                         (advice.empty() ? std::string() : "; " + advice));
}

std::size_t cholesky_factor_bytes(double lnz, std::size_t n) {
  // lnz excludes the zeros a supernodal factorization adds when it merges columns (typically 10-40%);
  // 1.5x covers that and the integer structure. Plus CHOLMOD's dense workspace (a few vectors of n).
  const double bytes = 1.5 * std::max(lnz, 0.0) * sizeof(std::complex<double>) + 64.0 * static_cast<double>(n);
  return static_cast<std::size_t>(bytes);
}

}  // namespace nfield
