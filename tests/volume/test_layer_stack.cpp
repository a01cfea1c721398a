// The explicit prism layers: the index rule's split of a prism and the
// shortening of a column (volume/layer_stack.h, layers/offset_points.h).

#include "core/errors.h"
#include "core/feature_size.h"
#include "core/nearest_triangle.h"
#include "core/tet_mesh.h"
#include "volume/improve.h"
#include "volume/layer_stack.h"
#include "volume/tet_editor.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace scalemesh {
namespace {

// The faces of `tets` whose three points are all in `quad`, as sorted triples.
std::set<std::array<int32_t, 3>> faces_on(const std::array<Tet, 3>& tets, const std::set<int32_t>& quad)
{
    std::set<std::array<int32_t, 3>> out;
    for (const Tet& t : tets)
        for (int k = 0; k < 4; ++k) {
            std::array<int32_t, 3> f = tet_face(t, k);
            if (!quad.count(f[0]) || !quad.count(f[1]) || !quad.count(f[2])) continue;
            std::sort(f.begin(), f.end());
            out.insert(f);
        }
    return out;
}

TEST(PrismSplit, EveryOrderOfTheColumnsGivesThreePositiveTetsFillingThePrism)
{
    // An oblique prism over a wall triangle whose normal is +z, the layer
    // below it: points 0..2 the bottom, 3..5 the top (its side quads are
    // planar, so every split fills the same volume).
    const Vec3 shift{0.3, 0.2, -1};
    const std::vector<Vec3> at = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}, Vec3{0, 0, 0} + shift, Vec3{2, 0, 0} + shift,
                                  Vec3{0, 2, 0} + shift};
    std::array<int32_t, 3> column{0, 1, 2};
    do {
        const std::array<Tet, 3> tets = prism_split({0, 1, 2}, {3, 4, 5}, column);
        double total = 0;
        for (const Tet& t : tets) {
            const double v = tet_volume6(at[t[0]], at[t[1]], at[t[2]], at[t[3]]);
            EXPECT_GT(v, 0) << "columns " << column[0] << column[1] << column[2];
            total += v;
        }
        // The union's volume is the prism's: base area 2 times height 1,
        // six times over.
        EXPECT_NEAR(total, 12.0, 1e-12);
        // Every point of the prism is a corner of some tet, and each tet
        // has points of both ends (no tet lies in one end).
        std::set<int32_t> used;
        for (const Tet& t : tets) {
            used.insert(t.begin(), t.end());
            const int bottom = int(std::count_if(t.begin(), t.end(), [](int32_t v) { return v < 3; }));
            EXPECT_GE(bottom, 1);
            EXPECT_LE(bottom, 3);
        }
        EXPECT_EQ(used.size(), 6u);
    } while (std::next_permutation(column.begin(), column.end()));
}

TEST(PrismSplit, TwoPrismsSharingASideCutItAlike)
{
    // Wall triangles (a, b, c) and (b, a, d) share the edge a-b; their
    // layer points are a + 10, b + 10, ... Whatever the third columns'
    // ids, both prisms cut the quad (a, b, b', a') along the same diagonal:
    // from the lower column's bottom to the higher's top.
    for (const auto& [c, d] : std::vector<std::pair<int32_t, int32_t>>{{0, 5}, {5, 0}, {9, 8}, {2, 3}}) {
        const int32_t a = 4, b = 6;
        const std::array<Tet, 3> left = prism_split({a, b, c}, {a + 10, b + 10, c + 10}, {a, b, c});
        const std::array<Tet, 3> right = prism_split({b, a, d}, {b + 10, a + 10, d + 10}, {b, a, d});
        const std::set<int32_t> quad{a, b, a + 10, b + 10};
        const auto on_left = faces_on(left, quad), on_right = faces_on(right, quad);
        EXPECT_EQ(on_left, on_right) << "third columns " << c << ", " << d;
        ASSERT_EQ(on_left.size(), 2u);
        EXPECT_TRUE(on_left.count({a, b, b + 10})) << "the diagonal runs from " << a << " to " << b + 10;
        EXPECT_TRUE(on_left.count({a, a + 10, b + 10}));
    }
}

TEST(LayerStack, AShortenedColumnKeepsItsFirstLayerAndEndsAtTheNewHeight)
{
    const std::vector<double> dist = {0.1, 0.35, 0.8}; // graded: 0.1, 0.25, 0.45
    EXPECT_EQ(shortened_column(dist.data(), 3, 1.0), dist);
    double ratio = 1e300;
    for (double scale : {0.9, 0.6, 0.4}) {
        const std::vector<double> out = shortened_column(dist.data(), 3, scale);
        ASSERT_EQ(out.size(), 3u);
        EXPECT_NEAR(out[0], 0.1, 1e-12) << scale;
        EXPECT_DOUBLE_EQ(out[2], scale * 0.8) << scale;
        // Geometric from the first layer, growing less the shorter it is.
        const double r = (out[1] - out[0]) / out[0];
        EXPECT_NEAR((out[2] - out[1]) / (out[1] - out[0]), r, 1e-9) << scale;
        EXPECT_GE(r, 1.0) << scale;
        EXPECT_LT(r, ratio) << scale;
        ratio = r;
    }
    // Too short for the first layer's thickness to grow from: equal layers.
    const std::vector<double> flat = shortened_column(dist.data(), 3, 0.3);
    EXPECT_NEAR(flat[0], 0.08, 1e-12);
    EXPECT_NEAR(flat[1], 0.16, 1e-12);
    EXPECT_NEAR(flat[2], 0.24, 1e-12);
}

// A wall triangle (a, b, c) whose edge a-b lies on an opening's rim (z = 0
// wall, y = 0 cap, the fluid at z > 0, y < 0), one layer: a and b's columns
// are the cap's nodes a1, b1, the cap's strip between them two triangles.
struct RimTriangle {
    SurfaceMesh surface;
    FeatureSize sizing;
    LayerColumns columns;
    LayerStackParams params;
    RimTriangle(const Vec3& c_inward, bool with_strip = true)
    {
        const double h = 0.5;
        surface.points = {{0, 0, 0}, {1, 0, 0}, {0.5, -1, 0}, {0, 0, h}, {1, 0, h}}; // a b c a1 b1
        surface.triangles = {{0, 1, 2}};
        surface.triangle_patch = {0};
        if (with_strip) {
            surface.triangles.push_back({0, 4, 1}), surface.triangle_patch.push_back(1);
            surface.triangles.push_back({0, 3, 4}), surface.triangle_patch.push_back(1);
        }
        sizing.d.assign(5, 1.0);
        sizing.D.assign(5, 10.0);
        columns.layers = 1;
        columns.inward = {{0, 0, 1}, {0, 0, 1}, normalized(c_inward), {0, 0, 1}, {0, 0, 1}};
        columns.dist.assign(5, h);
        columns.spacing.assign(5, h);
        columns.repaired.assign(5, 0);
        params.rim_columns = {3, 4, -1, -1, -1};
    }
};

TEST(LayerStack, APoorPrismOnARimEdgeLeavesAHoleClosedByTheCapsStrip)
{
    // The free column upright: one intact prism, nothing left to the core
    // but its top.
    {
        RimTriangle rim({0, 0, 1});
        const LayerStack stack = build_layer_stack(rim.surface, rim.sizing, rim.columns, rim.params);
        EXPECT_EQ(stack.holes, 0);
        EXPECT_EQ(stack.prisms, 1);
        EXPECT_EQ(stack.tets.size(), 3u);
        ASSERT_EQ(stack.top.size(), 1u);
    }
    // The free column lying almost along the wall, toward the rim: its
    // prism's tet on the wall stays flat however short the column is. The
    // triangle is left bare, and the core's boundary there is the triangle
    // and the cap's strip along a-b (where the prism's side would have been).
    RimTriangle rim({0, 1, 0.02});
    const LayerStack stack = build_layer_stack(rim.surface, rim.sizing, rim.columns, rim.params);
    EXPECT_EQ(stack.holes, 1);
    EXPECT_EQ(stack.prisms, 0);
    EXPECT_TRUE(stack.tets.empty());
    ASSERT_EQ(stack.top.size(), 3u);
    EXPECT_EQ(stack.top[0], (Triangle{0, 1, 2}));
    EXPECT_EQ(stack.top[1], (Triangle{0, 4, 1}));
    EXPECT_EQ(stack.top[2], (Triangle{0, 3, 4}));
    EXPECT_EQ(stack.top_of, (std::vector<int32_t>{0, 0, 0}));
    // Without the strip (a cap not cut as the rim prisms' sides) the hole
    // could not be closed: a stage error, not an open core.
    RimTriangle stripless({0, 1, 0.02}, false);
    try {
        build_layer_stack(stripless.surface, stripless.sizing, stripless.columns, stripless.params);
        ADD_FAILURE() << "no StageError without the cap's strip";
    } catch (const StageError& e) {
        EXPECT_NE(std::string(e.what()).find("strip along its rim edge 0-1"), std::string::npos) << e.what();
    }
}


// The rim triangle, its columns upright (0.5 long), with a core face (a
// cap's fill, given as such) 0.05 over c's top, level, its longest edge
// 1.03. With min_core_clearance (0.2) c's column is shortened until its top
// is at least 0.2 of that edge from the face; without it (0) it keeps its
// whole height.
TEST(LayerStack, AColumnsTopJustOverACapsFillIsShortened)
{
    const auto stack_of = [](double clearance) {
        RimTriangle rim({0, 0, 1});
        for (const Vec3& x : {Vec3{0, -1.5, 0.55}, Vec3{1, -1.5, 0.55}, Vec3{0.5, -0.6, 0.55}}) {
            rim.surface.points.push_back(x);
            rim.sizing.d.push_back(1.0);
            rim.sizing.D.push_back(10.0);
            rim.columns.inward.push_back({0, 0, 1});
            rim.columns.dist.push_back(std::nan(""));
            rim.columns.spacing.push_back(std::nan(""));
            rim.columns.repaired.push_back(0);
            rim.params.rim_columns.push_back(-1);
        }
        rim.params.core_faces = {{5, 6, 7}};
        rim.params.min_core_clearance = clearance;
        const LayerStack stack = build_layer_stack(rim.surface, rim.sizing, rim.columns, rim.params);
        EXPECT_EQ(stack.holes, 0);
        EXPECT_EQ(stack.prisms, 1);
        const std::vector<Vec3>& p = rim.surface.points;
        const Vec3 top = p[2] + stack.scale[2] * 0.5 * Vec3{0, 0, 1};
        return std::pair{stack.scale[2], std::sqrt(point_triangle_distance2(top, p[5], p[6], p[7]))};
    };
    const auto [whole, near] = stack_of(0);
    EXPECT_EQ(whole, 1.0);
    EXPECT_NEAR(near, 0.05, 1e-12);
    const auto [shortened, clear] = stack_of(0.2);
    EXPECT_LT(shortened, 1.0);
    EXPECT_GE(clear, 0.2 * std::hypot(0.5, 0.9));
}

// The directed edges of `faces` that no face runs the other way: the
// boundary of the surface they make.
std::set<std::pair<int32_t, int32_t>> unmatched_edges(const std::vector<Triangle>& faces)
{
    std::set<std::pair<int32_t, int32_t>> edges;
    for (const Triangle& t : faces)
        for (int k = 0; k < 3; ++k) edges.insert({t[k], t[(k + 1) % 3]});
    std::set<std::pair<int32_t, int32_t>> out;
    for (const auto& e : edges)
        if (!edges.count({e.second, e.first})) out.insert(e);
    return out;
}

TEST(LayerStack, ABareRimTriangleBesideAPrismLeavesTheCoreBoundaryOneSurface)
{
    // Two wall triangles, (a, b, c) on the rim edge a-b and (c, b, e)
    // beside it, one layer. The cap's node a1 (a's column) lies almost on
    // the wall, leaning along the rim, so (a, b, c)'s prism stays poor
    // however its free column is shortened: it is left bare. (c, b, e)
    // keeps its prism. The core's boundary is then the bare triangle, the
    // cap's strip along a-b, the prism's side face along b-c and its top:
    // one surface with one boundary loop, every directed edge inside it
    // matched by its reverse (no gap at b, where all four meet).
    const double h = 0.5;
    SurfaceMesh surface;
    surface.points = {{0, 0, 0}, {1, 0, 0}, {0.5, -1, 0}, {0.3, 0, 0.02}, {1, 0, h}, {1.5, -1, 0}}; // a b c a1 b1 e
    surface.triangles = {{0, 1, 2}, {2, 1, 5}, {0, 3, 1}, {3, 4, 1}};
    surface.triangle_patch = {0, 0, 1, 1};
    FeatureSize sizing;
    sizing.d.assign(6, 1.0);
    sizing.D.assign(6, 10.0);
    LayerColumns columns;
    columns.layers = 1;
    columns.inward.assign(6, Vec3{0, 0, 1});
    columns.dist.assign(6, h);
    columns.spacing.assign(6, h);
    columns.repaired.assign(6, 0);
    LayerStackParams params;
    params.rim_columns = {3, 4, -1, -1, -1, -1};
    const LayerStack stack = build_layer_stack(surface, sizing, columns, params);
    EXPECT_EQ(stack.holes, 1);
    EXPECT_EQ(stack.prisms, 1);
    EXPECT_EQ(stack.tets.size(), 3u);
    // The bare triangle and the strip are in the boundary as they are.
    for (const Triangle& t : {Triangle{0, 1, 2}, Triangle{0, 3, 1}, Triangle{3, 4, 1}})
        EXPECT_NE(std::find(stack.top.begin(), stack.top.end(), t), stack.top.end())
            << t[0] << " " << t[1] << " " << t[2];
    // One boundary loop: every point of it is left once and entered once.
    const auto loop = unmatched_edges(stack.top);
    std::map<int32_t, int> out_degree, in_degree;
    for (const auto& e : loop) ++out_degree[e.first], ++in_degree[e.second];
    for (const auto& [v, n] : out_degree) EXPECT_EQ(n, 1) << "point " << v << " leaves the boundary " << n << " times";
    EXPECT_EQ(in_degree, out_degree);
    // The edge b-c between the hole and the prism is inside the surface.
    EXPECT_FALSE(loop.count({1, 2}));
    EXPECT_FALSE(loop.count({2, 1}));
    // Euler: V - E + F = 1 for a disc.
    std::set<int32_t> points;
    std::set<std::pair<int32_t, int32_t>> edges;
    for (const Triangle& t : stack.top)
        for (int k = 0; k < 3; ++k) {
            points.insert(t[k]);
            edges.insert(std::minmax(t[k], t[(k + 1) % 3]));
        }
    EXPECT_EQ(int64_t(points.size()) - int64_t(edges.size()) + int64_t(stack.top.size()), 1);
}

// The worst side face between the two prisms of each layer over the wall
// triangles (a, b, c) and (b, a, d) (points 0 to 3, no holes): the angle between the
// quad a-b's area vector and the join of the prisms' centroids, degrees.
double worst_side_face_deg(const SurfaceMesh& surface, const LayerStack& stack)
{
    const int32_t n = static_cast<int32_t>(surface.points.size());
    const auto at = [&](int32_t v) { return v < n ? surface.points[v] : stack.points[v - n]; };
    const auto point = [&](int32_t v, int32_t m) { return m == 0 ? v : n + stack.first[v] + m - 1; };
    const auto centroid = [&](size_t first_tet) {
        Vec3 sum;
        double total = 0;
        for (size_t i = first_tet; i < first_tet + 3; ++i) {
            const Tet& t = stack.tets[i];
            const double v = tet_volume6(at(t[0]), at(t[1]), at(t[2]), at(t[3]));
            sum += v * (at(t[0]) + at(t[1]) + at(t[2]) + at(t[3])) / 4;
            total += v;
        }
        return sum / total;
    };
    double worst = 0;
    for (int32_t m = 1; m <= stack.layers; ++m) {
        // Tets in wall triangle order, then layer by layer, three a prism.
        const Vec3 join = centroid(3 * size_t(stack.layers + m - 1)) - centroid(3 * size_t(m - 1));
        const Vec3 area = cross(at(point(1, m)) - at(point(0, m - 1)), at(point(0, m)) - at(point(1, m - 1)));
        const double cosine = std::abs(dot(area, join)) / (norm(area) * norm(join));
        worst = std::max(worst, std::acos(std::min(1.0, cosine)) * 180 / M_PI);
    }
    return worst;
}

TEST(LayerStack, SideFacesBetweenPrismsStayWithinTheBound)
{
    // Two wall triangles on the edge a-b, three layers. a and b's columns
    // stand upright; c's leans toward +x and d's toward -x, as where the
    // wall curves: layer by layer the two prisms part along the edge, and
    // the join of their centroids turns away from the normal of the quad
    // they share. The columns are shortened until no side face is beyond
    // the bound.
    SurfaceMesh surface;
    surface.points = {{0, 0, 0}, {1, 0, 0}, {0.5, -0.25, 0}, {0.5, 0.25, 0}}; // a b c d
    surface.triangles = {{0, 1, 2}, {1, 0, 3}};
    surface.triangle_patch = {0, 0};
    FeatureSize sizing;
    sizing.d.assign(4, 1.0);
    sizing.D.assign(4, 100.0);
    LayerColumns columns;
    columns.layers = 3;
    columns.inward = {{0, 0, 1}, {0, 0, 1}, normalized(Vec3{0.84, 0, 1}), normalized(Vec3{-0.84, 0, 1})};
    for (int v = 0; v < 4; ++v) {
        columns.dist.insert(columns.dist.end(), {0.4, 0.9, 1.5});
        columns.spacing.insert(columns.spacing.end(), {0.4, 0.5, 0.6});
    }
    columns.repaired.assign(4, 0);

    LayerStackParams unbounded;
    unbounded.max_side_non_orthogonality_deg = 90;
    const LayerStack free_stack = build_layer_stack(surface, sizing, columns, unbounded);
    ASSERT_EQ(free_stack.prisms, 6); // two triangles, three layers
    ASSERT_EQ(free_stack.holes, 0);
    const double free_worst = worst_side_face_deg(surface, free_stack);
    EXPECT_GT(free_worst, 70); // beyond what a solver takes: the geometry asks for the bound

    const LayerStackParams bounded; // 65 degrees
    const LayerStack stack = build_layer_stack(surface, sizing, columns, bounded);
    ASSERT_EQ(stack.prisms, 6);
    EXPECT_EQ(stack.holes, 0);
    EXPECT_LE(worst_side_face_deg(surface, stack), bounded.max_side_non_orthogonality_deg + 1e-9);
    EXPECT_GT(stack.shortened_nodes, 0);
    // Shortened, not to the floor: the columns keep more than min_scale of
    // their height.
    for (int32_t v = 0; v < 4; ++v) EXPECT_GT(stack.scale[v], bounded.min_scale) << v;
}

TEST(LayerStack, TheCellPassesMeasureAPrismsFaceFromThePrismsCentre)
{
    // One right prism of height 0.2 over (a, b, c) and a core tet on its top
    // with its apex e off to the side. The solver sees the prism as one
    // cell, centred at (1/3, 1/3, 0.1): the top face's non-orthogonality is
    // measured from there, not from the centroid of the tet of the split
    // that holds the top.
    const std::vector<Vec3> x = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0.2}, {1, 0, 0.2}, {0, 1, 0.2}, {0.9, 0.6, 0.7}};
    const std::array<Tet, 3> split = prism_split({0, 1, 2}, {3, 4, 5}, {0, 1, 2});
    const Tet core{3, 4, 5, 6};
    PrismCells prisms;
    prisms.generator = {0, 1, 2, 0, 1, 2, -1};
    prisms.layer = {0, 0, 0, 1, 1, 1, -1};
    prisms.points = {{0, 1, 2, 3, 4, 5}};
    prisms.index[{0, 1, 2, 1}] = 0;
    prisms.start = x;
    improvement::CellCentres centres;
    centres.prisms = &prisms;
    const std::vector<int32_t> global = {0, 1, 2, 3, 4, 5, 6};
    centres.global = &global;
    for (int32_t v = 0; v < 7; ++v) centres.local[v] = v;
    centres.stacked = {1, 1, 1, 1, 1, 1, 0};
    const auto at = [&](int32_t v) -> const Vec3& { return x[v]; };

    for (const Tet& t : split) EXPECT_EQ(prisms.prism_of(t), 0) << t[0] << t[1] << t[2] << t[3];
    EXPECT_EQ(prisms.prism_of(core), -1);
    const Tet* top = nullptr;
    for (const Tet& t : split)
        if (improvement::TetEditor::contains(t, 3) && improvement::TetEditor::contains(t, 4) &&
            improvement::TetEditor::contains(t, 5))
            top = &t;
    ASSERT_NE(top, nullptr);

    const Vec3 prism_centre{1.0 / 3, 1.0 / 3, 0.1};
    const Vec3 core_centre = (x[3] + x[4] + x[5] + x[6]) / 4;
    const Vec3 join = core_centre - prism_centre;
    const double expected = join.z / norm(join); // the top face's normal out of the prism is +z
    const double measured = improvement::shared_face_cosine(at, *top, core, &centres);
    EXPECT_NEAR(measured, expected, 1e-12);
    // From the tet's own centroid the angle is another.
    EXPECT_GT(std::abs(improvement::shared_face_cosine(at, *top, core) - expected), 0.01);
    // Two tets of one prism are one cell: no face between them is measured.
    EXPECT_EQ(improvement::shared_face_cosine(at, split[0], split[1], &centres), 1.0);
}

} // namespace
} // namespace scalemesh
