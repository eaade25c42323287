// Rough air-water interface (see rough_interface.h for the conventions).
#include "rough_interface.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "optics.h"

namespace photic {

namespace {

constexpr double kSqrtPi = 1.77245385090551602730;

// Smith Lambda of a Gaussian slope distribution, nu = cot(theta) / (sqrt(2) w) with w^2 the
// per-axis slope variance in the plane of the direction.
double smith_lambda(double nu) {
    if (!(nu > 0.0)) return kInf;  // grazing: every facet masks
    if (nu > 8.0) return 0.0;       // below 1e-29
    double l = 0.5 * (std::exp(-nu * nu) / (nu * kSqrtPi) - std::erfc(nu));
    return std::max(0.0, l);
}

// Height-correlated Smith G for transmission: B(1 + a, 1 + b) (Euler beta function).
// Transmission from i to o (o.z < 0, local frame, eta_oi = n_i / n_o): the generalised half
// vector h (on the side of i), the cosines ci, co of i and o with it, the Fresnel reflectance
// F at ci and denom = ci + eta_oi co; false when no microfacet transmits i into o.
struct Transmission {
    Vec3 h;
    double ci, co, F, denom;
};
bool transmission(const Vec3& i, const Vec3& o, double eta_oi, Transmission* t) {
    t->h = normalize(i + o * eta_oi);
    if (t->h.z < 0.0) t->h = -t->h;
    t->ci = dot(i, t->h);
    t->co = dot(o, t->h);
    if (!(t->ci > 0.0) || !(t->co < 0.0)) return false;
    t->F = fresnel_unpolarized(t->ci, 1.0, eta_oi);
    if (t->F >= 1.0) return false;
    t->denom = t->ci + eta_oi * t->co;
    return true;
}

double beta_shadowing(double a, double b) {
    if (a >= kInf || b >= kInf) return 0.0;
    return std::exp(std::lgamma(1.0 + a) + std::lgamma(1.0 + b) - std::lgamma(2.0 + a + b));
}

}  // namespace

RoughInterface::RoughInterface(double sigma2_up, double sigma2_cross, double wind_azimuth, double eta)
    : s2u_(sigma2_up), s2c_(sigma2_cross), phi_w_(wind_azimuth), eta_(eta) {
    if (!(sigma2_up > 0.0) || !std::isfinite(sigma2_up))
        throw std::invalid_argument("RoughInterface: sigma2_up (upwind slope variance) must be > 0, got " +
                                    std::to_string(sigma2_up));
    if (!(sigma2_cross > 0.0) || !std::isfinite(sigma2_cross))
        throw std::invalid_argument("RoughInterface: sigma2_cross (crosswind slope variance) must be > 0, got " +
                                    std::to_string(sigma2_cross));
    if (!(eta > 0.0) || eta == 1.0 || !std::isfinite(eta))
        throw std::invalid_argument("RoughInterface: eta (n_water / n_air) must be > 0 and != 1, got " +
                                    std::to_string(eta));
    if (!std::isfinite(wind_azimuth))
        throw std::invalid_argument("RoughInterface: wind_azimuth must be finite");
    cw_ = std::cos(wind_azimuth);
    sw_ = std::sin(wind_azimuth);
}

double RoughInterface::d_local(const Vec3& h) const {
    if (!(h.z > 0.0)) return 0.0;
    double zx = h.x / h.z, zy = h.y / h.z;  // slopes up to sign (the Gaussian is even)
    double p22 = std::exp(-0.5 * (zx * zx / s2u_ + zy * zy / s2c_)) / (2.0 * kPi * std::sqrt(s2u_ * s2c_));
    double c2 = h.z * h.z;
    return p22 / (c2 * c2);
}

double RoughInterface::lambda_local(const Vec3& w) const {
    double t2 = s2u_ * w.x * w.x + s2c_ * w.y * w.y;  // (per-axis variance in w's plane) x sin^2
    if (t2 <= 0.0) return 0.0;                          // normal direction: no masking
    return smith_lambda(std::fabs(w.z) / std::sqrt(2.0 * t2));
}

double RoughInterface::distribution(const Vec3& h) const { return d_local(to_local(h)); }
double RoughInterface::lambda(const Vec3& w) const { return lambda_local(to_local(w)); }

double RoughInterface::eval_local(const Vec3& i, const Vec3& o, double eta_oi) const {
    if (o.z > 0.0) {  // reflection
        Vec3 h = normalize(i + o);
        double ci = dot(i, h);
        if (!(ci > 0.0)) return 0.0;
        double F = fresnel_unpolarized(ci, 1.0, eta_oi);
        double G = 1.0 / (1.0 + lambda_local(i) + lambda_local(o));
        return F * d_local(h) * G / (4.0 * i.z * o.z);
    }
    Transmission t;
    if (o.z < 0.0 && transmission(i, o, eta_oi, &t)) {
        double G = beta_shadowing(lambda_local(i), lambda_local(o));
        return t.ci * (-t.co) / (i.z * (-o.z)) * eta_oi * eta_oi * (1.0 - t.F) * G * d_local(t.h) /
               (t.denom * t.denom);
    }
    return 0.0;
}

double RoughInterface::pdf_local(const Vec3& i, const Vec3& o, double eta_oi) const {
    if (o.z > 0.0) {
        Vec3 h = normalize(i + o);
        double ci = dot(i, h);
        if (!(ci > 0.0)) return 0.0;
        double F = fresnel_unpolarized(ci, 1.0, eta_oi);
        return d_local(h) * h.z * F / (4.0 * ci);
    }
    Transmission t;
    if (o.z < 0.0 && transmission(i, o, eta_oi, &t))
        return d_local(t.h) * t.h.z * (1.0 - t.F) * eta_oi * eta_oi * (-t.co) / (t.denom * t.denom);
    return 0.0;
}

double RoughInterface::eval(const Vec3& wi, const Vec3& wo, Mode mode) const {
    Vec3 i = to_local(wi), o = to_local(wo);
    if (i.z == 0.0) return 0.0;
    double eta_oi = eta_;
    if (i.z < 0.0) {  // arriving from the water: mirror so that i is on top
        i.z = -i.z;
        o.z = -o.z;
        eta_oi = 1.0 / eta_;
    }
    double f = eval_local(i, o, eta_oi);
    if (mode == kRadiance && o.z < 0.0) f /= eta_oi * eta_oi;  // n^2 law: (n(wi) / n(wo))^2
    return f;
}

double RoughInterface::pdf(const Vec3& wi, const Vec3& wo) const {
    Vec3 i = to_local(wi), o = to_local(wo);
    if (i.z == 0.0) return 0.0;
    double eta_oi = eta_;
    if (i.z < 0.0) {
        i.z = -i.z;
        o.z = -o.z;
        eta_oi = 1.0 / eta_;
    }
    return pdf_local(i, o, eta_oi);
}

RoughSample RoughInterface::sample(const Vec3& wi, double u1, double u2, double u3, Mode mode) const {
    RoughSample s;
    Vec3 i = to_local(wi);
    if (i.z == 0.0) return s;
    bool below = i.z < 0.0;
    double eta_oi = eta_;
    if (below) {
        i.z = -i.z;
        eta_oi = 1.0 / eta_;
    }
    // Facet normal from D(h) h.z: the slope vector is Gaussian with the per-axis variances.
    double r = std::sqrt(-2.0 * std::log1p(-std::min(u1, 1.0 - 1e-16)));
    double phi = 2.0 * kPi * u2;
    Vec3 h = normalize(Vec3(-std::sqrt(s2u_) * r * std::cos(phi), -std::sqrt(s2c_) * r * std::sin(phi), 1.0));
    double ci = dot(i, h);
    if (!(ci > 0.0)) return s;  // wi sees the back of this facet
    double F = fresnel_unpolarized(ci, 1.0, eta_oi);
    double D = d_local(h);
    Vec3 o;
    if (u3 < F) {
        o = h * (2.0 * ci) - i;
        if (!(o.z > 0.0)) return s;
        double G = 1.0 / (1.0 + lambda_local(i) + lambda_local(o));
        s.weight = G * ci / (i.z * h.z);
        s.pdf = D * h.z * F / (4.0 * ci);
        s.reflection = true;
    } else {
        if (!refract(-i, h, 1.0, eta_oi, &o)) return s;  // not reached: F = 1 on TIR
        if (!(o.z < 0.0)) return s;
        double co = dot(o, h);
        double denom = ci + eta_oi * co;
        double G = beta_shadowing(lambda_local(i), lambda_local(o));
        s.weight = G * ci / (i.z * h.z);
        if (mode == kRadiance) s.weight /= eta_oi * eta_oi;
        s.pdf = D * h.z * (1.0 - F) * eta_oi * eta_oi * (-co) / (denom * denom);
        s.reflection = false;
    }
    s.fresnel = F;
    s.h = to_world(below ? Vec3(h.x, h.y, -h.z) : h);
    if (below) o.z = -o.z;
    s.wo = to_world(o);
    s.valid = s.pdf > 0.0;
    if (!s.valid) s.weight = 0.0;
    return s;
}

}  // namespace photic
