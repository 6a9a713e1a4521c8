// The fork-join loop: every item once, blocks fixed and ordered, the first exception rethrown.
#include <atomic>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

#include "geometry/parallel.hpp"
#include "geometry/random.hpp"

namespace photomill::geometry {
namespace {

TEST(Parallel, ForVisitsEveryItemOnce) {
  for (int threads : {0, 1, 2, 7}) {
    for (std::size_t n : {0u, 1u, 5u, 1000u}) {
      std::vector<std::atomic<int>> seen(n);
      parallel_for(n, threads, [&](std::size_t i) { ++seen[i]; });
      for (std::size_t i = 0; i < n; ++i) EXPECT_EQ(seen[i].load(), 1) << threads << " " << n << " " << i;
    }
  }
}

TEST(Parallel, BlocksAreContiguousAndIndexedInOrder) {
  const std::size_t n = 10007;
  for (int threads : {1, 2, 3, 8}) {
    const int w = block_count(n, threads, 100);
    EXPECT_EQ(w, threads);
    std::vector<std::pair<std::size_t, std::size_t>> range(static_cast<std::size_t>(w));
    parallel_blocks(n, threads, 100, [&](std::size_t b, std::size_t e, int k) { range[static_cast<std::size_t>(k)] = {b, e}; });
    std::size_t next = 0;
    for (const auto& [b, e] : range) {
      EXPECT_EQ(b, next);
      EXPECT_GE(e, b);
      next = e;
    }
    EXPECT_EQ(next, n);
  }
  // Small inputs stay on one block.
  EXPECT_EQ(block_count(99, 8, 100), 1);
  EXPECT_EQ(block_count(250, 8, 100), 2);
}

TEST(Parallel, RethrowsTheFirstErrorAfterJoining) {
  std::atomic<int> done{0};
  EXPECT_THROW(parallel_for(100, 4,
                            [&](std::size_t i) {
                              if (i == 3) throw std::runtime_error("item 3");
                              ++done;
                            }),
               std::runtime_error);
  EXPECT_LT(done.load(), 100);
  EXPECT_THROW(parallel_blocks(1000, 3, 1, [&](std::size_t, std::size_t, int k) {
    if (k == 2) throw std::invalid_argument("block 2");
  }), std::invalid_argument);
}

TEST(Random, IsSplitMix64InBothOfItsSeedings) {
  // The first values as splitmix64 (Steele, Lea, Flood 2014) defines them: a change here changes
  // every synthetic scene and test data set.
  Rng a(1), b(1), c(2);
  const std::uint64_t first = a.next();
  EXPECT_EQ(first, splitmix64(1));                        // mix(seed + gamma)
  EXPECT_EQ(a.next(), splitmix64(1 + Rng::kGoldenGamma));  // mix(seed + 2 gamma)
  EXPECT_EQ(b.next(), first);
  EXPECT_NE(c.next(), first);
  Rng k = Rng::counter(5);
  for (std::uint64_t i = 0; i < 4; ++i) EXPECT_EQ(k.next(), splitmix64(splitmix64(5) + i)) << i;
  double sum = 0, sq = 0;
  Rng r(7);
  for (int i = 0; i < 20000; ++i) {
    const double z = r.normal();
    sum += z;
    sq += z * z;
  }
  EXPECT_NEAR(sum / 20000, 0, 0.03);
  EXPECT_NEAR(sq / 20000, 1, 0.03);
  for (int i = 0; i < 1000; ++i) {
    const double u = r.uniform(2, 3);
    EXPECT_GE(u, 2);
    EXPECT_LT(u, 3);
    EXPECT_LT(r.index(7), 7u);
  }
}

}  // namespace
}  // namespace photomill::geometry
