#include "sizing/local_diameter.h"

#include "core/adjacency.h"
#include "core/errors.h"

#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <type_traits>

namespace scalemesh {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start)
{
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// Embree passes the context pointer of the intersect call to the filter, so a
// struct that begins with RTCIntersectContext carries the origin's fan to it.
// Once a filter is attached every call must pass this extended context.
struct OriginContext {
    RTCIntersectContext base;
    const int32_t* fan_begin = nullptr;
    const int32_t* fan_end = nullptr;
};
static_assert(std::is_standard_layout_v<OriginContext>, "the filter casts back from the first member");

// The ray starts on the triangles of its own vertex fan and about a third of
// the rays would report them at t ~ 0; those are not a re-intersection (eq. 3
// asks for lambda > 0). Most such hits fall below the ray's tnear (see
// RayCaster::cast); the filter rejects the rest, and a ray that runs along a
// fan triangle.
void reject_origin_fan(const RTCFilterFunctionNArguments* args)
{
    const auto* context = reinterpret_cast<const OriginContext*>(args->context);
    for (unsigned i = 0; i < args->N; ++i) {
        if (args->valid[i] == 0) continue;
        const auto prim = static_cast<int32_t>(RTCHitN_primID(args->hit, args->N, i));
        if (std::find(context->fan_begin, context->fan_end, prim) != context->fan_end) args->valid[i] = 0;
    }
}

struct DeviceDeleter {
    void operator()(RTCDevice device) const { rtcReleaseDevice(device); }
};
struct SceneDeleter {
    void operator()(RTCScene scene) const { rtcReleaseScene(scene); }
};
using DevicePtr = std::unique_ptr<RTCDeviceTy, DeviceDeleter>;
using ScenePtr = std::unique_ptr<RTCSceneTy, SceneDeleter>;

void check_device(RTCDevice device, const char* step)
{
    const RTCError error = rtcGetDeviceError(device);
    if (error != RTC_ERROR_NONE)
        throw StageError("sizing", std::string("Embree failed while ") + step + " (error code " +
                                       std::to_string(static_cast<int>(error)) + ")");
}

class RayCaster {
public:
    RayCaster(const SurfaceMesh& mesh, const VertexTable& fans) : mesh_(mesh), fans_(fans)
    {
        // The box of the points the triangles use: a stray point elsewhere
        // would only cost precision.
        const double inf = std::numeric_limits<double>::infinity();
        Vec3 lo{inf, inf, inf}, hi{-inf, -inf, -inf};
        for (int32_t i = 0; i < static_cast<int32_t>(mesh.points.size()); ++i)
            if (fans_.size(i) > 0)
                for (int k = 0; k < 3; ++k) {
                    lo[k] = std::min(lo[k], mesh.points[i][k]);
                    hi[k] = std::max(hi[k], mesh.points[i][k]);
                }
        if (!(lo.x <= hi.x)) lo = hi = Vec3{}; // no triangles
        centre_ = 0.5 * (lo + hi);
        const double near = kNearFraction * distance(lo, hi);
        tnear_ = std::isfinite(near) ? static_cast<float>(near) : 0.0f;
    }

    // Builds the BVH; returns its wall time.
    double build()
    {
        const auto start = Clock::now();
        device_.reset(rtcNewDevice(nullptr));
        if (!device_) throw StageError("sizing", "Embree could not create a device");
        scene_.reset(rtcNewScene(device_.get()));
        // Without the robust flag about 2 in 10,000 rays leak through shared
        // edges of a closed voxel surface (dependencies.md). The scene is
        // built once and cast against once per node in each direction, so
        // the quick Morton-code build (the low quality of a dynamic scene)
        // pays: on the 256 torus it halves the build and slows the rays by
        // about a tenth. The nearest hit is the same whatever the tree.
        rtcSetSceneFlags(scene_.get(), RTCSceneFlags(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_DYNAMIC));
        rtcSetSceneBuildQuality(scene_.get(), RTC_BUILD_QUALITY_LOW);

        // Embree reads vertices with 16-byte loads: at least one float past
        // the last vertex must be readable, so pad by four.
        vertices_.assign(3 * mesh_.points.size() + 4, 0.0f);
        for (size_t i = 0; i < mesh_.points.size(); ++i) {
            const Vec3 p = mesh_.points[i] - centre_;
            vertices_[3 * i] = static_cast<float>(p.x);
            vertices_[3 * i + 1] = static_cast<float>(p.y);
            vertices_[3 * i + 2] = static_cast<float>(p.z);
        }
        RTCGeometry geometry = rtcNewGeometry(device_.get(), RTC_GEOMETRY_TYPE_TRIANGLE);
        rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, vertices_.data(), 0,
                                   3 * sizeof(float), mesh_.points.size());
        rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, mesh_.triangles.data(), 0,
                                   sizeof(Triangle), mesh_.triangles.size());
        rtcSetGeometryIntersectFilterFunction(geometry, reject_origin_fan);
        rtcSetGeometryBuildQuality(geometry, RTC_BUILD_QUALITY_LOW);
        rtcCommitGeometry(geometry);
        rtcAttachGeometry(scene_.get(), geometry);
        rtcReleaseGeometry(geometry);
        rtcCommitScene(scene_.get());
        check_device(device_.get(), "building the BVH");
        return seconds_since(start);
    }

    // Distance from point i along `direction` (unit) to the first triangle
    // not incident to i, from tnear_ on; +infinity when the ray escapes.
    double cast(int32_t i, const Vec3& direction) const
    {
        OriginContext context;
        rtcInitIntersectContext(&context.base);
        context.fan_begin = fans_.begin(i);
        context.fan_end = fans_.end(i);

        const Vec3 origin = mesh_.points[i] - centre_;
        RTCRayHit rayhit{};
        rayhit.ray.org_x = static_cast<float>(origin.x);
        rayhit.ray.org_y = static_cast<float>(origin.y);
        rayhit.ray.org_z = static_cast<float>(origin.z);
        rayhit.ray.dir_x = static_cast<float>(direction.x);
        rayhit.ray.dir_y = static_cast<float>(direction.y);
        rayhit.ray.dir_z = static_cast<float>(direction.z);
        rayhit.ray.tnear = tnear_;
        rayhit.ray.tfar = std::numeric_limits<float>::infinity();
        rayhit.ray.mask = 0xFFFFFFFFu;
        rayhit.ray.flags = 0;
        rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rayhit.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene_.get(), &context.base, &rayhit);
        if (rayhit.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::numeric_limits<double>::infinity();
        // tfar is in units of the (single precision) direction's length.
        const Vec3 dir{rayhit.ray.dir_x, rayhit.ray.dir_y, rayhit.ray.dir_z};
        return static_cast<double>(rayhit.ray.tfar) * norm(dir);
    }

    bool has_fan(int32_t i) const { return fans_.size(i) > 0; }

private:
    const SurfaceMesh& mesh_;
    const VertexTable& fans_;
    Vec3 centre_;
    // Hits nearer than this are the origin's own fan: 1e-6 of the bounding
    // box diagonal is a few tens of single-precision steps of the (centred)
    // coordinates, far below any gap a voxel surface can have. Skipping
    // them before the filter runs saves about a third of the ray time.
    static constexpr double kNearFraction = 1e-6;
    float tnear_ = 0;
    std::vector<float> vertices_;
    DevicePtr device_;
    ScenePtr scene_;
};

void validate(const SurfaceMesh& mesh, const std::vector<Vec3>& normals, const std::vector<char>& inward_ok,
              double L_max, int threads)
{
    const size_t n = mesh.points.size();
    if (normals.size() != n || inward_ok.size() != n)
        throw InputError("ray casting got " + std::to_string(normals.size()) + " normals and " +
                             std::to_string(inward_ok.size()) + " inward flags for " + std::to_string(n) + " points",
                         "pass synthetic_normals and inward_check of the same mesh");
    if (!(L_max > 0) || !std::isfinite(L_max))
        throw InputError("L_max is " + std::to_string(L_max), "give a positive, finite L_max in mm");
    if (threads < 0)
        throw InputError("threads is " + std::to_string(threads), "use 0 for the default or a positive count");
}

} // namespace

RayResults cast_local_diameter(const SurfaceMesh& mesh, const std::vector<Vec3>& outward_normals,
                               const std::vector<char>& inward_ok, double L_max, int threads)
{
    return cast_local_diameter(mesh, vertex_triangles(mesh), outward_normals, inward_ok, L_max, threads);
}

RayResults cast_local_diameter(const SurfaceMesh& mesh, const VertexTable& fans,
                               const std::vector<Vec3>& outward_normals, const std::vector<char>& inward_ok,
                               double L_max, int threads)
{
    validate(mesh, outward_normals, inward_ok, L_max, threads);
    const auto n = static_cast<int32_t>(mesh.points.size());
    const double infinity = std::numeric_limits<double>::infinity();

    RayResults result;
    result.D.assign(n, L_max);
    result.D_out.assign(n, infinity);
    RayCaster caster(mesh, fans);
    std::atomic<int64_t> rays{0}, escaped{0};

    // Each point writes only its own entries, so the result does not depend
    // on how the range is split among threads.
    auto run = [&] {
        result.bvh_seconds = caster.build();
        const auto start = Clock::now();
        tbb::parallel_for(tbb::blocked_range<int32_t>(0, n, 512), [&](const tbb::blocked_range<int32_t>& range) {
            int64_t local_rays = 0, local_escaped = 0;
            for (int32_t i = range.begin(); i != range.end(); ++i) {
                if (!inward_ok[i] || !caster.has_fan(i)) continue;
                const double inward = caster.cast(i, -outward_normals[i]);
                if (std::isfinite(inward)) result.D[i] = inward;
                else ++local_escaped;
                result.D_out[i] = caster.cast(i, outward_normals[i]);
                local_rays += 2;
            }
            rays += local_rays;
            escaped += local_escaped;
        });
        result.ray_seconds = seconds_since(start);
    };
    if (threads > 0) tbb::task_arena(threads).execute(run);
    else run();

    result.rays = rays.load();
    result.escaped_inward = escaped.load();
    return result;
}

} // namespace scalemesh
