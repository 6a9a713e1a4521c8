// Checks an image file before a decoder sees it, so that every bad image gets one clear line
// (docs/errors.md) instead of OpenCV's warnings and libpng/libjpeg's messages on stderr, and a
// file cut short is refused instead of decoded with a grey tail. Standard library only: the
// callers decode with OpenCV afterwards.
#pragma once

#include <cstdint>
#include <string>

namespace photomill {

// The most pixels an image may claim: 2^28 (268 Mpixel; the largest phone sensors have 200).
// A header claiming more is junk or hostile, and decoding it would allocate that much first.
inline constexpr std::uint64_t kMaxImagePixels = std::uint64_t{1} << 28;
// The largest image file: 2^31 bytes (8 bytes a pixel at kMaxImagePixels, uncompressed).
inline constexpr std::uint64_t kMaxImageBytes = std::uint64_t{1} << 31;

// Throws InputError(path, 0, reason) unless `path` names a regular, non-empty file of at most
// kMaxImageBytes whose content is complete for its format and within kMaxImagePixels: a PNG needs its IDAT data and IEND
// chunk, a JPEG its end-of-image marker (data appended after it are allowed). Other formats
// (TIFF, BMP, ...) are left to the decoder.
void check_image_file(const std::string& path);

// check_image_file, returning the file's bytes: the one read of the photo, whose errors name it
// ("a.png: read error: Input/output error"); callers decode these bytes (formats/image_decode.hpp)
// instead of letting the decoder open the file again, through stdio, whose read errors would
// look like a broken image (and a file changed in between would not be the one checked).
std::string read_image_file(const std::string& path);

// True if `path` exists (any kind of file): callers that may run where the images are not
// (calib reading image sizes) ask before check_image_file.
bool image_file_exists(const std::string& path);

}  // namespace photomill
