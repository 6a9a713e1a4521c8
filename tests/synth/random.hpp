// synth draws from photomill's one portable generator (geometry/random.hpp).
#pragma once

#include "geometry/random.hpp"

namespace photomill::synth {

using geometry::Rng;
using geometry::splitmix64;

}  // namespace photomill::synth
