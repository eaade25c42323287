// Rough air-water interface: a microfacet BSDF (Walter, Marschner, Li & Torrance 2007) whose
// facet slopes follow Cox & Munk (1954) as an anisotropic Gaussian, i.e. an anisotropic
// Beckmann distribution. PHYSICS-NOTES 5.1-5.3; docs/physics.md "Rough air-water interface".
//
// Conventions (all directions are unit vectors in world space, pointing AWAY from the surface):
//  * The macroscopic normal is +z. Air (index 1) is on the +z side, water (relative index
//    eta = n_water / n_air, 1.34 by default) on the -z side. Either side may be the one `wi`
//    is on; total internal reflection is handled (from water, beyond the critical angle every
//    facet that would refract reflects instead).
//  * `wi` is the direction the path arrived from (in a camera path tracer: toward the camera /
//    previous vertex); `wo` is the sampled direction the path continues in.
//  * eval() returns the BSDF value f in 1/sr WITHOUT the cosine factor. The estimator is
//    f |wo.z| / pdf, which is exactly the `weight` returned by sample().
//  * Transport mode. kRadiance (default, for paths traced from the camera): f(wi, wo) is the
//    BSDF that turns radiance arriving from wo into radiance leaving toward wi, so a refraction
//    from medium n(wo) into n(wi) carries the n^2 law (n(wi)/n(wo))^2 (smaller than 1 for a
//    camera in air looking into water). kImportance (for light/particle tracing, e.g. beams
//    from the sun): f(wi, wo) scatters flux arriving from wi into wo; no n^2 factor, and
//    the integral of f |wo.z| over all wo is the fraction of the incident flux reflected plus
//    transmitted (<= 1). The two are adjoint: f_importance(a, b) = f_radiance(b, a).
//    Reflection is the same in both modes and reciprocal.
//  * Slopes: per-axis slope variances sigma2_up (along the upwind axis) and sigma2_cross
//    (crosswind); the upwind axis is at angle wind_azimuth from +x toward +y. Cox-Munk's
//    isotropic mean-square slope sigma^2 = 0.003 + 5.12e-3 U is the sum of the two (each axis
//    sigma^2 / 2). Beckmann alpha^2 per axis = 2 sigma2_axis.
//  * Shadowing-masking: Smith, height-correlated. Reflection G = 1 / (1 + L(wi) + L(wo));
//    transmission G = B(1 + L(wi), 1 + L(wo)) (Euler's beta function: a facet at height
//    fraction u is seen by wi with probability u^L(wi) and by wo from the other side with
//    (1 - u)^L(wo)), with L the Gaussian-slope Lambda of PHYSICS-NOTES 5.2.
//  * Sampling: a facet normal h from D(h) (h.n) (the slope vector is a 2-D Gaussian, drawn by
//    Box-Muller from u1, u2), then reflection with probability F(wi.h) (u3 < F) and refraction
//    otherwise. A sample fails (valid = false, weight 0, pdf 0) when wi sees the back of the
//    facet or the scattered direction ends on the wrong side of the macro surface; pdf() is
//    the density of the successful samples, so it integrates to the success probability.
#pragma once
#include "vec.h"

namespace photic {

struct RoughSample {
    Vec3 wo;
    double weight = 0.0;   // f |wo.z| / pdf (0 when not valid)
    double pdf = 0.0;      // solid-angle density of wo
    bool reflection = false;
    bool valid = false;
    Vec3 h;                // the sampled facet normal (world space, on the side of wi)
    double fresnel = 0.0;  // Fresnel reflectance of that facet for wi
};

class RoughInterface {
public:
    enum Mode { kRadiance = 0, kImportance = 1 };

    // Per-axis slope variances (> 0), upwind axis azimuth (radians from +x), eta = n_water/n_air.
    RoughInterface(double sigma2_up, double sigma2_cross, double wind_azimuth = 0.0, double eta = 1.34);

    // (Slope variances from the wind: photic.surface.slope_variances, Cox-Munk, in one place.)

    double eval(const Vec3& wi, const Vec3& wo, Mode mode = kRadiance) const;
    double pdf(const Vec3& wi, const Vec3& wo) const;
    RoughSample sample(const Vec3& wi, double u1, double u2, double u3, Mode mode = kRadiance) const;

    // Microfacet distribution D(h) (1/sr; integral of D(h) h.z over the hemisphere is 1) for a
    // world-space facet normal with h.z > 0, and Smith's Lambda for a direction (either side).
    double distribution(const Vec3& h) const;
    double lambda(const Vec3& w) const;

    double sigma2_up() const { return s2u_; }
    double sigma2_cross() const { return s2c_; }
    double wind_azimuth() const { return phi_w_; }
    double eta() const { return eta_; }

private:
    double s2u_, s2c_, phi_w_, eta_;
    double cw_, sw_;  // cos / sin of the wind azimuth

    // Local frame: x upwind, y crosswind, z up.
    Vec3 to_local(const Vec3& v) const { return Vec3(cw_ * v.x + sw_ * v.y, -sw_ * v.x + cw_ * v.y, v.z); }
    Vec3 to_world(const Vec3& v) const { return Vec3(cw_ * v.x - sw_ * v.y, sw_ * v.x + cw_ * v.y, v.z); }
    double d_local(const Vec3& h) const;
    double lambda_local(const Vec3& w) const;
    // Walter's BSDF f(i -> o) for flux arriving from i (importance form), in the local frame
    // with i.z > 0, and the ratio eta_o / eta_i of the indices on o's and i's sides.
    double eval_local(const Vec3& i, const Vec3& o, double eta_oi) const;
    double pdf_local(const Vec3& i, const Vec3& o, double eta_oi) const;
};

}  // namespace photic
