// Benchmarks of the surface stages against references measured in the same
// run, on the same input:
//   isosurface: our marching cubes vs OpenVDB's volumeToMesh, on a torus
//               phantom whose box is 512 voxels across (issue 2);
//   sizing:     rays per second and the whole sizing stage per million
//               vertices on a torus surface of about 1M triangles (issue 3);
// each on 1 and 2 threads, the median of repeated runs. Prints a table and
// writes the figures as JSON (first argument, default bench-surface.json).

#include "core/huge_pages.h"
#include "isosurface/marching_cubes.h"
#include "phantom/phantom.h"
#include "references.h"
#include "sizing/feature_size.h"
#include "sizing/local_diameter.h"
#include "sizing/normals.h"
#include "smoothing/volume_conserving_smoothing.h"

#include <tbb/global_control.h>

#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

namespace {

using namespace scalemesh;
using namespace scalemesh::bench;

struct Row {
    std::string what;
    int threads;
    double seconds;
    double items;
    std::string unit;
    double reference_seconds; // < 0: none
};

} // namespace

int main(int argc, char** argv)
{
    scalemesh::restart_with_huge_pages(argv);
    const std::string json_path = argc > 1 ? argv[1] : "bench-surface.json";
    const int repeats = 5;
    std::vector<Row> rows;

    // A torus 28 mm across, 512 voxels across its box.
    const auto torus = make_shape("torus", 1.0);
    Vec3 lo, hi;
    torus->bounds(lo, hi);
    const double h = (hi.x - lo.x) / 512.0;
    const auto grid = voxelize(*torus, {.voxel_size = h});
    std::printf("torus phantom: voxel %.4f mm, %llu inside voxels\n", h,
                static_cast<unsigned long long>(grid->activeVoxelCount()));

    SurfaceMesh surface;
    for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        size_t ours = 0, theirs = 0;
        const double t_ours = median_seconds(repeats, [&] {
            surface = marching_cubes(*grid);
            ours = surface.triangles.size();
        });
        const double t_vdb = median_of_reported(repeats, [&] {
            const ReferenceRun r = openvdb_volume_to_mesh(*grid, 0.5);
            theirs = r.items;
            return r.seconds;
        });
        rows.push_back({"isosurface (marching cubes)", threads, t_ours, double(ours), "triangles", -1});
        rows.push_back({"  reference: OpenVDB volumeToMesh", threads, t_vdb, double(theirs), "triangles", -1});
        rows.back().reference_seconds = -1;
        rows[rows.size() - 2].reference_seconds = t_vdb * double(ours) / double(theirs); // same triangle count
    }

    // Sizing on the smoothed surface of a finer-than-default torus (~1M triangles).
    smooth_volume_conserving(surface, {10, 1.0});
    const size_t vertices = surface.points.size();
    std::printf("sizing surface: %zu triangles, %zu vertices\n", surface.triangles.size(), vertices);
    const std::vector<Vec3> normals = synthetic_normals(surface);
    const std::vector<char> inward = inward_check(surface, normals);
    for (int threads : {1, 2}) {
        RayResults rays;
        const double t_rays = median_seconds(3, [&] { rays = cast_local_diameter(surface, normals, inward, 40.0, threads); });
        rows.push_back({"sizing: BVH build", threads, rays.bvh_seconds, double(surface.triangles.size()), "triangles", -1});
        rows.push_back({"sizing: rays (both directions)", threads, rays.ray_seconds, double(rays.rays), "rays", -1});
        SizingParams params;
        params.L_min = 0.5 * h;
        params.L_max = 40.0;
        params.threads = threads;
        const double t_stage = median_seconds(3, [&] { (void)compute_feature_size(surface, params); });
        rows.push_back({"sizing: whole stage", threads, t_stage, double(vertices), "vertices", -1});
        (void)t_rays;
    }

    std::printf("\n%-36s %7s %10s %12s %14s %10s\n", "stage", "threads", "seconds", "items", "items/s", "vs ref");
    for (const Row& r : rows) {
        std::printf("%-36s %7d %10.4f %12.0f %14.0f", r.what.c_str(), r.threads, r.seconds, r.items, r.items / r.seconds);
        if (r.reference_seconds > 0) std::printf(" %9.2fx", r.seconds / r.reference_seconds);
        std::printf("  (%s)\n", r.unit.c_str());
    }
    for (int threads : {1, 2})
        for (const Row& r : rows)
            if (r.what == "sizing: whole stage" && r.threads == threads)
                std::printf("sizing stage, %d thread%s: %.3f s per million surface vertices (goal: under 1 s on 2)\n",
                            threads, threads == 1 ? "" : "s", r.seconds / (r.items / 1e6));

    std::ofstream json(json_path);
    json << "{\n  \"voxel_size_mm\": " << h << ",\n  \"rows\": [\n";
    for (size_t i = 0; i < rows.size(); ++i) {
        const Row& r = rows[i];
        json << "    {\"stage\": \"" << r.what << "\", \"threads\": " << r.threads << ", \"seconds\": " << r.seconds
             << ", \"items\": " << r.items << ", \"unit\": \"" << r.unit << "\"";
        if (r.reference_seconds > 0) json << ", \"ratio_to_reference_per_item\": " << r.seconds / r.reference_seconds;
        json << "}" << (i + 1 < rows.size() ? "," : "") << "\n";
    }
    json << "  ]\n}\n";
    std::printf("wrote %s\n", json_path.c_str());
    return 0;
}
