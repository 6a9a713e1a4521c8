#include "formats/image.hpp"

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string_view>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "formats/error.hpp"

namespace photomill {
namespace {

std::uint32_t be32(const unsigned char* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | p[3];
}

// PNG (ISO/IEC 15948, 5.3): the signature, then chunks of length (4 bytes, big-endian), type (4),
// data, CRC (4): IHDR first (width, height), at least one IDAT, IEND last. Bytes after IEND are
// allowed. Returns the problem, empty if none.
std::string png_problem(const std::string& d, std::uint64_t& width, std::uint64_t& height) {
  std::size_t pos = 8;
  bool data = false;
  while (pos + 12 <= d.size()) {
    const auto* p = reinterpret_cast<const unsigned char*>(d.data() + pos);
    const std::uint64_t length = be32(p);
    const std::string_view type(d.data() + pos + 4, 4);
    if (type == "IHDR" && length >= 8 && pos + 16 <= d.size()) {
      width = be32(p + 8);
      height = be32(p + 12);
    }
    if (type == "IDAT") data = true;
    if (type == "IEND") return data ? "" : "not a valid PNG: it holds no image data (IDAT)";
    pos += 12 + length;
  }
  return "truncated PNG: the file ends before its IEND chunk";
}

// JPEG (ITU-T T.81, B.1.1 and B.2): SOI, then marker segments (FF xx, 2-byte big-endian length
// that counts itself); after each SOS the entropy-coded data run to the next marker (FF followed
// by anything but 00, a restart marker D0..D7 or a fill FF). Complete when EOI (FF D9) follows.
// Stopping at EOI allows data appended after the image (phones append videos and trailers), and
// walking the segments skips a thumbnail's own EOI inside APP1.
bool jpeg_complete(const std::string& d, std::uint64_t& width, std::uint64_t& height) {
  const auto* b = reinterpret_cast<const unsigned char*>(d.data());
  const std::size_t n = d.size();
  std::size_t pos = 2;
  while (pos + 1 < n) {
    if (b[pos] != 0xFF) return false;
    unsigned marker = b[pos + 1];
    while (marker == 0xFF && pos + 2 < n) marker = b[++pos + 1];  // fill bytes
    pos += 2;
    if (marker == 0xD9) return true;
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) continue;  // no length
    if (pos + 2 > n) return false;
    // Start of frame (SOF0..SOF15 but DHT C4, JPG C8, DAC CC): precision, height, width.
    if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC && pos + 7 <= n) {
      height = (std::uint64_t{b[pos + 3]} << 8) | b[pos + 4];
      width = (std::uint64_t{b[pos + 5]} << 8) | b[pos + 6];
    }
    pos += (std::size_t{b[pos]} << 8) | b[pos + 1];
    if (marker != 0xDA) continue;
    // Entropy-coded data after SOS.
    while (pos + 1 < n && !(b[pos] == 0xFF && b[pos + 1] != 0x00 && !(b[pos + 1] >= 0xD0 && b[pos + 1] <= 0xD7))) ++pos;
  }
  return false;
}

// Megapixels, 6 significant digits ("256", "0.003072", "10000").
std::string mpx(std::uint64_t pixels) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", static_cast<double>(pixels) / 1e6);
  return buf;
}

}  // namespace

bool image_file_exists(const std::string& path) {
  std::error_code ec;
  return std::filesystem::exists(path, ec);
}

void check_image_file(const std::string& path, std::uint64_t max_pixels) { (void)read_image_file(path, max_pixels); }

namespace {

// The whole regular file `path`, every read error named.
std::string read_whole_file(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw InputError(path, 0, std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  std::string d;
  if (::fstat(fd, &st) == 0 && st.st_size > 0) d.reserve(static_cast<std::size_t>(st.st_size));
  char buf[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const std::string reason = std::strerror(errno);
      ::close(fd);
      throw InputError(path, 0, "read error: " + reason);
    }
    if (n == 0) break;
    d.append(buf, static_cast<std::size_t>(n));
    if (d.size() > kMaxImageBytes) {
      ::close(fd);
      throw InputError(path, 0, "larger than " + std::to_string(kMaxImageBytes) + " bytes, more than a photo may have");
    }
  }
  ::close(fd);
  return d;
}

}  // namespace

std::string read_image_file(const std::string& path, std::uint64_t max_pixels) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (!fs::exists(status)) throw InputError(path, 0, "cannot open: No such file or directory");
  if (fs::is_directory(status)) throw InputError(path, 0, "is a directory");
  // The decoder opens the file again after this check: a FIFO would be empty by then, a device
  // endless (issue #25: detect hung on a FIFO and read /dev/zero until the memory ran out).
  if (!fs::is_regular_file(status)) {
    throw InputError(path, 0, "not a regular file: a photo is read twice (checked, then decoded), which a pipe or device cannot be");
  }
  if (fs::file_size(path, ec) > kMaxImageBytes) {
    throw InputError(path, 0, "larger than " + std::to_string(kMaxImageBytes) + " bytes, more than a photo may have");
  }
  std::string d = read_whole_file(path);
  if (d.empty()) throw InputError(path, 0, "empty file, not an image");
  std::uint64_t width = 0, height = 0;
  if (d.size() >= 8 && d.compare(0, 8, std::string_view("\x89PNG\r\n\x1a\n", 8)) == 0) {
    const std::string problem = png_problem(d, width, height);
    if (!problem.empty()) throw InputError(path, 0, problem);
  } else if (d.size() >= 3 && d.compare(0, 3, "\xFF\xD8\xFF") == 0) {
    if (!jpeg_complete(d, width, height)) {
      throw InputError(path, 0, "truncated JPEG: the file ends before its end-of-image marker");
    }
  }
  if (width * height > max_pixels) {
    throw InputError(path, 0, "its header claims " + std::to_string(width) + "x" + std::to_string(height) + " pixels (" +
                                  mpx(width * height) + " Mpx), more than the " + mpx(max_pixels) +
                                  " Mpx a photo may have (the pixel limit; detect takes --max-image-mpx)");
  }
  return d;
}

}  // namespace photomill
