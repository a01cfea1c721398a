// The walk-through of docs/user-guide.md, run as written: the commands of the
// block after its "walkthrough" marker, from a directory holding a copy of
// cases/aorta_mask (so the source tree stays clean), with only the path of
// the scalemesh binary replaced by the one under test.

#include "cli_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <fstream>
#include <regex>
#include <sstream>

namespace scalemesh {
namespace {

std::string read_all(const std::filesystem::path& path)
{
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// The lines of the first ```sh block after the walkthrough marker.
std::vector<std::string> walkthrough_commands()
{
    const std::string guide = read_all("docs/user-guide.md");
    const size_t marker = guide.find("<!-- walkthrough:");
    if (marker == std::string::npos) return {};
    const size_t start = guide.find("```sh\n", marker);
    const size_t end = guide.find("```", start + 6);
    std::vector<std::string> commands;
    std::istringstream block(guide.substr(start + 6, end - start - 6));
    for (std::string line; std::getline(block, line);)
        if (!line.empty()) commands.push_back(line);
    return commands;
}

TEST(UserGuide, TheAortaWalkThroughRunsAsWritten)
{
    const std::vector<std::string> commands = walkthrough_commands();
    ASSERT_EQ(commands.size(), 2u) << "docs/user-guide.md: a scalemesh run and a checkMesh";
    EXPECT_EQ(commands[0], "build/src/cli/scalemesh run cases/aorta_mask");
    EXPECT_EQ(commands[1], "WM_PROJECT_DIR=/usr/share/openfoam checkMesh -case cases/aorta_mask");
    if (std::system("command -v checkMesh >/dev/null 2>&1") != 0) GTEST_SKIP() << "OpenFOAM's checkMesh is not installed";

    const TempDir tmp;
    const std::filesystem::path source = std::filesystem::absolute("cases/aorta_mask");
    const std::filesystem::path dir = tmp.path / "cases" / "aorta_mask";
    std::filesystem::create_directories(dir);
    // The case names its image relative to itself; the copy names the same file.
    const std::string toml = read_all(source / "scalemesh.toml");
    std::smatch m;
    ASSERT_TRUE(std::regex_search(toml, m, std::regex(R"re(file = "([^"]*)")re")));
    const std::string image = (source / m[1].str()).lexically_normal().string();
    ASSERT_TRUE(std::filesystem::exists(image)) << image;
    std::ofstream(dir / "scalemesh.toml") << m.prefix() << "file = \"" << image << "\"" << m.suffix();

    const char* binary = std::getenv("SCALEMESH_BINARY");
    ASSERT_NE(binary, nullptr);
    std::vector<std::string> logs;
    for (size_t i = 0; i < commands.size(); ++i) {
        std::string command = commands[i];
        const std::string program = "build/src/cli/scalemesh";
        if (command.rfind(program, 0) == 0) command = quote(std::filesystem::absolute(binary).string()) + command.substr(program.size());
        const auto log = tmp.path / ("command" + std::to_string(i) + ".log");
        const auto start = std::chrono::steady_clock::now();
        const int status =
            std::system(("cd " + quote(tmp.path.string()) + " && " + command + " > " + quote(log.string()) + " 2>&1").c_str());
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        logs.push_back(read_all(log));
        ASSERT_EQ(status, 0) << commands[i] << ":\n" << logs.back();
        RecordProperty("seconds_" + std::to_string(i), std::to_string(seconds));
    }
    // The run's summary, as the guide shows it.
    for (const std::string line : {"\nscalemesh: done in ", "\n  cells ", "\n  layers ", "\n  quality   worst aspect ratio ",
                                   "\n  wrote "})
        EXPECT_NE(logs[0].find(line), std::string::npos) << line << " in:\n" << logs[0];
    EXPECT_NE(logs[1].find("\nMesh OK."), std::string::npos) << logs[1];

    std::ifstream in(dir / "report.json");
    const nlohmann::json report = nlohmann::json::parse(in);
    for (const auto& name : report["files"]) EXPECT_TRUE(std::filesystem::exists(dir / name.get<std::string>())) << name;
    for (const char* name : {"mesh.msh", "quality.png", "constant/polyMesh/owner", "system/controlDict"})
        EXPECT_TRUE(std::filesystem::exists(dir / name)) << name;
}

} // namespace
} // namespace scalemesh
