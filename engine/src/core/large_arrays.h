// An allocator for the beams' large arrays (their grid, keys and prisms): blocks of a megabyte
// or more aligned to 2 MiB, so that a kernel whose transparent huge pages are "always" on can
// back them with huge pages. They are not asked for (no madvise): on the 2-core machine a
// huge page faulted in for the first time cost 5-10x more per byte than small pages (the beam
// build of a 128 x 128 wave patch 0.8-1.1 s against 0.26-0.33 s, the stepped pool's 16-spp
// render 1.6-2.0 s against 1.2-1.3 s wall), against 2-8 % less time per sample once warm.
#pragma once
#include <cstddef>
#include <cstdlib>
#include <new>
#include <vector>

namespace photic {

template <class T>
struct LargeArrayAllocator {
    using value_type = T;
    static constexpr size_t kHuge = size_t(2) << 20;  // 2 MiB
    LargeArrayAllocator() = default;
    template <class U>
    LargeArrayAllocator(const LargeArrayAllocator<U>&) {}
    T* allocate(size_t n) {
        const size_t bytes = n * sizeof(T);
        if (bytes < (size_t(1) << 20)) {
            void* p = ::operator new(bytes, std::align_val_t(alignof(T) > 16 ? alignof(T) : 16));
            return static_cast<T*>(p);
        }
        const size_t rounded = (bytes + kHuge - 1) / kHuge * kHuge;
        void* p = std::aligned_alloc(kHuge, rounded);
        if (!p) throw std::bad_alloc();
        return static_cast<T*>(p);
    }
    void deallocate(T* p, size_t n) {
        const size_t bytes = n * sizeof(T);
        if (bytes < (size_t(1) << 20))
            ::operator delete(p, std::align_val_t(alignof(T) > 16 ? alignof(T) : 16));
        else
            std::free(p);
    }
    template <class U>
    bool operator==(const LargeArrayAllocator<U>&) const { return true; }
    template <class U>
    bool operator!=(const LargeArrayAllocator<U>&) const { return false; }
};

template <class T>
using LargeVector = std::vector<T, LargeArrayAllocator<T>>;

}  // namespace photic
