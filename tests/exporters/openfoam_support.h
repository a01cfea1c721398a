#pragma once
// Running OpenFOAM's own tools on cases the exporter tests write.

#include "exporters/openfoam_case.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

namespace scalemesh {

inline bool openfoam_available()
{
    return std::system("command -v checkMesh >/dev/null && command -v simpleFoam >/dev/null && "
                       "command -v gmshToFoam >/dev/null") == 0;
}

inline std::string read_text(const std::filesystem::path& p)
{
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

// Runs an OpenFOAM command line in `dir`, returning what it printed.
inline std::string run_openfoam(const std::string& command, const std::filesystem::path& dir, const std::string& log)
{
    const std::string cmd = "cd '" + dir.string() + "' && WM_PROJECT_DIR=/usr/share/openfoam " + command + " > '" +
                            log + "' 2>&1";
    (void)std::system(cmd.c_str());
    return read_text(dir / log);
}

struct CheckMeshFigures {
    std::string log;
    bool ok = false; // "Mesh OK."
    long cells = -1;
    double volume = -1; // "Total volume"
    double max_non_orthogonality = -1; // "Mesh non-orthogonality Max:"
    double max_skewness = -1;          // "Max skewness ="
};

// checkMesh on a case whose polyMesh is written; system/ comes from our case
// writer, with every patch a wall (no flow fields needed).
inline CheckMeshFigures check_mesh(const std::filesystem::path& case_dir)
{
    write_openfoam_case(case_dir, {"wall"}, {PatchRole::Wall});
    CheckMeshFigures f;
    f.log = run_openfoam("checkMesh -case .", case_dir, "checkMesh.log");
    f.ok = f.log.find("Mesh OK.") != std::string::npos;
    std::smatch m;
    if (std::regex_search(f.log, m, std::regex(R"(cells:\s+(\d+))"))) f.cells = std::stol(m[1]);
    if (std::regex_search(f.log, m, std::regex(R"(Total volume = ([0-9.eE+-]+))"))) f.volume = std::stod(m[1]);
    if (std::regex_search(f.log, m, std::regex(R"(non-orthogonality Max: ([0-9.eE+-]+))")))
        f.max_non_orthogonality = std::stod(m[1]);
    if (std::regex_search(f.log, m, std::regex(R"(Max skewness = ([0-9.eE+-]+))"))) f.max_skewness = std::stod(m[1]);
    return f;
}

} // namespace scalemesh
