// Rivara bisection (Algorithm 2, Appendix A) on a hand-built closed surface
// whose chain is known: the edge that is too long is not the longest of its
// neighbour triangle, so the chain's terminal edge is split first.

#include "core/surface_mesh.h"
#include "core/tet_mesh.h"
#include "remeshing/remesh.h"
#include "support/triangle_angles.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <utility>
#include <vector>

namespace scalemesh {
namespace {

double min_angle_degrees(const SurfaceMesh& mesh)
{
    double smallest = 180;
    for (const Triangle& t : mesh.triangles) smallest = std::min(smallest, min_angle_degrees(mesh, t));
    return smallest;
}

int32_t find_point(const SurfaceMesh& mesh, const Vec3& x)
{
    for (size_t i = 0; i < mesh.points.size(); ++i)
        if (distance(mesh.points[i], x) < 1e-12) return static_cast<int32_t>(i);
    return -1;
}

// The tetrahedron A = (0,0,0), B = (4,0,0), C = (2.5,2,0), D = (2,1,2):
// |AB| = 4 (the longest edge, of both its triangles), |AC| = 3.20,
// |AD| = |BD| = 3, |BC| = 2.5, |CD| = 2.29. With K = M = 1 the bisection
// length is min(d) of an edge's ends: d = 5 at A, B, D and 2.8 at C makes
// AC alone too long. AC is not the longest edge of ABC, so its Rivara chain
// runs AC -> AB: AB is split at m = (2,0,0) first. Then AC is the longest
// edge of both its triangles (AmC: 2, 2.06, 3.20; ACD) and is split at
// n = (1.25,1,0); every edge is then short enough: two bisections in all.
// A tetrahedron has no merge (every node has three neighbours) and no swap
// (its other diagonal is an edge already), and no smoothing runs, so the
// bisections are all that happens.
struct Chain {
    SurfaceMesh input;
    std::vector<double> d;
    RemeshParams params;
};

Chain tetrahedron_chain()
{
    Chain c;
    c.input.points = {{0, 0, 0}, {4, 0, 0}, {2.5, 2, 0}, {2, 1, 2}};
    Tet t{0, 1, 2, 3};
    const auto& p = c.input.points;
    if (tet_volume6(p[0], p[1], p[2], p[3]) < 0) std::swap(t[1], t[2]);
    for (int k = 0; k < 4; ++k) c.input.triangles.push_back(tet_face(t, k));
    c.d = {5, 5, 2.8, 5};
    c.params.K = 1;
    c.params.M = 1;
    c.params.cycles = 1;
    c.params.smoothing_sweeps = 0;
    c.params.conserve_volume = false;
    c.params.sizing.K = 1;
    c.params.sizing.M = 1;
    c.params.sizing.L_min = 0.1;
    c.params.sizing.L_max = 10;
    return c;
}

TEST(KernelRivara, ChainSplitsTheTerminalEdgeFirstAndStaysConforming)
{
    const Chain c = tetrahedron_chain();
    ASSERT_TRUE(surface_facts(c.input).closed_manifold());
    const double input_angle = min_angle_degrees(c.input);
    const RemeshResult r = remesh_to_feature_size(c.input, c.d, c.params);
    ASSERT_EQ(r.merges, 0);
    ASSERT_EQ(r.swaps, 0);
    EXPECT_EQ(r.bisections, 2);

    const SurfaceFacts facts = surface_facts(r.surface);
    EXPECT_TRUE(facts.closed_manifold()) << "a hanging node or an open edge";
    EXPECT_EQ(facts.euler_characteristic, 2);
    EXPECT_EQ(facts.components, 1);
    EXPECT_EQ(facts.vertices, 6);
    EXPECT_EQ(facts.triangles, 8);
    EXPECT_NEAR(facts.signed_volume, signed_volume(c.input), 1e-12);

    // The input points stay; the terminal edge AB and then AC were split at
    // their midpoints.
    for (const Vec3& x : c.input.points) EXPECT_GE(find_point(r.surface, x), 0) << "an input point moved";
    const int32_t m = find_point(r.surface, {2, 0, 0});
    const int32_t n = find_point(r.surface, {1.25, 1, 0});
    EXPECT_GE(m, 0) << "the chain's terminal edge AB was not split";
    EXPECT_GE(n, 0) << "the too long edge AC was not split";

    // Rivara's bound: no angle below half the smallest input angle.
    EXPECT_GE(min_angle_degrees(r.surface), input_angle / 2);

    // No edge is left longer than K/M d at the smaller d of its ends.
    ASSERT_EQ(r.target_d.size(), r.surface.points.size());
    for (const Triangle& t : r.surface.triangles)
        for (int k = 0; k < 3; ++k) {
            const int32_t a = t[k], b = t[(k + 1) % 3];
            EXPECT_LE(distance(r.surface.points[a], r.surface.points[b]), std::min(r.target_d[a], r.target_d[b]) + 1e-12);
        }
}

// With d = 5 at C too, no edge is too long (AB, the longest, is 4): nothing
// is split, so the split of AB above came from AC's chain alone.
TEST(KernelRivara, NothingTooLongNothingSplit)
{
    Chain c = tetrahedron_chain();
    c.d = {5, 5, 5, 5};
    const RemeshResult r = remesh_to_feature_size(c.input, c.d, c.params);
    EXPECT_EQ(r.bisections, 0);
    EXPECT_EQ(r.surface.points.size(), 4u);
    EXPECT_EQ(r.surface.triangles.size(), 4u);
}

} // namespace
} // namespace scalemesh
