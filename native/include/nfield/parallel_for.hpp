#pragma once
// Splitting a loop of independent iterations over the two cores this tool is built for.

#include <exception>
#include <thread>

namespace nfield {

/// Runs body(i) for every i in [0, n): on two threads (the calling one and one more), each over one
/// contiguous half, when n is at least 2 * min_per_thread and the machine has more than one core;
/// otherwise on the calling thread. body(i) must write only what belongs to i (its own output slot), so
/// the result is the same as the sequential loop's, bit for bit, whatever the split. An exception thrown
/// by either half is rethrown on the calling thread after both halves have finished (the first half's
/// first).
template <class Body>
void parallel_for(int n, Body&& body, int min_per_thread = 1024) {
  if (n < 2 * min_per_thread || std::thread::hardware_concurrency() < 2) {
    for (int i = 0; i < n; ++i) body(i);
    return;
  }
  const int half = n / 2;
  std::exception_ptr first_error, second_error;
  std::thread second([&] {
    try {
      for (int i = half; i < n; ++i) body(i);
    } catch (...) {
      second_error = std::current_exception();
    }
  });
  try {
    for (int i = 0; i < half; ++i) body(i);
  } catch (...) {
    first_error = std::current_exception();
  }
  second.join();
  if (first_error) std::rethrow_exception(first_error);
  if (second_error) std::rethrow_exception(second_error);
}

}  // namespace nfield
