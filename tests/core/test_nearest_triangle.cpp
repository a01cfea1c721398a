// Nearest triangles against distances known by construction and against a
// search of every triangle.

#include "core/nearest_triangle.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace scalemesh {
namespace {

TEST(PointTriangleDistance, IsTheDistanceToTheFaceAnEdgeOrAVertex)
{
    const Vec3 a{0, 0, 0}, b{2, 0, 0}, c{0, 2, 0};
    EXPECT_DOUBLE_EQ(point_triangle_distance2({0.5, 0.5, 3}, a, b, c), 9);     // above the face
    EXPECT_DOUBLE_EQ(point_triangle_distance2({-1, -1, 0}, a, b, c), 2);       // beyond vertex a
    EXPECT_DOUBLE_EQ(point_triangle_distance2({1, -2, 0}, a, b, c), 4);        // beside edge ab
    EXPECT_DOUBLE_EQ(point_triangle_distance2({2, 2, 0}, a, b, c), 2);         // beside edge bc
    EXPECT_DOUBLE_EQ(point_triangle_distance2({0.5, 0.5, 0}, a, b, c), 0);     // on the face
}

// A closed surface of 2 * n * n quads' triangles on the faces of a cube.
SurfaceMesh cube_surface(int n)
{
    SurfaceMesh m;
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side)
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    const auto point = [&](int u, int v) {
                        Vec3 p;
                        p[axis] = side;
                        p[(axis + 1) % 3] = static_cast<double>(u) / n;
                        p[(axis + 2) % 3] = static_cast<double>(v) / n;
                        return p;
                    };
                    const auto base = static_cast<int32_t>(m.points.size());
                    m.points.push_back(point(i, j));
                    m.points.push_back(point(i + 1, j));
                    m.points.push_back(point(i + 1, j + 1));
                    m.points.push_back(point(i, j + 1));
                    m.triangles.push_back({base, base + 1, base + 2});
                    m.triangles.push_back({base, base + 2, base + 3});
                }
    return m;
}

TEST(NearestTriangles, FindsTheTriangleUnderAPointJustOffIt)
{
    const SurfaceMesh cube = cube_surface(4);
    std::vector<Vec3> points;
    for (const Triangle& t : cube.triangles) {
        const Vec3 centroid = (cube.points[t[0]] + cube.points[t[1]] + cube.points[t[2]]) * (1.0 / 3);
        // Pushed out of the cube, 1e-3 off its face.
        const Vec3 out = centroid + (centroid - Vec3{0.5, 0.5, 0.5}) * 2e-3;
        points.push_back(out);
    }
    const std::vector<int32_t> nearest = nearest_triangles(cube, points);
    ASSERT_EQ(nearest.size(), points.size());
    for (size_t t = 0; t < nearest.size(); ++t) EXPECT_EQ(nearest[t], static_cast<int32_t>(t));
}

TEST(NearestTriangles, IsAsNearAsTheNearestOfAllTriangles)
{
    const SurfaceMesh cube = cube_surface(5);
    std::mt19937 random(7);
    std::uniform_real_distribution<double> coordinate(-1.5, 2.5);
    std::vector<Vec3> points(500);
    for (Vec3& p : points) p = {coordinate(random), coordinate(random), coordinate(random)};
    const std::vector<int32_t> nearest = nearest_triangles(cube, points);
    for (size_t p = 0; p < points.size(); ++p) {
        const auto distance2 = [&](int32_t t) {
            const Triangle& tri = cube.triangles[t];
            return point_triangle_distance2(points[p], cube.points[tri[0]], cube.points[tri[1]], cube.points[tri[2]]);
        };
        double best = std::numeric_limits<double>::infinity();
        for (size_t t = 0; t < cube.triangles.size(); ++t) best = std::min(best, distance2(static_cast<int32_t>(t)));
        EXPECT_EQ(distance2(nearest[p]), best) << "point " << p;
    }
}

} // namespace
} // namespace scalemesh
