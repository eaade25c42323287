// A 3-D grid of piecewise-constant densities over an axis-aligned box, stored sparsely in
// bricks, with the walk that gridded water needs: the exact integral of the density along a
// ray (the beams' and paths' optical depths), which also samples free paths exactly (regular
// tracking). Up to kMaxFields density fields share the lattice (e.g. sediment and CDOM, each
// scaling IOPs of its own): one walk integrates them all. The IOPs the densities scale live
// in Water (medium.h).
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <new>
#include <stdexcept>
#include <vector>
#include "parallel.h"
#include "vec.h"
#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace photic {

// Per voxel one density rho_f >= 0 per field; outside the box rho = 0. Empty space is skipped
// at three levels, so that a sparse plume costs little where rays miss it: the box of the
// non-empty voxels, bricks of B^3 voxels (only non-empty ones are stored), and per empty brick
// the radius of the empty cube of bricks around it, which a walk crosses in one jump. Steep
// rays walk by columns of voxels instead (prefix sums along z), so that thin voxels, which
// such rays cross by the dozen per column, cost per column crossed.
struct VoxelGrid {
    static constexpr int B = 8;        // voxels per brick edge (a power of 2)
    static constexpr int kShift = 3;   // log2(B)
    static constexpr int kClearCap = 4;  // largest empty-cube radius stored (bricks)
    static constexpr int kMaxFields = 4;  // density fields per grid
    static constexpr int kB3 = B * B * B;
    static constexpr float kInfF = std::numeric_limits<float>::infinity();
    int nfields = 1;
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    double cell[3] = {1, 1, 1}, icell[3] = {1, 1, 1};  // voxel size (m) and 1 / size
    int n[3] = {1, 1, 1}, nb[3] = {1, 1, 1};
    // An array of T aligned for the cache, not zeroed (the builds write every element, on
    // their threads, which then also share first touching the pages).
    template <class T>
    struct Buffer {
        struct Free {  // (C++17 aligned new: the alignment goes with the pointer)
            std::align_val_t align;
            Free() : align(std::align_val_t(64)) {}
            explicit Free(size_t a) : align(std::align_val_t(a)) {}
            void operator()(T* q) const { ::operator delete[](q, align); }
        };
        std::unique_ptr<T[], Free> p;
        size_t n = 0;
        void allocate(size_t count) {
            p.reset();
            n = count;
            if (!count) return;
            // Large arrays in 2 MB pages where the system gives them on request (Linux's
            // transparent huge pages): a walk enters a new brick (2 kB a field) every few
            // voxels, and 4 kB pages give the TLB little reach over tens of MB (measured: 1-4 %
            // of the plume example's render).
            constexpr size_t kHuge = size_t(2) << 20;
            const size_t bytes = count * sizeof(T);
            const size_t align = bytes >= 2 * kHuge ? kHuge : 64;
            const size_t size = (bytes + align - 1) / align * align;
            void* q = ::operator new[](size, std::align_val_t(align));
#ifdef MADV_HUGEPAGE
            if (align == kHuge) madvise(q, size, MADV_HUGEPAGE);
#endif
            p = std::unique_ptr<T[], Free>(static_cast<T*>(q), Free(align));
        }
        T& operator[](size_t i) { return p[i]; }
        const T& operator[](size_t i) const { return p[i]; }
        size_t size() const { return n; }
    };
    // Non-empty bricks only (a brick is stored where any field is > 0), nfields blocks of B^3
    // densities each, field after field (local (i, j, k) at (i * B + j) * B + k): a sparse
    // plume takes little memory, and a ray's voxels in one brick share cache lines.
    Buffer<float> bricks;  // (a dense 256^3 field: 64 MB)
    // Per brick its block in `bricks` (-1: empty).
    std::vector<int32_t> brick_slot;
    // Per brick 0 if non-empty, else r in 1..kClearCap such that every brick within r - 1
    // bricks of it (the cube of side 2 r - 1 around it) is empty. A byte, not the slot's
    // sign: a quarter of the memory stays in cache for random lookups, which were most of a
    // point's density lookup with the int array.
    std::vector<int8_t> brick_clear;
    // Per column (i, j) of voxels with any density, each field's prefix sums up the column,
    // P_f(k) = sum of rho_f(i, j, kz0 + m) over m < k for the faces k = 0..nzc of the
    // non-empty voxels' span along z, in double, the fields interleaved (P(k) of every field
    // side by side). A steep ray integrates each column it crosses from two lookups, however
    // many voxels it passes along z: thin voxels (water resolved finely in depth) make a
    // steep ray cross many voxels, and bricks, per column (the plume example's sun and camera
    // rays: 10-40). Costs 8 bytes a voxel and field over the non-empty columns' span.
    Buffer<double> col_prefix;
    std::vector<int32_t> col_slot;   // per column (i * n1 + j) its block in col_prefix (-1: empty)
    int kz0 = 0, nzc = 0;            // the span's first voxel along z and its length (0: no columns)
    // A walk goes by columns where its ray crosses at least this many voxels along z per
    // column (for fewer the voxel walk's runs along z are as fast).
    static constexpr double kColumnRatio = 2.0;
    static constexpr size_t kMaxColumnBytes = size_t(4) << 30;  // beyond: voxel walks only
    bool columns() const { return nzc > 0; }
    bool occupied = false;            // any rho > 0; then the box of those voxels:
    double occ_lo[3] = {0, 0, 0}, occ_hi[3] = {0, 0, 0};
    float rho_min[kMaxFields] = {}, rho_max[kMaxFields] = {};  // per field
    size_t brick_floats() const { return size_t(nfields) * kB3; }

    // The grid over [lo_, hi_] from the densities rho[f][(i * n1 + j) * n2 + k] of `fields`
    // fields (arrays of their own: the caller's, not copied into one; not kept); throws
    // std::invalid_argument for a density that is negative or not finite. Slabs of bricks
    // along x on `threads` threads (0: all cores).
    void build(const double* lo_, const double* hi_, const int* n_, const float* const* rho, int fields = 1,
               int threads = 1) {
        if (fields < 1 || fields > kMaxFields) throw std::invalid_argument("a grid holds 1 to 4 density fields");
        nfields = fields;
        for (int a = 0; a < 3; ++a) {
            lo[a] = lo_[a];
            hi[a] = hi_[a];
            n[a] = n_[a];
            cell[a] = (hi[a] - lo[a]) / n[a];
            nb[a] = (n[a] + B - 1) / B;
            icell[a] = 1.0 / cell[a];
        }
        // Two passes over the densities, each over slabs of bricks along x (a brick belongs
        // to one slab: no two tasks write the same flags or bricks). The first validates them
        // and marks the non-empty bricks; the bricks are then numbered in order and allocated
        // once (no reallocation); the second fills them.
        const size_t nbricks = size_t(nb[0]) * nb[1] * nb[2];
        constexpr int M = B - 1;
        std::vector<uint8_t> brick_used(nbricks, 0);
        std::vector<uint8_t> col_used(size_t(n[0]) * n[1], 0);
        struct alignas(64) Slab {  // what a slab found (cache lines of its own: no false sharing)
            float lo_v[kMaxFields], hi_v[kMaxFields];
            bool bad = false;
            int first[3] = {1 << 30, 1 << 30, 1 << 30}, last[3] = {-1, -1, -1};
            Slab() { std::fill(lo_v, lo_v + kMaxFields, kInfF); std::fill(hi_v, hi_v + kMaxFields, -kInfF); }
        };
        std::vector<Slab> slabs(nb[0]);
        auto rows = [&](int ib, auto&& row_fn) {  // the rows (i, j) of slab ib, by offset
            size_t off = size_t(ib) * B * n[1] * n[2];
            for (int i = ib * B; i < std::min(n[0], ib * B + B); ++i)
                for (int j = 0; j < n[1]; ++j, off += n[2]) row_fn(i, j, off);
        };
        parallel_for(size_t(nb[0]), threads, [&](size_t ib, int) {
            Slab& sl = slabs[ib];
            rows(int(ib), [&](int i, int j, size_t off) {
                const size_t row = (size_t(i >> kShift) * nb[1] + (j >> kShift)) * nb[2];
                int kfirst = n[2], klast = -1;
                for (int f = 0; f < nfields; ++f) {
                    const float* r = rho[f] + off;
                    // The row's smallest and largest value in a loop the compiler vectorises
                    // (NaN fails both comparisons, so it is counted apart); most rows of a
                    // sparse field are all zero and end there.
                    float lo_v = r[0], hi_v = r[0];
                    int nan = 0;
                    for (int k = 0; k < n[2]; ++k) {
                        const float v = r[k];
                        lo_v = v < lo_v ? v : lo_v;
                        hi_v = v > hi_v ? v : hi_v;
                        nan += v != v;
                    }
                    if (nan || !(lo_v >= 0.f) || !std::isfinite(hi_v)) sl.bad = true;
                    sl.lo_v[f] = std::min(sl.lo_v[f], lo_v);
                    sl.hi_v[f] = std::max(sl.hi_v[f], hi_v);
                    if (!(hi_v > 0.f)) continue;
                    for (int k = 0; k < n[2]; ++k) {
                        if (!(r[k] > 0.f)) continue;
                        brick_used[row + (k >> kShift)] = 1;
                        kfirst = std::min(kfirst, k);
                        klast = std::max(klast, k);
                    }
                }
                if (klast < 0) return;
                col_used[size_t(i) * n[1] + j] = 1;
                sl.first[0] = std::min(sl.first[0], i); sl.last[0] = std::max(sl.last[0], i);
                sl.first[1] = std::min(sl.first[1], j); sl.last[1] = std::max(sl.last[1], j);
                sl.first[2] = std::min(sl.first[2], kfirst); sl.last[2] = std::max(sl.last[2], klast);
            });
        });
        int first[3] = {n[0], n[1], n[2]}, last[3] = {-1, -1, -1};
        std::fill(rho_min, rho_min + kMaxFields, 0.f);
        std::fill(rho_max, rho_max + kMaxFields, 0.f);
        std::fill(rho_min, rho_min + nfields, kInfF);
        std::fill(rho_max, rho_max + nfields, -kInfF);
        for (const Slab& sl : slabs) {
            if (sl.bad) throw std::invalid_argument("densities must be finite and >= 0");
            for (int f = 0; f < nfields; ++f) {
                rho_min[f] = std::min(rho_min[f], sl.lo_v[f]);
                rho_max[f] = std::max(rho_max[f], sl.hi_v[f]);
            }
            for (int a = 0; a < 3; ++a) {
                first[a] = std::min(first[a], sl.first[a]);
                last[a] = std::max(last[a], sl.last[a]);
            }
        }
        brick_slot.assign(nbricks, -1);
        int32_t nslots = 0;
        for (size_t b = 0; b < nbricks; ++b)
            if (brick_used[b]) brick_slot[b] = nslots++;
        bricks.allocate(size_t(nslots) * brick_floats());
        // Every voxel of the non-empty bricks, 0 outside the grid and where rho = 0 (or -0).
        parallel_for(size_t(nb[0]), threads, [&](size_t ib, int) {
            for (int f = 0; f < nfields; ++f)
                for (int li = 0; li < B; ++li)
                    for (int j = 0; j < nb[1] * B; ++j) {
                        const int i = int(ib) * B + li;
                        const bool inside = i < n[0] && j < n[1];
                        const float* r = inside ? rho[f] + (size_t(i) * n[1] + j) * n[2] : nullptr;
                        const size_t row = (ib * nb[1] + (j >> kShift)) * nb[2];
                        const int local_ij = f * kB3 + (li * B + (j & M)) * B;
                        for (int kb = 0; kb < nb[2]; ++kb) {
                            const int32_t slot = brick_slot[row + kb];
                            if (slot < 0) continue;
                            float* dst = &bricks[size_t(slot) * brick_floats() + local_ij];
                            for (int lk = 0; lk < B; ++lk) {
                                const int k = kb * B + lk;
                                dst[lk] = inside && k < n[2] && r[k] > 0.f ? r[k] : 0.f;
                            }
                        }
                    }
        });
        occupied = last[0] >= 0;
        for (int a = 0; a < 3 && occupied; ++a) {
            // The faces of the first and last non-empty voxels; inside the grid widened by a
            // hair (the space there is empty) so that a ray along a face is not clipped away
            // by rounding; the grid's own faces exactly (beyond them the walk would count the
            // outermost voxels).
            double pad = 1e-9 * (hi[a] - lo[a]);
            occ_lo[a] = first[a] == 0 ? lo[a] : lo[a] + first[a] * cell[a] - pad;
            occ_hi[a] = last[a] == n[a] - 1 ? hi[a] : lo[a] + (last[a] + 1) * cell[a] + pad;
        }
        build_clear();
        build_columns(rho, col_used, first[2], last[2], threads);
    }

    // The columns' prefix sums (col_prefix) from the densities, for the columns marked in
    // `used` over voxels k0..k1 along z (none if k1 < k0 or beyond kMaxColumnBytes).
    void build_columns(const float* const* rho, const std::vector<uint8_t>& used, int k0, int k1, int threads) {
        col_slot.assign(used.size(), -1);
        col_prefix.allocate(0);
        kz0 = nzc = 0;
        if (k1 < k0) return;
        int32_t ncols = 0;
        for (size_t c = 0; c < used.size(); ++c)
            if (used[c]) col_slot[c] = ncols++;
        const size_t stride = size_t(k1 - k0 + 2) * nfields;
        if (size_t(ncols) * stride * sizeof(double) > kMaxColumnBytes) return;
        kz0 = k0;
        nzc = k1 - k0 + 1;
        col_prefix.allocate(size_t(ncols) * stride);
        parallel_for(size_t(n[0]), threads, [&](size_t i, int) {
            for (int j = 0; j < n[1]; ++j) {
                const int32_t slot = col_slot[i * n[1] + j];
                if (slot < 0) continue;
                double* dst = &col_prefix[size_t(slot) * stride];
                for (int f = 0; f < nfields; ++f) {
                    const float* r = rho[f] + (i * n[1] + j) * size_t(n[2]) + kz0;
                    double sum = 0.0;
                    for (int k = 0; k < nzc; ++k) {
                        dst[size_t(k) * nfields + f] = sum;
                        sum += r[k] > 0.f ? double(r[k]) : 0.0;  // as the bricks hold it
                    }
                    dst[size_t(nzc) * nfields + f] = sum;
                }
            }
        });
    }

    // The empty bricks' Chebyshev distance to the nearest non-empty brick, capped, into
    // brick_clear, by growing the non-empty set one brick at a time (a dilation by a 3^3
    // cube, one axis at a time).
    void build_clear() {
        const size_t nbricks = brick_slot.size();
        const std::ptrdiff_t stride[3] = {std::ptrdiff_t(nb[1]) * nb[2], nb[2], 1};
        std::vector<uint8_t> grown(nbricks), next(nbricks);
        brick_clear.assign(nbricks, 0);
        for (size_t b = 0; b < nbricks; ++b) {
            grown[b] = brick_slot[b] >= 0;
            if (!grown[b]) brick_clear[b] = kClearCap;
        }
        for (int radius = 1; radius < kClearCap; ++radius) {
            for (int a = 0; a < 3; ++a) {
                size_t b = 0;
                for (int i = 0; i < nb[0]; ++i)
                    for (int j = 0; j < nb[1]; ++j)
                        for (int k = 0; k < nb[2]; ++k, ++b) {
                            const int c = a == 0 ? i : a == 1 ? j : k;
                            uint8_t g = grown[b];
                            if (c > 0) g |= grown[b - stride[a]];
                            if (c + 1 < nb[a]) g |= grown[b + stride[a]];
                            next[b] = g;
                        }
                grown.swap(next);
            }
            for (size_t b = 0; b < nbricks; ++b)
                if (grown[b] && brick_clear[b] > radius) brick_clear[b] = int8_t(radius);
        }
    }

    // The densities at p, rho[0..nfields) (0 outside the box); false where all are 0 for
    // certain: points outside the non-empty voxels' box or in an empty brick, which touch no
    // large array. (Arrays of densities or their integrals passed to the grid have
    // kMaxFields entries: fixed-size copies compile to a few moves, not library calls.)
    bool at(const Vec3& p, double* rho) const {
        const double q[3] = {p.x, p.y, p.z};
        int idx[3];
        std::fill(rho, rho + kMaxFields, 0.0);
        for (int a = 0; a < 3; ++a) {
            if (!(q[a] >= occ_lo[a] && q[a] <= occ_hi[a])) return false;
            idx[a] = std::min(n[a] - 1, std::max(0, int((q[a] - lo[a]) * icell[a])));
        }
        const std::ptrdiff_t b = (std::ptrdiff_t(idx[0] >> kShift) * nb[1] + (idx[1] >> kShift)) * nb[2] + (idx[2] >> kShift);
        if (brick_clear[b]) return false;
        const int32_t slot = brick_slot[b];
        constexpr int M = B - 1;
        const float* v = &bricks[size_t(slot) * brick_floats() + (((idx[0] & M) * B + (idx[1] & M)) * B + (idx[2] & M))];
        for (int f = 0; f < nfields; ++f) rho[f] = v[f * kB3];
        return true;
    }
    // Where the rays from points towards the sun meet density: for rays from x along `up`
    // (up.z > 0) or any direction within `spread` radians of it, a map over the rays'
    // footprints f(x) = x_h - x.z up_h / up.z (where the ray along `up` through x meets
    // z = 0) holding per cell the lowest bottom and highest top of the non-empty voxels whose
    // footprint (widened for the spread) meets the cell. A ray from x (x.z >= z_floor) that
    // crosses a voxel over a positive length does so within the voxel's heights, so within
    // the cell's span and above x: outside it the ray has no density, exactly. The beams walk
    // only that part of a ray, and none where the span lies below x.
    struct ShadowMap {
        Vec3 up{0, 0, 1};
        double spread = -1.0;        // < 0: not built
        bool all = true;             // no map (too grazing a direction): every ray may meet density
        double sx = 0, sy = 0;       // up_h / up.z
        double z_floor = 0;          // valid for points at or above this height
        double f0[2] = {0, 0}, icell[2] = {1, 1};
        int nf[2] = {0, 0};
        // Per cell the bottom and top face of the span as voxel face indices along z (top 0
        // where no voxel reaches): 4 bytes a cell, so that the map stays in cache.
        std::vector<uint16_t> span;
        double z_lo = 0, z_cell = 1, z_pad = 0;  // a face's height: z_lo + index * z_cell (+- z_pad)
        // The heights [*z0, *z1] (z1 > x.z) outside which the ray from x has no density, or
        // false if it has none at all.
        bool meets(const Vec3& x, double* z0, double* z1) const {
            *z0 = -kInf;
            *z1 = kInf;
            if (all || !(x.z >= z_floor)) return true;
            const double fx = (x.x - sx * x.z - f0[0]) * icell[0], fy = (x.y - sy * x.z - f0[1]) * icell[1];
            if (!(fx >= 0.0 && fy >= 0.0 && fx < nf[0] && fy < nf[1])) return false;
            const uint16_t* c = &span[2 * (size_t(fx) * nf[1] + size_t(fy))];
            if (c[1] == 0) return false;
            *z0 = z_lo + c[0] * z_cell - z_pad;
            *z1 = z_lo + c[1] * z_cell + z_pad;
            return *z1 > x.z;
        }
    };
    void shadow_map(const Vec3& up, double spread, ShadowMap* m, int threads = 1) const {
        m->up = up;
        m->spread = spread;
        m->all = true;
        m->z_floor = lo[2];
        m->span.clear();
        // A direction within `spread` of up: its shift per unit height differs by at most
        // spread / cos^2(theta + spread) (theta: up's zenith angle), as |d(tan)| <= dtheta / cos^2.
        const double theta = std::acos(std::clamp(up.z, -1.0, 1.0));
        if (!(theta + spread < 1.48)) return;  // within 5 degrees of the horizon: walk always
        if (n[2] >= 0xFFFF) return;            // (face indices in 16 bits)
        m->all = false;
        m->sx = up.x / up.z;
        m->sy = up.y / up.z;
        const double c = std::cos(theta + spread), dh = spread / (c * c) * (1.0 + 1e-6);
        const double s[2] = {m->sx, m->sy};
        if (!occupied) {
            m->nf[0] = m->nf[1] = 0;
            return;
        }
        // The map spans the occupied box's footprints, in cells of the voxels' size (or
        // coarser, to stay within 2048 cells per axis).
        double flo[2], fhi[2];
        for (int a = 0; a < 2; ++a) {
            const double w = dh * (occ_hi[2] - m->z_floor) + 1e-9 * (hi[a] - lo[a]);
            flo[a] = occ_lo[a] - std::max(s[a] * occ_lo[2], s[a] * occ_hi[2]) - w;
            fhi[a] = occ_hi[a] - std::min(s[a] * occ_lo[2], s[a] * occ_hi[2]) + w;
            const double size = std::max(cell[a], (fhi[a] - flo[a]) / 2048.0);
            m->f0[a] = flo[a];
            m->icell[a] = 1.0 / size;
            m->nf[a] = std::max(1, int(std::ceil((fhi[a] - flo[a]) * m->icell[a])));
        }
        m->z_lo = lo[2];
        m->z_cell = cell[2];
        m->z_pad = 1e-9 * (hi[2] - lo[2]);  // rounding: the span stays conservative
        m->span.resize(2 * size_t(m->nf[0]) * m->nf[1]);
        for (size_t c = 0; c < m->span.size(); c += 2) {
            m->span[c] = 0xFFFF;
            m->span[c + 1] = 0;
        }
        const double eps[2] = {1e-9 * (hi[0] - lo[0]), 1e-9 * (hi[1] - lo[1])};  // rounding
        // The map's cells under voxel (i, j, k)'s widened footprint: r[a] .. r[2 + a].
        auto cells = [&](int i, int j, int k, int* r) {
            const int idx[2] = {i, j};
            const double z0 = lo[2] + k * cell[2], z1 = z0 + cell[2];
            const double w = dh * (z1 - m->z_floor);
            for (int a = 0; a < 2; ++a) {
                const double x0 = lo[a] + idx[a] * cell[a], x1 = x0 + cell[a];
                const double g0 = x0 - std::max(s[a] * z0, s[a] * z1) - w - m->f0[a];
                const double g1 = x1 - std::min(s[a] * z0, s[a] * z1) + w - m->f0[a];
                // floor() by truncation (a libm call otherwise): equal where >= 0, and the
                // first clamps to 0 anyway; a last < 0 (no cell) kept apart.
                const double f0 = (g0 - eps[a]) * m->icell[a], f1 = (g1 + eps[a]) * m->icell[a];
                r[a] = f0 > 0.0 ? int(f0) : 0;
                r[2 + a] = f1 >= 0.0 ? std::min(m->nf[a] - 1, int(f1)) : -1;
            }
        };
        // Per column (i, j) of voxels, each run of non-zero voxels up it, across bricks. The
        // cell ranges' ends are linear in the height (the footprint's edges move linearly),
        // so where a run's lowest and highest voxels cover the same cells, so do all between
        // and one update serves the run; else each half in turn (thin voxels: a few updates
        // per column). Slabs of bricks along x on `threads` threads, each thread into a map
        // of its own, merged after.
        const int nt = thread_count(threads, size_t(nb[0]));
        std::vector<std::vector<uint16_t>> own(size_t(nt - 1), m->span);
        parallel_for(size_t(nb[0]), nt, [&](size_t ib, int tid) {
            uint16_t* span = tid == 0 ? m->span.data() : own[size_t(tid - 1)].data();
            auto update = [&](const int* r, int bot, int top) {
                for (int i = r[0]; i <= r[2]; ++i)
                    for (int j = r[1]; j <= r[3]; ++j) {
                        uint16_t* c = &span[2 * (size_t(i) * m->nf[1] + j)];
                        c[0] = std::min(c[0], uint16_t(bot));
                        c[1] = std::max(c[1], uint16_t(top));
                    }
            };
            // Voxels k0..k1 of column (i, j), whose lowest and highest cover cells ra, rb.
            auto cover = [&](auto&& self, int i, int j, int k0, const int* ra, int k1, const int* rb) -> void {
                if (ra[0] == rb[0] && ra[1] == rb[1] && ra[2] == rb[2] && ra[3] == rb[3]) {
                    update(ra, k0, k1 + 1);
                    return;
                }
                const int km = (k0 + k1) / 2;  // (k1 > k0: one voxel covers its own cells)
                int rc[4], rd[4];
                cells(i, j, km, rc);
                cells(i, j, km + 1, rd);
                self(self, i, j, k0, ra, km, rc);
                self(self, i, j, km + 1, rd, k1, rb);
            };
            auto run = [&](int i, int j, int k0, int k1) {
                int ra[4], rb[4];
                cells(i, j, k0, ra);
                cells(i, j, k1, rb);
                cover(cover, i, j, k0, ra, k1, rb);
            };
            const int ib_ = int(ib);
            for (int jb = 0; jb < nb[1]; ++jb) {
                const int32_t* slots = &brick_slot[(size_t(ib_) * nb[1] + jb) * nb[2]];
                for (int li = 0; li < B && ib_ * B + li < n[0]; ++li)
                    for (int lj = 0; lj < B && jb * B + lj < n[1]; ++lj) {
                        const int i = ib_ * B + li, j = jb * B + lj;
                        int k_start = -1;  // the open run's first voxel
                        for (int kb = 0; kb < nb[2]; ++kb) {
                            if (slots[kb] < 0) {
                                if (k_start >= 0) run(i, j, k_start, kb * B - 1);
                                k_start = -1;
                                continue;
                            }
                            const float* row = &bricks[size_t(slots[kb]) * brick_floats() + (li * B + lj) * B];
                            for (int lk = 0; lk < B; ++lk) {
                                const int k = kb * B + lk;
                                bool positive = row[lk] > 0.f;  // any field's
                                for (int f = 1; f < nfields && !positive; ++f) positive = row[f * kB3 + lk] > 0.f;
                                if (positive) {
                                    if (k_start < 0) k_start = k;
                                } else if (k_start >= 0) {
                                    run(i, j, k_start, k - 1);
                                    k_start = -1;
                                }
                            }
                        }
                        if (k_start >= 0) run(i, j, k_start, nb[2] * B - 1);
                    }
            }
        });
        for (const auto& o : own)
            for (size_t c = 0; c < o.size(); c += 2) {
                m->span[c] = std::min(m->span[c], o[c]);
                m->span[c + 1] = std::max(m->span[c + 1], o[c + 1]);
            }
    }

    // The part [t0, t1] of the ray o + d t, t >= 0, where rho may be > 0 (the box of the
    // non-empty voxels); false if none. inv = 1 / d (+-inf where d = 0): no divisions.
    bool clip_occupied(const double* o, const double* inv, double* t0, double* t1) const {
        if (!occupied) return false;
        double a0 = 0.0, a1 = kInf;
        for (int a = 0; a < 3; ++a) {
            if (std::isinf(inv[a])) {
                if (o[a] < occ_lo[a] || o[a] > occ_hi[a]) return false;
                continue;
            }
            double ta = (occ_lo[a] - o[a]) * inv[a], tb = (occ_hi[a] - o[a]) * inv[a];
            if (ta > tb) std::swap(ta, tb);
            a0 = std::max(a0, ta);
            a1 = std::min(a1, tb);
        }
        *t0 = a0;
        *t1 = a1;
        return a1 > a0;
    }

    // The integral of each field's rho along the ray o + d t from t = 0, walked once however
    // often it is asked: value(t) for increasing t continues the walk where the last call
    // stopped, and march() samples free paths exactly along the same walk (regular tracking).
    // A steep ray (kColumnRatio) walks column by column through the columns' prefix sums
    // (walk_columns); any other one voxel DDA over the non-empty voxels' box, in a tight loop
    // per non-empty brick, where an empty brick's clear cube is crossed in one jump. (Walking
    // bricks, then each brick's voxels with a DDA set up per brick, cost 1.5 times as much:
    // most rays cross only a few voxels of each brick.)
    class Cursor {
     public:
        Cursor(const VoxelGrid& g, const Vec3& o, const Vec3& d)
            : g_(&g), o_{o.x, o.y, o.z}, d_{d.x, d.y, d.z}, inv_{1.0 / d.x, 1.0 / d.y, 1.0 / d.z} {
            // (inv_: +-inf along an axis.) The DDA is set up when the walk reaches the box:
            // many segments end before it.
            box_ = g.clip_occupied(o_, inv_, &t0_, &t1_);
            if (!box_) t0_ = t1_ = kInf;
            const double az = std::fabs(d.z) * g.icell[2];
            cols_ = g.columns() && az > 0.0 && az >= kColumnRatio * (std::fabs(d.x) * g.icell[0] + std::fabs(d.y) * g.icell[1]);
        }
        // int_0^t rho_f(o + d s) ds per field, for t at or beyond the position (else the
        // values there).
        const double* value(double t) {
            double xi = kInf, rho[kMaxFields];
            hit_ = false;
            if (t > t_) walk<false>(t, 0.0, nullptr, &xi, rho);
            return sum_;
        }
        // Regular tracking of the coefficient s0 + sum_f s1[f] rho_f (>= 0) from the position
        // on: if its optical depth reaches *xi before t_stop, the position moves there,
        // rho[0..nfields) are the densities there and the result is true; else the position
        // moves to t_stop, *xi loses the depth passed and the result is false.
        bool march(double s0, const double* s1, double* xi, double t_stop, double* rho) {
            std::fill(rho, rho + kMaxFields, 0.0);
            hit_ = false;
            if (t_stop > t_) walk<true>(t_stop, s0, s1, xi, rho);
            return hit_;
        }
        // Asks the memory for the column sums a walk by columns reads first (the entry and
        // exit heights of its first n columns), to be called before independent work such as
        // the ray's intersection: a walk's first lookups are otherwise cache misses waited for
        // one after another, once per path segment.
        void prefetch(int n) {
            if (!cols_ || !box_) return;
            if (!started_) start();
            const VoxelGrid& g = *g_;
            const size_t stride = size_t(g.nzc + 1) * g.nfields;
            const double zeta0 = (o_[2] - g.lo[2]) * g.icell[2] - g.kz0, dzeta = d_[2] * g.icell[2];
            int i = i_, j = j_;
            double tx = tx_, ty = ty_, t = std::max(t_, t0_);
            for (int c = 0; c < n; ++c) {
                const double tb = std::min(std::min(tx, ty), t1_);
                const int32_t slot = g.col_slot[size_t(i) * g.n[1] + j];
                if (slot >= 0)
                    for (const double zeta : {zeta0 + dzeta * t, zeta0 + dzeta * tb}) {
                        const double zc = zeta < 0.0 ? 0.0 : zeta > g.nzc ? g.nzc : zeta;
                        const int k = std::min(g.nzc - 1, int(zc));
                        __builtin_prefetch(&g.col_prefix[size_t(slot) * stride + size_t(k) * g.nfields]);
                    }
                if (tb >= t1_) break;
                t = tb;
                if (tx <= ty) {
                    i += si_;
                    tx += dx_;
                    if (unsigned(i) >= unsigned(g.n[0])) break;
                } else {
                    j += sj_;
                    ty += dy_;
                    if (unsigned(j) >= unsigned(g.n[1])) break;
                }
            }
        }
        double position() const { return t_; }
        bool by_columns() const { return cols_; }
        const double* integral() const { return sum_; }

     private:
        // The 3-D DDA's start: the voxel of a point just inside the clipped ray (robust at
        // faces), then per axis the step, the next face and the distance between faces.
        void start() {
            const VoxelGrid& g = *g_;
            const double tm = 0.5 * (t0_ + std::min(t1_, t0_ + 1e-9 * (1.0 + t1_ - t0_)));
            int idx[3], step[3];
            double next[3], delta[3];
            for (int a = 0; a < 3; ++a) {
                // int() truncates towards 0, which for -1 < x < 0 is the clamp to voxel 0 anyway.
                const double x = (o_[a] + d_[a] * tm - g.lo[a]) * g.icell[a];
                idx[a] = x < 0.0 ? 0 : std::min(g.n[a] - 1, int(x));
                step[a] = d_[a] > 0.0 ? 1 : d_[a] < 0.0 ? -1 : 0;
                next[a] = step[a] ? (g.lo[a] + (idx[a] + (step[a] > 0)) * g.cell[a] - o_[a]) * inv_[a] : kInf;
                delta[a] = step[a] ? step[a] * g.cell[a] * inv_[a] : kInf;
            }
            i_ = idx[0]; j_ = idx[1]; k_ = idx[2];
            si_ = step[0]; sj_ = step[1]; sk_ = step[2];
            tx_ = next[0]; ty_ = next[1]; tz_ = next[2];
            dx_ = delta[0]; dy_ = delta[1]; dz_ = delta[2];
            started_ = true;
        }
        template <bool kTrack>
        void walk(double te, double s0, const double* s1, double* xi, double* rho_hit) {
            switch (g_->nfields) {  // a walk compiled per number of fields (one: the common case)
                case 1: walk_fields<kTrack, 1>(te, s0, s1, xi, rho_hit); break;
                case 2: walk_fields<kTrack, 2>(te, s0, s1, xi, rho_hit); break;
                case 3: walk_fields<kTrack, 3>(te, s0, s1, xi, rho_hit); break;
                default: walk_fields<kTrack, kMaxFields>(te, s0, s1, xi, rho_hit); break;
            }
        }
        template <bool kTrack, int F>
        void walk_fields(double te, double s0, const double* s1, double* xi, double* rho_hit);
        template <bool kTrack, int F, class Empty>
        void walk_columns(double tv, double s0, const double* s1, double& xi, double* sum, double& t,
                          double* rho_hit, Empty& empty_stretch);
        const VoxelGrid* g_;
        double o_[3], d_[3], inv_[3];
        bool started_ = false;  // the DDA is set up
        bool box_ = false;  // the ray crosses the non-empty voxels' box, over [t0_, t1_]
        bool hit_ = false;  // march: the depth was reached
        bool cols_ = false;  // walks by columns (a steep ray: VoxelGrid::col_prefix)
        int i_ = 0, j_ = 0, k_ = 0, si_ = 0, sj_ = 0, sk_ = 0;
        double tx_ = 0, ty_ = 0, tz_ = 0, dx_ = 0, dy_ = 0, dz_ = 0;
        double t0_ = kInf, t1_ = kInf, t_ = 0.0;
        double sum_[kMaxFields] = {};
    };

    // int rho_f dl along the segment from p0 to p1 (length len) into out[0..nfields) (and 0
    // up to kMaxFields).
    void integral(const Vec3& p0, const Vec3& p1, double len, double* out) const {
        std::fill(out, out + kMaxFields, 0.0);
        if (!(len > 0.0)) return;
        Cursor c(*this, p0, (p1 - p0) * (1.0 / len));
        std::copy_n(c.value(len), kMaxFields, out);
    }
};

template <bool kTrack, int F>
void VoxelGrid::Cursor::walk_fields(double te, double s0, const double* s1_in, double* xi_io, double* rho_hit) {
    // Density-free stretches (before and after the box, clear cubes) and voxels of constant
    // density: each adds its integral, and in tracking its optical depth, until te or, in
    // tracking, the sampled depth xi is reached inside one (then the position stops there).
    // F fields: F sums, and in tracking the coefficient s0 + sum_f s1[f] rho_f.
    double xi = *xi_io;
    double t = t_, sum[F], s1[F];
    for (int f = 0; f < F; ++f) {
        sum[f] = sum_[f];
        s1[f] = kTrack ? s1_in[f] : 0.0;
    }
    bool done = false;
    auto empty_stretch = [&](double tb) {  // [t, tb) without density: true if xi is reached
        if (kTrack) {
            const double gain = s0 * (tb - t);
            if (gain >= xi && s0 > 0.0) {
                t += xi / s0;
                xi = 0.0;
                hit_ = true;
                return true;
            }
            xi -= gain;
        }
        t = tb;
        return false;
    };
    if (t < t0_) {  // before the box (or no box: t0_ = kInf)
        if (empty_stretch(std::min(te, t0_)) || t >= te) done = true;
    }
    if (!done && box_ && t < t1_) {
        if (!started_) start();
        if (cols_) {
            walk_columns<kTrack, F>(std::min(te, t1_), s0, s1, xi, sum, t, rho_hit, empty_stretch);
            done = hit_ || t >= te;
        }
    }
    if (!done && !cols_ && box_ && t < t1_) {
        constexpr int M = B - 1;
        const VoxelGrid& g = *g_;
        const double tv = std::min(te, t1_);  // the walk's end in the box
        // The state as locals (kept in registers in the loops), written back on the way out.
        int i = i_, j = j_, k = k_;
        const int si = si_, sj = sj_, sk = sk_;
        double tx = tx_, ty = ty_, tz = tz_;
        const double dx = dx_, dy = dy_, dz = dz_;
        const double idz = 1.0 / dz;  // (a ray with d.z = 0 never steps along z)
        const int ei = si > 0 ? 0 : M, ej = sj > 0 ? 0 : M, ek = sk > 0 ? 0 : M;  // entry faces
        const std::ptrdiff_t n0 = std::ptrdiff_t(g.nb[1]) * g.nb[2], n1 = g.nb[2];
        for (;;) {
            const size_t b = (i >> kShift) * n0 + (j >> kShift) * n1 + (k >> kShift);
            const int clear = g.brick_clear[b];
            if (clear) {
                // An empty brick and its clear cube (radius r): the voxel faces left along
                // each axis before leaving the cube, where the ray leaves first, and every
                // axis's voxel there. Stopping inside, the voxel stays the cube's entry one.
                const int extra = (clear - 1) * B;
                const int li = (si > 0 ? M - (i & M) : (i & M)) + extra;
                const int lj = (sj > 0 ? M - (j & M) : (j & M)) + extra;
                const int lk = (sk > 0 ? M - (k & M) : (k & M)) + extra;
                int ax = -1;
                double tc = tv;
                if (si && tx + li * dx < tc) { tc = tx + li * dx; ax = 0; }
                if (sj && ty + lj * dy < tc) { tc = ty + lj * dy; ax = 1; }
                if (sk && tz + lk * dz < tc) { tc = tz + lk * dz; ax = 2; }
                if (empty_stretch(std::max(t, tc)) || ax < 0) break;
                // The other axes step over every face before tc: counted, not looped (up to
                // 8 r steps with an unpredictable end), then settled exactly.
                auto cross = [tc](double& tf, double dd, int& idx, int st) {
                    if (!(tf < tc)) return;
                    const int m = int((tc - tf) / dd);
                    tf += m * dd;
                    idx += st * m;
                    while (tf < tc) { tf += dd; idx += st; }
                };
                if (ax == 0) { i += si * (li + 1); tx += (li + 1) * dx; } else cross(tx, dx, i, si);
                if (ax == 1) { j += sj * (lj + 1); ty += (lj + 1) * dy; } else cross(ty, dy, j, sj);
                if (ax == 2) { k += sk * (lk + 1); tz += (lk + 1) * dz; } else cross(tz, dz, k, sk);
                if (unsigned(i) >= unsigned(g.n[0]) || unsigned(j) >= unsigned(g.n[1]) || unsigned(k) >= unsigned(g.n[2])) {
                    t1_ = t;  // left the grid: no density beyond
                    break;
                }
                continue;
            }
            // A non-empty brick: voxel after voxel until the ray leaves it or the walk stops.
            // Leaving the grid is checked only where the ray leaves a brick (6 % faster beam
            // walks): inside a partial brick beyond the grid's faces the stored densities are
            // 0, and the walk ends at the box's exit t1_ anyway.
            const float* v = &g.bricks[size_t(g.brick_slot[b]) * (F * kB3)];
            bool stop = false;
            // The voxel's part [t, tb) with densities rho: true if the walk stops in it.
            auto voxel = [&](const double* rho, double tn) __attribute__((always_inline)) {
                const double tb = std::min(tn, tv);
                if (kTrack) {
                    double sig = s0;
                    for (int f = 0; f < F; ++f) sig += s1[f] * rho[f];
                    const double gain = sig * (tb - t);
                    if (gain >= xi && sig > 0.0) {
                        const double tc = t + xi / sig;
                        for (int f = 0; f < F; ++f) sum[f] += rho[f] * (tc - t);
                        t = tc;
                        xi = 0.0;
                        hit_ = true;
                        for (int f = 0; f < F; ++f) rho_hit[f] = rho[f];
                        return true;
                    }
                    xi -= gain;
                }
                for (int f = 0; f < F; ++f) sum[f] += rho[f] * (tb - t);
                t = tb;
                return tn >= tv;
            };
            // The voxel's offset in the brick, moved along with the indices.
            int off = (((i & M) << kShift) + (j & M)) * B + (k & M);
            for (;;) {
                double rho[F];
                for (int f = 0; f < F; ++f) rho[f] = v[off + f * kB3];
                if (tz <= tx && tz <= ty) {
                    // A run along z in one go: this voxel and the next c, whose exit faces all
                    // come before the next x and y faces and the walk's end, within the brick
                    // (steep rays in thin voxels cross many: the beams' walks towards the
                    // sun). In tracking only if the run's optical depth stays below xi; else
                    // voxel by voxel to the collision.
                    const int left = sk > 0 ? M - (k & M) : (k & M);
                    const int c = std::min(left, int((std::min(std::min(tx, ty), tv) - tz) * idz));
                    bool run_taken = false;
                    if (c > 0) {
                        double r[F];
                        const double te_run = tz + c * dz;
                        double gain = kTrack ? s0 * (te_run - t) : 0.0;
                        for (int f = 0; f < F; ++f) {
                            double run = 0.0;
                            for (int m = 1; m <= c; ++m) run += v[off + f * kB3 + m * sk];
                            r[f] = rho[f] * (tz - t) + run * dz;
                            if (kTrack) gain += s1[f] * r[f];
                        }
                        if (!kTrack || gain < xi) {
                            if (kTrack) xi -= gain;
                            for (int f = 0; f < F; ++f) sum[f] += r[f];
                            t = te_run;
                            k += (c + 1) * sk; tz = t + dz; off += (c + 1) * sk;
                            run_taken = true;
                        }
                    }
                    if (!run_taken) {
                        if (voxel(rho, tz)) { stop = true; break; }
                        k += sk; tz += dz; off += sk;
                    }
                    if ((k & M) == ek) {
                        if (unsigned(k) >= unsigned(g.n[2])) { t1_ = t; stop = true; }
                        break;
                    }
                } else if (tx <= ty) {
                    if (voxel(rho, tx)) { stop = true; break; }
                    i += si; tx += dx; off += si * (B * B);
                    if ((i & M) == ei) {
                        if (unsigned(i) >= unsigned(g.n[0])) { t1_ = t; stop = true; }
                        break;
                    }
                } else {
                    if (voxel(rho, ty)) { stop = true; break; }
                    j += sj; ty += dy; off += sj * B;
                    if ((j & M) == ej) {
                        if (unsigned(j) >= unsigned(g.n[1])) { t1_ = t; stop = true; }
                        break;
                    }
                }
            }
            if (stop) break;
        }
        i_ = i; j_ = j; k_ = k;
        tx_ = tx; ty_ = ty; tz_ = tz;
        done = hit_ || t >= te;
    }
    if (!done && t >= t1_ && t < te) empty_stretch(te);  // beyond the box
    t_ = t;
    for (int f = 0; f < F; ++f) sum_[f] = sum[f];
    *xi_io = xi;
}

template <bool kTrack, int F, class Empty>
void VoxelGrid::Cursor::walk_columns(double tv, double s0, const double* s1, double& xi, double* sum, double& t,
                                     double* rho_hit, Empty& empty_stretch) {
    // Column after column of the ray's 2-D DDA in (x, y), to tv (in the box): each field's
    // integral over the column's part [t, tb] is (Q_f(zeta(tb)) - Q_f(zeta(t))) / dzeta, with
    // zeta the height in voxels and Q_f the column's prefix sums interpolated (exact for
    // piecewise-constant voxels, however many the part crosses). In tracking, a column whose
    // optical depth reaches xi is searched over its voxel faces (interpolation search, then
    // bisection) for the voxel of the collision, which is then placed exactly with that
    // voxel's densities.
    const VoxelGrid& g = *g_;
    const size_t stride = size_t(g.nzc + 1) * F;
    const double zeta0 = (o_[2] - g.lo[2]) * g.icell[2] - g.kz0, dzeta = d_[2] * g.icell[2];
    const double idzeta = 1.0 / dzeta, top = g.nzc;
    auto prefix_at = [&](const double* P, double zeta, double* q) __attribute__((always_inline)) {
        const double zc = zeta < 0.0 ? 0.0 : zeta > top ? top : zeta;  // (no density beyond)
        const int k = std::min(g.nzc - 1, int(zc));
        const double fr = zc - k;
        const double* a = P + size_t(k) * F;
        for (int f = 0; f < F; ++f) q[f] = a[f] + fr * (a[F + f] - a[f]);
    };
    int i = i_, j = j_;
    double tx = tx_, ty = ty_;
    const int si = si_, sj = sj_;
    const double dx = dx_, dy = dy_;
    for (;;) {
        const double tb = std::min(std::min(tx, ty), tv);  // where the ray leaves the column (or stops)
        const int32_t slot = g.col_slot[size_t(i) * g.n[1] + j];
        if (slot < 0) {
            if (empty_stretch(tb)) break;
        } else {
            const double* P = &g.col_prefix[size_t(slot) * stride];
            const double za = zeta0 + dzeta * t, zb = zeta0 + dzeta * tb;
            double qa[F], qb[F], in[F];
            prefix_at(P, za, qa);
            prefix_at(P, zb, qb);
            double gain = kTrack ? s0 * (tb - t) : 0.0;
            for (int f = 0; f < F; ++f) {
                in[f] = std::max(0.0, (qb[f] - qa[f]) * idzeta);
                if (kTrack) gain += s1[f] * in[f];
            }
            if (kTrack && gain >= xi && gain > 0.0) {
                // The faces strictly between za and zb in the ray's order are f_m = first +
                // m dir, m < count, at distances off + m from za (in voxels along z). The
                // collision lies between the last face whose depth stays below xi and the next
                // one: a bracket [L, H] of faces (L = -1: za at depth 0; H = count: zb at
                // depth gain) narrowed by interpolation search, each guess read with its
                // neighbour (the same cache line): over voxels of similar densities the depth
                // grows nearly linearly, so guesses land on or next to the voxel. Each guess is
                // a dependent memory access, so few guesses matter more than few operations;
                // after kGuesses, bisection bounds the worst case.
                const int dir = dzeta > 0.0 ? 1 : -1;
                const double first = dir > 0 ? std::floor(za) + 1.0 : std::ceil(za) - 1.0;
                const int count = std::max(0, dir > 0 ? int(std::ceil(zb) - first) : int(first - std::floor(zb)));
                const double off = std::fabs(first - za);
                // The depth from za to face m, with the sums there into q.
                auto face_depth = [&](int m, double* qm) {
                    const int lev = std::min(g.nzc, std::max(0, int(first) + m * dir));
                    const double* a = P + size_t(lev) * F;
                    double dd = s0 * (off + m) * dir;  // (f_m - za)
                    for (int f = 0; f < F; ++f) {
                        qm[f] = a[f];
                        dd += s1[f] * (qm[f] - qa[f]);
                    }
                    return dd * idzeta;
                };
                int L = -1, H = count;
                double dL = 0.0, dH = gain, qL[F], q[F];
                std::copy_n(qa, F, qL);
                auto take = [&](int m, double dm) {  // face m narrows the bracket; true if below xi
                    if (dm >= xi) { H = m; dH = dm; return false; }
                    L = m; dL = dm; std::copy_n(q, F, qL);
                    return true;
                };
                // The first guess from the density of the voxel the ray enters at za (its sums
                // share qa's line): in dense water the collision lies a few voxels on, which a
                // guess between the column's ends misses where the density falls with depth.
                double x_first = -1.0;
                const int k_in = dir > 0 ? int(std::floor(za)) : int(std::ceil(za)) - 1;
                if (k_in >= 0 && k_in < g.nzc) {
                    const double* a = P + size_t(k_in) * F;
                    double sig = s0;
                    for (int f = 0; f < F; ++f) sig += s1[f] * (a[F + f] - a[f]);
                    if (sig > 0.0) x_first = xi / sig * std::fabs(dzeta);  // (voxels along z)
                }
                constexpr int kGuesses = 3;
                for (int guess = 0; H - L > 1; ++guess) {
                    if (guess >= kGuesses) {
                        const int m = (L + H) / 2;
                        take(m, face_depth(m, q));
                        continue;
                    }
                    const double xL = L < 0 ? 0.0 : off + L, xH = H >= count ? std::fabs(zb - za) : off + H;
                    const double x = guess == 0 && x_first >= 0.0 ? std::min(x_first, xH)  // (no overflow below)
                                                                  : xL + (xi - dL) / (dH - dL) * (xH - xL);
                    const int m = std::min(H - 1, std::max(L + 1, int(std::floor(x - off))));
                    if (take(m, face_depth(m, q))) {
                        if (m + 1 < H) take(m + 1, face_depth(m + 1, q));
                    } else if (m - 1 > L) {
                        take(m - 1, face_depth(m - 1, q));
                    }
                }
                const double zs = L < 0 ? za : first + L * dir;
                const double ze = H >= count ? zb : first + H * dir;
                const double ds = dL;
                double qs[F];
                std::copy_n(qL, F, qs);
                // The voxel's densities: its sums' difference (the lines just read; the
                // voxel's value to rounding, and 0 exactly where it is 0).
                double rho[F] = {};
                const int kv = int(std::floor(0.5 * (zs + ze)));
                if (kv >= 0 && kv < g.nzc) {
                    const double* a = P + size_t(kv) * F;
                    for (int f = 0; f < F; ++f) rho[f] = a[F + f] - a[f];
                }
                double sig = s0;
                for (int f = 0; f < F; ++f) sig += s1[f] * rho[f];
                const double ts = t + (zs - za) * idzeta, tend = t + (ze - za) * idzeta;
                const double left = std::max(0.0, xi - ds);
                const double tc = sig > 0.0 ? std::min(tend, ts + left / sig) : tend;
                for (int f = 0; f < F; ++f) {
                    sum[f] += std::max(0.0, (qs[f] - qa[f]) * idzeta) + rho[f] * (tc - ts);
                    rho_hit[f] = rho[f];
                }
                t = tc;
                xi = 0.0;
                hit_ = true;
                break;
            }
            if (kTrack) xi -= gain;
            for (int f = 0; f < F; ++f) sum[f] += in[f];
            t = tb;
        }
        if (t >= tv) break;
        if (tx <= ty) {
            i += si;
            tx += dx;
            if (unsigned(i) >= unsigned(g.n[0])) { t1_ = t; break; }
        } else {
            j += sj;
            ty += dy;
            if (unsigned(j) >= unsigned(g.n[1])) { t1_ = t; break; }
        }
    }
    i_ = i; j_ = j;
    tx_ = tx; ty_ = ty;
}

}  // namespace photic
