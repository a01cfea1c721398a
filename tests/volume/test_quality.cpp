// The quality measures of paper section 3 on tets whose values are known in
// closed form, and the sliver removal's moves of layer points.

#include "volume/improve.h"
#include "volume/quality.h"

#include <gtest/gtest.h>

#include <cmath>

namespace scalemesh {
namespace {

const Vec3 kRegular[4] = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};

double degrees(double radians) { return radians * 180.0 / M_PI; }

TEST(TetQuality, RegularTetHasAspectRatioOneAndDihedralAngleArccosOneThird)
{
    // Alternate corners of a cube; two swapped if needed for a positive volume.
    Vec3 a = kRegular[0], b = kRegular[1], c = kRegular[2], d = kRegular[3];
    if (tet_volume6(a, b, c, d) < 0) std::swap(c, d);
    EXPECT_NEAR(tet_aspect_ratio(a, b, c, d), 1.0, 1e-12);
    EXPECT_NEAR(tet_min_dihedral_deg(a, b, c, d), degrees(std::acos(1.0 / 3.0)), 1e-9); // 70.53
}

TEST(TetQuality, CornerTetHasRightAnglesAndArccosOfOneOverRootThree)
{
    // At the three edges through the corner the faces meet at 90 degrees; at
    // the three edges of the slanted face, at arccos(1 / sqrt 3) = 54.74.
    const Vec3 a{0, 0, 0}, b{1, 0, 0}, c{0, 1, 0}, d{0, 0, 1};
    ASSERT_GT(tet_volume6(a, b, c, d), 0);
    EXPECT_NEAR(tet_min_dihedral_deg(a, b, c, d), degrees(std::acos(1.0 / std::sqrt(3.0))), 1e-9);
    // r_in = 3 V / area = 3 (1/6) / (3/2 + sqrt(3)/2); l_max = sqrt 2.
    const double r_in = 0.5 / (1.5 + std::sqrt(3.0) / 2.0);
    EXPECT_NEAR(tet_aspect_ratio(a, b, c, d), 2.0 * std::sqrt(6.0) * r_in / std::sqrt(2.0), 1e-12);
}

TEST(TetQuality, FlatAndInvertedTetsScoreZeroDihedralAngle)
{
    const Vec3 a{0, 0, 0}, b{1, 0, 0}, c{0, 1, 0}, d{0, 0, 1};
    EXPECT_EQ(tet_min_dihedral_deg(a, b, d, c), 0.0);           // inverted
    EXPECT_LT(tet_aspect_ratio(a, b, d, c), 0.0);               // signed
    EXPECT_EQ(tet_min_dihedral_deg(a, b, c, {1, 1, 0}), 0.0);   // flat
    EXPECT_EQ(tet_aspect_ratio(a, b, c, {1, 1, 0}), 0.0);
    EXPECT_EQ(tet_min_dihedral_deg(a, a, c, d), 0.0);           // two corners in one place
}

TEST(TetQuality, ASliverHasASmallDihedralAngle)
{
    // Four points near a square, lifted alternately by h: a sliver whose
    // smallest dihedral angle shrinks with h.
    const double h = 1e-3;
    Vec3 a{0, 0, 0}, b{1, 0, h}, c{1, 1, 0}, d{0, 1, h};
    if (tet_volume6(a, b, c, d) < 0) std::swap(c, d);
    const double angle = tet_min_dihedral_deg(a, b, c, d);
    EXPECT_GT(angle, 0.0);
    EXPECT_LT(angle, 1.0);
    EXPECT_LT(tet_aspect_ratio(a, b, c, d), 0.01);
}

// The cube [0, 1]^3 as the cone from one interior point over its twelve
// boundary triangles, the point far off the centre so that its star is poor.
TetMesh cube_star(const Vec3& inside)
{
    TetMesh mesh;
    for (int i = 0; i < 8; ++i) mesh.points.push_back({double(i & 1), double((i >> 1) & 1), double((i >> 2) & 1)});
    mesh.points.push_back(inside);
    const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& f : faces)
        for (const Triangle& t : {Triangle{f[0], f[1], f[2]}, Triangle{f[0], f[2], f[3]}}) {
            Tet tet{t[0], t[1], t[2], 8};
            const auto& p = mesh.points;
            if (tet_volume6(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]]) < 0) std::swap(tet[0], tet[1]);
            mesh.tets.push_back(tet);
            mesh.boundary_faces.push_back(t);
        }
    return mesh;
}

// A layer point stays within its slack of its place (here 0.03, in every
// direction: on its layer and on its node's normal); a free point moves
// farther. Both moves raise the star's worst aspect ratio.
TEST(SliverRemoval, ALayerPointStaysWithinItsSlackOfItsLayer)
{
    const Vec3 start{0.2, 0.3, 0.15};
    TetMesh free_mesh = cube_star(start);
    const double before = quality_report(free_mesh).min_aspect_ratio;
    const SliverCounts free_counts = remove_slivers(free_mesh, 8, 0.9, 5);
    ASSERT_GT(free_counts.moves, 0);
    EXPECT_GT(std::abs(free_mesh.points[8].z - start.z), 0.05);
    EXPECT_GT(quality_report(free_mesh).min_aspect_ratio, before);

    TetMesh layer_mesh = cube_star(start);
    std::vector<LayerBound> layers(9);
    layers[8] = {start, {0, 0, 1}, 0.03};
    const SliverCounts layer_counts = remove_slivers(layer_mesh, 8, 0.9, 5, layers);
    ASSERT_GT(layer_counts.moves, 0);
    EXPECT_LE(distance(layer_mesh.points[8], start), 0.03 + 1e-12);
    EXPECT_GT(distance(layer_mesh.points[8], start), 0.02);
    EXPECT_GT(distance(free_mesh.points[8], start), 0.05);
    EXPECT_GT(quality_report(layer_mesh).min_aspect_ratio, before);
    for (const Tet& t : layer_mesh.tets) {
        const auto& p = layer_mesh.points;
        EXPECT_GT(tet_volume6(p[t[0]], p[t[1]], p[t[2]], p[t[3]]), 0);
    }
}

} // namespace
} // namespace scalemesh
