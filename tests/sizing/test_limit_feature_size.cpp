// Algorithm 1: clamping and gradient limiting of the raw local diameter.

#include "sizing/feature_size.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "sizing/local_diameter.h"
#include "sizing/normals.h"
#include "sizing/test_meshes.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>
#include <random>

namespace scalemesh {
namespace {

const double kInfinity = std::numeric_limits<double>::infinity();

SizingParams params()
{
    SizingParams p;
    p.L_min = 0.2;
    p.L_max = 5.0;
    return p;
}

// A rough raw field on the torus: values spread over [0.05, 8] so that both
// clamps bite and many edges violate the gradient limit.
std::vector<double> rough_field(size_t n, unsigned seed = 7)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(std::log(0.05), std::log(8.0));
    std::vector<double> D(n);
    for (double& v : D) v = std::exp(u(rng));
    return D;
}

std::vector<double> clamped(const std::vector<double>& D, const std::vector<double>& D_out, const SizingParams& p)
{
    std::vector<double> d0(D.size());
    for (size_t i = 0; i < D.size(); ++i)
        d0[i] = std::min(std::max(p.L_min, std::min(p.L_max, D[i])), 2 * p.M / p.K * D_out[i]);
    return d0;
}

// Independent reference: d_i = min_j (d0_j + G * graph distance(i, j)), by a
// multi-source Dijkstra over the undirected edges.
std::vector<double> dijkstra_reference(const SurfaceMesh& mesh, const std::vector<double>& d0, double G)
{
    std::vector<std::vector<std::pair<int32_t, double>>> graph(mesh.points.size());
    for (const auto& e : unique_edges(mesh)) {
        const double w = G * distance(mesh.points[e[0]], mesh.points[e[1]]);
        graph[e[0]].push_back({e[1], w});
        graph[e[1]].push_back({e[0], w});
    }
    std::vector<double> d = d0;
    using Item = std::pair<double, int32_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    for (int32_t i = 0; i < static_cast<int32_t>(d.size()); ++i) queue.push({d[i], i});
    while (!queue.empty()) {
        const auto [value, i] = queue.top();
        queue.pop();
        if (value > d[i]) continue;
        for (const auto& [j, w] : graph[i])
            if (value + w < d[j]) {
                d[j] = value + w;
                queue.push({d[j], j});
            }
    }
    return d;
}

double max_gradient_violation(const SurfaceMesh& mesh, const std::vector<double>& d, double G)
{
    double worst = -kInfinity;
    for (const auto& e : unique_edges(mesh))
        worst = std::max(worst, std::abs(d[e[0]] - d[e[1]]) - G * distance(mesh.points[e[0]], mesh.points[e[1]]));
    return worst;
}

TEST(FeatureSizeLimit, GradientBoundHoldsOnEveryEdge)
{
    const SurfaceMesh mesh = test::uv_torus(10.0, 3.0, 96, 32);
    const SizingParams p = params();
    const std::vector<double> D = rough_field(mesh.points.size());
    const std::vector<double> D_out(mesh.points.size(), kInfinity);
    ASSERT_GT(max_gradient_violation(mesh, clamped(D, D_out, p), p.G), 1.0); // the input is rough
    const std::vector<double> d = limit_feature_size(mesh, D, D_out, p);
    const double worst = max_gradient_violation(mesh, d, p.G);
    RecordProperty("max_gradient_violation", test::figure(worst));
    EXPECT_LE(worst, 1e-12);
}

TEST(FeatureSizeLimit, ClampsHold)
{
    const SurfaceMesh mesh = test::uv_torus(10.0, 3.0, 96, 32);
    const SizingParams p = params();
    const std::vector<double> D = rough_field(mesh.points.size());
    const std::vector<double> D_out(mesh.points.size(), kInfinity);
    const std::vector<double> d = limit_feature_size(mesh, D, D_out, p);
    for (size_t i = 0; i < d.size(); ++i) {
        EXPECT_LE(d[i], std::max(p.L_min, std::min(p.L_max, D[i])));
        EXPECT_LE(d[i], p.L_max);
        EXPECT_GE(d[i], p.L_min); // no D_out bound anywhere
    }
}

TEST(FeatureSizeLimit, OutwardBoundAppliesBelowLmin)
{
    // Algorithm 1 takes min(d, 2 (M/K) D_out) after the L_min clamp.
    const SurfaceMesh mesh = test::uv_torus(10.0, 3.0, 96, 32);
    const SizingParams p = params();
    const std::vector<double> D(mesh.points.size(), 3.0);
    std::vector<double> D_out(mesh.points.size(), kInfinity);
    const int32_t tight = 100;
    D_out[tight] = 0.01;
    const std::vector<double> d = limit_feature_size(mesh, D, D_out, p);
    const double bound = 2 * p.M / p.K * 0.01;
    ASSERT_LT(bound, p.L_min);
    EXPECT_EQ(d[tight], bound);
    for (size_t i = 0; i < d.size(); ++i) {
        EXPECT_LE(d[i], 2 * p.M / p.K * D_out[i]);
        EXPECT_GE(d[i], bound);
    }
    // The neighbours come down to it.
    const VertexTable neighbours = vertex_neighbours(mesh);
    for (const int32_t* j = neighbours.begin(tight); j != neighbours.end(tight); ++j)
        EXPECT_LE(d[*j], bound + p.G * distance(mesh.points[*j], mesh.points[tight]) + 1e-12);
    EXPECT_LE(max_gradient_violation(mesh, d, p.G), 1e-12);
}

TEST(FeatureSizeLimit, EqualsShortestPathReference)
{
    for (unsigned seed : {1u, 2u, 3u}) {
        const SurfaceMesh mesh = test::uv_torus(10.0, 3.0, 96, 32);
        const SizingParams p = params();
        const std::vector<double> D = rough_field(mesh.points.size(), seed);
        std::vector<double> D_out(mesh.points.size(), kInfinity);
        for (size_t i = 0; i < D_out.size(); i += 97) D_out[i] = D[i] / 10;
        const std::vector<double> d = limit_feature_size(mesh, D, D_out, p);
        const std::vector<double> reference = dijkstra_reference(mesh, clamped(D, D_out, p), p.G);
        double worst = 0;
        for (size_t i = 0; i < d.size(); ++i) worst = std::max(worst, std::abs(d[i] - reference[i]));
        RecordProperty("max_difference_to_dijkstra_seed_" + std::to_string(seed), test::figure(worst));
        EXPECT_LE(worst, 1e-12) << "seed " << seed;
        // The limited field is unique to the last bit (feature_size.cpp), so
        // the reference, which relaxes in another order, gives it exactly.
        EXPECT_EQ(d, reference) << "seed " << seed;
    }
}

TEST(FeatureSizeLimit, LimitedFieldIsAFixedPoint)
{
    const SurfaceMesh mesh = test::icosphere(10.0, 3);
    const SizingParams p = params();
    const std::vector<double> D_out(mesh.points.size(), kInfinity);
    const std::vector<double> d = limit_feature_size(mesh, rough_field(mesh.points.size()), D_out, p);
    EXPECT_EQ(limit_feature_size(mesh, d, D_out, p), d);
}

// Figure 6: one ray that slips past the interceding geometry changes d at its
// vertex by at most G times an incident edge length.
TEST(FeatureSizeLimit, SinglePerturbedRayHasBoundedEffect)
{
    const double r = 2.0;
    const int around = 48, along = 80;
    const SurfaceMesh mesh = test::capped_cylinder(r, 40.0, around, along);
    const std::vector<Vec3> normals = synthetic_normals(mesh);
    const RayResults rays = cast_local_diameter(mesh, normals, inward_check(mesh, normals), 100.0);
    SizingParams p;
    p.L_min = 0.01;
    p.L_max = 100.0;
    const std::vector<double> d = limit_feature_size(mesh, rays.D, rays.D_out, p);

    const VertexTable neighbours = vertex_neighbours(mesh);
    double worst_ratio = 0;
    for (const int32_t v : {40 * around + 7, 20 * around + 30, 60 * around}) {
        std::vector<double> perturbed = rays.D;
        perturbed[v] *= 10;
        const std::vector<double> d2 = limit_feature_size(mesh, perturbed, rays.D_out, p);
        double longest = 0;
        for (const int32_t* j = neighbours.begin(v); j != neighbours.end(v); ++j)
            longest = std::max(longest, distance(mesh.points[v], mesh.points[*j]));
        EXPECT_GT(d2[v], d[v]); // the perturbation is visible, and bounded:
        EXPECT_LE(std::abs(d2[v] - d[v]), p.G * longest);
        worst_ratio = std::max(worst_ratio, std::abs(d2[v] - d[v]) / (p.G * longest));
    }
    RecordProperty("worst_change_over_G_longest_edge", test::figure(worst_ratio));
}

TEST(FeatureSizeLimit, DeterministicOnAnyThreadCount)
{
    const SurfaceMesh mesh = test::uv_torus(10.0, 3.0, 384, 128);
    const std::vector<double> D = rough_field(mesh.points.size());
    const std::vector<double> D_out(mesh.points.size(), kInfinity);
    std::vector<double> one;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        one = limit_feature_size(mesh, D, D_out, params());
    }
    EXPECT_NE(one, clamped(D, D_out, params())); // the limit lowered some nodes
    for (int run = 0; run < 3; ++run) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
        EXPECT_EQ(limit_feature_size(mesh, D, D_out, params()), one) << "run " << run;
    }
}

TEST(FeatureSizeLimit, RejectsBadFields)
{
    const SurfaceMesh mesh = test::icosphere(1.0, 1);
    const size_t n = mesh.points.size();
    const std::vector<double> ok(n, 1.0), inf(n, kInfinity);
    EXPECT_THROW(limit_feature_size(mesh, std::vector<double>(n - 1, 1.0), inf, params()), InputError);
    EXPECT_THROW(limit_feature_size(mesh, ok, std::vector<double>(n + 1, 1.0), params()), InputError);
    std::vector<double> nan = ok;
    nan[3] = std::nan("");
    EXPECT_THROW(limit_feature_size(mesh, nan, inf, params()), InputError);
    EXPECT_THROW(limit_feature_size(mesh, ok, nan, params()), InputError);
    std::vector<double> negative = ok;
    negative[0] = -1;
    EXPECT_THROW(limit_feature_size(mesh, negative, inf, params()), InputError);
    EXPECT_NO_THROW(limit_feature_size(mesh, inf, inf, params())); // +infinity is clamped to L_max
}

} // namespace
} // namespace scalemesh
