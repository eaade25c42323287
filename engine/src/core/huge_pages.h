// An allocator for large arrays read at random (the beams' grid, keys and prisms): blocks of a
// megabyte or more are aligned to 2 MiB and marked for transparent huge pages, so that a
// lookup's scattered reads miss the TLB less (on Linux with THP in "madvise" mode, the common
// default; elsewhere it is a plain aligned allocation).
#pragma once
#include <cstddef>
#include <cstdlib>
#include <new>
#include <vector>
#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace photic {

template <class T>
struct HugePageAllocator {
    using value_type = T;
    static constexpr size_t kHuge = size_t(2) << 20;  // 2 MiB
    HugePageAllocator() = default;
    template <class U>
    HugePageAllocator(const HugePageAllocator<U>&) {}
    T* allocate(size_t n) {
        const size_t bytes = n * sizeof(T);
        if (bytes < (size_t(1) << 20)) {
            void* p = ::operator new(bytes, std::align_val_t(alignof(T) > 16 ? alignof(T) : 16));
            return static_cast<T*>(p);
        }
        const size_t rounded = (bytes + kHuge - 1) / kHuge * kHuge;
        void* p = std::aligned_alloc(kHuge, rounded);
        if (!p) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        madvise(p, rounded, MADV_HUGEPAGE);
#endif
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
    bool operator==(const HugePageAllocator<U>&) const { return true; }
    template <class U>
    bool operator!=(const HugePageAllocator<U>&) const { return false; }
};

template <class T>
using HugeVector = std::vector<T, HugePageAllocator<T>>;

}  // namespace photic
