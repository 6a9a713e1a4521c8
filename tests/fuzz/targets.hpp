// The fuzz targets: one per reader that takes input from outside. Each runs the reader on the
// bytes it is given; the reader may reject them only with photomill::InputError. Any other
// exception, a crash, a sanitizer report, a hang or a huge allocation is a bug.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace photomill::fuzz {

struct Target {
  const char* name;
  void (*run)(const std::string& data);
};

const std::vector<Target>& targets();
const Target* find_target(std::string_view name);

}  // namespace photomill::fuzz
