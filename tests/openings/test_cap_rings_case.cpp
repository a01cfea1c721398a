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

TEST(CapRings, TubeCaseCapsShowTheWallsThreeRings)
{
    const CaseConfig config = read_case("cases/tube");
    ASSERT_EQ(config.M, 7);
    const PipelineRun run = run_pipeline(config, {.sizing = true, .remesh = true, .volume = true});
    ASSERT_TRUE(run.remeshed && run.volume);
    const SurfaceMesh& surface = run.remeshed->surface;
    const FeatureSize& size = run.remeshed->sizing;
    const VolumeResult& volume = *run.volume;
    const double M = config.M;

    // Wall cross-section at z = 0: the layer index of each layer point.
    std::map<int, int> wall_rings;
    for (size_t i = surface.points.size(); i < volume.mesh.points.size(); ++i)
        if (std::abs(volume.mesh.points[i].z) < 0.5 && !volume.point_filler[i]) ++wall_rings[volume.point_layer[i]];

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
        // Each cap-interior vertex: its depth inside the rim in units of d/M.
        std::map<int, int> cap_rings;
        double worst_offset = 0;
        for (size_t i = 0; i < surface.points.size(); ++i) {
            if (nodes.cap_of[i] != cap.patch - 1 || !nodes.interior[i]) continue;
            double depth = INFINITY;
            for (const auto& e : rim)
                depth = std::min(depth, distance_to_segment(surface.points[i], surface.points[e[0]], surface.points[e[1]]));
            const double m = depth / (size.d[i] / M);
            const int ring = static_cast<int>(std::lround(m));
            worst_offset = std::max(worst_offset, std::abs(m - ring));
            ++cap_rings[ring];
        }
        std::printf("%s: cap rings", cap.name.c_str());
        for (const auto& [ring, count] : cap_rings) std::printf(" %d:%d", ring, count);
        std::printf("; wall rings");
        for (const auto& [ring, count] : wall_rings) std::printf(" %d:%d", ring, count);
        std::printf("; worst offset %.3f d/M\n", worst_offset);
        // Rings 1, 2 and 3 and nothing else, as across the wall.
        ASSERT_EQ(cap_rings.size(), 3u) << cap.name;
        EXPECT_EQ(cap_rings.begin()->first, 1) << cap.name;
        EXPECT_EQ(cap_rings.rbegin()->first, 3) << cap.name;
        EXPECT_EQ(wall_rings.size(), cap_rings.size());
        EXPECT_EQ(wall_rings.begin()->first, 1);
        EXPECT_EQ(wall_rings.rbegin()->first, 3);
        // Each point lies on its ring (the rim is a polygon, the rings are
        // laid along in-plane normals: a small offset).
        EXPECT_LT(worst_offset, 0.3) << cap.name;
    }
}

} // namespace
} // namespace scalemesh
