// Interface optics: Snell's law and unpolarised Fresnel reflectance.
#pragma once
#include "vec.h"

namespace photic {

// Unpolarised Fresnel reflectance for light arriving in medium n1 at cosine cos_i onto n2.
// Returns 1 beyond the critical angle (total internal reflection).
inline double fresnel_unpolarized(double cos_i, double n1, double n2) {
    cos_i = std::clamp(cos_i, 0.0, 1.0);
    double eta = n1 / n2;
    double sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if (sin2_t >= 1.0) return 1.0;
    double cos_t = std::sqrt(1.0 - sin2_t);
    double rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    double rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

// Refracted direction of unit direction d through a surface with unit normal nf facing the
// incoming side (dot(d, nf) < 0). Returns false on total internal reflection.
inline bool refract(const Vec3& d, const Vec3& nf, double n1, double n2, Vec3* out) {
    double cos_i = -dot(d, nf);
    double eta = n1 / n2;
    double sin2_t = eta * eta * std::max(0.0, 1.0 - cos_i * cos_i);
    if (sin2_t >= 1.0) return false;
    double cos_t = std::sqrt(1.0 - sin2_t);
    *out = normalize(d * eta + nf * (eta * cos_i - cos_t));
    return true;
}

inline Vec3 reflect(const Vec3& d, const Vec3& nf) { return d - nf * (2.0 * dot(d, nf)); }

}  // namespace photic
