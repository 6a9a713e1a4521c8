// Large OpenCV images in transparent huge pages (2 MiB) instead of 4 KiB pages.
//
// SIFT on a 2832 x 2128 photo builds its Gaussian and difference-of-Gaussian pyramids from the
// photo doubled in size: ~1.4 GB of float images, each page touched first by a blur. In 4 KiB
// pages that is ~350 000 page faults per photo and a TLB miss on nearly every row of a
// vertical blur; glibc maps such blocks itself (over its 32 MiB mmap limit) and the kernel's
// default THP mode on Debian ("madvise") only backs a mapping with huge pages when asked.
// Measured on one Sceaux photo (detect --max-features 11000 --cap-order scale): 4.5 s user + 2.9 s
// system in 4 KiB pages, 2.0 s + 2.7 s with huge pages, 12x fewer page faults
// (docs/measurements/detect.md). Makefile.example's GLIBC_TUNABLES=glibc.malloc.hugetlb=1 does
// the same for glibc's blocks; this holds for detect however it is run.
#pragma once

#include <cstddef>

namespace photomill::detect {

// Makes OpenCV allocate every cv::Mat of at least `min_bytes` as its own anonymous mapping,
// 2 MiB aligned, marked MADV_HUGEPAGE (smaller ones as before). Call before the images are
// made; the allocator lives until the process ends. Idempotent; the first call's sizes win.
// Freed blocks are kept, up to `cache_bytes` in all, and handed out again for arrays of the same
// size (the next photo's pyramid), so their pages are not cleared by the kernel again.
void use_huge_pages_for_large_images(std::size_t min_bytes = std::size_t{8} << 20,
                                     std::size_t cache_bytes = std::size_t{1} << 30);

}  // namespace photomill::detect
