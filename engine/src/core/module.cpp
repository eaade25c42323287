// Python bindings of the compiled core (photic._core). Heavy calls release the GIL.
#include <cmath>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include "bind_common.h"
#include "optics.h"
#include "scene.h"

using namespace photic;
namespace photic {
void bind_rough_interface(py::module_& m);        // bind_rough_interface.cpp
void bind_test_probes(py::class_<Scene>& scene);  // bind_test_probes.cpp
}

namespace {


Spectrum to_spectrum(const DArray& a, int nb, const char* what) {
    if (a.ndim() != 1 || a.shape(0) != nb)
        throw std::invalid_argument(std::string(what) + ": expected one value per band");
    Spectrum s;
    for (int k = 0; k < nb; ++k) s.v[k] = a.at(k);
    return s;
}


// A pass's [sum, sum of squares] of the given shape, zeroed: the caller's arrays `out` when
// given (reused from pass to pass: new large arrays cost a page fault per 4 kB page, on
// some allocator states every pass), else new ones.
std::pair<DArray, DArray> pass_buffers(const py::object& out, const std::vector<py::ssize_t>& shape) {
    std::pair<DArray, DArray> r;
    if (out.is_none()) {
        r = {DArray(shape), DArray(shape)};
    } else {
        auto t = out.cast<py::tuple>();
        if (t.size() != 2) throw std::invalid_argument("out: expected (sum, sum of squares)");
        for (int i = 0; i < 2; ++i) {
            auto a = t[i].cast<py::array>();
            if (!py::isinstance<py::array_t<double>>(a) || !(a.flags() & py::array::c_style) || !a.writeable() ||
                std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()) != shape)
                throw std::invalid_argument("out: expected writable C-contiguous float64 arrays of the pass's shape");
            (i ? r.second : r.first) = a.cast<DArray>();
        }
    }
    std::fill(r.first.mutable_data(), r.first.mutable_data() + r.first.size(), 0.0);
    std::fill(r.second.mutable_data(), r.second.mutable_data() + r.second.size(), 0.0);
    return r;
}

py::dict counters_dict(const Counters& c) {
    py::dict d;
    d["segments"] = c.segments;
    d["shadow_rays"] = c.shadow_rays;
    d["paths"] = c.paths;
    return d;
}

}  // namespace

PYBIND11_MODULE(_core, m) {
    m.doc() = "Photic compiled core: Embree geometry, phase functions and the path tracer";
    // Embree 4 from the embreex wheel, where photic.embree finds it; checked before anything
    // else, so a missing or unusable library fails the import with the reason.
    const auto embree_path = py::module_::import("photic.embree").attr("library_path")().cast<std::string>();
    m.attr("EMBREE") = load_embree(embree_path);
    py::register_exception<EmbreeError>(m, "EmbreeError", PyExc_RuntimeError);
    m.attr("MAX_BANDS") = kMaxBands;
    bind_rough_interface(m);
    static_assert(kNumComponents == 8, "COMPONENTS below names each component");
    m.attr("COMPONENTS") = py::make_tuple("total", "beam_surface", "beam_volume", "path", "beam_direct", "raman",
                                          "chlorophyll", "cdom");

    m.def("fresnel", [](double cos_i, double n1, double n2) { return fresnel_unpolarized(cos_i, n1, n2); },
          py::arg("cos_i"), py::arg("n1"), py::arg("n2"),
          "Unpolarised Fresnel reflectance (1 beyond the critical angle).");
    m.def("refract", [](std::array<double, 3> d, std::array<double, 3> n, double n1, double n2) -> py::object {
              Vec3 out;
              if (!refract(to_vec(d), to_vec(n), n1, n2, &out)) return py::none();
              return py::cast(std::array<double, 3>{out.x, out.y, out.z});
          }, py::arg("d"), py::arg("n"), py::arg("n1"), py::arg("n2"),
          "Refracted direction (None on total internal reflection); n faces the incoming side.");

    py::class_<PhaseFunction>(m, "PhaseFunction")
        .def_static("isotropic", &PhaseFunction::isotropic)
        .def_static("henyey_greenstein", &PhaseFunction::henyey_greenstein, py::arg("g"))
        .def_static("quadratic", &PhaseFunction::quadratic, py::arg("a"))
        .def_static("table", [](DArray x, DArray v) {
            std::vector<double> xs(x.data(), x.data() + x.size()), vs(v.data(), v.data() + v.size());
            return PhaseFunction::table(xs, vs);
        }, py::arg("x"), py::arg("values"))
        .def("eval", [](const PhaseFunction& p, DArray x) {
            DArray out(x.size());
            for (py::ssize_t i = 0; i < x.size(); ++i) out.mutable_data()[i] = p.eval(x.data()[i]);
            return out;
        }, py::arg("x"), "Phase function (1/sr) at x = 1 - cos(psi).")
        .def("cdf", [](const PhaseFunction& p, DArray x) {
            DArray out(x.size());
            for (py::ssize_t i = 0; i < x.size(); ++i) out.mutable_data()[i] = p.cdf(x.data()[i]);
            return out;
        }, py::arg("x"), "Fraction scattered into 1 - cos(psi) <= x.")
        .def("sample_x", [](const PhaseFunction& p, DArray u) {
            DArray out(u.size());
            for (py::ssize_t i = 0; i < u.size(); ++i) out.mutable_data()[i] = p.sample_x(u.data()[i]);
            return out;
        }, py::arg("u"), "Inverse-CDF samples of x = 1 - cos(psi) from uniforms u.")
        .def_property_readonly("table_x", &PhaseFunction::table_x)
        .def_property_readonly("table_values", &PhaseFunction::table_values);

    py::class_<Scene> scene(m, "Scene");
    scene
        .def(py::init<>())
        .def_readwrite("nbands", &Scene::nbands)
        .def_readwrite("seed", &Scene::seed)
        .def_readwrite("max_depth", &Scene::max_depth)
        .def_readwrite("rr_depth", &Scene::rr_depth)
        .def_readwrite("hybrid", &Scene::hybrid)
        .def_readwrite("beam_max_level", &Scene::beam_max_level)
        .def_readwrite("beam_min_area_fraction", &Scene::beam_min_area_fraction)
        .def_readonly("cone_half_angle", &Scene::cone_half_angle)
        .def("set_forward_cone", &Scene::set_forward_cone, py::arg("half_angle_rad"))
        .def("build_beams", [](Scene& s, std::array<double, 3> sun_dir, int threads, std::array<double, 2> facet_u,
                               bool keep_prisms) {
            py::gil_scoped_release nogil;
            s.build_beams(to_vec(sun_dir), threads, facet_u[0], facet_u[1], keep_prisms);
        }, py::arg("sun_direction"), py::arg("threads") = 0, py::arg("facet_u") = std::array<double, 2>{0.5, 0.0},
           py::arg("keep_prisms") = false,
           "Builds the beams for one sun direction (drawn in the disk for every pass); with a rough "
           "ocean surface, facet_u (two uniforms in [0, 1)) picks the sub-pixel facet of this build. "
           "With the sun-disk blur (beam_sun_blur, no rough sea) the prisms are the sun centre's "
           "and keep_prisms keeps those of the last build, only the shadow rays' direction and a "
           "flat sea's beams following sun_direction.")
        .def_readwrite("beam_source_region", &Scene::beam_source_region,
                       "(x, y, radius) triples (m) of disks over the ocean patch (periodic): only its "
                       "faces centred in one send beams; empty (default): every face.")
        .def_readwrite("beam_sun_blur", &Scene::beam_sun_blur,
                       "Spread each prism over the sun's disk (built once for its centre) instead of "
                       "drawing a direction in the disk for every build.")
        .def_property_readonly("sun_blur_active", &Scene::sun_blur_active)
        .def_property_readonly("ocean_rough", [](const Scene& s) { return s.ocean_rough; })
        .def_property_readonly("beam_count", [](const Scene& s) { return s.prisms.size(); })
        .def_property_readonly("has_flat_beam", [](const Scene& s) { return s.flat_beam; })
        .def_property_readonly("beam_grid_shared", &Scene::beam_grid_shared,
                               "Whether this pass's water beams use the grid built once for the sun's centre.")
        .def("beam_total_flux", &Scene::beam_total_flux)
        .def("beam_patch_copies", &Scene::beam_patch_copies)
        .def("sun_rehit_fraction", [](const Scene& s, std::array<double, 3> sun, double ior, int threads) {
            py::gil_scoped_release nogil;
            return s.sun_rehit_fraction(normalize(to_vec(sun)), ior, threads);
        }, py::arg("sun"), py::arg("ior"), py::arg("threads") = 0,
           "The sunlight entering the water that the beams do not carry (the ocean patch's "
           "reflections that meet it again, refractions that meet it from below), over what they carry.")
        .def_property_readonly("air_beam_count", [](const Scene& s) { return s.air_prisms.size(); })
        .def_property_readonly("has_air_beams", [](const Scene& s) { return s.has_air_beams(); })
        .def("air_beam_total_flux", &Scene::air_beam_total_flux)
        .def("beams_at", [](const Scene& s, std::array<double, 3> x, int medium) {
            BeamSample buf[256];
            int n = s.beams_at(to_vec(x), medium, buf, 256);
            py::list out;
            for (int i = 0; i < n; ++i) {
                std::vector<double> e(buf[i].e.v.begin(), buf[i].e.v.begin() + s.nbands);
                out.append(py::make_tuple(std::array<double, 3>{buf[i].d.x, buf[i].d.y, buf[i].d.z}, e));
            }
            return out;
        }, py::arg("x"), py::arg("medium"), "(direction, irradiance normal to it per band) of every beam at x.")
        .def("add_material", [](Scene& s, DArray refl) {
            Material m;
            m.reflectance = to_spectrum(refl, s.nbands, "reflectance");
            s.materials.push_back(m);
            return int(s.materials.size()) - 1;
        })
        .def("set_material_emission", [](Scene& s, int material, DArray emission) {
            Material& m = s.materials.at(material);
            m.emission = to_spectrum(emission, s.nbands, "emission");
            m.emits = false;
            for (int k = 0; k < s.nbands; ++k) m.emits |= m.emission.v[k] != 0.0;
        }, py::arg("material"), py::arg("emission"), "Radiance the material emits (per band), from both faces.")
        .def("set_material_texture", [](Scene& s, int material, FArray image, bool clamp, bool closest) {
            if (image.ndim() != 3 || image.shape(2) != s.nbands || image.shape(0) < 1 || image.shape(1) < 1)
                throw std::invalid_argument("texture must be (height, width, nbands) float32");
            Texture t;
            t.height = int(image.shape(0)); t.width = int(image.shape(1)); t.clamp = clamp; t.closest = closest;
            t.texels.assign(image.data(), image.data() + image.size());
            for (float x : t.texels)
                if (!(x >= 0.0f && x <= 1.0f)) throw std::invalid_argument("texture reflectances must be in [0, 1]");
            s.textures.push_back(std::move(t));
            s.materials.at(material).texture = int(s.textures.size()) - 1;
        }, py::arg("material"), py::arg("image"), py::arg("clamp") = false, py::arg("closest") = false,
           "A reflectance texture (height, width, nbands), rows from v = 0 up; bilinear (or the "
           "nearest texel), repeating or clamped.")
        .def("set_mesh_uv", [](Scene& s, int mesh, FArray uv) {
            MeshRecord& m = s.meshes.at(mesh);
            if (uv.ndim() != 3 || uv.shape(1) != 3 || uv.shape(2) != 2 || size_t(uv.shape(0)) * 3 != m.triangles.size())
                throw std::invalid_argument("uv must be (triangles, 3, 2) float32");
            m.corner_uv.assign(uv.data(), uv.data() + uv.size());
        }, py::arg("mesh"), py::arg("uv"), "Texture coordinates at each triangle's corners.")
        .def("set_mesh_instances", [](Scene& s, int mesh, FArray x) {
            MeshRecord& m = s.meshes.at(mesh);
            if (m.kind != SurfaceKind::kOpaque) throw std::invalid_argument("only opaque meshes can be instanced");
            if (x.ndim() != 3 || x.shape(0) < 1 || x.shape(1) != 3 || x.shape(2) != 4)
                throw std::invalid_argument("instances must be (N >= 1, 3, 4) float32: rows [R | t]");
            if (size_t(x.shape(0)) >= size_t(RTC_INVALID_GEOMETRY_ID))
                throw std::invalid_argument("too many instances for Embree's 32-bit ids");
            for (size_t i = 0; i < size_t(x.size()); ++i)
                if (!std::isfinite(x.data()[i])) throw std::invalid_argument("instances must be finite");
            m.instances.assign(x.data(), x.data() + x.size());
        }, py::arg("mesh"), py::arg("instances"),
           "Copies of an opaque mesh: (N, 3, 4) affine transforms [R | t] of its vertices, traced as "
           "an Embree instance array over the mesh's own BVH (the mesh is stored once).")
        .def("add_phase", [](Scene& s, const PhaseFunction& p) {
            s.phases.push_back(p);
            return int(s.phases.size()) - 1;
        })
        .def("add_water", [](Scene& s, double ior, DArray a, std::vector<std::pair<int, DArray>> comps) {
            Water w;
            w.ior = ior;
            WaterLayer layer;
            layer.a = to_spectrum(a, s.nbands, "absorption");
            if (comps.size() > 16) throw std::invalid_argument("at most 16 scattering components");
            for (auto& [pid, b] : comps) {
                if (pid < 0 || pid >= int(s.phases.size())) throw std::invalid_argument("bad phase index");
                ScatterComponent c;
                c.phase = pid;
                layer.comp_b.push_back(to_spectrum(b, s.nbands, "scattering"));
                for (int k = 0; k < s.nbands; ++k) layer.b.v[k] += layer.comp_b.back().v[k];
                w.components.push_back(c);
            }
            w.layers.push_back(layer);
            s.waters.push_back(w);  // path/beam coefficients: Scene::set_forward_cone at commit
            return int(s.waters.size()) - 1;
        }, py::arg("ior"), py::arg("absorption"), py::arg("components"),
           "A water body; its IOPs hold everywhere, or above the first layer added below it.")
        .def("set_water_inelastic", [](Scene& s, int water, int kind, DArray coupling, double rho) {
            Water& w = s.waters.at(water);
            const int nb = s.nbands;
            if (kind < 0 || kind >= kInelasticKinds) throw std::invalid_argument("unknown inelastic process kind");
            const int nl = coupling.ndim() == 3 ? int(coupling.shape(0)) : 1;
            if (!((coupling.ndim() == 2 || coupling.ndim() == 3) && coupling.shape(coupling.ndim() - 2) == nb &&
                  coupling.shape(coupling.ndim() - 1) == nb) ||
                (nl != 1 && nl != int(w.layers.size())))
                throw std::invalid_argument("inelastic coupling must be (nbands, nbands) or (layers, nbands, "
                                            "nbands): [layer, emission, excitation]");
            if (!(rho >= 0.0 && rho <= 1.0)) throw std::invalid_argument("inelastic phase rho must be in [0, 1]");
            Inelastic P;
            P.kind = kind;
            P.rho = rho;
            P.nb = nb;
            P.nlayers = nl;
            P.coupling.assign(coupling.data(), coupling.data() + coupling.size());
            for (double x : P.coupling)
                if (!(x >= 0.0 && std::isfinite(x))) throw std::invalid_argument("inelastic coupling must be finite and >= 0");
            P.from.assign(nb, 0);
            P.to.assign(nb, 0);
            P.in.assign(nl, Spectrum());
            for (int l = 0; l < nl; ++l)
                for (int j = 0; j < nb; ++j)
                    for (int i = 0; i < nb; ++i) {
                        const double m = P.coupling[(size_t(l) * nb + j) * nb + i];
                        if (!(m > 0.0)) continue;
                        P.from[j] = P.to[j] == 0 ? i : std::min(P.from[j], i);
                        P.to[j] = std::max(P.to[j], i + 1);
                        P.in[l].v[j] += m;
                    }
            for (int l = 0; l < nl; ++l)
                for (int j = 0; j < nb; ++j) {
                    P.in_max.v[j] = std::max(P.in_max.v[j], P.in[l].v[j]);
                    P.rate = std::max(P.rate, P.in[l].v[j]);
                }
            if (!(P.rate > 0.0)) return;  // (no band receives any: nothing to do)
            for (Inelastic& Q : w.inelastic)
                if (Q.kind == kind) throw std::invalid_argument("an inelastic process of this kind is set already");
            w.inelastic.push_back(std::move(P));
            w.inelastic_rate = 0.0;
            for (const Inelastic& Q : w.inelastic) w.inelastic_rate += Q.rate;
        }, py::arg("water"), py::arg("kind"), py::arg("coupling"), py::arg("rho"),
           "An inelastic process of the water body (kind 0: Raman scattering, 1: chlorophyll "
           "fluorescence, 2: CDOM fluorescence): coupling[(layer,) j, i] (m^-1) from excitation band i into emission band "
           "j per unit of band i's spectral irradiance (one per layer, or one for all); phase "
           "function 3 / (4 pi (3 + rho)) (1 + rho cos^2). The beams' single scattering and the "
           "paths' own inelastic collisions (both integrators). Its loss is the caller's, in the "
           "bands' absorption.")
        .def("add_water_layer", [](Scene& s, int water, double z_top, DArray a, std::vector<DArray> b) {
            if (water < 0 || water >= int(s.waters.size())) throw std::invalid_argument("bad water index");
            Water& w = s.waters[water];
            if (!std::isfinite(z_top) || !(z_top < w.layers.back().z_top))
                throw std::invalid_argument("layer tops must be finite and strictly descending");
            if (b.size() != w.components.size())
                throw std::invalid_argument("a layer needs one scattering spectrum per component of the water");
            WaterLayer layer;
            layer.z_top = z_top;
            layer.a = to_spectrum(a, s.nbands, "absorption");
            for (auto& bc : b) {
                layer.comp_b.push_back(to_spectrum(bc, s.nbands, "scattering"));
                for (int k = 0; k < s.nbands; ++k) layer.b.v[k] += layer.comp_b.back().v[k];
            }
            w.layers.push_back(layer);
            return int(w.layers.size()) - 1;
        }, py::arg("water"), py::arg("z_top"), py::arg("absorption"), py::arg("scattering"),
           "A layer of stratified water below the previous one: its IOPs for z <= z_top (m), one "
           "scattering spectrum per component (the components' phase functions are the water's).")
        .def("set_water_grid", [](Scene& s, int water, std::array<double, 3> lo, std::array<double, 3> hi,
                                  std::vector<py::array_t<float, py::array::c_style | py::array::forcecast>> rho,
                                  std::vector<DArray> a, std::vector<std::vector<DArray>> b, int threads) {
            if (water < 0 || water >= int(s.waters.size())) throw std::invalid_argument("bad water index");
            Water& w = s.waters[water];
            const int nf = int(rho.size());
            if (nf < 1 || nf > VoxelGrid::kMaxFields)
                throw std::invalid_argument("a grid holds 1 to 4 density fields");
            if (int(a.size()) != nf || int(b.size()) != nf)
                throw std::invalid_argument("the grid needs unit IOPs (absorption, scattering) per density field");
            int n[3];
            const float* fields[VoxelGrid::kMaxFields];
            for (int f = 0; f < nf; ++f) {
                if (rho[f].ndim() != 3) throw std::invalid_argument("each density must be an (nx, ny, nz) array");
                for (int ax = 0; ax < 3; ++ax) {
                    if (f == 0) n[ax] = int(rho[f].shape(ax));
                    else if (rho[f].shape(ax) != n[ax])
                        throw std::invalid_argument("the density fields must have one shape");
                }
                fields[f] = rho[f].data();
            }
            for (int ax = 0; ax < 3; ++ax) {
                if (!(hi[ax] > lo[ax]) || !std::isfinite(lo[ax]) || !std::isfinite(hi[ax]))
                    throw std::invalid_argument("the grid's box must have finite corners with hi > lo");
                if (n[ax] < 1) throw std::invalid_argument("the grid needs at least one voxel per axis");
            }
            std::vector<WaterLayer> units(nf);
            for (int f = 0; f < nf; ++f) {
                WaterLayer& unit = units[f];
                if (b[f].size() != w.components.size())
                    throw std::invalid_argument("the grid's unit IOPs need one scattering spectrum per component");
                unit.a = to_spectrum(a[f], s.nbands, "absorption");
                for (auto& bc : b[f]) {
                    unit.comp_b.push_back(to_spectrum(bc, s.nbands, "scattering"));
                    for (int k = 0; k < s.nbands; ++k) unit.b.v[k] += unit.comp_b.back().v[k];
                }
                for (int k = 0; k < s.nbands; ++k) {
                    if (unit.a.v[k] < 0.0 || unit.b.v[k] < 0.0)
                        throw std::invalid_argument("the grid's unit IOPs must be >= 0");
                }
            }
            auto g = std::make_shared<VoxelGrid>();
            {
                py::gil_scoped_release release;
                g->build(lo.data(), hi.data(), n, fields, nf, threads);  // checks the densities
            }
            w.grid_units = std::move(units);
            w.grid_nf = nf;
            w.grid = g;
        }, py::arg("water"), py::arg("lo"), py::arg("hi"), py::arg("density"), py::arg("absorption"),
           py::arg("scattering"), py::arg("threads") = 0,
           "3-D IOPs of a water body over the box [lo, hi] from F density fields on one lattice "
           "(a list of F arrays density[f][i, j, k] of one shape, x fastest varying in i; "
           "float32 C-ordered ones are read in place): per voxel its IOPs are the base (its "
           "layer at that height, if it has several) plus, per field, its density times the "
           "field's unit IOPs (absorption[f]: a spectrum; scattering[f]: one spectrum per "
           "component). Built on `threads` threads (0: all cores).")
        .def("add_mesh", [](Scene& s, FArray v, UArray t, int kind, int index) {
            if (v.ndim() != 2 || v.shape(1) != 3 || t.ndim() != 2 || t.shape(1) != 3)
                throw std::invalid_argument("vertices and triangles must be (N, 3) arrays");
            MeshRecord r;
            r.kind = kind == 0 ? SurfaceKind::kOpaque : SurfaceKind::kWaterBoundary;
            r.index = index;
            r.vertices.assign(v.data(), v.data() + v.size());
            r.triangles.assign(t.data(), t.data() + t.size());
            for (uint32_t i : r.triangles)
                if (i >= uint32_t(v.shape(0))) throw std::invalid_argument("triangle index out of range");
            s.meshes.push_back(std::move(r));
            return int(s.meshes.size()) - 1;
        }, py::arg("vertices"), py::arg("triangles"), py::arg("kind"), py::arg("index"))
        .def("set_ocean_roughness", [](Scene& s, double sigma2_up, double sigma2_cross, double wind_azimuth) {
            if (s.ocean_water < 0) throw std::invalid_argument("set the ocean surface first");
            if (!(sigma2_up > 0.0) || !(sigma2_cross > 0.0))
                throw std::invalid_argument("slope variances must be > 0");
            s.ocean_bsdf = RoughInterface(sigma2_up, sigma2_cross, wind_azimuth, s.waters.at(s.ocean_water).ior);
            s.ocean_rough = true;
        }, py::arg("sigma2_up"), py::arg("sigma2_cross"), py::arg("wind_azimuth") = 0.0,
           "Sub-pixel roughness of the ocean surface: per-axis slope variances and the upwind azimuth (rad).")
        .def("set_ocean_flat", [](Scene& s, int water, double z) {
            s.ocean_water = water; s.ocean_flat = true; s.ocean_z = z;
        })
        .def("set_ocean_patch", [](Scene& s, int water, FArray v, UArray t, double x0, double y0,
                                   double lx, double ly, double zmean, std::optional<FArray> normals) {
            s.ocean_water = water; s.ocean_flat = false; s.ocean_z = zmean;
            s.patch_vertices.assign(v.data(), v.data() + v.size());
            s.patch_triangles.assign(t.data(), t.data() + t.size());
            s.patch_x0 = x0; s.patch_y0 = y0; s.patch_lx = lx; s.patch_ly = ly;
            s.patch_normals.clear();
            if (normals) {
                const FArray& n = *normals;
                if (n.ndim() != 2 || n.shape(1) != 3 || n.size() != v.size())
                    throw std::invalid_argument("normals must be an (N, 3) array, one per vertex");
                for (py::ssize_t i = 0; i < n.shape(0); ++i)
                    if (!(n.at(i, 2) > 0.0f))
                        throw std::invalid_argument("patch normals must point up (z > 0)");
                s.patch_normals.assign(n.data(), n.data() + n.size());
            }
        }, py::arg("water"), py::arg("vertices"), py::arg("triangles"), py::arg("x0"), py::arg("y0"),
           py::arg("lx"), py::arg("ly"), py::arg("zmean"), py::arg("normals") = py::none(),
           "Periodic height-field ocean patch; optional exact vertex normals for the beams "
           "(default: area-weighted normals of the mesh, averaged across the seams).")
        .def("set_bottom", [](Scene& s, double z, int material) {
            s.has_bottom = true; s.bottom_z = z; s.bottom_material = material;
        })
        .def("set_sun", [](Scene& s, std::array<double, 3> dir, DArray radiance, double cos_half) {
            s.has_sun = true;
            s.sun_dir = normalize(to_vec(dir));
            s.sun_radiance = to_spectrum(radiance, s.nbands, "sun radiance");
            s.sun_cos_half = cos_half;
        })
        .def("set_sky_table", [](Scene& s, DArray table) {
            if (table.ndim() != 2 || table.shape(0) < 2 || table.shape(1) < 1)
                throw std::invalid_argument("sky table must be (n_theta >= 2, n_phi >= 1)");
            s.sky_nt = int(table.shape(0)); s.sky_np = int(table.shape(1));
            s.sky_table.assign(table.data(), table.data() + table.size());
        }, py::arg("table"), "Relative sky radiance on (zenith 0..90 deg) x (azimuth 0..360 deg, periodic) nodes; sky type 3.")
        .def("set_sky_table_bands", [](Scene& s, DArray table) {
            if (table.ndim() != 3 || table.shape(0) < 2 || table.shape(1) < 1 || table.shape(2) != s.nbands)
                throw std::invalid_argument("sky table must be (n_theta >= 2, n_phi >= 1, nbands)");
            s.sky_nt = int(table.shape(0)); s.sky_np = int(table.shape(1));
            s.sky_table.assign(table.data(), table.data() + table.size());
        }, py::arg("table"), "Relative sky radiance per band on (zenith 0..90 deg) x (azimuth 0..360 deg) nodes; sky type 4.")
        .def("set_sky", [](Scene& s, int type, DArray l0, bool full_sphere) {
            s.sky_type = type;
            s.sky_l0 = to_spectrum(l0, s.nbands, "sky radiance");
            s.sky_full_sphere = full_sphere;
        })
        .def("add_camera", [](Scene& s, bool ortho, std::array<double, 3> pos, std::array<double, 3> fwd,
                              std::array<double, 3> up, double fov_deg, double ortho_width, int w, int h,
                              int filter, double filter_width, std::array<double, 2> shift, double clip_start) {
            Camera c;
            c.orthographic = ortho;
            c.position = to_vec(pos);
            c.forward = normalize(to_vec(fwd));
            c.right = normalize(cross(c.forward, to_vec(up)));
            c.up = cross(c.right, c.forward);
            c.tan_half_fov = std::tan(0.5 * fov_deg * kPi / 180.0);
            c.ortho_width = ortho_width;
            c.width = w; c.height = h; c.filter = filter; c.filter_width = filter_width;
            c.shift_x = shift[0]; c.shift_y = shift[1]; c.clip_start = clip_start;
            s.cameras.push_back(c);
            return int(s.cameras.size()) - 1;
        })
        .def("add_radiometer", [](Scene& s, int quantity, std::array<double, 3> pos, std::array<double, 3> dir,
                                  double half_angle_deg, int polar_bins, int azimuth_bins) {
            Radiometer r;
            r.quantity = Quantity(quantity);
            r.position = to_vec(pos);
            r.direction = normalize(to_vec(dir));
            r.cos_half_angle = std::cos(half_angle_deg * kPi / 180.0);
            r.polar_bins = polar_bins; r.azimuth_bins = azimuth_bins;
            s.radiometers.push_back(r);
            return int(s.radiometers.size()) - 1;
        })
        .def("commit", [](Scene& s) { py::gil_scoped_release nogil; s.commit(); })
        .def("medium_at", [](const Scene& s, std::array<double, 3> p) { return s.medium_at(to_vec(p)); })
        .def("inside_opaque", [](const Scene& s, std::array<double, 3> p) { return s.inside_opaque(to_vec(p)); },
             "Whether p lies inside a closed opaque object (most of six rays meet one from behind).")
        .def("camera_medium", [](const Scene& s, int i) { return s.cameras.at(i).medium; })
        .def("radiometer_medium", [](const Scene& s, int i) { return s.radiometers.at(i).medium; })
        .def("radiometer_bins", [](const Scene& s, int i) { return s.radiometers.at(i).bins(); })
        .def_property_readonly("extent", &Scene::scene_extent)
        .def("cancel", [](Scene& s) { s.cancel_flag.store(true); })
        .def("reset_cancel", [](Scene& s) { s.cancel_flag.store(false); })
        .def_property_readonly("cancelled", [](const Scene& s) { return s.cancel_flag.load(); })
        .def("render_camera", [](const Scene& s, int cam, uint64_t start, uint64_t count, int threads, py::object out,
                                 py::object active, py::object rows) {
            const Camera& c = s.cameras.at(cam);
            int row0 = 0, row1 = c.height;
            if (!rows.is_none()) {
                auto t = rows.cast<std::pair<int, int>>();
                row0 = t.first; row1 = t.second;
                if (row0 < 0 || row1 > c.height || row0 >= row1)
                    throw std::invalid_argument("rows: expected (first, end) with 0 <= first < end <= height");
            }
            auto [sum, sq] = pass_buffers(out, {row1 - row0, c.width, kNumComponents, s.nbands});
            py::array_t<uint8_t, py::array::c_style | py::array::forcecast> mask;
            if (!active.is_none()) {
                mask = active.cast<py::array_t<uint8_t, py::array::c_style | py::array::forcecast>>();
                if (mask.ndim() != 2 || mask.shape(0) != c.height || mask.shape(1) != c.width)
                    throw std::invalid_argument("active: expected a (height, width) mask of the camera's pixels");
            }
            Counters cnt;
            {
                py::gil_scoped_release nogil;
                s.render_camera(cam, start, count, threads, sum.mutable_data(), sq.mutable_data(), &cnt,
                                active.is_none() ? nullptr : mask.data(), row0, row1);
            }
            return py::make_tuple(sum, sq, counters_dict(cnt));
        }, py::arg("camera"), py::arg("start"), py::arg("count"), py::arg("threads") = 0, py::arg("out") = py::none(),
           py::arg("active") = py::none(), py::arg("rows") = py::none(),
           "One pass of samples [start, start + count) per pixel: (sum, sum of squares, counters); "
           "out = (sum, sum of squares) arrays to fill instead of new ones; active = a (height, "
           "width) mask: pixels where it is 0 take no samples (their sums are 0); rows = (first, "
           "end): only those rows (the sums' first axis has end - first rows).")
        .def("camera_guides", [](const Scene& s, int cam, int per_axis, int threads, std::optional<std::pair<int, int>> rows) {
            const Camera& c = s.cameras.at(cam);
            if (per_axis < 1 || per_axis > 16) throw std::invalid_argument("per_axis: expected 1..16");
            int r0 = 0, r1 = c.height;
            if (rows) {
                r0 = rows->first; r1 = rows->second;
                if (r0 < 0 || r1 > c.height || r0 >= r1) throw std::invalid_argument("rows: expected 0 <= first < end <= height");
            }
            py::array_t<float> albedo({r1 - r0, c.width, s.nbands}), normal({r1 - r0, c.width, 3});
            {
                py::gil_scoped_release nogil;
                s.camera_guides(cam, per_axis, threads, albedo.mutable_data(), normal.mutable_data(), r0, r1);
            }
            return py::make_tuple(albedo, normal);
        }, py::arg("camera"), py::arg("per_axis") = 2, py::arg("threads") = 0, py::arg("rows") = py::none(),
           "Denoising guides of a camera, (albedo (H, W, bands), normal (H, W, 3)) float32, from "
           "per_axis^2 fixed sub-pixel rays per pixel (Scene::camera_guides); rows = (first, end): "
           "only those rows.")
        .def("render_radiometer", [](const Scene& s, int rad, uint64_t start, uint64_t count, int threads, py::object out,
                                     py::object moments) {
            int nbins = s.radiometers.at(rad).bins();
            auto [sum, sq] = pass_buffers(out, {nbins, kNumComponents, s.nbands});
            double* mom = nullptr;
            if (!moments.is_none()) {
                auto a = moments.cast<py::array>();
                if (!py::isinstance<py::array_t<double>>(a) || !(a.flags() & py::array::c_style) || !a.writeable() ||
                    std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()) != std::vector<py::ssize_t>{nbins, 3, s.nbands})
                    throw std::invalid_argument("moments: expected a writable C-contiguous float64 (bins, 3, bands) array");
                mom = static_cast<double*>(a.mutable_data());
            }
            Counters cnt;
            {
                py::gil_scoped_release nogil;
                s.render_radiometer(rad, start, count, threads, sum.mutable_data(), sq.mutable_data(), &cnt, mom);
            }
            return py::make_tuple(sum, sq, counters_dict(cnt));
        }, py::arg("radiometer"), py::arg("start"), py::arg("count"), py::arg("threads") = 0, py::arg("out") = py::none(),
           py::arg("moments") = py::none(),
           "One pass of samples [start, start + count): (sum, sum of squares, counters); out as for "
           "render_camera; moments: a (bins, 3, bands) array filled with the total's central sums of "
           "powers 2, 3, 4 about the pass's mean.")
        .def("trace_rays", [](const Scene& s, FArray o, FArray d, int threads, py::object tmax) {
            if (o.ndim() != 2 || o.shape(1) != 3 || d.ndim() != 2 || d.shape(1) != 3 || o.shape(0) != d.shape(0))
                throw std::invalid_argument("origins and directions must be matching (N, 3) arrays");
            size_t n = size_t(o.shape(0));
            FArray tm;
            if (!tmax.is_none()) {
                tm = tmax.cast<FArray>();
                if (tm.ndim() != 1 || size_t(tm.shape(0)) != n)
                    throw std::invalid_argument("tmax must be an (N,) array matching the rays");
            }
            FArray t(n);
            {
                py::gil_scoped_release nogil;
                s.trace_rays(o.data(), d.data(), n, threads, t.mutable_data(), tmax.is_none() ? nullptr : tm.data());
            }
            return t;
        }, py::arg("origins"), py::arg("directions"), py::arg("threads") = 0, py::arg("tmax") = py::none(),
           "Closest-hit distances (-1 for a miss) of the main Embree scene: raw ray throughput; "
           "tmax: per-ray far limits (default: rays to infinity).");
    bind_test_probes(scene);  // bind_test_probes.cpp: checks for the tests only
}
