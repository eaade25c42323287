#include "phase.h"
#include <algorithm>
#include <cstring>

namespace photic {

namespace {

// The top bits of a non-negative double: its exponent and the first m mantissa bits.
uint64_t x_key(double x, int m) {
    uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    return bits >> (52 - m);
}

}  // namespace

PhaseFunction PhaseFunction::table(const std::vector<double>& x, const std::vector<double>& v) {
    if (x.size() != v.size() || x.size() < 2)
        throw std::invalid_argument("phase table: x and values must have the same length >= 2");
    if (std::fabs(x.front()) > 1e-15 || std::fabs(x.back() - 2.0) > 1e-12)
        throw std::invalid_argument("phase table: x must run from 0 to 2");
    for (size_t i = 0; i < x.size(); ++i) {
        if (!(v[i] >= 0.0) || !std::isfinite(v[i]))
            throw std::invalid_argument("phase table: values must be finite and >= 0");
        if (i > 0 && !(x[i] > x[i - 1])) throw std::invalid_argument("phase table: x must increase");
    }
    PhaseFunction p;
    p.kind_ = kTable;
    p.x_ = x;
    p.v_ = v;
    p.cdf_.assign(x.size(), 0.0);
    for (size_t i = 1; i < x.size(); ++i)
        p.cdf_[i] = p.cdf_[i - 1] + 2.0 * kPi * 0.5 * (v[i - 1] + v[i]) * (x[i] - x[i - 1]);
    double total = p.cdf_.back();
    if (!(total > 0.0)) throw std::invalid_argument("phase table: integral is zero");
    for (auto& c : p.cdf_) c /= total;
    for (auto& val : p.v_) val /= total;
    p.cdf_.back() = 1.0;
    // Guide bins fine enough that a bin's u range mostly lies in one CDF segment (Petzold's
    // 1,041 nodes: 0.25 per bin on average, 32 at most in the tail, against 2 and 132 with
    // 512 bins), so sampling usually reads one segment: a tenth of a path segment's time
    // went to the search before.
    const size_t G = 4096;
    p.guide_.resize(G + 1);
    for (size_t j = 0; j <= G; ++j) {
        double u = double(j) / G;
        p.guide_[j] = uint32_t(std::upper_bound(p.cdf_.begin(), p.cdf_.end(), u) - p.cdf_.begin());
    }
    // x's guide: bins from x_[1]'s to 2's key (none for a first node x_[1] <= 0, which the
    // tolerance on x_[0] allows in principle: binary search then).
    if (!(p.x_[1] > 0.0)) return p;
    p.xkey0_ = x_key(p.x_[1], kXBits);
    const uint64_t nbins = x_key(2.0, kXBits) - p.xkey0_ + 1;
    p.xguide_.resize(nbins);
    for (uint64_t b = 0; b < nbins; ++b) {
        const uint64_t bits = (p.xkey0_ + b) << (52 - kXBits);
        double lo;
        std::memcpy(&lo, &bits, sizeof lo);
        p.xguide_[b] = uint32_t(std::upper_bound(p.x_.begin(), p.x_.end(), lo) - p.x_.begin());
    }
    return p;
}

size_t PhaseFunction::segment(double x) const {
    // (x in [0, 2]: positive doubles order as their bits.)
    const size_t n = x_.size();
    if (xguide_.empty()) {
        const size_t i = size_t(std::upper_bound(x_.begin(), x_.end(), x) - x_.begin());
        return std::min(std::max<size_t>(i, 1), n - 1);
    }
    size_t i = 1;
    if (x >= x_[1]) {
        i = xguide_[x_key(x, kXBits) - xkey0_];
        while (i < n && x_[i] <= x) ++i;
    }
    return std::min(i, n - 1);
}

double PhaseFunction::eval(double x) const {
    x = std::clamp(x, 0.0, 2.0);
    switch (kind_) {
        case kIsotropic: return 1.0 / (4.0 * kPi);
        case kHenyeyGreenstein: {
            double mu = 1.0 - x;
            double den = 1.0 + g_ * g_ - 2.0 * g_ * mu;
            return (1.0 - g_ * g_) / (4.0 * kPi * den * std::sqrt(den));
        }
        case kQuadratic: {
            double mu = 1.0 - x;
            return 3.0 * (1.0 + a_ * mu * mu) / (4.0 * kPi * (3.0 + a_));
        }
        case kTable: {
            const size_t i = segment(x);
            double t = (x - x_[i - 1]) / (x_[i] - x_[i - 1]);
            return v_[i - 1] + t * (v_[i] - v_[i - 1]);
        }
    }
    return 0.0;
}

double PhaseFunction::cdf(double x) const {
    x = std::clamp(x, 0.0, 2.0);
    switch (kind_) {
        case kIsotropic: return 0.5 * x;
        case kHenyeyGreenstein: {
            if (std::fabs(g_) < 1e-5) return 0.5 * x;
            // 2 pi int_0^x p dx' = (1 - g^2)/(2g) [1/(1-g) - 1/sqrt(1 + g^2 - 2g(1 - x))]
            double den = std::sqrt(1.0 + g_ * g_ - 2.0 * g_ * (1.0 - x));
            return std::clamp((1.0 - g_ * g_) / (2.0 * g_) * (1.0 / (1.0 - g_) - 1.0 / den), 0.0, 1.0);
        }
        case kQuadratic: {
            // mass of mu' in [1 - x, 1] of (1 + a mu^2), normalised by 2 + 2a/3
            double mu = 1.0 - x;
            double m = (1.0 - mu) + a_ * (1.0 - mu * mu * mu) / 3.0;
            return std::clamp(m / (2.0 + 2.0 * a_ / 3.0), 0.0, 1.0);
        }
        case kTable: {
            const size_t i = segment(x);
            double t = x - x_[i - 1];
            double v0 = v_[i - 1], slope = (v_[i] - v_[i - 1]) / (x_[i] - x_[i - 1]);
            return std::clamp(cdf_[i - 1] + 2.0 * kPi * (v0 * t + 0.5 * slope * t * t), 0.0, 1.0);
        }
    }
    return 0.0;
}

double PhaseFunction::sample_x(double u) const {
    switch (kind_) {
        case kIsotropic: return 2.0 * u;
        case kHenyeyGreenstein: {
            if (std::fabs(g_) < 1e-5) return 2.0 * u;
            // Inverse CDF written for x = 1 - mu directly (no cancellation near mu = 1);
            // 1 - u so that x grows with u like the other kinds.
            double s = (1.0 - g_ * g_) / (1.0 - g_ + 2.0 * g_ * (1.0 - u));
            double x = (s - (1.0 - g_)) * (s + (1.0 - g_)) / (2.0 * g_);
            return std::clamp(x, 0.0, 2.0);
        }
        case kQuadratic: {
            // CDF in mu: (mu + a mu^3/3 + 1 + a/3) / (2 + 2a/3) = 1 - u (u measured from mu = 1);
            // solve the depressed cubic mu^3 + p mu + q = 0 (one real root since p > 0).
            double target = 1.0 - u;
            if (a_ < 1e-9) return 2.0 * u;
            double p = 3.0 / a_;
            double q = 3.0 * ((1.0 + a_ / 3.0) - target * (2.0 + 2.0 * a_ / 3.0)) / a_;
            double disc = std::sqrt(q * q / 4.0 + p * p * p / 27.0);
            double mu = std::cbrt(-q / 2.0 + disc) + std::cbrt(-q / 2.0 - disc);
            return std::clamp(1.0 - mu, 0.0, 2.0);
        }
        case kTable: {
            size_t G = guide_.size() - 1;
            size_t j = std::min(G - 1, size_t(u * G));
            // The first node above u (as upper_bound) lies in [guide_[j] - 1, guide_[j + 1] + 1):
            // a scan from its start.
            const size_t n = cdf_.size(), end = std::min<size_t>(guide_[j + 1] + 1, n);
            size_t k = size_t(std::max<ptrdiff_t>(ptrdiff_t(guide_[j]) - 1, 0));
            while (k < end && cdf_[k] <= u) ++k;
            size_t i = std::min<size_t>(std::max<size_t>(k, 1), n - 1);
            double dx = x_[i] - x_[i - 1];
            double v0 = v_[i - 1], slope = (v_[i] - v_[i - 1]) / dx;
            double r = (u - cdf_[i - 1]) / (2.0 * kPi);  // area still to cover in this segment
            double disc = std::max(0.0, v0 * v0 + 2.0 * slope * r);
            double den = v0 + std::sqrt(disc);
            double t = den > 0.0 ? 2.0 * r / den : 0.0;  // stable root of v0 t + slope t^2/2 = r
            return std::clamp(x_[i - 1] + std::clamp(t, 0.0, dx), 0.0, 2.0);
        }
    }
    return 0.0;
}

}  // namespace photic
