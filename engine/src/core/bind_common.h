// What the binding files share: array types and small conversions (photic._core).
#pragma once
#include <array>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include "vec.h"

namespace py = pybind11;

namespace photic {

using DArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
using FArray = py::array_t<float, py::array::c_style | py::array::forcecast>;
using UArray = py::array_t<uint32_t, py::array::c_style | py::array::forcecast>;

inline Vec3 to_vec(const std::array<double, 3>& a) { return Vec3(a[0], a[1], a[2]); }

}  // namespace photic
