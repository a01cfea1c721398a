// The whole sizing stage: normals, rays, optional curvature, Algorithm 1.

#include "sizing/feature_size.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "sizing/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace scalemesh {
namespace {

SizingParams params(double L_min, double L_max)
{
    SizingParams p;
    p.L_min = L_min;
    p.L_max = L_max;
    return p;
}

TEST(FeatureSize, SphereFeatureSizeIsTheDiameter)
{
    const double R = 10.0;
    const SurfaceMesh mesh = test::icosphere(R, 4);
    const FeatureSize fs = compute_feature_size(mesh, params(0.1, 100.0));
    ASSERT_EQ(fs.d.size(), mesh.points.size());
    EXPECT_EQ(fs.escaped_inward_rays, 0);
    EXPECT_EQ(std::count(fs.inward_ok.begin(), fs.inward_ok.end(), 1), static_cast<long>(mesh.points.size()));
    for (size_t i = 0; i < fs.d.size(); ++i) {
        EXPECT_NEAR(fs.d[i], 2 * R, 0.03 * 2 * R);
        EXPECT_LE(fs.d[i], fs.D[i]);
        EXPECT_EQ(fs.D_out[i], std::numeric_limits<double>::infinity());
    }
    EXPECT_GE(fs.seconds_bvh, 0.0);
    EXPECT_GE(fs.seconds_rays, 0.0);
    EXPECT_GE(fs.seconds_limit, 0.0);
}

TEST(FeatureSize, LmaxCapsLargeDiameters)
{
    const SurfaceMesh mesh = test::icosphere(10.0, 3);
    const FeatureSize fs = compute_feature_size(mesh, params(0.1, 5.0));
    for (double d : fs.d) EXPECT_EQ(d, 5.0);
}

TEST(FeatureSize, ParallelTubesAreLimitedByTheGap)
{
    // 2 (M/K) D_out = 2 (7/4.2) 0.5 = 1.67 on the facing walls, against
    // D = 4 across each tube.
    const double r = 2.0, gap = 0.5;
    const int around = 48, along = 40;
    const SurfaceMesh mesh = test::parallel_tubes(r, gap, 20.0, around, along);
    const SizingParams p = params(0.05, 50.0);
    const FeatureSize fs = compute_feature_size(mesh, p);
    const double bound = 2 * p.M / p.K * gap;
    for (int k = 10; k <= 30; ++k) {
        EXPECT_NEAR(fs.d[k * around], bound, 0.02 * bound);
        EXPECT_GT(fs.d[k * around + around / 2], 3.0); // far side: the tube diameter
    }
}

TEST(FeatureSize, FailedInwardCheckGetsFiniteLimitedValue)
{
    int32_t vertex = -1;
    const SurfaceMesh mesh = test::folded_cap_cylinder(vertex);
    const SizingParams p = params(0.1, 1000.0);
    const FeatureSize fs = compute_feature_size(mesh, p);
    ASSERT_EQ(fs.inward_ok[vertex], 0);
    EXPECT_EQ(fs.D[vertex], p.L_max);
    EXPECT_TRUE(std::isfinite(fs.d[vertex]));
    // Gradient limiting brings it down to its neighbours' level.
    const VertexTable neighbours = vertex_neighbours(mesh);
    double lowest = std::numeric_limits<double>::infinity();
    for (const int32_t* j = neighbours.begin(vertex); j != neighbours.end(vertex); ++j) {
        const double limit = fs.d[*j] + p.G * distance(mesh.points[vertex], mesh.points[*j]);
        EXPECT_LE(fs.d[vertex], limit + 1e-12);
        lowest = std::min(lowest, limit);
    }
    EXPECT_EQ(fs.d[vertex], lowest);
    EXPECT_LT(fs.d[vertex], 0.1 * p.L_max);
}

TEST(FeatureSize, CurvatureTermOnTorusInnerEquator)
{
    // Eq. (12): at the inner equator of a fat torus the ray crosses the tube
    // (D = 2r = 2) while the surface curves around the axis with radius
    // R - r = 0.5, so D becomes 2 (R - r) = 1 with the term.
    const double R = 1.5, r = 1.0;
    const int nu = 128, nv = 64;
    const SurfaceMesh mesh = test::uv_torus(R, r, nu, nv);
    SizingParams p = params(0.01, 10.0);
    const FeatureSize plain = compute_feature_size(mesh, p);
    p.curvature_term = true;
    const FeatureSize curved = compute_feature_size(mesh, p);
    for (int i = 0; i < nu; ++i) {
        const int32_t inner = i * nv + nv / 2;
        EXPECT_NEAR(plain.D[inner], 2 * r, 0.03 * 2 * r);
        EXPECT_NEAR(curved.D[inner], 2 * (R - r), 0.03 * 2 * (R - r));
        EXPECT_LE(curved.d[inner], curved.D[inner]);
    }
}

TEST(FeatureSize, CurvatureTermLeavesSphereAlone)
{
    const double R = 10.0;
    const SurfaceMesh mesh = test::icosphere(R, 4);
    SizingParams p = params(0.1, 100.0);
    p.curvature_term = true;
    const FeatureSize fs = compute_feature_size(mesh, p);
    for (double D : fs.D) EXPECT_NEAR(D, 2 * R, 0.03 * 2 * R);
}

TEST(FeatureSize, ThreadCountDoesNotChangeResults)
{
    const SurfaceMesh mesh = test::parallel_tubes(2.0, 0.5, 20.0, 48, 40);
    SizingParams p = params(0.05, 50.0);
    p.threads = 1;
    const FeatureSize one = compute_feature_size(mesh, p);
    p.threads = 2;
    const FeatureSize two = compute_feature_size(mesh, p);
    EXPECT_EQ(one.D, two.D);
    EXPECT_EQ(one.D_out, two.D_out);
    EXPECT_EQ(one.d, two.d);
}

TEST(FeatureSize, RefusesOpenSurface)
{
    SurfaceMesh mesh = test::icosphere(1.0, 2);
    mesh.triangles.erase(mesh.triangles.begin() + 5);
    EXPECT_THROW(compute_feature_size(mesh, params(0.01, 1.0)), InputError);
}

TEST(FeatureSize, RejectsBadParamsWithRange)
{
    const SurfaceMesh mesh = test::icosphere(1.0, 1);
    auto expect_rejected = [&](SizingParams p, const std::string& name) {
        try {
            compute_feature_size(mesh, p);
            ADD_FAILURE() << name << " accepted";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("valid range"), std::string::npos) << e.what();
        }
    };
    const double nan = std::nan(""), inf = std::numeric_limits<double>::infinity();
    SizingParams p = params(0.01, 1.0);
    expect_rejected(SizingParams{}, "default L_min, L_max (unset)");
    p.K = 0;
    expect_rejected(p, "K = 0");
    p = params(0.01, 1.0);
    p.K = inf;
    expect_rejected(p, "K = inf");
    p = params(0.01, 1.0);
    p.M = 0.5;
    expect_rejected(p, "M = 0.5");
    p = params(0.01, 1.0);
    p.G = 0;
    expect_rejected(p, "G = 0");
    p = params(0.01, 1.0);
    p.G = nan;
    expect_rejected(p, "G = nan");
    expect_rejected(params(0, 1.0), "L_min = 0");
    expect_rejected(params(2.0, 1.0), "L_min > L_max");
    expect_rejected(params(0.01, inf), "L_max = inf");
    p = params(0.01, 1.0);
    p.threads = -2;
    expect_rejected(p, "threads = -2");
    EXPECT_NO_THROW(compute_feature_size(mesh, params(1.0, 1.0)));
}

} // namespace
} // namespace scalemesh
