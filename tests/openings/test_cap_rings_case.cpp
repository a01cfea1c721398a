// The sample tube case through the pipeline: the vertices on each cap show
// the same rings of layer points across the opening as a cross-section of
// the wall does (issue 7: 3 rings per side for M = 7).

#include "openings/openings.h"
#include "pipeline/case_config.h"
#include "pipeline/pipeline.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>

namespace scalemesh {
namespace {

double distance_to_segment(const Vec3& x, const Vec3& a, const Vec3& b)
{
    const Vec3 ab = b - a;
    const double t = std::clamp(dot(x - a, ab) / dot(ab, ab), 0.0, 1.0);
    return norm(x - (a + t * ab));
}

// The depths of the wall's rings in a cross-section (units of d/M, the mean
// per layer) and, on each cap, the vertices' depths inside the rim: every
// cap vertex lies on one of the wall's three rings, and each ring is there.
// The paper's layers, whose points stay at Algorithm 4's places (prism
// layers shorten their columns, the caps' rings with them).
void check_cap_rings(FirstLayer first_layer)
{
    CaseConfig config = read_case("cases/tube");
    config.first_layer = first_layer;
    config.layers = LayerMode::delaunay;
    ASSERT_EQ(config.M, 7);
    const PipelineRun run = run_pipeline(config, {.sizing = true, .remesh = true, .volume = true});
    ASSERT_TRUE(run.remeshed && run.volume);
    const SurfaceMesh& surface = run.remeshed->surface;
    const FeatureSize& size = run.remeshed->sizing;
    const VolumeResult& volume = *run.volume;
    const double M = config.M;

    // Wall cross-section at z = 0: each layer's mean depth in units of d/M.
    std::map<int, std::pair<double, int>> wall_sum;
    for (size_t i = surface.points.size(); i < volume.mesh.points.size(); ++i) {
        const Vec3& x = volume.mesh.points[i];
        if (std::abs(x.z) >= 0.5 || volume.point_filler[i]) continue;
        const int32_t g = volume.point_generator[i];
        const double depth = std::hypot(surface.points[g].x, surface.points[g].y) - std::hypot(x.x, x.y);
        auto& [sum, count] = wall_sum[volume.point_layer[i]];
        sum += depth / (size.d[g] / M), ++count;
    }
    std::map<int, double> wall_rings;
    for (const auto& [layer, sc] : wall_sum) wall_rings[layer] = sc.first / sc.second;
    ASSERT_EQ(wall_rings.size(), 3u);
    EXPECT_EQ(wall_rings.begin()->first, 1);
    EXPECT_EQ(wall_rings.rbegin()->first, 3);
    // The innermost layermaking ring is at 3 d/M whichever the first layer.
    EXPECT_NEAR(wall_rings[3], 3.0, 0.3);
    if (first_layer == FirstLayer::paper) {
        EXPECT_NEAR(wall_rings[1], 1.0, 0.15);
        EXPECT_NEAR(wall_rings[2], 2.0, 0.15);
    } else {
        EXPECT_LT(wall_rings[1], 0.9); // thinner than the paper's d/M: the edge length over K
    }

    const CapNodes nodes = classify_cap_nodes(surface, run.caps);
    ASSERT_EQ(run.caps.size(), 2u);
    for (const Cap& cap : run.caps) {
        // The rim as segments.
        std::vector<std::array<int32_t, 2>> rim;
        for (size_t f = 0; f < surface.triangles.size(); ++f) {
            if (surface.triangle_patch[f] != cap.patch) continue;
            const Triangle& t = surface.triangles[f];
            for (int k = 0; k < 3; ++k)
                if (nodes.rim[t[k]] && nodes.rim[t[(k + 1) % 3]]) rim.push_back({t[k], t[(k + 1) % 3]});
        }
        ASSERT_GT(rim.size(), 6u) << cap.name;
        // Each cap-interior vertex: its depth inside the rim in units of
        // d/M, and the wall ring nearest to it.
        std::map<int, int> cap_rings;
        double worst_offset = 0;
        for (size_t i = 0; i < surface.points.size(); ++i) {
            if (nodes.cap_of[i] != cap.patch - 1 || !nodes.interior[i]) continue;
            double depth = INFINITY;
            for (const auto& e : rim)
                depth = std::min(depth, distance_to_segment(surface.points[i], surface.points[e[0]], surface.points[e[1]]));
            const double m = depth / (size.d[i] / M);
            int ring = 0;
            double offset = INFINITY;
            for (const auto& [layer, mean] : wall_rings)
                if (std::abs(m - mean) < offset) offset = std::abs(m - mean), ring = layer;
            worst_offset = std::max(worst_offset, offset);
            ++cap_rings[ring];
        }
        std::printf("%s: cap rings", cap.name.c_str());
        for (const auto& [ring, count] : cap_rings) std::printf(" %d:%d", ring, count);
        std::printf("; wall rings at");
        for (const auto& [ring, mean] : wall_rings) std::printf(" %d:%.2f", ring, mean);
        std::printf(" d/M; worst offset %.3f d/M\n", worst_offset);
        // Rings 1, 2 and 3, as across the wall.
        ASSERT_EQ(cap_rings.size(), 3u) << cap.name;
        // Each point lies on its ring (the rim is a polygon, the rings are
        // laid along in-plane normals: a small offset).
        EXPECT_LT(worst_offset, 0.3) << cap.name;
    }
}

TEST(CapRings, TubeCaseCapsShowTheWallsThreeRingsAtMultiplesOfDOverM) { check_cap_rings(FirstLayer::paper); }

TEST(CapRings, TubeCaseCapsShowTheWallsThreeRingsWithTheEdgeFirstLayer) { check_cap_rings(FirstLayer::edge); }

} // namespace
} // namespace scalemesh
