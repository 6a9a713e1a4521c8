// photomill's one random generator: the same numbers on every platform and standard library
// (std::normal_distribution and friends are implementation-defined), counter-based so that a
// parallel loop can give item k its own stream Rng(seed + k) and draw the same values whatever
// the thread count. For RANSAC samples, synthetic scenes and test data; not for cryptography.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>

namespace photomill::geometry {

// SplitMix64 finaliser (Steele, Lea, Flood 2014): a bijective 64-bit mix.
inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// A small sequential generator on top of splitmix64.
class Rng {
public:
  explicit Rng(std::uint64_t seed) : state_(splitmix64(seed)) {}
  std::uint64_t next() { return splitmix64(state_++); }
  // Uniform in [0, 1).
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // An index in [0, n), n > 0 (modulo bias below 2^-40 for n < 2^24).
  std::size_t index(std::size_t n) { return static_cast<std::size_t>(next() % n); }
  // Standard normal (Box-Muller).
  double normal() {
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }

private:
  std::uint64_t state_;
};

}  // namespace photomill::geometry
