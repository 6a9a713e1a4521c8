// photomill's one fork-join loop, in two schedules over one worker launcher:
//   parallel_blocks: contiguous blocks fixed in advance, each with its block index, for work whose
//     per-block partial results (sums) must be combined in a fixed order (deterministic output);
//   parallel_for: items handed out one at a time through an atomic index, for items of uneven
//     cost that each write only their own result slot.
// Worker 0 runs on the calling thread; an exception is rethrown in the caller after every worker
// has joined.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <thread>
#include <vector>

namespace photomill::geometry {

// The number of worker threads for `requested` (0: every hardware thread), at least 1.
inline int thread_count(int requested) {
  if (requested > 0) return requested;
  const unsigned hw = std::thread::hardware_concurrency();
  return hw == 0 ? 1 : static_cast<int>(hw);
}

// Runs task(worker) for worker in [0, workers), worker 0 on the calling thread; rethrows the
// first exception (in worker order) after all have joined.
template <typename Task>
void run_workers(int workers, Task&& task) {
  workers = std::max(1, workers);
  if (workers == 1) {
    task(0);
    return;
  }
  const auto w = static_cast<std::size_t>(workers);
  std::vector<std::exception_ptr> errors(w);
  auto guarded = [&](std::size_t k) {
    try {
      task(static_cast<int>(k));
    } catch (...) {
      errors[k] = std::current_exception();
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(w - 1);
  for (std::size_t k = 1; k < w; ++k) pool.emplace_back(guarded, k);
  guarded(0);
  for (auto& t : pool) t.join();
  for (auto& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

// Number of blocks parallel_blocks uses for n items: thread_count(threads), but never more than
// one per `min_block` items, so small inputs stay on the calling thread.
inline int block_count(std::size_t n, int threads, std::size_t min_block) {
  const std::size_t by_size = std::max<std::size_t>(1, n / std::max<std::size_t>(1, min_block));
  return static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(thread_count(threads)), by_size));
}

// Calls body(begin, end, block) on the block_count(n, threads, min_block) blocks
// [n k / w, n (k + 1) / w) covering [0, n), one per worker.
template <typename Body>
void parallel_blocks(std::size_t n, int threads, std::size_t min_block, Body&& body) {
  const int w = block_count(n, threads, min_block);
  const auto ws = static_cast<std::size_t>(w);
  run_workers(w, [&](int k) {
    const auto ks = static_cast<std::size_t>(k);
    body(n * ks / ws, n * (ks + 1) / ws, k);
  });
}

// Calls fn(i) for every i in [0, n) on up to thread_count(threads) workers, items handed out in
// order one at a time. After an item throws no further items are handed out; the error rethrown
// is that of the lowest item index that threw, which (items being handed out in order) is the
// first failing item whatever the threads' timing.
template <typename Fn>
void parallel_for(std::size_t n, int threads, Fn&& fn) {
  const auto workers = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(thread_count(threads)), n));
  if (workers <= 1) {
    for (std::size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  std::atomic<std::size_t> next{0};
  std::vector<std::size_t> failed_at(static_cast<std::size_t>(workers), n);
  std::vector<std::exception_ptr> failure(static_cast<std::size_t>(workers));
  run_workers(workers, [&](int w) {
    const auto ws = static_cast<std::size_t>(w);
    for (std::size_t i = next.fetch_add(1); i < n; i = next.fetch_add(1)) {
      try {
        fn(i);
      } catch (...) {
        next.store(n);  // stop handing out work
        failed_at[ws] = i;
        failure[ws] = std::current_exception();
        return;
      }
    }
  });
  std::size_t first = 0;
  for (std::size_t w = 1; w < failed_at.size(); ++w) {
    if (failed_at[w] < failed_at[first]) first = w;
  }
  if (failure[first]) std::rethrow_exception(failure[first]);
}

}  // namespace photomill::geometry
