// libFuzzer entry point for one target, chosen at compile time (PHOTOMILL_FUZZ_TARGET), so each
// harness is its own executable with its own corpus. Built only with clang (scripts/fuzz.sh).
#include <cstddef>
#include <cstdint>
#include <string>

#include "formats/error.hpp"
#include "tests/fuzz/targets.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const photomill::fuzz::Target* target = photomill::fuzz::find_target(PHOTOMILL_FUZZ_TARGET);
  try {
    target->run(std::string(reinterpret_cast<const char*>(data), size));
  } catch (const photomill::InputError&) {
    // The expected answer to bad input.
  }
  return 0;
}
