// Python bindings of the rough air-water interface BSDF (photic._core.RoughInterface).
// Directions are arrays of shape (3,) or (N, 3); one (3,) argument is broadcast against the
// other. Two (3,) arguments give a float, otherwise an array of shape (N,).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>

#include "rough_interface.h"

namespace py = pybind11;

namespace photic {

namespace {

using DArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

struct Dirs {
    const double* p;
    py::ssize_t n;
    bool single;
    Vec3 at(py::ssize_t k) const {
        const double* q = p + 3 * (single ? 0 : k);
        return Vec3(q[0], q[1], q[2]);
    }
};

Dirs dirs(const DArray& a, const char* what) {
    if (a.ndim() == 1 && a.shape(0) == 3) return {a.data(), 1, true};
    if (a.ndim() == 2 && a.shape(1) == 3) return {a.data(), a.shape(0), false};
    throw std::invalid_argument(std::string("RoughInterface: ") + what + " must have shape (3,) or (N, 3)");
}

RoughInterface::Mode mode_of(const std::string& m) {
    if (m == "radiance") return RoughInterface::kRadiance;
    if (m == "importance") return RoughInterface::kImportance;
    throw std::invalid_argument("RoughInterface: mode must be 'radiance' or 'importance', got '" + m + "'");
}

// Applies fn(wi_k, wo_k) over broadcast pairs of direction arrays.
template <class Fn>
py::object pairwise(const DArray& wi, const DArray& wo, Fn fn) {
    Dirs a = dirs(wi, "wi"), b = dirs(wo, "wo");
    if (a.single && b.single) return py::float_(fn(a.at(0), b.at(0)));
    py::ssize_t n = a.single ? b.n : a.n;
    if (!a.single && !b.single && a.n != b.n)
        throw std::invalid_argument("RoughInterface: wi and wo must have the same number of rows");
    DArray out(n);
    double* o = out.mutable_data();
    for (py::ssize_t k = 0; k < n; ++k) o[k] = fn(a.at(k), b.at(k));
    return std::move(out);
}

}  // namespace

void bind_rough_interface(py::module_& m) {
    py::class_<RoughInterface>(m, "RoughInterface", R"doc(
Rough air-water interface BSDF (Walter et al. 2007 microfacet model, Cox-Munk Gaussian slopes,
height-correlated Smith shadowing). Macro normal +z; air above (+z), water below; directions
point away from the surface. eval(wi, wo) is f in 1/sr without the cosine; sample() returns
weight = f |wo_z| / pdf. mode 'radiance' (camera paths: f carries the n^2 law
(n(wi)/n(wo))^2 on refraction) or 'importance' (light tracing: f transports flux from wi to wo).
See engine/src/core/rough_interface.h and docs/physics.md.)doc")
        .def(py::init<double, double, double, double>(), py::arg("sigma2_up"), py::arg("sigma2_cross"),
             py::arg("wind_azimuth") = 0.0, py::arg("eta") = 1.34,
             "Per-axis slope variances (upwind, crosswind), upwind azimuth (rad from +x), n_water/n_air.")
        .def_property_readonly("sigma2_up", &RoughInterface::sigma2_up)
        .def_property_readonly("sigma2_cross", &RoughInterface::sigma2_cross)
        .def_property_readonly("wind_azimuth", &RoughInterface::wind_azimuth)
        .def_property_readonly("eta", &RoughInterface::eta)
        .def("eval", [](const RoughInterface& r, DArray wi, DArray wo, const std::string& mode) {
                 auto md = mode_of(mode);
                 return pairwise(wi, wo, [&](const Vec3& a, const Vec3& b) { return r.eval(a, b, md); });
             }, py::arg("wi"), py::arg("wo"), py::arg("mode") = "radiance",
             "BSDF value f(wi, wo) in 1/sr, cosine not included.")
        .def("pdf", [](const RoughInterface& r, DArray wi, DArray wo) {
                 return pairwise(wi, wo, [&](const Vec3& a, const Vec3& b) { return r.pdf(a, b); });
             }, py::arg("wi"), py::arg("wo"), "Solid-angle density of sample()'s wo given wi.")
        .def("distribution", [](const RoughInterface& r, DArray h) {
                 Dirs a = dirs(h, "h");
                 DArray out(a.n);
                 for (py::ssize_t k = 0; k < a.n; ++k) out.mutable_data()[k] = r.distribution(a.at(k));
                 return out;
             }, py::arg("h"), "Microfacet distribution D(h) (1/sr) for facet normals with h_z > 0.")
        .def("smith_lambda", [](const RoughInterface& r, DArray w) {
                 Dirs a = dirs(w, "w");
                 DArray out(a.n);
                 for (py::ssize_t k = 0; k < a.n; ++k) out.mutable_data()[k] = r.lambda(a.at(k));
                 return out;
             }, py::arg("w"), "Smith's Lambda for directions w (either side).")
        .def("sample", [](const RoughInterface& r, DArray wi, DArray u1, DArray u2, DArray u3,
                          const std::string& mode) {
                 auto md = mode_of(mode);
                 Dirs a = dirs(wi, "wi");
                 py::ssize_t n = u1.size();
                 if (u2.size() != n || u3.size() != n || (!a.single && a.n != n))
                     throw std::invalid_argument("RoughInterface.sample: u1, u2, u3 (and wi rows) must have equal lengths");
                 DArray wo({n, py::ssize_t(3)}), weight(n), pdf(n);
                 py::array_t<bool> refl(n);
                 double* pw = wo.mutable_data();
                 for (py::ssize_t k = 0; k < n; ++k) {
                     RoughSample s = r.sample(a.at(k), u1.data()[k], u2.data()[k], u3.data()[k], md);
                     pw[3 * k] = s.wo.x; pw[3 * k + 1] = s.wo.y; pw[3 * k + 2] = s.wo.z;
                     weight.mutable_data()[k] = s.weight;
                     pdf.mutable_data()[k] = s.pdf;
                     refl.mutable_data()[k] = s.reflection;
                 }
                 return py::make_tuple(wo, weight, pdf, refl);
             }, py::arg("wi"), py::arg("u1"), py::arg("u2"), py::arg("u3"), py::arg("mode") = "radiance",
             "Samples wo for each row: (wo (N,3), weight = f |wo_z| / pdf, pdf, is_reflection). "
             "Failed samples (wi sees a facet's back, or wo ends on the wrong side) have pdf = weight = 0.");
}

}  // namespace photic
