// synth draws from photomill's one portable generator (geometry/random.hpp) in its counter-based
// form: value k of Rng(seed) is splitmix64(splitmix64(seed) + k).
#pragma once

#include <cstdint>

#include "geometry/random.hpp"

namespace photomill::synth {

using geometry::splitmix64;

class Rng : public geometry::Rng {
public:
  explicit Rng(std::uint64_t seed) : geometry::Rng(geometry::Rng::counter(seed)) {}
};

}  // namespace photomill::synth
