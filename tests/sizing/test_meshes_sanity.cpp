// The analytic test surfaces are what every sizing and smoothing test stands
// on: closed, oriented outward, of the right genus.

#include "sizing/test_meshes.h"

#include <gtest/gtest.h>

#include <numbers>

namespace scalemesh {
namespace {

TEST(SizingTestMeshes, ClosedOrientedWithExpectedTopology)
{
    struct Case {
        const char* name;
        SurfaceMesh mesh;
        int64_t euler;
        int64_t components;
        double volume;
    };
    const double pi = std::numbers::pi;
    const Case cases[] = {
        {"icosphere", test::icosphere(2.0, 3), 2, 1, 4.0 / 3.0 * pi * 8},
        {"torus", test::uv_torus(10.0, 3.0, 96, 32), 0, 1, 2 * pi * pi * 10 * 9},
        {"cylinder", test::capped_cylinder(2.0, 40.0, 48, 80), 2, 1, pi * 4 * 40},
        {"tubes", test::parallel_tubes(2.0, 0.5, 20.0, 48, 40), 4, 2, 2 * pi * 4 * 20},
    };
    for (const Case& c : cases) {
        const SurfaceFacts facts = surface_facts(c.mesh);
        EXPECT_TRUE(facts.closed_manifold()) << c.name;
        EXPECT_EQ(facts.euler_characteristic, c.euler) << c.name;
        EXPECT_EQ(facts.components, c.components) << c.name;
        // Inscribed polyhedra: a little less than the analytic volume.
        EXPECT_GT(facts.signed_volume, 0.97 * c.volume) << c.name;
        EXPECT_LT(facts.signed_volume, c.volume) << c.name;
    }
}

} // namespace
} // namespace scalemesh
