// A minimal fork-join loop for fitsurf's per-point work (basis rows, normal equations, foot
// points). Each worker gets one contiguous block and its worker index, so callers keep
// per-worker partial sums and combine them after the join: no shared counters, no locks.
#pragma once

#include <algorithm>
#include <cstddef>
#include <exception>
#include <thread>
#include <vector>

namespace photomill::fitsurf {

// The number of workers to use: `requested`, or every hardware thread when it is 0.
inline int resolve_threads(int requested) {
  if (requested > 0) return requested;
  const unsigned hw = std::thread::hardware_concurrency();
  return hw == 0 ? 1 : static_cast<int>(hw);
}

// Number of workers parallel_for will actually start for n items (never more than one per
// `min_block` items, so small inputs stay on the calling thread).
inline int worker_count(std::size_t n, int threads, std::size_t min_block = 2048) {
  const std::size_t by_size = std::max<std::size_t>(1, n / std::max<std::size_t>(1, min_block));
  return static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(resolve_threads(threads)), by_size));
}

// Calls body(begin, end, worker) on `workers` contiguous blocks covering [0, n), worker 0 on the
// calling thread. The first exception thrown by a block is rethrown after all have joined.
template <typename Body>
void parallel_for(std::size_t n, int workers, Body&& body) {
  workers = std::max(1, workers);
  if (workers == 1 || n == 0) {
    body(std::size_t{0}, n, 0);
    return;
  }
  const std::size_t w = static_cast<std::size_t>(workers);
  std::vector<std::exception_ptr> errors(w);
  auto block = [&](std::size_t k) {
    try {
      body(n * k / w, n * (k + 1) / w, static_cast<int>(k));
    } catch (...) {
      errors[k] = std::current_exception();
    }
  };
  std::vector<std::thread> threads;
  threads.reserve(w - 1);
  for (std::size_t k = 1; k < w; ++k) threads.emplace_back(block, k);
  block(0);
  for (auto& t : threads) t.join();
  for (auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

}  // namespace photomill::fitsurf
