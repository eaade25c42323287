// The part of Embree 4's C API that the core uses, declared here: the Embree the core traces
// with is the one the embreex wheel ships (libembree4 in embreex.libs/), and wheels carry no
// headers. Written from Embree's documentation, with include/embree4/*.h (4.3, 4.4) as the
// reference for the ABI; numbers and layouts must match the library's, not its spelling.
//
// The functions are reached through pointers that embree.cpp fills with dlsym when `_core` is
// imported (photic/embree.py says where the library is). The inline wrappers below keep the
// API's own names, so call sites read as ordinary Embree code. Everything is in namespace
// photic: no C symbol of ours can clash with an Embree 3 or 4 that the host process (Blender)
// has loaded under the same names.
//
// Struct layouts depend on how the library was configured. Declared here: Embree's defaults,
// RTC_MAX_INSTANCE_LEVEL_COUNT 1 and EMBREE_GEOMETRY_INSTANCE_ARRAY on (instPrimID after
// instID), as in the embreex wheels; embree.cpp checks the loaded library against them at
// start-up (a ray and a point query into guarded buffers) and refuses any other.
#pragma once
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>
#if !defined(_WIN32)
#include <sys/types.h>  // ssize_t
#endif

namespace photic {

#if defined(_WIN32)
using ssize_t = long long;  // as Embree's header declares it on 64-bit Windows
#endif

constexpr unsigned int RTC_INVALID_GEOMETRY_ID = ~0u;
constexpr int RTC_MAX_INSTANCE_LEVEL_COUNT = 1;  // checked at start-up (embree.cpp)

typedef struct RTCDeviceTy* RTCDevice;
typedef struct RTCSceneTy* RTCScene;
typedef struct RTCGeometryTy* RTCGeometry;

// Enums: only the values used; C enums are int-sized in the library's ABI.
enum RTCFormat : int { RTC_FORMAT_UINT3 = 0x5003, RTC_FORMAT_FLOAT3 = 0x9003, RTC_FORMAT_FLOAT3X4_ROW_MAJOR = 0x9134 };
enum RTCBuildQuality : int { RTC_BUILD_QUALITY_LOW = 0, RTC_BUILD_QUALITY_MEDIUM = 1, RTC_BUILD_QUALITY_HIGH = 2 };
enum RTCBufferType : int { RTC_BUFFER_TYPE_INDEX = 0, RTC_BUFFER_TYPE_VERTEX = 1, RTC_BUFFER_TYPE_TRANSFORM = 23 };
enum RTCGeometryType : int { RTC_GEOMETRY_TYPE_TRIANGLE = 0, RTC_GEOMETRY_TYPE_INSTANCE_ARRAY = 122 };
enum RTCSceneFlags : int { RTC_SCENE_FLAG_NONE = 0, RTC_SCENE_FLAG_ROBUST = 1 << 2 };
enum RTCDeviceProperty : int {
    RTC_DEVICE_PROPERTY_VERSION = 0,  // e.g. 40400 for 4.4.0
    RTC_DEVICE_PROPERTY_VERSION_MAJOR = 1,
    RTC_DEVICE_PROPERTY_VERSION_MINOR = 2,
    RTC_DEVICE_PROPERTY_VERSION_PATCH = 3,
    RTC_DEVICE_PROPERTY_TASKING_SYSTEM = 128,
};
enum RTCError : int {
    RTC_ERROR_NONE = 0,
    RTC_ERROR_UNKNOWN = 1,
    RTC_ERROR_INVALID_ARGUMENT = 2,
    RTC_ERROR_INVALID_OPERATION = 3,
    RTC_ERROR_OUT_OF_MEMORY = 4,
    RTC_ERROR_UNSUPPORTED_CPU = 5,
    RTC_ERROR_CANCELLED = 6,
};
enum RTCRayQueryFlags : int { RTC_RAY_QUERY_FLAG_INCOHERENT = 0, RTC_RAY_QUERY_FLAG_COHERENT = 1 << 16 };
enum RTCFeatureFlags : unsigned int { RTC_FEATURE_FLAG_ALL = 0xffffffffu };

struct alignas(16) RTCRay {
    float org_x, org_y, org_z, tnear;
    float dir_x, dir_y, dir_z, time;
    float tfar;           // the hit distance after rtcIntersect1; -inf after rtcOccluded1 when blocked
    unsigned int mask;    // hits geometries whose mask (default 1 in Embree 4) shares a bit
    unsigned int id, flags;
};

struct alignas(16) RTCHit {
    float Ng_x, Ng_y, Ng_z;  // unnormalised geometric normal, (v1 - v0) x (v2 - v0)
    float u, v;
    unsigned int primID, geomID;
    unsigned int instID[RTC_MAX_INSTANCE_LEVEL_COUNT];
    unsigned int instPrimID[RTC_MAX_INSTANCE_LEVEL_COUNT];  // (instance arrays, Embree >= 4.3)
};

struct RTCRayHit {
    RTCRay ray;
    RTCHit hit;
};

// Instance stacks for callbacks and manual instancing (one level: no instStackSize member).
struct RTCRayQueryContext {
    unsigned int instID[RTC_MAX_INSTANCE_LEVEL_COUNT];
    unsigned int instPrimID[RTC_MAX_INSTANCE_LEVEL_COUNT];
};

inline void rtcInitRayQueryContext(RTCRayQueryContext* c) {
    c->instID[0] = RTC_INVALID_GEOMETRY_ID;
    c->instPrimID[0] = RTC_INVALID_GEOMETRY_ID;
}

// Optional arguments of rtcIntersect1 and rtcOccluded1 (a null pointer: the defaults, and a
// context of the library's own). The last member exists only in libraries built with
// EMBREE_MIN_WIDTH; declaring it always is harmless (read or not, it is 0) and never too short.
struct RTCIntersectArguments {
    RTCRayQueryFlags flags;
    RTCFeatureFlags feature_mask;
    RTCRayQueryContext* context;
    void* filter;     // RTCFilterFunctionN
    void* intersect;  // RTCIntersectFunctionN (RTCOccludedFunctionN in RTCOccludedArguments)
    float minWidthDistanceFactor;
};
using RTCOccludedArguments = RTCIntersectArguments;  // the same layout

inline void rtcInitIntersectArguments(RTCIntersectArguments* a) {
    a->flags = RTC_RAY_QUERY_FLAG_INCOHERENT;
    a->feature_mask = RTC_FEATURE_FLAG_ALL;
    a->context = nullptr;
    a->filter = nullptr;
    a->intersect = nullptr;
    a->minWidthDistanceFactor = 0.0f;
}
inline void rtcInitOccludedArguments(RTCOccludedArguments* a) { rtcInitIntersectArguments(a); }

struct alignas(16) RTCPointQuery {
    float x, y, z, time, radius;
};

struct alignas(16) RTCPointQueryContext {
    float world2inst[RTC_MAX_INSTANCE_LEVEL_COUNT][16];
    float inst2world[RTC_MAX_INSTANCE_LEVEL_COUNT][16];
    unsigned int instID[RTC_MAX_INSTANCE_LEVEL_COUNT];
    unsigned int instPrimID[RTC_MAX_INSTANCE_LEVEL_COUNT];
    unsigned int instStackSize;
};

inline void rtcInitPointQueryContext(RTCPointQueryContext* c) {
    c->instStackSize = 0;
    c->instID[0] = RTC_INVALID_GEOMETRY_ID;
    c->instPrimID[0] = RTC_INVALID_GEOMETRY_ID;
}

struct alignas(16) RTCPointQueryFunctionArguments {
    RTCPointQuery* query;  // its radius may be shrunk by the callback
    void* userPtr;
    unsigned int primID, geomID;
    RTCPointQueryContext* context;
    float similarityScale;
};
typedef bool (*RTCPointQueryFunction)(RTCPointQueryFunctionArguments* args);
typedef void (*RTCErrorFunction)(void* userPtr, RTCError code, const char* str);

// The layouts of Embree 4.3/4.4's headers for x86-64 and arm64 (LP64 and LLP64 alike).
static_assert(sizeof(RTCRay) == 48 && offsetof(RTCRay, tfar) == 32 && offsetof(RTCRay, flags) == 44, "RTCRay");
static_assert(offsetof(RTCHit, u) == 12 && offsetof(RTCHit, primID) == 20 && offsetof(RTCHit, geomID) == 24 &&
              offsetof(RTCHit, instID) == 28 && offsetof(RTCHit, instPrimID) == 32 && sizeof(RTCHit) == 48, "RTCHit");
static_assert(offsetof(RTCRayHit, hit) == 48 && sizeof(RTCRayHit) == 96, "RTCRayHit");
static_assert(offsetof(RTCIntersectArguments, context) == 8 && offsetof(RTCIntersectArguments, filter) == 16 &&
              offsetof(RTCIntersectArguments, intersect) == 24 && offsetof(RTCIntersectArguments, minWidthDistanceFactor) == 32,
              "RTCIntersectArguments");
static_assert(sizeof(RTCPointQuery) == 32, "RTCPointQuery");
static_assert(offsetof(RTCPointQueryContext, instID) == 128 && offsetof(RTCPointQueryContext, instStackSize) == 136 &&
              sizeof(RTCPointQueryContext) == 144, "RTCPointQueryContext");
static_assert(offsetof(RTCPointQueryFunctionArguments, primID) == 16 &&
              offsetof(RTCPointQueryFunctionArguments, context) == 24 &&
              offsetof(RTCPointQueryFunctionArguments, similarityScale) == 32, "RTCPointQueryFunctionArguments");

// The functions used: X(return type, name, parameters, arguments). embree.cpp looks each up
// by its name; a library without one is refused at start-up.
#define PHOTIC_EMBREE_FUNCTIONS(X)                                                                       \
    X(RTCDevice, rtcNewDevice, (const char* config), (config))                                           \
    X(void, rtcReleaseDevice, (RTCDevice device), (device))                                              \
    X(ssize_t, rtcGetDeviceProperty, (RTCDevice device, RTCDeviceProperty prop), (device, prop))        \
    X(RTCError, rtcGetDeviceError, (RTCDevice device), (device))                                         \
    X(void, rtcSetDeviceErrorFunction, (RTCDevice device, RTCErrorFunction f, void* userPtr),            \
      (device, f, userPtr))                                                                              \
    X(RTCScene, rtcNewScene, (RTCDevice device), (device))                                               \
    X(void, rtcReleaseScene, (RTCScene scene), (scene))                                                  \
    X(void, rtcSetSceneFlags, (RTCScene scene, RTCSceneFlags flags), (scene, flags))                     \
    X(void, rtcSetSceneBuildQuality, (RTCScene scene, RTCBuildQuality q), (scene, q))                    \
    X(void, rtcCommitScene, (RTCScene scene), (scene))                                                   \
    X(RTCGeometry, rtcNewGeometry, (RTCDevice device, RTCGeometryType type), (device, type))             \
    X(void*, rtcSetNewGeometryBuffer,                                                                    \
      (RTCGeometry g, RTCBufferType type, unsigned int slot, RTCFormat format, size_t byteStride,        \
       size_t itemCount),                                                                                \
      (g, type, slot, format, byteStride, itemCount))                                                    \
    X(void, rtcCommitGeometry, (RTCGeometry g), (g))                                                     \
    X(void, rtcSetGeometryInstancedScene, (RTCGeometry g, RTCScene scene), (g, scene))                   \
    X(unsigned int, rtcAttachGeometry, (RTCScene scene, RTCGeometry g), (scene, g))                      \
    X(void, rtcReleaseGeometry, (RTCGeometry g), (g))                                                    \
    X(void, rtcIntersect1, (RTCScene scene, RTCRayHit* rayhit, RTCIntersectArguments* args),             \
      (scene, rayhit, args))                                                                             \
    X(void, rtcOccluded1, (RTCScene scene, RTCRay* ray, RTCOccludedArguments* args), (scene, ray, args)) \
    X(bool, rtcPointQuery,                                                                               \
      (RTCScene scene, RTCPointQuery* query, RTCPointQueryContext* context, RTCPointQueryFunction f,     \
       void* userPtr),                                                                                   \
      (scene, query, context, f, userPtr))

struct EmbreeFunctions {
#define PHOTIC_EMBREE_POINTER(ret, name, params, args) ret(*name) params = nullptr;
    PHOTIC_EMBREE_FUNCTIONS(PHOTIC_EMBREE_POINTER)
#undef PHOTIC_EMBREE_POINTER
};
extern EmbreeFunctions embree_functions;  // filled by load_embree (embree.cpp)

// The API's calls by their own names (rtcIntersect1 and rtcOccluded1 with optional arguments,
// as in the API's C++ header).
#define PHOTIC_EMBREE_WRAPPER(ret, name, params, args) \
    inline ret name params { return embree_functions.name args; }
PHOTIC_EMBREE_FUNCTIONS(PHOTIC_EMBREE_WRAPPER)
#undef PHOTIC_EMBREE_WRAPPER
inline void rtcIntersect1(RTCScene scene, RTCRayHit* rayhit) { embree_functions.rtcIntersect1(scene, rayhit, nullptr); }
inline void rtcOccluded1(RTCScene scene, RTCRay* ray) { embree_functions.rtcOccluded1(scene, ray, nullptr); }

// --- the loader (embree.cpp) ---------------------------------------------------------------------

// Loads Embree 4 from `path` (a libembree4 shared library) and checks it: a device, version 4.3
// or later of major version 4, and the struct layouts above on a one-triangle scene. Returns a
// one-line description ("Embree 4.4.0 from PATH"). Throws std::runtime_error with the reason.
// Once loaded, later calls return the same description (only one Embree per process).
std::string load_embree(const std::string& path);
const std::string& embree_description();

// Embree's errors as exceptions: devices made by new_embree_device record errors through their
// callback, and check_embree throws the first one recorded on this thread since the last check.
struct EmbreeError : std::runtime_error {
    using std::runtime_error::runtime_error;
};
RTCDevice new_embree_device();
void check_embree(const char* what);

// A committed scene of triangle meshes, geometry ids 0, 1, ... in order; robust traversal
// (no misses through shared edges) over a high-quality BVH. Throws EmbreeError. A mesh with
// instances is built once as a scene of its own (the bottom level) and placed by an instance
// array (its geometry id in the top level): a hit on copy k of it has instID[0] = that id,
// instPrimID[0] = k, and geomID 0, primID and Ng in the mesh's own frame.
struct TriangleMeshView {
    const float* vertices;      // xyz
    size_t nv;
    const uint32_t* triangles;  // ijk
    size_t nt;
    const float* instances = nullptr;  // ninst transforms, 3 x 4 row-major [R | t]; none: not instanced
    size_t ninst = 0;
};
RTCScene new_triangle_scene(RTCDevice device, const std::vector<TriangleMeshView>& meshes);

}  // namespace photic
