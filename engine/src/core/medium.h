// Water as a participating medium: its coefficients (homogeneous, a depth profile of layers,
// or a 3-D grid of densities over a base), and behind a few calls what the integrator and the
// beams ask of it, whatever its kind: the coefficients at a point, the transmittance of a
// straight segment, and (MediumWalk) a path's free flights, collisions and absorption.
#pragma once
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <vector>
#include "phase.h"
#include "rng.h"
#include "vec.h"
#include "voxel_grid.h"

namespace photic {

constexpr int kMaxBands = 16;  // bands per render pass; larger band lists are split in groups

struct Spectrum {
    std::array<double, kMaxBands> v{};
    static Spectrum constant(double c) { Spectrum s; s.v.fill(c); return s; }
};

// Inelastic processes: Raman scattering by water, fluorescence by chlorophyll and by CDOM (their
// light is reported apart: Components::inelastic[kind]).
constexpr int kInelasticKinds = 3;
enum InelasticKind { kRaman = 0, kChlorophyll = 1, kCDOM = 2 };

// One inelastic process of a water body (Scene::set_water_inelastic): light of excitation band
// i leaves it (the loss is in the band's absorption) and re-appears in emission band j, with
// coupling(l)[j * nb + i] (m^-1) in layer l the gain of band j per unit of band i's spectral
// irradiance (the emission's share in band j, photons to energy), and the phase function
// 3 / (4 pi (3 + rho)) (1 + rho cos^2) (Raman: rho 0.55; fluorescence: 0, isotropic). One
// layer's coupling serves every layer. Beams (their single scattering) and paths (their own
// inelastic collisions) alike.
struct Inelastic {
    int kind = kRaman;
    double rho = 0.0;
    int nb = 0, nlayers = 1;
    std::vector<double> coupling;  // nlayers x nb x nb
    std::vector<Spectrum> in;      // per layer, per emission band j: sum_i coupling[j][i]
    Spectrum in_max;               // per emission band: its largest over the layers
    // Per emission band j, the excitation bands [from[j], to[j]) of its nonzero couplings in
    // any layer (a few neighbours for Raman: the loop over them is what it costs per beam).
    std::vector<int> from, to;
    double rate = 0.0;             // the largest `in`: the rate of the paths' tentative collisions
    const double* at(int layer) const { return coupling.data() + size_t(nlayers > 1 ? layer : 0) * nb * nb; }
    const Spectrum& in_at(int layer) const { return in[nlayers > 1 ? layer : 0]; }
    double phase(double mu) const { return 3.0 / (4.0 * kPi * (3.0 + rho)) * (1.0 + rho * mu * mu); }
    Vec3 sample_direction(const Vec3& d, Rng& rng) const;
};

struct ScatterComponent {
    int phase = 0;   // index into Scene::phases (the same in every layer of a water body)
    double f = 0.0;  // fraction of its phase function inside the forward cone (kept in beams)
    double weight = 0.0;  // sum of its b over bands and layers: its share in beam-direction MIS
};

// The IOPs of one horizontal layer of a water body. Homogeneous water has one layer; stratified
// water has several, piecewise constant in z (photic.scene.IOPProfile).
struct WaterLayer {
    double z_top = kInf;                 // upper boundary (m); the first layer has no upper limit
    Spectrum a;                          // absorption per band, 1/m
    Spectrum b;                          // total scattering per band, 1/m
    std::vector<Spectrum> comp_b;        // per component of Water::components: b per band
    std::vector<Spectrum> comp_b_path;   // per component: b (1 - f), what path tracing scatters
    double a_min = 0.0;                  // smallest absorption over the bands
    double majorant = 0.0;               // largest b_path over the bands (regional tracking)
    Spectrum b_path;                     // scattering sampled by paths: sum of b (1 - f)
    Spectrum c_beam;                     // beam attenuation a + b (1 - f)
    Spectrum c_path;                     // a + b_path: attenuation of light along a path
    double c_path_mean = 0.0;
    // comp_b_path, b_path, c_beam and c_path from a, comp_b and the components' cone fractions.
    void set_path_coefficients(const std::vector<ScatterComponent>& components, int nbands);
};

struct Water {
    double ior = 1.34;
    std::vector<ScatterComponent> components;
    // Layers from the top down: layers[i] holds layers[i+1].z_top < z <= layers[i].z_top, the
    // last one extends downwards without limit and the first one upwards. One layer:
    // homogeneous water (the plain code paths).
    std::vector<WaterLayer> layers;
    double majorant = 0.0;               // >= b_path in every band and layer (delta tracking)
    double a_min = 0.0;                  // smallest absorption over the bands and layers
    double c_path_mean = 0.0;            // homogeneous: the layer's; stratified: smallest > 0
    double c_beam_min = 0.0;             // smallest beam attenuation over bands and layers
    double b_max = 0.0;                  // largest b (all scattering) over bands, layers, voxels
    double mis_bsum = 0.0;               // sum of all b (beam-direction MIS sampling)
    double mis_wsum = 0.0;               // sum of the components' weights (its pdf)
    // Its inelastic processes (none: purely elastic), and the sum of their rates.
    std::vector<Inelastic> inelastic;
    double inelastic_rate = 0.0;
    // How often a path estimates the inelastic light along a water segment by a branch
    // (Scene::inelastic_branch; else, until it makes one, it leaves it out: Russian roulette):
    // as often as that light matters against the elastic light there, the largest gain /
    // (gain + b_path) over the bands, at least 1/100 and at most 1/2 (set_forward_cone). (A
    // trade: in clear water, where b is 100 times the gain, a Raman share of Rrs of 10-15 %
    // comes mostly through the branches, whose variance grows as 1 / split; a floor of 1/10
    // cut the cost of those bands' error 3-fold but made every scene with Raman on 1.5x
    // slower, its elastic bands included.)
    double inelastic_split = 0.0;

    // Its kind: homogeneous (one layer, no grid), layered (stratified) or gridded (grid set,
    // over one layer or several); varying(): not homogeneous.
    bool stratified() const { return layers.size() > 1; }
    // Whether the water scatters anywhere, in any band: only then are there beam-direction
    // samples (Scene::sample_beam_direction draws from the scattering components' phase
    // functions; with no scattering their pdf is 0 and no direction may be drawn from them).
    bool scatters() const { return mis_wsum > 0.0; }

    // ---- What the integrator and the beams ask, whatever the kind ----
    // The path/beam coefficients from the components' b and a with the forward cone's
    // half-angle (the fraction f of each component's phase function inside it stays in the
    // beams), and the bounds the tracking needs (majorants, smallest attenuation, MIS sums).
    void set_forward_cone(const std::vector<PhaseFunction>& phases, double half_angle, int nbands);
    // Transmittance exp(-int c dl) per band over the straight segment from a to b of length
    // len, c = a + b (1 - f) (beams and paths alike). exact = false: the first layer's
    // coefficients everywhere (a ranking only). `integral`: the grid's density integral over
    // the segment where the caller knows it already.
    void transmittance(const Vec3& a, const Vec3& b, double len, int nb, double* T, bool exact = true,
                       const double* integral = nullptr) const {
        if (!varying() || !exact) {  // (inline: the common case, once per beam evaluation)
            const Spectrum& c = layers[0].c_beam;
            for (int k = 0; k < nb; ++k) T[k] = std::exp(-c.v[k] * len);
        } else {
            varying_transmittance(a, b, len, nb, T, integral);
        }
    }
    void varying_transmittance(const Vec3& a, const Vec3& b, double len, int nb, double* T,
                               const double* integral) const;  // layers or grid
    // The absorption and scattering optical depths over such a segment, added to *tau_a and
    // *tau_b (one walk through a grid for both).
    void add_optical_depths(const Vec3& a, const Vec3& b, double len, int nb, Spectrum* tau_a,
                            Spectrum* tau_b) const {
        add_optical_depth(&WaterLayer::a, a.z, b.z, len, nb, tau_a);
        add_optical_depth(&WaterLayer::b, a.z, b.z, len, nb, tau_b);
        if (grid) {
            double r[VoxelGrid::kMaxFields];
            grid->integral(a, b, len, r);
            grid_add_bands(r, &WaterLayer::a, nb, tau_a->v.data());
            grid_add_bands(r, &WaterLayer::b, nb, tau_b->v.data());
        }
    }
    // The water at a point: its base layer and, inside a grid, the densities there.
    struct Point {
        const WaterLayer* base;
        bool in_field;
        double rho[VoxelGrid::kMaxFields];
    };
    Point at(const Vec3& x) const {
        Point p;
        p.base = &layer_at(x.z);
        p.in_field = grid && grid->at(x, p.rho);
        return p;
    }
    // sum over components c of b_c(x) pv[c] per band, added to bp[0..nb): the scattering
    // towards a direction whose component phase functions are pv.
    void add_scattering(const Point& p, const double* pv, int nb, double* bp) const {
        const size_t nc = components.size();
        for (size_t ci = 0; ci < nc; ++ci) {
            const double* __restrict u = p.base->comp_b[ci].v.data();
            for (int kb = 0; kb < nb; ++kb) bp[kb] += u[kb] * pv[ci];
        }
        if (p.in_field)
            for (int f = 0; f < grid_fields(); ++f)
                if (p.rho[f] > 0.0)
                    for (size_t ci = 0; ci < nc; ++ci) {
                        if (!(grid_comp_fields[ci] >> f & 1u)) continue;
                        const double* __restrict u = grid_units[f].comp_b[ci].v.data();
                        for (int kb = 0; kb < nb; ++kb) bp[kb] += p.rho[f] * u[kb] * pv[ci];
                    }
    }

    // ---- The kinds' own representation (MediumWalk and the calls above use these) ----
    // 3-D IOPs over a box, or null: c(x) = c_base(z) + sum_f rho_f(x) c_unit,f (absorption
    // and each component's b alike) over the grid's density fields, with the base IOPs in the
    // layers (one: homogeneous; several: a depth profile) and each field's unit ones in
    // grid_units. Densities and their integrals come as arrays rho[0..fields).
    std::shared_ptr<VoxelGrid> grid;
    std::vector<WaterLayer> grid_units;  // one per field
    int grid_nf = 0;                     // their number (read per voxel step: a plain int)
    // The free paths' majorant in a grid where the densities are rho: s0 + sum_f s1[f] rho_f
    // >= b_path in every band (s0, s1[f]: the base's and field f's unit b_path's largest over
    // the bands and layers).
    double grid_s0 = 0.0, grid_s1[VoxelGrid::kMaxFields] = {};
    // Bit f set where field f's unit scatters at all (grid_scatter_fields), and per component
    // where it scatters in that component (grid_comp_fields): the sums below skip the rest (a
    // CDOM field scatters nothing; a particle field adds to its own component only).
    unsigned grid_scatter_fields = 0;
    std::vector<unsigned> grid_comp_fields;
    bool varying() const { return layers.size() > 1 || grid; }
    int grid_fields() const { return grid_nf; }
    double grid_majorant(const double* r) const {
        double m = grid_s0;
        for (int f = 0; f < grid_fields(); ++f) m += grid_s1[f] * r[f];
        return m;
    }
    // sum_f r[f] unit_f[k] added to out[k] in bands 0..nb, the fields in order; unit(U) is
    // the Spectrum of field unit U to scale. The bands innermost, in a loop the compiler
    // vectorises (a loop over the fields per band did a few flops per branch, at every
    // collision and for every transmittance). Fields with r = 0 add nothing.
    template <class Unit>
    void grid_add_bands(const double* r, Unit unit, int nb, double* __restrict out, unsigned fields = ~0u) const {
        for (int f = 0; f < grid_nf; ++f) {
            const double rf = r[f];
            if (rf == 0.0 || !(fields >> f & 1u)) continue;
            const double* __restrict u = unit(grid_units[f]).v.data();
            for (int k = 0; k < nb; ++k) out[k] += rf * u[k];
        }
    }
    // The same for the member `what` of each field's unit WaterLayer.
    void grid_add_bands(const double* r, Spectrum WaterLayer::*what, int nb, double* out, unsigned fields = ~0u) const {
        grid_add_bands(r, [what](const WaterLayer& U) -> const Spectrum& { return U.*what; }, nb, out, fields);
    }
    // A grid's coefficients where its densities are r: the base plus the fields' units times
    // their densities (written into *scratch). Only what a collision's decision reads, b_path
    // (linear in r like every coefficient, so the base's and units' sums serve); a scattering
    // vertex then asks for the components' b_path with local_components.
    // (z: the height, for the base's layer.)
    const WaterLayer& local_at_density(const double* r, double z, WaterLayer* scratch, int nb) const {
        const WaterLayer& B = layer_at(z);
        bool zero = true;
        for (int f = 0; f < grid_fields(); ++f) zero = zero && r[f] == 0.0;
        if (zero) return B;
        double* out = scratch->b_path.v.data();
        std::copy_n(B.b_path.v.data(), nb, out);
        grid_add_bands(r, &WaterLayer::b_path, nb, out, grid_scatter_fields);
        return *scratch;
    }
    void local_components(const double* r, double z, WaterLayer* scratch, int nb) const {
        const WaterLayer& B = layer_at(z);
        const size_t nc = B.comp_b_path.size();
        scratch->comp_b_path.resize(nc);
        for (size_t c = 0; c < nc; ++c) {
            double* out = scratch->comp_b_path[c].v.data();
            std::copy_n(B.comp_b_path[c].v.data(), nb, out);
            grid_add_bands(r, [c](const WaterLayer& U) -> const Spectrum& { return U.comp_b_path[c]; }, nb, out,
                           grid_comp_fields[c]);
        }
    }
    // Grid, a segment of length len over which the densities integrate to r: its absorption
    // optical depth added to *tau, and its attenuation exp(-c_path optical depth) into
    // t[0..nb) (no spectrum to clear: these run once or twice per path segment), per band.
    // The segment runs from height z0 to z1 (the base's layers).
    void grid_absorption(double z0, double z1, double len, const double* r, int nb, Spectrum* tau) const {
        double g[kMaxBands];
        grid_depth(&WaterLayer::a, len, r, nb, g);
        if (layers.size() > 1) add_optical_depth(&WaterLayer::a, z0, z1, len, nb, tau);
        for (int k = 0; k < nb; ++k) tau->v[k] += g[k];
    }
    void grid_transmittance(double z0, double z1, double len, const double* r, int nb, double* t) const {
        double g[kMaxBands];
        grid_depth(&WaterLayer::c_path, len, r, nb, g);
        if (layers.size() > 1) {
            Spectrum tau;
            add_optical_depth(&WaterLayer::c_path, z0, z1, len, nb, &tau);
            for (int k = 0; k < nb; ++k) g[k] += tau.v[k];
        }
        for (int k = 0; k < nb; ++k) t[k] = std::exp(-g[k]);
    }
    // The optical depth of coefficient `what` over such a segment in g[0..nb): the fields', plus
    // the homogeneous base's (a layered base's is added by the callers, through its layers).
    void grid_depth(Spectrum WaterLayer::*what, double len, const double* r, int nb, double* g) const {
        const bool layered = layers.size() > 1;
        for (int k = 0; k < nb; ++k) g[k] = layered ? 0.0 : (layers[0].*what).v[k] * len;
        grid_add_bands(r, what, nb, g);
    }
    const WaterLayer& layer_at(double z) const { return layers[layer_index(z)]; }
    int layer_index(double z) const {
        int lo = 1, hi = int(layers.size());  // the first layer i >= 1 with z_top < z, minus one
        while (lo < hi) {
            int mid = (lo + hi) / 2;
            if (layers[mid].z_top >= z) lo = mid + 1; else hi = mid;
        }
        return lo - 1;
    }
    // Regional delta tracking through the layers: the distance from height z, along a
    // direction with vertical component dz, at which the optical depth of the layers'
    // majorants reaches xi (an Exp(1) sample), and the layer it lies in; kInf if never.
    double free_flight(double z, double dz, double xi, int* layer) const {
        const int n = int(layers.size());
        int i = layer_index(z);
        double t = 0.0;
        for (;;) {
            const WaterLayer& L = layers[i];
            int next = -1;
            double s = kInf, zb = z;  // distance to the layer's boundary along the ray
            if (dz < 0.0 && i + 1 < n) { next = i + 1; zb = layers[next].z_top; }
            else if (dz > 0.0 && i > 0) { next = i - 1; zb = L.z_top; }
            if (next >= 0) s = std::max(0.0, (zb - z) / dz);
            if (L.majorant > 0.0 && xi < L.majorant * s) {
                *layer = i;
                return t + xi / L.majorant;
            }
            if (next < 0) return kInf;
            xi -= L.majorant * s;
            t += s;
            z = zb;
            i = next;
        }
    }
    // Adds the optical depth of one coefficient (e.g. &WaterLayer::a) over a straight segment
    // of length len from height z0 to z1, per band: closed form, layer by layer.
    void add_optical_depth(Spectrum WaterLayer::*coef, double z0, double z1, double len, int nb,
                           Spectrum* tau) const {
        if (layers.size() == 1 || z0 == z1) {
            const Spectrum& c = layer_at(z0).*coef;
            for (int k = 0; k < nb; ++k) tau->v[k] += c.v[k] * len;
            return;
        }
        double zlo = std::min(z0, z1), zhi = std::max(z0, z1), inv = len / (zhi - zlo);
        for (int i = layer_index(zhi), n = int(layers.size()); i < n; ++i) {
            double top = i == 0 ? zhi : std::min(zhi, layers[i].z_top);
            double bottom = i + 1 < n ? std::max(zlo, layers[i + 1].z_top) : zlo;
            if (top > bottom) {
                const Spectrum& c = layers[i].*coef;
                double l = (top - bottom) * inv;
                for (int k = 0; k < nb; ++k) tau->v[k] += c.v[k] * l;
            }
            if (bottom <= zlo) break;
        }
    }
private:
    void set_grid_coefficients(int nbands);
};

// A path's walk through water (delta tracking, in the spirit of pbrt-v4's majorant
// iterator): per segment the free flights to tentative collisions against the medium's
// majorant (the water's one, each layer's own: regional tracking, or in a grid the local
// s0 + s1 rho along a voxel walk), the coefficients at a collision, and the absorption
// travelled, which is applied to the path's throughput lazily (light is scored in water only
// by the beam terms, which apply it themselves; Russian roulette uses a bound meanwhile).
// The integrator calls the same few methods whatever the water's kind.
class MediumWalk {
public:
    // scratch: a grid's coefficients at the current collision (reused: one per thread);
    // inelastic: where a deferred beam term's inelastic light goes (the path's components,
    // kInelasticKinds of them).
    MediumWalk(int nb, WaterLayer* scratch, Spectrum* inelastic) : nb_(nb), scratch_(scratch), inelastic_out_(inelastic) {}

    // ---- The path's absorption not yet carried by its throughput ----
    double absorbed(const Water& w, int k) const {  // the factor, band k
        return w.varying() ? std::exp(-tau_a_.v[k]) : std::exp(-w.layers[0].a.v[k] * pending_);
    }
    double absorbed_bound(const Water& w) const {  // >= absorbed(w, k) in every band
        if (!w.varying()) return std::exp(-w.a_min * pending_);
        double t = tau_a_.v[0];
        for (int k = 1; k < nb_; ++k) t = std::min(t, tau_a_.v[k]);
        return std::exp(-t);
    }
    void flush(const Water& w, Spectrum* beta) {  // applies it
        if (w.varying()) {
            for (int k = 0; k < nb_; ++k) beta->v[k] *= std::exp(-tau_a_.v[k]);
            for (int k = 0; k < nb_; ++k) tau_a_.v[k] = 0.0;  // (only the bands in use are read)
            return;
        }
        if (pending_ > 0.0)
            for (int k = 0; k < nb_; ++k) beta->v[k] *= std::exp(-w.layers[0].a.v[k] * pending_);
        pending_ = 0.0;
    }

    // ---- One straight segment in water w from o along d ----
    void begin(const Water& w, const Vec3& o, const Vec3& d) {
        w_ = &w;
        o_ = o;
        d_ = d;
        L_ = &w.layers[0];
        lc_ = 0;
        dt0_ = kInf;
        xi0_ = -1.0;
        t_clip_ = kInf;
        t_beam_ = -1.0;
        beam_read_ = false;
        if (w.grid) {
            cursor_.emplace(*w.grid, o, d);
            // The walk's first column sums are fetched while the ray is intersected (the
            // walk waits on them otherwise, once per segment: 4-8 % of the plume example).
            cursor_->prefetch(3);
        }
    }
    // Whether the segment's ray may be cast only up to its first tentative collision
    // (short rays are cheaper, and most flights in water end in the volume): the water must
    // scatter, and a grid's walk cannot find that collision before the ray is cast (it would
    // go on past the surface or the floor and back), but its tracked coefficient
    // s0 + s1 rho is at least s0 (rho >= 0), so the collision lies within xi / s0.
    bool can_clip() const { return w_->majorant > 0.0 && (!w_->grid || w_->grid_s0 > 0.0); }
    // Before the ray is cast: draws what the medium needs first and returns how far the ray
    // must be cast to find what lies before the first tentative collision (clip = false: kInf).
    double before_cast(Rng& rng, bool clip) {
        if (w_->grid) {
            if (!clip) return kInf;
            xi0_ = depth(rng);
            t_clip_ = xi0_ / w_->grid_s0 * (1.0 + 1e-9) + 1e-9;  // (margin for the walk's rounding)
            return t_clip_;
        }
        if (w_->majorant > 0.0) dt0_ = plain_flight(depth(rng), 0.0);
        return clip ? dt0_ : kInf;
    }
    // A beam term along the segment at a point the walk has yet to pass (gridded water: its
    // attenuation comes from the walk) is written here by the beam code; null: none waits.
    double* beam_point() { return w_->grid ? &t_beam_ : nullptr; }
    // The beam term's contribution and its inelastic light (kInelasticKinds spectra; before
    // the attenuation to its point, where deferred): added to *volume and the inelastic
    // components now, or by settle() when the walk has passed its point.
    void add_beam(const Spectrum& contribution, const Spectrum* inelastic, Spectrum* volume) {
        if (w_->grid) {
            beam_wait_ = contribution;
            std::copy_n(inelastic, kInelasticKinds, inelastic_wait_);
        } else {
            for (int k = 0; k < nb_; ++k) volume->v[k] += contribution.v[k];
            for (int c = 0; c < kInelasticKinds; ++c)
                for (int k = 0; k < nb_; ++k) inelastic_out_[c].v[k] += inelastic[c].v[k];
        }
    }
    // The distance to the first tentative collision, after the ray is cast (t_hit: where it
    // ends, clipped: cast only to the clip distance; rest(t) casts the rest from t on and
    // updates both); kInf: none before the ray's end.
    template <class Rest>
    double first_flight(Rng& rng, const double& t_hit, const bool& clipped, Rest&& rest) {
        if (!w_->grid) return dt0_;
        if (!(w_->majorant > 0.0)) return kInf;
        return flight(xi0_ >= 0.0 ? xi0_ : depth(rng), 0.0, t_hit, clipped, rest);
    }
    // The next one, from a null collision at t_cur.
    template <class Rest>
    double next_flight(Rng& rng, double t_cur, const double& t_hit, const bool& clipped, Rest&& rest) {
        return flight(depth(rng), t_cur, t_hit, clipped, rest);
    }
    // At a tentative collision t (dt after the previous one): the coefficients there (b_path
    // for the decision) and the majorant the flight was drawn against.
    const WaterLayer& collide(double t, double dt, double* majorant) {
        const Water& w = *w_;
        if (w.grid) L_ = &w.local_at_density(grho_, o_.z + d_.z * t, scratch_, nb_);
        else if (w.stratified()) L_ = &w.layers[lc_];
        else pending_ += dt;
        *majorant = w.grid ? w.grid_majorant(grho_) : w.stratified() ? L_->majorant : w.majorant;
        return *L_;
    }
    // The path leaves the segment at t by a collision of its own process (an inelastic one,
    // independent of the walk's), the walk's last tentative collision at t_cur: the waiting
    // beam term and the absorption travelled up to t. A grid's walk may have gone on beyond t
    // (to its next tentative collision), so its integral to t is a walk of its own (rare:
    // once per Raman collision).
    void leave_at(double t, double t_cur, Spectrum* volume) {
        if (w_->grid) {
            settle(kInf, volume);
            double r[VoxelGrid::kMaxFields];
            const Vec3 x = o_ + d_ * t;
            w_->grid->integral(o_, x, t, r);
            w_->grid_absorption(o_.z, x.z, t, r, nb_, &tau_a_);
        } else if (w_->stratified()) {
            travel(t);
        } else {
            pending_ += t - t_cur;
        }
    }
    // The path scatters at the last collision t: the waiting beam term and the absorption up
    // to t settled; the coefficients there with each component's b_path.
    const WaterLayer& scatter_at(double t, Spectrum* volume) {
        settle(t, volume);
        if (L_ == scratch_) w_->local_components(grho_, o_.z + d_.z * t, scratch_, nb_);
        if (w_->stratified() && !w_->grid) travel(t);  // (a grid: settle did)
        return *L_;
    }
    // The segment ends at a surface at t_end (kInf: the ray escaped), the last collision at
    // t_cur: the waiting beam term and the absorption travelled.
    void end_at(double t_end, double t_cur, Spectrum* volume) {
        settle(t_end, volume);
        if (!(t_end < kInf)) return;
        if (w_->stratified() && !w_->grid) travel(t_end);
        else pending_ += t_end - t_cur;
    }
    // The path ends in the water (no absorption needed): the waiting beam term.
    void abandon(Spectrum* volume) { settle(kInf, volume); }

private:
    static double depth(Rng& rng) { return -std::log(1.0 - rng.uniform()); }  // an Exp(1) sample
    double plain_flight(double xi, double t_cur) {
        return w_->stratified() ? w_->free_flight(o_.z + d_.z * t_cur, d_.z, xi, &lc_) : xi / w_->majorant;
    }
    template <class Rest>
    double flight(double xi, double t_cur, const double& t_hit, const bool& clipped, Rest& rest) {
        if (!w_->grid) return plain_flight(xi, t_cur);
        for (;;) {  // on to the collision, reading the integral at t_beam on the way
            if (t_beam_ >= 0.0 && !beam_read_ && t_beam_ <= cursor_->position()) {
                std::copy_n(cursor_->integral(), VoxelGrid::kMaxFields, r_beam_);
                beam_read_ = true;
            }
            const bool to_beam = t_beam_ >= 0.0 && !beam_read_;
            if (cursor_->march(w_->grid_s0, w_->grid_s1, &xi, to_beam ? t_beam_ : clipped ? t_clip_ : t_hit, grho_))
                return cursor_->position() - t_cur;
            if (clipped && !to_beam) {
                // (Rounding only: the depth reaches xi by t_clip.) The rest of the ray, then
                // on to the collision.
                rest(cursor_->position());
                continue;
            }
            if (!to_beam) return kInf;  // none before the segment's end
        }
    }
    // Layers: the absorption optical depth from the segment's start to t.
    void travel(double t) { w_->add_optical_depth(&WaterLayer::a, o_.z, o_.z + d_.z * t, t, nb_, &tau_a_); }
    // Grid: the beam term of this segment waits for the walk (deferred to its point t_beam);
    // settle adds it and the absorption up to t_end (kInf: none needed). The cursor only walks
    // on: the two integrals are read in the order of their points.
    void settle(double t_end, Spectrum* volume) {
        if (w_->grid) settle_grid(t_end, volume);  // (the check inline: most water is not gridded)
    }
    void settle_grid(double t_end, Spectrum* volume) {
        const Water& w = *w_;
        double r_end[VoxelGrid::kMaxFields] = {};
        const bool end = t_end < kInf;
        const bool beam = t_beam_ >= 0.0 && !beam_read_;
        if (beam && (!end || t_beam_ <= t_end)) std::copy_n(cursor_->value(t_beam_), VoxelGrid::kMaxFields, r_beam_);
        // (Every walk stops at the segment's end t_hit, so t_end is at or beyond the position
        // but for rounding: at a collision t_cur sums the flights.)
        if (end) std::copy_n(cursor_->value(t_end), VoxelGrid::kMaxFields, r_end);
        if (beam && end && t_beam_ > t_end) std::copy_n(cursor_->value(t_beam_), VoxelGrid::kMaxFields, r_beam_);
        if (t_beam_ >= 0.0) {
            double att[kMaxBands];
            w.grid_transmittance(o_.z, o_.z + d_.z * t_beam_, t_beam_, r_beam_, nb_, att);
            for (int kb = 0; kb < nb_; ++kb) volume->v[kb] += beam_wait_.v[kb] * att[kb];
            for (int c = 0; c < kInelasticKinds; ++c)
                for (int kb = 0; kb < nb_; ++kb) inelastic_out_[c].v[kb] += inelastic_wait_[c].v[kb] * att[kb];
            t_beam_ = -1.0;
        }
        if (end) w.grid_absorption(o_.z, o_.z + d_.z * t_end, t_end, r_end, nb_, &tau_a_);
    }

    const int nb_;
    WaterLayer* scratch_;
    Spectrum* inelastic_out_;
    // The path's absorption since its throughput last carried it: `pending_` metres in
    // homogeneous water (factor exp(-a s)), or the optical depth tau_a_ per band in layered or
    // gridded water, added exactly segment by segment (factor exp(-tau_a)).
    double pending_ = 0.0;
    Spectrum tau_a_;
    // The segment.
    const Water* w_ = nullptr;
    Vec3 o_, d_;
    const WaterLayer* L_ = nullptr;  // the coefficients at the tentative collision
    int lc_ = 0;                     // layers: its layer
    double dt0_ = kInf, xi0_ = -1.0;  // the first flight, or a grid's first depth, drawn before the cast
    double t_clip_ = kInf;           // gridded, clipped: the ray was intersected up to here only
    std::optional<VoxelGrid::Cursor> cursor_;
    double grho_[VoxelGrid::kMaxFields] = {};  // a grid's densities at the collision
    double t_beam_ = -1.0, r_beam_[VoxelGrid::kMaxFields] = {};
    bool beam_read_ = false;
    Spectrum beam_wait_, inelastic_wait_[kInelasticKinds];
};

}  // namespace photic
