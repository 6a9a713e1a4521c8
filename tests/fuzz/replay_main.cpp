// Replays a fuzz corpus through one target without libFuzzer (any compiler, any build), so ctest
// checks every seed and every past crash input on every run:
//   fuzz_replay TARGET DIR...
// Files named "valid-*" must be accepted; every other file may be rejected, but only with an
// InputError, and each must be answered within --max-seconds (default 30). The limit catches an
// input that hangs a reader, it does not measure speed: under a sanitizer a CAD reader's child
// process that crashes symbolizes its report (about 2 s on tests/fuzz/corpus/step/crash-fffe...),
// and a loaded CI machine may take several times that.
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "formats/error.hpp"
#include "tests/fuzz/targets.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::cerr << "usage: fuzz_replay TARGET DIR... [--max-seconds S]\n";
    return 2;
  }
  const auto* target = photomill::fuzz::find_target(argv[1]);
  if (target == nullptr) {
    std::cerr << "fuzz_replay: unknown target '" << argv[1] << "'\n";
    return 2;
  }
  double max_seconds = 30.0;
  std::vector<std::filesystem::path> files;
  for (int a = 2; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--max-seconds" && a + 1 < argc) {
      max_seconds = std::stod(argv[++a]);
      continue;
    }
    if (std::filesystem::is_directory(arg)) {
      for (const auto& e : std::filesystem::directory_iterator(arg)) files.push_back(e.path());
    } else {
      files.emplace_back(arg);
    }
  }
  int failures = 0;
  int accepted = 0;
  int rejected = 0;
  for (const auto& f : files) {
    std::ifstream in(f, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    const bool must_accept = f.filename().string().rfind("valid-", 0) == 0;
    const auto start = std::chrono::steady_clock::now();
    try {
      target->run(s.str());
      ++accepted;
    } catch (const photomill::InputError& e) {
      ++rejected;
      if (must_accept) {
        std::cerr << f << ": rejected a valid seed: " << e.what() << "\n";
        ++failures;
      }
    } catch (const std::exception& e) {
      std::cerr << f << ": threw something other than InputError: " << e.what() << "\n";
      ++failures;
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (seconds > max_seconds) {
      std::cerr << f << ": took " << seconds << " s (limit " << max_seconds << " s)\n";
      ++failures;
    }
  }
  std::cout << argv[1] << ": " << files.size() << " inputs, " << accepted << " accepted, " << rejected
            << " rejected with InputError\n";
  if (files.empty()) {
    std::cerr << "fuzz_replay: no inputs\n";
    return 1;
  }
  std::cout << (files.size() - static_cast<std::size_t>(failures)) << " passed, " << failures << " failed\n";
  return failures == 0 ? 0 : 1;
}
