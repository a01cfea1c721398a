// The slab cut the parallel insertion and improvement share, and the
// section 2.3 topology check, on inputs whose answer is known by
// construction.

#include "core/tet_mesh.h"
#include "volume/slabs.h"
#include "volume/volume_mesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace scalemesh {
namespace {

TEST(EqualCountSlabs, CutsAlongTheLongestSideIntoEqualCounts)
{
    std::mt19937 random(7);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<Vec3> points;
    for (int i = 0; i < 1000; ++i) points.push_back({unit(random), 5 * unit(random) - 2, unit(random)});

    for (int count : {1, 2, 3, 4}) {
        const SlabCut cut = equal_count_slabs(points, count);
        EXPECT_EQ(cut.axis, 1);
        ASSERT_EQ(cut.count(), count);
        EXPECT_TRUE(std::is_sorted(cut.bounds.begin(), cut.bounds.end()));
        std::vector<double> y;
        for (const Vec3& p : points) y.push_back(p.y);
        std::sort(y.begin(), y.end());
        EXPECT_EQ(cut.bounds.front(), y.front());
        EXPECT_EQ(cut.bounds.back(), y.back());
        for (int s = 1; s < count; ++s) EXPECT_EQ(cut.bounds[s], y[y.size() * s / count]);
        // Distinct coordinates: every slab holds exactly its share.
        std::vector<int> in(count, 0);
        for (const Vec3& p : points) {
            const int s = cut.of(p);
            ASSERT_GE(s, 0);
            ASSERT_LT(s, count);
            EXPECT_LE(cut.bounds[s], p.y);
            ++in[s];
        }
        for (int s = 0; s < count; ++s) EXPECT_EQ(in[s], static_cast<int>(points.size() * (s + 1) / count - points.size() * s / count));
    }
    const SlabCut none = equal_count_slabs({}, 3);
    EXPECT_EQ(none.count(), 3);
    EXPECT_EQ(none.of(Vec3{1, 2, 3}), 2);
}

// The second cut of the cell passes: count + 1 slabs whose inner cuts are
// the middles (in rank) of the equal-count slabs, so each cut of one lies
// strictly inside a slab of the other.
TEST(MiddleSlabs, CutTheEqualCountSlabsAtTheirMiddles)
{
    std::mt19937 random(11);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<Vec3> points;
    for (int i = 0; i < 1000; ++i) points.push_back({unit(random), unit(random), 3 * unit(random)});
    std::vector<double> z;
    for (const Vec3& p : points) z.push_back(p.z);
    std::sort(z.begin(), z.end());
    for (int count : {1, 2, 4, 8}) {
        const SlabCut equal = equal_count_slabs(points, count), middle = middle_slabs(points, count);
        EXPECT_EQ(middle.axis, equal.axis);
        ASSERT_EQ(middle.count(), count + 1);
        EXPECT_EQ(middle.bounds.front(), z.front());
        EXPECT_EQ(middle.bounds.back(), z.back());
        for (int s = 1; s <= count; ++s) {
            EXPECT_EQ(middle.bounds[s], z[z.size() * (2 * s - 1) / (2 * count)]);
            EXPECT_GT(middle.bounds[s], equal.bounds[s - 1]);
            EXPECT_LT(middle.bounds[s], equal.bounds[s]);
        }
    }
}

TetMesh tets_on_seven_points(const std::vector<Tet>& tets)
{
    TetMesh mesh;
    for (int i = 0; i < 8; ++i) mesh.points.push_back({double(i), double(i * i % 5), double(i * i * i % 7)});
    mesh.tets = tets;
    return mesh;
}

TEST(TopologyCheck, ANodeFailsWhenItsTetsDoNotMeetAcrossFacesThroughIt)
{
    // Two tets on a face: every node's tets meet.
    EXPECT_TRUE(topology_check_failures(tets_on_seven_points({{0, 1, 2, 3}, {1, 2, 3, 4}}), 5).empty());
    // On a vertex only: that node fails.
    EXPECT_EQ(topology_check_failures(tets_on_seven_points({{0, 1, 2, 3}, {0, 4, 5, 6}}), 7),
              (std::vector<int32_t>{0}));
    // On an edge only: both of its ends fail.
    EXPECT_EQ(topology_check_failures(tets_on_seven_points({{0, 1, 2, 3}, {0, 1, 4, 5}}), 6),
              (std::vector<int32_t>{0, 1}));
    // A node without tets fails.
    EXPECT_EQ(topology_check_failures(tets_on_seven_points({{0, 1, 2, 3}}), 5), (std::vector<int32_t>{4}));
    // Node 0's two tets are joined by a chain of faces, but only through
    // tets that do not hold node 0: its star is still two pieces.
    const TetMesh chain = tets_on_seven_points({{0, 1, 2, 3}, {1, 2, 3, 4}, {1, 2, 4, 5}, {1, 4, 5, 6}, {0, 4, 5, 6}});
    EXPECT_EQ(topology_check_failures(chain, 7), (std::vector<int32_t>{0}));
    // Only nodes below surface_points are judged.
    EXPECT_TRUE(topology_check_failures(chain, 0).empty());
    // The adjacency must be of these tets.
    EXPECT_THROW(topology_check_failures(chain, 7, tet_face_adjacency(tets_on_seven_points({{0, 1, 2, 3}}))),
                 std::invalid_argument);
}

} // namespace
} // namespace scalemesh
