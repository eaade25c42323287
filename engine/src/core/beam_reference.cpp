// One beam grid per render: the grid of the sun's centre serves every pass's direction.
//
// Each pass builds its beams for a direction drawn in the sun's disk (0.53 deg across). Under
// a wave patch the prisms of two such directions are the same prisms, moved a little: mostly
// all alike (which the grid's shear, made per pass, takes up) and each by a few millimetres
// more. So the grid of the centre's prisms, every piece's box widened by a margin that covers
// those few millimetres, lists every pass's prisms where they are. The pass's prisms are then
// checked against the centre's (the same source corners, and within the margin at every
// height); one that does not fit gets a grid of its own. Results do not depend on the grid:
// a lookup finds the same prisms (in prism order) whatever the cells that list them.
#include <algorithm>
#include <cmath>
#include "optics.h"
#include "scene.h"

namespace photic {

namespace {

// (The helpers take Scene's private types as template parameters.)
// The height h at which a horizontally sliced prism's ray j starts (its source corner).
template <class Ref>
double start_height(const Ref& R, int j) { return R.up ? R.v[3 * j + 2] : -R.v[3 * j + 2]; }

}  // namespace

bool Scene::reference_shear(const Vec3& s, double* sx, double* sy) const {
    // u = x + sx z stays constant along the refracted ray d: sx = -d.x / d.z.
    const double ior = waters[ocean_water].ior;
    Vec3 d, d0;
    if (!refract(-s, Vec3(0, 0, 1), 1.0, ior, &d) || !refract(-grid_ref_.sun, Vec3(0, 0, 1), 1.0, ior, &d0)) return false;
    *sx = grid_ref_.sx + (-d.x / d.z - -d0.x / d0.z);
    *sy = grid_ref_.sy + (-d.y / d.z - -d0.y / d0.z);
    return true;
}

bool Scene::grid_reference_allowed() const {
    if (!has_sun || ocean_water < 0 || ocean_flat || ocean_rough) return false;
    for (const auto& m : meshes)
        if (m.kind == SurfaceKind::kWaterBoundary) return false;
    return true;
}

namespace {

// How far, in the grid's sheared x or y, a corner of the prism with key K (grid shear sx, sy)
// can be from the reference prism's (shear rsx, rsy) at the same height h: each corner lies at
// u = a + beta h in the sheared frame (beta = b + sigma s, z = sigma h), so |u' - u| <=
// |a' - a| + |beta' - beta| |h|: *da gets the largest |a' - a|, *dg the largest
// |beta' - beta|, over the corners and both axes.
template <class Ref, class Key>
void deviation(const Ref& R, double rsx, double rsy, const Key& K, double sx, double sy, double* da, double* dg) {
    const double sigma = R.up ? 1.0 : -1.0;
    *da = *dg = 0.0;
    for (int j = 0; j < 3; ++j) {
        *da = std::max({*da, std::fabs(K.ax[j] - R.ax[j]), std::fabs(K.ay[j] - R.ay[j])});
        *dg = std::max({*dg, std::fabs(K.bx[j] + sigma * (sx - rsx) - R.bx[j]),
                        std::fabs(K.by[j] + sigma * (sy - rsy) - R.by[j])});
    }
}

// Whether prism P (key K) is the reference prism's in another pass: the same source corners,
// water and slicing.
template <class Ref, class Key>
bool same_prism(const Ref& R, const BeamPrism& P, const Key& K) {
    if (!K.horizontal || K.up != R.up || K.water != R.water || K.periodic != R.periodic) return false;
    for (int j = 0; j < 3; ++j)
        if (P.v[j].x != R.v[3 * j] || P.v[j].y != R.v[3 * j + 1] || P.v[j].z != R.v[3 * j + 2]) return false;
    return true;
}

void ray_ends(const BeamPrism& P, double* end) {
    for (int j = 0; j < 3; ++j) end[j] = P.mv[j] + P.md[j] * P.len[j];
}

// The layers of cells (as build_grid marks them) that a horizontally sliced prism's heights
// [h0, h1] cross.
template <class Grid>
void layers(const Grid& g, bool up, double h0, double h1, int* k0, int* k1) {
    const double zlo = up ? h0 : -h1, zhi = up ? h1 : -h0;
    *k0 = std::clamp(int(std::floor((zlo - g.lo.z) / g.cell.z)), 0, g.nz - 1);
    *k1 = std::clamp(int(std::floor((zhi - g.lo.z) / g.cell.z)), 0, g.nz - 1);
}

}  // namespace

void Scene::build_grid_reference(const Spectrum& e_sun, int threads) {
    GridReference& ref = grid_ref_;
    ref.built = true;
    ref.usable = false;
    ref.sun = sun_dir;
    ref.cos_half = sun_cos_half;
    ref.prisms.clear();
    ref.grid.clear();
    // (The centre's prisms in the buffers of the build's own, which it fills later: their
    // memory is faulted in once.)
    LargeVector<BeamPrism>& centre = prisms;
    LargeVector<PrismKey>& keys = prism_keys_;
    struct Empty {  // left empty, whichever way this returns
        Scene* s;
        ~Empty() {
            s->prisms.clear();
            s->prism_keys_.clear();
        }
    } empty{this};
    centre.clear();
    std::vector<std::array<Vec3, 3>> normals;  // each prism's corners' shading normals
    make_prisms(sun_dir, e_sun, false, threads, 0.5, 0.0, &centre, &normals);
    make_keys(centre, &keys);
    if (centre.empty()) return;
    for (const PrismKey& K : keys)
        if (!K.horizontal) return;
    double sx, sy;
    grid_shear(keys, &sx, &sy);
    ref.sx = sx;
    ref.sy = sy;
    ref.prisms.resize(centre.size());
    for (size_t i = 0; i < centre.size(); ++i) {
        if ((i & 4095) == 0 && cancel_flag.load(std::memory_order_relaxed)) throw BuildCancelled{};
        const BeamPrism& P = centre[i];
        const PrismKey& K = keys[i];
        ReferencePrism& R = ref.prisms[i];
        for (int j = 0; j < 3; ++j) {
            R.v[3 * j] = P.v[j].x;
            R.v[3 * j + 1] = P.v[j].y;
            R.v[3 * j + 2] = P.v[j].z;
            R.ax[j] = K.ax[j];
            R.bx[j] = K.bx[j];
            R.ay[j] = K.ay[j];
            R.by[j] = K.by[j];
        }
        ray_ends(P, R.end);
        R.water = K.water;
        R.up = K.up;
        R.periodic = K.periodic;
    }
    // Two probes on the disk's edge at right angles: the prisms move about linearly with the
    // direction, so at angle phi on the edge each deviation is at most sqrt(d1^2 + d2^2) (d1,
    // d2: the probes'); the margins add a quarter for what is not linear. A probe's prism is
    // the centre's with its corners' rays refracted for the probe's direction, as make_prisms
    // refracts them (its keys need no more: no ray is traced; a pass whose prisms are made
    // otherwise, subdivided where the centre's are not, gets a grid of its own).
    const double alpha = std::acos(std::clamp(sun_cos_half, -1.0, 1.0));
    const Vec3 a = std::fabs(sun_dir.x) < 0.9 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
    const Vec3 u = normalize(cross(sun_dir, a)), v = cross(sun_dir, u);
    const double ior = waters[ocean_water].ior;
    std::vector<double> a1(centre.size(), 0.0), g1(centre.size(), 0.0);
    for (ReferencePrism& R : ref.prisms) R.margin_a = R.margin_g = 0.0;
    for (int k = 0; k < 2 && alpha > 0.0; ++k) {
        const Vec3 dir = normalize(sun_dir * std::cos(alpha) + (k == 0 ? u : v) * std::sin(alpha));
        double px, py;
        if (!reference_shear(dir, &px, &py)) return;
        for (size_t i = 0; i < centre.size(); ++i) {
            if ((i & 4095) == 0 && cancel_flag.load(std::memory_order_relaxed)) throw BuildCancelled{};
            ReferencePrism& R = ref.prisms[i];
            const BeamPrism& P = centre[i];
            PrismKey Q = keys[i];  // the probe's key
            for (int j = 0; j < 3; ++j) {
                // (trace_vertex's direction: through the corner's normal, else the face's)
                const Vec3& n = normals[i][j];
                Vec3 d;
                if (!(dot(n, dir) > 0.0 && refract(-dir, n, 1.0, ior, &d)) && !refract(-dir, P.n_src, 1.0, ior, &d))
                    d = -n;
                const double md = Q.up ? d.z : -d.z, mv = Q.up ? P.v[j].z : -P.v[j].z;
                if (!(md > 0.1)) return;  // (its prism would not be sliced alike)
                Q.bx[j] = d.x / md;
                Q.by[j] = d.y / md;
                Q.ax[j] = P.v[j].x - Q.bx[j] * mv;
                Q.ay[j] = P.v[j].y - Q.by[j] * mv;
            }
            double da, dg;
            deviation(R, sx, sy, Q, px, py, &da, &dg);
            if (k == 0) {
                a1[i] = da;
                g1[i] = dg;
            } else {
                R.margin_a = 1.25 * std::hypot(a1[i], da);
                R.margin_g = 1.25 * std::hypot(g1[i], dg);
            }
        }
    }
    // (Some deviations are rounding, 1e-16 m, which is not linear in the direction: the
    // margins take 1e-10 of the scene's size more; the grid's boxes 1e-9, far more than their
    // own rounding.)
    std::vector<double> ma(centre.size()), mg(centre.size());
    for (size_t i = 0; i < centre.size(); ++i) {
        ReferencePrism& R = ref.prisms[i];
        R.margin_a += 1e-10 * extent_;
        R.margin_g = R.margin_g * (1.0 + 1e-9) + 1e-12;
        ma[i] = R.margin_a + 1e-9 * extent_;
        mg[i] = R.margin_g * (1.0 + 1e-9);
    }
    build_grid(centre, keys, &ref.grid, ma.data(), mg.data(), &cancel_flag);
    ref.usable = true;
}

bool Scene::grid_reference_fits(double sx, double sy) const {
    const GridReference& ref = grid_ref_;
    if (prisms.size() != ref.prisms.size()) return false;
    for (size_t i = 0; i < prisms.size(); ++i) {
        const ReferencePrism& R = ref.prisms[i];
        const BeamPrism& P = prisms[i];
        const PrismKey& K = prism_keys_[i];
        if (!same_prism(R, P, K)) return false;
        double end[3], da, dg;
        ray_ends(P, end);
        deviation(R, ref.sx, ref.sy, K, sx, sy, &da, &dg);
        if (!(da <= R.margin_a && dg <= R.margin_g)) return false;
        // the heights it spans must lie in the layers the reference's marked
        double h0 = kInf, h1 = -kInf, r1 = -kInf;
        for (int j = 0; j < 3; ++j) {
            h0 = std::min(h0, start_height(R, j));
            h1 = std::max(h1, end[j]);
            r1 = std::max(r1, R.end[j]);
        }
        int k0, k1, m0, m1;
        layers(ref.grid, R.up, h0, h1, &k0, &k1);
        layers(ref.grid, R.up, h0, r1, &m0, &m1);
        if (k0 < m0 || k1 > m1) return false;
    }
    return true;
}

}  // namespace photic
