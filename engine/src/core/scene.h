// The compiled scene: geometry in Embree, water bodies, sun, sky and sensors.
// Built once from Python (photic.compile), then traced from many threads without the GIL.
#pragma once
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>
#include "phase.h"
#include "rng.h"
#include "vec.h"
#include "rough_interface.h"
#include "medium.h"
#include "large_arrays.h"
#include "embree4_api.h"

namespace photic {

constexpr int kNumComponents = 8;  // total, beam_surface, beam_volume, path, beam_direct, raman, chlorophyll, cdom
constexpr int kRoughFlatBeams = 16;  // facets per build below a rough flat ocean
constexpr int kMaxBeams = 64;      // beams summed at one point (overlaps in strong caustics)
// Exact mode (forward cone 0): the fraction of path continuations drawn around a beam's
// reverse (Scene::trace, radiometer_sample).
constexpr double kBeamGuide = 0.25;
// The guided continuations' weights (own pdf over the mixture's: about 1 / (1 - kBeamGuide) away
// from the beam) multiply along a path: at a fixed fraction they grow geometrically with the
// number of scatterings (4/3 per vertex), and in high-albedo water the rare long paths carried
// weights of thousands (heavy tails). So once their product exceeds kGuidedWeightScale a path
// guides less often, kBeamGuide * kGuidedWeightScale / product, which keeps the product's growth
// about linear in the number of vertices while every vertex still guides some of its paths
// (without that, a path that arrives straight at the beam's reverse by its phase function alone
// is the heavy tail the guide exists to remove).
constexpr double kGuidedWeightScale = 2.0;
// A continuation whose direction the beam-direction pdf (the phase function around a beam's
// reverse) gives more than this density (sr^-1; 12 times an isotropic one, within ~10 deg of
// the refracted sun's reverse in ocean water) heads into the beam's forward peak: Russian
// roulette is skipped there (Scene::trace_path).
constexpr double kBeamPeakPdf = 1.0;

struct Material {  // Lambertian, optionally textured and emitting
    Spectrum reflectance;  // (textured: the texture's mean, for what has no texture coordinates)
    Spectrum emission;     // radiance it emits from both faces (W m^-2 sr^-1 per band unit)
    bool emits = false;
    int texture = -1;      // Scene::textures index, or -1
};

// A reflectance texture: nbands values per texel, rows from v = 0 (bottom) up, columns from
// u = 0; bilinear (or the nearest texel), repeating (or clamped at the edges).
struct Texture {
    int width = 0, height = 0;
    bool clamp = false;
    bool closest = false;       // the nearest texel instead of bilinear
    std::vector<float> texels;  // (height, width, nbands)
};

enum class SurfaceKind : int { kOpaque = 0, kWaterBoundary = 1 };

struct MeshRecord {  // one Embree geometry of the main scene
    SurfaceKind kind = SurfaceKind::kOpaque;
    int index = 0;   // material (opaque) or water body (boundary)
    std::vector<float> vertices;      // xyz
    std::vector<uint32_t> triangles;  // ijk
    // A water boundary's smooth shading normals at each triangle's corners (9 per triangle,
    // outward): the area-weighted normals of the faces around the vertex that turn by less
    // than 30 deg from the triangle, so that a wave surface refracts and reflects
    // continuously (beams and paths alike) while the sharp edges of a box stay sharp. Made at
    // commit (smooth_corner_normals).
    std::vector<float> corner_normals;
    // An opaque mesh's texture coordinates at each triangle's corners (6 per triangle), or none.
    std::vector<float> corner_uv;
    // An opaque mesh's copies (12 per copy: 3 x 4 row-major [R | t], world = R v + t), or none:
    // the vertices above are then in the mesh's own frame, stored and traced once (an Embree
    // instance array over the mesh's own BVH).
    std::vector<float> instances;
    size_t copies() const { return instances.empty() ? 1 : instances.size() / 12; }
    Vec3 to_world(size_t copy, const Vec3& p) const;
    // Bounds of every copy in the world (of the vertices when not instanced); empty: lo > hi.
    std::pair<Vec3, Vec3> world_bounds() const;
    // The outward normal in the world of copy `copy` for the mesh's own normal n (not unit):
    // |det R| R^-T n, i.e. the cofactor matrix of R times sign(det R) (a mirrored copy keeps
    // its faces outward, as a flattened copy with its winding reversed does).
    Vec3 normal_to_world(size_t copy, const Vec3& n) const;
};
void smooth_corner_normals(MeshRecord* m);

struct Hit {
    int id = -1;          // Embree geometry id; -2 ocean bottom, -3 ocean surface
    bool valid = false;
    double t = kInf;
    Vec3 n;               // unit geometric normal (outward for water boundaries)
    Vec3 ns;              // shading normal: the interpolated exact normals of a wave patch, else n
    SurfaceKind kind = SurfaceKind::kOpaque;
    int index = -1;
    int prim = -1;        // triangle of the mesh hit (Embree primID), -1 for the ocean's
    double bu = 0.0, bv = 0.0;  // its barycentric coordinates there
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
    double shift_x = 0.0, shift_y = 0.0;   // image centre offset in image widths (lens shift)
    double clip_start = 0.0;               // m along forward: rays start on this plane
    int width = 64, height = 64;
    int filter = 0;            // 0 box, 1 gaussian
    double filter_width = 1.0; // px: box full width; gaussian FWHM
    int medium = -1;
};

// One beam covering a point: its local direction and irradiance normal to it, per band.
struct BeamSample {
    Vec3 d;
    Spectrum e;
    double l = 0.0;  // its path length in the water, from where it entered to the point
    // It holds the sun's whole disk (a prism spread by the blur): its light scatters with
    // Scene::beam_phase and reaches a radiometer from the disk's image. Otherwise (a flat sea's
    // analytic beam, sharp prisms) it is one direction drawn in the disk for the pass.
    bool spread = false;
};

// A prism of refracted sunlight below one water-surface triangle (Watt 1990; Nishita &
// Nakamae 1994): three vertex rays v_i + t d_i, sliced by planes normal to m.
// What a query reads comes first, in the order it reads it, in whole cache lines (the prisms
// are megabytes read at random: a lookup prefetches the first kPrismQueryLines lines of every
// prism that passed its key test, at once).
struct alignas(64) BeamPrism {
    Vec3 m;            // slicing normal
    double md[3], mv[3];
    Vec3 v[3], d[3];
    double len[3];     // where each vertex ray ends (hit surface, or attenuation cap)
    Vec3 n_src;        // source triangle normal (pointing to the air side)
    double src_area = 0.0;  // area of the source triangle
    int water = 0;
    // Shadow rays of each query: an object may cut the prism between its source and the query
    // point (check_path), or shade its source from the sun (check_sun).
    bool check_path = false, check_sun = false;
    // Queries at heights h = m . y below this need no path ray (set_prism_checks found no
    // object near the part of the prism above it).
    double path_clear_below = -kInf;
    // Below the periodic ocean patch: traced without the scene's meshes (each query shifts the
    // prism into the period it asks about, where other objects stand), so they are met by the
    // shadow rays at query time instead.
    bool periodic = false;
    bool partial_lit = false;       // a vertex of its source is in a wave's shadow
    // The sun reflected by the water surface into the air (water = -1: no attenuation), lit
    // on the air side of its source.
    bool reflected = false;
    // The sun's disk as seen through this prism (sun_blur): at path length l, the light of
    // the slice's point x spreads over the ellipse {x + l (u k1 + v k2): u^2 + v^2 <= 1} of the
    // slicing plane, k1, k2 the drifts of the refracted (reflected) direction for the disk's
    // edge, projected along the beam. Stored as the dual vectors g1, g2 (point p at offset
    // p - x from the centre: u = g1 . (p - x) / l) and the ellipse's area per l^2 over pi
    // (blur_det; 0: a sharp prism).
    Vec3 blur_g1, blur_g2;
    double blur_det = 0.0;
    Spectrum phi;      // flux entering the water through the triangle, per band
    // (not read by queries)
    bool hit[3];       // whether each vertex ray ended on a surface
    double blur_reach = 0.0;  // the blur ellipse's largest semi-axis per unit of path length
    Vec3 lo, hi;       // bounding box
};
// The lines a query reads: up to phi's first three bands.
constexpr int kPrismQueryLines = int((offsetof(BeamPrism, phi) + 3 * sizeof(double) + 63) / 64);

// Component passes of the hybrid integrator.
struct Components {
    Spectrum beam_surface;  // the sun from beams on surfaces (refracted under water, reflected in the air)
    Spectrum beam_volume;   // single scattering of beams along traced water segments
    Spectrum path;          // everything path tracing finds itself (sky, sun above water, ...)
    // Light an inelastic process (InelasticKind: Raman, chlorophyll, CDOM fluorescence) put into
    // these bands, the beams' or the paths' (a path's first such event decides the kind).
    Spectrum inelastic[kInelasticKinds];
    double total(int k) const {  // all of band k's light
        double s = beam_surface.v[k] + beam_volume.v[k] + path.v[k];
        for (const Spectrum& x : inelastic) s += x.v[k];
        return s;
    }
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
    std::vector<Texture> textures;
    std::vector<PhaseFunction> phases;
    std::vector<Water> waters;
    std::vector<MeshRecord> meshes;
    std::vector<Camera> cameras;
    std::vector<Radiometer> radiometers;

    // Ocean: water below a surface unbounded horizontally.
    int ocean_water = -1;             // -1: no ocean
    // Sub-pixel roughness of the ocean surface (Cox-Munk microfacets), used by path tracing.
    bool ocean_rough = false;
    RoughInterface ocean_bsdf{1e-6, 1e-6};
    bool ocean_flat = true;
    double ocean_z = 0.0;             // flat surface height (or patch mean)
    std::vector<float> patch_vertices;
    std::vector<uint32_t> patch_triangles;
    // Unit vertex normals (air side): given (a wave model's exact ones), or made at commit from
    // the mesh (smooth_patch_normals). Beams and paths both refract about them.
    std::vector<float> patch_normals;
    double patch_x0 = 0, patch_y0 = 0, patch_lx = 1, patch_ly = 1, patch_zmin = 0, patch_zmax = 0;
    // The steepest facet's slope |grad z| (made at commit; inf unless the patch is a height
    // field: every facet facing up, their shadows covering one period once).
    double patch_slope_max = kInf;
    bool has_bottom = false;
    double bottom_z = 0.0;
    int bottom_material = -1;

    bool has_sun = false;
    Vec3 sun_dir{0, 0, 1};           // towards the sun
    double sun_cos_half = 1.0;       // cosine of angular radius
    Spectrum sun_radiance;           // uniform disk radiance

    int sky_type = 0;                // 0 black, 1 uniform, 2 cardioidal, 3 tabulated, 4 tabulated per band
    // Tabulated sky (type 3): relative radiance on nodes theta_i = i/(nt-1) 90 deg (zenith
    // angle) x phi_j = j/np 360 deg (azimuth from +x towards +y, periodic), bilinear.
    // Type 4: the same nodes with nbands values each (an environment map), times L0.
    std::vector<double> sky_table;
    int sky_nt = 0, sky_np = 0;
    bool sky_full_sphere = false;    // uniform radiance below the horizon too (furnace tests)
    Spectrum sky_l0;

    uint64_t seed = 0;
    int max_depth = 256;
    int rr_depth = 8;

    // Hybrid integrator: the refracted sun comes only from beams below the water.
    bool hybrid = false;
    double cone_half_angle = 0.0;     // forward-scattering cone (radians); 0: full phase function
    int beam_max_level = 5;           // adaptive subdivision levels of a surface triangle
    double beam_min_area_fraction = 1e-6;  // floor of a cross-section, times the source area
    // Where the ocean patch sends beams from: (x, y, radius) triples, in m, of disks over the
    // patch (periodic); its faces whose centres lie in none send none. Empty: the whole patch.
    // (For checks that need the beams at a few points only: photic.render's wave-mesh check.)
    std::vector<double> beam_source_region;
    // The sun's finite disk in the beams (beams.cpp, prism_eval): true, the prisms are built
    // once for the sun's centre and each spreads its light over the image of the disk (an
    // ellipse growing with path length), which bounds the irradiance of caustic foci where a
    // prism's cross-section collapses; false (and always below a rough sea, whose facets are
    // drawn per build), every build takes its own direction within the disk and the average
    // over passes does the spreading.
    bool beam_sun_blur = true;
    // Beams of the current pass (rebuilt for every sun direction drawn in the disk): the
    // refracted sun in the water, and the sun reflected by smooth water surfaces into the air
    // (where opaque objects or radiometers stand in the air).
    LargeVector<BeamPrism> prisms;
    LargeVector<BeamPrism> air_prisms;
    // The sun reflected by a smooth flat ocean: one analytic beam in the air.
    bool flat_air_beam = false;
    Vec3 flat_air_d;
    Spectrum flat_air_e;
    bool flat_beam = false;           // analytic beam(s) below a flat ocean
    // Their refracted directions and irradiances normal to them just below the surface: one
    // beam for a smooth surface, kRoughFlatBeams facets (stratified) for a rough one.
    std::vector<Vec3> flat_d;
    std::vector<Spectrum> flat_e0;
    // Gridded ocean water: where the flat beams' sunward rays can meet density
    // (VoxelGrid::ShadowMap), elsewhere a beam needs no walk. Built once for a cone around the
    // refracted sun's centre (the sun's radius, plus kRoughShadeSpread below a rough sea);
    // flat_shade_ok says per flat beam whether its direction lies in the cone.
    static constexpr double kRoughShadeSpread = 0.1;  // radians (5.7 deg)
    VoxelGrid::ShadowMap flat_shade;
    std::vector<uint8_t> flat_shade_ok;
    Vec3 beam_sun_dir{0, 0, 1};
    double beam_mu_w = 1.0;           // cosine of the refracted sun's zenith angle in water

    void set_forward_cone(double half_angle);  // recomputes the waters' path/beam coefficients
    // Beams for one sun direction. With a rough ocean surface, facet_u (two uniforms) picks
    // one sub-pixel facet orientation (relative to each local normal) for this build: over
    // builds, the beams then spread as the rough BTDF says (in expectation).
    // Stops early, leaving no beams, when cancel() is called (checked per block of vertices,
    // per source triangle and per 4,096 prisms of the grid: a 512 x 512 patch's first build
    // takes seconds).
    // keep_prisms: with the sun-disk blur, the prisms of the last whole build (all built for
    // the sun's centre) are kept and only the direction of the shadow rays and of a flat sea's
    // analytic beams follow sun_direction: one build per render instead of one per pass.
    void build_beams(const Vec3& sun_direction, int threads, double facet_u1 = 0.5, double facet_u2 = 0.0,
                     bool keep_prisms = false);
    // Whether builds spread each prism over the sun's disk (beam_sun_blur, a sun of finite size
    // up to kMaxBlurRadius, no rough sea). The spreading is first order in the disk's radius:
    // ~1e-5 of the irradiance for the real sun (0.27 deg), a few per cent for the 20 deg suns
    // that tests give path tracing to find, whose images also cover tens of small prisms per
    // point; beyond 1 deg every pass draws its direction instead. So does a wave patch smaller
    // than twice the disk's image at the water's depth (a lookup would visit every copy of the
    // patch the image covers: 640,000 under a 1 mm patch; the light there is smooth anyway).
    static constexpr double kMaxBlurRadius = 0.017453292519943295;  // 1 deg
    bool sun_blur_active() const {
        if (!(beam_sun_blur && !ocean_rough && sun_cos_half < 1.0 && sun_cos_half >= std::cos(kMaxBlurRadius)))
            return false;
        if (ocean_water >= 0 && !ocean_flat) {
            const double depth = patch_zmax - (has_bottom ? bottom_z : double(bounds_lo_[2]));
            const double reach = 2.0 * std::acos(sun_cos_half) * std::max(depth, 0.0);
            if (!(reach <= 0.5 * std::min(patch_lx, patch_ly))) return false;
        }
        return true;
    }
    // Every beam covering x (in water body `medium`, or -1: the reflected beams in the air);
    // returns how many were written (<= max).
    // exact = false: a ranking of the beams, as strongest_beam makes: in stratified or gridded
    // water each beam's irradiance is attenuated with the top or base layer's coefficients only
    // (no walk through the layers or voxels), and prisms spread over the sun's disk are taken
    // sharp (no overlap of the disk's image with the slice to compute, and only the prisms
    // whose slice holds x).
    int beams_at(const Vec3& x, int medium, BeamSample* out, int max, bool exact = true) const;
    double beam_total_flux() const;   // sum of prism fluxes entering the water (band 0)
    // The most copies of the periodic ocean patch that one beam lookup visits (1 without one):
    // the beams of every period that reach a point, whose count grows as (spread / period)^2
    // where a small patch's beams spread over many periods on their way down.
    double beam_patch_copies() const;
    // The sunlight entering the water that the beams do not carry, over what they carry: per
    // face of the periodic ocean patch that the sun towards s lights (no wave's shadow taken
    // off: an upper bound), the share it reflects that meets the patch again (the next wave,
    // from above) and the share it refracts that meets the patch again from below, weighted by
    // the face's projected area. Path tracing alone finds that light, along rare paths (through
    // the surface into the sun's disk after a reflection), so where it is not negligible the
    // exact mode's error bars cannot be trusted (photic.render.exact_mode_below_waves).
    // 0 without a patch. (Over at most 65,536 of the patch's faces, spread over it.)
    double sun_rehit_fraction(const Vec3& s, double ior, int threads) const;
    // Whether this pass's water beams are looked up in the grid built for the sun's centre.
    bool beam_grid_shared() const { return water_grid_ == &grid_ref_.grid; }
    double air_beam_total_flux() const;   // sum of the reflected prisms' fluxes (band 0)

    void commit();                    // builds the BVHs and resolves sensor media

    // --- queries ----------------------------------------------------------------
    // Which side of the ocean patch's surface a ray starts on, where the caller knows it (from
    // the medium it is in): a ray that leaves the surface more steeply than any facet rises
    // cannot meet it, and intersect_patch then skips the tiles.
    enum class Side : int { kUnknown = 0, kAbove = 1, kBelow = -1 };
    Side ocean_side(int medium) const {
        return medium < 0 ? Side::kAbove : medium == ocean_water ? Side::kBelow : Side::kUnknown;
    }
    Hit intersect(const Vec3& o, const Vec3& d, double tmax = kInf, Side side = Side::kUnknown) const;  // closest hit before tmax
    bool occluded(const Vec3& o, const Vec3& d, Side side = Side::kUnknown) const;  // to infinity
    // The same without the meshes: only the ocean's surface and bottom, which repeat with the
    // patch's period (the periodic beams are traced against these alone).
    Hit intersect_ocean(const Vec3& o, const Vec3& d, double tmax = kInf, Side side = Side::kUnknown) const;
    bool occluded_ocean(const Vec3& o, const Vec3& d, Side side = Side::kUnknown) const;
    // Whether a mesh (opaque or water boundary) lies on the segment o + t d, tnear < t < tfar;
    // false at once when the segment misses the meshes' bounding box.
    bool meshes_block(const Vec3& o, const Vec3& d, double tnear, double tfar) const;
    int medium_at(const Vec3& p) const;
    // Whether p lies inside a closed opaque object: most of six rays from it first meet an
    // opaque surface from behind (a sensor there sees nothing).
    bool inside_opaque(const Vec3& p) const;
    double offset_for(const Vec3& p) const { return eps_ + 4e-6 * max_abs(p); }

    // --- light ------------------------------------------------------------------
    Spectrum sky_radiance(const Vec3& d) const;
    // The opaque surface at a hit: its material with the reflectance of its texture there.
    Material surface_at(const Hit& h) const;
    bool in_sun(const Vec3& d) const { return has_sun && dot(d, sun_dir) >= sun_cos_half; }
    Vec3 sample_sun(double u1, double u2) const;
    double sun_pdf() const { return 1.0 / (2.0 * kPi * (1.0 - sun_cos_half)); }

    // Radiance arriving at o from direction -d (a backward path started along d), split into
    // the hybrid integrator's components (all in `path` for pure path tracing).
    // sun_covered: NEE already counted the sun seen straight from o; beam_covered: the beams
    // already count the refracted sun reaching o straight (hybrid).
    // first_beam_weight: MIS weight of the first segment's beam scattering (radiometers).
    // camera: a pixel's path, whose beam-direction samples follow beam_mis_share (a
    // radiometer's always take them: its other noise is small, so they pay even in clear water).
    // reflect_covered: the reflected beams in the air already count the sun reaching o by one
    // reflection on the water (a radiometer in the air, hybrid).
    // branch_inelastic: the path may estimate the inelastic light along its water segments by
    // a branch (inelastic_branch; one at most); a branch's own path may not.
    Components trace(Vec3 o, Vec3 d, int medium, bool sun_covered, bool beam_covered, Rng& rng,
                     Counters& c, double first_beam_weight = 1.0, bool camera = false,
                     bool reflect_covered = false, bool branch_inelastic = true) const;
    bool has_beams() const { return flat_beam || !prisms.empty(); }
    // The phase function `phase` seen by a beam's light (1/sr at x = 1 - cos psi): with the
    // sun-disk blur, averaged over the refracted sun's disk (a cap of angular radius
    // beam_disk_radius around the beam's direction), which bounds the forward peak at about
    // its mean over the cap (a beam of the centre's direction alone would meet the peak's
    // singular tip: the rare, huge single-scattering samples along views towards the sun);
    // otherwise, and beyond kDiskPhaseReach radii, the phase function itself.
    // With a forward cone the mean is that of the phase function outside the cone (the light
    // within the cone of each of the disk's directions stays in the beam), and x < the cone's
    // is no longer out of reach.
    double beam_phase(int phase, double x) const {
        if (!disk_phase_.empty() && x < disk_phase_x_max_) return disk_phase_eval(phase, x);
        return phases[phase].eval(x);
    }
    bool beam_phase_spread() const { return !disk_phase_.empty(); }
    // radians: the refracted sun's disk in the water as a circle of the solid angle a level
    // surface gives it (sqrt(cos i / cos t) times the sun's radius / ior); 0: no blur
    double beam_disk_radius = 0.0;
    static constexpr double kDiskPhaseReach = 12.0;
    static constexpr int kDiskPhaseNodes = 384;
    bool has_air_beams() const { return flat_air_beam || !air_prisms.empty(); }
    // Beam single scattering seen from o along d over [0, T] in water `medium` (per band,
    // without the throughput), one distance sample.
    // deferred_t: in gridded water, the attenuation from o to the point drawn is left out and
    // that point's distance stored here, for a caller who walks the segment anyway.
    // inelastic: the same point's inelastic scattering of the beams into each band, per kind
    // (kInelasticKinds spectra; Water::inelastic).
    void beam_scatter_along(const Vec3& o, const Vec3& d, double T, int medium, Rng& rng, Spectrum* out,
                            double* deferred_t = nullptr, Spectrum* inelastic = nullptr) const;
    bool strongest_beam(const Vec3& x, int medium, BeamSample* beam) const;
    // How often a camera path at a point lit by `beam` tries the beam's reverse direction: the
    // probability of the beam-scattering MIS's second sample (and, times kBeamGuide, of a
    // beam-guided continuation in the exact mode). Both serve the light that the beam scatters
    // in the phase function's forward peak, at most about b l of the beam's own (l: its path
    // in the water): 1 where the water scatters at least once along the beam, less in clear
    // water, where they mostly cost rays and lookups for light that a pixel's other noise
    // drowns.
    double beam_mis_share(const Water& w, const BeamSample& beam) const {
        return std::min(1.0, w.b_max * beam.l);
    }
    // The second strategy of the beam-scattering MIS: look directions drawn from the water's
    // phase function around the beam's reverse direction (the forward peak of natural waters).
    double beam_direction_pdf(const Water& w, const Vec3& beam_d, const Vec3& omega) const;
    Vec3 sample_beam_direction(const Water& w, const Vec3& beam_d, Rng& rng) const;
    bool occluded_segment(const Vec3& o, const Vec3& d, double tmax) const;

    // --- sensors ----------------------------------------------------------------
    // Sums over samples [start, start + count) of each pixel, per component and band:
    // sum[(pixel * kNumComponents + component) * nbands + band]; components are
    // total, beam_surface, beam_volume, path, beam_direct.
    // active (optional, height x width): pixels where it is 0 are skipped (adaptive sampling).
    // Rows [row0, row1) only (row1 < 0: to the last): sum and sumsq hold those rows; active, when
    // given, covers the whole image.
    void render_camera(int cam, uint64_t start, uint64_t count, int threads,
                       double* sum, double* sumsq, Counters* total, const uint8_t* active = nullptr,
                       int row0 = 0, int row1 = -1) const;
    // Denoising guides of a camera (what a denoiser such as OpenImageDenoise takes besides the
    // noisy image), per_axis^2 fixed sub-pixel rays per pixel, deterministic and noise-free:
    // albedo (height x width x nbands): the share of light a pixel's view returns, the first
    // opaque surface's reflectance seen through the water in front of it (and through water
    // boundaries, along their more likely way), plus what that water scatters (its optical
    // depths' single-scattering albedo times 1 - transmittance); normal (height x width x 3):
    // that surface's world normal facing the camera, weighted by the light that reaches it.
    // Rows [row0, row1) only (row1 < 0: to the last); albedo and normal then hold those rows.
    void camera_guides(int cam, int per_axis, int threads, float* albedo, float* normal, int row0 = 0,
                       int row1 = -1) const;
    // Sums over samples [start, start + count) per bin, component and band (chunked, fixed order).
    // moments (optional): per bin and band, the total's central sums of powers 2, 3 and 4 about
    // the pass's own mean, moments[(bin * 3 + (power - 2)) * nbands + band]: the tails of the
    // samples' distribution (the variance of the variance), exact where raw power sums would
    // cancel.
    void render_radiometer(int rad, uint64_t start, uint64_t count, int threads,
                           double* sum, double* sumsq, Counters* total, double* moments = nullptr) const;
    // One radiometer sample: out[component] per band.
    // at_sensor: the beams at the radiometer (the same for all its samples in a pass).
    void radiometer_sample(int rad, uint64_t index, const BeamSample* at_sensor, int n_at_sensor,
                           Spectrum* out, int* bin, Counters& c) const;

    void trace_rays(const float* o, const float* d, size_t n, int threads, float* t_out,
                    const float* tmax = nullptr) const;

    std::atomic<bool> cancel_flag{false};
    double scene_extent() const { return extent_; }

    bool intersect_patch(const Vec3& o, const Vec3& d, double tmax, Hit* hit, Side side = Side::kUnknown) const;
    void smooth_patch_normals();  // patch_normals from the mesh (area weighted, seams shared)
    // Beam of prism P at y (primary-patch frame; `world` is the same point unshifted).
    bool prism_eval(const BeamPrism& P, const Vec3& y, const Vec3& world, BeamSample* out,
                    bool exact = true) const;

private:
    // beam_scatter_along's halves: the distance t drawn (with its pdf; false: no point, the
    // term is 0), and the sum over the beams found at x = o + d t.
    bool beam_scatter_point(const Water& w, const Vec3& d, double T, Rng& rng, double* t, double* pdf) const;
    void beam_scatter_sum(const Vec3& o, const Vec3& d, double t, double pdf, int medium, const BeamSample* beams,
                          int n, Spectrum* out, double* deferred_t, Spectrum* inelastic = nullptr) const;
    // A path's beam-scattering terms in water (along its water segments and its MIS rays) whose
    // points are drawn in turn but whose beams are looked up together when the path ends: all
    // their grid cells are fetched, then all their candidates' keys, then the prisms whose keys
    // pass (the candidates kept), so that the misses of a path's lookups overlap instead of
    // queueing. Each term is weight * I / den (the factors and their order as when each was
    // added at once), added to beam_volume in the order drawn, before anything else adds to
    // it: the same sums, bit for bit.
    struct BeamTerms {
        static constexpr int kMax = 24;
        struct Term {  // (plain arrays: a path's list is not cleared when made)
            double o[3], d[3];
            double t, pdf, den;
            int medium;
            double weight[kMaxBands];
        };
        int n = 0;
        Term terms[kMax];
        // After an inelastic collision the path carries the light of the bands that excite
        // the ones it set out in: what it finds in band i goes to band k of the result at
        // share[k * nb + i] (fold_inelastic), into the component of its first such
        // collision's kind. `before`: the components when it was last folded; inelastic:
        // whether it had such a collision.
        bool inelastic = false;
        int kind = kRaman;
        Components before;
        double share[kMaxBands * kMaxBands];
    };
    // Moves what the path found since its last inelastic collision into the component of its
    // kind, in the bands it set out in (the terms settled first).
    void fold_inelastic(BeamTerms& b, Components* out) const;
    // Queues a term (settling a full list first); returns its weight, for the caller to fill.
    double* queue_beam_term(BeamTerms& b, Components* out, const Vec3& o, const Vec3& d, double t, double pdf,
                            int medium, double den) const;
    void settle_beam_terms(BeamTerms& b, Components* out) const;
    // trace's body (trace settles the path's beam terms when it returns).
    Components trace_path(Vec3 o, Vec3 d, int medium, bool sun_covered, bool beam_covered, Rng& rng,
                          Counters& c, double first_beam_weight, bool camera, bool reflect_covered,
                          BeamTerms& terms, bool branch_inelastic) const;
    // The inelastic light along the water segment [0, T] from o along d, seen from o: a point
    // drawn on it, a process by its share of the gain there, and a new path from there in a
    // direction drawn from the process's phase function, whose light (in the bands that excite
    // the path's) comes back into the path's bands; weight[k]: the path's throughput in band k
    // over the branch's probability. Added to out->inelastic.
    void inelastic_branch(const Vec3& o, const Vec3& d, double T, int medium, const double* weight, Rng& rng,
                          Counters& c, bool camera, Components* out) const;
    // Starts fetching the water beams' grid cells at x in `medium` (a hint: a later lookup
    // there then finds them in the cache; the cells by multiplications, which may differ from
    // lookup's at a cell's edge): below the periodic patch, the cells of x's images in every
    // period the grid covers, as lookup visits them (paths soon leave the primary period).
    // Always inlined: GCC's link-time optimisation takes an out-of-line function that only
    // reads memory and prefetches for one without effects, and drops its calls.
    __attribute__((always_inline)) void prefetch_beams(const Vec3& x, int medium) const {
        const BeamGrid& grid = *water_grid_;
        if (grid.nx == 0) return;
        double fx = (x.x + grid.sx * x.z - grid.lo.x) * grid.inv_cell.x;
        double fy = (x.y + grid.sy * x.z - grid.lo.y) * grid.inv_cell.y;
        const double fz = (x.z - grid.lo.z) * grid.inv_cell.z;
        if (!(fz >= 0.0 && fz < grid.nz)) return;
        double px = kInf, py = kInf;  // the period in cells (inf: the point itself only)
        if (medium == ocean_water && !ocean_flat) {
            px = patch_lx * grid.inv_cell.x;
            py = patch_ly * grid.inv_cell.y;
            fx -= double(floor_to_long(fx / px)) * px;  // the image in [0, px), then those above it
            fy -= double(floor_to_long(fy / py)) * py;
        }
        const size_t layer = size_t(fz) * grid.ny;
        for (double gy = fy; gy >= 0.0 && gy < grid.ny; gy += py)
            for (double gx = fx; gx >= 0.0 && gx < grid.nx; gx += px) {
                __builtin_prefetch(&grid.cells[((layer + size_t(gy)) * grid.nx + size_t(gx)) * BeamGrid::kCellWords]);
            }
    }
    struct BeamGrid {  // uniform grid over prism pieces (primary patch frame, sheared)
        double sx = 0.0, sy = 0.0;  // cell (i, j, k) holds u = x + sx z, v = y + sy z, z
        Vec3 lo, cell, inv_cell;
        int nx = 0, ny = 0, nz = 0;
        // Cell c lists its prisms in items[start[c], start[c + 1]). What a query reads is
        // cells[c * kCellWords ...]: the count, start[c], and the first kInline items, in
        // one 32-byte record (one miss where start and items were two dependent ones).
        static constexpr int kCellWords = 8, kInline = kCellWords - 2;
        LargeVector<uint32_t> cells, items;
        LargeVector<uint32_t> start, fill, last;  // the build's (kept: see build_grid)
        LargeVector<uint64_t> marks;
        // Empty (no cells), keeping the arrays' memory for the next pass.
        void clear() {
            sx = sy = 0.0;
            lo = cell = inv_cell = Vec3();
            nx = ny = nz = 0;
            cells.clear();
            items.clear();
        }
    } grid_;
    // Per prism, what a query reads first (beside it in memory, not in the large BeamPrism):
    // its water body and, for prisms sliced horizontally, the corners of the slice at height
    // h = -z as x = ax + bx h, y = ay + by h, for a point-in-triangle test that rejects most
    // candidates before prism_eval (conservatively: it accepts whatever prism_eval would).
    // Two whole cache lines (104 bytes used), both fetched ahead by prefetch_cell_keys: a key
    // straddling three lines, of which the first alone was fetched, cost a second miss.
    struct alignas(128) PrismKey {
        double ax[3], bx[3], ay[3], by[3];
        int water;
        bool horizontal;  // sliced by horizontal planes: h = -z (down) or z (up)
        bool up;
        bool periodic;    // below (or above) the periodic ocean patch: looked up in every period
        // The sun-disk blur's reach across at height h: at most (h >= 0 ? r_hi : r_lo) h + r_c
        // (0 for a sharp prism).
        float r_hi, r_lo, r_c;
    };
    // Fetches the keys of the candidates of the cell whose record is rec (inline: see
    // prefetch_beams; two loops, as a select between the record and the item list would load
    // both, and the list is a miss of its own for the many cells whose items all fit in the
    // record).
    __attribute__((always_inline)) static void prefetch_cell_keys(const BeamGrid& grid, const uint32_t* rec,
                                                                  const LargeVector<PrismKey>& keys) {
        auto fetch = [&](uint32_t pi) {
            const char* p = reinterpret_cast<const char*>(&keys[pi]);
            __builtin_prefetch(p);
            __builtin_prefetch(p + 64);
        };
        const uint32_t count = rec[0], first = rec[1];
        const uint32_t in_record = std::min<uint32_t>(count, BeamGrid::kInline);
        for (uint32_t q = 0; q < in_record; ++q) fetch(rec[2 + q]);
        for (uint32_t q = BeamGrid::kInline; q < count; ++q) fetch(grid.items[first + q]);
    }
    LargeVector<PrismKey> prism_keys_;
    // The water beams' grid of the sun's centre, kept from pass to pass (beam_reference.cpp).
    // Every pass draws its own direction within the sun's disk, and its prisms lie within
    // `margin` of the centre's (in the grid's sheared frame, after each pass's own shear):
    // the centre's grid, its marks widened by the margin, then serves them all, one grid per
    // render instead of one per pass. A pass whose prisms it does not fit (another structure,
    // or farther than the margin) gets a grid of its own.
    struct ReferencePrism {  // what a pass's prism is compared with
        double v[9];                        // its source corners (the same in every pass)
        double ax[3], bx[3], ay[3], by[3];  // its key: corner j at x = ax + bx h, y = ay + by h
        double end[3];                      // where each ray ends, in h
        // How far the prisms of other directions may lie from it, in the grid's sheared frame,
        // at heights h: a + g |h| (the grid's margin there).
        double margin_a, margin_g;
        int water;
        bool up, periodic;
    };
    struct GridReference {
        bool built = false;   // for the sun `sun` of half-angle cosine `cos_half`
        bool usable = false;  // (built: every prism sliced horizontally, the probes alike)
        Vec3 sun;
        double cos_half = 0.0;
        double sx = 0.0, sy = 0.0;  // the centre's shear (the grid's is each pass's own)
        std::vector<ReferencePrism> prisms;
        BeamGrid grid;
    } grid_ref_;
    const BeamGrid* water_grid_ = &grid_;  // the water lookups' grid: grid_ or grid_ref_.grid
    // Whether the scene's beams may share the reference: a smooth ocean patch and no water
    // meshes (whose prisms' subdivision follows the sun more closely).
    bool grid_reference_allowed() const;
    // The reference for the current sun: the centre's prisms, their grid with the margin that
    // two probes on the disk's edge need.
    void build_grid_reference(const Spectrum& e_sun, int threads);
    // The shared grid's shear for the sun towards s: the centre's, moved as the drift of the
    // sun refracted by a level surface moves (smooth in the direction, as the prisms' drifts
    // are, where each pass's own median is not).
    bool reference_shear(const Vec3& s, double* sx, double* sy) const;
    // Whether the current prisms (keys in prism_keys_, shear sx, sy) fit the reference.
    bool grid_reference_fits(double sx, double sy) const;
    std::vector<std::vector<BeamPrism>> prism_lists_;  // build_beams' per-triangle lists (kept)
    // The sun (towards s) refracted through the ocean surface with local normal n (a rough sea
    // through the build's facet u1, u2): the direction d and the transmitted fraction T.
    bool refract_sun(const Vec3& s, const Vec3& n, double ior, Vec3* d, double* T, double u1, double u2) const;
    // build_beams' prisms for the sun towards s (e_sun: its irradiance normal to itself),
    // appended to dest: refracted into the water, or (air) reflected into the air; normals
    // (optional): each prism's corners' shading normals, appended alike.
    void make_prisms(const Vec3& s, const Spectrum& e_sun, bool air, int threads, double facet_u1, double facet_u2,
                     LargeVector<BeamPrism>* dest, std::vector<std::array<Vec3, 3>>* normals = nullptr,
                     bool blur = false);
    BeamGrid air_grid_;
    LargeVector<PrismKey> air_keys_;
    static void make_keys(const LargeVector<BeamPrism>& prisms, LargeVector<PrismKey>* keys);
    // The grid's shear: the median drift per metre of depth of the horizontally sliced prisms.
    static void grid_shear(const LargeVector<PrismKey>& keys, double* sx, double* sy);
    // A grid over the prisms (their keys made); margins (optional, per prism): a piece of
    // prism i at heights z is widened across by margin_a[i] + margin_g[i] max |z|, and covers
    // its whole layer of cells.
    static void build_grid(const LargeVector<BeamPrism>& prisms, const LargeVector<PrismKey>& keys, BeamGrid* grid,
                           const double* margin_a = nullptr, const double* margin_g = nullptr,
                           const std::atomic<bool>* cancel = nullptr);
    // build_beams' work; throws BuildCancelled when cancel_flag is set on the way.
    void build_beams_now(const Vec3& sun_direction, int threads, double facet_u1, double facet_u2, bool keep_prisms);
    // The prisms now held were built (whole) for the sun's centre with the blur.
    bool blurred_prisms_built_ = false;
    // beam_phase's tables: per phase function, the cap means at psi_i = i reach / nodes.
    std::vector<std::vector<double>> disk_phase_;
    double disk_phase_x_max_ = 0.0, disk_phase_step_ = 0.0, disk_phase_cone_ = -1.0;
    void make_disk_phases(double radius, double cone);
    double disk_phase_eval(int phase, double x) const;
    // The disk blur's margins of the current prisms for build_grid (per prism: a + g |z|).
    std::vector<double> blur_margin_a_, blur_margin_g_;
    void blur_margins(const LargeVector<BeamPrism>& prisms, const LargeVector<PrismKey>& keys);
    struct BuildCancelled {};
    // The prisms of one set (keys and grid) covering x, appended to out from index n.
    int lookup(const LargeVector<BeamPrism>& prisms, const LargeVector<PrismKey>& keys, const BeamGrid& grid,
               const Vec3& x, int medium, BeamSample* out, int n, int max, bool exact) const;
    // lookup's two halves. A candidate: a prism whose key passed at x shifted by (i, j) periods
    // of the ocean patch.
    struct BeamCandidate {
        uint32_t prism;
        int32_t i, j;
    };
    // Appends the candidates at x (in the order lookup evaluates them), their prisms fetched ahead.
    void find_candidates(const LargeVector<BeamPrism>& prisms, const LargeVector<PrismKey>& keys, const BeamGrid& grid,
                         const Vec3& x, int medium, std::vector<BeamCandidate>* found, bool blurred = true) const;
    // The beams of found[0, count) covering x, appended to out from index n (at most max in all).
    int eval_candidates(const LargeVector<BeamPrism>& prisms, const BeamCandidate* found, size_t count,
                        const Vec3& x, BeamSample* out, int n, int max, bool exact) const;
    // beams_at's beams of a flat sea (refracted, or reflected into the air), before the prisms'.
    int flat_beams_at(const Vec3& x, int medium, BeamSample* out, int max, bool exact) const;
    // The bounds of meshes, radiometers and the ocean (not cameras): where reflected beams end.
    Vec3 bounds_lo_{-1, -1, -1}, bounds_hi_{1, 1, 1};
    // The first of the boxes [lo_i, hi_i] (grown by tol) in which an opaque triangle may lie,
    // other than those entirely on or behind the plane through plane_p with normal plane_n
    // (pointing into the region; plane_n = 0: none excluded), or -1: none. Conservative: 0
    // when more triangles are near than it examines.
    int first_opaque_box(const std::vector<std::pair<Vec3, Vec3>>& boxes, double tol, const Vec3& plane_n,
                         const Vec3& plane_p, double plane_tol) const;
    // A water mesh's prism: its shadow-ray flags from the opaque triangles near its source's
    // sun column and, for one whose rays end on one plane (uniform: ends_on_surface) or in
    // open water, near itself (else it always tests the path).
    void set_prism_checks(BeamPrism* P, bool uniform, bool ends_on_surface) const;
    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    RTCScene patch_scene_ = nullptr;
    double eps_ = 1e-6, extent_ = 1.0;
    Vec3 meshes_lo_{kInf, kInf, kInf}, meshes_hi_{-kInf, -kInf, -kInf};  // bounds of all meshes
};

}  // namespace photic
