// Benchmark of the volume stage (issue 5) against CGAL's plain
// Delaunay_triangulation_3 insertion of the same final point set, measured
// in the same run: a torus phantom (marching cubes, smoothing, sizing,
// remeshing to edge length K/M d, as Algorithm 6 does) with L_max chosen to
// give about a million output tets. Prints the stage's own timers, both
// totals, their ratio and output tets per second. Where the volume stage
// asks for a finer surface (section 2.3), L_max is lowered by 3% and the
// surface remeshed, as a stand-in for the pipeline's local refinement.
// Usage: bench_volume [L_max_mm, default 0.7] [voxel_size_mm, default 0.25]

#include "core/huge_pages.h"
#include "isosurface/marching_cubes.h"
#include "phantom/phantom.h"
#include "references.h"
#include "remeshing/remesh.h"
#include "sizing/feature_size.h"
#include "smoothing/volume_conserving_smoothing.h"
#include "volume/volume_mesh.h"

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

using namespace scalemesh;
using namespace scalemesh::bench;

} // namespace

int main(int argc, char** argv)
{
    scalemesh::restart_with_huge_pages(argv);
    double L_max = argc > 1 ? std::atof(argv[1]) : 0.7;
    const double h = argc > 2 ? std::atof(argv[2]) : 0.25;
    const auto shape = make_shape("torus", h);
    SurfaceMesh surface = marching_cubes(*voxelize(*shape, {.voxel_size = h}));
    smooth_volume_conserving(surface, {10, 1.0, 0.5 * h});

    VolumeResult r;
    Clock::time_point t0;
    for (int attempt = 0;; ++attempt) {
        SizingParams sizing;
        sizing.L_min = 0.5 * h;
        sizing.L_max = L_max;
        const FeatureSize size = compute_feature_size(surface, sizing);
        RemeshParams remesh;
        remesh.K = sizing.K;
        remesh.M = sizing.M;
        remesh.sizing = sizing;
        remesh.max_displacement = 0.5 * h;
        const RemeshResult remeshed = remesh_to_feature_size(surface, size.d, remesh);
        VolumeParams params;
        params.K = sizing.K;
        params.M = sizing.M;
        params.L_max = L_max;
        std::printf("torus phantom, voxel %.3f mm, L_max %.3f mm: remeshed surface %zu points, %zu triangles\n", h,
                    L_max, remeshed.surface.points.size(), remeshed.surface.triangles.size());
        try {
            t0 = Clock::now();
            r = build_volume_mesh(remeshed.surface, remeshed.sizing, params);
            break;
        } catch (const VolumeConformityError& e) {
            std::printf("  %s\n", e.what());
            if (attempt == 4) return 1;
            L_max *= 0.97;
        }
    }
    const double ours = seconds_since(t0);
    const size_t tets = r.mesh.tets.size();

    const ReferenceRun reference = cgal_delaunay(r.mesh.points);

    const auto& q0 = r.before_flips;
    const auto& q1 = r.after_flips;
    const auto& q2 = r.after_slivers;
    std::printf("volume stage: %zu points, %zu tets (%lld inserted interior points, %lld deferred to the sequential "
                "pass, %lld retries)\n",
                r.mesh.points.size(), tets, static_cast<long long>(r.inserted_points),
                static_cast<long long>(r.deferred_points), static_cast<long long>(r.insertion_retries));
    std::printf("  seconds: points %.3f, insertion %.3f, removal %.3f, flips %.3f, slivers %.3f, quality %.3f, "
                "checks %.3f, total %.3f\n",
                r.seconds_points, r.seconds_insertion, r.seconds_classify, r.seconds_flips, r.seconds_slivers,
                r.seconds_quality, r.seconds_checks, r.seconds_total);
    std::printf("  aspect ratio min %.4f / %.4f / %.4f, below 0.1: %.4f%% / %.4f%% / %.4f%% (raw / flips / slivers)\n",
                q0.min_aspect_ratio, q1.min_aspect_ratio, q2.min_aspect_ratio, 100 * q0.fraction_below_0_1,
                100 * q1.fraction_below_0_1, 100 * q2.fraction_below_0_1);
    std::printf("reference: CGAL Delaunay_triangulation_3 of the same %zu points: %.3f s, %zu finite cells\n",
                r.mesh.points.size(), reference.seconds, reference.items);
    std::printf("ratio volume stage / CGAL plain insertion: %.2f\n", ours / reference.seconds);
    // Issue 5's goal names these parts: insertion + removal + improvement.
    const double core = r.seconds_insertion + r.seconds_classify + r.seconds_flips + r.seconds_slivers;
    std::printf("ratio insertion + removal + improvement (%.3f s) / CGAL plain insertion: %.2f\n", core,
                core / reference.seconds);
    std::printf("output tets per second: %.3g\n", double(tets) / ours);
    return 0;
}
