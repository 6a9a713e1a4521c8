// cv::MatAllocator backing large images with transparent huge pages (see huge_pages.hpp).
#include "detect/huge_pages.hpp"

#include <sys/mman.h>

#include <cstdint>
#include <map>
#include <mutex>

#include <opencv2/core.hpp>

namespace photomill::detect {
namespace {

constexpr std::size_t kHugePage = std::size_t{2} << 20;

std::size_t round_up(std::size_t n, std::size_t to) { return (n + to - 1) / to * to; }

// A 2 MiB-aligned anonymous mapping of round_up(bytes, 2 MiB) bytes: one larger mapping with the
// unaligned head and the tail beyond the aligned block unmapped again, so that munmap(p, length)
// later frees exactly what is left. nullptr if the system refuses.
void* map_aligned(std::size_t bytes) {
  const std::size_t length = round_up(bytes, kHugePage);
  void* raw = mmap(nullptr, length + kHugePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) return nullptr;
  const auto start = reinterpret_cast<std::uintptr_t>(raw);
  const std::uintptr_t aligned = round_up(start, kHugePage);
  if (aligned > start) munmap(raw, aligned - start);
  const std::uintptr_t end = start + length + kHugePage;
  if (end > aligned + length) munmap(reinterpret_cast<void*>(aligned + length), end - (aligned + length));
  void* p = reinterpret_cast<void*>(aligned);
  madvise(p, length, MADV_HUGEPAGE);  // advice: without THP the mapping still works in small pages
  return p;
}

// OpenCV's Mat allocation contract (as its standard allocator keeps it): allocate() fills `step`
// for a dense array (memory the caller owns, `data`, is left to OpenCV's allocator), returns a
// UMatData whose data and origdata point to the block and whose size is its byte count;
// deallocate() frees a block it allocated. Blocks under `min_bytes` go to OpenCV's own allocator.
class HugePageAllocator final : public cv::MatAllocator {
 public:
  HugePageAllocator(std::size_t min_bytes, std::size_t cache_bytes)
      : min_bytes_(min_bytes), cache_limit_(cache_bytes), std_(cv::Mat::getStdAllocator()) {}

  cv::UMatData* allocate(int dims, const int* sizes, int type, void* data, size_t* step, cv::AccessFlag flags,
                         cv::UMatUsageFlags usage) const override {
    if (data || !step) return std_->allocate(dims, sizes, type, data, step, flags, usage);
    std::size_t total = CV_ELEM_SIZE(type);
    for (int i = dims - 1; i >= 0; --i) {
      step[i] = total;
      total *= static_cast<std::size_t>(sizes[i]);
    }
    if (total < min_bytes_) return std_->allocate(dims, sizes, type, data, step, flags, usage);
    void* block = take_cached(round_up(total, kHugePage));
    if (!block) block = map_aligned(total);
    if (!block) return std_->allocate(dims, sizes, type, data, step, flags, usage);
    auto* u = new cv::UMatData(this);
    u->data = u->origdata = static_cast<uchar*>(block);
    u->size = total;
    return u;
  }

  bool allocate(cv::UMatData* u, cv::AccessFlag, cv::UMatUsageFlags) const override { return u != nullptr; }

  void deallocate(cv::UMatData* u) const override {
    if (!u) return;
    CV_Assert(u->urefcount == 0 && u->refcount == 0);
    if (!(u->flags & cv::UMatData::USER_ALLOCATED) && u->origdata) release(u->origdata, round_up(u->size, kHugePage));
    u->origdata = nullptr;
    delete u;
  }

 private:
  // A freed block of exactly this length, or nullptr.
  void* take_cached(std::size_t length) const {
    const std::lock_guard lock(mutex_);
    const auto it = cache_.find(length);
    if (it == cache_.end()) return nullptr;
    void* p = it->second;
    cache_.erase(it);
    cached_ -= length;
    return p;
  }

  // Keeps the block for the next image's arrays of the same size while the cache holds less than
  // its limit; unmaps it otherwise. A reused block is not cleared again by the kernel, which
  // costs ~1 s a photo for SIFT's ~0.8 GB of pyramids (docs/measurements/detect.md, session 53).
  void release(void* p, std::size_t length) const {
    {
      const std::lock_guard lock(mutex_);
      if (cached_ + length <= cache_limit_) {
        cache_.emplace(length, p);
        cached_ += length;
        return;
      }
    }
    munmap(p, length);
  }

  std::size_t min_bytes_;
  std::size_t cache_limit_;
  cv::MatAllocator* std_;
  mutable std::mutex mutex_;
  mutable std::multimap<std::size_t, void*> cache_;
  mutable std::size_t cached_ = 0;
};

}  // namespace

void use_huge_pages_for_large_images(std::size_t min_bytes, std::size_t cache_bytes) {
  // Never destroyed: Mats made with it may outlive any static (OpenCV's own allocator is the same).
  static HugePageAllocator* const allocator = new HugePageAllocator(min_bytes, cache_bytes);
  cv::Mat::setDefaultAllocator(allocator);
}

}  // namespace photomill::detect
