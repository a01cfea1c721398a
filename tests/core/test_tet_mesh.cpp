// Tet face adjacency and mesh facts on meshes whose answer is known by
// construction, checked against a plain map of faces.

#include "core/tet_mesh.h"
#include "exporters/tet_meshes.h"

#include <tbb/task_arena.h>

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <stdexcept>

namespace scalemesh {
namespace {

// The tets holding each face, by its sorted points: the answer by brute force.
std::map<std::array<int32_t, 3>, std::vector<int32_t>> tets_by_face(const TetMesh& mesh)
{
    std::map<std::array<int32_t, 3>, std::vector<int32_t>> by_face;
    for (int32_t t = 0; t < static_cast<int32_t>(mesh.tets.size()); ++t)
        for (int k = 0; k < 4; ++k) {
            Triangle f = tet_face(mesh.tets[t], k);
            std::sort(f.begin(), f.end());
            by_face[f].push_back(t);
        }
    return by_face;
}

void expect_matches_brute_force(const TetMesh& mesh, const TetFaceAdjacency& adjacency)
{
    const auto by_face = tets_by_face(mesh);
    ASSERT_EQ(adjacency.across.size(), 4 * mesh.tets.size());
    int64_t overshared = 0;
    for (const auto& [face, tets] : by_face) overshared += tets.size() > 2;
    EXPECT_EQ(adjacency.overshared_faces, overshared);
    for (int32_t t = 0; t < static_cast<int32_t>(mesh.tets.size()); ++t)
        for (int k = 0; k < 4; ++k) {
            Triangle f = tet_face(mesh.tets[t], k);
            std::sort(f.begin(), f.end());
            const std::vector<int32_t>& tets = by_face.at(f);
            const int32_t across = adjacency.across[4 * t + k];
            if (tets.size() == 1) EXPECT_EQ(across, TetFaceAdjacency::kBoundary);
            else if (tets.size() > 2) EXPECT_EQ(across, TetFaceAdjacency::kOvershared);
            else EXPECT_EQ(across, tets[0] == t ? tets[1] : tets[0]) << "tet " << t << " face " << k;
        }
}

TEST(TetFaceAdjacency, BoxOfCubesMatchesAMapOfFaces)
{
    const TetMesh box = box_of_cubes(3, 4, 5);
    const TetFaceAdjacency adjacency = tet_face_adjacency(box);
    expect_matches_brute_force(box, adjacency);
    int64_t boundary = 0;
    for (int32_t a : adjacency.across) boundary += a == TetFaceAdjacency::kBoundary;
    EXPECT_EQ(boundary, 2 * 2 * (3 * 4 + 4 * 5 + 3 * 5)); // two triangles per unit square of the box's faces
}

TEST(TetFaceAdjacency, SameAnswerForAnyThreadCountAndTetOrder)
{
    TetMesh box = box_of_cubes(20, 20, 20); // 48,000 tets: more than one chunk
    std::mt19937 random(7);
    std::shuffle(box.tets.begin(), box.tets.end(), random);
    const TetFaceAdjacency one = tbb::task_arena(1).execute([&] { return tet_face_adjacency(box); });
    const TetFaceAdjacency two = tbb::task_arena(2).execute([&] { return tet_face_adjacency(box); });
    EXPECT_EQ(one.across, two.across);
    expect_matches_brute_force(box, two);
}

TEST(SortTetsBySmallestPoint, TheOrderDependsOnTheTetsAloneAndEachTetKeepsItsOrientation)
{
    const TetMesh box = box_of_cubes(12, 10, 9);
    std::vector<Tet> first = box.tets, second = box.tets;
    std::mt19937 random(11);
    std::shuffle(first.begin(), first.end(), random);
    std::shuffle(second.begin(), second.end(), random);
    ASSERT_NE(first, second);
    sort_tets_by_smallest_point(first, box.points.size());
    tbb::task_arena(1).execute([&] { sort_tets_by_smallest_point(second, box.points.size()); });
    EXPECT_EQ(first, second);
    auto sorted = [](Tet t) {
        std::sort(t.begin(), t.end());
        return t;
    };
    for (size_t i = 1; i < first.size(); ++i)
        EXPECT_LT(sorted(first[i - 1]), sorted(first[i])) << "tets " << i - 1 << " and " << i;
    // The same tets, each with its own point order (so its orientation).
    std::vector<Tet> before = box.tets, after = first;
    std::sort(before.begin(), before.end());
    std::sort(after.begin(), after.end());
    EXPECT_EQ(before, after);
}

TEST(TetFaceAdjacency, AFaceOfThreeTetsIsOversharedAndFailsTheFacts)
{
    TetMesh box = box_of_cubes(1, 1, 1);
    // A copy of tet 0 shares all four of its faces with it and its neighbours.
    box.tets.push_back(box.tets[0]);
    const TetFaceAdjacency adjacency = tet_face_adjacency(box);
    expect_matches_brute_force(box, adjacency);
    EXPECT_GT(adjacency.overshared_faces, 0);
    EXPECT_GT(tet_mesh_facts(box).overshared_faces, 0);
}

TEST(TetFaceAdjacency, APointOutOfRangeIsRefused)
{
    TetMesh box = box_of_cubes(1, 1, 1);
    box.tets[3][2] = static_cast<int32_t>(box.points.size());
    EXPECT_THROW(tet_face_adjacency(box), std::out_of_range);
    box.tets[3][2] = -1;
    EXPECT_THROW(tet_mesh_facts(box), std::out_of_range);
}

TEST(TetMeshFacts, AGivenAdjacencyGivesTheSameFactsAndMustFitTheMesh)
{
    TetMesh box = box_of_cubes(2, 2, 2);
    const TetFaceAdjacency adjacency = tet_face_adjacency(box);
    const TetMeshFacts own = tet_mesh_facts(box), given = tet_mesh_facts(box, adjacency);
    EXPECT_EQ(own.boundary_faces, given.boundary_faces);
    EXPECT_EQ(own.volume, given.volume);
    EXPECT_TRUE(given.boundary_matches);
    box.tets.pop_back();
    EXPECT_THROW(tet_mesh_facts(box, adjacency), std::invalid_argument);
}

TEST(TetMeshFacts, BoxOfCubesHoldsAndAMissingTetBreaksTheBoundary)
{
    TetMesh box = box_of_cubes(2, 3, 4);
    TetMeshFacts facts = tet_mesh_facts(box);
    EXPECT_EQ(facts.nonpositive_tets, 0);
    EXPECT_EQ(facts.overshared_faces, 0);
    EXPECT_TRUE(facts.boundary_matches);
    EXPECT_NEAR(facts.volume, 24.0, 1e-12);
    box.tets.erase(box.tets.begin() + 20);
    facts = tet_mesh_facts(box);
    EXPECT_FALSE(facts.boundary_matches);
    EXPECT_NEAR(facts.volume, 24.0 - 1.0 / 6.0, 1e-12);
}

} // namespace
} // namespace scalemesh
