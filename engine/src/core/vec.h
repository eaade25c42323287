// Small double-precision vector algebra used throughout the core.
#pragma once
#include <cmath>
#include <algorithm>

namespace photic {

struct Vec3 {
    double x = 0, y = 0, z = 0;
    Vec3() = default;
    Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
    Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
    Vec3 operator-() const { return {-x, -y, -z}; }
    Vec3& operator+=(const Vec3& o) { x += o.x; y += o.y; z += o.z; return *this; }
    double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};

inline double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3& a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalize(const Vec3& a) { double l = length(a); return l > 0 ? a * (1.0 / l) : a; }
inline double max_abs(const Vec3& a) { return std::max({std::fabs(a.x), std::fabs(a.y), std::fabs(a.z)}); }
// floor(v) and ceil(v) as integers, for |v| < 2^62: the same as long(std::floor(v)), without
// the libm call (the core is built without SSE4.1's rounding instructions) in the beams'
// lookups, which take several per point.
inline long floor_to_long(double v) { const long i = long(v); return i - long(v < double(i)); }
inline long ceil_to_long(double v) { const long i = long(v); return i + long(v > double(i)); }

// Orthonormal basis around a unit vector (Duff et al. 2017, branchless and robust).
struct Frame {
    Vec3 s, t, n;
    explicit Frame(const Vec3& nn) : n(nn) {
        double sign = std::copysign(1.0, n.z);
        double a = -1.0 / (sign + n.z);
        double b = n.x * n.y * a;
        s = Vec3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        t = Vec3(b, sign + n.y * n.y * a, -n.y);
    }
    Vec3 to_world(const Vec3& v) const { return s * v.x + t * v.y + n * v.z; }
    Vec3 to_local(const Vec3& v) const { return Vec3(dot(v, s), dot(v, t), dot(v, n)); }
};

// Direction at polar cosine mu (with 1 - mu = x given separately for precision near mu = 1)
// and azimuth phi around axis n.
inline Vec3 direction_around(const Vec3& n, double x_one_minus_mu, double phi) {
    double mu = 1.0 - x_one_minus_mu;
    double sin_t = std::sqrt(std::max(0.0, x_one_minus_mu * (2.0 - x_one_minus_mu)));
    Frame f(n);
    return normalize(f.to_world(Vec3(sin_t * std::cos(phi), sin_t * std::sin(phi), mu)));
}

constexpr double kPi = 3.14159265358979323846;
constexpr double kInvPi = 1.0 / kPi;
constexpr double kInf = 1e300;

}  // namespace photic
