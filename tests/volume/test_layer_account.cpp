// The layer account (volume/layer_account.h) on hand-made fates, and the
// first layer that follows the surface's edge length
// (edge_layer_fractions, offset_points with FirstLayer::edge).

#include "core/adjacency.h"
#include "core/feature_size.h"
#include "core/surface_mesh.h"
#include "layers/offset_points.h"
#include "volume/layer_account.h"
#include "volume/quality.h"

#include <gtest/gtest.h>

#include <iostream>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>
#include <stdexcept>

namespace scalemesh {
namespace {

// A regular tetrahedron's surface of edge 1 around the origin (4 nodes), the
// last triangle in patch 1 when `cap` (nodes 1, 2, 3 then are opening
// nodes: a cap's triangle touches them).
SurfaceMesh tetrahedron(bool cap = false)
{
    SurfaceMesh s;
    const double a = 1 / std::sqrt(8.0);
    s.points = {{a, a, a}, {a, -a, -a}, {-a, a, -a}, {-a, -a, a}};
    s.triangles = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
    s.triangle_patch = {0, 0, 0, cap ? 1 : 0};
    return s;
}

FeatureSize sizing_of(const SurfaceMesh& s, double D)
{
    FeatureSize f;
    const size_t n = s.points.size();
    f.D.assign(n, D);
    f.D_out.assign(n, INFINITY);
    f.d.assign(n, D);
    f.inward_ok.assign(n, 1);
    for (const Vec3& p : s.points) f.normals.push_back(normalized(p));
    return f;
}

// floor(M/2) = 3 layermaking points per node, spacing 1 apart, far from
// every other node's (the account needs only their places).
std::vector<OffsetPoint> layer_points(int32_t nodes)
{
    std::vector<OffsetPoint> points;
    for (int32_t i = 0; i < nodes; ++i)
        for (int32_t m = 1; m <= 3; ++m)
            points.push_back({{100.0 * i, 0.0, double(m)}, i, m, false, double(m), 1.0});
    return points;
}

std::vector<FinalPoint> all_in_place(const std::vector<OffsetPoint>& kept)
{
    std::vector<FinalPoint> out;
    for (size_t k = 0; k < kept.size(); ++k) out.push_back({int32_t(k), kept[k].position});
    return out;
}

TEST(LayerAccount, EveryPointInPlaceGivesFullCoverage)
{
    const SurfaceMesh s = tetrahedron();
    const std::vector<OffsetPoint> raw = layer_points(4);
    const std::vector<InsertionFate> fates(raw.size(), InsertionFate::inserted);
    const LayerAccount a = account_layers(s, sizing_of(s, 7.0), 7, 1.0, raw, raw, fates, all_in_place(raw), 0.25);
    EXPECT_EQ(a.layermaking, 3);
    EXPECT_EQ(a.wall_nodes, 4);
    EXPECT_EQ(a.eligible_nodes, 4);
    EXPECT_EQ(a.eligible_full, 4);
    EXPECT_DOUBLE_EQ(a.coverage(), 1.0);
    EXPECT_DOUBLE_EQ(a.eligible_mean, 3.0);
    for (LayerLoss l : a.loss) EXPECT_EQ(l, LayerLoss::none);
}

// Each way a layer goes missing is named by the first missing layer, and
// the realised count stops there.
TEST(LayerAccount, NamesTheFateOfTheFirstMissingLayer)
{
    const SurfaceMesh s = tetrahedron();
    const std::vector<OffsetPoint> raw = layer_points(4);
    // Node 0: layer 2 filtered out. Node 1: layer 1 refused for a tiny tet.
    // Node 2: layer 3 moved by 0.3 of its spacing. Node 3: layer 2 inserted
    // but not in the mesh (no inside tet kept it).
    std::vector<OffsetPoint> kept;
    for (const OffsetPoint& p : raw)
        if (!(p.generator == 0 && p.layer == 2)) kept.push_back(p);
    std::vector<InsertionFate> fates(kept.size(), InsertionFate::inserted);
    std::vector<FinalPoint> final_points;
    for (size_t k = 0; k < kept.size(); ++k) {
        const OffsetPoint& p = kept[k];
        if (p.generator == 1 && p.layer == 1) {
            fates[k] = InsertionFate::tiny_tet;
            continue;
        }
        if (p.generator == 3 && p.layer == 2) continue;
        Vec3 at = p.position;
        if (p.generator == 2 && p.layer == 3) at.x += 0.3;
        final_points.push_back({int32_t(k), at});
    }
    const LayerAccount a = account_layers(s, sizing_of(s, 7.0), 7, 1.0, raw, kept, fates, final_points, 0.25);
    EXPECT_EQ(a.realised, (std::vector<int32_t>{1, 0, 2, 1}));
    EXPECT_EQ(a.loss[0], LayerLoss::filtered);
    EXPECT_EQ(a.loss[1], LayerLoss::tiny_tet);
    EXPECT_EQ(a.loss[2], LayerLoss::moved);
    EXPECT_EQ(a.loss[3], LayerLoss::unused);
    EXPECT_EQ(a.eligible_full, 0);
    EXPECT_DOUBLE_EQ(a.eligible_mean, 1.0);
    EXPECT_EQ(a.eligible_losses[int(LayerLoss::filtered)], 1);
    EXPECT_EQ(a.eligible_losses[int(LayerLoss::moved)], 1);
    EXPECT_EQ(a.stand_ins, 0);

    // The same move within the tolerance counts.
    const LayerAccount wider = account_layers(s, sizing_of(s, 7.0), 7, 1.0, raw, kept, fates, final_points, 0.35);
    EXPECT_EQ(wider.realised[2], 3);
    EXPECT_NEAR(wider.max_displacement, 0.3, 1e-12);
}

// A point that is not in the mesh is stood in for by another node's point of
// the same layer within the tolerance of its place, not by one of another
// layer.
TEST(LayerAccount, AnotherNodesPointOfTheSameLayerStandsIn)
{
    const SurfaceMesh s = tetrahedron();
    std::vector<OffsetPoint> raw = layer_points(2);
    // Node 1's layer-2 point sits 0.2 from node 0's, its layer-3 point 0.2
    // from node 0's layer-2 point (another layer).
    raw[4].position = raw[1].position + Vec3{0.2, 0, 0};
    raw[5].position = raw[1].position + Vec3{0, 0.2, 0};
    std::vector<InsertionFate> fates(raw.size(), InsertionFate::inserted);
    fates[4] = fates[5] = InsertionFate::hidden;
    std::vector<FinalPoint> final_points;
    for (size_t k = 0; k < raw.size(); ++k)
        if (k != 4 && k != 5) final_points.push_back({int32_t(k), raw[k].position});
    FeatureSize f = sizing_of(s, 7.0);
    const LayerAccount a = account_layers(s, f, 7, 1.0, raw, raw, fates, final_points, 0.25);
    EXPECT_EQ(a.realised[1], 2);
    EXPECT_EQ(a.loss[1], LayerLoss::hidden);
    EXPECT_EQ(a.stand_ins, 1);
}

// Opening nodes (any triangle off patch 0) and nodes with D < L_min are not
// owed the layers; a node whose normal failed is named so.
TEST(LayerAccount, OpeningNodesAndThinPlacesAreApart)
{
    const SurfaceMesh s = tetrahedron(true);
    FeatureSize f = sizing_of(s, 7.0);
    f.D[0] = 0.5;
    const std::vector<OffsetPoint> raw = layer_points(4);
    const std::vector<InsertionFate> fates(raw.size(), InsertionFate::inserted);
    LayerAccount a = account_layers(s, f, 7, 1.0, raw, raw, fates, all_in_place(raw), 0.25);
    EXPECT_EQ(a.wall_nodes, 1);
    EXPECT_EQ(a.opening_nodes, 3);
    EXPECT_EQ(a.eligible_nodes, 0);
    EXPECT_DOUBLE_EQ(a.coverage(), 1.0);

    const SurfaceMesh closed = tetrahedron();
    FeatureSize g = sizing_of(closed, 7.0);
    g.inward_ok[2] = 0; // Algorithm 4 then lays no point from node 2
    std::vector<OffsetPoint> kept;
    for (const OffsetPoint& p : raw)
        if (p.generator != 2) kept.push_back(p);
    a = account_layers(closed, g, 7, 1.0, kept, kept, std::vector<InsertionFate>(kept.size(), InsertionFate::inserted),
                       all_in_place(kept), 0.25);
    EXPECT_EQ(a.loss[2], LayerLoss::normal);
    EXPECT_EQ(a.eligible_full, 3);
    EXPECT_DOUBLE_EQ(a.coverage(), 0.75);
}

TEST(LayerAccount, RefusesMismatchedInputs)
{
    const SurfaceMesh s = tetrahedron();
    const std::vector<OffsetPoint> raw = layer_points(4);
    const FeatureSize f = sizing_of(s, 7.0);
    EXPECT_THROW(account_layers(s, f, 7, 1.0, raw, raw, {}, {}, 0.25), std::invalid_argument);
    std::vector<OffsetPoint> stranger = raw;
    stranger.push_back({{0, 0, 0}, 0, 9, false, 9.0, 1.0});
    EXPECT_THROW(account_layers(s, f, 7, 1.0, raw, stranger,
                                std::vector<InsertionFate>(stranger.size(), InsertionFate::inserted), {}, 0.25),
                 std::invalid_argument);
}

// The first layer at a given fraction, the others geometric to the same
// total; nothing changes where the first would not be thinner.
TEST(EdgeFirstLayer, FractionsStartAtTheFirstAndSumToTheSameTotal)
{
    const std::vector<double> lambda = layer_fractions(7, 1.0);
    const std::vector<double> graded = edge_layer_fractions(lambda, 0.05);
    ASSERT_EQ(graded.size(), 3u);
    EXPECT_DOUBLE_EQ(graded[0], 0.05);
    EXPECT_NEAR(std::accumulate(graded.begin(), graded.end(), 0.0), 3.0 / 7.0, 1e-12);
    const double r = graded[1] / graded[0];
    EXPECT_GT(r, 1.0);
    EXPECT_NEAR(graded[2] / graded[1], r, 1e-9);
    EXPECT_EQ(edge_layer_fractions(lambda, 0.2), lambda);
    EXPECT_EQ(edge_layer_fractions(lambda, 0.0), lambda);
}

// offset_points with FirstLayer::edge: the first point at the node's mean
// edge length over K, the last layermaking point where the paper's is. K = 1
// on the tetrahedron (edges 1): the first layer, 1, is above the cap floor
// of the next test (0.55), so the edge length alone sets it.
TEST(EdgeFirstLayer, OffsetPointsFollowTheEdgeLength)
{
    const SurfaceMesh s = tetrahedron();
    const FeatureSize f = sizing_of(s, 14.0); // d = 14: the paper's spacing is 2, edges are 1
    OffsetParams params;
    params.M = 7;
    params.L_max = 14;
    params.K = 1.0;
    params.first_layer = FirstLayer::edge;
    const std::vector<OffsetPoint> points = offset_points(s, f, params);
    params.first_layer = FirstLayer::paper;
    const std::vector<OffsetPoint> paper = offset_points(s, f, params);
    int checked = 0;
    for (const OffsetPoint& p : points) {
        if (p.layer == 1) { EXPECT_NEAR(p.dist, 1.0, 1e-12); ++checked; }
        if (p.layer == 3) { EXPECT_NEAR(p.dist, 6.0, 1e-9); ++checked; }
    }
    EXPECT_EQ(checked, 8);
    for (const OffsetPoint& p : paper)
        if (p.layer == 1) { EXPECT_NEAR(p.dist, 2.0, 1e-12); }
}

// The cap floor on a sharp corner: at a vertex of the regular tetrahedron
// the layer direction is acos(1/3) = 70.5 degrees from each incident
// triangle's normal, so a first-layer point at thickness t lies only t / 3
// above each triangle, whose height from the vertex is sqrt(3) / 2. The
// thickness is raised from edge / K = 0.25 to tan(12 deg) * (sqrt(3) / 2) * 3
// = 0.552. The cap tet over each triangle of the node, with the point as
// its apex, then has no dihedral angle below 12 degrees (28.1: the point
// also leans toward the far edge); at 0.25 it would have 7.5. With the last
// triangle on an opening, its tilt is not counted (a rim node's layer runs
// in the opening's plane), and the nodes on it keep the floor of their wall
// triangles, also 0.552.
TEST(EdgeFirstLayer, TheFirstLayerClearsTheTrianglesItIsTiltedFrom)
{
    const double floor = std::tan(12.0 * M_PI / 180) * std::sqrt(3.0) / 2 * 3;
    for (bool cap : {false, true}) {
        const SurfaceMesh s = tetrahedron(cap);
        const FeatureSize f = sizing_of(s, 7.0); // the paper's spacing is 1: not thinner than the floor
        OffsetParams params;
        params.M = 7;
        params.L_max = 7;
        params.K = 4.0;
        params.first_layer = FirstLayer::edge;
        int checked = 0;
        for (const OffsetPoint& p : offset_points(s, f, params))
            if (p.layer == 1) {
                EXPECT_NEAR(p.dist, floor, 1e-9) << "node " << p.generator << (cap ? " with a cap" : "");
                // The cap tet over each wall triangle of the node, with this
                // point as apex, and with the point at edge / K instead.
                for (size_t t = 0; t < s.triangles.size(); ++t) {
                    const Triangle& tri = s.triangles[t];
                    if (s.triangle_patch[t] != 0 || std::find(tri.begin(), tri.end(), p.generator) == tri.end())
                        continue;
                    const Vec3 &a = s.points[tri[0]], &b = s.points[tri[2]], &c = s.points[tri[1]];
                    EXPECT_GE(tet_min_dihedral_deg(a, b, c, p.position), 12.0);
                    const Vec3 at_edge_length = s.points[p.generator] + 0.25 / p.dist * (p.position - s.points[p.generator]);
                    EXPECT_LT(tet_min_dihedral_deg(a, b, c, at_edge_length), 10.0);
                }
                ++checked;
            }
        EXPECT_EQ(checked, 4);
    }
}

} // namespace
} // namespace scalemesh

namespace scalemesh {
namespace {

// The repaired direction of a node whose normal failed the inward check:
// when one is returned it clears every triangle of the fan by the margin;
// when none is, none of 20,000 directions spread over the sphere does
// either; a direction that already clears them is kept as it is.
TEST(RepairedNormal, ClearsEveryTriangleOfTheFanOrNoDirectionDoes)
{
    {
        // A closed cylinder (radius 2, 10 long, 32 around, 10 along) with
        // its top cap's centre pulled out to radius 3 (folded), or left
        // flat and started from a direction 87 degrees off its axis, or from
        // the axis.
        auto cylinder = [](double pull) {
            SurfaceMesh m;
            const int around = 32, along = 10;
            for (int j = 0; j <= along; ++j)
                for (int i = 0; i < around; ++i) {
                    const double a = 2 * M_PI * i / around;
                    m.points.push_back({2 * std::cos(a), 2 * std::sin(a), 10.0 * j / along});
                }
            const int32_t bottom = static_cast<int32_t>(m.points.size());
            m.points.push_back({0, 0, 0});
            const int32_t top = static_cast<int32_t>(m.points.size());
            m.points.push_back({pull, 0.5 * pull / 3, 10.0});
            for (int j = 0; j < along; ++j)
                for (int i = 0; i < around; ++i) {
                    const int32_t a = j * around + i, b = j * around + (i + 1) % around;
                    m.triangles.push_back({a, b, b + around});
                    m.triangles.push_back({a, b + around, a + around});
                }
            for (int i = 0; i < around; ++i) {
                m.triangles.push_back({bottom, (i + 1) % around, i});
                m.triangles.push_back({top, along * around + i, along * around + (i + 1) % around});
            }
            m.triangle_patch.assign(m.triangles.size(), 0);
            return std::make_pair(m, top);
        };
        for (const auto& [pull, start] : {std::pair{3.0, Vec3{0, 0, 1}}, std::pair{0.0, normalized(Vec3{1, 0, 0.05})},
                                          std::pair{0.0, Vec3{0, 0, 1}}}) {
            const auto [m, top] = cylinder(pull);
            const VertexTable fans = vertex_triangles(m);
            std::vector<Vec3> faces;
            for (const int32_t* f = fans.begin(top); f != fans.end(top); ++f) {
                const Triangle& t = m.triangles[*f];
                faces.push_back(normalized(cross(m.points[t[1]] - m.points[t[0]], m.points[t[2]] - m.points[t[0]])));
            }
            auto clearance = [&](const Vec3& x) {
                double low = 1;
                for (const Vec3& f : faces) low = std::min(low, dot(x, f));
                return low;
            };
            const std::optional<Vec3> x = repaired_inward_direction(m, fans, top, start, 0.1);
            if (x) {
                EXPECT_GE(clearance(*x), 0.1) << "pull " << pull;
                EXPECT_NEAR(norm(*x), 1.0, 1e-12);
                if (clearance(start) >= 0.1) {
                    EXPECT_EQ(*x, start); // already clear: kept
                }
            } else {
                double best = -1;
                const int count = 20000;
                for (int k = 0; k < count; ++k) { // a Fibonacci sphere
                    const double z = 1 - 2 * (k + 0.5) / count, r = std::sqrt(1 - z * z), a = k * 2.399963229728653;
                    best = std::max(best, clearance({r * std::cos(a), r * std::sin(a), z}));
                }
                EXPECT_LT(best, 0.1) << "pull " << pull << ": a direction clears the fan by " << best;
            }
            std::cout << "[ pull " << pull << " ] " << (x ? "repaired, clearance " : "none; start's clearance ")
                      << clearance(x ? *x : start) << "\n";
            if (pull == 0.0) {
                EXPECT_TRUE(x.has_value()); // a flat cap: its axis clears it
            }
        }
    }
}

} // namespace
} // namespace scalemesh
