// The sun-disk blur's geometry: the area of a triangle within the unit disk (the disk's image
// around a point, in the coordinates where it is the unit disk), per blurred prism per lookup.
#pragma once
#include <algorithm>
#include <cmath>
#include "vec.h"

namespace photic {

// atan2(y, x) to within 2e-14 rad: reduced to |r| <= tan(pi/8) and a degree-8 polynomial in
// r^2 (least squares on Chebyshev nodes). The blur's overlaps take one per piece of an edge
// outside the disk, where libm's correctly rounded atan2 cost a tenth of a wavy sea's lookups.
inline double atan2_fast(double y, double x) {
    const double ax = std::fabs(x), ay = std::fabs(y);
    const double hi = std::max(ax, ay), lo = std::min(ax, ay);
    if (!(hi > 0.0)) return 0.0;
    double a = lo / hi, base = 0.0;
    constexpr double kTanPi8 = 0.41421356237309503;
    if (a > kTanPi8) {
        a = (a - 1.0) / (a + 1.0);
        base = 0.25 * kPi;
    }
    const double s = a * a;
    double p = 0.03069793728508894;
    for (double c : {-0.05876924587125649, 0.07564372236730019, -0.0907848821144031, 0.11110392704163019,
                     -0.1428569075649446, 0.19999999612109892, -0.3333333333086642, 0.9999999999999737})
        p = p * s + c;
    double th = base + a * p;
    if (ay > ax) th = 0.5 * kPi - th;
    if (x < 0.0) th = kPi - th;
    return y < 0.0 ? -th : th;
}

// The area of the triangle (u_j, v_j) within the unit disk around the origin: exactly pi when
// the disk lies within the triangle. Summed per edge a -> b over the triangle (origin, a, b)
// cut by the circle: its straight parts inside, circular sectors outside (signed).
inline double unit_disk_triangle_overlap(const double u[3], const double v[3]) {
    if (std::min({u[0], u[1], u[2]}) >= 1.0 || std::max({u[0], u[1], u[2]}) <= -1.0 ||
        std::min({v[0], v[1], v[2]}) >= 1.0 || std::max({v[0], v[1], v[2]}) <= -1.0)
        return 0.0;
    const double twice = (u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0]);
    bool all_in = true, far_edges = twice != 0.0;
    for (int j = 0; j < 3; ++j) {
        all_in = all_in && u[j] * u[j] + v[j] * v[j] <= 1.0;
        const int k = (j + 1) % 3;
        const double eu = u[k] - u[j], ev = v[k] - v[j];
        // the origin's distance from the edge's line, positive inside
        const double dist = (eu * (-v[j]) - ev * (-u[j])) * (twice > 0.0 ? 1.0 : -1.0);
        far_edges = far_edges && dist > 0.0 && dist * dist >= eu * eu + ev * ev;
    }
    if (far_edges) return kPi;
    if (all_in) return 0.5 * std::fabs(twice);
    double sum = 0.0;
    for (int j = 0; j < 3; ++j) {
        const int k = (j + 1) % 3;
        const double au = u[j], av = v[j], du = u[k] - au, dv = v[k] - av;
        const double dd = du * du + dv * dv;
        if (!(dd > 0.0)) continue;
        // |a + t d|^2 = 1: the segment's crossings of the circle, in (0, 1)
        double ts[4] = {0.0, 0.0, 0.0, 1.0};
        int nt = 1;
        const double b = au * du + av * dv, c = au * au + av * av - 1.0;
        const double disc = b * b - dd * c;
        if (disc > 0.0) {
            const double r = std::sqrt(disc);
            const double q = b >= 0.0 ? -(b + r) : -(b - r);  // (stable roots)
            double t1 = q / dd, t2 = q != 0.0 ? c / q : t1;
            if (t1 > t2) std::swap(t1, t2);
            if (t1 > 0.0 && t1 < 1.0) ts[nt++] = t1;
            if (t2 > 0.0 && t2 < 1.0) ts[nt++] = t2;
        }
        ts[nt++] = 1.0;
        for (int i = 0; i + 1 < nt; ++i) {
            const double pu = au + du * ts[i], pv = av + dv * ts[i];
            const double qu = au + du * ts[i + 1], qv = av + dv * ts[i + 1];
            const double mu = 0.5 * (pu + qu), mv = 0.5 * (pv + qv);
            const double cr = pu * qv - pv * qu;
            if (mu * mu + mv * mv <= 1.0)
                sum += 0.5 * cr;
            else
                sum += 0.5 * atan2_fast(cr, pu * qu + pv * qv);
        }
    }
    // (a triangle outside the disk leaves sectors that cancel but for rounding, ~1e-16: such
    // overlaps, and any below 1e-12 of the disk, are none)
    const double a = std::fabs(sum);
    return a > 1e-12 ? a : 0.0;
}

}  // namespace photic
