#pragma once
// Hostile but valid inputs for the whole pipeline: tiny images written as
// MetaImage files, closed STL surfaces, the scalemesh binary run under a time
// limit, the facts every written mesh must have, and each test's input and
// outcome recorded for the table in docs/reliability.md.

#include "cli/cli_support.h"
#include "core/surface_mesh.h"
#include "core/tet_mesh.h"
#include "gmsh_io/msh_reader.h"
#include "volume/volume_mesh.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace scalemesh {

// Voxel (i, j, k) of an nx x ny x nz image: inside or not.
using VoxelTest = std::function<bool(int i, int j, int k)>;

// A 0/1 MetaImage (.mha, unsigned char, x fastest) of cubic voxels of
// `spacing` mm, origin 0.
inline void write_label_mha(const std::filesystem::path& path, std::array<int, 3> size, double spacing,
                            const VoxelTest& inside)
{
    std::ofstream out(path, std::ios::binary);
    out << "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
        << "DimSize = " << size[0] << ' ' << size[1] << ' ' << size[2] << "\n";
    out.precision(17);
    out << "ElementSpacing = " << spacing << ' ' << spacing << ' ' << spacing << "\n"
        << "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n";
    for (int k = 0; k < size[2]; ++k)
        for (int j = 0; j < size[1]; ++j)
            for (int i = 0; i < size[0]; ++i) out.put(inside(i, j, k) ? 1 : 0);
}

// Voxels within `r` voxel widths of voxel `c` (centre to centre).
inline VoxelTest ball(std::array<int, 3> c, double r)
{
    return [=](int i, int j, int k) {
        const double x = i - c[0], y = j - c[1], z = k - c[2];
        return x * x + y * y + z * z <= r * r;
    };
}

// An ASCII STL of the triangles (counter-clockwise seen from outside).
inline void write_stl(const std::filesystem::path& path, const std::vector<std::array<Vec3, 3>>& triangles)
{
    std::ofstream out(path);
    out.precision(17);
    out << "solid s\n";
    for (const auto& t : triangles) {
        const Vec3 n = cross(t[1] - t[0], t[2] - t[0]);
        out << "facet normal " << n.x << ' ' << n.y << ' ' << n.z << "\nouter loop\n";
        for (const Vec3& v : t) out << "vertex " << v.x << ' ' << v.y << ' ' << v.z << "\n";
        out << "endloop\nendfacet\n";
    }
    out << "endsolid s\n";
}

inline void write_case(const std::filesystem::path& dir, const std::string& toml)
{
    std::ofstream(dir / "scalemesh.toml") << toml;
}

// `scalemesh run dir -q` (and `extra` arguments), killed after `seconds`: a
// hang shows as exit code 124, a crash as 128 + the signal (timeout(1)).
inline CommandResult run_case_limited(const std::filesystem::path& dir, int seconds,
                                      const std::vector<std::string>& extra = {})
{
    const char* binary = std::getenv("SCALEMESH_BINARY");
    if (!binary) throw std::runtime_error("SCALEMESH_BINARY is not set; run the tests through ctest");
    const std::filesystem::path err_file = dir.parent_path() / (dir.filename().string() + ".stderr");
    std::string cmd = "timeout " + std::to_string(seconds) + " " + quote(binary) + " run " + quote(dir.string()) + " -q";
    for (const std::string& a : extra) cmd += " " + quote(a);
    cmd += " </dev/null >/dev/null 2>" + quote(err_file.string());
    const int status = std::system(cmd.c_str());
    CommandResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    std::ifstream in(err_file);
    r.err.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    std::filesystem::remove(err_file);
    return r;
}

// What expect_mesh_facts found: the mesh's size and the facts that failed.
struct MeshOutcome {
    size_t tets = 0;
    int64_t surface_components = 0;       // of the mesh's boundary faces
    std::vector<std::string> failed_facts; // empty when every fact holds
};

// "meshed: 1554 tets, 1 surface component, all facts true", or with the
// failed facts in place of "all facts true".
inline std::string describe(const MeshOutcome& m)
{
    std::string line = "meshed: " + std::to_string(m.tets) + " tets, " + std::to_string(m.surface_components) +
                       " surface component" + (m.surface_components == 1 ? "" : "s") + ", ";
    if (m.failed_facts.empty()) return line + "all facts true";
    line += "facts failing: ";
    for (size_t i = 0; i < m.failed_facts.size(); ++i) line += (i ? ", " : "") + m.failed_facts[i];
    return line;
}

// A run that wrote no mesh, in one line: "refused: " and the message for exit
// code 2, else the exit code (124: killed at the time limit) and the last line
// of stderr.
inline std::string describe_unmeshed(const CommandResult& r)
{
    std::string message = r.err;
    while (!message.empty() && message.back() == '\n') message.pop_back();
    const size_t last_line = message.rfind('\n');
    if (last_line != std::string::npos) message.erase(0, last_line + 1);
    // The tests' scratch directories (TempDir) have random names: keep the
    // path inside them only.
    for (size_t at; (at = message.find("scalemesh-test-")) != std::string::npos;) {
        const size_t start = message.rfind(' ', at) == std::string::npos ? 0 : message.rfind(' ', at) + 1;
        const size_t slash = message.find('/', at);
        if (slash == std::string::npos) break;
        message.erase(start, slash + 1 - start);
    }
    if (r.exit_code == 2) return "refused: " + message;
    return "exit code " + std::to_string(r.exit_code) + (r.exit_code == 124 ? " (killed at the time limit)" : "") +
           (message.empty() ? "" : ": " + message);
}

// The facts every mesh scalemesh writes must have, read back from mesh.msh:
// every tet positive, every face in one or two tets, the one-tet faces
// exactly the surface triangles, the tets' volume the volume the surface
// encloses, and each surface node's tets one face-connected component.
// Returns what it found, for the recorded outcome.
inline MeshOutcome expect_mesh_facts(const std::filesystem::path& dir)
{
    const TetMesh mesh = read_msh_volume(dir / "mesh.msh");
    const TetMeshFacts facts = tet_mesh_facts(mesh);
    EXPECT_GT(mesh.tets.size(), 0u);
    EXPECT_EQ(facts.nonpositive_tets, 0);
    EXPECT_EQ(facts.overshared_faces, 0);
    EXPECT_TRUE(facts.boundary_matches);
    SurfaceMesh boundary;
    boundary.points = mesh.points;
    boundary.triangles = mesh.boundary_faces;
    const SurfaceFacts surface = surface_facts(boundary);
    EXPECT_TRUE(surface.closed_manifold());
    const double volume_tolerance = 1e-9 * std::abs(surface.signed_volume);
    EXPECT_NEAR(facts.volume, surface.signed_volume, volume_tolerance);
    // The surface points come first in the mesh: those on a boundary face.
    int32_t surface_points = 0;
    for (const Triangle& t : mesh.boundary_faces)
        for (int32_t v : t) surface_points = std::max(surface_points, v + 1);
    const size_t topology_failures = topology_check_failures(mesh, surface_points).size();
    EXPECT_EQ(topology_failures, 0u);

    // The same facts, named for the outcome line.
    MeshOutcome seen{mesh.tets.size(), surface.components, {}};
    const std::pair<bool, std::string> checks[] = {
        {!mesh.tets.empty(), "no tets"},
        {facts.nonpositive_tets == 0, std::to_string(facts.nonpositive_tets) + " tets not positive"},
        {facts.overshared_faces == 0, std::to_string(facts.overshared_faces) + " faces in three or more tets"},
        {facts.boundary_matches, "one-tet faces not the surface triangles"},
        {surface.closed_manifold(), "boundary not a closed 2-manifold"},
        {std::abs(facts.volume - surface.signed_volume) <= volume_tolerance, "tet volume not the enclosed volume"},
        {topology_failures == 0, std::to_string(topology_failures) + " surface nodes failing the topology check"}};
    for (const auto& [holds, failure] : checks)
        if (!holds) seen.failed_facts.push_back(failure);
    return seen;
}

// A refusal: exit 2, the last line of stderr one error saying what is wrong
// and what to do ("Hint:"), and no output written besides what was there.
inline void expect_refused(const CommandResult& r, const std::filesystem::path& dir,
                           const std::vector<std::string>& inputs)
{
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.err.rfind("scalemesh: error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find("Hint: "), std::string::npos) << r.err;
    std::vector<std::string> left;
    for (const auto& e : std::filesystem::directory_iterator(dir)) left.push_back(e.path().filename().string());
    std::sort(left.begin(), left.end());
    std::vector<std::string> expected = inputs;
    expected.push_back("scalemesh.toml");
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(left, expected);
}

// A hostile-input test's input and outcome as the test properties "input"
// and "outcome" (tests/reliability/reliability_table.py reads them from
// --gtest_output=json). The outcome is what the runs did, not what the test
// expects: each run's describe() or describe_unmeshed() line, joined with
// "; ", recorded when the test ends, also when an assertion ends it early.
class RecordedOutcome {
public:
    explicit RecordedOutcome(const std::string& input) { ::testing::Test::RecordProperty("input", input); }
    ~RecordedOutcome() { ::testing::Test::RecordProperty("outcome", runs_.empty() ? "no run finished" : runs_); }
    RecordedOutcome(const RecordedOutcome&) = delete;
    RecordedOutcome& operator=(const RecordedOutcome&) = delete;

    // One run's outcome; `label` tells the runs of one test apart.
    void add(const std::string& outcome, const std::string& label = "")
    {
        runs_ += (runs_.empty() ? "" : "; ") + (label.empty() ? "" : label + ": ") + outcome;
    }

private:
    std::string runs_;
};

} // namespace scalemesh
