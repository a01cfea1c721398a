#include "sizing/curvature.h"

#include "core/errors.h"
#include "sizing/normals.h"
#include "sizing/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace scalemesh {
namespace {

TEST(SizingCurvature, SphereRadius)
{
    const double R = 10.0;
    const SurfaceMesh mesh = test::icosphere(R, 4, {5, 5, -5});
    const std::vector<double> radius = curvature_radius(mesh, synthetic_normals(mesh));
    double worst = 0;
    for (double rc : radius) worst = std::max(worst, std::abs(rc - R) / R);
    RecordProperty("worst_relative_error", test::figure(worst));
    EXPECT_LE(worst, 0.02);
}

TEST(SizingCurvature, CylinderWallRadiusAndFlatCap)
{
    const double r = 2.0;
    const int around = 48, along = 80;
    const SurfaceMesh mesh = test::capped_cylinder(r, 40.0, around, along);
    const std::vector<double> radius = curvature_radius(mesh, synthetic_normals(mesh));
    for (int k = 2; k <= along - 2; ++k)
        for (int i = 0; i < around; ++i) EXPECT_NEAR(radius[k * around + i], r, 0.02 * r);
    // The cap centres see a flat fan.
    EXPECT_GT(radius[radius.size() - 1], 1e6);
}

TEST(SizingCurvature, TorusInnerEquatorTakesTheLargerCurvature)
{
    // Inner equator: curvature 1/r across the tube and 1/(R - r) around the
    // axis, of opposite signs; with R - r < r the second one wins.
    const double R = 1.5, r = 1.0;
    const int nu = 128, nv = 64;
    const SurfaceMesh mesh = test::uv_torus(R, r, nu, nv);
    const std::vector<double> radius = curvature_radius(mesh, synthetic_normals(mesh));
    for (int i = 0; i < nu; ++i) {
        EXPECT_NEAR(radius[i * nv + nv / 2], R - r, 0.03 * (R - r));
        EXPECT_NEAR(radius[i * nv], r, 0.03 * r); // outer equator: 1/r > 1/(R + r)
    }
}

TEST(SizingCurvature, RejectsMismatchedNormals)
{
    const SurfaceMesh mesh = test::icosphere(1.0, 1);
    EXPECT_THROW(curvature_radius(mesh, std::vector<Vec3>(1)), InputError);
}

} // namespace
} // namespace scalemesh
