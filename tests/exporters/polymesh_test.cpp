// The polyMesh writer on hand-made meshes: OpenFOAM's ordering rules checked
// directly, then by checkMesh itself; invalid meshes refused with nothing written.

#include "core/errors.h"
#include "core/tet_mesh.h"
#include "exporters/polymesh_writer.h"
#include "openfoam_support.h"
#include "polymesh_files.h"
#include "tet_meshes.h"

#include "support/temp_dir.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>

namespace scalemesh {
namespace {

TEST(PolyMesh, CubeInSixTetsFollowsOpenFoamsOrderingRules)
{
    const TempDir dir;
    const TetMesh mesh = cube_in_six_tets();
    ASSERT_EQ(mesh.boundary_faces.size(), 12u);
    const PolyMeshCounts counts = write_polymesh(mesh, dir.path);
    EXPECT_EQ(counts.cells, 6);
    EXPECT_EQ(counts.internal_faces, 6);
    EXPECT_EQ(counts.faces, 18);
    ASSERT_EQ(counts.patch_faces.size(), 1u);
    EXPECT_EQ(counts.patch_faces[0], 12);

    const auto poly = dir.path / "constant" / "polyMesh";
    const auto owner = read_label_list(poly / "owner");
    const auto neighbour = read_label_list(poly / "neighbour");
    const auto faces = read_face_list(poly / "faces");
    ASSERT_EQ(owner.size(), 18u);
    ASSERT_EQ(neighbour.size(), 6u);
    ASSERT_EQ(faces.size(), 18u);
    auto centroid = [&](int64_t cell) {
        Vec3 c;
        for (int32_t v : mesh.tets[cell]) c += mesh.points[v];
        return c / 4.0;
    };
    for (size_t f = 0; f < faces.size(); ++f) {
        const Vec3 a = mesh.points[faces[f][0]], b = mesh.points[faces[f][1]], c = mesh.points[faces[f][2]];
        const Vec3 normal = cross(b - a, c - a);
        const Vec3 centre = (a + b + c) / 3.0;
        // The normal points away from the owner's centroid ...
        EXPECT_GT(dot(normal, centre - centroid(owner[f])), 0) << "face " << f;
        if (f < neighbour.size()) {
            // ... towards the neighbour's, owner < neighbour, upper-triangular order.
            EXPECT_LT(owner[f], neighbour[f]);
            EXPECT_GT(dot(normal, centroid(neighbour[f]) - centre), 0) << "face " << f;
            if (f > 0) {
                EXPECT_TRUE(owner[f - 1] < owner[f] || (owner[f - 1] == owner[f] && neighbour[f - 1] < neighbour[f]));
            }
        }
    }
}

TEST(PolyMesh, CheckMeshAcceptsTheCubeInAsciiAndBinary)
{
    if (!openfoam_available()) GTEST_SKIP() << "OpenFOAM (Debian package openfoam) is not installed";
    for (bool binary : {false, true}) {
        const TempDir dir;
        write_polymesh(cube_in_six_tets(), dir.path, {.binary = binary, .patch_types = {}});
        const CheckMeshFigures check = check_mesh(dir.path);
        EXPECT_TRUE(check.ok) << (binary ? "binary" : "ascii") << "\n" << check.log;
        EXPECT_EQ(check.cells, 6);
        EXPECT_NEAR(check.volume, 1.0, 1e-12);
    }
}

TEST(PolyMesh, RefusesInvalidMeshesAndWritesNothing)
{
    const TempDir dir;
    TetMesh inverted = cube_in_six_tets();
    std::swap(inverted.tets[2][0], inverted.tets[2][1]); // one tet turned inside out
    EXPECT_THROW(write_polymesh(inverted, dir.path), StageError);

    TetMesh open = cube_in_six_tets();
    open.boundary_faces.pop_back(); // a boundary face nobody claims
    EXPECT_THROW(write_polymesh(open, dir.path), StageError);

    TetMesh flipped = cube_in_six_tets();
    std::swap(flipped.boundary_faces[0][1], flipped.boundary_faces[0][2]); // a boundary face facing in
    EXPECT_THROW(write_polymesh(flipped, dir.path), StageError);

    TetMesh doubled = cube_in_six_tets();
    doubled.tets.push_back(doubled.tets[0]); // a face shared by three cells
    EXPECT_THROW(write_polymesh(doubled, dir.path), StageError);

    EXPECT_FALSE(std::filesystem::exists(dir.path / "constant" / "polyMesh" / "points"));
}

TEST(PolyMesh, PatchesAreGroupedInTheOrderOfBoundary)
{
    const TempDir dir;
    TetMesh mesh = cube_in_six_tets();
    mesh.patch_names = {"wall", "inlet"};
    mesh.boundary_patch.assign(mesh.boundary_faces.size(), 0);
    for (size_t f = 0; f < mesh.boundary_faces.size(); ++f) {
        bool bottom = true;
        for (int32_t v : mesh.boundary_faces[f]) bottom = bottom && mesh.points[v].z == 0.0;
        if (bottom) mesh.boundary_patch[f] = 1;
    }
    const PolyMeshCounts counts = write_polymesh(mesh, dir.path, {.patch_types = {"wall", "patch"}});
    ASSERT_EQ(counts.patch_faces.size(), 2u);
    EXPECT_EQ(counts.patch_faces[0], 10);
    EXPECT_EQ(counts.patch_faces[1], 2);
    std::ifstream in(dir.path / "constant" / "polyMesh" / "boundary");
    std::stringstream text;
    text << in.rdbuf();
    const std::string b = text.str();
    EXPECT_LT(b.find("wall"), b.find("inlet"));
    EXPECT_NE(b.find("startFace       16;"), std::string::npos) << b;
    EXPECT_NE(b.find("type            patch;"), std::string::npos) << b;
    if (openfoam_available()) {
        EXPECT_TRUE(check_mesh(dir.path).ok);
    }
}

} // namespace
} // namespace scalemesh
