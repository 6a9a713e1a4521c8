// photomill's one random generator: the same numbers on every platform and standard library
// (std::normal_distribution and friends are implementation-defined), so RANSAC samples, synthetic
// scenes and test data are reproducible everywhere and whatever the thread count. Not for
// cryptography.
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

// SplitMix64 as Steele, Lea and Flood define it: a state advanced by an odd "gamma" and mixed by
// splitmix64's finaliser, value k = mix(state0 + k gamma).
class Rng {
public:
  static constexpr std::uint64_t kGoldenGamma = 0x9E3779B97F4A7C15ull;
  // The paper's generator (and Java's SplittableRandom's) from `seed`, with the golden gamma:
  // value k = mix(seed + (k + 1) gamma). fitsurf's RANSAC and test shapes draw from it.
  explicit Rng(std::uint64_t seed) : state_(seed), gamma_(kGoldenGamma) {}
  // The counter-based form synth's scenes are drawn with: value k = splitmix64(splitmix64(seed) + k),
  // so item k of a parallel loop can take its own stream from a seed of its own.
  static Rng counter(std::uint64_t seed) { return Rng(splitmix64(seed) + kGoldenGamma - 1, 1); }

  std::uint64_t next() {
    state_ += gamma_;
    std::uint64_t x = state_;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
  }
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
  Rng(std::uint64_t state, std::uint64_t gamma) : state_(state), gamma_(gamma) {}
  std::uint64_t state_;
  std::uint64_t gamma_;
};

}  // namespace photomill::geometry
