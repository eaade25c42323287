// Loading Embree 4 at run time (see embree4_api.h), its start-up checks, devices whose errors
// become exceptions, and the triangle scenes the core traces.
#include "embree4_api.h"
#include <cmath>
#include <cstring>
#include <mutex>
#ifdef _WIN32
#include <windows.h>
#else
#include <dlfcn.h>
#endif

namespace photic {

EmbreeFunctions embree_functions;

namespace {

std::string g_description;  // set once the library passed its checks

const char* error_name(RTCError code) {
    switch (code) {
        case RTC_ERROR_NONE: return "RTC_ERROR_NONE";
        case RTC_ERROR_UNKNOWN: return "RTC_ERROR_UNKNOWN";
        case RTC_ERROR_INVALID_ARGUMENT: return "RTC_ERROR_INVALID_ARGUMENT";
        case RTC_ERROR_INVALID_OPERATION: return "RTC_ERROR_INVALID_OPERATION";
        case RTC_ERROR_OUT_OF_MEMORY: return "RTC_ERROR_OUT_OF_MEMORY";
        case RTC_ERROR_UNSUPPORTED_CPU: return "RTC_ERROR_UNSUPPORTED_CPU";
        case RTC_ERROR_CANCELLED: return "RTC_ERROR_CANCELLED";
    }
    return "RTC_ERROR (unknown code)";
}

// Embree reports an error on the thread whose call failed (also for a scene build that its
// worker threads run), so the first one since the last check is kept per thread.
thread_local std::string t_error;

void on_error(void*, RTCError code, const char* str) {
    if (t_error.empty()) t_error = std::string(error_name(code)) + (str && *str ? std::string(": ") + str : "");
}

#ifdef _WIN32
// Not built here: Windows would load embree4.dll with its TBB from the same folder.
void* open_library(const std::string& path, std::string* err) {
    HMODULE h = LoadLibraryExA(path.c_str(), nullptr, LOAD_LIBRARY_SEARCH_DLL_LOAD_DIR | LOAD_LIBRARY_SEARCH_DEFAULT_DIRS);
    if (!h) *err = "LoadLibraryEx failed with error " + std::to_string(GetLastError());
    return reinterpret_cast<void*>(h);
}
void* find_symbol(void* lib, const char* name) {
    return reinterpret_cast<void*>(GetProcAddress(reinterpret_cast<HMODULE>(lib), name));
}
#else
void* open_library(const std::string& path, std::string* err) {
    int flags = RTLD_NOW | RTLD_LOCAL;
#ifdef RTLD_DEEPBIND
    // The library's calls to its own exported functions and to its TBB bind inside it and the
    // TBB beside it, not to an Embree or TBB the host has loaded first under the same names
    // (Debian's Blender links libembree3 and libtbb; glibc would bind to those first).
    flags |= RTLD_DEEPBIND;
#endif
    void* h = dlopen(path.c_str(), flags);
    if (!h) *err = dlerror();
    return h;
}
void* find_symbol(void* lib, const char* name) { return dlsym(lib, name); }
#endif

// The struct layouts of embree4_api.h against the library's: a ray hits a triangle with its
// hit in a buffer whose words past geomID carry a marker; the library must write exactly
// instID[0] and instPrimID[0] (one instance level, instance arrays), nothing beyond RTCHit, and
// the values where they are declared; then an occlusion ray and a point query.
void check_layouts(RTCDevice device) {
    const float v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t t[3] = {0, 1, 2};
    RTCScene scene = new_triangle_scene(device, {{v, 3, t, 1}});
    constexpr unsigned kMark = 0x5a5a5a5au;
    struct alignas(16) Guarded {
        RTCRayHit rh;
        unsigned guard[8];
    } g;
    std::memset(&g, 0x5a, sizeof g);
    RTCRay& r = g.rh.ray;
    r.org_x = 0.25f; r.org_y = 0.5f; r.org_z = 2.0f; r.tnear = 0.0f;
    r.dir_x = 0.0f; r.dir_y = 0.0f; r.dir_z = -1.0f; r.time = 0.0f;
    r.tfar = INFINITY; r.mask = 0xFFFFFFFFu; r.id = 0; r.flags = 0;
    g.rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &g.rh);
    const RTCHit& h = g.rh.hit;
    std::string bad;
    auto near = [](float a, float b) { return std::fabs(a - b) < 1e-6f; };
    if (h.geomID != 0 || h.primID != 0 || !near(r.tfar, 2.0f) || !near(h.u, 0.25f) || !near(h.v, 0.5f) ||
        !near(h.Ng_x, 0.0f) || !near(h.Ng_y, 0.0f) || !(h.Ng_z > 0.0f))
        bad = "a ray's hit is not where RTCRayHit declares it";
    else if (h.instID[0] != RTC_INVALID_GEOMETRY_ID || h.instPrimID[0] != RTC_INVALID_GEOMETRY_ID)
        bad = "the hit's instance ids differ (built without EMBREE_GEOMETRY_INSTANCE_ARRAY, or Embree < 4.3?)";
    else
        for (unsigned w : g.guard)
            if (w != kMark) bad = "it writes past RTCHit (RTC_MAX_INSTANCE_LEVEL_COUNT > 1?)";
    RTCRay o = r;
    o.tfar = INFINITY;
    rtcOccluded1(scene, &o);
    if (bad.empty() && !(o.tfar < 0.0f)) bad = "an occlusion ray through a triangle was not blocked";

    struct Found {
        RTCPointQuery* query;
        RTCPointQueryContext* context;
        int calls = 0;
        bool ok = true;
    };
    RTCPointQuery pq{0.25f, 0.25f, 0.0f, 0.0f, 1.0f};
    RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    Found found{&pq, &ctx};
    rtcPointQuery(scene, &pq, &ctx, [](RTCPointQueryFunctionArguments* a) {
        auto* f = static_cast<Found*>(a->userPtr);
        f->calls++;
        f->ok = f->ok && a->query == f->query && a->context == f->context && a->geomID == 0 && a->primID == 0 &&
                a->similarityScale == 1.0f;
        return false;
    }, &found);
    if (bad.empty() && !(found.calls == 1 && found.ok)) bad = "a point query's callback arguments differ";
    rtcReleaseScene(scene);
    check_embree("the start-up checks");
    if (!bad.empty())
        throw EmbreeError("this Embree's data layouts differ from those the core was built for: " + bad);
}

}  // namespace

std::string load_embree(const std::string& path) {
    static std::mutex mutex;
    std::lock_guard<std::mutex> lock(mutex);
    if (!g_description.empty()) return g_description;
    std::string err;
    void* lib = open_library(path, &err);
    if (!lib) throw EmbreeError("cannot load Embree from " + path + ": " + err);
    EmbreeFunctions f;
    std::string missing;
#define PHOTIC_EMBREE_LOOKUP(ret, name, params, args)                        \
    f.name = reinterpret_cast<ret(*) params>(find_symbol(lib, #name)); \
    if (!f.name) missing += " " #name;
    PHOTIC_EMBREE_FUNCTIONS(PHOTIC_EMBREE_LOOKUP)
#undef PHOTIC_EMBREE_LOOKUP
    if (!missing.empty()) throw EmbreeError(path + " is not an Embree 4 library: it lacks" + missing);
    embree_functions = f;
    // Left open on failure too: a library cannot be safely unloaded once its code has run.
    try {
        RTCDevice device = rtcNewDevice(nullptr);
        if (!device)
            throw EmbreeError(std::string("Embree could not create a device: ") + error_name(rtcGetDeviceError(nullptr)));
        rtcSetDeviceErrorFunction(device, on_error, nullptr);
        const ssize_t version = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION);
        const ssize_t major = version / 10000, minor = version / 100 % 100, patch = version % 100;
        const std::string text = std::to_string(major) + "." + std::to_string(minor) + "." + std::to_string(patch);
        try {
            if (major != 4 || minor < 3)
                throw EmbreeError("Embree " + text + " from " + path +
                                  ": the core needs Embree 4, version 4.3 or later (its API and layouts)");
            check_layouts(device);
        } catch (...) {
            rtcReleaseDevice(device);
            throw;
        }
        rtcReleaseDevice(device);
        g_description = "Embree " + text + " from " + path;
    } catch (...) {
        embree_functions = EmbreeFunctions{};
        t_error.clear();
        throw;
    }
    return g_description;
}

const std::string& embree_description() { return g_description; }

RTCDevice new_embree_device() {
    if (g_description.empty()) throw EmbreeError("Embree is not loaded (photic._core loads it when imported)");
    RTCDevice device = rtcNewDevice(nullptr);
    if (!device) throw EmbreeError(std::string("Embree could not create a device: ") + error_name(rtcGetDeviceError(nullptr)));
    rtcSetDeviceErrorFunction(device, on_error, nullptr);
    return device;
}

void check_embree(const char* what) {
    if (t_error.empty()) return;
    std::string msg = std::string("Embree failed in ") + what + ": " + t_error;
    t_error.clear();
    throw EmbreeError(msg);
}

RTCScene new_triangle_scene(RTCDevice device, const std::vector<TriangleMeshView>& meshes) {
    RTCScene scene = rtcNewScene(device);
    check_embree("rtcNewScene");
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    try {
        for (const TriangleMeshView& m : meshes) {
            if (m.instances) {  // the mesh as a scene of its own, placed by an instance array
                TriangleMeshView own = m;
                own.instances = nullptr;
                RTCScene bottom = new_triangle_scene(device, {own});
                RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE_ARRAY);
                if (!g) {
                    rtcReleaseScene(bottom);
                    check_embree("rtcNewGeometry (instance array)");
                    throw EmbreeError("Embree could not create an instance array");
                }
                rtcSetGeometryInstancedScene(g, bottom);  // (the geometry keeps a reference)
                rtcReleaseScene(bottom);
                auto* xb = static_cast<float*>(rtcSetNewGeometryBuffer(
                    g, RTC_BUFFER_TYPE_TRANSFORM, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR, 12 * sizeof(float), m.ninst));
                if (!xb) {
                    rtcReleaseGeometry(g);
                    check_embree("rtcSetNewGeometryBuffer (transforms)");
                    throw EmbreeError("Embree could not allocate an instance array's transforms");
                }
                std::memcpy(xb, m.instances, 12 * m.ninst * sizeof(float));
                rtcCommitGeometry(g);
                rtcAttachGeometry(scene, g);
                rtcReleaseGeometry(g);
                check_embree("adding an instance array");
                continue;
            }
            RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
            check_embree("rtcNewGeometry");
            auto* vb = static_cast<float*>(
                rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.nv));
            auto* ib = static_cast<uint32_t*>(
                rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), m.nt));
            if (!vb || !ib) {
                rtcReleaseGeometry(g);
                check_embree("rtcSetNewGeometryBuffer");
                throw EmbreeError("Embree could not allocate geometry buffers");
            }
            std::memcpy(vb, m.vertices, 3 * m.nv * sizeof(float));
            std::memcpy(ib, m.triangles, 3 * m.nt * sizeof(uint32_t));
            rtcCommitGeometry(g);
            rtcAttachGeometry(scene, g);  // ids are assigned 0, 1, 2, ... in order
            rtcReleaseGeometry(g);
            check_embree("adding a triangle mesh");
        }
        rtcCommitScene(scene);
        check_embree("rtcCommitScene (building the BVH)");
    } catch (...) {
        rtcReleaseScene(scene);
        throw;
    }
    return scene;
}

}  // namespace photic
