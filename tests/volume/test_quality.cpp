// The quality measures of paper section 3 on tets whose values are known in
// closed form.

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

} // namespace
} // namespace scalemesh
