#include "scene.h"
#include <cstring>
#include <map>
#include <limits>
#include <stdexcept>

namespace photic {

namespace {

RTCScene build_embree_scene(RTCDevice device, const std::vector<const MeshRecord*>& meshes) {
    std::vector<TriangleMeshView> views;
    for (const MeshRecord* m : meshes)
        views.push_back({m->vertices.data(), m->vertices.size() / 3, m->triangles.data(), m->triangles.size() / 3,
                         m->instances.empty() ? nullptr : m->instances.data(), m->instances.size() / 12});
    return new_triangle_scene(device, views);
}

RTCRayHit make_rayhit(const Vec3& o, const Vec3& d, double tmin, double tmax) {
    RTCRayHit rh;
    rh.ray.org_x = float(o.x); rh.ray.org_y = float(o.y); rh.ray.org_z = float(o.z);
    rh.ray.dir_x = float(d.x); rh.ray.dir_y = float(d.y); rh.ray.dir_z = float(d.z);
    rh.ray.tnear = float(std::max(0.0, tmin));
    rh.ray.tfar = tmax >= kInf ? std::numeric_limits<float>::infinity() : float(tmax);
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instPrimID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

}  // namespace

Vec3 MeshRecord::to_world(size_t copy, const Vec3& p) const {
    const float* x = &instances[12 * copy];
    return Vec3(x[0] * p.x + x[1] * p.y + x[2] * p.z + x[3], x[4] * p.x + x[5] * p.y + x[6] * p.z + x[7],
                x[8] * p.x + x[9] * p.y + x[10] * p.z + x[11]);
}

std::pair<Vec3, Vec3> MeshRecord::world_bounds() const {
    Vec3 lo(kInf, kInf, kInf), hi(-kInf, -kInf, -kInf);
    for (size_t i = 0; i + 2 < vertices.size(); i += 3)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], double(vertices[i + a]));
            hi[a] = std::max(hi[a], double(vertices[i + a]));
        }
    if (instances.empty() || !(lo.x <= hi.x)) return {lo, hi};
    // Each copy's box: the mesh's box transformed (exact for its corners: R's entries' signs
    // pick the extreme corner per axis).
    Vec3 wlo(kInf, kInf, kInf), whi(-kInf, -kInf, -kInf);
    for (size_t k = 0; k < copies(); ++k) {
        const float* x = &instances[12 * k];
        for (int a = 0; a < 3; ++a) {
            double l = x[4 * a + 3], h = l;
            for (int j = 0; j < 3; ++j) {
                const double r = x[4 * a + j];
                l += r * (r >= 0.0 ? lo[j] : hi[j]);
                h += r * (r >= 0.0 ? hi[j] : lo[j]);
            }
            wlo[a] = std::min(wlo[a], l);
            whi[a] = std::max(whi[a], h);
        }
    }
    return {wlo, whi};
}

Vec3 MeshRecord::normal_to_world(size_t copy, const Vec3& n) const {
    const float* x = &instances[12 * copy];
    const Vec3 r0(x[0], x[1], x[2]), r1(x[4], x[5], x[6]), r2(x[8], x[9], x[10]);
    // The cofactor matrix's rows are the cross products of R's rows: C = det(R) R^-T.
    const Vec3 c0 = cross(r1, r2), c1 = cross(r2, r0), c2 = cross(r0, r1);
    const double sign = dot(r0, c0) < 0.0 ? -1.0 : 1.0;
    return Vec3(dot(c0, n), dot(c1, n), dot(c2, n)) * sign;
}

Scene::Scene() {
    device_ = new_embree_device();
}

Scene::~Scene() {
    if (scene_) rtcReleaseScene(scene_);
    if (patch_scene_) rtcReleaseScene(patch_scene_);
    if (device_) rtcReleaseDevice(device_);
}

namespace {

// The largest |grad z| over a periodic patch's facets, rounded up; inf unless the patch is a
// height field over one period: every facet facing up, their shadows' areas adding up to the
// period's (so that they cover it once).
double height_field_slope(const std::vector<float>& v, const std::vector<uint32_t>& t, double lx, double ly) {
    double slope = 0.0, area = 0.0;
    auto V = [&](uint32_t i) { return Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]); };
    for (size_t k = 0; k + 2 < t.size(); k += 3) {
        const Vec3 p0 = V(t[k]), n = cross(V(t[k + 1]) - p0, V(t[k + 2]) - p0);
        if (!(n.z > 0.0)) return kInf;
        slope = std::max(slope, std::sqrt(n.x * n.x + n.y * n.y) / n.z);
        area += 0.5 * n.z;
    }
    if (!(std::fabs(area - lx * ly) <= 1e-6 * lx * ly)) return kInf;
    return slope * (1.0 + 1e-9) + 1e-12;
}

}  // namespace

void Scene::commit() {
    grid_ref_.built = false;  // (its prisms came from the geometry before)
    if (nbands < 1 || nbands > kMaxBands) throw std::invalid_argument("nbands must be in 1..16");
    std::vector<const MeshRecord*> ptrs;
    Vec3 lo(kInf, kInf, kInf), hi(-kInf, -kInf, -kInf);
    auto grow = [&](double x, double y, double z) {
        lo = Vec3(std::min(lo.x, x), std::min(lo.y, y), std::min(lo.z, z));
        hi = Vec3(std::max(hi.x, x), std::max(hi.y, y), std::max(hi.z, z));
    };
    for (auto& m : meshes) {
        if (m.kind == SurfaceKind::kWaterBoundary && m.corner_normals.size() != 3 * m.triangles.size())
            smooth_corner_normals(&m);
        ptrs.push_back(&m);
        const auto b = m.world_bounds();
        if (b.first.x <= b.second.x) {
            grow(b.first.x, b.first.y, b.first.z);
            grow(b.second.x, b.second.y, b.second.z);
        }
    }
    meshes_lo_ = lo;
    meshes_hi_ = hi;
    for (const auto& r : radiometers) grow(r.position.x, r.position.y, r.position.z);
    if (ocean_water >= 0) grow(0, 0, ocean_z);
    if (has_bottom) grow(0, 0, bottom_z);

    if (scene_) rtcReleaseScene(scene_);
    scene_ = build_embree_scene(device_, ptrs);

    if (ocean_water >= 0 && !ocean_flat) {
        MeshRecord rec;
        rec.vertices = patch_vertices;
        rec.triangles = patch_triangles;
        patch_zmin = kInf; patch_zmax = -kInf;
        for (size_t i = 2; i < patch_vertices.size(); i += 3) {
            patch_zmin = std::min(patch_zmin, double(patch_vertices[i]));
            patch_zmax = std::max(patch_zmax, double(patch_vertices[i]));
        }
        if (patch_scene_) rtcReleaseScene(patch_scene_);
        patch_scene_ = build_embree_scene(device_, {&rec});
        if (patch_normals.size() != patch_vertices.size()) smooth_patch_normals();
        patch_slope_max = height_field_slope(patch_vertices, patch_triangles, patch_lx, patch_ly);
        grow(patch_x0, patch_y0, patch_zmin);
        grow(patch_x0 + patch_lx, patch_y0 + patch_ly, patch_zmax);
    }
    // Where reflected beams can be looked up (surfaces, radiometers) and start from (water
    // surfaces): the bounds so far, without the cameras, which beams never light (a camera high
    // above made the air prisms metres long, and their grid tens of millions of marks).
    bounds_lo_ = lo.x <= hi.x ? lo : Vec3(-1, -1, -1);
    bounds_hi_ = lo.x <= hi.x ? hi : Vec3(1, 1, 1);
    // The scene's extent (and the offsets from surfaces) counts every sensor.
    for (const auto& c : cameras) grow(c.position.x, c.position.y, c.position.z);
    extent_ = lo.x <= hi.x ? std::max(1e-3, length(hi - lo)) : 1.0;
    eps_ = 1e-6 * extent_;
    set_forward_cone(cone_half_angle);
    // Rays start on the near clipping plane, so the medium is the one there.
    for (auto& c : cameras) c.medium = medium_at(c.position + c.forward * c.clip_start);
    for (auto& r : radiometers) r.medium = medium_at(r.position);
}

void smooth_corner_normals(MeshRecord* mp) {
    MeshRecord& m = *mp;
    const size_t nt = m.triangles.size() / 3, nv = m.vertices.size() / 3;
    auto V = [&](uint32_t i) { return Vec3(m.vertices[3 * i], m.vertices[3 * i + 1], m.vertices[3 * i + 2]); };
    std::vector<Vec3> fn(nt);
    std::vector<uint32_t> start(nv + 1, 0), faces;
    for (size_t t = 0; t < nt; ++t) {
        const uint32_t* tri = &m.triangles[3 * t];
        fn[t] = cross(V(tri[1]) - V(tri[0]), V(tri[2]) - V(tri[0]));  // length: twice the area
        for (int j = 0; j < 3; ++j) start[tri[j] + 1]++;
    }
    for (size_t i = 0; i < nv; ++i) start[i + 1] += start[i];
    faces.resize(start[nv]);
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t t = 0; t < nt; ++t)
        for (int j = 0; j < 3; ++j) faces[fill[m.triangles[3 * t + j]]++] = uint32_t(t);
    const double cos_limit = std::cos(30.0 * kPi / 180.0);
    m.corner_normals.assign(9 * nt, 0.0f);
    for (size_t t = 0; t < nt; ++t) {
        const uint32_t* tri = &m.triangles[3 * t];
        const Vec3 nf = normalize(fn[t]);
        for (int j = 0; j < 3; ++j) {
            Vec3 sum;
            for (uint32_t k = start[tri[j]]; k < start[tri[j] + 1]; ++k)
                if (dot(normalize(fn[faces[k]]), nf) > cos_limit) sum += fn[faces[k]];
            const Vec3 n = normalize(sum);
            for (int c = 0; c < 3; ++c) m.corner_normals[9 * t + 3 * j + c] = float(n[c]);
        }
    }
}

void Scene::smooth_patch_normals() {
    // Area-weighted normals of the faces around each vertex; vertices that are the same point
    // of the periodic surface (on opposite seams) share one normal, so the tiles join smoothly.
    const size_t nv = patch_vertices.size() / 3, nt = patch_triangles.size() / 3;
    auto V = [&](size_t i) { return Vec3(patch_vertices[3 * i], patch_vertices[3 * i + 1], patch_vertices[3 * i + 2]); };
    std::vector<Vec3> vn(nv);
    std::map<std::pair<long, long>, std::vector<size_t>> same;
    const double qx = patch_lx * 1e-7, qy = patch_ly * 1e-7;
    for (size_t i = 0; i < nv; ++i) {
        Vec3 p = V(i);
        double fx = std::fmod(p.x - patch_x0, patch_lx); if (fx < 0) fx += patch_lx;
        double fy = std::fmod(p.y - patch_y0, patch_ly); if (fy < 0) fy += patch_ly;
        long kx = std::lround(fx / qx), ky = std::lround(fy / qy);
        if (kx >= std::lround(patch_lx / qx)) kx = 0;
        if (ky >= std::lround(patch_ly / qy)) ky = 0;
        same[{kx, ky}].push_back(i);
    }
    for (size_t t = 0; t < nt; ++t) {
        const uint32_t* tri = &patch_triangles[3 * t];
        Vec3 c = cross(V(tri[1]) - V(tri[0]), V(tri[2]) - V(tri[0]));  // area weighted
        if (c.z < 0) c = -c;
        for (int j = 0; j < 3; ++j) vn[tri[j]] += c;
    }
    for (auto& [key, ids] : same) {
        Vec3 sum;
        for (size_t i : ids) sum += vn[i];
        for (size_t i : ids) vn[i] = normalize(sum);
    }
    patch_normals.resize(3 * nv);
    for (size_t i = 0; i < nv; ++i)
        for (int c = 0; c < 3; ++c) patch_normals[3 * i + c] = float(vn[i][c]);
}

bool Scene::intersect_patch(const Vec3& o, const Vec3& d, double tmax, Hit* hit, Side side) const {
    // A ray that starts below the surface and goes down more steeply than any facet rises (or
    // above it, going up) stays on its side: along its horizontal path the surface changes
    // height by at most patch_slope_max per metre, less than the ray does.
    if (side != Side::kUnknown && double(int(side)) * d.z > 0.0 &&
        std::fabs(d.z) >= patch_slope_max * std::sqrt(d.x * d.x + d.y * d.y))
        return false;
    double tol = 1e-6 * extent_;
    double t0, t1;
    if (std::fabs(d.z) < 1e-12) {
        if (o.z < patch_zmin - tol || o.z > patch_zmax + tol) return false;
        t0 = 0.0; t1 = tmax;
    } else {
        double ta = (patch_zmin - tol - o.z) / d.z, tb = (patch_zmax + tol - o.z) / d.z;
        t0 = std::max(0.0, std::min(ta, tb));
        t1 = std::min(tmax, std::max(ta, tb));
    }
    if (!(t0 < t1)) return false;
    // Walk the periodic tiles the ray crosses inside the slab of wave heights (2-D DDA).
    Vec3 p = o + d * t0;
    long i = floor_to_long((p.x - patch_x0) / patch_lx);
    long j = floor_to_long((p.y - patch_y0) / patch_ly);
    double t_cur = t0;
    const int kMaxTiles = 100000;  // beyond this a near-horizontal ray is treated as passing
    for (int step = 0; step < kMaxTiles; ++step) {
        double tx = kInf, ty = kInf;
        if (d.x > 0) tx = (patch_x0 + (i + 1) * patch_lx - o.x) / d.x;
        else if (d.x < 0) tx = (patch_x0 + i * patch_lx - o.x) / d.x;
        if (d.y > 0) ty = (patch_y0 + (j + 1) * patch_ly - o.y) / d.y;
        else if (d.y < 0) ty = (patch_y0 + j * patch_ly - o.y) / d.y;
        double t_exit = std::min({tx, ty, t1});
        // Trace in the patch's own frame from the point where the ray enters this tile.
        Vec3 shift(double(i) * patch_lx, double(j) * patch_ly, 0.0);
        Vec3 local = o + d * t_cur - shift;
        RTCRayHit rh = make_rayhit(local, d, 0.0, (t_exit - t_cur) + tol);
        rtcIntersect1(patch_scene_, &rh);
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
            double t = t_cur + double(rh.ray.tfar);
            if (t > 0.0 && t < tmax) {
                const uint32_t* tri = &patch_triangles[3 * rh.hit.primID];
                auto v = [&](uint32_t k) { return Vec3(patch_vertices[3 * k], patch_vertices[3 * k + 1], patch_vertices[3 * k + 2]); };
                Vec3 n = normalize(cross(v(tri[1]) - v(tri[0]), v(tri[2]) - v(tri[0])));
                if (n.z < 0) n = -n;  // water lies below the surface: outward is up
                hit->ns = n;
                if (patch_normals.size() == patch_vertices.size()) {  // (always, after commit)
                    auto vn = [&](uint32_t k) { return Vec3(patch_normals[3 * k], patch_normals[3 * k + 1], patch_normals[3 * k + 2]); };
                    double u = rh.hit.u, w = rh.hit.v;
                    Vec3 ns = normalize(vn(tri[0]) * (1.0 - u - w) + vn(tri[1]) * u + vn(tri[2]) * w);
                    if (ns.z > 0.0) hit->ns = ns;
                }
                hit->valid = true; hit->t = t; hit->n = n; hit->id = -3;
                hit->kind = SurfaceKind::kWaterBoundary; hit->index = ocean_water;
                return true;
            }
        }
        if (t_exit >= t1) return false;
        if (tx <= ty) i += d.x > 0 ? 1 : -1; else j += d.y > 0 ? 1 : -1;
        t_cur = t_exit;
    }
    return false;
}

Hit Scene::intersect(const Vec3& o, const Vec3& d, double tmax, Side side) const {
    Hit hit;
    hit.t = tmax;
    RTCRayHit rh = make_rayhit(o, d, 0.0, tmax);
    rtcIntersect1(scene_, &rh);
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
        // A copy of an instanced mesh: the instance array's id is the mesh's, and Embree's
        // normal is in the mesh's own frame.
        const bool copy = rh.hit.instID[0] != RTC_INVALID_GEOMETRY_ID;
        const unsigned int id = copy ? rh.hit.instID[0] : rh.hit.geomID;
        const MeshRecord& m = meshes[id];
        hit.valid = true;
        hit.id = int(id);
        hit.t = rh.ray.tfar;
        // Embree's geometric normal is (v1 - v0) x (v2 - v0), the same winding convention.
        const Vec3 ng(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
        hit.n = normalize(copy ? m.normal_to_world(rh.hit.instPrimID[0], ng) : ng);
        hit.ns = hit.n;
        hit.kind = m.kind;
        hit.index = m.index;
        hit.prim = int(rh.hit.primID);
        hit.bu = rh.hit.u;
        hit.bv = rh.hit.v;
        if (!m.corner_normals.empty()) {  // a water boundary: its smooth shading normal
            const float* c = &m.corner_normals[9 * size_t(rh.hit.primID)];
            const double u = rh.hit.u, v = rh.hit.v, w0 = 1.0 - u - v;
            const Vec3 ns = normalize(Vec3(w0 * c[0] + u * c[3] + v * c[6], w0 * c[1] + u * c[4] + v * c[7],
                                           w0 * c[2] + u * c[5] + v * c[8]));
            if (dot(ns, hit.n) > 0.0) hit.ns = ns;
        }
    }
    Hit oh = intersect_ocean(o, d, hit.t, side);
    return oh.valid ? oh : hit;
}

Hit Scene::intersect_ocean(const Vec3& o, const Vec3& d, double tmax, Side side) const {
    Hit hit;
    hit.t = tmax;
    if (ocean_water < 0) return hit;
    if (ocean_flat) {
        if (d.z != 0.0) {
            double t = (ocean_z - o.z) / d.z;
            if (t > 0.0 && t < hit.t) {
                hit.valid = true; hit.t = t; hit.n = Vec3(0, 0, 1); hit.ns = hit.n; hit.id = -3;
                hit.kind = SurfaceKind::kWaterBoundary; hit.index = ocean_water;
            }
        }
    } else {
        Hit ph;
        if (intersect_patch(o, d, hit.t, &ph, side)) hit = ph;
    }
    if (has_bottom && d.z != 0.0) {
        double t = (bottom_z - o.z) / d.z;
        if (t > 0.0 && t < hit.t) {
            hit.valid = true; hit.t = t; hit.n = Vec3(0, 0, 1); hit.id = -2;
            hit.kind = SurfaceKind::kOpaque; hit.index = bottom_material;
        }
    }
    return hit;
}

bool Scene::occluded(const Vec3& o, const Vec3& d, Side side) const {
    RTCRayHit rh = make_rayhit(o, d, 0.0, kInf);
    rtcOccluded1(scene_, &rh.ray);
    if (rh.ray.tfar < 0.0f) return true;
    return occluded_ocean(o, d, side);
}

bool Scene::occluded_ocean(const Vec3& o, const Vec3& d, Side side) const {
    if (ocean_water < 0) return false;
    Hit h;
    if (ocean_flat) {
        if (d.z != 0.0 && (ocean_z - o.z) / d.z > 0.0) return true;
    } else if (intersect_patch(o, d, kInf, &h, side)) {
        return true;
    }
    return has_bottom && d.z != 0.0 && (bottom_z - o.z) / d.z > 0.0;
}

bool Scene::meshes_block(const Vec3& o, const Vec3& d, double tnear, double tfar) const {
    // The segment against the meshes' box (slabs) first: most beam queries are far from any
    // object, and this costs a few flops against an Embree traversal.
    double t0 = std::max(0.0, tnear), t1 = tfar;
    for (int a = 0; a < 3 && t0 <= t1; ++a) {
        const double lo = meshes_lo_[a], hi = meshes_hi_[a], oa = o[a], da = d[a];
        if (da == 0.0) {
            if (oa < lo || oa > hi) return false;
            continue;
        }
        double ta = (lo - oa) / da, tb = (hi - oa) / da;
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    if (!(t0 <= t1)) return false;
    RTCRayHit rh = make_rayhit(o, d, tnear, tfar);
    rtcOccluded1(scene_, &rh.ray);
    return rh.ray.tfar < 0.0f;
}

bool Scene::occluded_segment(const Vec3& o, const Vec3& d, double tmax) const {
    Hit h = intersect(o, d, tmax);
    return h.valid;
}

bool Scene::inside_opaque(const Vec3& p) const {
    const Vec3 dirs[6] = {normalize(Vec3(1, 0.0123, 0.0071)), normalize(Vec3(-1, 0.0089, -0.0061)),
                          normalize(Vec3(0.0113, 1, 0.0057)), normalize(Vec3(-0.0097, -1, 0.0043)),
                          normalize(Vec3(0.0071, 0.0031, 1)), normalize(Vec3(-0.0053, 0.0083, -1))};
    int behind = 0;
    for (const Vec3& d : dirs) {
        Hit h = intersect(p, d);
        if (h.valid && h.kind == SurfaceKind::kOpaque && h.id >= 0 && dot(h.n, d) > 0.0) ++behind;
    }
    return behind >= 4;
}

int Scene::medium_at(const Vec3& p) const {
    // Cast a slightly tilted ray upwards; the first water boundary it meets tells whether p
    // is inside (leaving through the boundary) or outside. Opaque surfaces are passed through.
    Vec3 d = normalize(Vec3(0.00123, 0.00071, 1.0));
    Vec3 o = p;
    for (int k = 0; k < 10000; ++k) {
        Hit h = intersect(o, d);
        if (!h.valid) return -1;
        if (h.kind == SurfaceKind::kWaterBoundary) return dot(d, h.n) > 0.0 ? h.index : -1;
        Vec3 x = o + d * h.t;
        o = x + d * offset_for(x);
    }
    return -1;
}

Spectrum Scene::sky_radiance(const Vec3& d) const {
    Spectrum s;
    if (sky_type == 0) return s;
    if (d.z <= 0.0 && !sky_full_sphere) return s;
    double f = sky_type == 2 ? (1.0 + 2.0 * d.z) : 1.0;
    if (sky_type == 3 || sky_type == 4) {
        double th = std::acos(std::clamp(d.z, 0.0, 1.0)) / (0.5 * kPi) * (sky_nt - 1);
        double ph = std::atan2(d.y, d.x);
        if (ph < 0) ph += 2.0 * kPi;
        ph = ph / (2.0 * kPi) * sky_np;
        int i0 = std::min(sky_nt - 2, int(th)), j0 = int(ph) % sky_np, j1 = (j0 + 1) % sky_np;
        double ft = th - i0, fp = ph - std::floor(ph);
        const int nv = sky_type == 4 ? nbands : 1;
        auto T = [&](int i, int j, int k) { return sky_table[(size_t(i) * sky_np + j) * nv + k]; };
        for (int k = 0; k < nv; ++k) {
            s.v[k] = (1 - ft) * ((1 - fp) * T(i0, j0, k) + fp * T(i0, j1, k))
                     + ft * ((1 - fp) * T(i0 + 1, j0, k) + fp * T(i0 + 1, j1, k));
        }
        f = s.v[0];
        if (sky_type == 4) {
            for (int k = 0; k < nbands; ++k) s.v[k] *= sky_l0.v[k];
            return s;
        }
    }
    for (int k = 0; k < nbands; ++k) s.v[k] = sky_l0.v[k] * f;
    return s;
}

Material Scene::surface_at(const Hit& h) const {
    Material m = materials[h.index];
    if (m.texture < 0 || h.id < 0) return m;
    const MeshRecord& r = meshes[h.id];
    if (r.corner_uv.empty() || h.prim < 0) return m;
    const Texture& tex = textures[m.texture];
    const float* c = &r.corner_uv[6 * size_t(h.prim)];
    const double w0 = 1.0 - h.bu - h.bv;
    double u = w0 * c[0] + h.bu * c[2] + h.bv * c[4];
    double v = w0 * c[1] + h.bu * c[3] + h.bv * c[5];
    // Texel centres at (i + 0.5) / size; bilinear between the four around (u, v).
    double x = u * tex.width - 0.5, y = v * tex.height - 0.5;
    if (!std::isfinite(x) || !std::isfinite(y)) return m;
    const double fx = std::floor(x), fy = std::floor(y);
    const double ax = x - fx, ay = y - fy;
    auto wrap = [&](long long i, int n) {
        if (tex.clamp) return int(std::clamp<long long>(i, 0, n - 1));
        long long r2 = i % n;
        return int(r2 < 0 ? r2 + n : r2);
    };
    const int x0 = wrap((long long)fx, tex.width), x1 = wrap((long long)fx + 1, tex.width);
    const int y0 = wrap((long long)fy, tex.height), y1 = wrap((long long)fy + 1, tex.height);
    const int nb = nbands;
    auto T = [&](int yy, int xx, int k) { return double(tex.texels[(size_t(yy) * tex.width + xx) * nb + k]); };
    if (tex.closest) {
        const int xn = ax < 0.5 ? x0 : x1, yn = ay < 0.5 ? y0 : y1;
        for (int k = 0; k < nb; ++k) m.reflectance.v[k] = T(yn, xn, k);
        return m;
    }
    for (int k = 0; k < nb; ++k)
        m.reflectance.v[k] = (1 - ay) * ((1 - ax) * T(y0, x0, k) + ax * T(y0, x1, k))
                             + ay * ((1 - ax) * T(y1, x0, k) + ax * T(y1, x1, k));
    return m;
}

Vec3 Scene::sample_sun(double u1, double u2) const {
    return direction_around(sun_dir, u1 * (1.0 - sun_cos_half), 2.0 * kPi * u2);
}

}  // namespace photic
