// OpenFOAM habits of the command line: `scalemesh -case DIR` is `scalemesh
// run DIR`; the run's log is written into the case (log.scalemesh); every
// OpenFOAM case gets an Allrun that runs Debian's OpenFOAM with logs and
// fails when a tool does; an ASCII MSH 2.2 mesh.msh is read by gmshToFoam.

#include "cli_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <regex>
#include <sstream>

namespace scalemesh {
namespace {

std::string slurp(const std::filesystem::path& path)
{
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

// Runs a shell command in `dir`; its exit code, and what it printed in `out`.
int shell(const std::string& command, const std::filesystem::path& dir, std::string& out)
{
    const std::filesystem::path file = dir.parent_path() / "shell.out";
    const int status =
        std::system(("cd " + quote(dir.string()) + " && " + command + " > " + quote(file.string()) + " 2>&1").c_str());
    out = slurp(file);
    std::filesystem::remove(file);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::filesystem::path make_case(const TempDir& tmp, const std::string& name, const std::string& text)
{
    const auto dir = tmp.path / name;
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "scalemesh.toml") << text;
    return dir;
}

const char* kBall = "[input]\nphantom = \"sphere\"\nvoxel_size = 1.0\n";

// The tube of cases/tube, coarser: an inlet and an outlet, so a flow case.
const char* kTube = "[input]\nphantom = \"tube\"\nvoxel_size = 0.75\n"
                    "[[openings]]\nname = \"inlet\"\ntype = \"inlet\"\npoint = [0, 0, -12]\nnormal = [0, 0, -1]\n"
                    "[[openings]]\nname = \"outlet\"\ntype = \"outlet\"\npoint = [0, 0, 12]\nnormal = [0, 0, 1]\n";

TEST(CliOpenFoam, DashCaseIsRunAndTheLogHoldsWhatTheRunPrinted)
{
    const TempDir tmp;
    const auto dir = make_case(tmp, "ball", kBall);
    const CommandResult r = run_scalemesh({"-case", dir.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(std::filesystem::exists(dir / "mesh.msh"));
    EXPECT_TRUE(std::filesystem::exists(dir / "report.json"));
    // stderr is not a terminal here: whole lines, the same in the log.
    ASSERT_TRUE(std::filesystem::exists(dir / "log.scalemesh"));
    const std::string log = slurp(dir / "log.scalemesh");
    EXPECT_EQ(log, r.err);
    EXPECT_NE(log.find("scalemesh: volume "), std::string::npos) << log;
    EXPECT_NE(log.find("\nscalemesh: done in "), std::string::npos) << log;

    // Options after the directory, as after `run DIR`; -q silences the
    // terminal, not the log.
    const CommandResult quiet = run_scalemesh({"-case", dir.string(), "--threads", "1", "-q"});
    ASSERT_EQ(quiet.exit_code, 0) << quiet.err;
    EXPECT_EQ(quiet.err, "");
    EXPECT_NE(slurp(dir / "log.scalemesh").find("\nscalemesh: done in "), std::string::npos);
    const nlohmann::json report = nlohmann::json::parse(slurp(dir / "report.json"));
    EXPECT_EQ(report["parameters"]["threads"], 1);
}

TEST(CliOpenFoam, DashCaseRefusesAMissingDirectoryOrAVerb)
{
    const TempDir tmp;
    CommandResult r = run_scalemesh({"-case"});
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.err.find("-case needs the case directory"), std::string::npos) << r.err;
    r = run_scalemesh({"check", "-case", tmp.path.string()});
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.err.find("without the verb 'check'"), std::string::npos) << r.err;
    r = run_scalemesh({"-case", (tmp.path / "nowhere").string()});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_TRUE(tmp.files().empty());
}

TEST(CliOpenFoam, AFailedRunWritesNoLog)
{
    const TempDir tmp;
    const auto dir = make_case(tmp, "ball", std::string(kBall) + "[sizing]\nK = -1\n");
    EXPECT_EQ(run_scalemesh({"-case", dir.string()}).exit_code, 2);
    EXPECT_EQ(tmp.files(), (std::vector<std::string>{"ball", "ball/scalemesh.toml"}));
}

// Openings that pose no flow (one outlet, no inlet) leave 0/ unwritten, and
// the run says so, as a warning about the case that --strict fails. On the
// paper's Delaunay layers: on this coarse tube the prism layers' core has a
// tet cell below the dihedral floor, and their giving way would be a second
// warning.
TEST(CliOpenFoam, OpeningsThatPoseNoFlowAreWarnedOf)
{
    const TempDir tmp;
    const auto dir = make_case(tmp, "tube",
                               "[input]\nphantom = \"tube\"\nvoxel_size = 0.75\n[[openings]]\nname = \"out\"\n"
                               "type = \"outlet\"\npoint = [0, 0, 12]\nnormal = [0, 0, 1]\n[volume]\nlayers = \"delaunay\"\n");
    const CommandResult r = run_scalemesh({"run", dir.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "0"));
    const std::string warning = "scalemesh: warning: the case has 1 opening but no inlet, so no flow is posed: 0/U and "
                                "0/p are not written";
    EXPECT_NE(r.err.find(warning), std::string::npos) << r.err;
    EXPECT_LT(r.err.find(warning), r.err.find("\n  surface ")) << "before the summary";
    const nlohmann::json report = nlohmann::json::parse(slurp(dir / "report.json"));
    ASSERT_EQ(report["warnings"].size(), 1u);
    const CommandResult strict = run_scalemesh({"run", dir.string(), "-q", "--strict"});
    EXPECT_EQ(strict.exit_code, 6) << strict.err;
    EXPECT_NE(strict.err.find("the run warned 1 time about its input (--strict)"), std::string::npos) << strict.err;
}

TEST(CliOpenFoam, AllrunChecksTheMeshAndRunsTheFlow)
{
    const TempDir tmp;
    const auto dir = make_case(tmp, "tube", kTube);
    const CommandResult r = run_scalemesh({"-case", dir.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto perms = std::filesystem::status(dir / "Allrun").permissions();
    EXPECT_NE(perms & std::filesystem::perms::owner_exec, std::filesystem::perms::none);
    const nlohmann::json report = nlohmann::json::parse(slurp(dir / "report.json"));
    EXPECT_NE(std::find(report["files"].begin(), report["files"].end(), "Allrun"), report["files"].end());

    std::string out;
    ASSERT_EQ(shell("./Allrun", dir, out), 0) << out;
    EXPECT_NE(out.find("Running checkMesh"), std::string::npos) << out;
    EXPECT_NE(slurp(dir / "log.checkMesh").find("\nMesh OK."), std::string::npos);
    const std::string flow = slurp(dir / "log.simpleFoam");
    EXPECT_NE(flow.find("SIMPLE solution converged"), std::string::npos) << flow.substr(flow.size() > 2000 ? flow.size() - 2000 : 0);
    EXPECT_NE(flow.find("\nEnd"), std::string::npos);

    // A broken mesh: Allrun stops at checkMesh, non-zero, naming the log.
    std::filesystem::remove(dir / "constant" / "polyMesh" / "owner");
    std::filesystem::remove(dir / "log.simpleFoam");
    EXPECT_NE(shell("./Allrun", dir, out), 0) << out;
    EXPECT_NE(out.find("Allrun: checkMesh failed"), std::string::npos) << out;
    EXPECT_NE(out.find("log.checkMesh"), std::string::npos) << out;
    EXPECT_FALSE(std::filesystem::exists(dir / "log.simpleFoam"));
}

TEST(CliOpenFoam, DecomposeIsCheckedAndNothingIsWrittenForABadOne)
{
    const TempDir tmp;
    for (const auto& [value, says] : {std::pair<std::string, std::string>{"0", "must be at least 1"},
                                      {"-3", "must be at least 1"},
                                      {"2.5", "must be a whole number"},
                                      {"\"2\"", "must be a whole number"}}) {
        const auto dir = make_case(tmp, "bad", std::string(kTube) + "[output]\ndecompose = " + value + "\n");
        const CommandResult r = run_scalemesh({"run", dir.string(), "-q"});
        EXPECT_EQ(r.exit_code, 2) << value << ": " << r.err;
        EXPECT_NE(r.err.find("decompose"), std::string::npos) << r.err;
        EXPECT_NE(r.err.find(says), std::string::npos) << r.err;
        EXPECT_FALSE(std::filesystem::exists(dir / "report.json"));
    }
    // Pieces of a case that writes no OpenFOAM case: refused, in the file
    // and on the command line.
    const auto no_openfoam =
        make_case(tmp, "no_openfoam", std::string(kTube) + "[output]\nopenfoam = false\ndecompose = 2\n");
    const CommandResult in_file = run_scalemesh({"run", no_openfoam.string(), "-q"});
    EXPECT_EQ(in_file.exit_code, 2) << in_file.err;
    EXPECT_NE(in_file.err.find("openfoam = false writes no OpenFOAM case"), std::string::npos) << in_file.err;
    const auto flag_only = make_case(tmp, "flag_only", std::string(kTube) + "[output]\nopenfoam = false\n");
    const CommandResult on_line = run_scalemesh({"run", flag_only.string(), "-q", "--decompose", "2"});
    EXPECT_EQ(on_line.exit_code, 2) << on_line.err;
    EXPECT_NE(on_line.err.find("--decompose 2 asks for processor meshes"), std::string::npos) << on_line.err;
    for (const auto& d : {no_openfoam, flag_only}) EXPECT_FALSE(std::filesystem::exists(d / "report.json"));

    const auto dir = make_case(tmp, "tube", kTube);
    for (const char* value : {"0", "two"}) {
        const CommandResult r = run_scalemesh({"run", dir.string(), "-q", "--decompose", value});
        EXPECT_NE(r.exit_code, 0) << value;
        EXPECT_NE(r.err.find("--decompose"), std::string::npos) << r.err;
    }
    // More pieces than cells: found once the cells are known, and the run
    // writes nothing.
    const CommandResult many = run_scalemesh({"run", dir.string(), "-q", "--decompose", "10000000"});
    EXPECT_EQ(many.exit_code, 2) << many.err;
    EXPECT_NE(many.err.find("more processor meshes than the"), std::string::npos) << many.err;
    EXPECT_EQ(std::count(many.err.begin(), many.err.end(), '\n'), 1) << many.err;
    for (const char* name : {"report.json", "processor0", "constant", "mesh.msh"})
        EXPECT_FALSE(std::filesystem::exists(dir / name)) << name;

    // Three pieces, then two (processor2 goes), then none (all go, and
    // Allrun is the serial one again).
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q", "--decompose", "3"}).exit_code, 0);
    EXPECT_TRUE(std::filesystem::exists(dir / "processor2" / "constant" / "polyMesh" / "faceProcAddressing"));
    EXPECT_TRUE(std::filesystem::exists(dir / "processor2" / "0" / "U"));
    EXPECT_NE(slurp(dir / "Allrun").find("mpirun -np \"$processors\" \"$1\" -parallel"), std::string::npos);
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q", "--decompose", "2"}).exit_code, 0);
    EXPECT_TRUE(std::filesystem::exists(dir / "processor1"));
    EXPECT_FALSE(std::filesystem::exists(dir / "processor2"));
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q"}).exit_code, 0);
    for (const char* name : {"processor0", "processor1", "constant/cellDecomposition", "system/decomposeParDict"})
        EXPECT_FALSE(std::filesystem::exists(dir / name)) << name;
    EXPECT_EQ(slurp(dir / "Allrun").find("mpirun"), std::string::npos);
}

TEST(CliOpenFoam, AllrunWithoutOpeningsOnlyChecksTheMesh)
{
    const TempDir tmp;
    const auto dir = make_case(tmp, "ball", kBall);
    ASSERT_EQ(run_scalemesh({"-case", dir.string(), "-q"}).exit_code, 0);
    std::string out;
    ASSERT_EQ(shell("bash Allrun", dir, out), 0) << out;
    EXPECT_NE(slurp(dir / "log.checkMesh").find("\nMesh OK."), std::string::npos);
    EXPECT_FALSE(std::filesystem::exists(dir / "log.simpleFoam"));
    EXPECT_EQ(out.find("simpleFoam"), std::string::npos) << out;
}

// The fallback route into OpenFOAM: an ASCII MSH 2.2 mesh.msh (msh_binary =
// false is the default) read by gmshToFoam, then accepted by checkMesh with
// the cells of scalemesh's mesh and its patches.
TEST(CliOpenFoam, GmshToFoamReadsTheAsciiMsh)
{
    const TempDir tmp;
    const auto dir = make_case(tmp, "tube", std::string(kTube) + "[output]\nmsh_version = 2.2\nmsh_binary = false\n");
    ASSERT_EQ(run_scalemesh({"-case", dir.string(), "-q"}).exit_code, 0);
    const std::string msh = slurp(dir / "mesh.msh");
    ASSERT_EQ(msh.rfind("$MeshFormat\n2.2 0 8\n", 0), 0u) << msh.substr(0, 40); // 0: ASCII
    // gmshToFoam into a case of its own (system/ only), not over ours.
    const auto foam = tmp.path / "via_gmsh";
    std::filesystem::create_directories(foam);
    std::filesystem::copy(dir / "system", foam / "system", std::filesystem::copy_options::recursive);
    std::filesystem::copy_file(dir / "mesh.msh", foam / "mesh.msh");
    std::string out;
    ASSERT_EQ(shell("WM_PROJECT_DIR=/usr/share/openfoam gmshToFoam mesh.msh -case .", foam, out), 0) << out;
    ASSERT_EQ(shell("WM_PROJECT_DIR=/usr/share/openfoam checkMesh -case .", foam, out), 0) << out;
    EXPECT_NE(out.find("\nMesh OK."), std::string::npos) << out;
    const nlohmann::json report = nlohmann::json::parse(slurp(dir / "report.json"));
    std::smatch cells;
    ASSERT_TRUE(std::regex_search(out, cells, std::regex(R"(cells:\s+(\d+))"))) << out;
    EXPECT_EQ(std::stol(cells[1]), report["volume"]["tets"].get<long>());
    const std::string boundary = slurp(foam / "constant" / "polyMesh" / "boundary");
    for (const char* patch : {"wall", "inlet", "outlet"})
        EXPECT_NE(boundary.find(patch), std::string::npos) << boundary;
}

} // namespace
} // namespace scalemesh
