// A minimal parallel loop: splits [0, n) into contiguous chunks, one per thread. Each chunk's
// body must touch only the items it owns (no shared counters; results go into per-item slots).
#pragma once

#include <algorithm>
#include <cstddef>
#include <exception>
#include <thread>
#include <vector>

namespace photomill::triangulate {

// Number of worker threads for `requested` (0: all hardware threads).
inline int thread_count(int requested) {
  if (requested > 0) return requested;
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

// Calls body(begin, end) on disjoint chunks covering [0, n). Rethrows the first exception.
template <typename Body>
void parallel_for(std::size_t n, int threads, const Body& body) {
  const std::size_t workers = std::min<std::size_t>(static_cast<std::size_t>(thread_count(threads)), std::max<std::size_t>(n / 64, 1));
  if (workers <= 1) {
    body(std::size_t{0}, n);
    return;
  }
  std::vector<std::thread> pool;
  std::vector<std::exception_ptr> errors(workers);
  const std::size_t chunk = (n + workers - 1) / workers;
  for (std::size_t w = 0; w < workers; ++w) {
    const std::size_t begin = w * chunk;
    const std::size_t end = std::min(n, begin + chunk);
    pool.emplace_back([&, w, begin, end] {
      try {
        if (begin < end) body(begin, end);
      } catch (...) {
        errors[w] = std::current_exception();
      }
    });
  }
  for (auto& t : pool) t.join();
  for (auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

}  // namespace photomill::triangulate
