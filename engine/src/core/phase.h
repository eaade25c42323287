// Phase functions behind one small interface: eval (per steradian, equal to the sampling
// pdf in solid angle) and sample. Angles are passed as x = 1 - cos(psi), which keeps full
// precision in the forward peak where natural waters scatter most of their light.
#pragma once
#include <cstdint>
#include <vector>
#include <string>
#include <stdexcept>
#include "vec.h"

namespace photic {

class PhaseFunction {
public:
    enum Kind { kIsotropic = 0, kHenyeyGreenstein = 1, kQuadratic = 2, kTable = 3 };

    static PhaseFunction isotropic() { PhaseFunction p; p.kind_ = kIsotropic; return p; }
    static PhaseFunction henyey_greenstein(double g) {
        if (!(g > -1.0 && g < 1.0)) throw std::invalid_argument("henyey_greenstein: g must be in (-1, 1)");
        PhaseFunction p; p.kind_ = kHenyeyGreenstein; p.g_ = g; return p;
    }
    // p(psi) proportional to 1 + a cos^2(psi) (a = 0.835 for pure water).
    static PhaseFunction quadratic(double a) {
        if (!(a >= 0.0)) throw std::invalid_argument("quadratic phase function: a must be >= 0");
        PhaseFunction p; p.kind_ = kQuadratic; p.a_ = a; return p;
    }
    // Piecewise linear in x on the given nodes (x ascending from 0 to 2); renormalised here
    // so that the table itself is the phase function and sampling it is exact.
    static PhaseFunction table(const std::vector<double>& x, const std::vector<double>& v);

    Kind kind() const { return kind_; }
    double eval(double x) const;        // 1/sr
    // x = 1 - cos(psi), distributed as 2 pi eval(x) dx; increasing in u (u = 0 gives x = 0).
    double sample_x(double u) const;
    // Fraction of scattering into angles with 1 - cos(psi) <= x (the CDF in x).
    double cdf(double x) const;
    // Direction after scattering from travel direction d, given two uniforms.
    Vec3 sample_direction(const Vec3& d, double u1, double u2) const {
        return direction_around(d, sample_x(u1), 2.0 * kPi * u2);
    }
    const std::vector<double>& table_x() const { return x_; }
    const std::vector<double>& table_values() const { return v_; }

private:
    Kind kind_ = kIsotropic;
    double g_ = 0.0, a_ = 0.0;
    std::vector<double> x_, v_, cdf_;
    std::vector<uint32_t> guide_;  // guide_[j]: first CDF node above j / size (narrows the search)
    // The node segment of x in O(1): x's bits shifted (its exponent and kXBits mantissa bits,
    // 2^kXBits bins per octave, which suits nodes logarithmic in the forward peak) index the
    // first node above the bin's lower edge; a short scan finishes.
    static constexpr int kXBits = 5;
    uint64_t xkey0_ = 0;              // the key of x_[1]
    std::vector<uint32_t> xguide_;
    size_t segment(double x) const;   // i in [1, n - 1] with x_[i - 1] <= x < x_[i] (as upper_bound)
};

}  // namespace photic
