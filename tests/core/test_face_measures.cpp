// The face and cell measures OpenFOAM's checkMesh judges, on cells whose
// answer is known by construction.

#include "core/face_measures.h"

#include <gtest/gtest.h>

#include <cmath>

namespace scalemesh {
namespace {

// A cube's six faces give 1 (checkMesh's normalisation), whatever its size
// and the faces' orientation; five of them (a cube with one face on the
// boundary) give less, and faces whose normals lie in one plane give 0.
TEST(CellDeterminant, IsOneForACubeAndZeroWithoutADirection)
{
    for (const double side : {1e-3, 1.0, 40.0}) {
        CellDeterminant cube;
        for (int axis = 0; axis < 3; ++axis)
            for (const double sign : {1.0, -1.0}) {
                Vec3 area{0, 0, 0};
                area[axis] = sign * side * side;
                cube.add(area);
            }
        EXPECT_NEAR(cube.determinant(), 1.0, 1e-12) << "side " << side;
    }
    // Five faces of the unit cube: the sum of outer products is
    // diag(2, 2, 1), over a mean area of 1, over 8.
    CellDeterminant five;
    for (const Vec3& area : {Vec3{1, 0, 0}, Vec3{-1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, -1, 0}, Vec3{0, 0, 1}}) five.add(area);
    EXPECT_NEAR(five.determinant(), 4.0 / 8, 1e-12);
    CellDeterminant flat;
    for (const Vec3& area : {Vec3{1, 0, 0}, Vec3{0, 2, 0}, Vec3{1, 1, 0}}) flat.add(area);
    EXPECT_NEAR(flat.determinant(), 0.0, 1e-12);
    EXPECT_EQ(CellDeterminant{}.determinant(), 0.0) << "no internal face";
}

// A tall tet on a small, obtuse triangle of the boundary, the shape
// checkMesh fails at a cap: its three internal faces' normals all but lie
// in one plane. The same tet with its base equilateral passes.
TEST(CellDeterminant, ATallTetOnAnObtuseBoundaryTriangleIsSmall)
{
    const auto internal_faces = [](const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& apex) {
        CellDeterminant d;
        d.add(cross(b - a, apex - a));
        d.add(cross(c - b, apex - b));
        d.add(cross(a - c, apex - c));
        return d.determinant();
    };
    const Vec3 apex{0.5, 0.1, 3.0};
    EXPECT_LT(internal_faces({0, 0, 0}, {1, 0, 0}, {0.5, 0.1, 0}, apex), 0.001);
    EXPECT_GT(internal_faces({0, 0, 0}, {1, 0, 0}, {0.5, std::sqrt(0.75), 0}, {0.5, 0.29, 0.8}), 0.01);
}

} // namespace
} // namespace scalemesh
