// A 3-D grid of piecewise-constant densities over an axis-aligned box, stored sparsely in
// bricks, with the walks that gridded water needs: the exact integral of the density along a
// segment (the beams' and paths' optical depths) and a brick-by-brick walk (regional delta
// tracking). The IOPs the densities scale live in Water (scene.h).
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>
#include "vec.h"

namespace photic {

// One density rho >= 0 per voxel; outside the box rho = 0. Empty space is skipped at three
// levels, so that a sparse plume costs little where rays miss it: the box of the non-empty
// voxels, bricks of B^3 voxels (only non-empty ones are stored, each with its largest rho and
// its majorant), and per empty brick the radius of the empty cube of bricks around it, which
// a walk crosses in one jump.
struct VoxelGrid {
    static constexpr int B = 8;        // voxels per brick edge (a power of 2)
    static constexpr int kShift = 3;   // log2(B)
    static constexpr int kClearCap = 4;  // largest empty-cube radius stored (bricks)
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    double cell[3] = {1, 1, 1}, bcell[3] = {1, 1, 1};    // voxel and brick sizes (m)
    double icell[3] = {1, 1, 1}, ibcell[3] = {1, 1, 1};  // 1 / size
    int n[3] = {1, 1, 1}, nb[3] = {1, 1, 1};
    // Non-empty bricks only, B^3 densities each (local (i, j, k) at (i * B + j) * B + k): a
    // sparse plume takes little memory, and a ray's voxels in one brick share cache lines.
    std::vector<float> bricks;
    std::vector<int32_t> brick_slot;  // per brick: its block in `bricks`, or -1 when empty
    std::vector<float> brick_max;     // largest rho per brick, layout (i * nb[1] + j) * nb[2] + k
    std::vector<double> brick_maj;    // majorant per brick (Scene::set_grid_coefficients)
    // Per brick: 0 if non-empty, else r (1..kClearCap) such that every brick within r - 1
    // bricks of it (the cube of side 2 r - 1 around it) is empty.
    std::vector<uint8_t> brick_clear;
    bool occupied = false;            // any rho > 0; then the box of those voxels:
    double occ_lo[3] = {0, 0, 0}, occ_hi[3] = {0, 0, 0};
    float rho_min = 0.f, rho_max = 0.f;

    // The grid over [lo_, hi_] from densities rho[(i * n1 + j) * n2 + k] (not kept); throws
    // std::invalid_argument for a density that is negative or not finite.
    void build(const double* lo_, const double* hi_, const int* n_, const float* rho) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = lo_[a];
            hi[a] = hi_[a];
            n[a] = n_[a];
            cell[a] = (hi[a] - lo[a]) / n[a];
            nb[a] = (n[a] + B - 1) / B;
            bcell[a] = cell[a] * B;
            icell[a] = 1.0 / cell[a];
            ibcell[a] = 1.0 / bcell[a];
        }
        // One pass over the densities: each brick gets its block when its first non-zero
        // voxel is met.
        const size_t nbricks = size_t(nb[0]) * nb[1] * nb[2];
        constexpr int M = B - 1;
        brick_max.assign(nbricks, 0.f);
        brick_slot.assign(nbricks, -1);
        bricks.clear();
        rho_min = rho[0];
        rho_max = rho[0];
        int first[3] = {n[0], n[1], n[2]}, last[3] = {-1, -1, -1};
        const float* r = rho;
        for (int i = 0; i < n[0]; ++i)
            for (int j = 0; j < n[1]; ++j) {
                const size_t row = (size_t(i >> kShift) * nb[1] + (j >> kShift)) * nb[2];
                const int local_ij = ((i & M) * B + (j & M)) * B;
                int kfirst = -1, klast = -1;
                for (int k = 0; k < n[2]; ++k, ++r) {
                    const float v = *r;
                    if (!(v >= 0.f) || !std::isfinite(v))
                        throw std::invalid_argument("densities must be finite and >= 0");
                    rho_min = std::min(rho_min, v);
                    rho_max = std::max(rho_max, v);
                    if (!(v > 0.f)) continue;
                    const size_t b = row + (k >> kShift);
                    if (brick_slot[b] < 0) {
                        brick_slot[b] = int32_t(bricks.size() / (B * B * B));
                        bricks.resize(bricks.size() + B * B * B, 0.f);
                    }
                    bricks[size_t(brick_slot[b]) * B * B * B + local_ij + (k & M)] = v;
                    brick_max[b] = std::max(brick_max[b], v);
                    if (kfirst < 0) kfirst = k;
                    klast = k;
                }
                if (kfirst < 0) continue;
                first[0] = std::min(first[0], i); last[0] = std::max(last[0], i);
                first[1] = std::min(first[1], j); last[1] = std::max(last[1], j);
                first[2] = std::min(first[2], kfirst); last[2] = std::max(last[2], klast);
            }
        bricks.shrink_to_fit();
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
    }

    // brick_clear: the empty bricks' Chebyshev distance to the nearest non-empty brick, capped,
    // by growing the non-empty set one brick at a time (a dilation by a 3^3 cube, one axis at
    // a time).
    void build_clear() {
        const size_t nbricks = brick_slot.size();
        const std::ptrdiff_t stride[3] = {std::ptrdiff_t(nb[1]) * nb[2], nb[2], 1};
        brick_clear.assign(nbricks, uint8_t(kClearCap));
        std::vector<uint8_t> grown(nbricks), next(nbricks);
        for (size_t b = 0; b < nbricks; ++b) {
            grown[b] = brick_slot[b] >= 0;
            if (grown[b]) brick_clear[b] = 0;
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
                if (grown[b] && brick_clear[b] > radius) brick_clear[b] = uint8_t(radius);
        }
    }

    // The density at p (0 outside the box).
    double at(const Vec3& p) const {
        const double q[3] = {p.x, p.y, p.z};
        int idx[3];
        for (int a = 0; a < 3; ++a) {
            if (!(q[a] >= lo[a] && q[a] <= hi[a])) return 0.0;
            idx[a] = std::min(n[a] - 1, std::max(0, int((q[a] - lo[a]) * icell[a])));
        }
        int32_t slot = brick_slot[(size_t(idx[0] >> kShift) * nb[1] + (idx[1] >> kShift)) * nb[2] + (idx[2] >> kShift)];
        if (slot < 0) return 0.0;
        constexpr int M = B - 1;
        return bricks[size_t(slot) * B * B * B + (((idx[0] & M) * B + (idx[1] & M)) * B + (idx[2] & M))];
    }

    // The brick holding p, or -1 outside the box.
    std::ptrdiff_t brick_at(const Vec3& p) const {
        const double q[3] = {p.x, p.y, p.z};
        int idx[3];
        for (int a = 0; a < 3; ++a) {
            if (!(q[a] >= lo[a] && q[a] <= hi[a])) return -1;
            idx[a] = std::min(nb[a] - 1, std::max(0, int((q[a] - lo[a]) * ibcell[a])));
        }
        return (std::ptrdiff_t(idx[0]) * nb[1] + idx[1]) * nb[2] + idx[2];
    }
    // Per brick: 0 if no ray from a point in it along `up` (up.z > 0) crosses a non-empty
    // brick, else 1 (conservative). A ray leaves a brick through its top or the sides `up`
    // points to, so a brick is shaded if it or one of those neighbours is (an edge or a
    // corner is reached through them too); computed from the top down, the neighbours first.
    void shade_bricks(const Vec3& up, std::vector<uint8_t>* shade) const {
        shade->assign(brick_slot.size(), 0);
        const int sx = up.x > 0.0 ? 1 : up.x < 0.0 ? -1 : 0, sy = up.y > 0.0 ? 1 : up.y < 0.0 ? -1 : 0;
        const int sz = up.z > 0.0 ? 1 : up.z < 0.0 ? -1 : 0;
        auto index = [&](int i, int j, int k) { return (size_t(i) * nb[1] + j) * nb[2] + k; };
        auto lit = [&](int i, int j, int k) {  // outside the grid: no density
            return i < 0 || j < 0 || k < 0 || i >= nb[0] || j >= nb[1] || k >= nb[2] || !(*shade)[index(i, j, k)];
        };
        for (int kk = 0; kk < nb[2]; ++kk) {
            const int k = sz > 0 ? nb[2] - 1 - kk : kk;
            for (int ii = 0; ii < nb[0]; ++ii) {
                const int i = sx > 0 ? nb[0] - 1 - ii : ii;
                for (int jj = 0; jj < nb[1]; ++jj) {
                    const int j = sy > 0 ? nb[1] - 1 - jj : jj;
                    bool s = brick_slot[index(i, j, k)] >= 0;
                    if (!s && sz) s = !lit(i, j, k + sz);
                    if (!s && sx) s = !lit(i + sx, j, k);
                    if (!s && sy) s = !lit(i, j + sy, k);
                    (*shade)[index(i, j, k)] = s;
                }
            }
        }
    }

    // The part [t0, t1] of o + d t, t in [0, tmax], inside the box [blo, bhi]; false if none.
    static bool clip(const double* blo, const double* bhi, const Vec3& o, const Vec3& d,
                     double tmax, double* t0, double* t1) {
        const double oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z};
        double a0 = 0.0, a1 = tmax;
        for (int a = 0; a < 3; ++a) {
            if (dd[a] == 0.0) {
                if (oo[a] < blo[a] || oo[a] > bhi[a]) return false;
                continue;
            }
            double ta = (blo[a] - oo[a]) / dd[a], tb = (bhi[a] - oo[a]) / dd[a];
            if (ta > tb) std::swap(ta, tb);
            a0 = std::max(a0, ta);
            a1 = std::min(a1, tb);
        }
        *t0 = a0;
        *t1 = a1;
        return a1 > a0;
    }
    // The part of o + d t, t in [0, tmax], where rho may be > 0 (the non-empty voxels' box).
    bool clip_occupied(const Vec3& o, const Vec3& d, double tmax, double* t0, double* t1) const {
        return occupied && clip(occ_lo, occ_hi, o, d, tmax, t0, t1);
    }

    // A 3-D DDA along o + d t for t in [t0, t1] over cells of size cs (m per axis, from the
    // corner org): the first cell from a point just inside the segment (robust at faces),
    // then one face at a time. No divisions after the set-up.
    struct Dda {
        int idx[3] = {0, 0, 0}, step[3] = {0, 0, 0};
        double tnext[3] = {kInf, kInf, kInf}, tdelta[3] = {kInf, kInf, kInf};
        Dda() = default;
        Dda(const double* o, const double* d, double t0, double t1, const double* org,
            const double* cs, const double* ics, const int* m) {
            const double tm = 0.5 * (t0 + std::min(t1, t0 + 1e-9 * (1.0 + t1 - t0)));
            for (int a = 0; a < 3; ++a) {
                // int() truncates towards 0, which for -1 < x < 0 is the clamp to cell 0 anyway.
                double x = (o[a] + d[a] * tm - org[a]) * ics[a];
                idx[a] = x < 0.0 ? 0 : std::min(m[a] - 1, int(x));
                if (d[a] > 0.0) {
                    step[a] = 1;
                    tnext[a] = (org[a] + (idx[a] + 1) * cs[a] - o[a]) / d[a];
                    tdelta[a] = cs[a] / d[a];
                } else if (d[a] < 0.0) {
                    step[a] = -1;
                    tnext[a] = (org[a] + idx[a] * cs[a] - o[a]) / d[a];
                    tdelta[a] = -cs[a] / d[a];
                } else {
                    step[a] = 0;
                    tnext[a] = kInf;
                    tdelta[a] = kInf;
                }
            }
        }
    };

    // The bricks along o + d t for t in [t0, t1] (inside the box), in order: f(brick, t_enter,
    // t_leave) for the non-empty ones, gap(t_enter, t_leave) for runs of empty ones (an empty
    // brick's clear cube crossed at once); either returns true to stop. Returns true if one did.
    template <class F, class G>
    bool walk_bricks(const Vec3& o, const Vec3& d, double t0, double t1, F&& f, G&& gap) const {
        const double oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z};
        Dda w(oo, dd, t0, t1, lo, bcell, ibcell, nb);
        const std::ptrdiff_t stride[3] = {std::ptrdiff_t(nb[1]) * nb[2], nb[2], 1};
        std::ptrdiff_t lin = w.idx[0] * stride[0] + w.idx[1] * stride[1] + w.idx[2];
        double t = t0;
        for (;;) {
            const int r = brick_clear[lin];
            int a;
            double tb;
            if (r > 1) {  // an empty cube of side 2 r - 1: leave it along its first face
                double te = kInf;
                a = 0;
                for (int c = 0; c < 3; ++c) {
                    if (!w.step[c]) continue;
                    double tc = w.tnext[c] + (r - 1) * w.tdelta[c];
                    if (tc < te) { te = tc; a = c; }
                }
                tb = std::min(std::max(te, t), t1);
                if (gap(t, tb)) return true;
                if (tb >= t1) return false;
                for (int c = 0; c < 3; ++c) {  // the other axes: their last face before te
                    if (c == a) continue;
                    while (w.tnext[c] < te) { w.tnext[c] += w.tdelta[c]; w.idx[c] += w.step[c]; }
                }
                w.idx[a] += w.step[a] * (r - 1);
                w.tnext[a] += (r - 1) * w.tdelta[a];
            } else {
                a = w.tnext[0] < w.tnext[1] ? (w.tnext[0] < w.tnext[2] ? 0 : 2) : (w.tnext[1] < w.tnext[2] ? 1 : 2);
                tb = std::min(std::max(w.tnext[a], t), t1);
                if (r == 0 ? f(size_t(lin), t, tb) : gap(t, tb)) return true;
                if (tb >= t1) return false;
            }
            t = tb;
            w.idx[a] += w.step[a];
            w.tnext[a] += w.tdelta[a];
            if (unsigned(w.idx[0]) >= unsigned(nb[0]) || unsigned(w.idx[1]) >= unsigned(nb[1]) ||
                unsigned(w.idx[2]) >= unsigned(nb[2]))
                return false;
            lin = w.idx[0] * stride[0] + w.idx[1] * stride[1] + w.idx[2];
        }
    }

    // The integral of rho along the ray o + d t from t = 0, walked once however often it is
    // asked: value(t) for increasing t continues the walk where the last call stopped. One
    // voxel DDA over the non-empty voxels' box, in a tight loop per non-empty brick; an empty
    // brick's clear cube is crossed in one jump. (Walking bricks, then each brick's voxels
    // with a DDA set up per brick, cost 1.5 times as much: most rays cross only a few voxels
    // of each brick.)
    class Cursor {
     public:
        Cursor(const VoxelGrid& g, const Vec3& o, const Vec3& d) : g_(&g) {
            double t0, t1;
            if (!g.clip_occupied(o, d, kInf, &t0, &t1)) return;
            const double oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z};
            const Dda w(oo, dd, t0, t1, g.lo, g.cell, g.icell, g.n);
            i_ = w.idx[0]; j_ = w.idx[1]; k_ = w.idx[2];
            si_ = w.step[0]; sj_ = w.step[1]; sk_ = w.step[2];
            tx_ = w.tnext[0]; ty_ = w.tnext[1]; tz_ = w.tnext[2];
            dx_ = w.tdelta[0]; dy_ = w.tdelta[1]; dz_ = w.tdelta[2];
            t_ = t0;
            t1_ = t1;
            live_ = true;
        }
        // int_0^t rho(o + d s) ds, for t at or beyond the last call's (else that one's value).
        double value(double t) {
            if (live_ && t > t_) walk(std::min(t, t1_));
            return sum_;
        }

     private:
        void walk(double te);
        const VoxelGrid* g_;
        bool live_ = false;  // false: no density (left) on this ray
        int i_ = 0, j_ = 0, k_ = 0, si_ = 0, sj_ = 0, sk_ = 0;
        double tx_ = 0, ty_ = 0, tz_ = 0, dx_ = 0, dy_ = 0, dz_ = 0;
        double t_ = 0.0, t1_ = 0.0, sum_ = 0.0;
    };

    // int rho dl along the segment from p0 to p1 (length len).
    double integral(const Vec3& p0, const Vec3& p1, double len) const {
        if (!(len > 0.0)) return 0.0;
        return Cursor(*this, p0, (p1 - p0) * (1.0 / len)).value(len);
    }

    // Regional delta tracking along o + d t: the tentative collisions drawn against the
    // bricks' majorants (m0, the base water's, in empty bricks and outside the non-empty
    // voxels' box), one after the other, each brick stepped over once.
    class Flight {
     public:
        Flight(const VoxelGrid& g, const Vec3& o, const Vec3& d, double m0) : g_(&g), m0_(m0) {
            double t0, t1;
            maj_ = m0;
            if (!g.clip_occupied(o, d, kInf, &t0, &t1)) return;  // base water all along
            const double oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z};
            w_ = Dda(oo, dd, t0, t1, g.lo, g.bcell, g.ibcell, g.nb);
            end_ = t0;   // the base water up to the box, then the bricks
            t1_ = t1;
            in_box_ = true;
        }
        // The next tentative collision's distance (kInf if none) for an Exp(1) sample xi, and
        // the majorant there.
        double next(double xi, double* maj) {
            for (;;) {
                const double room = maj_ * (end_ - t_);
                if (maj_ > 0.0 && xi < room) {
                    t_ += xi / maj_;
                    *maj = maj_;
                    return t_;
                }
                if (end_ >= kInf) return kInf;
                xi -= room;
                t_ = end_;
                advance();
            }
        }

     private:
        void advance();
        const VoxelGrid* g_;
        double m0_;
        Dda w_{};
        double t_ = 0.0, end_ = kInf, maj_ = 0.0, t1_ = 0.0;
        bool in_box_ = false, started_ = false;
        int jump_axis_ = -1, jump_ = 0;  // the step the current region ends with
    };
};

inline void VoxelGrid::Cursor::walk(double te) {
    constexpr int M = B - 1;
    const VoxelGrid& g = *g_;
    // The state as locals (kept in registers in the loops), written back on the way out.
    int i = i_, j = j_, k = k_;
    const int si = si_, sj = sj_, sk = sk_;
    double tx = tx_, ty = ty_, tz = tz_, t = t_, sum = sum_;
    const double dx = dx_, dy = dy_, dz = dz_;
    const int ei = si > 0 ? 0 : M, ej = sj > 0 ? 0 : M, ek = sk > 0 ? 0 : M;  // entry faces
    const std::ptrdiff_t s0 = std::ptrdiff_t(g.nb[1]) * g.nb[2], s1 = g.nb[2];
    bool live = true;
    for (;;) {
        const size_t b = (i >> kShift) * s0 + (j >> kShift) * s1 + (k >> kShift);
        const int32_t slot = g.brick_slot[b];
        if (slot < 0) {
            // An empty brick and its clear cube (radius r): the voxel faces left along each
            // axis before leaving the cube, where the ray leaves first, and every axis's voxel
            // there.
            const int extra = (g.brick_clear[b] - 1) * B;
            const int li = (si > 0 ? M - (i & M) : (i & M)) + extra;
            const int lj = (sj > 0 ? M - (j & M) : (j & M)) + extra;
            const int lk = (sk > 0 ? M - (k & M) : (k & M)) + extra;
            int ax = -1;
            double tc = te;
            if (si && tx + li * dx < tc) { tc = tx + li * dx; ax = 0; }
            if (sj && ty + lj * dy < tc) { tc = ty + lj * dy; ax = 1; }
            if (sk && tz + lk * dz < tc) { tc = tz + lk * dz; ax = 2; }
            if (ax < 0) { t = te; break; }  // the walk stops in the cube
            if (ax == 0) { i += si * (li + 1); tx += (li + 1) * dx; } else { while (tx < tc) { tx += dx; i += si; } }
            if (ax == 1) { j += sj * (lj + 1); ty += (lj + 1) * dy; } else { while (ty < tc) { ty += dy; j += sj; } }
            if (ax == 2) { k += sk * (lk + 1); tz += (lk + 1) * dz; } else { while (tz < tc) { tz += dz; k += sk; } }
            t = tc;
            if (unsigned(i) >= unsigned(g.n[0]) || unsigned(j) >= unsigned(g.n[1]) || unsigned(k) >= unsigned(g.n[2])) {
                live = false;
                break;
            }
            continue;
        }
        // A non-empty brick: voxel after voxel until the ray leaves it or the walk stops.
        const float* v = &g.bricks[size_t(slot) * B * B * B];
        bool stop = false;
        for (;;) {
            const double rho = v[(((i & M) << kShift) + (j & M)) * B + (k & M)];
            if (tz <= tx && tz <= ty) {
                if (tz >= te) { sum += rho * (te - t); t = te; stop = true; break; }
                sum += rho * (tz - t);
                t = tz; k += sk; tz += dz;
                if (unsigned(k) >= unsigned(g.n[2])) { live = false; stop = true; break; }
                if ((k & M) == ek) break;
            } else if (tx <= ty) {
                if (tx >= te) { sum += rho * (te - t); t = te; stop = true; break; }
                sum += rho * (tx - t);
                t = tx; i += si; tx += dx;
                if (unsigned(i) >= unsigned(g.n[0])) { live = false; stop = true; break; }
                if ((i & M) == ei) break;
            } else {
                if (ty >= te) { sum += rho * (te - t); t = te; stop = true; break; }
                sum += rho * (ty - t);
                t = ty; j += sj; ty += dy;
                if (unsigned(j) >= unsigned(g.n[1])) { live = false; stop = true; break; }
                if ((j & M) == ej) break;
            }
        }
        if (stop) break;
    }
    i_ = i; j_ = j; k_ = k;
    tx_ = tx; ty_ = ty; tz_ = tz;
    t_ = t;
    sum_ = sum;
    live_ = live && t < t1_;
}

inline void VoxelGrid::Flight::advance() {
    // The region that starts at end_: the first brick (entering the box), the next brick or
    // clear cube, or the base water beyond the box.
    const VoxelGrid& g = *g_;
    if (!in_box_) {
        maj_ = m0_;
        end_ = kInf;
        return;
    }
    if (started_) {  // step past the region that just ended
        const int a = jump_axis_;
        w_.idx[a] += w_.step[a] * jump_;
        w_.tnext[a] += jump_ * w_.tdelta[a];
        if (end_ >= t1_ || unsigned(w_.idx[0]) >= unsigned(g.nb[0]) ||
            unsigned(w_.idx[1]) >= unsigned(g.nb[1]) || unsigned(w_.idx[2]) >= unsigned(g.nb[2])) {
            in_box_ = false;
            maj_ = m0_;
            end_ = kInf;
            return;
        }
    }
    started_ = true;
    const size_t b = (size_t(w_.idx[0]) * g.nb[1] + w_.idx[1]) * g.nb[2] + w_.idx[2];
    const int r = g.brick_clear[b];
    const int extra = r > 1 ? r - 1 : 0;  // a clear cube reaches r - 1 bricks further
    double te = kInf;
    int a = 0;
    for (int c = 0; c < 3; ++c) {
        if (!w_.step[c]) continue;
        const double tc = w_.tnext[c] + extra * w_.tdelta[c];
        if (tc < te) { te = tc; a = c; }
    }
    if (extra > 0)  // the other axes: their last face before the cube's exit
        for (int c = 0; c < 3; ++c) {
            if (c == a) continue;
            while (w_.tnext[c] < te) { w_.tnext[c] += w_.tdelta[c]; w_.idx[c] += w_.step[c]; }
        }
    jump_axis_ = a;
    jump_ = extra + 1;
    maj_ = r == 0 ? g.brick_maj[b] : m0_;
    end_ = std::max(t_, std::min(te, t1_));
}

}  // namespace photic
