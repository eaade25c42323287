#include "medium.h"

namespace photic {

void Water::varying_transmittance(const Vec3& a, const Vec3& b, double len, int nb, double* T,
                                  const double* integral) const {
    if (grid) {
        double r[VoxelGrid::kMaxFields];
        if (!integral) {
            grid->integral(a, b, len, r);
            integral = r;
        }
        grid_transmittance(a.z, b.z, len, integral, nb, T);
    } else {
        Spectrum tau;
        add_optical_depth(&WaterLayer::c_beam, a.z, b.z, len, nb, &tau);
        for (int k = 0; k < nb; ++k) T[k] = std::exp(-tau.v[k]);
    }
}

void WaterLayer::set_path_coefficients(const std::vector<ScatterComponent>& components, int nbands) {
    b_path = Spectrum();
    comp_b_path.assign(components.size(), Spectrum());
    for (size_t ci = 0; ci < components.size(); ++ci)
        for (int k = 0; k < nbands; ++k) {
            comp_b_path[ci].v[k] = comp_b[ci].v[k] * (1.0 - components[ci].f);
            b_path.v[k] += comp_b_path[ci].v[k];
        }
    for (int k = 0; k < nbands; ++k) {
        c_beam.v[k] = a.v[k] + b_path.v[k];
        c_path.v[k] = c_beam.v[k];
    }
}

void Water::set_forward_cone(const std::vector<PhaseFunction>& phases, double cone_half_angle, int nbands) {
    double xc = 1.0 - std::cos(cone_half_angle);
    for (auto& c : components) c.f = cone_half_angle > 0.0 ? phases[c.phase].cdf(xc) : 0.0;
    majorant = 0.0;
    c_beam_min = kInf;
    b_max = 0.0;
    for (const auto& L : layers)
        for (int k = 0; k < nbands; ++k) b_max = std::max(b_max, L.b.v[k]);
    double c_mean_min = kInf;
    for (auto& L : layers) {
        L.set_path_coefficients(components, nbands);
        L.c_path_mean = 0.0;
        L.a_min = L.a.v[0];
        L.majorant = 0.0;
        for (int k = 0; k < nbands; ++k) {
            L.majorant = std::max(L.majorant, L.b_path.v[k]);
            majorant = std::max(majorant, L.b_path.v[k]);
            L.c_path_mean += L.c_path.v[k] / nbands;
            L.a_min = std::min(L.a_min, L.a.v[k]);
            c_beam_min = std::min(c_beam_min, L.c_beam.v[k]);
        }
        a_min = &L == &layers[0] ? L.a_min : std::min(a_min, L.a_min);
        if (L.c_path_mean > 0.0) c_mean_min = std::min(c_mean_min, L.c_path_mean);
    }
    // Beam scattering along segments samples distances at this rate (any rate > 0 is
    // unbiased); in stratified water the slowest layer's, so the weights stay bounded.
    c_path_mean = !stratified() ? layers[0].c_path_mean : c_mean_min < kInf ? c_mean_min : 0.0;
    // Beam-direction MIS: each component's share of all scattering (bands and layers).
    mis_bsum = 0.0;
    mis_wsum = 0.0;
    for (size_t ci = 0; ci < components.size(); ++ci) {
        double b = 0.0;
        for (const auto& L : layers)
            for (int k = 0; k < nbands; ++k) {
                b += L.comp_b[ci].v[k];
                mis_bsum += L.comp_b[ci].v[k];
            }
        components[ci].weight = b;
        mis_wsum += b;
    }
    inelastic_split = 0.0;
    for (int k = 0; k < nbands; ++k) {
        double gain = 0.0, b = kInf;
        for (const Inelastic& P : inelastic) gain += P.in_max.v[k];
        for (const auto& L : layers) b = std::min(b, L.b_path.v[k]);
        if (gain > 0.0) inelastic_split = std::max(inelastic_split, std::clamp(gain / (gain + b), 0.01, 0.5));
    }
    if (grid) set_grid_coefficients(nbands);
}

// A grid's unit coefficients with the forward cone's f, the free paths' majorant
// s0 + sum_f s1[f] rho_f, and the water's bounds (majorant, smallest beam attenuation,
// beam-scattering rate, MIS weights) widened to every density in the grid.
// c(x) = c_base + sum_f rho_f c_unit,f with rho_f >= 0 and c_unit,f >= 0.
void Water::set_grid_coefficients(int nbands) {
    VoxelGrid& g = *grid;
    const int nf = grid_fields();
    for (WaterLayer& U : grid_units) U.set_path_coefficients(components, nbands);
    grid_scatter_fields = 0;
    grid_comp_fields.assign(components.size(), 0u);
    for (int f = 0; f < nf; ++f)
        for (size_t ci = 0; ci < components.size(); ++ci)
            for (int k = 0; k < nbands; ++k)
                if (grid_units[f].comp_b[ci].v[k] > 0.0) {
                    grid_comp_fields[ci] |= 1u << f;
                    grid_scatter_fields |= 1u << f;
                }
    // Over the base's layers (a depth profile under the grid) and bands.
    grid_s0 = 0.0;
    for (int f = 0; f < nf; ++f) {
        grid_s1[f] = 0.0;
        for (int k = 0; k < nbands; ++k) grid_s1[f] = std::max(grid_s1[f], grid_units[f].b_path.v[k]);
    }
    double rmin[VoxelGrid::kMaxFields], rmax[VoxelGrid::kMaxFields];
    for (int f = 0; f < nf; ++f) {
        rmin[f] = g.rho_min[f];
        rmax[f] = g.rho_max[f];
    }
    double cmean = 0.0;
    for (const WaterLayer& B : layers) {
        double c_beam_lo[kMaxBands], c_path_hi[kMaxBands];  // at the least and most densities
        std::copy_n(B.c_beam.v.data(), nbands, c_beam_lo);
        std::copy_n(B.c_path.v.data(), nbands, c_path_hi);
        grid_add_bands(rmin, &WaterLayer::c_beam, nbands, c_beam_lo);
        grid_add_bands(rmax, &WaterLayer::c_path, nbands, c_path_hi);
        double layer_mean = 0.0;
        for (int k = 0; k < nbands; ++k) {
            grid_s0 = std::max(grid_s0, B.b_path.v[k]);
            c_beam_min = std::min(c_beam_min, c_beam_lo[k]);
            a_min = std::min(a_min, B.a.v[k]);
            layer_mean += c_path_hi[k] / nbands;
        }
        cmean = std::max(cmean, layer_mean);
    }
    majorant = std::max(majorant, grid_majorant(rmax));
    for (const WaterLayer& B : layers)  // b at the densest voxel of every field
        for (int k = 0; k < nbands; ++k) {
            double b = B.b.v[k];
            for (int f = 0; f < nf; ++f)
                for (const Spectrum& cb : grid_units[f].comp_b) b += rmax[f] * cb.v[k];
            b_max = std::max(b_max, b);
        }
    if (!(c_path_mean > 0.0)) c_path_mean = cmean;  // any rate > 0 is unbiased
    for (size_t ci = 0; ci < components.size(); ++ci) {
        double b = 0.0;
        for (int k = 0; k < nbands; ++k)
            for (const WaterLayer& U : grid_units) b += U.comp_b[ci].v[k];
        components[ci].weight += b;
        mis_bsum += b;
        mis_wsum += b;
    }
}

Vec3 Inelastic::sample_direction(const Vec3& d, Rng& rng) const {
    // cos(psi) by rejection from the uniform density (accepted at least 1 / (1 + rho) of the
    // time: 65 % for Raman's 0.55, always when isotropic), then a uniform azimuth about d.
    double mu;
    do mu = 2.0 * rng.uniform() - 1.0;
    while (rho > 0.0 && rng.uniform() * (1.0 + rho) > 1.0 + rho * mu * mu);
    return direction_around(d, 1.0 - mu, 2.0 * kPi * rng.uniform());
}

}  // namespace photic
