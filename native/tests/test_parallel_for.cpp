// parallel_for (parallel_for.hpp): every index visited exactly once, on two threads when the loop is long
// enough and the machine has two cores; the result equals the sequential loop's; an exception thrown in
// either half reaches the caller after both halves finished.
#include <atomic>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "check.hpp"
#include "nfield/parallel_for.hpp"

using namespace nfield::test;

int main() {
  run("every index once, the same values as sequentially", [] {
    for (int n : {0, 1, 7, 2047, 2048, 100001}) {
      std::vector<int> visits(n, 0);
      std::vector<double> out(n), expected(n);
      for (int i = 0; i < n; ++i) expected[i] = 1.0 / (1.0 + i) + i * 1e-3;
      nfield::parallel_for(n, [&](int i) {
        ++visits[i];
        out[i] = 1.0 / (1.0 + i) + i * 1e-3;
      });
      for (int i = 0; i < n; ++i) {
        CHECK(visits[i] == 1);
        CHECK(out[i] == expected[i]);
      }
    }
  });
  run("two threads on a long loop (where the machine has two cores), one on a short one", [] {
    std::mutex lock;
    std::set<std::thread::id> long_loop, short_loop;
    nfield::parallel_for(100000, [&](int) {
      std::lock_guard<std::mutex> guard(lock);
      long_loop.insert(std::this_thread::get_id());
    });
    nfield::parallel_for(100, [&](int) {
      std::lock_guard<std::mutex> guard(lock);
      short_loop.insert(std::this_thread::get_id());
    });
    CHECK(long_loop.size() == (std::thread::hardware_concurrency() >= 2 ? 2u : 1u));
    CHECK(long_loop.count(std::this_thread::get_id()) == 1);
    CHECK(short_loop.size() == 1 && short_loop.count(std::this_thread::get_id()) == 1);
  });
  run("an exception in either half reaches the caller after both halves ran", [] {
    for (int bad : {10, 99990}) {
      std::atomic<int> done{0};
      bool caught = false;
      try {
        nfield::parallel_for(100000, [&](int i) {
          if (i == bad) throw std::runtime_error("bad index");
          ++done;
        });
      } catch (const std::runtime_error& e) {
        caught = std::string(e.what()) == "bad index";
      }
      CHECK(caught);
      // The half without the bad index ran to its end; the other stopped at it.
      const int half = 50000;
      const int expected = bad < half ? (100000 - half) + bad : half + (bad - half);
      CHECK(done.load() == (std::thread::hardware_concurrency() >= 2 ? expected : bad));
    }
  });
  return finish();
}
