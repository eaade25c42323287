// Unbiased volumetric path tracing of water light fields (the baseline integrator).
//
// Volume: distances are sampled from a scattering majorant; absorption is carried as the
// weight exp(-a t) per band, and the gap between the majorant and each band's b is handled
// by null collisions (spectral delta tracking), so one geometric path serves all bands and
// spatially varying IOPs only need a majorant. Interfaces: Fresnel reflect / refract chosen
// by probability, radiance scaled by the n^2 law. Sun: next-event estimation wherever a
// straight, unrefracted connection exists (vertices in air); otherwise paths find it by
// escaping into its disk.
#include <cmath>
#include <thread>
#include <vector>
#include "optics.h"
#include "parallel.h"
#include "scene.h"

namespace photic {

namespace {

constexpr double kShiftMin = 0.1;  // the least probability of an inelastic collision's event

Vec3 cosine_hemisphere(const Vec3& n, double u1, double u2) {
    // 1 - cos(theta) = 1 - sqrt(1 - u1)
    double mu = std::sqrt(1.0 - u1);
    return direction_around(n, 1.0 - mu, 2.0 * kPi * u2);
}

double max_component(const Spectrum& s, int nb) {
    double m = 0.0;
    for (int k = 0; k < nb; ++k) m = std::max(m, s.v[k]);
    return m;
}

}  // namespace

void Scene::beam_scatter_along(const Vec3& o, const Vec3& d, double T, int medium, Rng& rng,
                               Spectrum* out, double* deferred_t, Spectrum* inelastic) const {
    *out = Spectrum();
    if (inelastic) std::fill_n(inelastic, kInelasticKinds, Spectrum());
    double t, pdf;
    if (!beam_scatter_point(waters[medium], d, T, rng, &t, &pdf)) return;
    thread_local BeamSample beams[kMaxBeams];  // per thread: zeroing 64 spectra per call costs
    const int n = beams_at(o + d * t, medium, beams, kMaxBeams);
    beam_scatter_sum(o, d, t, pdf, medium, beams, n, out, deferred_t, inelastic);
}

bool Scene::beam_scatter_point(const Water& w, const Vec3& d, double T, Rng& rng, double* t_out,
                               double* pdf_out) const {
    // Single scattering of the beams along the water segment [0, T] from o along d, as seen
    // from o: int exp(-c t) sum_beams b p(psi) E dt, estimated with one distance drawn with
    // pdf proportional to exp(-k t), where k follows the integrand: attenuation back to o (c)
    // and the beams growing towards the surface (c_beam per metre of beam path, which changes
    // by -d_z / mu_w per metre along the segment). The bands' c differ (the red's water
    // absorption is 10-100 times the blue's): drawn at the bands' mean c alone, a band far
    // below it would get weights growing as exp((c_mean - c) t), an infinite variance where
    // c < c_mean / 2; so half the draws take the smallest c (a defensive mixture: every
    // band's weight stays bounded).
    if (!(w.c_path_mean > 0.0) || !(T > 0.0)) return false;
    const bool finite = T < kInf;
    auto rate = [&](double c) {
        double k = c * (1.0 - d.z / beam_mu_w);
        return !finite && k < 0.5 * c ? 0.5 * c : k;
    };
    auto norm = [&](double k) { return finite ? -std::expm1(-std::fabs(k) * T) : 1.0; };
    auto uniform = [&](double k) { return finite && std::fabs(k) * T < 1e-6; };
    auto sample = [&](double k, double u) {
        if (uniform(k)) return u * T;
        const double s_ = -std::log1p(-u * norm(k)) / std::fabs(k);  // from the start (k > 0) or from the end
        return k > 0 ? s_ : T - s_;
    };
    auto pdf = [&](double k, double t) {
        if (uniform(k)) return 1.0 / T;
        const double s_ = k > 0 ? t : T - t;
        return std::fabs(k) * std::exp(-std::fabs(k) * s_) / norm(k);
    };
    const double k1 = rate(w.c_path_mean);
    const bool mix = w.c_beam_min > 0.0 && w.c_beam_min < 0.999 * w.c_path_mean;
    if (!mix) {
        *t_out = sample(k1, rng.uniform());
        *pdf_out = pdf(k1, *t_out);
        return true;
    }
    const double k0 = rate(w.c_beam_min);
    const bool low = rng.uniform() < 0.5;
    *t_out = sample(low ? k0 : k1, rng.uniform());
    *pdf_out = 0.5 * (pdf(k0, *t_out) + pdf(k1, *t_out));
    return true;
}

void Scene::beam_scatter_sum(const Vec3& o, const Vec3& d, double t, double pdf, int medium,
                             const BeamSample* beams, int n, Spectrum* out, double* deferred_t,
                             Spectrum* inelastic) const {
    const Water& w = waters[medium];
    *out = Spectrum();
    if (inelastic) std::fill_n(inelastic, kInelasticKinds, Spectrum());
    if (n == 0) return;
    const Vec3 x = o + d * t;
    // The local scattering at x and the attenuation back to o (through the layers or voxels
    // crossed; gridded water: the caller's walk along the segment will tell).
    const Water::Point local = w.at(x);
    double att[kMaxBands];
    if (deferred_t) {
        *deferred_t = t;
        for (int kb = 0; kb < nbands; ++kb) att[kb] = 1.0;
    } else {
        w.transmittance(o, x, t, nbands, att);
    }
    const double cone_x = 1.0 - std::cos(cone_half_angle);
    const size_t nc = w.components.size();
    const bool spread_phase = beam_phase_spread();
    const bool shifts = inelastic && !w.inelastic.empty();
    const int layer = shifts ? int(local.base - w.layers.data()) : 0;
    for (int j = 0; j < n; ++j) {
        double xs = std::max(0.0, 1.0 + dot(beams[j].d, d));  // 1 - cos(psi)
        if (shifts)  // (inelastic light leaves the beam's band: no forward cone for it)
            for (const Inelastic& P : w.inelastic) {
                const double p = P.phase(1.0 - xs);
                const double* m = P.at(layer);
                Spectrum& into = inelastic[P.kind];
                for (int kb = 0; kb < nbands; ++kb) {
                    double r = 0.0;
                    for (int ki = P.from[kb]; ki < P.to[kb]; ++ki) r += m[size_t(kb) * nbands + ki] * beams[j].e.v[ki];
                    into.v[kb] += att[kb] * p * r / pdf;
                }
            }
        double pv[16];
        if (beams[j].spread && spread_phase) {  // (the cone is in the disk's mean)
            for (size_t ci = 0; ci < nc; ++ci) pv[ci] = beam_phase(w.components[ci].phase, xs);
        } else {
            if (xs < cone_x) continue;  // inside the cone the light stays in the beam
            for (size_t ci = 0; ci < nc; ++ci) pv[ci] = phases[w.components[ci].phase].eval(xs);
        }
        double bp[kMaxBands] = {};  // b p per band
        w.add_scattering(local, pv, nbands, bp);
        for (int kb = 0; kb < nbands; ++kb) out->v[kb] += att[kb] * bp[kb] * beams[j].e.v[kb] / pdf;
    }
}

namespace {

// The brightest beam (band 0) of a list, or null when there is none.
const BeamSample* brightest(const BeamSample* beams, int n) {
    double best = 0.0;
    const BeamSample* b = nullptr;
    for (int j = 0; j < n; ++j)
        if (beams[j].e.v[0] > best) { best = beams[j].e.v[0]; b = &beams[j]; }
    return b;
}

}  // namespace

bool Scene::strongest_beam(const Vec3& x, int medium, BeamSample* beam) const {
    // Only a ranking for the MIS direction (any deterministic choice is unbiased): no walks
    // through layers or voxels. A per-thread buffer: zeroing 64 spectra per call costs.
    thread_local BeamSample beams[kMaxBeams];
    const BeamSample* b = brightest(beams, beams_at(x, medium, beams, kMaxBeams, false));
    if (b) *beam = *b;
    return b != nullptr;
}

double Scene::beam_direction_pdf(const Water& w, const Vec3& beam_d, const Vec3& omega) const {
    // Looking along omega at light of a beam along beam_d: scattering angle cos = -beam_d . omega.
    double x = std::max(0.0, 1.0 + dot(beam_d, omega));
    double p = 0.0;
    for (const auto& c : w.components) p += c.weight * phases[c.phase].eval(x);
    return w.mis_wsum > 0.0 ? p / w.mis_wsum : 0.0;
}

Vec3 Scene::sample_beam_direction(const Water& w, const Vec3& beam_d, Rng& rng) const {
    double u = rng.uniform() * w.mis_bsum;
    size_t pick = 0;
    for (; pick + 1 < w.components.size(); ++pick) {
        double b = w.components[pick].weight;
        if (u < b) break;
        u -= b;
    }
    double u1 = rng.uniform(), u2 = rng.uniform();
    return phases[w.components[pick].phase].sample_direction(-beam_d, u1, u2);
}

double* Scene::queue_beam_term(BeamTerms& b, Components* out, const Vec3& o, const Vec3& d, double t, double pdf,
                               int medium, double den) const {
    if (b.n == BeamTerms::kMax) settle_beam_terms(b, out);
    BeamTerms::Term& e = b.terms[b.n++];
    e.o[0] = o.x; e.o[1] = o.y; e.o[2] = o.z;
    e.d[0] = d.x; e.d[1] = d.y; e.d[2] = d.z;
    e.t = t;
    e.pdf = pdf;
    e.den = den;
    e.medium = medium;
    return e.weight;
}

void Scene::settle_beam_terms(BeamTerms& b, Components* out) const {
    // All the points' grid cells fetched ahead; then all their candidates found (the prisms
    // that pass fetched ahead); then each term's beams evaluated and added in order. (Fetching
    // the candidates' keys ahead too, a stage of its own, cost more than it saved below wave
    // patches, and nothing in the stepped pool.)
    auto vec = [](const double* v) { return Vec3(v[0], v[1], v[2]); };
    auto point = [&](const BeamTerms::Term& e) { return vec(e.o) + vec(e.d) * e.t; };
    for (int i = 0; i < b.n; ++i) prefetch_beams(point(b.terms[i]), b.terms[i].medium);
    thread_local std::vector<BeamCandidate> found;  // per thread: kept, so rarely grown
    found.clear();
    size_t first[BeamTerms::kMax + 1];
    for (int i = 0; i < b.n; ++i) {
        first[i] = found.size();
        find_candidates(prisms, prism_keys_, *water_grid_, point(b.terms[i]), b.terms[i].medium, &found);
    }
    first[b.n] = found.size();
    thread_local BeamSample beams_tls[kMaxBeams];  // (as beam_scatter_along's)
    BeamSample* const beams = beams_tls;  // (the thread-local address looked up once)
    for (int i = 0; i < b.n; ++i) {
        const BeamTerms::Term& e = b.terms[i];
        const Vec3 x = point(e);
        int n = flat_beams_at(x, e.medium, beams, kMaxBeams, true);
        n = eval_candidates(prisms, found.data() + first[i], first[i + 1] - first[i], x, beams, n, kMaxBeams, true);
        Spectrum I, R[kInelasticKinds];
        beam_scatter_sum(vec(e.o), vec(e.d), e.t, e.pdf, e.medium, beams, n, &I, nullptr, R);
        for (int k = 0; k < nbands; ++k) out->beam_volume.v[k] += e.weight[k] * I.v[k] / e.den;
        for (int c = 0; c < kInelasticKinds; ++c)
            for (int k = 0; k < nbands; ++k) out->inelastic[c].v[k] += e.weight[k] * R[c].v[k] / e.den;
    }
    b.n = 0;
}

Components Scene::trace(Vec3 o, Vec3 d, int medium, bool sun_covered, bool beam_covered, Rng& rng,
                        Counters& c, double first_beam_weight, bool camera, bool reflect_covered,
                        bool branch_inelastic) const {
    BeamTerms terms;
    Components out = trace_path(o, d, medium, sun_covered, beam_covered, rng, c, first_beam_weight, camera,
                                reflect_covered, terms, branch_inelastic);
    if (terms.inelastic) fold_inelastic(terms, &out);
    else settle_beam_terms(terms, &out);
    return out;
}

void Scene::fold_inelastic(BeamTerms& t, Components* out) const {
    settle_beam_terms(t, out);
    const int nb = nbands;
    const Components& b = t.before;
    double found[kMaxBands];
    for (int i = 0; i < nb; ++i) found[i] = out->total(i) - b.total(i);
    Spectrum into = b.inelastic[t.kind];
    for (int k = 0; k < nb; ++k)
        for (int i = 0; i < nb; ++i) into.v[k] += t.share[k * nb + i] * found[i];
    *out = b;
    out->inelastic[t.kind] = into;
    t.before = *out;
}

void Scene::inelastic_branch(const Vec3& o, const Vec3& d, double T, int medium, const double* weight, Rng& rng,
                             Counters& c, bool camera, Components* out) const {
    const Water& w = waters[medium];
    const int nb = nbands;
    double t, pdf;
    if (!beam_scatter_point(w, d, T, rng, &t, &pdf)) return;
    const Vec3 x = o + d * t;
    double att[kMaxBands];
    w.transmittance(o, x, t, nb, att);
    const int layer = w.layer_index(x.z);
    double g[kInelasticKinds] = {}, total = 0.0;
    for (size_t pi = 0; pi < w.inelastic.size(); ++pi) {
        const Spectrum& in = w.inelastic[pi].in_at(layer);
        for (int k = 0; k < nb; ++k) g[pi] += weight[k] * att[k] * in.v[k];
        total += g[pi];
    }
    if (!(total > 0.0)) return;
    double u = rng.uniform() * total;
    size_t pick = 0;
    while (pick + 1 < w.inelastic.size() && u >= g[pick]) u -= g[pick++];
    const Inelastic& P = w.inelastic[pick];
    if (!(g[pick] > 0.0)) return;
    // The branch: the light arriving at x along the direction drawn (its phase function's
    // weight is 1), with the beams' direct light at x left to the segment's beam term.
    const Components L = trace(x, P.sample_direction(d, rng), medium, false, hybrid, rng, c, 1.0, camera, false, false);
    const double* m = P.at(layer);
    const double scale = total / (g[pick] * pdf);
    for (int k = 0; k < nb; ++k) {
        double r = 0.0;
        for (int i = P.from[k]; i < P.to[k]; ++i) r += m[size_t(k) * nb + i] * L.total(i);
        out->inelastic[P.kind].v[k] += weight[k] * att[k] * r * scale;
    }
}

Components Scene::trace_path(Vec3 o, Vec3 d, int medium, bool sun_covered, bool beam_covered, Rng& rng,
                             Counters& c, double first_beam_weight, bool camera, bool reflect_covered,
                             BeamTerms& terms, bool branch_inelastic) const {
    const int nb = nbands;
    Components out;
    Spectrum beta = Spectrum::constant(1.0);
    int depth = 0;
    c.paths++;
    thread_local WaterLayer grid_local_tls;  // a grid's coefficients at the current collision (reused)
    MediumWalk walk(nb, &grid_local_tls, out.inelastic);  // (the thread-local address looked up once per path)
    const double cone_x = 1.0 - std::cos(cone_half_angle);
    // The reflected beams in the air count the sun that reaches a point in the air by one
    // reflection on the water: from a vertex where they were looked up (1), a path that
    // reflects once on the water from the air side (2) and then escapes into the sun has
    // found light they already counted.
    int reflect_state = reflect_covered ? 1 : 0;
    double bv_weight = first_beam_weight;  // MIS weight of this segment's beam scattering
    double guided_weight = 1.0;  // product of the guided continuations' weights (kGuidedWeightScale)

    for (;;) {
        Hit h;
        double t_hit;
        // Whether this vertex sent the path into the beam's forward peak (its direction more
        // likely under the beam-direction pdf than under the vertex's own, or denser than
        // kBeamPeakPdf under it): such a path carries the guide's small weight (or got there
        // from one that did: a forward scattering keeps it in the peak), its next beam terms
        // multiply two forward peaks, and Russian roulette, which would return the survivors
        // to a weight of about 1 at the odds of that small weight, would make exactly the rare,
        // huge samples the guide removes (the main example's fireflies: a floor's guided
        // continuation, then roulette at the next scattering, still in the peak, boosting it
        // 42 times); it is skipped there (a choice that depends only on the path so far, so
        // the estimate stays unbiased).
        bool into_peak = false;
        if (medium >= 0) {
            const Water& w = waters[medium];
            bool scattered = false;
            double t_cur = 0.0;
            bool clipped = false;
            walk.begin(w, o, d);
            // A clipped ray's rest, from t on (what lies beyond the bound was unknown).
            auto intersect_rest = [&](double t) {
                h = intersect(o + d * t, d, kInf, ocean_side(medium));
                c.segments++;
                clipped = false;
                if (h.valid) h.t += t;
                t_hit = h.valid ? h.t : kInf;
            };
            // The inelastic light along the segment, where the path's bands can gain any: until
            // the path has made a branch (inelastic_branch), each such segment makes one with
            // probability inelastic_split (its weight over that) or leaves it out (Russian
            // roulette: unbiased); after it, the path's own inelastic collisions count it. (The
            // collisions alone meet the source at its rate, 1e-5 to 1e-3 per metre, each with
            // a weight of order 1: rare, huge samples. A branch draws a point on every segment
            // it serves, the weight the source's share: at most one per path keeps the cost
            // at most twice.)
            double gain = 0.0;  // (> 0: some process feeds a band of this throughput)
            if (w.inelastic_rate > 0.0)
                for (const Inelastic& P : w.inelastic)
                    for (int k = 0; k < nb; ++k) gain += beta.v[k] * P.in_max.v[k];
            bool branch = false, roulette = false;
            if (branch_inelastic && gain > 0.0) {
                roulette = true;
                branch = rng.uniform() < w.inelastic_split;
                if (branch) branch_inelastic = false;
            }
            // Path tracing casts the ray only up to the first tentative collision (the
            // medium's bound for it); the beam terms and a branch need the whole length.
            const bool short_ray = !hybrid && walk.can_clip() && !branch;
            t_hit = kInf;
            const double t_cast = walk.before_cast(rng, short_ray);
            h = intersect(o, d, t_cast, ocean_side(medium));
            clipped = short_ray && !h.valid;  // nothing before t_cast; what lies beyond is unknown
            c.segments++;
            t_hit = h.valid ? h.t : kInf;
            if (hybrid && has_beams()) {
                if (!walk.beam_point()) {  // (no point drawn: the term is 0)
                    double tb, pdf;
                    if (beam_scatter_point(w, d, t_hit, rng, &tb, &pdf)) {
                        double* weight = queue_beam_term(terms, &out, o, d, tb, pdf, medium, 1.0);
                        for (int kb = 0; kb < nb; ++kb) weight[kb] = bv_weight * beta.v[kb] * walk.absorbed(w, kb);
                    }
                } else {  // gridded water: the walk attenuates it, added when the walk passes it
                    settle_beam_terms(terms, &out);
                    Spectrum I, R[kInelasticKinds], contribution;
                    beam_scatter_along(o, d, t_hit, medium, rng, &I, walk.beam_point(), R);
                    for (int kb = 0; kb < nb; ++kb) {
                        const double f = bv_weight * beta.v[kb] * walk.absorbed(w, kb);
                        contribution.v[kb] = f * I.v[kb];
                        for (int c = 0; c < kInelasticKinds; ++c) R[c].v[kb] *= f;
                    }
                    walk.add_beam(contribution, R, &out.beam_volume);
                }
            }
            bv_weight = 1.0;
            if (branch) {
                double weight[kMaxBands];
                for (int k = 0; k < nb; ++k) weight[k] = beta.v[k] * walk.absorbed(w, k) / w.inelastic_split;
                inelastic_branch(o, d, t_hit, medium, weight, rng, c, camera, &out);
            }
            double dt = walk.first_flight(rng, t_hit, clipped, intersect_rest);
            const WaterLayer* L = nullptr;  // the coefficients at the tentative collision (walk.collide)
            // Inelastic scattering (Raman, fluorescence): tentative collisions of its own at the
            // sum of its processes' rates, independent of the walk's (exponential flights are
            // memoryless, so neither disturbs the other), each collision a process drawn by its
            // rate. A source sum_i M[k][i] L_i is a gain of band k, not a loss (that is in the
            // absorption): at such a collision the path scatters with probability p (about
            // q / (1 + q), q the throughput-weighted sum_i M[k][i] / rate there) or goes on with
            // the whole null weight 1 / (1 - p): unbiased whatever p.
            const double shift_rate = w.inelastic_rate;
            auto shift_flight = [&]() { return shift_rate > 0.0 ? -std::log(1.0 - rng.uniform()) / shift_rate : kInf; };
            double t_shift = roulette ? kInf : shift_flight();
            const Inelastic* shift = nullptr;  // the process of the collision chosen (null: none)
            int shift_layer = 0;
            double shift_p = 0.0;
            if (!(gain > 0.0)) t_shift = kInf;  // (no process can give this throughput any light)
            for (;;) {
                const double t_next = t_cur + dt;
                if (t_shift < t_next && t_shift < t_hit) {
                    const double z = o.z + d.z * t_shift;
                    const int layer = w.layer_index(z);
                    double u = w.inelastic.size() > 1 ? rng.uniform() * shift_rate : 0.0;
                    const Inelastic* P = &w.inelastic[0];
                    for (size_t pi = 0; pi + 1 < w.inelastic.size() && u >= P->rate; ++pi, ++P) u -= P->rate;
                    double num = 0.0, den = 0.0;
                    const Spectrum& in = P->in_at(layer);
                    for (int k = 0; k < nb; ++k) {
                        num += beta.v[k] * in.v[k];
                        den += beta.v[k];
                    }
                    // (p at least kShiftMin where q > 0: a throughput whose gaining bands have
                    // become tiny would otherwise go on for ever down an endless segment)
                    const double q = den > 0.0 ? num / (den * P->rate) : 0.0;
                    const double p = q > 0.0 ? std::max(kShiftMin, q / (1.0 + q)) : 0.0;
                    if (q > 0.0 && rng.uniform() < p) {
                        shift = P;
                        shift_layer = layer;
                        shift_p = p;
                        break;
                    }
                    for (int k = 0; k < nb; ++k) beta.v[k] /= 1.0 - p;
                    // (Where this layer gives no process any gain and the ray never leaves it,
                    // no later collision can: none on this segment.)
                    const int last = int(w.layers.size()) - 1;
                    if ((layer == last && d.z <= 0.0) || (layer == 0 && d.z >= 0.0)) {
                        double here = 0.0;
                        for (const Inelastic& Q : w.inelastic)
                            for (int k = 0; k < nb; ++k) here += beta.v[k] * Q.in_at(layer).v[k];
                        if (!(here > 0.0)) {
                            t_shift = kInf;
                            continue;
                        }
                    }
                    t_shift += shift_flight();
                    continue;
                }
                if (!(t_next < t_hit)) break;
                t_cur = t_next;
                double maj;
                L = &walk.collide(t_cur, dt, &maj);
                // Any probability fixed before the decision keeps the estimate unbiased;
                // weighting by the (not yet absorbed) throughput keeps band weights tame.
                double num = 0.0, den = 0.0;
                for (int k = 0; k < nb; ++k) {
                    num += beta.v[k] * (L->b_path.v[k] / maj);
                    den += beta.v[k];
                }
                if (!(den > 0.0)) {
                    walk.abandon(&out.beam_volume);
                    return out;
                }
                double p_real = num / den;
                if (p_real >= 1.0 || rng.uniform() < p_real) {
                    for (int k = 0; k < nb; ++k) beta.v[k] *= (L->b_path.v[k] / maj) / p_real;
                    scattered = true;
                    break;
                }
                for (int k = 0; k < nb; ++k) beta.v[k] *= (1.0 - L->b_path.v[k] / maj) / (1.0 - p_real);
                if (clipped) intersect_rest(t_cur);  // a null collision: now find the surface beyond it
                dt = walk.next_flight(rng, t_cur, t_hit, clipped, intersect_rest);
            }
            if (shift) {
                // An inelastic collision: the path goes on as the light that excites its bands,
                // beta_i = sum_k beta_k M[k][i] / (rate p), in a direction drawn from the
                // process's phase function; everything it finds from here on is inelastic light.
                walk.leave_at(t_shift, t_cur, &out.beam_volume);
                walk.flush(w, &beta);
                if (terms.inelastic) {
                    fold_inelastic(terms, &out);
                } else {
                    settle_beam_terms(terms, &out);
                    terms.inelastic = true;
                    terms.kind = shift->kind;
                    terms.before = out;
                    for (int k = 0; k < nb * nb; ++k) terms.share[k] = k % (nb + 1) == 0 ? 1.0 : 0.0;
                }
                // Band i now carries sum_k beta_k M[k][i] / (rate p); of what it finds, band k
                // of the path so far gets the share beta_k M[k][i] / sum_k' (...).
                const double* m = shift->at(shift_layer);
                Spectrum excite;
                double a[kMaxBands * kMaxBands] = {};
                for (int k = 0; k < nb; ++k)
                    for (int i = shift->from[k]; i < shift->to[k]; ++i) {
                        a[k * nb + i] = beta.v[k] * m[size_t(k) * nb + i];
                        excite.v[i] += a[k * nb + i];
                    }
                double share[kMaxBands * kMaxBands] = {};
                for (int k = 0; k < nb; ++k)
                    for (int j = 0; j < nb; ++j) {
                        const double s = terms.share[k * nb + j];
                        if (s == 0.0) continue;
                        for (int i = shift->from[j]; i < shift->to[j]; ++i)
                            if (excite.v[i] > 0.0) share[k * nb + i] += s * a[j * nb + i] / excite.v[i];
                    }
                std::copy_n(share, nb * nb, terms.share);
                const double scale = 1.0 / (shift->rate * shift_p);
                for (int i = 0; i < nb; ++i) excite.v[i] *= scale;
                beta = excite;
                if (++depth > max_depth) return out;
                o = o + d * t_shift;
                d = shift->sample_direction(d, rng);
                sun_covered = false;
                beam_covered = hybrid;  // the beams' inelastic light at this point is in the last beam term
                if (depth >= rr_depth) {
                    double q = std::min(0.95, max_component(beta, nb));
                    if (!(rng.uniform() < q)) return out;
                    for (int k = 0; k < nb; ++k) beta.v[k] /= q;
                }
                continue;
            }
            if (scattered) {
                L = &walk.scatter_at(t_cur, &out.beam_volume);
                if (++depth > max_depth) return out;
                o = o + d * t_cur;
                // Choose a mixture component by its throughput-weighted share of scattering,
                // sample it (outside the forward cone), and weight each band by its own
                // phase function over the mixture pdf.
                size_t nc = w.components.size();
                double q[16];
                double qsum = 1.0;
                if (nc == 1) {
                    q[0] = 1.0;
                } else {
                    double wsum = 0.0;
                    qsum = 0.0;
                    for (int k = 0; k < nb; ++k) wsum += beta.v[k];
                    for (size_t ci = 0; ci < nc; ++ci) {
                        double sacc = 0.0;
                        for (int k = 0; k < nb; ++k)
                            if (L->b_path.v[k] > 0) sacc += beta.v[k] * L->comp_b_path[ci].v[k] / L->b_path.v[k];
                        q[ci] = wsum > 0 ? sacc / wsum : 0.0;
                        qsum += q[ci];
                    }
                    if (!(qsum > 0.0)) return out;
                }
                // Truncated (outside the cone), renormalised component phase functions at a
                // direction, the sampling pdf (mixture by q) and each band's own mixture.
                double pv[16];
                auto eval_components = [&](const Vec3& wdir) {
                    double x = std::max(0.0, 1.0 - dot(d, wdir));
                    for (size_t ci = 0; ci < nc; ++ci) {
                        const ScatterComponent& cc = w.components[ci];
                        pv[ci] = (x >= cone_x && cc.f < 1.0) ? phases[cc.phase].eval(x) / (1.0 - cc.f) : 0.0;
                    }
                };
                auto pdf_a = [&]() {
                    double pdf = 0.0;
                    for (size_t ci = 0; ci < nc; ++ci) pdf += (q[ci] / qsum) * pv[ci];
                    return pdf;
                };
                auto band_phase = [&](int k) {
                    if (!(L->b_path.v[k] > 0)) return 0.0;
                    double pk = 0.0;
                    for (size_t ci = 0; ci < nc; ++ci) pk += L->comp_b_path[ci].v[k] * pv[ci];
                    return pk / L->b_path.v[k];
                };
                double u = rng.uniform() * qsum;
                size_t pick = 0;
                while (pick + 1 < nc && u >= q[pick]) { u -= q[pick]; ++pick; }
                const ScatterComponent& sc = w.components[pick];
                double u1 = sc.f + rng.uniform() * (1.0 - sc.f), u2 = rng.uniform();
                Vec3 nd = phases[sc.phase].sample_direction(d, u1, u2);
                // The strongest beam here (its direction bd) and the share qb of the
                // beam-direction samples (beam_mis_share: 1 unless the water is clear along the
                // beam). (Path tracing skips this: no spectra to copy or clear per collision.)
                bool beams_here = false;
                Vec3 bd;
                double qb = 0.0;
                double beta_pre[kMaxBands];
                if (hybrid && has_beams()) {
                    BeamSample bs;
                    beams_here = strongest_beam(o, medium, &bs);
                    if (beams_here) {
                        bd = bs.d;
                        qb = camera ? beam_mis_share(w, bs) : 1.0;
                        std::copy_n(beta.v.begin(), nb, beta_pre);
                    }
                }
                // Beam-guided continuation (exact mode, forward cone 0): a fraction
                // kBeamGuide qb of the paths here go on in a direction drawn from the phase
                // function around the beam's reverse instead, weighted by the mixture's pdf (at
                // most 1 / (1 - kBeamGuide) times the phase function's weight). A path then
                // arrives near the refracted sun's reverse as often as its forward peak sends
                // light there, so the next vertex's beam term, which multiplies two forward
                // peaks, no longer makes rare huge samples (the exact mode's heavy tails).
                const bool guide = beams_here && cone_x == 0.0;
                const double gp = kBeamGuide * qb * std::min(1.0, kGuidedWeightScale / guided_weight);
                if (guide && rng.uniform() < gp) nd = sample_beam_direction(w, bd, rng);
                double pa = 0.0;
                if (nc > 1 || beams_here) {
                    eval_components(nd);
                    pa = pdf_a();
                }
                auto mixture = [&](double pa_v, double pb_v) {  // the continuation's pdf
                    return guide ? (1.0 - gp) * pa_v + gp * pb_v : pa_v;
                };
                const double pmix = beams_here ? mixture(pa, beam_direction_pdf(w, bd, nd)) : pa;
                if (nc > 1 || guide)
                    for (int k = 0; k < nb; ++k) beta.v[k] *= pmix > 0 ? band_phase(k) / pmix : 0.0;
                if (guide && pmix > 0.0) guided_weight *= pa / pmix;
                if (beams_here) {
                    // Beam-scattering MIS: the next segment's beam term (directions from the
                    // continuation's pdf here) is weighted against a second direction drawn from
                    // the phase function around the beam (the forward peak at the next point),
                    // taken with probability qb (balance heuristic with q samples expected).
                    double pb = beam_direction_pdf(w, bd, nd);
                    bv_weight = pmix / (pmix + qb * pb);
                    into_peak = guide && (pb > pa || pb > kBeamPeakPdf);
                    Vec3 wb;
                    double pa_b = 0.0, pb_b = 0.0;
                    if (qb >= 1.0 || rng.uniform() < qb) {
                        wb = sample_beam_direction(w, bd, rng);
                        eval_components(wb);
                        pa_b = pdf_a();
                        pb_b = beam_direction_pdf(w, bd, wb);
                    }
                    if (pa_b > 0.0) {
                        Hit hb = intersect(o, wb, kInf, ocean_side(medium));
                        c.segments++;
                        double tb, pdf;
                        if (beam_scatter_point(w, wb, hb.valid ? hb.t : kInf, rng, &tb, &pdf)) {
                            double* weight = queue_beam_term(terms, &out, o, wb, tb, pdf, medium,
                                                             mixture(pa_b, pb_b) + qb * pb_b);
                            for (int k = 0; k < nb; ++k) weight[k] = beta_pre[k] * band_phase(k) * walk.absorbed(w, k);
                        }
                    }
                }
                d = nd;
                sun_covered = false;   // no straight connection to the sun from inside water
                beam_covered = hybrid; // the beams already count the sun arriving here straight
                if (depth >= rr_depth && !into_peak) {
                    double q = std::min(0.95, max_component(beta, nb) * walk.absorbed_bound(w));
                    if (!(rng.uniform() < q)) return out;
                    for (int k = 0; k < nb; ++k) beta.v[k] /= q;
                }
                continue;
            }
            walk.end_at(h.valid ? t_hit : kInf, t_cur, &out.beam_volume);
            if (!h.valid) return out;  // lost in infinitely deep water
        } else {
            h = intersect(o, d, kInf, Side::kAbove);  // (in the air)
            c.segments++;
            t_hit = h.valid ? h.t : kInf;
        }

        if (!h.valid) {  // escaped to the environment
            Spectrum sky = sky_radiance(d);
            bool sun = !sun_covered && !beam_covered && reflect_state != 2 && in_sun(d);
            for (int k = 0; k < nb; ++k)
                out.path.v[k] += beta.v[k] * (sky.v[k] + (sun ? sun_radiance.v[k] : 0.0));
            return out;
        }

        Vec3 x = o + d * t_hit;
        double off = offset_for(x);
        if (++depth > max_depth) return out;

        if (h.kind == SurfaceKind::kOpaque) {
            Vec3 n = dot(h.n, d) > 0.0 ? -h.n : h.n;  // face the arriving ray
            const Material m = surface_at(h);  // (a texture's reflectance at the hit)
            if (m.emits)
                for (int k = 0; k < nb; ++k) out.path.v[k] += beta.v[k] * m.emission.v[k];
            Vec3 xo = x + n * off;
            bool nee = has_sun && medium < 0;
            if (nee) {
                double u1 = rng.uniform(), u2 = rng.uniform();
                Vec3 ws = sample_sun(u1, u2);
                double cs = dot(n, ws);
                if (cs > 0.0) {
                    c.shadow_rays++;
                    if (!occluded(xo, ws, Side::kAbove)) {
                        double f = cs * kInvPi / sun_pdf();
                        for (int k = 0; k < nb; ++k)
                            out.path.v[k] += beta.v[k] * m.reflectance.v[k] * sun_radiance.v[k] * f;
                    }
                }
            }
            // The beams covering the point: their light on the surface, and the brightest one
            // guides the continuation below (the same lookup serves both).
            const BeamSample* best = nullptr;
            thread_local BeamSample beams[kMaxBeams];  // per thread: not zeroed per path (10 kB)
            if (hybrid && medium >= 0) {
                // The refracted sun on an underwater surface: every beam covering the point.
                walk.flush(waters[medium], &beta);
                int nbm = beams_at(xo, medium, beams, kMaxBeams);
                // (Beam-direction samples, below, only where the water scatters: else they
                // have no density, and a guided continuation drawn from them would be counted
                // as if it had, adding light that is not there.)
                if (has_beams() && waters[medium].scatters()) best = brightest(beams, nbm);
                for (int j = 0; j < nbm; ++j) {
                    double cs = -dot(beams[j].d, n);
                    if (cs <= 0.0) continue;
                    for (int k = 0; k < nb; ++k)
                        out.beam_surface.v[k] += beta.v[k] * m.reflectance.v[k] * kInvPi * cs * beams[j].e.v[k];
                }
            }
            // The sun reflected into the air by the water's smooth surfaces, on a surface in the
            // air (the reflected beams' light; path tracing would find it only by escaping
            // into the sun's disk after a reflection on the water: rare, bright samples).
            reflect_state = 0;
            if (hybrid && medium < 0 && has_air_beams()) {
                thread_local BeamSample air[kMaxBeams];
                const int na = beams_at(xo, -1, air, kMaxBeams);
                for (int j = 0; j < na; ++j) {
                    double cs = -dot(air[j].d, n);
                    if (cs <= 0.0) continue;
                    for (int k = 0; k < nb; ++k)
                        out.beam_surface.v[k] += beta.v[k] * m.reflectance.v[k] * kInvPi * cs * air[j].e.v[k];
                }
                reflect_state = 1;
            }
            sun_covered = nee;
            beam_covered = hybrid && medium >= 0;
            double u1 = rng.uniform(), u2 = rng.uniform();
            Vec3 nd = cosine_hemisphere(n, u1, u2);
            double scale = 1.0;  // the continuation's cosine lobe over its pdf (guided: <= 1/(1 - kBeamGuide))
            if (best) {
                // Beam-scattering MIS as at scattering vertices, with the cosine lobe here, and
                // in the exact mode the same beam-guided continuation (light reflected off the
                // floor straight back towards the refracted sun then scatters in both peaks),
                // both as often as the water along the beam makes them worth it.
                const Water& w = waters[medium];
                const Vec3 bd = best->d;
                const double q = camera ? beam_mis_share(w, *best) : 1.0;
                const bool guide = cone_half_angle == 0.0;
                const double gp = kBeamGuide * q * std::min(1.0, kGuidedWeightScale / guided_weight);
                if (guide && rng.uniform() < gp) nd = sample_beam_direction(w, bd, rng);
                auto mixture = [&](double pa_v, double pb_v) {
                    return guide ? (1.0 - gp) * pa_v + gp * pb_v : pa_v;
                };
                double pa = std::max(0.0, dot(n, nd)) * kInvPi, pb = beam_direction_pdf(w, bd, nd);
                const double pm = mixture(pa, pb);
                if (guide) scale = pm > 0.0 ? pa / pm : 0.0;
                guided_weight *= scale;
                bv_weight = pm / (pm + q * pb);
                into_peak = guide && (pb > pa || pb > kBeamPeakPdf);
                Vec3 wb;
                double cb = 0.0;
                if (q >= 1.0 || rng.uniform() < q) {
                    wb = sample_beam_direction(w, bd, rng);
                    cb = dot(n, wb);
                }
                if (cb > 0.0) {
                    double pa_b = cb * kInvPi, pb_b = beam_direction_pdf(w, bd, wb);
                    Hit hb = intersect(xo, wb, kInf, ocean_side(medium));
                    c.segments++;
                    double tb, pdf;
                    if (beam_scatter_point(w, wb, hb.valid ? hb.t : kInf, rng, &tb, &pdf)) {
                        double* weight = queue_beam_term(terms, &out, xo, wb, tb, pdf, medium,
                                                         mixture(pa_b, pb_b) + q * pb_b);
                        for (int k = 0; k < nb; ++k) weight[k] = beta.v[k] * m.reflectance.v[k] * cb * kInvPi;
                    }
                }
            }
            if (!(dot(nd, n) > 0.0)) return out;  // a guided direction into the surface
            d = nd;
            for (int k = 0; k < nb; ++k) beta.v[k] *= m.reflectance.v[k] * scale;
            o = xo;
        } else if (h.id == -3 && ocean_rough) {
            // The rough ocean surface: a microfacet BSDF around the geometric normal (which
            // points into the air). Next-event estimation of the sun here gives glint from above
            // and (path tracing) the sun seen through the surface from below; paths sampled on
            // into the sun are then not counted again (sun_covered).
            // The BSDF's frame follows the shading normal (a wave model's exact normals, as the
            // beams refract with them); directions must also lie on the right side of the
            // geometric facet, else the sample is lost (rare, at grazing angles).
            const Water& w = waters[h.index];
            if (medium >= 0) walk.flush(w, &beta);
            const Frame fr(h.ns);
            const Vec3 wi = fr.to_local(-d);
            if ((wi.z > 0.0) != (medium < 0)) return out;
            // In the hybrid integrator the beams carry the sun into the water: from below, the
            // sun is estimated here only on paths the beams do not already cover (a camera's).
            if (has_sun && (!hybrid || medium < 0 || !beam_covered)) {
                double u1 = rng.uniform(), u2 = rng.uniform();
                Vec3 ws = sample_sun(u1, u2);
                Vec3 wsl = fr.to_local(ws);
                if (wsl.z > 0.0 && dot(ws, h.n) > 0.0) {
                    double f = ocean_bsdf.eval(wi, wsl, RoughInterface::kRadiance);
                    if (f > 0.0) {
                        c.shadow_rays++;
                        if (!occluded(x + h.n * off, ws, Side::kAbove)) {
                            double g = f * wsl.z / sun_pdf();
                            for (int k = 0; k < nb; ++k) out.path.v[k] += beta.v[k] * sun_radiance.v[k] * g;
                        }
                    }
                }
            }
            double u1 = rng.uniform(), u2 = rng.uniform(), u3 = rng.uniform();
            RoughSample rs = ocean_bsdf.sample(wi, u1, u2, u3, RoughInterface::kRadiance);
            if (!rs.valid || !(rs.weight > 0.0)) return out;
            for (int k = 0; k < nb; ++k) beta.v[k] *= rs.weight;
            bool to_air = rs.wo.z > 0.0;
            d = fr.to_world(rs.wo);
            if ((dot(d, h.n) > 0.0) != to_air) return out;
            o = x + h.n * (to_air ? off : -off);
            medium = to_air ? -1 : h.index;
            sun_covered = has_sun;  // by the estimate above, or by the beams (hybrid, from below)
            beam_covered = false;
            reflect_state = 0;
        } else {
            // Water boundary with outward normal h.n. The ocean patch and water meshes reflect
            // and refract about their smooth shading normals, as their beams do (else paths and
            // beams would see two different surfaces: facets and the smooth one), where both
            // outcomes then leave on their own side of the facet; a flat sea, and where they
            // would not, about h.n.
            const Water& w = waters[h.index];
            bool entering = dot(d, h.n) < 0.0;
            double n1 = entering ? 1.0 : w.ior, n2 = entering ? w.ior : 1.0;
            const Vec3 ng = entering ? h.n : -h.n;  // the facet's, on the arriving side
            Vec3 nf = ng;
            Vec3 dtr;
            if (h.id == -3 ? !ocean_flat : h.id >= 0) {
                const Vec3 ns = entering ? h.ns : -h.ns;
                Vec3 t;
                const bool tir = !refract(d, ns, n1, n2, &t);
                if (dot(d, ns) < 0.0 && dot(reflect(d, ns), ng) > 0.0 && (tir || dot(t, ng) < 0.0)) nf = ns;
            }
            double cos_i = -dot(d, nf);
            double F = fresnel_unpolarized(cos_i, n1, n2);
            if (rng.uniform() < F || !refract(d, nf, n1, n2, &dtr)) {
                d = normalize(reflect(d, nf));
                o = x + ng * off;
                beam_covered = false;  // a reflected path is not a beam's straight line
                reflect_state = reflect_state == 1 && entering ? 2 : 0;
            } else {
                reflect_state = 0;
                if (!entering) walk.flush(w, &beta);  // leaving the water: beta must carry its absorption
                double r = n1 / n2;
                for (int k = 0; k < nb; ++k) beta.v[k] *= r * r;  // radiance n^2 law
                d = dtr;
                o = x - ng * off;
                medium = entering ? h.index : -1;
                if (entering) beam_covered = false;
            }
            sun_covered = false;  // a specular event: NEE could not have seen this path
        }
        if (depth >= rr_depth && !into_peak) {
            double bound = medium >= 0 ? walk.absorbed_bound(waters[medium]) : 1.0;
            double q = std::min(0.95, max_component(beta, nb) * bound);
            if (!(q > 0.0) || !(rng.uniform() < q)) return out;
            for (int k = 0; k < nb; ++k) beta.v[k] /= q;
        }
    }
}

namespace {

// The ray through image point (x, y) in pixels from the top left corner: normalised image
// coordinates in [-1, 1] horizontally, row 0 at the top. A lens shift moves the image window
// by whole image widths (2 in these units).
inline void camera_ray(const Camera& cam, double x, double y, Vec3* o, Vec3* d) {
    double aspect = double(cam.height) / double(cam.width);
    double sx = 2.0 * (x / cam.width) - 1.0 + 2.0 * cam.shift_x;
    double sy = (1.0 - 2.0 * (y / cam.height)) * aspect + 2.0 * cam.shift_y;
    if (cam.orthographic) {
        double hw = 0.5 * cam.ortho_width;
        *o = cam.position + cam.right * (sx * hw) + cam.up * (sy * hw) + cam.forward * cam.clip_start;
        *d = cam.forward;
    } else {
        *d = normalize(cam.forward + cam.right * (sx * cam.tan_half_fov) + cam.up * (sy * cam.tan_half_fov));
        *o = cam.position + *d * (cam.clip_start / dot(*d, cam.forward));
    }
}

// A sample's total in band k: the sum of its components 1.. (component 0 is the total).
inline double total_of(const Spectrum* comp, int k) {
    double tot = 0.0;
    for (int ci = 1; ci < kNumComponents; ++ci) tot += comp[ci].v[k];
    return tot;
}

// Adds one sample's components to the running sums: component 0 is their total.
inline void accumulate(const Spectrum* comp, int nb, double* s, double* s2) {
    for (int k = 0; k < nb; ++k) {
        double tot = total_of(comp, k);
        s[k] += tot;
        s2[k] += tot * tot;
    }
    for (int ci = 1; ci < kNumComponents; ++ci)
        for (int k = 0; k < nb; ++k) {
            double v = comp[ci].v[k];
            s[ci * nb + k] += v;
            s2[ci * nb + k] += v * v;
        }
}

}  // namespace

void Scene::render_camera(int ci, uint64_t start, uint64_t count, int threads,
                          double* sum, double* sumsq, Counters* total, const uint8_t* active,
                          int row0, int row1) const {
    const Camera& cam = cameras.at(ci);
    if (row1 < 0 || row1 > cam.height) row1 = cam.height;
    row0 = std::clamp(row0, 0, row1);
    const int nb = nbands;
    const size_t stride = size_t(kNumComponents) * nb;
    int nthreads = threads <= 0 ? int(std::max(1u, std::thread::hardware_concurrency())) : threads;
    std::vector<Counters> per_thread(std::max(64, nthreads));
    // One task per row: a pixel's samples are always summed by one thread in order.
    parallel_for(size_t(row1 - row0), nthreads, [&](size_t r, int tid) {
        if (cancel_flag.load(std::memory_order_relaxed)) return;
        Counters& cnt = per_thread[tid];
        const size_t row = size_t(row0) + r;
        for (int px = 0; px < cam.width; ++px) {
            size_t pix = row * size_t(cam.width) + size_t(px);
            if (active && !active[pix]) continue;
            size_t at = (r * size_t(cam.width) + size_t(px)) * stride;  // in the rows' buffers
            double* s = sum + at;
            double* s2 = sumsq + at;
            for (uint64_t si = start; si < start + count; ++si) {
                Rng rng(seed, 0x100000000ull * uint64_t(ci + 1), uint64_t(pix) * 0x100000000ull + si);
                double fx, fy;
                double u1 = rng.uniform(), u2 = rng.uniform();
                if (cam.filter == 1) {  // Gaussian with the given FWHM (Box-Muller)
                    double sigma = cam.filter_width / 2.354820045;
                    double r = sigma * std::sqrt(-2.0 * std::log(1.0 - u1));
                    fx = r * std::cos(2 * kPi * u2); fy = r * std::sin(2 * kPi * u2);
                } else {
                    fx = (u1 - 0.5) * cam.filter_width; fy = (u2 - 0.5) * cam.filter_width;
                }
                Vec3 o, d;
                camera_ray(cam, px + 0.5 + fx, row + 0.5 + fy, &o, &d);
                Components L = trace(o, d, cam.medium, false, false, rng, cnt, 1.0, true);
                Spectrum comp[kNumComponents] = {Spectrum(), L.beam_surface, L.beam_volume, L.path, Spectrum(),
                                                 L.inelastic[kRaman], L.inelastic[kChlorophyll], L.inelastic[kCDOM]};
                accumulate(comp, nb, s, s2);
            }
        }
    });
    if (total)
        for (const auto& c : per_thread) {
            total->segments += c.segments; total->shadow_rays += c.shadow_rays; total->paths += c.paths;
        }
}

void Scene::camera_guides(int ci, int per_axis, int threads, float* albedo, float* normal, int row0,
                          int row1) const {
    const Camera& cam = cameras.at(ci);
    const int nb = nbands;
    const int n = std::max(1, per_axis);
    const double inv = 1.0 / double(n * n);
    const double far = 1e6;  // m: a ray that meets nothing, as far as water can matter
    int nthreads = threads <= 0 ? int(std::max(1u, std::thread::hardware_concurrency())) : threads;
    if (row1 < 0 || row1 > cam.height) row1 = cam.height;
    row0 = std::clamp(row0, 0, row1);
    parallel_for(size_t(row1 - row0), nthreads, [&](size_t i, int) {
        const size_t row = size_t(row0) + i;
        for (int px = 0; px < cam.width; ++px) {
            double alb[kMaxBands] = {};
            Vec3 nrm;
            for (int sy = 0; sy < n; ++sy)
                for (int sx = 0; sx < n; ++sx) {
                    Vec3 o, d;
                    camera_ray(cam, px + (sx + 0.5) / n, double(row) + (sy + 0.5) / n, &o, &d);
                    int medium = cam.medium;
                    double wgt[kMaxBands];
                    std::fill_n(wgt, nb, 1.0);
                    for (int event = 0; event < 16; ++event) {
                        Hit h = intersect(o, d);
                        const double t = h.valid ? h.t : far;
                        if (medium >= 0) {  // the water in front: what it scatters back
                            const Water& w = waters[medium];
                            Spectrum ta, tb;
                            const Vec3 e = o + d * t;
                            w.add_optical_depths(o, e, t, nb, &ta, &tb);
                            for (int k = 0; k < nb; ++k) {
                                double tau = ta.v[k] + tb.v[k];
                                double tr = std::exp(-tau);
                                if (tau > 0.0) alb[k] += wgt[k] * (1.0 - tr) * tb.v[k] / tau * inv;
                                wgt[k] *= tr;
                            }
                        }
                        if (!h.valid) break;  // the sky: no surface (albedo 0, normal 0)
                        const Vec3 x = o + d * h.t;
                        const double off = offset_for(x);
                        if (h.kind == SurfaceKind::kOpaque) {
                            Vec3 nf = dot(h.n, d) > 0.0 ? -h.n : h.n;
                            const Material surface = surface_at(h);
                            double mean_w = 0.0;
                            for (int k = 0; k < nb; ++k) {
                                alb[k] += wgt[k] * surface.reflectance.v[k] * inv;
                                mean_w += wgt[k];
                            }
                            nrm = nrm + nf * (mean_w / nb * inv);
                            break;
                        }
                        // A water boundary: through it as the more likely of its two ways (a
                        // specular surface; the guides show what lies beyond, as Cycles' do).
                        const Water& w = waters[h.index];
                        const bool entering = dot(d, h.n) < 0.0;
                        const double n1 = entering ? 1.0 : w.ior, n2 = entering ? w.ior : 1.0;
                        const Vec3 ng = entering ? h.n : -h.n;
                        const Vec3 ns = (h.id == -3 ? !ocean_flat : h.id >= 0) ? (entering ? h.ns : -h.ns) : ng;
                        Vec3 dt;
                        const bool through = refract(d, ns, n1, n2, &dt) && dot(dt, ng) < 0.0 &&
                                             fresnel_unpolarized(-dot(d, ns), n1, n2) < 0.5;
                        if (through) {
                            d = dt;
                            o = x - ng * off;
                            medium = entering ? h.index : -1;
                        } else {
                            d = normalize(reflect(d, ns));
                            if (dot(d, ng) <= 0.0) d = normalize(reflect(d, ng));
                            o = x + ng * off;
                        }
                    }
                }
            const size_t pix = i * size_t(cam.width) + size_t(px);  // (rows from row0)
            for (int k = 0; k < nb; ++k) albedo[pix * nb + k] = float(std::min(1.0, std::max(0.0, alb[k])));
            normal[pix * 3 + 0] = float(nrm.x);
            normal[pix * 3 + 1] = float(nrm.y);
            normal[pix * 3 + 2] = float(nrm.z);
        }
    });
}

void Scene::radiometer_sample(int ri, uint64_t index, const BeamSample* at_sensor, int n_at_sensor,
                              Spectrum* out, int* bin, Counters& c) const {
    const Radiometer& r = radiometers[ri];
    Rng rng(seed, 0x7000000000000000ull + uint64_t(ri), index);
    for (int ci = 0; ci < kNumComponents; ++ci) out[ci] = Spectrum();
    double u1 = rng.uniform(), u2 = rng.uniform();
    Vec3 w;            // look direction: light arrives travelling along -w
    double weight;     // response / pdf
    *bin = 0;
    auto response = [&](const Vec3& v) -> double {  // W(v) for the sun's and beams' direct terms
        switch (r.quantity) {
            case Quantity::kEd: return std::max(0.0, v.z);
            case Quantity::kEu: return std::max(0.0, -v.z);
            case Quantity::kEo: return 1.0;
            case Quantity::kEod: return v.z > 0 ? 1.0 : 0.0;
            case Quantity::kEou: return v.z < 0 ? 1.0 : 0.0;
            case Quantity::kRadiance:
                return dot(v, r.direction) >= r.cos_half_angle ? 1.0 / (2 * kPi * (1 - r.cos_half_angle)) : 0.0;
            case Quantity::kRadianceDistribution: {
                double theta = std::acos(std::clamp(v.z, -1.0, 1.0));
                double phi = std::atan2(v.y, v.x);
                if (phi < 0) phi += 2 * kPi;
                int ip = std::min(r.polar_bins - 1, int(theta / kPi * r.polar_bins));
                int ia = std::min(r.azimuth_bins - 1, int(phi / (2 * kPi) * r.azimuth_bins));
                if (ip * r.azimuth_bins + ia != *bin) return 0.0;
                double t0 = kPi * ip / r.polar_bins, t1 = kPi * (ip + 1) / r.polar_bins;
                double omega = (std::cos(t0) - std::cos(t1)) * (2 * kPi / r.azimuth_bins);
                return 1.0 / omega;
            }
        }
        return 0.0;
    };
    const Vec3 up(0, 0, 1);
    switch (r.quantity) {
        case Quantity::kEd: w = cosine_hemisphere(up, u1, u2); weight = kPi; break;
        case Quantity::kEu: w = cosine_hemisphere(-up, u1, u2); weight = kPi; break;
        case Quantity::kEo: w = direction_around(up, 2.0 * u1, 2 * kPi * u2); weight = 4 * kPi; break;
        case Quantity::kEod: w = direction_around(up, u1, 2 * kPi * u2); weight = 2 * kPi; break;
        case Quantity::kEou: w = direction_around(-up, u1, 2 * kPi * u2); weight = 2 * kPi; break;
        case Quantity::kRadiance:
            w = direction_around(r.direction, u1 * (1.0 - r.cos_half_angle), 2 * kPi * u2); weight = 1.0; break;
        case Quantity::kRadianceDistribution: {
            int nbins = r.polar_bins * r.azimuth_bins;
            *bin = int(index % uint64_t(nbins));  // stratified over bins
            int ip = *bin / r.azimuth_bins, ia = *bin % r.azimuth_bins;
            double c0 = std::cos(kPi * ip / r.polar_bins), c1 = std::cos(kPi * (ip + 1) / r.polar_bins);
            double mu = c0 + u1 * (c1 - c0);
            double phi = 2 * kPi * (ia + u2) / r.azimuth_bins;
            double st = std::sqrt(std::max(0.0, 1 - mu * mu));
            w = Vec3(st * std::cos(phi), st * std::sin(phi), mu);
            weight = 1.0;
            break;
        }
    }
    bool sensor_nee = has_sun && r.medium < 0;
    bool sensor_beams = hybrid && r.medium >= 0;
    // In the air: the sun reflected by the water reaching the sensor, in closed form from the
    // reflected beams at it (its paths then leave that light to them).
    const bool sensor_air_beams = hybrid && r.medium < 0 && has_air_beams();
    double first_weight = 1.0;
    // The beams at the radiometer serve both the MIS below and the closed-form direct term.
    const BeamSample* beams = at_sensor;
    const int nbeams = sensor_beams ? n_at_sensor : 0;
    // (Beam-direction samples only in water that scatters, as at surface vertices.)
    const BeamSample* best = sensor_beams && waters[r.medium].scatters() ? brightest(beams, nbeams) : nullptr;
    if (best) {
        const Vec3 bd = best->d;
        // Beam-scattering MIS for the first segment: the sensor's own directions against
        // directions drawn from the phase function around the beam (looking towards the sun).
        const Water& wat = waters[r.medium];
        // Beam-guided first direction (exact mode, irradiances that see the sky; as at
        // scattering vertices):
        // the path starts towards the beam's reverse a fraction kBeamGuide of the time, and
        // its score is the response over the mixture's pdf.
        const double sensor_pdf = weight;  // response / sensor_pdf is the sensor's own pdf
        const bool guide = cone_half_angle == 0.0 && (r.quantity == Quantity::kEd || r.quantity == Quantity::kEo ||
                                                      r.quantity == Quantity::kEod);
        auto mixture = [&](const Vec3& v) {
            const double own = response(v) / sensor_pdf;
            return guide ? (1.0 - kBeamGuide) * own + kBeamGuide * beam_direction_pdf(wat, bd, v) : own;
        };
        if (guide) {
            if (rng.uniform() < kBeamGuide) w = sample_beam_direction(wat, bd, rng);
            const double pm = mixture(w);
            weight = pm > 0.0 ? response(w) / pm : 0.0;  // the path's score per unit radiance
        }
        double pa = mixture(w), pb = beam_direction_pdf(wat, bd, w);
        first_weight = pa + pb > 0.0 ? pa / (pa + pb) : 0.0;
        Vec3 wb = sample_beam_direction(wat, bd, rng);
        double resp = response(wb);
        if (resp > 0.0) {
            double pa_b = mixture(wb), pb_b = beam_direction_pdf(wat, bd, wb);
            Hit hb = intersect(r.position, wb, kInf, ocean_side(r.medium));
            c.segments++;
            Spectrum I, R[kInelasticKinds];
            beam_scatter_along(r.position, wb, hb.valid ? hb.t : kInf, r.medium, rng, &I, nullptr, R);
            for (int k = 0; k < nbands; ++k) {
                out[2].v[k] += resp * I.v[k] / (pa_b + pb_b);
                for (int c = 0; c < kInelasticKinds; ++c) out[5 + c].v[k] += resp * R[c].v[k] / (pa_b + pb_b);
            }
        }
    }
    Components L = trace(r.position, w, r.medium, sensor_nee, sensor_beams, rng, c, first_weight, false,
                         sensor_air_beams);
    for (int k = 0; k < nbands; ++k) {
        out[1].v[k] = L.beam_surface.v[k] * weight;
        out[2].v[k] += L.beam_volume.v[k] * weight;
        out[3].v[k] = L.path.v[k] * weight;
        for (int c = 0; c < kInelasticKinds; ++c) out[5 + c].v[k] += L.inelastic[c].v[k] * weight;
    }
    if (sensor_nee) {
        double s1 = rng.uniform(), s2 = rng.uniform();
        Vec3 ws = sample_sun(s1, s2);
        double resp = response(ws);
        if (resp > 0.0) {
            c.shadow_rays++;
            if (!occluded(r.position, ws, Side::kAbove))
                for (int k = 0; k < nbands; ++k) out[3].v[k] += resp * sun_radiance.v[k] / sun_pdf();
        }
    }
    if (sensor_beams || sensor_air_beams) {
        // The refracted (or, in the air, reflected) sun at the radiometer itself, in closed form.
        // A spread beam (the sun centre's prism holding the whole disk): a radiance or a
        // radiance distribution, whose response steps at its cap's or bin's edge, takes it at a
        // point drawn in the disk's image around the beam (a cap of the refracted image's solid
        // angle in water, of the sun's own in the air), as passes drawing their directions in
        // the disk do for the other beams.
        const bool stepped = r.quantity == Quantity::kRadiance || r.quantity == Quantity::kRadianceDistribution;
        const double radius = !stepped || !sun_blur_active() ? 0.0
                              : r.medium >= 0 ? beam_disk_radius : std::acos(std::clamp(sun_cos_half, -1.0, 1.0));
        for (int j = 0; j < n_at_sensor; ++j) {
            Vec3 v = -beams[j].d;
            if (radius > 0.0 && beams[j].spread) {
                const Frame f(v);
                const double rho = radius * std::sqrt(rng.uniform()), phi = 2.0 * kPi * rng.uniform();
                v = normalize(v + (f.s * std::cos(phi) + f.t * std::sin(phi)) * std::tan(rho));
            }
            double resp = response(v);
            if (resp > 0.0)
                for (int k = 0; k < nbands; ++k) out[4].v[k] += resp * beams[j].e.v[k];
        }
    }
}

namespace {

// Count, mean and central sums of powers 2-4 of a set of samples (Pebay 2008: the sums of two
// sets merge exactly, without the cancellation of raw power sums).
struct Moments {
    double n = 0, mean = 0, m2 = 0, m3 = 0, m4 = 0;
    void merge(const Moments& b) {
        if (b.n == 0) return;
        if (n == 0) { *this = b; return; }
        const double na = n, nb = b.n, nn = na + nb, d = b.mean - mean, d2 = d * d;
        m4 += b.m4 + d2 * d2 * na * nb * (na * na - na * nb + nb * nb) / (nn * nn * nn) +
              6.0 * d2 * (na * na * b.m2 + nb * nb * m2) / (nn * nn) + 4.0 * d * (na * b.m3 - nb * m3) / nn;
        m3 += b.m3 + d2 * d * na * nb * (na - nb) / (nn * nn) + 3.0 * d * (na * b.m2 - nb * m2) / nn;
        m2 += b.m2 + d2 * na * nb / nn;
        mean += d * nb / nn;
        n = nn;
    }
};

}  // namespace

void Scene::render_radiometer(int ri, uint64_t start, uint64_t count, int threads,
                              double* sum, double* sumsq, Counters* total, double* moments) const {
    const Radiometer& r = radiometers.at(ri);
    const int nb = nbands, nbins = r.bins();
    const size_t stride = size_t(kNumComponents) * nb;
    const uint64_t kChunk = 1024;
    size_t nchunks = size_t((count + kChunk - 1) / kChunk);
    std::vector<double> csum(nchunks * nbins * stride, 0.0), csq(nchunks * nbins * stride, 0.0);
    // Per chunk, bin and band: the total's moments (two passes over the chunk's samples).
    std::vector<Moments> cmom(moments ? nchunks * nbins * nb : 0);
    int nthreads = threads <= 0 ? int(std::max(1u, std::thread::hardware_concurrency())) : threads;
    std::vector<Counters> per_thread(std::max(64, nthreads));
    // The beams at the sensor: fixed within the pass (its position and these beams), so
    // evaluated once, not per sample (in gridded water each is a walk to the surface).
    std::vector<BeamSample> at_sensor(kMaxBeams);
    const int n_at_sensor = hybrid && (r.medium >= 0 || has_air_beams())
                                ? beams_at(r.position, r.medium, at_sensor.data(), kMaxBeams) : 0;
    parallel_for(nchunks, nthreads, [&](size_t chunk, int tid) {
        if (cancel_flag.load(std::memory_order_relaxed)) return;
        uint64_t b = start + chunk * kChunk, e = std::min(start + count, b + kChunk);
        // The chunk's sums are accumulated in the thread's own buffers and stored at its end:
        // chunks next to each other in csum share cache lines at their edges, and two threads
        // writing them on every sample made the lines bounce between the cores.
        thread_local std::vector<double> local_sum, local_sq;
        local_sum.assign(nbins * stride, 0.0);
        local_sq.assign(nbins * stride, 0.0);
        double* s = local_sum.data();
        double* s2 = local_sq.data();
        thread_local std::vector<double> totals;  // the chunk's totals (moments only)
        thread_local std::vector<int> bins;
        totals.clear();
        bins.clear();
        for (uint64_t i = b; i < e; ++i) {
            Spectrum comp[kNumComponents];
            int bin = 0;
            radiometer_sample(ri, i, at_sensor.data(), n_at_sensor, comp, &bin, per_thread[tid]);
            accumulate(comp, nb, s + bin * stride, s2 + bin * stride);
            if (moments) {
                bins.push_back(bin);
                for (int k = 0; k < nb; ++k)
                    totals.push_back(total_of(comp, k));
            }
        }
        std::copy(local_sum.begin(), local_sum.end(), csum.begin() + chunk * nbins * stride);
        std::copy(local_sq.begin(), local_sq.end(), csq.begin() + chunk * nbins * stride);
        if (!moments) return;
        Moments* m = &cmom[chunk * nbins * nb];
        const double* tsum = s;  // per bin: the total's sum is component 0 of the sums
        for (size_t j = 0; j < bins.size(); ++j)
            for (int k = 0; k < nb; ++k) m[bins[j] * nb + k].n += 1.0;
        for (int bi = 0; bi < nbins; ++bi)
            for (int k = 0; k < nb; ++k)
                if (m[bi * nb + k].n > 0) m[bi * nb + k].mean = tsum[bi * stride + k] / m[bi * nb + k].n;
        for (size_t j = 0; j < bins.size(); ++j)
            for (int k = 0; k < nb; ++k) {
                Moments& q = m[bins[j] * nb + k];
                const double d = totals[j * nb + k] - q.mean, d2 = d * d;
                q.m2 += d2;
                q.m3 += d2 * d;
                q.m4 += d2 * d2;
            }
    });
    // Reduce in chunk order so the result is independent of the thread count.
    for (size_t ch = 0; ch < nchunks; ++ch)
        for (size_t i = 0; i < nbins * stride; ++i) {
            sum[i] += csum[ch * nbins * stride + i];
            sumsq[i] += csq[ch * nbins * stride + i];
        }
    if (moments) {
        for (int i = 0; i < nbins * nb; ++i) {
            Moments acc;
            for (size_t ch = 0; ch < nchunks; ++ch) acc.merge(cmom[ch * nbins * nb + i]);
            const int bi = i / nb, k = i % nb;
            moments[(bi * 3 + 0) * nb + k] = acc.m2;
            moments[(bi * 3 + 1) * nb + k] = acc.m3;
            moments[(bi * 3 + 2) * nb + k] = acc.m4;
        }
    }
    if (total)
        for (const auto& c : per_thread) {
            total->segments += c.segments; total->shadow_rays += c.shadow_rays; total->paths += c.paths;
        }
}

void Scene::trace_rays(const float* o, const float* d, size_t n, int threads, float* t_out,
                       const float* tmax) const {
    const size_t kBlock = 4096;
    size_t nblocks = (n + kBlock - 1) / kBlock;
    parallel_for(nblocks, threads, [&](size_t blk, int) {
        size_t b = blk * kBlock, e = std::min(n, b + kBlock);
        for (size_t i = b; i < e; ++i) {
            RTCRayHit rh;
            rh.ray.org_x = o[3 * i]; rh.ray.org_y = o[3 * i + 1]; rh.ray.org_z = o[3 * i + 2];
            rh.ray.dir_x = d[3 * i]; rh.ray.dir_y = d[3 * i + 1]; rh.ray.dir_z = d[3 * i + 2];
            rh.ray.tnear = 0.0f; rh.ray.tfar = tmax ? tmax[i] : std::numeric_limits<float>::infinity();
            rh.ray.time = 0.0f; rh.ray.mask = 0xFFFFFFFFu; rh.ray.id = 0; rh.ray.flags = 0;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID; rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(scene_, &rh);
            t_out[i] = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? -1.0f : rh.ray.tfar;
        }
    });
}

}  // namespace photic
