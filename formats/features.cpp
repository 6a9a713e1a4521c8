#include "formats/features.hpp"

#include <cmath>
#include <stdexcept>

#include "formats/error.hpp"
#include "formats/run.hpp"
#include "formats/text.hpp"
#include "formats/magnitude.hpp"

namespace photomill {

FeatureSet read_features(std::istream& in, const std::string& source, FeatureLimits limits) {
  LineReaderOptions opt;
  opt.max_line_bytes = limits.max_line_bytes;
  LineReader lines(in, source, opt);
  FeatureSet fs;
  auto header = [&](std::string_view key, std::size_t n_values) {
    const auto line = lines.next();
    if (!line) throw InputError(source, lines.line_number(), "unexpected end of input: expected '" + std::string(key) + "'");
    auto f = split_whitespace(*line);
    if (f.empty() || f[0] != key || f.size() != n_values + 1) {
      lines.fail("expected '" + std::string(key) + "' with " + std::to_string(n_values) + " value(s)");
    }
    return f;
  };
  auto int_in = [&](std::string_view s, const char* what, long long lo, long long hi) {
    const auto v = parse_int(s);
    if (!v || *v < lo || *v > hi) {
      lines.fail(std::string(what) + " must be an integer in " + std::to_string(lo) + ".." + std::to_string(hi));
    }
    return *v;
  };
  {
    const auto line = lines.next();
    if (!line || trim(*line) != "photomill-features v1") {
      throw InputError(source, lines.line_number(), "not a photomill features file (expected 'photomill-features v1')");
    }
  }
  {
    const auto line = lines.next();
    if (!line || line->rfind("image ", 0) != 0 || trim(line->substr(6)).empty()) {
      throw InputError(source, lines.line_number(), "expected 'image NAME'");
    }
    fs.image = std::string(trim(line->substr(6)));
  }
  {
    const auto f = header("size", 2);
    fs.image_width_px = static_cast<int>(int_in(f[1], "width", 1, 1'000'000));
    fs.image_height_px = static_cast<int>(int_in(f[2], "height", 1, 1'000'000));
  }
  const auto count = int_in(header("count", 1)[1], "count", 0, 1LL << 40);
  fs.descriptor_dim = static_cast<int>(int_in(header("dim", 1)[1], "dim", 1, limits.max_descriptor_dim));
  const std::size_t dim = static_cast<std::size_t>(fs.descriptor_dim);
  for (long long k = 0; k < count; ++k) {
    const auto line = lines.next();
    if (!line) {
      throw InputError(source, lines.line_number(), "truncated: 'count " + std::to_string(count) +
                                                        "' but only " + std::to_string(k) + " features");
    }
    const auto f = split_whitespace(*line);
    if (f.size() != 5 + dim) lines.fail("expected " + std::to_string(5 + dim) + " values, got " + std::to_string(f.size()));
    Keypoint kp;
    double* fields[5] = {&kp.x_px, &kp.y_px, &kp.size_px, &kp.angle_deg, &kp.response};
    const char* names[5] = {"x_px", "y_px", "size_px", "angle_deg", "response"};
    for (int c = 0; c < 5; ++c) {
      const auto v = parse_bounded(f[static_cast<std::size_t>(c)]);
      if (!v) lines.fail(std::string(names[c]) + " " + number_problem(f[static_cast<std::size_t>(c)]));
      *fields[c] = *v;
    }
    fs.keypoints.push_back(kp);
    for (std::size_t d = 0; d < dim; ++d) {
      fs.descriptors.push_back(static_cast<std::uint8_t>(int_in(f[5 + d], "descriptor value", 0, 255)));
    }
  }
  if (lines.next()) lines.fail("more features than 'count' says");
  fs.run_id = lines.run_id();
  return fs;
}

void write_features(std::ostream& out, const FeatureSet& fs) {
  if (fs.image.empty() || fs.image.find_first_of("\r\n") != std::string::npos) throw std::invalid_argument("bad image name");
  if (fs.descriptors.size() != fs.keypoints.size() * static_cast<std::size_t>(fs.descriptor_dim)) {
    throw std::invalid_argument("descriptor count does not match keypoints");
  }
  std::string t = "photomill-features v1\n" + stamp_line(std::nullopt) + "image " + fs.image + "\nsize " + std::to_string(fs.image_width_px) + " " +
                  std::to_string(fs.image_height_px) + "\ncount " + std::to_string(fs.keypoints.size()) +
                  "\ndim " + std::to_string(fs.descriptor_dim) + "\n# x_px y_px size_px angle_deg response descriptor...\n";
  const std::size_t dim = static_cast<std::size_t>(fs.descriptor_dim);
  for (std::size_t k = 0; k < fs.keypoints.size(); ++k) {
    const Keypoint& kp = fs.keypoints[k];
    for (double v : {kp.x_px, kp.y_px, kp.size_px, kp.angle_deg, kp.response}) {
      if (!std::isfinite(v)) throw std::invalid_argument("non-finite keypoint value");
      append_double(t, v);
      t += ' ';
    }
    for (std::size_t d = 0; d < dim; ++d) {
      t += std::to_string(fs.descriptors[k * dim + d]);
      t += d + 1 < dim ? ' ' : '\n';
    }
    if (t.size() > (1 << 16)) {
      out << t;
      t.clear();
    }
  }
  out << t;
}

}  // namespace photomill
