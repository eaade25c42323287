// The compiled scene: geometry in Embree, water bodies, sun, sky and sensors.
// Built once from Python (photic.compile), then traced from many threads without the GIL.
#pragma once
#include <embree3/rtcore.h>
#include <array>
#include <atomic>
#include <cstdint>
#include <vector>
#include "phase.h"
#include "rng.h"
#include "vec.h"

namespace photic {

constexpr int kMaxBands = 16;  // bands per render pass; larger band lists are split in groups

struct Spectrum {
    std::array<double, kMaxBands> v{};
    static Spectrum constant(double c) { Spectrum s; s.v.fill(c); return s; }
};

struct Material {  // Lambertian
    Spectrum reflectance;
};

struct ScatterComponent {
    int phase = 0;   // index into Scene::phases
    Spectrum b;      // scattering coefficient per band, 1/m
};

struct Water {
    double ior = 1.34;
    Spectrum a;                          // absorption per band, 1/m
    Spectrum b;                          // total scattering per band, 1/m
    std::vector<ScatterComponent> components;
    double majorant = 0.0;               // >= b in every band (delta tracking)
    double a_min = 0.0;                  // smallest absorption over the bands
};

enum class SurfaceKind : int { kOpaque = 0, kWaterBoundary = 1 };

struct MeshRecord {  // one Embree geometry of the main scene
    SurfaceKind kind = SurfaceKind::kOpaque;
    int index = 0;   // material (opaque) or water body (boundary)
    std::vector<float> vertices;      // xyz
    std::vector<uint32_t> triangles;  // ijk
};

struct Hit {
    bool valid = false;
    double t = kInf;
    Vec3 n;               // unit geometric normal (outward for water boundaries)
    SurfaceKind kind = SurfaceKind::kOpaque;
    int index = -1;
};

enum class Quantity : int {
    kEd = 0, kEu = 1, kEo = 2, kEod = 3, kEou = 4, kRadiance = 5, kRadianceDistribution = 6
};

struct Radiometer {
    Quantity quantity = Quantity::kEd;
    Vec3 position;
    Vec3 direction{0, 0, -1};
    double cos_half_angle = 0.0;
    int polar_bins = 1, azimuth_bins = 1;
    int medium = -1;  // resolved at commit
    int bins() const { return quantity == Quantity::kRadianceDistribution ? polar_bins * azimuth_bins : 1; }
};

struct Camera {
    bool orthographic = false;
    Vec3 position, forward, right, up;   // orthonormal
    double tan_half_fov = 0.4, ortho_width = 2.0;
    int width = 64, height = 64;
    int filter = 0;            // 0 box, 1 gaussian
    double filter_width = 1.0; // px: box full width; gaussian FWHM
    int medium = -1;
};

struct alignas(64) Counters {  // one cache line each: no false sharing between threads
    uint64_t segments = 0;   // ray-geometry queries along paths (closest hit)
    uint64_t shadow_rays = 0;
    uint64_t paths = 0;
};

class Scene {
public:
    Scene();
    ~Scene();
    Scene(const Scene&) = delete;
    Scene& operator=(const Scene&) = delete;

    // --- building ---------------------------------------------------------------
    int nbands = 1;
    std::vector<Material> materials;
    std::vector<PhaseFunction> phases;
    std::vector<Water> waters;
    std::vector<MeshRecord> meshes;
    std::vector<Camera> cameras;
    std::vector<Radiometer> radiometers;

    // Ocean: water below a surface unbounded horizontally.
    int ocean_water = -1;             // -1: no ocean
    bool ocean_flat = true;
    double ocean_z = 0.0;             // flat surface height (or patch mean)
    std::vector<float> patch_vertices;
    std::vector<uint32_t> patch_triangles;
    double patch_x0 = 0, patch_y0 = 0, patch_lx = 1, patch_ly = 1, patch_zmin = 0, patch_zmax = 0;
    bool has_bottom = false;
    double bottom_z = 0.0;
    int bottom_material = -1;

    bool has_sun = false;
    Vec3 sun_dir{0, 0, 1};           // towards the sun
    double sun_cos_half = 1.0;       // cosine of angular radius
    Spectrum sun_radiance;           // uniform disk radiance

    int sky_type = 0;                // 0 black, 1 uniform, 2 cardioidal
    bool sky_full_sphere = false;    // uniform radiance below the horizon too (furnace tests)
    Spectrum sky_l0;

    uint64_t seed = 0;
    int max_depth = 256;
    int rr_depth = 8;

    void commit();                    // builds the BVHs and resolves sensor media

    // --- queries ----------------------------------------------------------------
    Hit intersect(const Vec3& o, const Vec3& d, double tmax = kInf) const;  // closest hit before tmax
    bool occluded(const Vec3& o, const Vec3& d) const;  // to infinity
    int medium_at(const Vec3& p) const;
    double offset_for(const Vec3& p) const { return eps_ + 4e-6 * max_abs(p); }

    // --- light ------------------------------------------------------------------
    Spectrum sky_radiance(const Vec3& d) const;
    bool in_sun(const Vec3& d) const { return has_sun && dot(d, sun_dir) >= sun_cos_half; }
    Vec3 sample_sun(double u1, double u2) const;
    double sun_pdf() const { return 1.0 / (2.0 * kPi * (1.0 - sun_cos_half)); }

    // Radiance arriving at o from direction -d (a backward path started along d).
    Spectrum trace(Vec3 o, Vec3 d, int medium, bool sun_covered, Rng& rng, Counters& c) const;

    // --- sensors ----------------------------------------------------------------
    // Sums over samples [start, start + count) of each pixel, per band.
    void render_camera(int cam, uint64_t start, uint64_t count, int threads,
                       double* sum, double* sumsq, Counters* total) const;
    // Sums over samples [start, start + count) per bin and band (chunked, fixed order).
    void render_radiometer(int rad, uint64_t start, uint64_t count, int threads,
                           double* sum, double* sumsq, Counters* total) const;
    double radiometer_sample(int rad, uint64_t index, Spectrum* out, int* bin, Counters& c) const;

    void trace_rays(const float* o, const float* d, size_t n, int threads, float* t_out) const;

    std::atomic<bool> cancel_flag{false};
    double scene_extent() const { return extent_; }

private:
    bool intersect_patch(const Vec3& o, const Vec3& d, double tmax, Hit* hit) const;
    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    RTCScene patch_scene_ = nullptr;
    double eps_ = 1e-6, extent_ = 1.0;
};

// Runs body(i) for i in [0, n) on `threads` threads with dynamic scheduling.
template <class F>
void parallel_for(size_t n, int threads, F&& body);

}  // namespace photic
