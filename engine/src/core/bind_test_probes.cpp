// Bindings that only tests use (photic._core.Scene): the beams' flux through a plane, the prisms'
// arrays and shadow checks, and the voxel grid's walks, integrals and lookups, each checked
// against an independent numpy computation. Kept apart from module.cpp, which binds what the
// renderer uses.
#include <chrono>
#include <cmath>
#include "bind_common.h"
#include "disk_overlap.h"
#include "scene.h"

namespace photic {

namespace {

// The grid of water `water` (the test bindings' walks and lookups), or a ValueError.
const VoxelGrid& grid_of(const Scene& s, int water) {
    const Water& w = s.waters.at(water);
    if (!w.grid) throw std::invalid_argument("this water has no grid");
    return *w.grid;
}

// A walk along o + d (normalised) through the grid of `water`, for the tracking bindings,
// which take one coefficient per density field in s1.
VoxelGrid::Cursor grid_cursor(const Scene& s, int water, const std::array<double, 3>& o,
                              const std::array<double, 3>& d, const std::vector<double>& s1) {
    const VoxelGrid& g = grid_of(s, water);
    if (int(s1.size()) != g.nfields) throw std::invalid_argument("s1 needs one coefficient per density field");
    return VoxelGrid::Cursor(g, to_vec(o), normalize(to_vec(d)));
}

// A tracking binding's answer: (reached, position, densities there, int rho_f up to it, depth left).
py::tuple march_result(const VoxelGrid::Cursor& c, bool hit, const double* rho, double xi, int nf) {
    return py::make_tuple(hit, c.position(), std::vector<double>(rho, rho + nf),
                          std::vector<double>(c.integral(), c.integral() + nf), xi);
}

}  // namespace

void bind_test_probes(py::class_<Scene>& scene) {
    scene
        .def_static("embree_error_probe", [] {
            // A failing Embree call (there is no geometry type 999) on a device of the core's.
            RTCDevice device = new_embree_device();
            RTCGeometry g = rtcNewGeometry(device, RTCGeometryType(999));
            if (g) rtcReleaseGeometry(g);
            rtcReleaseDevice(device);
            check_embree("rtcNewGeometry");
        }, "Raises the EmbreeError that Embree's error callback turned the failure of a call into.")
        .def_static("unit_disk_triangle_overlap", [](std::array<double, 3> u, std::array<double, 3> v) {
            return unit_disk_triangle_overlap(u.data(), v.data());
        }, py::arg("u"), py::arg("v"), "The area of the triangle (u_j, v_j) within the unit disk (the blur's kernel).")
        .def_static("atan2_fast", [](py::array_t<double, py::array::c_style | py::array::forcecast> y,
                                     py::array_t<double, py::array::c_style | py::array::forcecast> x) {
            if (y.size() != x.size()) throw std::invalid_argument("atan2_fast: y and x differ in size");
            py::array_t<double> out(y.size());
            for (py::ssize_t i = 0; i < y.size(); ++i) out.mutable_data()[i] = atan2_fast(y.data()[i], x.data()[i]);
            return out;
        }, py::arg("y"), py::arg("x"), "The blur's arctangent, elementwise over flat arrays.")
        .def("beam_phase", [](const Scene& s, int phase, double x) {
            if (phase < 0 || size_t(phase) >= s.phases.size()) throw std::invalid_argument("beam_phase: no such phase function");
            return s.beam_phase(phase, x);
        }, py::arg("phase"), py::arg("x"),
           "The phase function (1/sr) at x = 1 - cos(psi) as the beams' light meets it (averaged over "
           "the refracted sun's disk with the blur, after a build).")
        .def_readonly("beam_disk_radius", &Scene::beam_disk_radius)
        .def("time_beam_lookups", [](const Scene& s, py::array_t<double, py::array::c_style | py::array::forcecast> points,
                                     int medium, int repeats) {
            // The beams at each point, `repeats` times over (one thread, no GIL): (beams found
            // in all, seconds). For measuring the lookups' cost at given points.
            if (points.ndim() != 2 || points.shape(1) != 3) throw std::invalid_argument("points: expected (n, 3)");
            const double* p = points.data();
            const size_t n = size_t(points.shape(0));
            long found = 0;
            double seconds;
            {
                py::gil_scoped_release nogil;
                thread_local BeamSample out[kMaxBeams];
                const auto t0 = std::chrono::steady_clock::now();
                for (int r = 0; r < repeats; ++r)
                    for (size_t i = 0; i < n; ++i)
                        found += s.beams_at(Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]), medium, out, kMaxBeams);
                seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            }
            return py::make_tuple(found, seconds);
        }, py::arg("points"), py::arg("medium"), py::arg("repeats") = 1)
        .def("beams_brute_force", [](const Scene& s, py::array_t<double, py::array::c_style | py::array::forcecast> points,
                                     int medium) {
            // The beams at each point found without the grid: every prism (in the water
            // `medium`, or reflected into the air for medium -1) evaluated at every image of the point that falls within a metre of the
            // prism's box (every period below the ocean patch). (n,) counts and (n,) sums of
            // band 0's irradiance, for comparing with beams_at.
            if (points.ndim() != 2 || points.shape(1) != 3) throw std::invalid_argument("points: expected (n, 3)");
            const double* p = points.data();
            const py::ssize_t n = points.shape(0);
            py::array_t<long> count(n);
            DArray sum(n);
            for (py::ssize_t i = 0; i < n; ++i) {
                const Vec3 x(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
                long c = 0;
                double e = 0.0;
                for (const BeamPrism& P : medium < 0 ? s.air_prisms : s.prisms) {
                    if (P.water != medium) continue;
                    const double tol = 1.0;
                    long i0 = 0, i1 = 0, j0 = 0, j1 = 0;
                    if (P.periodic) {
                        i0 = long(std::ceil((x.x - P.hi.x - tol) / s.patch_lx));
                        i1 = long(std::floor((x.x - P.lo.x + tol) / s.patch_lx));
                        j0 = long(std::ceil((x.y - P.hi.y - tol) / s.patch_ly));
                        j1 = long(std::floor((x.y - P.lo.y + tol) / s.patch_ly));
                    }
                    for (long a = i0; a <= i1; ++a)
                        for (long b = j0; b <= j1; ++b) {
                            BeamSample bs;
                            if (s.prism_eval(P, x - Vec3(a * s.patch_lx, b * s.patch_ly, 0.0), x, &bs)) {
                                ++c;
                                e += bs.e.v[0];
                            }
                        }
                }
                count.mutable_at(i) = c;
                sum.mutable_at(i) = e;
            }
            return py::make_tuple(count, sum);
        }, py::arg("points"), py::arg("medium"))
        .def("beam_flux_through_plane", [](const Scene& s, double z) {
            // Sum over prisms of (irradiance on the horizontal plane at the slice centroid) x
            // (area of the prism's horizontal cross-section at z), band 0. Prisms sliced
            // horizontally only; the cross-section area is computed here independently.
            double flux = 0.0;
            for (const auto& P : s.prisms) {
                if (P.m.z != -1.0) continue;
                Vec3 p[3];
                bool inside = true;
                for (int j = 0; j < 3; ++j) {
                    double t = (-z - P.mv[j]) / P.md[j];
                    if (t < 0.0 || t > P.len[j]) inside = false;
                    p[j] = P.v[j] + P.d[j] * t;
                }
                if (!inside) continue;
                double area = 0.5 * std::fabs((p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y));
                Vec3 cen = (p[0] + p[1] + p[2]) * (1.0 / 3.0);
                BeamSample b;
                BeamPrism sharp = P;  // (the prism's own flux density, not spread over the sun's disk)
                sharp.blur_det = 0.0;
                if (!s.prism_eval(sharp, cen, cen, &b)) continue;
                flux += b.e.v[0] * (-b.d.z) * area;
            }
            return flux;
        }, py::arg("z"))
        .def("prism_arrays", [](const Scene& s, bool air) {
            // (start vertices (N,3,3), directions (N,3,3), lengths (N,3), flux band 0 (N,),
            //  whether each ray ended on a surface (N,3)); air: the reflected prisms in the air
            const auto& prisms = air ? s.air_prisms : s.prisms;
            size_t n = prisms.size();
            DArray v({py::ssize_t(n), py::ssize_t(3), py::ssize_t(3)}), d({py::ssize_t(n), py::ssize_t(3), py::ssize_t(3)});
            DArray len({py::ssize_t(n), py::ssize_t(3)});
            DArray phi{py::ssize_t(n)};
            py::array_t<bool> hit({py::ssize_t(n), py::ssize_t(3)});
            for (size_t i = 0; i < n; ++i) {
                const auto& P = prisms[i];
                for (int j = 0; j < 3; ++j) {
                    for (int c = 0; c < 3; ++c) {
                        v.mutable_at(i, j, c) = P.v[j][c];
                        d.mutable_at(i, j, c) = P.d[j][c];
                    }
                    len.mutable_at(i, j) = P.len[j];
                    hit.mutable_at(i, j) = P.hit[j];
                }
                phi.mutable_at(i) = P.phi.v[0];
            }
            return py::make_tuple(v, d, len, phi, hit);
        }, py::arg("air") = false)
        .def("prism_checks", [](const Scene& s) {
            // Per prism, which shadow rays its queries test: (N, 2) of (path, sun).
            py::array_t<bool> c({py::ssize_t(s.prisms.size()), py::ssize_t(2)});
            for (size_t i = 0; i < s.prisms.size(); ++i) {
                c.mutable_at(i, 0) = s.prisms[i].check_path;
                c.mutable_at(i, 1) = s.prisms[i].check_sun;
            }
            return c;
        })
        .def("grid_integral", [](const Scene& s, int water, std::array<double, 3> p0, std::array<double, 3> p1) {
            const VoxelGrid& g = grid_of(s, water);
            Vec3 a = to_vec(p0), b = to_vec(p1);
            double r[VoxelGrid::kMaxFields];
            g.integral(a, b, length(b - a), r);
            return std::vector<double>(r, r + g.nfields);
        }, py::arg("water"), py::arg("p0"), py::arg("p1"),
           "The integral of each of the grid's density fields along the segment p0 -> p1 (m): "
           "what the integrators' optical depths use (for tests).")
        .def("grid_density", [](const Scene& s, int water, std::array<double, 3> p) {
            const VoxelGrid& g = grid_of(s, water);
            double r[VoxelGrid::kMaxFields];
            g.at(to_vec(p), r);
            return std::vector<double>(r, r + g.nfields);
        }, py::arg("water"), py::arg("p"),
           "The grid's densities at p, one per field (0 outside the box): what the beam terms' "
           "scattering uses (for tests).")
        .def("grid_march", [](const Scene& s, int water, std::array<double, 3> o, std::array<double, 3> d,
                              double s0, std::vector<double> s1, double xi, double t_stop) {
            VoxelGrid::Cursor c = grid_cursor(s, water, o, d, s1);
            double rho[VoxelGrid::kMaxFields];
            const bool hit = c.march(s0, s1.data(), &xi, t_stop, rho);
            return march_result(c, hit, rho, xi, int(s1.size()));
        }, py::arg("water"), py::arg("o"), py::arg("d"), py::arg("s0"), py::arg("s1"), py::arg("xi"),
           py::arg("t_stop"),
           "Regular tracking along o + d t in the grid (for tests): (reached, position, densities "
           "there, int rho_f up to it, depth left) for the optical depth xi of "
           "s0 + sum_f s1[f] rho_f.")
        .def("grid_walk", [](const Scene& s, int water, std::array<double, 3> o, std::array<double, 3> d,
                             double s0, std::vector<double> s1, std::vector<std::pair<double, double>> steps) {
            VoxelGrid::Cursor c = grid_cursor(s, water, o, d, s1);
            py::list out;
            for (auto [xi, t] : steps) {
                double rho[VoxelGrid::kMaxFields] = {};
                bool hit = false;
                if (xi < 0.0) c.value(t);
                else hit = c.march(s0, s1.data(), &xi, t, rho);
                out.append(march_result(c, hit, rho, xi, int(s1.size())));
            }
            return py::make_tuple(c.by_columns(), out);
        }, py::arg("water"), py::arg("o"), py::arg("d"), py::arg("s0"), py::arg("s1"), py::arg("steps"),
           "One walk along o + d t in the grid taking steps in turn, as the integrators do (for "
           "tests): (xi, t) with xi < 0 reads the integrals at t (value), else tracks as "
           "grid_march does; (walked by columns, [(reached, position, densities, integrals, "
           "depth left) per step]).");
}

}  // namespace photic
