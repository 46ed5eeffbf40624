// A minimal assertion helper for the native unit tests. No test framework: every native/tests/*.cpp is
// one executable (CMakeLists.txt) whose exit status ctest reads. A failed check prints where and why and
// the test carries on; run() catches an exception escaping a case (a failure too); finish() returns the
// exit status. With NFIELD_TEST_VERBOSE=1 in the environment every CHECK_LE prints its value and bound
// (to see the margins of the tolerances).
#pragma once
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

namespace nfield::test {

inline int& failure_count() {
  static int count = 0;
  return count;
}

inline void fail(const char* file, int line, const std::string& what) {
  ++failure_count();
  std::printf("FAIL %s:%d: %s\n", file, line, what.c_str());
  std::fflush(stdout);
}

/// Runs one test case; an exception escaping it counts as a failure.
template <class Case>
void run(const char* name, Case&& test_case) {
  const int before = failure_count();
  try {
    test_case();
  } catch (const std::exception& e) {
    fail(name, 0, std::string("unexpected exception: ") + e.what());
  }
  std::printf("%s %s\n", failure_count() == before ? "ok  " : "FAILED", name);
  std::fflush(stdout);
}

/// Exit status of the test executable: 0 if every check passed.
inline int finish() {
  if (failure_count() > 0) std::printf("%d check(s) failed\n", failure_count());
  return failure_count() > 0 ? 1 : 0;
}

inline bool verbose() {
  static const bool on = std::getenv("NFIELD_TEST_VERBOSE") != nullptr;
  return on;
}

inline std::string number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", x);
  return buf;
}

}  // namespace nfield::test

/// CHECK(condition): the condition must hold.
#define CHECK(cond)                                                                                   \
  do {                                                                                                \
    if (!(cond)) ::nfield::test::fail(__FILE__, __LINE__, "CHECK(" #cond ")");                        \
  } while (0)

/// CHECK_LE(value, bound): value <= bound (both printed on failure; NaN fails).
#define CHECK_LE(value, bound)                                                                        \
  do {                                                                                                \
    const double nfield_v_ = (value), nfield_b_ = (bound);                                            \
    if (::nfield::test::verbose())                                                                    \
      std::printf("  %s:%d: %s = %.3g <= %.3g\n", __FILE__, __LINE__, #value, nfield_v_, nfield_b_);  \
    if (!(nfield_v_ <= nfield_b_))                                                                    \
      ::nfield::test::fail(__FILE__, __LINE__,                                                        \
                           #value " = " + ::nfield::test::number(nfield_v_) + " exceeds " #bound " = " + \
                               ::nfield::test::number(nfield_b_));                                    \
  } while (0)

/// CHECK_EQ(a, b): exact equality of two integers (printed on failure).
#define CHECK_EQ(a, b)                                                                                \
  do {                                                                                                \
    const long long nfield_a_ = (a), nfield_b_ = (b);                                                 \
    if (nfield_a_ != nfield_b_)                                                                       \
      ::nfield::test::fail(__FILE__, __LINE__,                                                        \
                           #a " = " + std::to_string(nfield_a_) + " != " #b " = " + std::to_string(nfield_b_)); \
  } while (0)

/// CHECK_THROWS(Type, "part of the message", statement...): the statement throws Type whose what()
/// contains the given text (the statement comes last so that it may contain commas).
#define CHECK_THROWS(Type, text, ...)                                                                 \
  do {                                                                                                \
    bool nfield_thrown_ = false;                                                                      \
    try {                                                                                             \
      __VA_ARGS__;                                                                                    \
    } catch (const Type& e) {                                                                         \
      nfield_thrown_ = true;                                                                          \
      if (std::string(e.what()).find(text) == std::string::npos)                                      \
        ::nfield::test::fail(__FILE__, __LINE__,                                                      \
                             std::string(#Type " message '") + e.what() + "' lacks '" + (text) + "'"); \
    }                                                                                                 \
    if (!nfield_thrown_) ::nfield::test::fail(__FILE__, __LINE__, #__VA_ARGS__ " did not throw " #Type); \
  } while (0)
