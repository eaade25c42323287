// Beams: the refracted direct sun below the water surface.
//
// Below a flat ocean the refracted sun is one analytic beam. Below any triangulated water
// surface (an ocean's height-field patch, the sun-facing faces of a closed water mesh) every
// lit triangle sends a prism of light: its three vertex rays are the refracted sun directions
// at the vertices, traced to the first surface they meet. Where the three rays disagree (an
// object edge, a shadow), the triangle is subdivided. The irradiance inside a prism at path
// length l is Phi exp(-c_beam l) / A(l), A the cross-section, so focusing waves give caustics.
#include <algorithm>
#include <array>
#include <cmath>
#include <thread>
#include "disk_overlap.h"
#include "optics.h"
#include "parallel.h"
#include "scene.h"

namespace photic {

namespace {

struct VertexRay {
    Vec3 p, n, d;        // surface point, surface normal (air side), refracted direction
    double len = 0.0;    // to the first surface met in the water (or the attenuation cap)
    int id = -1;         // what it hit (-1 nothing)
    Vec3 hn;             // the normal of the surface it hit
    bool lit = false;    // the sun reaches p and refracts into the water
};

struct SourceTri {
    Vec3 p[3], n[3];     // corners and their shading normals (air side)
    Vec3 nf;             // face normal (air side)
    int water;
    bool periodic;
    int64_t vid[3] = {-1, -1, -1};  // the ocean patch's vertices at the corners (-1: a mesh's)
};

}  // namespace

void Scene::set_forward_cone(double half_angle) {
    cone_half_angle = std::max(0.0, half_angle);
    for (auto& w : waters) w.set_forward_cone(phases, cone_half_angle, nbands);
}

double Scene::beam_total_flux() const {
    double s = 0.0;
    for (const auto& p : prisms) s += p.phi.v[0];
    return s;
}

double Scene::air_beam_total_flux() const {
    double s = 0.0;
    for (const auto& p : air_prisms) s += p.phi.v[0];
    return s;
}

namespace {

// Room for n items with a quarter to spare: the sizes vary from pass to pass (the sun's
// direction is drawn anew), and an array grown to the exact size was allocated afresh (and its
// pages faulted in and zeroed) at nearly every pass that needed a few more items. At least
// doubled when it grows: an array filled piece by piece (the grid's items, layer by layer)
// would otherwise be copied into fresh pages some ten times per build; pages reserved and
// never written cost nothing.
template <class V>
void make_room(V& v, size_t n) {
    if (n > v.capacity()) v.reserve(std::max(n + n / 4, 2 * v.capacity()));
}

}  // namespace

// Refraction of the sun (towards s) through the ocean surface with local normal n: the
// direction and the transmitted fraction of the flux arriving on the macro surface. A rough
// surface refracts through the build's facet (the same facet relative to every local normal),
// weighted so that the expectation over builds is the rough BTDF's transmission.
bool Scene::refract_sun(const Vec3& s, const Vec3& n, double ior, Vec3* d, double* T, double u1, double u2) const {
    if (!(dot(n, s) > 0.0)) return false;
    if (!ocean_rough) {
        if (!refract(-s, n, 1.0, ior, d)) return false;
        *T = 1.0 - fresnel_unpolarized(dot(n, s), 1.0, ior);
        return true;
    }
    const Frame fr(n);
    RoughSample rs = ocean_bsdf.sample(fr.to_local(s), u1, u2, 1.0, RoughInterface::kImportance);
    if (!rs.valid || rs.reflection) return false;
    *d = fr.to_world(rs.wo);
    *T = (1.0 - rs.fresnel) * rs.weight;  // transmission was forced: its probability 1 - F
    return true;
}

void Scene::make_prisms(const Vec3& s, const Spectrum& e_sun, bool air, int threads, double facet_u1,
                        double facet_u2, LargeVector<BeamPrism>* dest, std::vector<std::array<Vec3, 3>>* normals,
                        bool blur) {
    auto ocean_refraction = [&](const Vec3& n, double ior, Vec3* d, double* T, double u1, double u2) {
        return refract_sun(s, n, ior, d, T, u1, u2);
    };
    // The sun's disk seen through a prism (BeamPrism::blur_g1): the directions that the prism's
    // mean normal gives the disk's edge, at right angles, half their differences (the secant
    // over the disk, to first order in its radius the Jacobian of refraction or reflection),
    // projected along the beam onto the slicing plane. Where a probe does not refract (total
    // reflection is near) the prism stays sharp.
    const double blur_alpha = std::acos(std::clamp(sun_cos_half, -1.0, 1.0));
    const Frame sun_frame(s);
    auto set_blur = [&](BeamPrism* P, const Vec3 n[3], double ior) {
        const Vec3 nc = normalize(n[0] + n[1] + n[2]);
        auto dir = [&](const Vec3& sp, Vec3* d) {
            if (!(dot(nc, sp) > 0.0)) return false;
            if (air) {
                *d = reflect(-sp, nc);
                return true;
            }
            return refract(-sp, nc, 1.0, ior, d);
        };
        Vec3 dc;
        if (!dir(s, &dc) || !(dot(dc, P->m) > 1e-6)) return;
        const double ca = std::cos(blur_alpha), sa = std::sin(blur_alpha);
        Vec3 k[2];
        for (int a = 0; a < 2; ++a) {
            const Vec3& e = a ? sun_frame.t : sun_frame.s;
            Vec3 dp, dm;
            if (!dir(s * ca + e * sa, &dp) || !dir(s * ca - e * sa, &dm)) return;
            const Vec3 kk = (dp - dm) * 0.5;
            k[a] = kk - dc * (dot(kk, P->m) / dot(dc, P->m));
        }
        const double D = dot(cross(k[0], k[1]), P->m);
        if (!(std::fabs(D) > 1e-300)) return;
        P->blur_g1 = cross(k[1], P->m) * (1.0 / D);
        P->blur_g2 = cross(P->m, k[0]) * (1.0 / D);
        P->blur_det = std::fabs(D);
        P->blur_reach = std::sqrt(dot(k[0], k[0]) + dot(k[1], k[1]));
    };
    // Source triangles: the ocean patch (with its vertex normals) and the sun-facing faces of
    // closed water meshes (face normals).
    std::vector<SourceTri> src;
    if (ocean_water >= 0 && !ocean_flat) {
        size_t nv = patch_vertices.size() / 3, nt = patch_triangles.size() / 3;
        auto V = [&](size_t i) { return Vec3(patch_vertices[3 * i], patch_vertices[3 * i + 1], patch_vertices[3 * i + 2]); };
        // The patch's shading normals (given, or made smooth at commit): the same as paths meet.
        std::vector<Vec3> vn(nv);
        for (size_t i = 0; i < nv; ++i)
            vn[i] = normalize(Vec3(patch_normals[3 * i], patch_normals[3 * i + 1], patch_normals[3 * i + 2]));
        for (size_t t = 0; t < nt; ++t) {
            const uint32_t* tri = &patch_triangles[3 * t];
            SourceTri st;
            for (int j = 0; j < 3; ++j) { st.p[j] = V(tri[j]); st.n[j] = vn[tri[j]]; st.vid[j] = tri[j]; }
            st.nf = normalize(cross(st.p[1] - st.p[0], st.p[2] - st.p[0]));
            if (st.nf.z < 0) {
                std::swap(st.p[1], st.p[2]);
                std::swap(st.n[1], st.n[2]);
                std::swap(st.vid[1], st.vid[2]);
                st.nf = -st.nf;
            }
            st.water = ocean_water;
            st.periodic = true;
            if (!beam_source_region.empty()) {
                const Vec3 c = (st.p[0] + st.p[1] + st.p[2]) * (1.0 / 3.0);
                bool inside = false;
                for (size_t k = 0; k + 2 < beam_source_region.size() && !inside; k += 3) {
                    double dx = c.x - beam_source_region[k], dy = c.y - beam_source_region[k + 1];
                    dx -= patch_lx * std::round(dx / patch_lx);
                    dy -= patch_ly * std::round(dy / patch_ly);
                    inside = dx * dx + dy * dy <= beam_source_region[k + 2] * beam_source_region[k + 2];
                }
                if (!inside) continue;
            }
            if (dot(st.nf, s) > 0.0) src.push_back(st);
        }
    }
    for (const auto& m : meshes) {
        if (m.kind != SurfaceKind::kWaterBoundary) continue;
        const size_t nt = m.triangles.size() / 3;
        auto V = [&](uint32_t i) { return Vec3(m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]); };
        // The smooth shading normals at the corners (smooth_corner_normals, made at commit),
        // which the paths meet too.
        for (size_t t = 0; t < nt; ++t) {
            const uint32_t* tri = &m.triangles[3 * t];
            SourceTri st;
            for (int j = 0; j < 3; ++j) st.p[j] = V(tri[j]);
            st.nf = normalize(cross(st.p[1] - st.p[0], st.p[2] - st.p[0]));
            if (dot(st.nf, s) <= 0.0) continue;
            const float* c = &m.corner_normals[9 * t];
            for (int j = 0; j < 3; ++j) st.n[j] = normalize(Vec3(c[3 * j], c[3 * j + 1], c[3 * j + 2]));
            st.water = m.index;
            st.periodic = false;
            if (dot(st.nf, s) > 0.0) src.push_back(st);
        }
    }
    if (src.empty()) return;

    // Bounding boxes of opaque objects: prisms that overlap one test visibility per query.
    std::vector<std::pair<Vec3, Vec3>> object_boxes;
    for (const auto& m : meshes)  // (an instanced mesh: one box around all its copies)
        if (m.kind == SurfaceKind::kOpaque) object_boxes.push_back(m.world_bounds());

    // A vertex ray of the periodic patch meets only what repeats with it (the surface, the
    // bottom): its prism serves every period, and the meshes (which stand in one period only)
    // are met by each query's shadow rays in the period it asks about. A vertex ray of a water
    // mesh meets everything.
    // Reflected rays end where they leave the scene's bounds (nothing beyond to light).
    auto air_cap = [&](const Vec3& o, const Vec3& d) {
        double t1 = 100.0 * extent_;
        for (int a = 0; a < 3; ++a) {
            const double lo = bounds_lo_[a] - 1e-3 * extent_, hi = bounds_hi_[a] + 1e-3 * extent_;
            if (d[a] > 0.0) t1 = std::min(t1, (hi - o[a]) / d[a]);
            else if (d[a] < 0.0) t1 = std::min(t1, (lo - o[a]) / d[a]);
        }
        return std::max(t1, 0.0);
    };
    // A vertex ray of the sun reflected into the air about the vertex's normal (lit if that
    // normal faces the sun and the reflection leaves on the air side of the face; else it
    // follows the face's own reflection, as a placeholder that the shadow rays sort out).
    auto trace_vertex_air = [&](const Vec3& p, const Vec3& n, const Vec3& nf, bool periodic) {
        VertexRay r;
        r.p = p;
        r.n = n;
        const double off = offset_for(p);
        r.d = reflect(-s, n);
        if (dot(n, s) > 0.0 && dot(r.d, nf) > 0.0) {
            r.lit = periodic ? !occluded_ocean(p + n * off, s, Side::kAbove) : !occluded(p + n * off, s);
        } else {
            r.d = reflect(-s, nf);
        }
        const Vec3 o = p + nf * off;
        const double cap = air_cap(o, r.d);
        Hit h = periodic ? intersect_ocean(o, r.d, cap, Side::kAbove) : intersect(o, r.d, cap);
        r.len = h.valid ? h.t + off : cap;
        r.id = h.valid ? h.id : -1;
        r.hn = h.valid ? h.n : Vec3();
        return r;
    };
    // (through: whether the sun refracts through the vertex's own normal; only then is the ray
    // the same for every face around the vertex.)
    auto trace_vertex = [&](const Vec3& p, const Vec3& n, const Vec3& nf, int wi, bool rough, bool periodic,
                            bool* through_out = nullptr) {
        VertexRay r;
        r.p = p;
        r.n = n;
        const Water& w = waters[wi];
        double cmin = w.c_beam_min;
        double cap = std::min(cmin > 0 ? 30.0 / cmin : kInf, 100.0 * extent_);
        double off = offset_for(p);
        double cs = dot(n, s), T;
        bool through = rough ? ocean_refraction(n, w.ior, &r.d, &T, facet_u1, facet_u2)
                             : cs > 0.0 && refract(-s, n, 1.0, w.ior, &r.d);
        if (through_out) *through_out = through;
        if (through) {
            r.lit = periodic ? !occluded_ocean(p + n * off, s, Side::kAbove) : !occluded(p + n * off, s);
        } else if (!(rough ? ocean_refraction(nf, w.ior, &r.d, &T, facet_u1, facet_u2)
                           : refract(-s, nf, 1.0, w.ior, &r.d))) {
            // Unlit: the sun grazes the vertex's normal from behind. Its ray follows the sun
            // refracted by the source face (which faces the sun), so that the prism stays a
            // prism (a placeholder straight down made prisms metres wide at grazing suns,
            // marking thousands of grid cells each); the shadow rays of each query say where
            // the light is.
            r.d = -n;
        }
        Hit h = periodic ? intersect_ocean(p - n * off, r.d, cap, Side::kBelow) : intersect(p - n * off, r.d, cap);
        r.len = h.valid ? h.t + off : cap;
        r.id = h.valid ? h.id : -1;
        r.hn = h.valid ? h.n : Vec3();
        return r;
    };

    // The ocean patch's vertex rays, traced once per vertex rather than once per face around it
    // (six in the patch's grid), where they do not depend on the face: where the sun refracts
    // through the vertex's own normal.
    std::vector<VertexRay> vrays;
    std::vector<uint8_t> vshared;
    if (!air && ocean_water >= 0 && !ocean_flat) {
        const size_t nv = patch_vertices.size() / 3;
        vrays.resize(nv);
        vshared.assign(nv, 0);
        std::vector<uint8_t> used(nv, 0);  // (by a face that the sun lights)
        for (const SourceTri& st : src)
            for (int j = 0; j < 3; ++j)
                if (st.vid[j] >= 0) used[size_t(st.vid[j])] = 1;
        const size_t kBlock = 256;
        parallel_for((nv + kBlock - 1) / kBlock, threads, [&](size_t b, int) {
            if (cancel_flag.load(std::memory_order_relaxed)) return;
            for (size_t i = b * kBlock; i < std::min(nv, (b + 1) * kBlock); ++i) {
                if (!used[i]) continue;
                const Vec3 p(patch_vertices[3 * i], patch_vertices[3 * i + 1], patch_vertices[3 * i + 2]);
                const Vec3 n = normalize(Vec3(patch_normals[3 * i], patch_normals[3 * i + 1], patch_normals[3 * i + 2]));
                bool through = false;
                // (the face normal only matters where the ray does not go through)
                vrays[i] = trace_vertex(p, n, Vec3(0, 0, 1), ocean_water, ocean_rough, true, &through);
                vshared[i] = through;
            }
        });
    }

    // Per source triangle, adaptive subdivision into prisms (in parallel, merged in order):
    // the refracted sun's in the water, then (air) the reflected sun's in the air, from the
    // smooth surfaces (a rough sea's reflection is sampled by its BSDF instead).
    // Per source triangle, its prisms (lists kept from pass to pass: freed, their megabytes
    // came back as fresh pages to be zeroed by the kernel in every build).
    std::vector<std::vector<BeamPrism>>& out = prism_lists_;
    if (out.size() < src.size()) out.resize(src.size());
    std::vector<std::vector<std::array<Vec3, 3>>> out_normals(normals ? src.size() : 0);
    if (cancel_flag.load()) throw BuildCancelled{};
    parallel_for(src.size(), threads, [&](size_t ti, int) {
        out[ti].clear();
        if (cancel_flag.load(std::memory_order_relaxed)) return;
        const SourceTri& st = src[ti];
        const Water& w = waters[st.water];
        const bool rough = st.periodic && ocean_rough;  // the ocean patch's facets
        if (air && rough) return;
        struct Item { Vec3 p[3], n[3]; int level; };
        std::vector<Item> stack{{{st.p[0], st.p[1], st.p[2]}, {st.n[0], st.n[1], st.n[2]}, 0}};
        while (!stack.empty()) {
            Item it = stack.back();
            stack.pop_back();
            VertexRay r[3];
            for (int j = 0; j < 3; ++j) {
                const int64_t vid = it.level == 0 ? st.vid[j] : -1;
                if (air)
                    r[j] = trace_vertex_air(it.p[j], it.n[j], st.nf, st.periodic);
                else if (vid >= 0 && vshared[size_t(vid)])
                    r[j] = vrays[size_t(vid)];
                else
                    r[j] = trace_vertex(it.p[j], it.n[j], st.nf, st.water, rough, st.periodic);
            }
            int lit = int(r[0].lit) + int(r[1].lit) + int(r[2].lit);
            if (lit == 0) continue;
            // One prism is right only if its three rays end on one plane of one object; else
            // the end face (interpolated between the rays' ends) would cut across an edge.
            bool uniform = lit == 3 && r[0].id == r[1].id && r[1].id == r[2].id &&
                           (r[0].id == -1 ||  // all three end in open water (attenuation cap)
                            (dot(r[0].hn, r[1].hn) > 0.999 && dot(r[1].hn, r[2].hn) > 0.999));
            if (!uniform && it.level < beam_max_level) {
                Vec3 mp[3], mn[3];  // midpoints of edges 01, 12, 20
                for (int j = 0; j < 3; ++j) {
                    int k = (j + 1) % 3;
                    mp[j] = (it.p[j] + it.p[k]) * 0.5;
                    mn[j] = normalize(it.n[j] + it.n[k]);
                }
                int L = it.level + 1;
                stack.push_back({{it.p[0], mp[0], mp[2]}, {it.n[0], mn[0], mn[2]}, L});
                stack.push_back({{mp[0], it.p[1], mp[1]}, {mn[0], it.n[1], mn[1]}, L});
                stack.push_back({{mp[2], mp[1], it.p[2]}, {mn[2], mn[1], it.n[2]}, L});
                stack.push_back({{mp[0], mp[1], mp[2]}, {mn[0], mn[1], mn[2]}, L});
                continue;
            }
            BeamPrism P;
            double cs = dot(st.nf, s);
            double area = 0.5 * length(cross(it.p[1] - it.p[0], it.p[2] - it.p[0]));
            const double F = fresnel_unpolarized(cs, 1.0, w.ior);
            double T = air ? F : 1.0 - F;  // the flux reflected into the air, or transmitted
            Vec3 d_face;
            if (rough && !ocean_refraction(st.nf, w.ior, &d_face, &T, facet_u1, facet_u2)) continue;
            for (int k = 0; k < nbands; ++k) P.phi.v[k] = e_sun.v[k] * cs * area * T;
            P.src_area = area;
            bool down = true, up = true;
            // A water mesh's prism whose rays end on different faces (an object's edge at the
            // finest level) runs on to its longest ray: the shadow rays of each query find
            // where it is blocked, and an end face interpolated across the edge would cut off
            // lit water beside the object.
            double len_max = 0.0;
            for (int j = 0; j < 3; ++j) len_max = std::max(len_max, r[j].len);
            const bool run_on = !uniform && !st.periodic;
            for (int j = 0; j < 3; ++j) {
                P.v[j] = it.p[j];
                P.d[j] = r[j].d;
                P.len[j] = run_on ? len_max : r[j].len;
                P.hit[j] = r[j].id != -1;
                down = down && -r[j].d.z > 0.1;
                up = up && r[j].d.z > 0.1;
            }
            // Horizontal slices when the beam goes down (flux through horizontal planes is then
            // exact per prism), or up (reflected); slices normal to the mean direction for
            // grazing beams.
            P.m = down ? Vec3(0, 0, -1) : up ? Vec3(0, 0, 1) : normalize(r[0].d + r[1].d + r[2].d);
            bool ok = true;
            for (int j = 0; j < 3; ++j) {
                P.md[j] = dot(P.m, P.d[j]);
                P.mv[j] = dot(P.m, P.v[j]);
                ok = ok && P.md[j] > 1e-6;
            }
            if (!ok) continue;  // vertex rays diverging by > 90 deg: no consistent slicing
            if (blur && blur_alpha > 0.0) set_blur(&P, it.n, w.ior);
            P.n_src = st.nf;
            P.water = air ? -1 : st.water;
            P.periodic = st.periodic;
            P.partial_lit = lit < 3;
            P.reflected = air;
            P.lo = Vec3(kInf, kInf, kInf);
            P.hi = Vec3(-kInf, -kInf, -kInf);
            for (int j = 0; j < 3; ++j)
                for (const Vec3& q : {P.v[j], P.v[j] + P.d[j] * P.len[j]}) {
                    P.lo = Vec3(std::min(P.lo.x, q.x), std::min(P.lo.y, q.y), std::min(P.lo.z, q.z));
                    P.hi = Vec3(std::max(P.hi.x, q.x), std::max(P.hi.y, q.y), std::max(P.hi.z, q.z));
                }
            // Which shadow rays its queries need. A prism whose rays end on different surfaces
            // needs both. Periodic prisms are shifted at query time, so any mesh may cut one of
            // their images (or shade its source from above the water): they test whenever the
            // scene has meshes (meshes_block skips those far from the query). A water mesh's
            // prism whose three rays end on one plane: only where an opaque triangle may stand
            // in it, or in the sun's path to its source (set_prism_checks). With an ocean too
            // (whose surface the shadow rays also meet): where an object's box overlaps it.
            P.check_path = P.check_sun = !uniform || (st.periodic && !meshes.empty());
            if (uniform && !st.periodic && ocean_water >= 0) {
                for (const auto& [lo, hi] : object_boxes)
                    if (lo.x <= P.hi.x && hi.x >= P.lo.x && lo.y <= P.hi.y && hi.y >= P.lo.y &&
                        lo.z <= P.hi.z && hi.z >= P.lo.z)
                        P.check_path = P.check_sun = true;
            } else if (!st.periodic && !object_boxes.empty()) {
                set_prism_checks(&P, uniform, r[0].id != -1);
                if (lit < 3) P.check_sun = true;  // shaded in part, by whatever shades it
            }
            out[ti].push_back(P);
            if (normals) out_normals[ti].push_back({it.n[0], it.n[1], it.n[2]});
        }
    });
    if (cancel_flag.load()) throw BuildCancelled{};
    size_t total = dest->size();
    for (size_t ti = 0; ti < src.size(); ++ti) total += out[ti].size();
    make_room(*dest, total);
    for (size_t ti = 0; ti < src.size(); ++ti) {
        if ((ti & 1023) == 0 && cancel_flag.load(std::memory_order_relaxed)) throw BuildCancelled{};
        for (const BeamPrism& p : out[ti]) dest->push_back(p);
    }
    if (normals)
        for (const auto& list : out_normals) normals->insert(normals->end(), list.begin(), list.end());
}

void Scene::build_beams(const Vec3& sun_direction, int threads, double facet_u1, double facet_u2, bool keep_prisms) {
    try {
        build_beams_now(sun_direction, threads, facet_u1, facet_u2, keep_prisms);
    } catch (const BuildCancelled&) {  // no beams, and nothing half-built kept for the next build
        blurred_prisms_built_ = false;
        prisms.clear();
        air_prisms.clear();
        prism_keys_.clear();
        air_keys_.clear();
        grid_.clear();
        air_grid_.clear();
        grid_ref_.built = grid_ref_.usable = false;
        grid_ref_.prisms.clear();
        grid_ref_.grid.clear();
        water_grid_ = &grid_;
        flat_beam = flat_air_beam = false;
    }
}

void Scene::build_beams_now(const Vec3& sun_direction, int threads, double facet_u1, double facet_u2,
                            bool keep_prisms) {
    const bool blur = sun_blur_active();
    const bool keep = keep_prisms && blur && blurred_prisms_built_;
    if (!keep) {
        blurred_prisms_built_ = false;
        prisms.clear();
        air_prisms.clear();
        grid_.clear();
        air_grid_.clear();
    }
    flat_beam = false;
    flat_air_beam = false;
    flat_d.clear();
    flat_e0.clear();
    if (!has_sun) return;
    // With the blur the prisms are the sun centre's, spread over the disk (in place, and in
    // direction by beam_phase); the shadow rays and a flat sea's analytic beams (cheap, and
    // exact averaged over the passes) take the pass's direction.
    const Vec3 s = normalize(sun_direction);
    beam_sun_dir = s;
    const Vec3 centre = blur ? normalize(sun_dir) : s;
    {
        // The refracted disk as a circle of the solid angle that a level surface gives it: the
        // sun's radius over n across the plane of incidence, times cos(i) / (n cos(t)) in it.
        const double ior = waters.empty() ? 1.34 : waters[ocean_water >= 0 ? ocean_water : 0].ior;
        const double ci = std::clamp(centre.z, 0.0, 1.0);
        const double ct = std::sqrt(std::max(0.0, 1.0 - (1.0 - ci * ci) / (ior * ior)));
        const double radius = blur && ci > 0.0
                              ? std::acos(std::clamp(sun_cos_half, -1.0, 1.0)) / ior * std::sqrt(ci / ct) : 0.0;
        if (radius != beam_disk_radius || cone_half_angle != disk_phase_cone_ ||
            disk_phase_.size() != (radius > 0.0 ? phases.size() : 0))
            make_disk_phases(radius, cone_half_angle);
    }
    {   // refracted sun below a level surface, for sampling along segments
        double n = waters.empty() ? 1.34 : waters[ocean_water >= 0 ? ocean_water : 0].ior;
        double sin_t = std::sqrt(std::max(0.0, 1.0 - s.z * s.z)) / n;
        beam_mu_w = std::max(0.05, std::sqrt(std::max(0.0, 1.0 - sin_t * sin_t)));
    }
    const double alpha = std::acos(std::clamp(sun_cos_half, -1.0, 1.0));
    // Irradiance normal to the sun per band (uniform disk): L pi sin^2(alpha).
    Spectrum e_sun;
    // Each direction of the disk carries L dw, so a beam built for one direction drawn
    // uniformly in the disk carries L times the disk's solid angle (normal to itself).
    for (int k = 0; k < nbands; ++k) e_sun.v[k] = sun_radiance.v[k] * 2.0 * kPi * (1.0 - std::cos(alpha));

    auto ocean_refraction = [&](const Vec3& n, double ior, Vec3* d, double* T, double u1, double u2) {
        return refract_sun(s, n, ior, d, T, u1, u2);
    };

    if (ocean_water >= 0 && ocean_flat && s.z > 0.0) {
        // A rough flat sea: kRoughFlatBeams facets, stratified in the facet's slope radius and
        // rotated by the golden angle, each carrying its share of the flux.
        const Water& w = waters[ocean_water];
        const int nf = ocean_rough ? kRoughFlatBeams : 1;
        for (int i = 0; i < nf; ++i) {
            double u1 = ocean_rough ? (i + facet_u1) / nf : facet_u1;
            double u2 = std::fmod(facet_u2 + i * 0.6180339887498949, 1.0);
            Vec3 d;
            double T;
            if (!ocean_refraction(Vec3(0, 0, 1), w.ior, &d, &T, u1, u2)) continue;
            Spectrum e0;
            for (int k = 0; k < nbands; ++k) e0.v[k] = e_sun.v[k] * s.z * T / (-d.z) / nf;
            flat_d.push_back(d);
            flat_e0.push_back(e0);
        }
        flat_beam = !flat_d.empty();
        if (w.grid) {
            // One shadow map per render, around the refracted centre of the sun: the passes'
            // directions lie within the refracted disk, whose radius is at most the sun's
            // (refraction into denser water narrows angles); a rough sea's facets spread the
            // directions by a few degrees more (a facet outside the map's cone walks always).
            Vec3 centre;
            const double spread = 1.001 * alpha + 1e-9 + (ocean_rough ? kRoughShadeSpread : 0.0);
            if (refract(-sun_dir, Vec3(0, 0, 1), 1.0, w.ior, &centre)) {
                VoxelGrid::ShadowMap& m = flat_shade;
                if (!(m.spread == spread && dot(m.up, -centre) >= 1.0 - 1e-12))  // (else built)
                    w.grid->shadow_map(-centre, spread, &m, threads);
                flat_shade_ok.assign(flat_d.size(), 0);
                for (size_t i = 0; i < flat_d.size(); ++i)
                    flat_shade_ok[i] = dot(m.up, -flat_d[i]) >= std::cos(m.spread);
            } else {
                flat_shade_ok.clear();
            }
        } else {
            flat_shade_ok.clear();
        }
    }

    // The sun reflected into the air by smooth water surfaces lights what stands in the air:
    // built only where opaque objects or radiometers are there to be lit.
    bool need_air = false;
    for (const auto& m : meshes) need_air = need_air || m.kind == SurfaceKind::kOpaque;
    for (const auto& r : radiometers) need_air = need_air || r.medium < 0;
    if (need_air && ocean_water >= 0 && ocean_flat && !ocean_rough && s.z > 0.0) {
        // A smooth flat sea: the mirror image of the sun, its irradiance normal to itself F E.
        const double F = fresnel_unpolarized(s.z, 1.0, waters[ocean_water].ior);
        flat_air_d = Vec3(-s.x, -s.y, s.z);
        for (int k = 0; k < nbands; ++k) flat_air_e.v[k] = e_sun.v[k] * F;
        flat_air_beam = F > 0.0;
    }

    if (keep) return;  // (the prisms kept; the shadow rays and flat beams took s)
    if (blur) {
        // The prisms of the sun's centre, each spread over the disk's image: built once for
        // every pass (which keep_prisms then asks for), with a grid of their own whose marks
        // reach as far as the blur does.
        make_prisms(centre, e_sun, false, threads, 0.5, 0.0, &prisms, nullptr, true);
        if (need_air) make_prisms(centre, e_sun, true, threads, 0.5, 0.0, &air_prisms, nullptr, true);
        water_grid_ = &grid_;
        make_keys(prisms, &prism_keys_);
        blur_margins(prisms, prism_keys_);
        build_grid(prisms, prism_keys_, &grid_, blur_margin_a_.data(), blur_margin_g_.data(), &cancel_flag);
        make_keys(air_prisms, &air_keys_);
        blur_margins(air_prisms, air_keys_);
        build_grid(air_prisms, air_keys_, &air_grid_, blur_margin_a_.data(), blur_margin_g_.data(), &cancel_flag);
        blurred_prisms_built_ = true;
        return;
    }
    // The grid of the sun's centre, the first time (in the buffers of this build's prisms,
    // which it leaves empty, so that their memory is not faulted in twice).
    const GridReference& ref = grid_ref_;
    const bool shared = grid_reference_allowed();
    if (shared && !(ref.built && ref.sun.x == sun_dir.x && ref.sun.y == sun_dir.y && ref.sun.z == sun_dir.z &&
                    ref.cos_half == sun_cos_half))
        build_grid_reference(e_sun, threads);
    make_prisms(s, e_sun, false, threads, facet_u1, facet_u2, &prisms);
    if (need_air) make_prisms(s, e_sun, true, threads, facet_u1, facet_u2, &air_prisms);
    // The water beams' grid: the reference's, when these prisms fit it, else their own.
    make_keys(prisms, &prism_keys_);
    water_grid_ = &grid_;
    if (shared) {
        double sx, sy;
        if (ref.usable && reference_shear(s, &sx, &sy) && grid_reference_fits(sx, sy)) {
            grid_ref_.grid.sx = sx;
            grid_ref_.grid.sy = sy;
            water_grid_ = &grid_ref_.grid;
        }
    }
    if (water_grid_ == &grid_) build_grid(prisms, prism_keys_, &grid_, nullptr, nullptr, &cancel_flag);
    make_keys(air_prisms, &air_keys_);
    build_grid(air_prisms, air_keys_, &air_grid_, nullptr, nullptr, &cancel_flag);
}

namespace {

// Embree point query: the opaque triangles whose boxes overlap a region's box, up to a cap.
struct NearTriangles {
    const Scene* scene;
    Vec3 lo, hi;
    std::vector<std::array<Vec3, 3>> tris;
    bool overflow = false;
    static constexpr size_t kCap = 64;
};

bool gather_near_triangle(RTCPointQueryFunctionArguments* args) {
    auto* q = static_cast<NearTriangles*>(args->userPtr);
    // In a copy of an instanced mesh the ids are the instance array's and the copy's.
    const bool copy = args->context->instStackSize > 0;
    const MeshRecord& m = q->scene->meshes[copy ? args->context->instID[0] : args->geomID];
    if (m.kind != SurfaceKind::kOpaque) return false;
    std::array<Vec3, 3> t;
    for (int j = 0; j < 3; ++j) {
        const float* v = &m.vertices[3 * size_t(m.triangles[3 * size_t(args->primID) + j])];
        t[j] = Vec3(v[0], v[1], v[2]);
        if (copy) t[j] = m.to_world(args->context->instPrimID[0], t[j]);
    }
    for (int a = 0; a < 3; ++a)
        if (std::min({t[0][a], t[1][a], t[2][a]}) > q->hi[a] || std::max({t[0][a], t[1][a], t[2][a]}) < q->lo[a])
            return false;
    if (q->tris.size() >= NearTriangles::kCap) {  // too many to examine: the answer is "maybe"
        q->overflow = true;
        args->query->radius = 0.0f;
        return true;
    }
    q->tris.push_back(t);
    return false;
}

}  // namespace

int Scene::first_opaque_box(const std::vector<std::pair<Vec3, Vec3>>& boxes, double tol, const Vec3& plane_n,
                            const Vec3& plane_p, double plane_tol) const {
    if (!scene_ || boxes.empty()) return -1;
    NearTriangles q{this, Vec3(kInf, kInf, kInf), Vec3(-kInf, -kInf, -kInf), {}};
    for (const auto& [lo, hi] : boxes)
        for (int a = 0; a < 3; ++a) {
            q.lo[a] = std::min(q.lo[a], lo[a] - tol);
            q.hi[a] = std::max(q.hi[a], hi[a] + tol);
        }
    const Vec3 c = (q.lo + q.hi) * 0.5;
    RTCPointQuery pq;
    pq.x = float(c.x); pq.y = float(c.y); pq.z = float(c.z);
    pq.time = 0.0f;
    pq.radius = float(0.5 * length(q.hi - q.lo) * (1.0 + 1e-5) + eps_);
    RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(scene_, &pq, &ctx, gather_near_triangle, &q);
    if (q.overflow) return 0;
    const bool plane = plane_n.x != 0.0 || plane_n.y != 0.0 || plane_n.z != 0.0;
    size_t first = boxes.size();
    for (const auto& t : q.tris) {
        if (plane && dot(plane_n, t[0] - plane_p) <= plane_tol && dot(plane_n, t[1] - plane_p) <= plane_tol &&
            dot(plane_n, t[2] - plane_p) <= plane_tol)
            continue;  // on or behind the excluded plane
        const Vec3 nt = cross(t[1] - t[0], t[2] - t[0]);
        const double ntl = length(nt);
        for (size_t k = 0; k < first; ++k) {
            const auto& [lo, hi] = boxes[k];
            bool apart = false;
            for (int a = 0; a < 3 && !apart; ++a)
                apart = std::min({t[0][a], t[1][a], t[2][a]}) > hi[a] + tol ||
                        std::max({t[0][a], t[1][a], t[2][a]}) < lo[a] - tol;
            if (apart) continue;
            // The triangle's plane must pass through the box (grown by tol).
            const Vec3 bc = (lo + hi) * 0.5, he = (hi - lo) * 0.5;
            const double reach = std::fabs(nt.x) * he.x + std::fabs(nt.y) * he.y + std::fabs(nt.z) * he.z;
            if (std::fabs(dot(nt, bc - t[0])) <= reach + tol * ntl) {
                first = k;
                break;
            }
        }
        if (first == 0) break;
    }
    return first < boxes.size() ? int(first) : -1;
}

void Scene::set_prism_checks(BeamPrism* P, bool uniform, bool ends_on_surface) const {
    double h0 = kInf, h1 = -kInf, off = 0.0;
    for (int j = 0; j < 3; ++j) {
        h0 = std::min(h0, P->mv[j]);
        h1 = std::max(h1, P->mv[j] + P->md[j] * P->len[j]);
        off = std::max({off, offset_for(P->v[j]), offset_for(P->v[j] + P->d[j] * P->len[j])});
    }
    const double width = std::sqrt(std::max(1e-30, 0.5 * length(cross(P->v[1] - P->v[0], P->v[2] - P->v[0]))));
    const double tol = 2.0 * off;
    auto grow = [](std::pair<Vec3, Vec3>& b, const Vec3& q) {
        for (int a = 0; a < 3; ++a) {
            b.first[a] = std::min(b.first[a], q[a]);
            b.second[a] = std::max(b.second[a], q[a]);
        }
    };
    const std::pair<Vec3, Vec3> empty{Vec3(kInf, kInf, kInf), Vec3(-kInf, -kInf, -kInf)};
    std::vector<std::pair<Vec3, Vec3>> boxes;
    P->check_path = true;
    P->path_clear_below = -kInf;
    if (uniform) {
        // The region the first shadow ray can cross: the segments from the query point back
        // to the source point with the same barycentric coordinates. Those points are
        // combinations of points on the three vertex rays whose heights along m differ by at
        // most the source's spread dh, so boxes of the rays between heights ha - dh and
        // hb + dh cover each slab [ha, hb] of it. The rays' ends lie on one plane (the prism's
        // end face): an opaque triangle entirely on or behind it cannot cut the prism (the
        // floor it lights).
        const double dh = std::max({P->mv[0], P->mv[1], P->mv[2]}) - h0;
        const int n = std::clamp(int(std::ceil((h1 - h0) / width)), 1, 32);
        for (int k = 0; k < n; ++k) {
            const double ha = h0 + (h1 - h0) * k / n - dh, hb = h0 + (h1 - h0) * (k + 1) / n + dh;
            auto b = empty;
            for (int j = 0; j < 3; ++j)
                for (double h : {ha, hb}) {
                    const double t = std::clamp((h - P->mv[j]) / P->md[j], 0.0, (h1 - P->mv[j]) / P->md[j]);
                    grow(b, P->v[j] + P->d[j] * t);
                }
            boxes.push_back(b);
        }
        Vec3 pn, pp;
        if (ends_on_surface) {
            const Vec3 e0 = P->v[0] + P->d[0] * P->len[0], e1 = P->v[1] + P->d[1] * P->len[1],
                       e2 = P->v[2] + P->d[2] * P->len[2];
            pn = cross(e1 - e0, e2 - e0);
            const double l = length(pn);
            if (l > 0.0) {
                pn = pn * (1.0 / l);
                if (dot(pn, P->v[0] - e0) < 0.0) pn = -pn;  // towards the source
                pp = e0;
            } else {
                pn = Vec3();
            }
        }
        // Slab k covers the shadow rays' parts at heights in [h0 + (h1 - h0) k / n, ... (k + 1) / n]:
        // a query below the first slab an object cuts needs no ray.
        const int k = first_opaque_box(boxes, tol, pn, pp, 2.0 * off);
        P->check_path = k >= 0;
        P->path_clear_below = k > 0 ? h0 + (h1 - h0) * k / n : -kInf;
    }
    // The second shadow ray goes from the source point towards the sun: the column above the
    // source triangle, as far as it is inside the meshes' bounds.
    double t_top = 0.0;
    for (int j = 0; j < 3; ++j) {
        double t0 = 0.0, t1 = kInf;
        for (int a = 0; a < 3; ++a) {
            const double lo = meshes_lo_[a] - tol, hi = meshes_hi_[a] + tol, o = P->v[j][a], d = beam_sun_dir[a];
            if (d == 0.0) {
                if (o < lo || o > hi) t1 = -1.0;
                continue;
            }
            double ta = (lo - o) / d, tb = (hi - o) / d;
            if (ta > tb) std::swap(ta, tb);
            t0 = std::max(t0, ta);
            t1 = std::min(t1, tb);
        }
        if (t0 <= t1) t_top = std::max(t_top, t1);
    }
    boxes.clear();
    const int m = std::clamp(int(std::ceil(t_top / width)), 1, 32);
    for (int k = 0; k < m && t_top > 0.0; ++k) {
        auto b = empty;
        for (int j = 0; j < 3; ++j)
            for (double t : {t_top * k / m, t_top * (k + 1) / m}) grow(b, P->v[j] + beam_sun_dir * t);
        boxes.push_back(b);
    }
    P->check_sun = first_opaque_box(boxes, tol, Vec3(), Vec3(), 0.0) >= 0;
}

void Scene::make_keys(const LargeVector<BeamPrism>& prisms, LargeVector<PrismKey>* keys_out) {
    LargeVector<PrismKey>& keys = *keys_out;
    make_room(keys, prisms.size());
    keys.resize(prisms.size());
    for (size_t pi = 0; pi < prisms.size(); ++pi) {
        const BeamPrism& P = prisms[pi];
        PrismKey& K = keys[pi];
        K.water = P.water;
        K.horizontal = P.m.x == 0.0 && P.m.y == 0.0 && (P.m.z == -1.0 || P.m.z == 1.0);
        K.up = P.m.z == 1.0;
        K.periodic = P.periodic;
        for (int j = 0; j < 3; ++j) {  // p_j = v_j + d_j (h - mv_j) / md_j
            K.bx[j] = P.d[j].x / P.md[j];
            K.by[j] = P.d[j].y / P.md[j];
            K.ax[j] = P.v[j].x - K.bx[j] * P.mv[j];
            K.ay[j] = P.v[j].y - K.by[j] * P.mv[j];
        }
        // The blur's reach at h: blur_reach times the largest path length of the three rays,
        // t_j = h / md_j - mv_j / md_j (all md_j > 0), bounded by one line on each side of 0,
        // widened a little beyond rounding (floats).
        K.r_hi = K.r_lo = K.r_c = 0.0f;
        if (P.blur_det > 0.0) {
            double a_hi = 0.0, a_lo = kInf, c = -kInf;
            for (int j = 0; j < 3; ++j) {
                a_hi = std::max(a_hi, 1.0 / P.md[j]);
                a_lo = std::min(a_lo, 1.0 / P.md[j]);
                c = std::max(c, -P.mv[j] / P.md[j]);
            }
            const double r = 1.01 * P.blur_reach;
            K.r_hi = float(r * a_hi);
            K.r_lo = float(r * a_lo);
            K.r_c = float(r * c + (c > 0.0 ? 1e-6 * r * c : -1e-6 * r * c));
        }
    }
}

void Scene::make_disk_phases(double a, double cone) {
    // p_a(psi) = (1 / pi a^2) int over the cap of radius a around psi's direction of p: in
    // polar coordinates about the peak's tip (small angles: the cap a plane disk at distance
    // psi), the circle of radius rho lies in the cap over an angle theta(rho), so
    // p_a(psi) = (1 / pi a^2) int p(rho) rho theta(rho) d rho over |psi - a| .. psi + a,
    // p taken as 0 within the forward cone (radius `cone`).
    beam_disk_radius = a;
    disk_phase_cone_ = cone;
    disk_phase_.assign(phases.size(), {});
    if (!(a > 0.0)) {
        disk_phase_.clear();
        disk_phase_x_max_ = 0.0;
        return;
    }
    const double reach = cone + kDiskPhaseReach * a;
    disk_phase_step_ = reach / kDiskPhaseNodes;
    disk_phase_x_max_ = 2.0 * std::pow(std::sin(0.5 * reach), 2);
    const int steps = 4000;
    for (size_t pi = 0; pi < phases.size(); ++pi) {
        const PhaseFunction& ph = phases[pi];
        auto p = [&](double rho) { return rho < cone ? 0.0 : ph.eval(2.0 * std::pow(std::sin(0.5 * rho), 2)); };
        std::vector<double>& tab = disk_phase_[pi];
        tab.resize(kDiskPhaseNodes + 1);
        for (int i = 0; i <= kDiskPhaseNodes; ++i) {
            const double psi = i * disk_phase_step_;
            const double r0 = std::fabs(psi - a), r1 = psi + a;
            double sum = 0.0;
            if (psi < a) {  // the tip inside the cap: its whole circles up to a - psi
                const double h = r0 / steps;
                for (int k = 0; k < steps; ++k) {
                    const double rho = (k + 0.5) * h;
                    sum += p(rho) * rho * 2.0 * kPi * h;
                }
            }
            const double h = (r1 - r0) / steps;
            for (int k = 0; k < steps; ++k) {
                const double rho = r0 + (k + 0.5) * h;
                const double c = (rho * rho + psi * psi - a * a) / (2.0 * rho * std::max(psi, 1e-300));
                const double theta = psi > 0.0 ? 2.0 * std::acos(std::clamp(c, -1.0, 1.0)) : 2.0 * kPi;
                sum += p(rho) * rho * theta * h;
            }
            tab[i] = sum / (kPi * a * a);
        }
        // (joined to the phase function at the table's end: the cap's mean differs from the
        // value there by ~(a / psi)^2 of it, 1e-2 at most; scaled so that nothing jumps)
        const double end = p(reach), last = tab[kDiskPhaseNodes];
        for (int i = 0; i <= kDiskPhaseNodes && last > 0.0; ++i) {
            const double f = double(i) / kDiskPhaseNodes;
            tab[i] *= 1.0 + f * f * (end / last - 1.0);
        }
    }
}

double Scene::disk_phase_eval(int phase, double x) const {
    const double psi = 2.0 * std::asin(std::sqrt(0.5 * std::max(0.0, x)));
    const double u = psi / disk_phase_step_;
    const int i = std::min(int(u), kDiskPhaseNodes - 1);
    const double t = u - i;
    const std::vector<double>& tab = disk_phase_[size_t(phase)];
    return tab[size_t(i)] + t * (tab[size_t(i) + 1] - tab[size_t(i)]);
}

void Scene::blur_margins(const LargeVector<BeamPrism>& prisms, const LargeVector<PrismKey>& keys) {
    // A horizontally sliced prism's blur reaches R(h) <= r_hi |h| + max(r_c, 0) across, and
    // |h| = |z|; a prism sliced otherwise: its reach at the farthest end of its rays.
    blur_margin_a_.assign(prisms.size(), 0.0);
    blur_margin_g_.assign(prisms.size(), 0.0);
    for (size_t pi = 0; pi < prisms.size(); ++pi) {
        const BeamPrism& P = prisms[pi];
        const PrismKey& K = keys[pi];
        if (P.blur_det <= 0.0) continue;
        if (K.horizontal) {
            blur_margin_a_[pi] = std::max(0.0, double(K.r_c));
            blur_margin_g_[pi] = std::max(0.0, double(K.r_hi));
        } else {
            const double l = std::max({P.len[0], P.len[1], P.len[2], 0.0});
            blur_margin_a_[pi] = 1.001 * P.blur_reach * l;
        }
    }
}

void Scene::grid_shear(const LargeVector<PrismKey>& keys, double* sx, double* sy) {
    // The grid is sheared along the beams' typical drift (sx, sy) per metre of depth (the
    // median over the horizontally sliced prisms' rays): in coordinates u = x + sx z,
    // v = y + sy z, z a prism stands nearly upright, so cells can be tall (few marks per
    // prism) and narrow (few candidates per query) at once. (A key's b is the drift per unit
    // of h: h = -z going down, z going up.)
    std::vector<double> bxs, bys;
    for (const PrismKey& K : keys)
        if (K.horizontal) {
            bxs.push_back(K.up ? -K.bx[0] : K.bx[0]);
            bys.push_back(K.up ? -K.by[0] : K.by[0]);
        }
    auto median = [](std::vector<double>& v) {
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        return v[v.size() / 2];
    };
    *sx = bxs.empty() ? 0.0 : median(bxs);
    *sy = bys.empty() ? 0.0 : median(bys);
}

void Scene::build_grid(const LargeVector<BeamPrism>& prisms, const LargeVector<PrismKey>& keys, BeamGrid* grid_out,
                       const double* margin_a, const double* margin_g, const std::atomic<bool>* cancel) {
    BeamGrid& grid = *grid_out;
    grid.clear();
    if (prisms.empty()) return;
    auto check_cancel = [cancel](size_t pi) {  // (every 4,096 prisms)
        if (cancel && (pi & 4095) == 0 && cancel->load(std::memory_order_relaxed)) throw BuildCancelled{};
    };
    double sx, sy;
    grid_shear(keys, &sx, &sy);
    auto dxdz = [](const PrismKey& K, int j) { return K.up ? K.bx[j] : -K.bx[j]; };
    auto dydz = [](const PrismKey& K, int j) { return K.up ? K.by[j] : -K.by[j]; };
    auto median = [](std::vector<double>& v) {
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        return v[v.size() / 2];
    };
    grid.sx = sx;
    grid.sy = sy;
    // Each prism is cut into pieces along its slicing axis; the box (in the sheared frame) of
    // each piece's six corner points marks its cells. The slice at h (what prism_eval takes:
    // the triangle of the vertex rays at h, even before a ray's start or beyond its end, cut
    // by the source's plane and by the end face) lies in the triangle of its corners, which
    // move linearly with h, so the convex hull of the corners at ha and hb, and its box,
    // contains every slice between (the shear, being linear, keeps that). The corners are not
    // clamped to the rays' spans: where one ray ends before the others (on a wall), the slice
    // reaches beyond its end (clamped corners lost beams there, beside the stepped pool's walls).
    auto piece = [&](const BeamPrism& P, double ha, double hb, Vec3* blo, Vec3* bhi) {
        *blo = Vec3(kInf, kInf, kInf);
        *bhi = Vec3(-kInf, -kInf, -kInf);
        for (int j = 0; j < 3; ++j)
            for (double h : {ha, hb}) {
                const double t = (h - P.mv[j]) / P.md[j];
                Vec3 q = P.v[j] + P.d[j] * t;
                q = Vec3(q.x + sx * q.z, q.y + sy * q.z, q.z);
                *blo = Vec3(std::min(blo->x, q.x), std::min(blo->y, q.y), std::min(blo->z, q.z));
                *bhi = Vec3(std::max(bhi->x, q.x), std::max(bhi->y, q.y), std::max(bhi->z, q.z));
            }
    };
    auto span = [](const BeamPrism& P, double* h0, double* h1) {
        *h0 = kInf;
        *h1 = -kInf;
        for (int j = 0; j < 3; ++j) {
            *h0 = std::min(*h0, P.mv[j]);
            *h1 = std::max(*h1, P.mv[j] + P.md[j] * P.len[j]);
        }
    };
    // How far prism pi's boxes are widened across, for a piece at heights z in [za, zb].
    auto margin = [&](size_t pi, double za, double zb) {
        return margin_a ? margin_a[pi] + margin_g[pi] * std::max(std::fabs(za), std::fabs(zb)) : 0.0;
    };
    Vec3 lo(kInf, kInf, kInf), hi(-kInf, -kInf, -kInf);
    std::vector<double> widths, drifts;
    for (size_t pi = 0; pi < prisms.size(); ++pi) {
        check_cancel(pi);
        const BeamPrism& P = prisms[pi];
        double h0, h1;
        span(P, &h0, &h1);
        Vec3 blo, bhi;
        piece(P, h0, h1, &blo, &bhi);
        lo = Vec3(std::min(lo.x, blo.x), std::min(lo.y, blo.y), std::min(lo.z, blo.z));
        hi = Vec3(std::max(hi.x, bhi.x), std::max(hi.y, bhi.y), std::max(hi.z, bhi.z));
        widths.push_back(std::sqrt(std::max(1e-30, 0.5 * length(cross(P.v[1] - P.v[0], P.v[2] - P.v[0])))));
        const PrismKey& K = keys[pi];
        if (K.horizontal) {  // how far its rays drift from the shear per metre of depth
            double dr = 0.0;
            for (int j = 0; j < 3; ++j) dr = std::max(dr, std::hypot(-dxdz(K, j) - sx, -dydz(K, j) - sy));
            drifts.push_back(dr);
        }
    }
    double width = median(widths);
    if (margin_a) {
        // Cells at least as wide as the typical margin at the grid's deepest point: a margin
        // many cells wide marks (margin / cell)^2 cells per prism and layer (the sun-disk blur
        // under a 1 mm patch: gigabytes of marks before the copies' bound could refuse it).
        const double zdeep = std::max(std::fabs(lo.z), std::fabs(hi.z));
        std::vector<double> margins(prisms.size());
        for (size_t pi = 0; pi < prisms.size(); ++pi) margins[pi] = margin(pi, zdeep, zdeep);
        width = std::max(width, median(margins));
    }
    const double drift = drifts.empty() ? 1.0 : median(drifts);
    if (margin_a) {  // widened by the largest margin of any layer (layers reach a cell beyond)
        const double zmax = std::max(std::fabs(lo.z), std::fabs(hi.z)) + (hi.z - lo.z);
        double m = 0.0;
        for (size_t pi = 0; pi < prisms.size(); ++pi) m = std::max(m, margin(pi, zmax, zmax));
        lo = lo - Vec3(m, m, 0.0);
        hi = hi + Vec3(m, m, 0.0);
    }
    Vec3 ext = hi - lo;
    // Cells: across, a typical prism's width; tall enough that a typical prism drifts by half
    // of that in one cell (narrower or shorter cells: no faster in the stepped pool). Not so
    // small that the grid has more than ~32 cells per prism (long, tilted prisms of grazing
    // suns would fill it otherwise).
    double cxy = std::max(width, 1e-6);
    double cz = std::clamp(0.5 * width / std::max(drift, 1e-9), cxy, std::max(cxy, ext.z));
    const double volume = std::max(1e-30, ext.x * ext.y * ext.z);
    const double min_cell = std::cbrt(volume / (32.0 * prisms.size()));
    if (cxy * cxy * cz < min_cell * min_cell * min_cell) {
        const double f = min_cell / std::cbrt(cxy * cxy * cz);
        cxy *= f;
        cz *= f;
    }
    auto cells = [&]() {
        return (std::floor(ext.x / cxy) + 1) * (std::floor(ext.y / cxy) + 1) * (std::floor(ext.z / cz) + 1);
    };
    while (cells() > double(1 << 21)) {
        cxy *= 1.25;
        cz *= 1.25;
    }
    grid.lo = lo;
    grid.cell = Vec3(cxy, cxy, cz);
    grid.inv_cell = Vec3(1.0 / cxy, 1.0 / cxy, 1.0 / cz);
    grid.nx = int(std::floor(ext.x / cxy)) + 1;
    grid.ny = int(std::floor(ext.y / cxy)) + 1;
    grid.nz = int(std::floor(ext.z / cz)) + 1;
    size_t ncell = size_t(grid.nx) * grid.ny * grid.nz;
    // The cells of a layer that the convex hull of points q (the sheared x, y of a piece's
    // corners) meets, the hull widened by m: row by row (row(r, x0, x1)), the hull's extent
    // across within the row (its edges clipped to the row), where the piece's box marked whole
    // rectangles (a slice, a triangle, fills about half of its box).
    auto hull_rows = [&](std::array<std::array<double, 2>, 6> q, double m, auto&& row) {
        for (int i = 1; i < 6; ++i)  // (sorted by x, then y: insertion sort)
            for (int j = i; j > 0 && q[j] < q[j - 1]; --j) std::swap(q[j], q[j - 1]);
        std::array<std::array<double, 2>, 12> h;  // Andrew's monotone chain
        auto turn = [](const std::array<double, 2>& o, const std::array<double, 2>& a,
                       const std::array<double, 2>& b) {
            return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
        };
        int nh = 0;
        for (int i = 0; i < 6; ++i) {
            while (nh >= 2 && turn(h[nh - 2], h[nh - 1], q[i]) <= 0.0) --nh;
            h[nh++] = q[i];
        }
        for (int i = 4, lower = nh + 1; i >= 0; --i) {
            while (nh >= lower && turn(h[nh - 2], h[nh - 1], q[i]) <= 0.0) --nh;
            h[nh++] = q[i];
        }
        nh = std::max(1, nh - 1);  // (the last point is the first)
        // Per edge: its heights' range across (y) and x as a linear function of y there.
        double ey0[6], ey1[6], ex0[6], ex1[6], slope[6];
        double ylo = kInf, yhi = -kInf;
        for (int i = 0; i < nh; ++i) {
            const auto& a = h[i];
            const auto& b = h[(i + 1) % nh];
            const bool up = a[1] <= b[1];
            ey0[i] = up ? a[1] : b[1];
            ey1[i] = up ? b[1] : a[1];
            ex0[i] = up ? a[0] : b[0];
            ex1[i] = up ? b[0] : a[0];
            slope[i] = ey1[i] > ey0[i] ? (ex1[i] - ex0[i]) / (ey1[i] - ey0[i]) : 0.0;
            ylo = std::min(ylo, ey0[i]);
            yhi = std::max(yhi, ey1[i]);
        }
        const double eps = 1e-9 * (cxy + std::fabs(lo.x) + std::fabs(lo.y));
        const double inv = 1.0 / cxy;  // (cells by multiplications: the hull is widened by eps)
        const int r0 = std::clamp(int((ylo - m - eps - lo.y) * inv), 0, grid.ny - 1);
        const int r1 = std::clamp(int((yhi + m + eps - lo.y) * inv), 0, grid.ny - 1);
        for (int r = r0; r <= r1; ++r) {
            const double b0 = lo.y + r * cxy - m - eps, b1 = lo.y + (r + 1) * cxy + m + eps;
            double xmin = kInf, xmax = -kInf;
            for (int i = 0; i < nh; ++i) {  // each edge's part within the row
                const double y0 = std::max(b0, ey0[i]), y1 = std::min(b1, ey1[i]);
                if (y0 > y1) continue;
                const double xa = ey1[i] > ey0[i] ? ex0[i] + slope[i] * (y0 - ey0[i]) : ex0[i];
                const double xb = ey1[i] > ey0[i] ? ex0[i] + slope[i] * (y1 - ey0[i]) : ex1[i];
                xmin = std::min({xmin, xa, xb});
                xmax = std::max({xmax, xa, xb});
            }
            if (!(xmin <= xmax)) continue;
            // (widened by the rounding of the edges' slopes: eps per cell of height)
            const double w = m + eps * (1.0 + (b1 - b0) / cxy);
            const int x0 = std::clamp(int((xmin - w - lo.x) * inv), 0, grid.nx - 1);
            const int x1 = std::clamp(int((xmax + w - lo.x) * inv), 0, grid.nx - 1);
            row(r, x0, x1);
        }
    };

    // A point's layer of cells is floor((z - lo.z) / cz): the pieces of horizontally sliced
    // prisms are the parts between those layers' planes (widened far beyond rounding), each
    // marking cells of its own layer only. layer_piece: prism pi's piece in layer k, its six
    // corners in the sheared frame and its margin (false: none).
    const double pad = 1e-9 * (cz + std::fabs(lo.z) + std::fabs(hi.z));
    auto layers_of = [&](size_t pi, int* k0, int* k1) {
        double h0, h1;
        span(prisms[pi], &h0, &h1);
        const bool up = keys[pi].up;  // h = z going up, -z going down
        const double zlo = up ? h0 : -h1, zhi = up ? h1 : -h0;
        *k0 = std::clamp(int(std::floor((zlo - lo.z) / cz)), 0, grid.nz - 1);
        *k1 = std::clamp(int(std::floor((zhi - lo.z) / cz)), 0, grid.nz - 1);
    };
    // (With margins, for the shared grid, the whole layer: another pass's prism may reach a
    // little beyond this one's span.)
    auto layer_piece = [&](size_t pi, int k, std::array<std::array<double, 2>, 6>* q, double* m) {
        const BeamPrism& P = prisms[pi];
        double h0, h1;
        span(P, &h0, &h1);
        if (margin_a) {
            h0 = -kInf;
            h1 = kInf;
        }
        const bool up = keys[pi].up;
        const double za = lo.z + k * cz - pad, zb = lo.z + (k + 1) * cz + pad;
        const double ha = std::max(h0, up ? za : -zb), hb = std::min(h1, up ? zb : -za);
        if (!(ha <= hb)) return false;
        // (the corners piece() takes, from the key: x = ax + bx h, y = ay + by h, z = -h going
        // down; the hull is widened far beyond the rounding that differs)
        const PrismKey& K = keys[pi];
        const double sz = up ? 1.0 : -1.0;
        for (int j = 0; j < 3; ++j)
            for (int e = 0; e < 2; ++e) {
                const double h = e ? hb : ha;
                (*q)[2 * j + e] = {K.ax[j] + (K.bx[j] + sz * sx) * h, K.ay[j] + (K.by[j] + sz * sy) * h};
            }
        *m = margin(pi, za, zb);
        return true;
    };
    // A cell lists its prisms in prism order, so that a point's beams are summed in prism
    // order whatever the cells. The arrays keep their memory from pass to pass: fresh ones
    // cost a page fault and a zeroed page per 4 kB, a fifth of a build's time.
    make_room(grid.start, ncell + 1);
    bool all_horizontal = true;
    for (const PrismKey& K : keys) all_horizontal = all_horizontal && K.horizontal;
    if (all_horizontal) {
        // Layer by layer, each piece's marks made once and sorted by cell in the layer (a
        // counting sort, stable: prism order), the layer's counts in the cache.
        std::vector<int> k0(prisms.size()), k1(prisms.size());
        for (size_t pi = 0; pi < prisms.size(); ++pi) layers_of(pi, &k0[pi], &k1[pi]);
        grid.start.resize(ncell + 1);
        const size_t nlayer = size_t(grid.nx) * grid.ny;
        std::vector<uint32_t> count(nlayer + 1);
        LargeVector<uint64_t>& marks = grid.marks;  // (cell in the layer << 32 | prism)
        grid.items.clear();
        for (int k = 0; k < grid.nz; ++k) {
            marks.clear();
            for (size_t pi = 0; pi < prisms.size(); ++pi) {
                check_cancel(pi);
                std::array<std::array<double, 2>, 6> q;
                double m;
                if (k < k0[pi] || k > k1[pi] || !layer_piece(pi, k, &q, &m)) continue;
                hull_rows(q, m, [&](int r, int x0, int x1) {
                    for (int x = x0; x <= x1; ++x) marks.push_back(uint64_t(size_t(r) * grid.nx + x) << 32 | pi);
                });
            }
            std::fill(count.begin(), count.end(), 0u);
            for (uint64_t mk : marks) count[(mk >> 32) + 1]++;
            for (size_t c = 0; c < nlayer; ++c) count[c + 1] += count[c];
            const size_t base = grid.items.size();
            for (size_t c = 0; c < nlayer; ++c) grid.start[size_t(k) * nlayer + c] = uint32_t(base + count[c]);
            make_room(grid.items, base + marks.size());
            grid.items.resize(base + marks.size());
            for (uint64_t mk : marks) grid.items[base + count[mk >> 32]++] = uint32_t(mk);
        }
        grid.start[ncell] = uint32_t(grid.items.size());
    } else {
        // The (cell, prism) marks visited twice in prism order, to count each cell's and then
        // to fill them (a counting sort without storing the marks).
        auto for_each_mark = [&](auto&& mark) {
            make_room(grid.last, ncell);
            grid.last.assign(ncell, ~uint32_t(0));
            for (size_t pi = 0; pi < prisms.size(); ++pi) {
                check_cancel(pi);
                const BeamPrism& P = prisms[pi];
                if (keys[pi].horizontal) {
                    int k0, k1;
                    layers_of(pi, &k0, &k1);
                    for (int k = k0; k <= k1; ++k) {
                        std::array<std::array<double, 2>, 6> q;
                        double m;
                        if (!layer_piece(pi, k, &q, &m)) continue;
                        // (each cell once: a prism's layers and rows are visited once each)
                        hull_rows(q, m, [&](int r, int x0, int x1) {
                            for (int x = x0; x <= x1; ++x) mark((size_t(k) * grid.ny + r) * grid.nx + x, uint32_t(pi));
                        });
                    }
                    continue;
                }
                // pieces about a cell wide (grazing beams), their boxes' cells
                double h0, h1;
                span(P, &h0, &h1);
                const int pieces = std::max(1, std::min(100000, int(std::ceil((h1 - h0) / cxy))));
                for (int k = 0; k < pieces; ++k) {
                    double ha = h0 + (h1 - h0) * k / pieces, hb = h0 + (h1 - h0) * (k + 1) / pieces;
                    Vec3 blo, bhi;
                    piece(P, ha, hb, &blo, &bhi);
                    const double m = margin(pi, blo.z, bhi.z);
                    const int x0 = std::clamp(int((blo.x - m - lo.x) / cxy), 0, grid.nx - 1);
                    const int x1 = std::clamp(int((bhi.x + m - lo.x) / cxy), 0, grid.nx - 1);
                    const int y0 = std::clamp(int((blo.y - m - lo.y) / cxy), 0, grid.ny - 1);
                    const int y1 = std::clamp(int((bhi.y + m - lo.y) / cxy), 0, grid.ny - 1);
                    const int z0 = std::clamp(int((blo.z - m - lo.z) / cz), 0, grid.nz - 1);
                    const int z1 = std::clamp(int((bhi.z + m - lo.z) / cz), 0, grid.nz - 1);
                    for (int z = z0; z <= z1; ++z)
                        for (int y = y0; y <= y1; ++y)
                            for (int x = x0; x <= x1; ++x) {
                                const size_t c = (size_t(z) * grid.ny + y) * grid.nx + x;
                                if (grid.last[c] == uint32_t(pi)) continue;
                                grid.last[c] = uint32_t(pi);
                                mark(c, uint32_t(pi));
                            }
                }
            }
        };
        make_room(grid.fill, ncell);
        grid.start.assign(ncell + 1, 0);
        for_each_mark([&](size_t c, uint32_t) { grid.start[c + 1]++; });
        for (size_t c = 0; c < ncell; ++c) grid.start[c + 1] += grid.start[c];
        make_room(grid.items, grid.start[ncell]);
        grid.items.resize(grid.start[ncell]);
        grid.fill.assign(grid.start.begin(), grid.start.end() - 1);
        for_each_mark([&](size_t c, uint32_t pi) { grid.items[grid.fill[c]++] = pi; });
    }
    make_room(grid.cells, ncell * BeamGrid::kCellWords);
    grid.cells.assign(ncell * BeamGrid::kCellWords, 0);
    for (size_t c = 0; c < ncell; ++c) {
        uint32_t* rec = &grid.cells[c * BeamGrid::kCellWords];
        const uint32_t count = grid.start[c + 1] - grid.start[c];
        rec[0] = count;
        rec[1] = grid.start[c];
        for (uint32_t q = 0; q < count && q < uint32_t(BeamGrid::kInline); ++q) rec[2 + q] = grid.items[grid.start[c] + q];
    }
}

bool Scene::prism_eval(const BeamPrism& P, const Vec3& y, const Vec3& world, BeamSample* out,
                       bool exact) const {
    // The slice through y: its corners p_j on the vertex rays (at t_j), its area S along m
    // and y's barycentric coordinates l_j in it.
    double t[3], S, l0, l1, h;
    Vec3 off[3];  // the slice's corners relative to y (for the blur)
    if (P.m.x == 0.0 && P.m.y == 0.0) {
        // Horizontal slices (most prisms): only the z components of the products along m are
        // nonzero; the same operations as the general case's on them, so the same results.
        const double mz = P.m.z;
        h = mz * y.z;
        double px[3], py[3];
        for (int j = 0; j < 3; ++j) {
            t[j] = (h - P.mv[j]) / P.md[j];
            px[j] = P.v[j].x + P.d[j].x * t[j];
            py[j] = P.v[j].y + P.d[j].y * t[j];
        }
        auto cross_z = [](double ax, double ay, double bx, double by) { return ax * by - ay * bx; };
        S = 0.5 * (cross_z(px[1] - px[0], py[1] - py[0], px[2] - px[0], py[2] - py[0]) * mz);
        if (S == 0.0) return false;
        l0 = 0.5 * (cross_z(px[1] - y.x, py[1] - y.y, px[2] - y.x, py[2] - y.y) * mz) / S;
        l1 = 0.5 * (cross_z(px[2] - y.x, py[2] - y.y, px[0] - y.x, py[0] - y.y) * mz) / S;
        for (int j = 0; j < 3; ++j) off[j] = Vec3(px[j] - y.x, py[j] - y.y, 0.0);
    } else {
        h = dot(P.m, y);
        Vec3 p[3];
        for (int j = 0; j < 3; ++j) {
            t[j] = (h - P.mv[j]) / P.md[j];
            p[j] = P.v[j] + P.d[j] * t[j];
        }
        S = 0.5 * dot(cross(p[1] - p[0], p[2] - p[0]), P.m);
        if (S == 0.0) return false;
        l0 = 0.5 * dot(cross(p[1] - y, p[2] - y), P.m) / S;
        l1 = 0.5 * dot(cross(p[2] - y, p[0] - y), P.m) / S;
        for (int j = 0; j < 3; ++j) off[j] = p[j] - y;
    }
    double l2 = 1.0 - l0 - l1;
    const double tol = -1e-12;
    const bool inside = !(l0 < tol || l1 < tol || l2 < tol);
    // With the sun's disk (blur_det > 0): the slice's light spread over the disk's image, an
    // ellipse K around each of its points. At y: flux x area(slice within K(y)) / (S area(K)),
    // i.e. the flux over a_blur = area(K) S / area(slice within K), computed where K is the
    // unit disk (ratios of areas are kept). Where K lies within the slice, the sharp value.
    double a_blur = 0.0;
    if (P.blur_det > 0.0 && exact) {  // (a ranking takes the prism sharp: see beams_at)
        // the blur at the path length of the slice's point nearest y (barycentric coordinates
        // clamped), which also gives the light's direction and path below when y is outside
        const double c0 = std::max(l0, 0.0), c1 = std::max(l1, 0.0), c2 = std::max(l2, 0.0);
        const double cs = c0 + c1 + c2;
        const double lb = (c0 * t[0] + c1 * t[1] + c2 * t[2]) / cs;
        if (!(lb > 0.0)) {
            if (!inside) return false;
        } else {
            double u[3], v[3];
            for (int j = 0; j < 3; ++j) {
                u[j] = dot(off[j], P.blur_g1) / lb;
                v[j] = dot(off[j], P.blur_g2) / lb;
            }
            const double at = 0.5 * std::fabs((u[1] - u[0]) * (v[2] - v[0]) - (u[2] - u[0]) * (v[1] - v[0]));
            const double overlap = std::min(unit_disk_triangle_overlap(u, v), at);
            if (!(overlap > 0.0)) return false;
            if (overlap < kPi) {  // (kPi exactly: the disk within the slice)
                a_blur = kPi * P.blur_det * lb * lb * at / overlap;
                l0 = c0 / cs;
                l1 = c1 / cs;
                l2 = c2 / cs;
            }
        }
    } else if (!inside) {
        return false;
    }
    double l = l0 * t[0] + l1 * t[1] + l2 * t[2];
    double lend = l0 * P.len[0] + l1 * P.len[1] + l2 * P.len[2];
    if (l < 0.0 || l > lend) return false;
    // on the wrong side of the source surface (in the air, or in the water for a reflected beam)
    if (P.reflected ? dot(y - P.v[0], P.n_src) < 0.0 : dot(y - P.v[0], P.n_src) > 0.0) return false;
    Vec3 d = normalize(P.d[0] * l0 + P.d[1] * l1 + P.d[2] * l2);
    double md = dot(P.m, d);
    if (!(md > 0.0)) return false;
    // Lower bound of the cross-section, so that foci stay finite. The sun's finite size is
    // what bounds real foci: with the blur, a_blur is at least the disk image's area; without
    // it (a rough sea), a direction drawn in the disk for every pass, and the average over
    // passes blurs each focus over the sun's image. Within one pass the cross-section is only
    // kept above a tiny fraction of the source cell's area (beam_min_area_fraction, 1e-6):
    // irradiance at most 1e6 times the cell's, and the flux lost in slices thinner than that
    // is negligible (flux conservation is tested to 1e-5).
    double a_eff = a_blur > 0.0 ? a_blur : std::max(std::fabs(S), beam_min_area_fraction * P.src_area);
    if (P.check_path || P.check_sun) {
        // The light reaching y entered the water at e, the point of the source triangle with
        // y's barycentric coordinates (exactly on the surface, so the shadow rays start on the
        // right side of it: a point extrapolated back along d lies above or below a wavy
        // surface by more than the offsets, which dropped half the beams).
        const Vec3 shift = world - y;
        const Vec3 e = P.v[0] * l0 + P.v[1] * l1 + P.v[2] * l2 + shift;
        const Vec3 to_e = e - world;
        const double dist = length(to_e);
        const double off = std::max(offset_for(world), offset_for(e));
        if (P.check_path && dist > 0.0 && !(h < P.path_clear_below)) {
            const Vec3 u = to_e * (1.0 / dist);
            // Periodic prisms: only the meshes can block (the surface and bottom repeat with
            // the prism). A water mesh's prism: everything but its own source face.
            if (P.periodic ? meshes_block(world, u, 0.0, dist - off)
                           : occluded_segment(world, u, std::max(0.0, dist - 2.0 * off)))
                return false;
        }
        const Vec3 q = e + P.n_src * off;
        if (!P.check_sun) {
        } else if (P.periodic) {
            if (meshes_block(q, beam_sun_dir, 0.0, kInf)) return false;
            // Wave-shaded corners: the surface's own shadow (else the build's lit test says).
            if (P.partial_lit && occluded_ocean(q, beam_sun_dir, Side::kAbove)) return false;
        } else if (occluded(q, beam_sun_dir)) {
            return false;
        }
    }
    out->d = d;
    out->l = l;
    out->spread = P.blur_det > 0.0;
    if (P.water < 0) {  // reflected into the air: nothing attenuates it
        for (int k = 0; k < nbands; ++k) out->e.v[k] = P.phi.v[k] / (a_eff * md);
        return true;
    }
    // Attenuated along the beam's straight path from the surface (y - d l) to y.
    double att[kMaxBands];
    waters[P.water].transmittance(y - d * l, y, l, nbands, att, exact);
    for (int k = 0; k < nbands; ++k) out->e.v[k] = P.phi.v[k] * att[k] / (a_eff * md);
    return true;
}

int Scene::beams_at(const Vec3& x, int medium, BeamSample* out, int max, bool exact) const {
    if (max <= 0) return 0;
    const int n = flat_beams_at(x, medium, out, max, exact);
    if (medium < 0) return lookup(air_prisms, air_keys_, air_grid_, x, -1, out, n, max, exact);
    return lookup(prisms, prism_keys_, *water_grid_, x, medium, out, n, max, exact);
}

int Scene::flat_beams_at(const Vec3& x, int medium, BeamSample* out, int max, bool exact) const {
    int n = 0;
    if (medium < 0) {  // the reflected sun in the air
        if (flat_air_beam && x.z > ocean_z) {
            const double l = (x.z - ocean_z) / flat_air_d.z;
            bool visible = true;
            if (!meshes.empty()) {
                const double off = offset_for(x);
                visible = !occluded_segment(x, -flat_air_d, std::max(0.0, l - 2.0 * off)) &&
                          !occluded(x - flat_air_d * l + Vec3(0, 0, off), beam_sun_dir);
            }
            if (visible) {
                out[n].d = flat_air_d;
                out[n].e = flat_air_e;
                out[n].l = l;
                out[n].spread = false;
                ++n;
            }
        }
        return n;
    }
    if (flat_beam && medium == ocean_water && x.z < ocean_z && (!has_bottom || x.z > bottom_z)) {
        const Water& w = waters[medium];
        for (size_t i = 0; i < flat_d.size() && n < max; ++i) {
            const Vec3& fd = flat_d[i];
            double l = (ocean_z - x.z) / (-fd.z);
            bool visible = true;
            if (!meshes.empty()) {
                double off = offset_for(x);
                visible = !occluded_segment(x, -fd, std::max(0.0, l - 2.0 * off));
                if (visible) visible = !occluded(x - fd * l + Vec3(0, 0, off), beam_sun_dir);
            }
            if (visible) {
                out[n].d = fd;
                out[n].l = l;
                out[n].spread = false;
                // Attenuated from the surface down to x. In gridded water only the part of the
                // ray between the heights where it may meet density is walked (none if it
                // meets none: the shadow map of the beams' directions says).
                double r[VoxelGrid::kMaxFields];
                const double* integral = nullptr;
                if (w.grid && exact) {
                    std::fill_n(r, VoxelGrid::kMaxFields, 0.0);
                    double z0 = -kInf, z1 = kInf;
                    if (i >= flat_shade_ok.size() || !flat_shade_ok[i] || flat_shade.meets(x, &z0, &z1)) {
                        const double za = std::max(x.z, z0), zb = std::min(ocean_z, z1);
                        const double la = (za - x.z) / (-fd.z), lb = (zb - x.z) / (-fd.z);
                        w.grid->integral(x - fd * lb, x - fd * la, lb - la, r);
                    }
                    integral = r;
                }
                const Vec3 entry(x.x - fd.x * l, x.y - fd.y * l, ocean_z);
                double att[kMaxBands];
                w.transmittance(entry, x, l, nbands, att, exact, integral);
                for (int k = 0; k < nbands; ++k) out[n].e.v[k] = flat_e0[i].v[k] * att[k];
                ++n;
            }
        }
    }
    return n;
}

namespace {

// Whether prism key K may cover y (primary-patch frame) for a query in `medium`; `shifted`: y
// was moved from another period of the ocean patch. For horizontally sliced prisms, the
// slice's corners and y's edge functions: prism_eval's barycentric test with a tolerance a
// thousand times looser (rounding of the corners here differs from its own by ~1e-16
// relative), so that it never rejects what prism_eval would accept.
template <class Key>
inline bool may_cover(const Key& K, const Vec3& y, int medium, bool shifted, bool blurred) {
    if (K.water != medium) return false;
    if (shifted && !K.periodic) return false;
    if (!K.horizontal) return true;
    const double h = K.up ? y.z : -y.z;
    double px[3], py[3];
    for (int q = 0; q < 3; ++q) {
        px[q] = K.ax[q] + K.bx[q] * h;
        py[q] = K.ay[q] + K.by[q] * h;
    }
    const double C = (px[1] - px[0]) * (py[2] - py[0]) - (px[2] - px[0]) * (py[1] - py[0]);
    if (C == 0.0) return true;
    const double c0 = (px[1] - y.x) * (py[2] - y.y) - (px[2] - y.x) * (py[1] - y.y);
    const double c1 = (px[2] - y.x) * (py[0] - y.y) - (px[0] - y.x) * (py[2] - y.y);
    const double tol = -1e-9 * std::fabs(C);
    const double s0 = C > 0.0 ? c0 : -c0, s1 = C > 0.0 ? c1 : -c1;
    const double s2 = (C > 0.0 ? C : -C) - s0 - s1;
    if (!(s0 < tol || s1 < tol || s2 < tol)) return true;
    if (!blurred) return false;
    // Outside: a blurred prism still reaches y within R of every edge's line (s_k is twice
    // the area of y and edge k: R |edge k| at that distance).
    const double R = double(h >= 0.0 ? K.r_hi : K.r_lo) * h + double(K.r_c);
    if (!(R > 0.0)) return false;
    const double R2 = R * R;
    auto near = [&](double sk, int a, int b) {
        const double eu = px[b] - px[a], ev = py[b] - py[a];
        return sk >= tol || sk * sk <= R2 * (eu * eu + ev * ev) * (1.0 + 1e-9);
    };
    return near(s0, 1, 2) && near(s1, 2, 0) && near(s2, 0, 1);
}

}  // namespace

double Scene::sun_rehit_fraction(const Vec3& s, double ior, int threads) const {
    if (ocean_water < 0 || ocean_flat) return 0.0;
    // At most kFaces faces, spread over the patch by a stride coprime with the face count (a
    // share, not an image: 65,536 faces put it within about 0.5 % of the whole patch's, and a
    // 2048 x 2048 patch's 8 million would cost seconds per render).
    const size_t nt = patch_triangles.size() / 3;
    constexpr size_t kFaces = size_t(1) << 16;
    const size_t nf = std::min(nt, kFaces);
    const uint64_t stride = nt > kFaces ? 2654435761u : 1u;  // (a prime above any face count)
    const size_t kBlock = 1024, nblock = (nf + kBlock - 1) / kBlock;
    std::vector<double> carried(nblock, 0.0), missed(nblock, 0.0);
    parallel_for(nblock, threads, [&](size_t b, int) {
        for (size_t f = b * kBlock; f < std::min(nf, (b + 1) * kBlock); ++f) {
            const size_t i = size_t((uint64_t(f) * stride) % uint64_t(nt));
            Vec3 p[3];
            for (int j = 0; j < 3; ++j) {
                const size_t k = patch_triangles[3 * i + j];
                p[j] = Vec3(patch_vertices[3 * k], patch_vertices[3 * k + 1], patch_vertices[3 * k + 2]);
            }
            const Vec3 c = cross(p[1] - p[0], p[2] - p[0]);
            const double twice_area = length(c);
            if (!(twice_area > 0.0)) continue;
            const Vec3 n = c * ((c.z >= 0.0 ? 1.0 : -1.0) / twice_area);
            const double cs = dot(n, s);
            if (!(cs > 0.0)) continue;
            const double R = fresnel_unpolarized(cs, 1.0, ior), w = cs * twice_area;
            const Vec3 o = (p[0] + p[1] + p[2]) * (1.0 / 3.0);
            const double off = offset_for(o);
            Hit h;
            if (intersect_patch(o + n * off, n * (2.0 * cs) - s, kInf, &h, Side::kAbove)) missed[b] += w * R;
            Vec3 t;
            if (!refract(-s, n, 1.0, ior, &t)) continue;
            carried[b] += w * (1.0 - R);
            const double tmax = has_bottom && t.z < 0.0 ? (bottom_z - o.z) / t.z : kInf;
            if (intersect_patch(o - n * off, t, tmax, &h, Side::kBelow)) missed[b] += w * (1.0 - R);
        }
    });
    double in = 0.0, out = 0.0;
    for (size_t b = 0; b < nblock; ++b) {
        in += carried[b];
        out += missed[b];
    }
    return in > 0.0 ? out / in : 0.0;
}

double Scene::beam_patch_copies() const {
    if (ocean_water < 0 || ocean_flat) return 1.0;
    auto copies = [&](const BeamGrid& g) {
        if (g.nx == 0) return 1.0;  // as find_candidates' range of periods (i0..i1, j0..j1)
        return (std::floor(g.nx * g.cell.x / patch_lx) + 1.0) * (std::floor(g.ny * g.cell.y / patch_ly) + 1.0);
    };
    return std::max(water_grid_ ? copies(*water_grid_) : 1.0, copies(air_grid_));
}

int Scene::lookup(const LargeVector<BeamPrism>& prisms, const LargeVector<PrismKey>& keys, const BeamGrid& grid,
                  const Vec3& x, int medium, BeamSample* out, int n, int max, bool exact) const {
    thread_local std::vector<BeamCandidate> found;  // per thread: kept, so rarely grown
    found.clear();
    find_candidates(prisms, keys, grid, x, medium, &found, exact);
    return eval_candidates(prisms, found.data(), found.size(), x, out, n, max, exact);
}

void Scene::find_candidates(const LargeVector<BeamPrism>& prisms, const LargeVector<PrismKey>& keys,
                            const BeamGrid& grid, const Vec3& x, int medium,
                            std::vector<BeamCandidate>* found, bool blurred) const {
    if (grid.nx == 0) return;
    // Below (or above) the periodic patch the beams of every period meet at x.
    bool periodic = ocean_water >= 0 && !ocean_flat && (medium == ocean_water || medium < 0);
    long i0 = 0, i1 = 0, j0 = 0, j1 = 0;
    Vec3 ghi = grid.lo + Vec3(grid.nx * grid.cell.x, grid.ny * grid.cell.y, grid.nz * grid.cell.z);
    // (in the grid's sheared frame: a shift by whole periods is horizontal there too)
    const double xu = x.x + grid.sx * x.z, xv = x.y + grid.sy * x.z;
    if (periodic) {
        i0 = ceil_to_long((xu - ghi.x) / patch_lx); i1 = floor_to_long((xu - grid.lo.x) / patch_lx);
        j0 = ceil_to_long((xv - ghi.y) / patch_ly); j1 = floor_to_long((xv - grid.lo.y) / patch_ly);
    }
    for (long i = i0; i <= i1; ++i)
        for (long j = j0; j <= j1; ++j) {
            Vec3 y = x - Vec3(double(i) * patch_lx, double(j) * patch_ly, 0.0);
            const long cx = floor_to_long((xu - double(i) * patch_lx - grid.lo.x) / grid.cell.x);
            const long cy = floor_to_long((xv - double(j) * patch_ly - grid.lo.y) / grid.cell.y);
            const long cz = floor_to_long((y.z - grid.lo.z) / grid.cell.z);
            if (cx < 0 || cy < 0 || cz < 0 || cx >= grid.nx || cy >= grid.ny || cz >= grid.nz) continue;
            size_t c = (size_t(cz) * grid.ny + cy) * grid.nx + cx;
            // The keys all fetched at once and tested (independent loads into arrays of
            // megabytes, so their misses overlap), and the prisms that passed fetched at once.
            const uint32_t* rec = &grid.cells[c * BeamGrid::kCellWords];
            const uint32_t count = rec[0], first = rec[1];
            auto item = [&](uint32_t q) { return q < uint32_t(BeamGrid::kInline) ? rec[2 + q] : grid.items[first + q]; };
            prefetch_cell_keys(grid, rec, keys);
            for (uint32_t k = 0; k < count; ++k) {
                const uint32_t pi = item(k);
                if (!may_cover(keys[pi], y, medium, i != 0 || j != 0, blurred)) continue;
                const char* pp = reinterpret_cast<const char*>(&prisms[pi]);
                for (int line = 0; line < kPrismQueryLines; ++line) __builtin_prefetch(pp + 64 * line);
                found->push_back({pi, int32_t(i), int32_t(j)});
            }
        }
}

int Scene::eval_candidates(const LargeVector<BeamPrism>& prisms, const BeamCandidate* found, size_t count,
                           const Vec3& x, BeamSample* out, int n, int max, bool exact) const {
    if (max <= 0) return n;
    for (size_t q = 0; q < count; ++q) {
        const BeamCandidate& f = found[q];
        const Vec3 y = x - Vec3(double(f.i) * patch_lx, double(f.j) * patch_ly, 0.0);
        if (n < max) {
            if (prism_eval(prisms[f.prism], y, x, &out[n], exact)) ++n;
            continue;
        }
        // More beams than the list holds (the sun's disk spread over many small prisms far
        // down): the beam joins the listed one nearest in direction, so no light is lost (their
        // directions differ by about the disk's image).
        BeamSample b;
        if (!prism_eval(prisms[f.prism], y, x, &b, exact)) continue;
        int best = 0;
        for (int k = 1; k < n; ++k)
            if (dot(out[k].d, b.d) > dot(out[best].d, b.d)) best = k;
        BeamSample& a = out[best];
        double wa = 0.0, wb = 0.0;
        for (int k = 0; k < nbands; ++k) {
            wa += a.e.v[k];
            wb += b.e.v[k];
        }
        const double w = wa + wb > 0.0 ? wb / (wa + wb) : 0.5;
        a.d = normalize(a.d * (1.0 - w) + b.d * w);
        a.l = a.l * (1.0 - w) + b.l * w;
        for (int k = 0; k < nbands; ++k) a.e.v[k] += b.e.v[k];
    }
    return n;
}

}  // namespace photic
