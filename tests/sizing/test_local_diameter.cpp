#include "sizing/local_diameter.h"

#include "core/errors.h"
#include "sizing/normals.h"
#include "sizing/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace scalemesh {
namespace {

const double kInfinity = std::numeric_limits<double>::infinity();

RayResults cast(const SurfaceMesh& mesh, double L_max = 1000.0, int threads = 0)
{
    const std::vector<Vec3> normals = synthetic_normals(mesh);
    return cast_local_diameter(mesh, normals, inward_check(mesh, normals), L_max, threads);
}

TEST(LocalDiameter, SphereDiameterIsTwiceTheRadius)
{
    const double R = 10.0;
    const SurfaceMesh mesh = test::icosphere(R, 4, {3, -1, 2});
    const RayResults rays = cast(mesh);
    int64_t within = 0;
    double worst = 0;
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        const double error = std::abs(rays.D[i] - 2 * R) / (2 * R);
        worst = std::max(worst, error);
        within += error <= 0.03;
        EXPECT_EQ(rays.D_out[i], kInfinity) << "vertex " << i;
    }
    const double fraction = static_cast<double>(within) / static_cast<double>(mesh.points.size());
    RecordProperty("fraction_within_3_percent", test::figure(fraction));
    RecordProperty("worst_relative_error", test::figure(worst));
    EXPECT_GE(fraction, 0.95);
    EXPECT_EQ(rays.rays, 2 * static_cast<int64_t>(mesh.points.size()));
    EXPECT_EQ(rays.escaped_inward, 0);
    EXPECT_GE(rays.bvh_seconds, 0.0);
    EXPECT_GE(rays.ray_seconds, 0.0);
}

TEST(LocalDiameter, CylinderWallDiameterIsTwiceTheRadius)
{
    const double r = 2.0, length = 40.0;
    const int around = 48, along = 80;
    const SurfaceMesh mesh = test::capped_cylinder(r, length, around, along);
    const RayResults rays = cast(mesh);
    double worst = 0;
    int checked = 0;
    for (int k = 0; k <= along; ++k)
        for (int i = 0; i < around; ++i) {
            const int32_t v = k * around + i;
            if (mesh.points[v].z < 5.0 || mesh.points[v].z > length - 5.0) continue;
            worst = std::max(worst, std::abs(rays.D[v] - 2 * r) / (2 * r));
            EXPECT_EQ(rays.D_out[v], kInfinity);
            ++checked;
        }
    RecordProperty("worst_relative_error", test::figure(worst));
    EXPECT_GT(checked, 1000);
    EXPECT_LE(worst, 0.05);
}

TEST(LocalDiameter, TorusEquators)
{
    const double R = 10.0, r = 3.0;
    const int nu = 96, nv = 32;
    const SurfaceMesh mesh = test::uv_torus(R, r, nu, nv);
    const RayResults rays = cast(mesh);
    for (int i = 0; i < nu; ++i) {
        const int32_t outer = i * nv, inner = i * nv + nv / 2;
        // Both rays inward cross the tube through its centre line.
        EXPECT_NEAR(rays.D[outer], 2 * r, 0.03 * 2 * r) << "u index " << i;
        EXPECT_NEAR(rays.D[inner], 2 * r, 0.03 * 2 * r) << "u index " << i;
        // Outward from the inner equator the ray crosses the hole.
        EXPECT_EQ(rays.D_out[outer], kInfinity);
        EXPECT_NEAR(rays.D_out[inner], 2 * (R - r), 0.03 * 2 * (R - r)) << "u index " << i;
    }
}

TEST(LocalDiameter, ParallelTubesSeeTheGap)
{
    const double r = 2.0, gap = 0.5, length = 20.0;
    const int around = 48, along = 40;
    const SurfaceMesh mesh = test::parallel_tubes(r, gap, length, around, along);
    const RayResults rays = cast(mesh);
    const int32_t second = (along + 1) * around + 2; // first vertex of the second tube
    double worst = 0;
    for (int k = 0; k <= along; ++k) {
        const double z = length * k / along;
        if (z < 4.0 || z > length - 4.0) continue;
        for (const int32_t v : {k * around, second + k * around + around / 2}) {
            worst = std::max(worst, std::abs(rays.D_out[v] - gap) / gap);
            EXPECT_NEAR(rays.D[v], 2 * r, 0.03 * 2 * r);
        }
        // The walls facing away from each other see nothing outside.
        EXPECT_EQ(rays.D_out[k * around + around / 2], kInfinity);
        EXPECT_EQ(rays.D_out[second + k * around], kInfinity);
    }
    RecordProperty("worst_gap_relative_error", test::figure(worst));
    EXPECT_LE(worst, 0.02);
}

TEST(LocalDiameter, FailedInwardCheckGivesLmax)
{
    int32_t vertex = -1;
    const SurfaceMesh mesh = test::folded_cap_cylinder(vertex);
    const double L_max = 123.0;
    const std::vector<Vec3> normals = synthetic_normals(mesh);
    const std::vector<char> ok = inward_check(mesh, normals);
    ASSERT_EQ(ok[vertex], 0);
    const RayResults rays = cast_local_diameter(mesh, normals, ok, L_max);
    EXPECT_EQ(rays.D[vertex], L_max);
    EXPECT_EQ(rays.D_out[vertex], kInfinity);
    EXPECT_EQ(rays.rays, 2 * std::count(ok.begin(), ok.end(), 1));
}

TEST(LocalDiameter, EscapingInwardRayGivesLmaxAndIsCounted)
{
    // Normals flipped to point inward: every "inward" ray leaves the sphere.
    const SurfaceMesh mesh = test::icosphere(1.0, 2);
    std::vector<Vec3> normals = synthetic_normals(mesh);
    for (Vec3& n : normals) n = -n;
    const std::vector<char> ok(mesh.points.size(), 1);
    const RayResults rays = cast_local_diameter(mesh, normals, ok, 7.0);
    EXPECT_EQ(rays.escaped_inward, static_cast<int64_t>(mesh.points.size()));
    for (double D : rays.D) EXPECT_EQ(D, 7.0);
    for (double D_out : rays.D_out) EXPECT_NEAR(D_out, 2.0, 0.06);
}

TEST(LocalDiameter, ThreadCountDoesNotChangeResults)
{
    const SurfaceMesh mesh = test::uv_torus(10.0, 3.0, 96, 32);
    const RayResults one = cast(mesh, 1000.0, 1);
    const RayResults two = cast(mesh, 1000.0, 2);
    const RayResults all = cast(mesh, 1000.0, 0);
    EXPECT_EQ(one.D, two.D);
    EXPECT_EQ(one.D_out, two.D_out);
    EXPECT_EQ(one.D, all.D);
    EXPECT_EQ(one.D_out, all.D_out);
}

TEST(LocalDiameter, RejectsBadInput)
{
    const SurfaceMesh mesh = test::icosphere(1.0, 1);
    const std::vector<Vec3> normals = synthetic_normals(mesh);
    const std::vector<char> ok(mesh.points.size(), 1);
    EXPECT_THROW(cast_local_diameter(mesh, std::vector<Vec3>(2), ok, 1.0), InputError);
    EXPECT_THROW(cast_local_diameter(mesh, normals, std::vector<char>(2), 1.0), InputError);
    EXPECT_THROW(cast_local_diameter(mesh, normals, ok, 0.0), InputError);
    EXPECT_THROW(cast_local_diameter(mesh, normals, ok, kInfinity), InputError);
    EXPECT_THROW(cast_local_diameter(mesh, normals, ok, 1.0, -1), InputError);
}

} // namespace
} // namespace scalemesh
