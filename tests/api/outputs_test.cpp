// The library's outputs (include/scalemesh/mesh.h): write_openfoam,
// write_msh and report_json on meshes made through the public header, and
// openings given as options on an open tube. checkMesh, where OpenFOAM is
// installed, must pass the cases written.

#include "scalemesh/scalemesh.h"

#include "api/surfaces.h"
#include "support/temp_dir.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace {

using scalemesh::MeshOpening;
using scalemesh::MeshResult;
using scalemesh::SurfaceInput;
namespace fs = std::filesystem;

std::string read_text(const fs::path& p)
{
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

// checkMesh's verdict on the case in `dir`: "ok", "failed" with its log, or
// "" when OpenFOAM is not installed.
std::string check_mesh(const fs::path& dir)
{
    if (std::system("command -v checkMesh >/dev/null 2>&1") != 0) return "";
    const std::string command = "cd '" + dir.string() + "' && WM_PROJECT_DIR=${WM_PROJECT_DIR:-/usr/share/openfoam} "
                                "checkMesh -case . > log.checkMesh 2>&1";
    (void)std::system(command.c_str());
    const std::string log = read_text(dir / "log.checkMesh");
    return log.find("Mesh OK.") != std::string::npos ? "ok" : "failed:\n" + log;
}

scalemesh::MeshOptions fast_options()
{
    scalemesh::MeshOptions o;
    o.threads = 2;
    return o;
}

// The sphere of tests/api meshed once, for the tests that only write it.
const MeshResult& sphere()
{
    static const MeshResult mesh = scalemesh::mesh_surface(scalemesh::test::icosphere(5.0, 3), fast_options());
    return mesh;
}

TEST(ApiOutputs, WritesTheOpenFoamCaseOfAClosedSurface)
{
    const scalemesh::TempDir tmp;
    const fs::path dir = tmp.path / "made" / "case"; // neither exists: write_openfoam makes them
    const scalemesh::OpenFoamCase written = scalemesh::write_openfoam(sphere(), dir);
    for (const char* file : {"constant/polyMesh/points", "constant/polyMesh/faces", "constant/polyMesh/owner",
                             "constant/polyMesh/neighbour", "constant/polyMesh/boundary", "constant/transportProperties",
                             "constant/turbulenceProperties", "system/controlDict", "system/fvSchemes",
                             "system/fvSolution", "Allrun", "report.json"})
        EXPECT_TRUE(fs::is_regular_file(dir / file)) << file;
    EXPECT_TRUE((fs::status(dir / "Allrun").permissions() & fs::perms::owner_exec) != fs::perms::none);
    // A closed surface poses no flow: no 0/ fields, one wall patch.
    EXPECT_FALSE(written.flow_fields);
    EXPECT_FALSE(fs::exists(dir / "0"));
    EXPECT_FALSE(fs::exists(dir / "quality.png")); // the OpenFOAM case only
    EXPECT_EQ(written.patch_names, std::vector<std::string>{"wall"});
    ASSERT_EQ(written.patch_faces.size(), 1u);
    EXPECT_EQ(static_cast<size_t>(written.patch_faces[0]), sphere().boundary_count());
    // The default Delaunay layers keep some layer prisms whole: fewer cells
    // than tets, and quads between the prisms.
    EXPECT_GT(written.layer_prisms, 0);
    EXPECT_EQ(static_cast<size_t>(written.cells),
              sphere().tet_count() - 2 * static_cast<size_t>(written.layer_prisms));
    const std::string boundary = read_text(dir / "constant/polyMesh/boundary");
    EXPECT_NE(boundary.find("wall"), std::string::npos) << boundary;

    // report.json: the run's report with the OpenFOAM section and the files.
    const nlohmann::json report = nlohmann::json::parse(read_text(dir / "report.json"));
    EXPECT_EQ(report["openfoam"]["cells"].get<int64_t>(), written.cells);
    EXPECT_EQ(report["volume"]["tets"].get<size_t>(), sphere().tet_count());
    const std::vector<std::string> files = report["files"].get<std::vector<std::string>>();
    EXPECT_NE(std::find(files.begin(), files.end(), "constant/polyMesh"), files.end());
    EXPECT_EQ(std::find(files.begin(), files.end(), "quality.png"), files.end());

    const std::string verdict = check_mesh(dir);
    if (verdict.empty()) GTEST_SKIP() << "checkMesh is not installed";
    EXPECT_EQ(verdict, "ok");
}

// One surface file meshed by mesh_image and by `scalemesh run`: the same
// polyMesh and case files, byte for byte, since both go through the same
// writers. (A file's points reach the stages in the reader's order, so the
// file, not the sphere in memory, is meshed both ways.)
TEST(ApiOutputs, TheOpenFoamCaseIsTheCommandLines)
{
    const char* binary = std::getenv("SCALEMESH_BINARY");
    ASSERT_NE(binary, nullptr) << "run the tests through ctest";
    const scalemesh::TempDir tmp;
    const SurfaceInput surface = scalemesh::test::icosphere(5.0, 3);
    {
        std::ofstream ply(tmp.path / "sphere.ply");
        ply << "ply\nformat ascii 1.0\nelement vertex " << surface.points.size() / 3
            << "\nproperty double x\nproperty double y\nproperty double z\nelement face "
            << surface.triangles.size() / 3 << "\nproperty list uchar int vertex_indices\nend_header\n";
        char number[64];
        for (size_t i = 0; i < surface.points.size(); ++i) {
            std::snprintf(number, sizeof number, "%.17g", surface.points[i]);
            ply << number << (i % 3 == 2 ? "\n" : " ");
        }
        for (size_t f = 0; f < surface.triangles.size(); f += 3)
            ply << "3 " << surface.triangles[f] << " " << surface.triangles[f + 1] << " " << surface.triangles[f + 2]
                << "\n";
        std::ofstream(tmp.path / "scalemesh.toml")
            << "[input]\nfile = \"sphere.ply\"\n[output]\nsurface = []\nvolume = []\n[run]\nthreads = 2\n";
    }
    ASSERT_EQ(std::system((std::string(binary) + " run -q '" + tmp.path.string() + "'").c_str()), 0);
    const fs::path library = tmp.path / "library";
    scalemesh::write_openfoam(scalemesh::mesh_image(tmp.path / "sphere.ply", fast_options()), library);
    for (const char* file : {"constant/polyMesh/points", "constant/polyMesh/faces", "constant/polyMesh/owner",
                             "constant/polyMesh/neighbour", "constant/polyMesh/boundary", "constant/transportProperties",
                             "system/controlDict", "system/fvSchemes", "system/fvSolution", "Allrun"}) {
        const std::string ours = read_text(library / file);
        EXPECT_FALSE(ours.empty()) << file;
        EXPECT_TRUE(ours == read_text(tmp.path / file)) << file << " differs from scalemesh run's";
    }
}

// mesh_surface's labels are the patches the writers write too (as walls).
TEST(ApiOutputs, LabelledPatchesAreWrittenAsTheArraysHaveThem)
{
    SurfaceInput surface = scalemesh::test::icosphere(5.0, 3);
    for (size_t f = 0; f < surface.triangles.size(); f += 3) {
        double z = 0;
        for (int k = 0; k < 3; ++k) z += surface.points[3 * surface.triangles[f + k] + 2] / 3;
        surface.labels.push_back(z > 0 ? 1 : 0);
    }
    surface.label_names = {"lower", "upper"};
    const MeshResult m = scalemesh::mesh_surface(surface, fast_options());
    const scalemesh::TempDir tmp;
    const scalemesh::OpenFoamCase written = scalemesh::write_openfoam(m, tmp.path);
    ASSERT_EQ(written.patch_names, (std::vector<std::string>{"lower", "upper"}));
    ASSERT_EQ(written.patch_faces.size(), 2u);
    EXPECT_EQ(static_cast<size_t>(written.patch_faces[1]),
              static_cast<size_t>(std::count(m.boundary_patch.begin(), m.boundary_patch.end(), 1)));
    EXPECT_FALSE(written.flow_fields);
    scalemesh::write_msh(m, tmp.path / "mesh.msh");
    EXPECT_NE(read_text(tmp.path / "mesh.msh").find("\"upper\""), std::string::npos);
    const std::string verdict = check_mesh(tmp.path);
    if (!verdict.empty()) {
        EXPECT_EQ(verdict, "ok");
    }
}

TEST(ApiOutputs, ReportIsTheRunsReportJson)
{
    const nlohmann::json report = nlohmann::json::parse(scalemesh::report_json(sphere()));
    EXPECT_EQ(report["volume"]["tets"].get<size_t>(), sphere().tet_count());
    EXPECT_EQ(report["volume"]["points"].get<size_t>(), sphere().point_count());
    EXPECT_EQ(report["parameters"]["M"].get<double>(), 7.0);
    EXPECT_EQ(report["stages"].back()["stage"], "volume");
    EXPECT_TRUE(report["files"].empty());
    EXPECT_FALSE(report.contains("openfoam"));
    EXPECT_TRUE(report["warnings"].is_array());
}

TEST(ApiOutputs, WritesTheMshWithPhysicalGroupsAndViews)
{
    const scalemesh::TempDir tmp;
    scalemesh::write_msh(sphere(), tmp.path / "mesh.msh");
    const std::string msh = read_text(tmp.path / "mesh.msh");
    EXPECT_EQ(msh.rfind("$MeshFormat\n4.1 0", 0), 0u) << msh.substr(0, 40);
    EXPECT_NE(msh.find("$Comments"), std::string::npos);
    EXPECT_NE(msh.find("\"fluid\""), std::string::npos);
    EXPECT_NE(msh.find("\"wall\""), std::string::npos);
    for (const char* view : {"\"D\"", "\"d\"", "\"layers\"", "\"aspect_ratio\""})
        EXPECT_NE(msh.find(view), std::string::npos) << view;
    scalemesh::write_msh(sphere(), tmp.path / "old.msh", {.version = 2.2});
    EXPECT_EQ(read_text(tmp.path / "old.msh").rfind("$MeshFormat\n2.2 0", 0), 0u);
    EXPECT_THROW(scalemesh::write_msh(sphere(), tmp.path / "mesh.vtk"), scalemesh::InputError);
    EXPECT_THROW(scalemesh::write_msh(sphere(), tmp.path / "x.msh", {.version = 3}), scalemesh::InputError);
    EXPECT_FALSE(fs::exists(tmp.path / "x.msh"));
}

TEST(ApiOutputs, BadOptionsAndForeignResultsWriteNothing)
{
    const scalemesh::TempDir tmp;
    const fs::path dir = tmp.path / "case";
    try {
        scalemesh::write_openfoam(sphere(), dir, {.viscosity = -1});
        ADD_FAILURE() << "a negative viscosity was accepted";
    } catch (const scalemesh::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("viscosity"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(dir));
    const MeshResult foreign; // made by hand: no run behind it
    EXPECT_THROW(scalemesh::write_openfoam(foreign, dir), scalemesh::InputError);
    EXPECT_THROW(scalemesh::write_msh(foreign, tmp.path / "m.msh"), scalemesh::InputError);
    EXPECT_THROW(scalemesh::report_json(foreign), scalemesh::InputError);
    EXPECT_FALSE(fs::exists(dir));
    // A file where the case directory should be.
    std::ofstream(tmp.path / "file") << "x";
    EXPECT_THROW(scalemesh::write_openfoam(sphere(), tmp.path / "file"), scalemesh::IoError);
}

// An open tube with its two ends named as openings (one with a flow
// extension): patches in the options' order, each cap flat at its end, a
// flow case whose 0/ fields checkMesh's case accepts.
TEST(ApiOutputs, OpeningsOfAnOpenTube)
{
    const double radius = 2.0, length = 16.0;
    const SurfaceInput tube = scalemesh::test::open_tube(radius, length, 24);
    scalemesh::MeshOptions options = fast_options();
    MeshOpening in;
    in.name = "in";
    in.type = "inlet";
    in.near = {{0, 0, -length / 2}};
    MeshOpening out;
    out.name = "out";
    out.type = "outlet";
    out.near = {{0, 0, length / 2}};
    out.extension = 1; // one cap diameter beyond the outlet
    options.openings = {in, out};
    const MeshResult m = scalemesh::mesh_surface(tube, options);
    ASSERT_EQ(m.patch_names, (std::vector<std::string>{"wall", "in", "out"}));
    double lowest_cap = 1e9, highest_cap = -1e9, highest = -1e9;
    std::vector<size_t> faces(3, 0);
    for (size_t f = 0; f < m.boundary_count(); ++f) {
        const int32_t patch = m.boundary_patch[f];
        ++faces.at(static_cast<size_t>(patch));
        for (int k = 0; k < 3; ++k) {
            const double z = m.points[3 * m.boundary_triangles[3 * f + k] + 2];
            highest = std::max(highest, z);
            if (patch == 1) lowest_cap = std::min(lowest_cap, z), highest_cap = std::max(highest_cap, z);
        }
    }
    EXPECT_GT(faces[1], 0u);
    EXPECT_GT(faces[2], 0u);
    // The inlet's cap is flat, just inside the open end.
    EXPECT_NEAR(lowest_cap, highest_cap, 1e-9);
    EXPECT_LT(lowest_cap, -length / 2 + radius);
    // The extension carries the outlet about a diameter beyond the end.
    EXPECT_GT(highest, length / 2 + radius);

    const scalemesh::TempDir tmp;
    const scalemesh::OpenFoamCase written = scalemesh::write_openfoam(m, tmp.path);
    EXPECT_TRUE(written.flow_fields);
    EXPECT_TRUE(fs::is_regular_file(tmp.path / "0/U"));
    EXPECT_TRUE(fs::is_regular_file(tmp.path / "0/p"));
    EXPECT_EQ(written.patch_names, m.patch_names);
    const std::string U = read_text(tmp.path / "0/U");
    EXPECT_NE(U.find("in"), std::string::npos);
    const nlohmann::json report = nlohmann::json::parse(scalemesh::report_json(m));
    ASSERT_EQ(report["openings"].size(), 2u);
    EXPECT_EQ(report["openings"][0]["name"], "in");
    EXPECT_EQ(report["openings"][0]["type"], "inlet");
    const std::string verdict = check_mesh(tmp.path);
    if (!verdict.empty()) {
        EXPECT_EQ(verdict, "ok");
    }
}

// Without openings an open tube's ends are named as a case file names them.
TEST(ApiOutputs, AnOpenSurfaceNamesItsOwnEnds)
{
    const MeshResult m = scalemesh::mesh_surface(scalemesh::test::open_tube(2.0, 10.0, 20), fast_options());
    EXPECT_EQ(m.patch_names, (std::vector<std::string>{"wall", "inlet", "outlet_1"}));
}

TEST(ApiOutputs, BadOpeningsThrowInputErrorNamingTheKey)
{
    const SurfaceInput tube = scalemesh::test::open_tube(2.0, 10.0, 20);
    const auto message = [&](const scalemesh::MeshOptions& o, const SurfaceInput& s) {
        try {
            scalemesh::mesh_surface(s, o);
        } catch (const scalemesh::InputError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    scalemesh::MeshOptions o = fast_options();
    o.openings = {MeshOpening{.name = "in", .type = "sideways", .near = {{0, 0, -5}}}};
    EXPECT_NE(message(o, tube).find("type"), std::string::npos) << message(o, tube);
    o.openings = {MeshOpening{.name = "wall", .type = "inlet", .near = {{0, 0, -5}}}};
    EXPECT_NE(message(o, tube).find("name"), std::string::npos) << message(o, tube);
    o.openings = {MeshOpening{.name = "in", .type = "inlet", .point = {{0, 0, -4}}}};
    EXPECT_NE(message(o, tube).find("normal"), std::string::npos) << message(o, tube);
    o.openings = {MeshOpening{.name = "in", .type = "inlet", .near = {{0, 0, -5}}, .extension = 500}};
    EXPECT_NE(message(o, tube).find("extension"), std::string::npos) << message(o, tube);
    // Labels are the patches of a closed surface without openings.
    SurfaceInput labelled = tube;
    labelled.labels.assign(tube.triangles.size() / 3, 0);
    EXPECT_NE(message(fast_options(), labelled).find("labels"), std::string::npos);
}

} // namespace
