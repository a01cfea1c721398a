#include "sizing/normals.h"

#include "core/errors.h"
#include "sizing/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace scalemesh {
namespace {

TEST(Normals, SphereNormalsAreOutwardRadialUnitVectors)
{
    const Vec3 centre{1, -2, 3};
    const SurfaceMesh mesh = test::icosphere(5.0, 4, centre);
    const std::vector<Vec3> normals = synthetic_normals(mesh);
    ASSERT_EQ(normals.size(), mesh.points.size());
    double min_cos = 1;
    for (size_t i = 0; i < normals.size(); ++i) {
        EXPECT_NEAR(norm(normals[i]), 1.0, 1e-14);
        min_cos = std::min(min_cos, dot(normals[i], normalized(mesh.points[i] - centre)));
    }
    RecordProperty("min_cos_to_radial", test::figure(min_cos));
    EXPECT_GT(min_cos, 0.9999);
}

TEST(Normals, CylinderRimNormalBisectsWallAndCap)
{
    const int around = 32;
    const SurfaceMesh mesh = test::capped_cylinder(2.0, 10.0, around, 10);
    const std::vector<Vec3> normals = synthetic_normals(mesh);
    // Bottom rim vertex at angle 0: between the wall normal (1,0,0) and the
    // cap normal (0,0,-1), so both of its components are clearly nonzero.
    EXPECT_GT(normals[0].x, 0.3);
    EXPECT_LT(normals[0].z, -0.3);
    // Top cap centre: straight up.
    EXPECT_NEAR(normals[mesh.points.size() - 1].z, 1.0, 1e-14);
}

TEST(Normals, InwardCheckPassesOnSmoothShapes)
{
    for (const SurfaceMesh& mesh :
         {test::icosphere(1.0, 3), test::uv_torus(10.0, 3.0, 64, 24), test::capped_cylinder(2.0, 10.0, 32, 10)}) {
        const std::vector<char> ok = inward_check(mesh, synthetic_normals(mesh));
        EXPECT_EQ(std::count(ok.begin(), ok.end(), 1), static_cast<long>(mesh.points.size()));
    }
}

TEST(Normals, InwardCheckFailsAtFoldedVertex)
{
    int32_t vertex = -1;
    const SurfaceMesh mesh = test::folded_cap_cylinder(vertex);
    const std::vector<char> ok = inward_check(mesh, synthetic_normals(mesh));
    EXPECT_EQ(ok[vertex], 0);
    // Vertices far from the fold still pass.
    int64_t far_ok = 0, far = 0;
    for (size_t i = 0; i < mesh.points.size(); ++i)
        if (mesh.points[i].z < 8.0) {
            ++far;
            far_ok += ok[i];
        }
    EXPECT_EQ(far_ok, far);
}

// The sizing stage takes the normals and the inward flags from one pass over
// the fans; both must be what the separate functions give.
TEST(Normals, OnePassGivesTheNormalsAndTheInwardCheck)
{
    int32_t vertex = -1;
    for (const SurfaceMesh& mesh : {test::folded_cap_cylinder(vertex), test::uv_torus(10.0, 3.0, 64, 24)}) {
        std::vector<char> ok;
        const std::vector<Vec3> normals = synthetic_normals(mesh, vertex_triangles(mesh), &ok);
        const std::vector<Vec3> alone = synthetic_normals(mesh);
        ASSERT_EQ(normals.size(), alone.size());
        for (size_t i = 0; i < normals.size(); ++i) EXPECT_EQ(normals[i], alone[i]) << i;
        EXPECT_EQ(ok, inward_check(mesh, alone));
    }
    std::vector<char> ok;
    const SurfaceMesh folded = test::folded_cap_cylinder(vertex);
    (void)synthetic_normals(folded, vertex_triangles(folded), &ok);
    EXPECT_EQ(ok[vertex], 0);
}

TEST(Normals, InwardCheckRejectsMismatchedNormals)
{
    const SurfaceMesh mesh = test::icosphere(1.0, 1);
    EXPECT_THROW(inward_check(mesh, std::vector<Vec3>(3)), InputError);
}

} // namespace
} // namespace scalemesh
