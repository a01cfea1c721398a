// Benchmark of the remeshing stage against a reference run in the same
// process, on the same input: a torus phantom voxelised fine (512 voxels
// across its box), marching cubes and 10 sweeps of volume-conserving
// smoothing, about 1M triangles. Then
//   ours:  Algorithm 6's surface loop, remesh_to_feature_size with 3 cycles
//          and d from compute_feature_size (the final sizing included);
//   CGAL:  Polygon_mesh_processing::isotropic_remeshing, 3 iterations, at
//          one target length, the median of our K/M d over the input points,
//          nothing protected.
// Prints plain lines: input triangles per second for both, their ratio, the
// output triangle counts and the fraction of output triangles whose smallest
// angle is above 15 degrees. Then, for the sphere, torus, tube and
// bifurcation phantoms at the sample cases' settings (0.5 mm voxels, L_min
// 0.5 and L_max 40 voxels, smoothing reach 0.5 voxels), the fraction of
// edges with length / (K/M d) in [0.45, 1.1], d the stable d of the result,
// and the same angle fraction.

#include "core/huge_pages.h"
#include "core/adjacency.h"
#include "isosurface/marching_cubes.h"
#include "phantom/phantom.h"
#include "references.h"
#include "remeshing/remesh.h"
#include "sizing/feature_size.h"
#include "smoothing/volume_conserving_smoothing.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

namespace {

using namespace scalemesh;
using namespace scalemesh::bench;

double min_angle_degrees(const Vec3& a, const Vec3& b, const Vec3& c)
{
    auto angle = [](const Vec3& u, const Vec3& v) { return std::atan2(norm(cross(u, v)), dot(u, v)); };
    return std::min({angle(b - a, c - a), angle(c - b, a - b), angle(a - c, b - c)}) * 180 / std::numbers::pi;
}

double fraction_above_15_degrees(const SurfaceMesh& surface)
{
    size_t good = 0;
    for (const Triangle& t : surface.triangles)
        good += min_angle_degrees(surface.points[t[0]], surface.points[t[1]], surface.points[t[2]]) > 15;
    return double(good) / double(surface.triangles.size());
}

// Edges with length / (K/M d) in [0.45, 1.1], d the mean of the two ends.
double fraction_in_band(const SurfaceMesh& surface, const std::vector<double>& d, double K, double M)
{
    const auto edges = unique_edges(surface);
    size_t in = 0;
    for (const auto& [a, b] : edges) {
        const double ratio = distance(surface.points[a], surface.points[b]) / (K / M * 0.5 * (d[a] + d[b]));
        in += ratio >= 0.45 && ratio <= 1.1;
    }
    return double(in) / double(edges.size());
}

} // namespace

int main(int, char** argv)
{
    scalemesh::restart_with_huge_pages(argv);
    const auto torus = make_shape("torus", 1.0);
    Vec3 lo, hi;
    torus->bounds(lo, hi);
    const double h = (hi.x - lo.x) / 512.0;
    SurfaceMesh surface = marching_cubes(*voxelize(*torus, {.voxel_size = h}));
    smooth_volume_conserving(surface, {10, 1.0, 0.5 * h});
    const auto triangles = static_cast<double>(surface.triangles.size());
    std::printf("torus phantom: voxel %.4f mm, %zu triangles, %zu points\n", h, surface.triangles.size(),
                surface.points.size());

    RemeshParams params;
    params.sizing.L_min = 0.5 * h; // the sample cases' "0.5 voxels" and "40 voxels"
    params.sizing.L_max = 40 * h;
    params.max_displacement = 0.5 * h;
    auto start = Clock::now();
    const FeatureSize sizing = compute_feature_size(surface, params.sizing);
    const double t_sizing = seconds_since(start);
    std::vector<double> target(sizing.d.size());
    for (size_t i = 0; i < target.size(); ++i) target[i] = params.K / params.M * sizing.d[i];
    std::nth_element(target.begin(), target.begin() + target.size() / 2, target.end());
    const double median_target = target[target.size() / 2];
    std::printf("sizing of the input: %.3f s; median K/M d %.4f mm\n", t_sizing, median_target);
    std::fflush(stdout);

    start = Clock::now();
    const RemeshResult ours = remesh_to_feature_size(surface, sizing.d, params);
    const double t_ours = seconds_since(start);
    std::printf("ours: remesh_to_feature_size, %d cycles: %.3f s (final sizing %.3f s), %zu triangles out, "
                "%lld merges, %lld swaps, %lld bisections\n",
                params.cycles, t_ours, ours.seconds_sizing, ours.surface.triangles.size(), (long long)ours.merges,
                (long long)ours.swaps, (long long)ours.bisections);

    SurfaceMesh cgal;
    const ReferenceRun reference = cgal_isotropic_remeshing(surface, median_target, 3, &cgal);
    const double t_cgal = reference.seconds;
    std::printf("CGAL: isotropic_remeshing, 3 iterations at %.4f mm: %.3f s (conversion not counted), "
                "%zu triangles out\n",
                median_target, t_cgal, reference.items);

    std::printf("input triangles per second: ours %.0f, CGAL %.0f\n", triangles / t_ours, triangles / t_cgal);
    std::printf("speed ratio ours / CGAL: %.2f\n", t_cgal / t_ours);
    std::printf("triangles with smallest angle > 15 degrees: ours %.4f, CGAL %.4f\n",
                fraction_above_15_degrees(ours.surface), fraction_above_15_degrees(cgal));
    std::fflush(stdout);

    for (const std::string name : {"sphere", "torus", "tube", "bifurcation"}) {
        const double voxel = 0.5;
        SurfaceMesh input = marching_cubes(*voxelize(*make_shape(name, voxel), {.voxel_size = voxel}));
        smooth_volume_conserving(input, {10, 1.0, 0.5 * voxel});
        RemeshParams phantom;
        phantom.sizing.L_min = 0.5 * voxel;
        phantom.sizing.L_max = 40 * voxel;
        phantom.max_displacement = 0.5 * voxel;
        const FeatureSize d = compute_feature_size(input, phantom.sizing);
        start = Clock::now();
        const RemeshResult r = remesh_to_feature_size(input, d.d, phantom);
        std::printf("%s: %zu -> %zu triangles in %.3f s; edges with length / (K/M d) in [0.45, 1.1]: %.3f; "
                    "triangles with smallest angle > 15 degrees: %.4f\n",
                    name.c_str(), input.triangles.size(), r.surface.triangles.size(), seconds_since(start),
                    fraction_in_band(r.surface, r.sizing.d, phantom.K, phantom.M), fraction_above_15_degrees(r.surface));
        std::fflush(stdout);
    }
    return 0;
}
