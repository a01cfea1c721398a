// Volume .msh and .vtk: read back through the Gmsh SDK, and the same mesh
// through gmshToFoam and through our polyMesh writer measured alike by checkMesh.

#include "core/errors.h"
#include "exporters/polymesh_writer.h"
#include "exporters/volume_writers.h"
#include "gmsh_io/gmsh_session.h"
#include "openfoam_support.h"
#include "tet_meshes.h"

#include <gmsh.h>
#include "support/temp_dir.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>

namespace scalemesh {
namespace {

TetMesh sample()
{
    TetMesh m = box_of_cubes(2, 2, 3);
    std::vector<double> height, index;
    for (const Vec3& p : m.points) height.push_back(p.z);
    for (size_t t = 0; t < m.tets.size(); ++t) index.push_back(double(t));
    m.point_fields.push_back({"height", height});
    m.tet_fields.push_back({"index", index});
    return m;
}

TEST(VolumeMsh, RoundTripsNodesTetsGroupsAndViews)
{
    const TetMesh mesh = sample();
    for (double version : {4.1, 2.2}) {
        const TempDir dir;
        const auto file = dir.path / "mesh.msh";
        write_volume_msh(mesh, file, {.msh_version = version});
        GmshSession session;
        ScratchModel model("readback");
        gmsh::merge(file.string());
        std::vector<int> types;
        std::vector<std::vector<size_t>> tags, nodes;
        gmsh::model::mesh::getElements(types, tags, nodes, 3);
        ASSERT_EQ(types.size(), 1u);
        EXPECT_EQ(types[0], 4);
        EXPECT_EQ(tags[0].size(), mesh.tets.size()) << version;
        gmsh::model::mesh::getElements(types, tags, nodes, 2);
        size_t triangles = 0;
        for (const auto& t : tags) triangles += t.size();
        EXPECT_EQ(triangles, mesh.boundary_faces.size());
        std::vector<size_t> node_tags;
        std::vector<double> coords, params;
        gmsh::model::mesh::getNodes(node_tags, coords, params);
        EXPECT_EQ(node_tags.size(), mesh.points.size());
        gmsh::vectorpair groups;
        gmsh::model::getPhysicalGroups(groups);
        std::set<std::string> names;
        for (const auto& [dim, tag] : groups) {
            std::string name;
            gmsh::model::getPhysicalName(dim, tag, name);
            names.insert(std::to_string(dim) + ":" + name);
        }
        EXPECT_EQ(names, (std::set<std::string>{"3:fluid", "2:wall", "2:inlet", "2:outlet"}));
        std::vector<int> views;
        gmsh::view::getTags(views);
        model.adopt_views(views);
        EXPECT_EQ(views.size(), 2u);
    }
    // The views are in the file itself.
    const TempDir dir;
    write_volume_msh(mesh, dir.path / "mesh.msh");
    const std::string text = read_text(dir.path / "mesh.msh");
    EXPECT_NE(text.find("$NodeData"), std::string::npos);
    EXPECT_NE(text.find("$ElementData"), std::string::npos);
    EXPECT_NE(text.find("\"height\""), std::string::npos);
}

TEST(VolumeVtk, IsAWellFormedUnstructuredGrid)
{
    const TempDir dir;
    const TetMesh mesh = sample();
    write_volume_vtk(mesh, dir.path / "mesh.vtk");
    const std::string text = read_text(dir.path / "mesh.vtk");
    EXPECT_NE(text.find("POINTS " + std::to_string(mesh.points.size()) + " double"), std::string::npos);
    EXPECT_NE(text.find("CELLS " + std::to_string(mesh.tets.size()) + " " + std::to_string(5 * mesh.tets.size())),
              std::string::npos);
    EXPECT_NE(text.find("SCALARS height double"), std::string::npos);
    EXPECT_NE(text.find("CELL_DATA " + std::to_string(mesh.tets.size())), std::string::npos);
}

TEST(VolumeWriters, RefuseInvalidMeshesAndWriteNothing)
{
    const TempDir dir;
    TetMesh inverted = sample();
    std::swap(inverted.tets[0][0], inverted.tets[0][1]);
    EXPECT_THROW(write_volume_msh(inverted, dir.path / "a.msh"), StageError);
    EXPECT_THROW(write_volume_vtk(inverted, dir.path / "a.vtk"), StageError);
    TetMesh long_field = sample();
    long_field.point_fields[0].values.push_back(0.0);
    EXPECT_THROW(write_volume_msh(long_field, dir.path / "b.msh"), InputError);
    TetMesh short_field = sample();
    short_field.tet_fields[0].second.pop_back();
    EXPECT_THROW(write_volume_msh(short_field, dir.path / "b.msh"), InputError);
    EXPECT_THROW(write_volume_msh(sample(), dir.path / "c.msh", {.msh_version = 3.0}), InputError);
    EXPECT_TRUE(std::filesystem::is_empty(dir.path));
}

TEST(VolumeMsh, GmshToFoamAgreesWithOurPolyMeshWriter)
{
    if (!openfoam_available()) GTEST_SKIP() << "OpenFOAM (Debian package openfoam) is not installed";
    const TetMesh mesh = sample();
    const TempDir via_gmsh, ours;
    write_volume_msh(mesh, via_gmsh.path / "mesh.msh", {.msh_version = 2.2});
    write_openfoam_case(via_gmsh.path, {"wall"}, {PatchRole::Wall}); // gmshToFoam needs system/
    const std::string log = run_openfoam("gmshToFoam mesh.msh -case .", via_gmsh.path, "gmshToFoam.log");
    ASSERT_EQ(log.find("FATAL"), std::string::npos) << log;
    write_polymesh(mesh, ours.path);
    const CheckMeshFigures a = check_mesh(via_gmsh.path), b = check_mesh(ours.path);
    EXPECT_TRUE(a.ok) << a.log;
    EXPECT_TRUE(b.ok) << b.log;
    EXPECT_EQ(a.cells, static_cast<long>(mesh.tets.size()));
    EXPECT_EQ(b.cells, a.cells);
    EXPECT_NEAR(b.volume, 12.0, 1e-9);
    EXPECT_NEAR(a.volume, b.volume, 1e-9 * b.volume);
}

} // namespace
} // namespace scalemesh
