// Checks an image file before a decoder sees it, so that every bad image gets one clear line
// (docs/errors.md) instead of OpenCV's warnings and libpng/libjpeg's messages on stderr, and a
// file cut short is refused instead of decoded with a grey tail. Standard library only: the
// callers decode with OpenCV afterwards.
#pragma once

#include <cstdint>
#include <string>

namespace photomill {

// The most pixels a photo may claim, checked from its header before any decoding (issue #25):
// 220 million. The largest camera sensors make 200 Mpx (16320 x 12240 phone sensors; medium
// format backs 150 Mpx); a 16000 x 16000 header (256 Mpx) is refused, since decoding it would
// allocate 2 GB before anything could look at it, and a flat PNG that claims it is a few KB.
// detect's --max-image-mpx raises or lowers it for one run.
inline constexpr std::uint64_t kMaxImagePixels = 220'000'000;
// The largest image file: 2^31 bytes (8 bytes a pixel at kMaxImagePixels, uncompressed).
inline constexpr std::uint64_t kMaxImageBytes = std::uint64_t{1} << 31;

// Throws InputError(path, 0, reason) unless `path` names a regular, non-empty file of at most
// kMaxImageBytes whose content is complete for its format and whose header claims at most
// `max_pixels` (width x height from a PNG's IHDR or a JPEG's SOF; nothing is decoded): a PNG needs
// its IDAT data and IEND chunk, a JPEG its end-of-image marker (data appended after it are
// allowed). Other formats (TIFF, BMP, ...) are left to the decoder.
void check_image_file(const std::string& path, std::uint64_t max_pixels = kMaxImagePixels);

// check_image_file, returning the file's bytes: the one read of the photo, whose errors name it
// ("a.png: read error: Input/output error"); callers decode these bytes (formats/image_decode.hpp)
// instead of letting the decoder open the file again, through stdio, whose read errors would
// look like a broken image (and a file changed in between would not be the one checked).
std::string read_image_file(const std::string& path, std::uint64_t max_pixels = kMaxImagePixels);

// True if `path` exists (any kind of file): callers that may run where the images are not
// (calib reading image sizes) ask before check_image_file.
bool image_file_exists(const std::string& path);

}  // namespace photomill
