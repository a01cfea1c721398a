#include "layers/offset_points.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

namespace scalemesh {
namespace {

// Three nodes on the plane z = 0 with inward direction +z (outward normal -z).
struct Plane {
    SurfaceMesh surface;
    FeatureSize sizing;
};

Plane three_nodes()
{
    Plane p;
    p.surface.points = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
    p.sizing.d = {1.4, 1.4, 1.4};
    p.sizing.D = {1.4, 4.0, 4.0};
    p.sizing.normals = {{0, 0, -1}, {0, 0, -1}, {0, 0, -1}};
    p.sizing.inward_ok = {1, 1, 0};
    return p;
}

TEST(OffsetPoints, LayersAtLambdaDThenFillersUpToHalfD)
{
    const Plane p = three_nodes();
    OffsetParams params;
    params.M = 7;
    params.L_max = 2.1;
    const std::vector<OffsetPoint> points = offset_points(p.surface, p.sizing, params);

    // Node 0 (D = d): three layermaking points at 0.2, 0.4, 0.6 (D / 2 = 0.7).
    // Node 1: the same three, then fillers every min(D, L_max) / M = 0.3 up
    // to D / 2 = 2: 0.9, 1.2, 1.5, 1.8. Node 2: its inward check failed.
    const std::vector<std::pair<int, double>> expected = {{0, 0.2}, {0, 0.4}, {0, 0.6}, {1, 0.2}, {1, 0.4},
                                                          {1, 0.6}, {1, 0.9}, {1, 1.2}, {1, 1.5}, {1, 1.8}};
    ASSERT_EQ(points.size(), expected.size());
    for (size_t k = 0; k < points.size(); ++k) {
        const OffsetPoint& q = points[k];
        EXPECT_EQ(q.generator, expected[k].first) << k;
        EXPECT_NEAR(q.dist, expected[k].second, 1e-12) << k;
        EXPECT_NEAR(q.position.z, expected[k].second, 1e-12) << k;
        EXPECT_EQ(q.position.x, p.surface.points[q.generator].x) << k;
        const int m = static_cast<int>(k < 3 ? k + 1 : k - 2);
        EXPECT_EQ(q.layer, m) << k;
        EXPECT_EQ(q.filler, m > 3) << k;
        EXPECT_NEAR(q.spacing, m > 3 ? 0.3 : 0.2, 1e-12) << k;
    }
}

// Section 4's rule written out over all pairs (with the filler radius): in order of distance to the
// generator (ties: index), a point is dropped when a kept point before it
// from another generator is closer than filter_fraction min(d_a, d_b) / M.
std::vector<size_t> greedy_by_all_pairs(const std::vector<OffsetPoint>& points, const FeatureSize& sizing,
                                        const OffsetParams& params)
{
    std::vector<size_t> order(points.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return points[a].dist < points[b].dist; });
    std::vector<char> keep(points.size(), 0);
    std::vector<size_t> kept_so_far;
    for (size_t a : order) {
        bool clash = false;
        for (size_t b : kept_so_far) {
            double r =
                params.filter_fraction * std::min(sizing.d[points[a].generator], sizing.d[points[b].generator]) / params.M;
            if (points[a].filler) r = std::max(r, params.filler_filter_fraction * points[a].spacing);
            if (points[a].generator != points[b].generator && distance(points[a].position, points[b].position) < r) {
                clash = true;
                break;
            }
        }
        if (clash) continue;
        keep[a] = 1;
        kept_so_far.push_back(a);
    }
    std::vector<size_t> kept;
    for (size_t i = 0; i < points.size(); ++i)
        if (keep[i]) kept.push_back(i);
    return kept;
}

TEST(FilterInteriorPoints, KeepsWhatTheGreedyRuleOverAllPairsKeepsOnAnyThreadCount)
{
    // 3000 points of 150 generators in a 0.3 mm cube, radius 0.1 d / 7 with d
    // in [0.5, 1.5] (and half the spacing for fillers): dense enough that
    // many points clash. Distances are rounded to 0.01 so that ties occur.
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> unit(0, 1);
    FeatureSize sizing;
    for (int g = 0; g < 150; ++g) sizing.d.push_back(0.5 + unit(rng));
    std::vector<OffsetPoint> points;
    for (int k = 0; k < 3000; ++k) {
        OffsetPoint q;
        q.position = {0.3 * unit(rng), 0.3 * unit(rng), 0.3 * unit(rng)};
        q.generator = static_cast<int32_t>(rng() % 150);
        q.layer = 1 + static_cast<int32_t>(rng() % 5);
        q.filler = q.layer > 3;
        q.dist = std::round(100 * unit(rng)) / 100;
        q.spacing = 0.02 + 0.04 * unit(rng); // filler radius 0.5 spacing: 0.01 to 0.03, around the layer radius
        points.push_back(q);
    }
    OffsetParams params;
    params.M = 7;
    params.L_max = 1;
    params.filter_fraction = 0.1;

    const std::vector<size_t> expected = greedy_by_all_pairs(points, sizing, params);
    ASSERT_GT(expected.size(), 100u);
    ASSERT_LT(expected.size(), points.size() - 100);
    for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        const std::vector<OffsetPoint> kept = filter_interior_points(points, sizing, params);
        ASSERT_EQ(kept.size(), expected.size()) << threads << " threads";
        for (size_t k = 0; k < kept.size(); ++k) {
            const OffsetPoint& want = points[expected[k]];
            ASSERT_EQ(kept[k].position, want.position) << k << ", " << threads << " threads";
            ASSERT_EQ(kept[k].generator, want.generator) << k;
            ASSERT_EQ(kept[k].dist, want.dist) << k;
        }
    }
}

// Where many generators' innermost points meet (the centre of a sphere), all
// of them clash with each other: the first in order stays, the rest go, in
// time and memory linear in the points.
TEST(FilterInteriorPoints, PointsCrowdedAtOneSpotKeepOnlyTheFirst)
{
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> unit(-1, 1);
    const int count = 50000;
    FeatureSize sizing;
    sizing.d.assign(count, 1.0);
    std::vector<OffsetPoint> points;
    for (int k = 0; k < count; ++k)
        points.push_back({{1e-4 * unit(rng), 1e-4 * unit(rng), 1e-4 * unit(rng)}, k, 4, true, 0.5 + 0.1 * unit(rng), 0.1});
    OffsetParams params;
    params.M = 7;
    params.L_max = 1;
    params.filter_fraction = 0.1; // radius 0.014, far above the spread
    const std::vector<OffsetPoint> kept = filter_interior_points(points, sizing, params);
    ASSERT_EQ(kept.size(), 1u);
    const auto first = std::min_element(points.begin(), points.end(),
                                        [](const OffsetPoint& a, const OffsetPoint& b) { return a.dist < b.dist; });
    EXPECT_EQ(kept[0].generator, first->generator);
    EXPECT_EQ(greedy_by_all_pairs(points, sizing, params), std::vector<size_t>{size_t(first->generator)});
}

// Filler rays of a tube converge on its axis (a torus's core, a large
// vessel with L_max below its diameter): 96 generators around a circle of
// radius 4, fillers every 0.0625 along each inward ray. Within 0.95 of the
// axis neighbouring rays are closer than the spacing, and only the layer
// radius (0.1 spacing here) would leave the points there hundreds of times
// denser than elsewhere, the tets among them slivers. With the filler
// radius no two kept fillers of different rays are closer than half the
// spacing, and outside the converging zone every point stays.
TEST(FilterInteriorPoints, FillersConvergingOnAnAxisAreThinnedToTheirFillerRadius)
{
    const int rays = 96;
    const double R = 4, s = 0.0625;
    FeatureSize sizing;
    sizing.d.assign(rays, 0.4375);
    std::vector<OffsetPoint> points;
    for (int g = 0; g < rays; ++g) {
        const double angle = 2 * 3.14159265358979 * g / rays;
        for (int m = 4; m * s <= R; ++m) {
            const double r = R - m * s;
            for (double z : {0.0, s})
                points.push_back({{r * std::cos(angle), r * std::sin(angle), z}, g, m, true, m * s, s});
        }
    }
    OffsetParams params;
    params.M = 7;
    params.L_max = 0.4375;
    const double f = params.filler_filter_fraction; // the default radius, a fraction of the filler spacing
    ASSERT_GT(f, 0.5);
    const std::vector<OffsetPoint> kept = filter_interior_points(points, sizing, params);
    EXPECT_EQ(greedy_by_all_pairs(points, sizing, params).size(), kept.size());
    double closest = 1e300;
    for (size_t i = 0; i < kept.size(); ++i)
        for (size_t j = i + 1; j < kept.size(); ++j)
            if (kept[i].generator != kept[j].generator)
                closest = std::min(closest, distance(kept[i].position, kept[j].position));
    EXPECT_GE(closest, f * s);
    // Rays 2 pi r / 96 apart: farther than the radius f s beyond
    // r = f s 96 / (2 pi), 0.76 for f = 0.8; there every point stays.
    const double apart = f * s * rays / (2 * 3.14159265358979);
    size_t outside = 0, kept_outside = 0;
    for (const OffsetPoint& p : points) outside += std::hypot(p.position.x, p.position.y) > 1.02 * apart;
    for (const OffsetPoint& p : kept) kept_outside += std::hypot(p.position.x, p.position.y) > 1.02 * apart;
    EXPECT_EQ(kept_outside, outside);
    // Inside it they are thinned: fewer than the rays bring.
    EXPECT_LT(kept.size(), points.size());
    // Near the axis the layer radius alone keeps far more.
    params.filler_filter_fraction = 0;
    const std::vector<OffsetPoint> layer_rule = filter_interior_points(points, sizing, params);
    EXPECT_GT(layer_rule.size(), kept.size() + 500) << kept.size();
}

TEST(FilterInteriorPoints, PointsOfOneGeneratorNeverClash)
{
    FeatureSize sizing;
    sizing.d = {1.0};
    std::vector<OffsetPoint> points;
    for (int k = 0; k < 5; ++k) points.push_back({{0, 0, 1e-6 * k}, 0, k + 1, false, 1e-6 * k, 0.1});
    OffsetParams params;
    params.L_max = 1;
    EXPECT_EQ(filter_interior_points(points, sizing, params).size(), points.size());
}

} // namespace
} // namespace scalemesh
