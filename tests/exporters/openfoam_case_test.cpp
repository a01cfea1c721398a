// The OpenFOAM case around a polyMesh: checkMesh accepts it and simpleFoam
// runs it to convergence; a case without openings poses no flow problem.

#include "core/errors.h"
#include "core/tet_mesh.h"
#include "exporters/openfoam_case.h"
#include "exporters/polymesh_writer.h"

#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <random>
#include <sstream>

namespace scalemesh {
namespace {

struct Dir {
    std::filesystem::path path = std::filesystem::temp_directory_path() /
                                 ("scalemesh-foamcase-" + std::to_string(std::random_device{}()));
    Dir() { std::filesystem::create_directories(path); }
    ~Dir() { std::filesystem::remove_all(path); }
};

// A box of n x n x 2n cubes of 1 mm, each cut into six tets around its
// diagonal (the same diagonal everywhere, so the cuts conform); boundary
// faces at z = 0 are the inlet (patch 1), at the top the outlet (patch 2).
TetMesh channel(int n)
{
    TetMesh m;
    const int nz = 2 * n;
    auto id = [&](int i, int j, int k) { return (k * (n + 1) + j) * (n + 1) + i; };
    for (int k = 0; k <= nz; ++k)
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i) m.points.push_back({double(i), double(j), double(k)});
    const int kuhn[6][4] = {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7}, {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}};
    for (int k = 0; k < nz; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
                for (const auto& t : kuhn) {
                    Tet tet;
                    for (int c = 0; c < 4; ++c) tet[c] = id(i + (t[c] & 1), j + ((t[c] >> 1) & 1), k + ((t[c] >> 2) & 1));
                    if (tet_volume6(m.points[tet[0]], m.points[tet[1]], m.points[tet[2]], m.points[tet[3]]) < 0)
                        std::swap(tet[2], tet[3]);
                    m.tets.push_back(tet);
                }
    const int faces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    std::map<std::array<int32_t, 3>, std::pair<int, Triangle>> seen;
    for (const Tet& t : m.tets)
        for (const auto& f : faces) {
            const Triangle tri{t[f[0]], t[f[1]], t[f[2]]};
            std::array<int32_t, 3> key{tri[0], tri[1], tri[2]};
            std::sort(key.begin(), key.end());
            ++seen[key].first;
            seen[key].second = tri;
        }
    for (const auto& [key, entry] : seen) {
        if (entry.first != 1) continue;
        m.boundary_faces.push_back(entry.second);
        double z = 0;
        for (int32_t v : entry.second) z += m.points[v].z / 3.0;
        m.boundary_patch.push_back(z == 0.0 ? 1 : (z == double(nz) ? 2 : 0));
    }
    m.patch_names = {"wall", "inlet", "outlet"};
    return m;
}

std::string run(const std::string& command, const std::filesystem::path& log)
{
    const std::string cmd = "WM_PROJECT_DIR=/usr/share/openfoam " + command + " > '" + log.string() + "' 2>&1";
    (void)std::system(cmd.c_str());
    std::ifstream in(log);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

bool openfoam_available() { return std::system("command -v simpleFoam >/dev/null && command -v checkMesh >/dev/null") == 0; }

TEST(OpenFoamCase, ChannelRunsToConvergenceWithSimpleFoam)
{
    if (!openfoam_available()) GTEST_SKIP() << "OpenFOAM (Debian package openfoam) is not installed";
    const Dir dir;
    const TetMesh mesh = channel(4);
    write_polymesh(mesh, dir.path, {.binary = false, .scale = 1e-3, .patch_types = {"wall", "patch", "patch"}});
    const bool flow = write_openfoam_case(dir.path, mesh.patch_names,
                                          {PatchRole::Wall, PatchRole::Inlet, PatchRole::Outlet},
                                          {.kinematic_viscosity = 1e-6, .inlet_speed = 0.01, .iterations = 1000});
    EXPECT_TRUE(flow);
    const std::string check = run("checkMesh -case '" + dir.path.string() + "'", dir.path / "checkMesh.log");
    EXPECT_NE(check.find("Mesh OK."), std::string::npos) << check;
    const std::string solve = run("simpleFoam -case '" + dir.path.string() + "'", dir.path / "simpleFoam.log");
    EXPECT_EQ(solve.find("FOAM FATAL"), std::string::npos) << solve.substr(0, 4000);
    EXPECT_NE(solve.find("SIMPLE solution converged"), std::string::npos) << solve.substr(solve.size() > 3000 ? solve.size() - 3000 : 0);
}

TEST(OpenFoamCase, NoOpeningsMeansNoFlowFields)
{
    const Dir dir;
    EXPECT_FALSE(write_openfoam_case(dir.path, {"wall"}, {PatchRole::Wall}));
    EXPECT_TRUE(std::filesystem::exists(dir.path / "system" / "controlDict"));
    EXPECT_TRUE(std::filesystem::exists(dir.path / "constant" / "transportProperties"));
    EXPECT_FALSE(std::filesystem::exists(dir.path / "0"));
}

TEST(OpenFoamCase, RefusesImpossibleSettings)
{
    const Dir dir;
    EXPECT_THROW(write_openfoam_case(dir.path, {"wall"}, {PatchRole::Wall}, {.kinematic_viscosity = -1}), InputError);
    EXPECT_THROW(write_openfoam_case(dir.path, {"wall"}, {PatchRole::Wall}, {.inlet_speed = 0}), InputError);
    EXPECT_THROW(write_openfoam_case(dir.path, {"wall", "inlet"}, {PatchRole::Wall}), InputError);
    EXPECT_TRUE(std::filesystem::is_empty(dir.path));
}

} // namespace
} // namespace scalemesh
