// The OpenFOAM case around a polyMesh: checkMesh accepts it and simpleFoam
// runs it to convergence; a case without openings poses no flow problem.

#include "core/errors.h"
#include "core/tet_mesh.h"
#include "exporters/openfoam_case.h"
#include "exporters/polymesh_writer.h"
#include "openfoam_support.h"
#include "tet_meshes.h"

#include "support/temp_dir.h"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>

namespace scalemesh {
namespace {

TEST(OpenFoamCase, ChannelRunsToConvergenceWithSimpleFoam)
{
    if (!openfoam_available()) GTEST_SKIP() << "OpenFOAM (Debian package openfoam) is not installed";
    const TempDir dir;
    const TetMesh mesh = box_of_cubes(4, 4, 8);
    write_polymesh(mesh, dir.path, {.binary = false, .scale = 1e-3, .patch_types = {"wall", "patch", "patch"}});
    const bool flow = write_openfoam_case(dir.path, mesh.patch_names,
                                          {PatchRole::Wall, PatchRole::Inlet, PatchRole::Outlet},
                                          {.kinematic_viscosity = 1e-6, .inlet_speed = 0.01, .iterations = 1000});
    EXPECT_TRUE(flow);
    const std::string check = run_openfoam("checkMesh -case .", dir.path, "checkMesh.log");
    EXPECT_NE(check.find("Mesh OK."), std::string::npos) << check;
    const std::string solve = run_openfoam("simpleFoam -case .", dir.path, "simpleFoam.log");
    EXPECT_EQ(solve.find("FOAM FATAL"), std::string::npos) << solve.substr(0, 4000);
    EXPECT_NE(solve.find("SIMPLE solution converged"), std::string::npos) << solve.substr(solve.size() > 3000 ? solve.size() - 3000 : 0);
}

TEST(OpenFoamCase, NoOpeningsMeansNoFlowFields)
{
    const TempDir dir;
    EXPECT_FALSE(write_openfoam_case(dir.path, {"wall"}, {PatchRole::Wall}));
    EXPECT_TRUE(std::filesystem::exists(dir.path / "system" / "controlDict"));
    EXPECT_TRUE(std::filesystem::exists(dir.path / "constant" / "transportProperties"));
    EXPECT_FALSE(std::filesystem::exists(dir.path / "0"));
}

TEST(OpenFoamCase, RefusesImpossibleSettings)
{
    const TempDir dir;
    EXPECT_THROW(write_openfoam_case(dir.path, {"wall"}, {PatchRole::Wall}, {.kinematic_viscosity = -1}), InputError);
    EXPECT_THROW(write_openfoam_case(dir.path, {"wall"}, {PatchRole::Wall}, {.inlet_speed = 0}), InputError);
    EXPECT_THROW(write_openfoam_case(dir.path, {"wall", "inlet"}, {PatchRole::Wall}), InputError);
    EXPECT_TRUE(std::filesystem::is_empty(dir.path));
}

} // namespace
} // namespace scalemesh
