// Surfaces as users have them (issue 28): open ends cut flat and capped
// without a word in the case file, ends named and reordered by `near` and
// `label`, face labels of a .msh as patches, an implausible size warned
// about with the likely unit, opening points far off refused.

#include "cli_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <numbers>
#include <sstream>

namespace scalemesh {
namespace {

struct Mesh {
    std::vector<std::array<double, 3>> points;
    std::vector<std::array<int, 3>> triangles;
    std::vector<int> labels; // per triangle, for .msh
};

// A tube of radius r along z from 0 to `length`, open at both ends, scaled
// by `scale`; with `caps`, closed by flat fans labelled 2 (z = 0) and 3.
Mesh tube(double r, double length, bool caps = false, double scale = 1.0)
{
    const int n = 32, rings = 41;
    Mesh m;
    for (int j = 0; j < rings; ++j)
        for (int i = 0; i < n; ++i) {
            const double a = 2 * std::numbers::pi * (i + 0.5 * (j % 2)) / n;
            m.points.push_back({scale * r * std::cos(a), scale * r * std::sin(a), scale * length * j / (rings - 1)});
        }
    const auto id = [&](int i, int j) { return j * n + (i % n); };
    for (int j = 0; j + 1 < rings; ++j)
        for (int i = 0; i < n; ++i) {
            m.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            m.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    m.labels.assign(m.triangles.size(), 1);
    if (caps) {
        const int bottom = static_cast<int>(m.points.size());
        m.points.push_back({0, 0, 0});
        const int top = bottom + 1;
        m.points.push_back({0, 0, scale * length});
        for (int i = 0; i < n; ++i) {
            m.triangles.push_back({id(i + 1, 0), id(i, 0), bottom});
            m.labels.push_back(2);
            m.triangles.push_back({id(i, rings - 1), id(i + 1, rings - 1), top});
            m.labels.push_back(3);
        }
    }
    return m;
}

void write_stl(const std::filesystem::path& path, const Mesh& m)
{
    std::ofstream out(path, std::ios::binary);
    const std::string header(80, '\0');
    out.write(header.data(), 80);
    const auto count = static_cast<uint32_t>(m.triangles.size());
    out.write(reinterpret_cast<const char*>(&count), 4);
    for (const auto& t : m.triangles) {
        float record[12] = {};
        for (int c = 0; c < 3; ++c)
            for (int k = 0; k < 3; ++k) record[3 + 3 * c + k] = static_cast<float>(m.points[t[c]][k]);
        out.write(reinterpret_cast<const char*>(record), sizeof record);
        const uint16_t attribute = 0;
        out.write(reinterpret_cast<const char*>(&attribute), 2);
    }
}

// MSH 2.2 with one physical surface per label, named as given.
void write_msh(const std::filesystem::path& path, const Mesh& m, const std::map<int, std::string>& names)
{
    std::ofstream out(path);
    out.precision(17);
    out << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n" << names.size() << "\n";
    for (const auto& [tag, name] : names) out << "2 " << tag << " \"" << name << "\"\n";
    out << "$EndPhysicalNames\n$Nodes\n" << m.points.size() << "\n";
    for (size_t i = 0; i < m.points.size(); ++i)
        out << i + 1 << " " << m.points[i][0] << " " << m.points[i][1] << " " << m.points[i][2] << "\n";
    out << "$EndNodes\n$Elements\n" << m.triangles.size() << "\n";
    for (size_t t = 0; t < m.triangles.size(); ++t)
        out << t + 1 << " 2 2 " << m.labels[t] << " " << m.labels[t] << " " << m.triangles[t][0] + 1 << " "
            << m.triangles[t][1] + 1 << " " << m.triangles[t][2] + 1 << "\n";
    out << "$EndElements\n";
}

void write_case(const std::filesystem::path& dir, const std::string& file, const std::string& extra = "")
{
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "scalemesh.toml") << "[input]\nfile = \"" << file << "\"\n" << extra;
}

nlohmann::json report(const std::filesystem::path& dir)
{
    std::ifstream in(dir / "report.json");
    return nlohmann::json::parse(in);
}

std::vector<std::string> cap_names(const nlohmann::json& r)
{
    std::vector<std::string> names;
    for (const auto& cap : r["openings"]) names.push_back(cap["name"].get<std::string>());
    return names;
}

TEST(OpenSurfaces, AnOpenTubeGetsTwoFlatCapsWithoutOpenings)
{
    const TempDir tmp;
    write_stl(tmp.path / "tube.stl", tube(2, 20));
    write_case(tmp.path / "case", (tmp.path / "tube.stl").string());
    const CommandResult r = run_scalemesh({"run", (tmp.path / "case").string(), "--strict"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("2 open ends, to be cut flat and capped"), std::string::npos) << r.err;
    const nlohmann::json rep = report(tmp.path / "case");
    EXPECT_EQ(cap_names(rep), (std::vector<std::string>{"inlet", "outlet_1"}));
    ASSERT_EQ(rep["input"]["open_ends"].size(), 2u);
    for (const auto& cap : rep["openings"]) {
        const double size = std::sqrt(cap["rim_area_mm2"].get<double>());
        EXPECT_LE(cap["max_distance_from_plane_mm"].get<double>(), 1e-9 * size);
        EXPECT_LE(cap["mesh_max_distance_from_plane_mm"].get<double>(), 1e-9 * size);
        EXPECT_NEAR(std::abs(cap["normal"][2].get<double>()), 1.0, 1e-12);
    }
    EXPECT_EQ(rep["opened_surface"]["components"].get<int64_t>(), 1);
    EXPECT_TRUE(rep["volume"]["boundary_matches_surface"].get<bool>());
}

TEST(OpenSurfaces, EndsAreNamedAndOrderedByNear)
{
    const TempDir tmp;
    write_stl(tmp.path / "tube.stl", tube(2, 20));
    write_case(tmp.path / "case", (tmp.path / "tube.stl").string(),
               "[volume]\nenabled = false\n"
               "[[openings]]\nname = \"distal\"\ntype = \"outlet\"\nnear = [0.5, 0, 19]\n"
               "[[openings]]\nname = \"proximal\"\ntype = \"inlet\"\nnear = [0, 0, 1]\n");
    const CommandResult r = run_scalemesh({"run", (tmp.path / "case").string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json rep = report(tmp.path / "case");
    ASSERT_EQ(cap_names(rep), (std::vector<std::string>{"distal", "proximal"}));
    EXPECT_GT(rep["openings"][0]["normal"][2].get<double>(), 0.99);
    EXPECT_EQ(rep["openings"][0]["type"], "outlet");
    EXPECT_LT(rep["openings"][1]["normal"][2].get<double>(), -0.99);
    EXPECT_EQ(rep["openings"][1]["type"], "inlet");
}

TEST(OpenSurfaces, ANearPointFarFromEveryEndIsRefusedWithTheEnds)
{
    const TempDir tmp;
    write_stl(tmp.path / "tube.stl", tube(2, 20));
    write_case(tmp.path / "case", (tmp.path / "tube.stl").string(),
               "[[openings]]\nname = \"inlet\"\ntype = \"inlet\"\nnear = [0, 0, 10]\n");
    const CommandResult r = run_scalemesh({"run", (tmp.path / "case").string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("opening 'inlet': near = (0, 0, 10) mm is 10 mm from the nearest open end"), std::string::npos)
        << r.err;
    EXPECT_FALSE(std::filesystem::exists(tmp.path / "case" / "mesh.msh"));
}

TEST(OpenSurfaces, NearOnAClosedSurfaceIsRefused)
{
    const TempDir tmp;
    Mesh closed = tube(2, 20, true);
    write_stl(tmp.path / "tube.stl", closed);
    write_case(tmp.path / "case", (tmp.path / "tube.stl").string(),
               "[[openings]]\nname = \"inlet\"\ntype = \"inlet\"\nnear = [0, 0, 0]\n");
    const CommandResult r = run_scalemesh({"run", (tmp.path / "case").string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("has no open ends or flat labelled caps"), std::string::npos) << r.err;
}

TEST(OpenSurfaces, PhysicalSurfacesOfAMshBecomeNamedPatches)
{
    const TempDir tmp;
    write_msh(tmp.path / "tube.msh", tube(2, 20, true), {{1, "vessel"}, {2, "root"}, {3, "distal"}});
    write_case(tmp.path / "case", (tmp.path / "tube.msh").string());
    const CommandResult r = run_scalemesh({"run", (tmp.path / "case").string(), "--strict"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("3 face labels (physical surfaces): 1 'vessel' wall, 2 'root' flat cap, 3 'distal' flat cap"),
              std::string::npos)
        << r.err;
    const nlohmann::json rep = report(tmp.path / "case");
    std::vector<std::string> names = cap_names(rep);
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"distal", "root"}));
    ASSERT_EQ(rep["input"]["face_labels"]["labels"].size(), 3u);
    EXPECT_EQ(rep["input"]["face_labels"]["labels"][0]["role"], "wall");
    EXPECT_EQ(rep["input"]["face_labels"]["labels"][1]["role"], "cap");
    // The OpenFOAM boundary has them as patches.
    std::ifstream in(tmp.path / "case" / "constant" / "polyMesh" / "boundary");
    const std::string boundary((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(boundary.find("root"), std::string::npos);
    EXPECT_NE(boundary.find("distal"), std::string::npos);
}

TEST(OpenSurfaces, ALabelNamesACapInTheCaseFile)
{
    const TempDir tmp;
    write_msh(tmp.path / "tube.msh", tube(2, 20, true), {{1, "vessel"}, {2, "root"}, {3, "distal"}});
    write_case(tmp.path / "case", (tmp.path / "tube.msh").string(),
               "[volume]\nenabled = false\n[[openings]]\nname = \"aorta_out\"\ntype = \"outlet\"\nlabel = 3\n");
    const CommandResult r = run_scalemesh({"run", (tmp.path / "case").string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json rep = report(tmp.path / "case");
    ASSERT_EQ(cap_names(rep), (std::vector<std::string>{"aorta_out", "root"}));
    EXPECT_EQ(rep["openings"][1]["type"], "inlet"); // the case file names no inlet: the largest other end

    write_case(tmp.path / "bad", (tmp.path / "tube.msh").string(),
               "[[openings]]\nname = \"x\"\ntype = \"outlet\"\nlabel = 7\n");
    const CommandResult bad = run_scalemesh({"run", (tmp.path / "bad").string()});
    EXPECT_EQ(bad.exit_code, 2);
    EXPECT_NE(bad.err.find("no flat labelled cap has label 7 (physical surfaces). Hint: choose one of the cap labels: 2, 3"),
              std::string::npos)
        << bad.err;
}

TEST(OpenSurfaces, AMetreScaleSurfaceWarnsWithTheLikelyUnit)
{
    const TempDir tmp;
    write_stl(tmp.path / "tube.stl", tube(2, 20, false, 1e-3));
    write_case(tmp.path / "case", (tmp.path / "tube.stl").string(), "[volume]\nenabled = false\n");
    const CommandResult r = run_scalemesh({"run", (tmp.path / "case").string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("warning: the surface is 0.02 mm across, implausible for an anatomy read in mm; if the file "
                         "is in m, set [input] units = \"m\""),
              std::string::npos)
        << r.err;
    EXPECT_EQ(report(tmp.path / "case")["warnings"].size(), 1u);
    // Before the summary, where it changes how to read it.
    EXPECT_LT(r.err.find("warning: the surface is 0.02 mm across"), r.err.find("\n  surface ")) << r.err;
    const CommandResult strict = run_scalemesh({"run", (tmp.path / "case").string(), "--strict"});
    EXPECT_EQ(strict.exit_code, 6);
    EXPECT_NE(strict.err.find("scalemesh: error: the run warned 1 time about its input (--strict)"), std::string::npos)
        << strict.err;
    EXPECT_NE(strict.err.find("Hint: act on the warnings about the input (units, face labels, openings)\n"), std::string::npos)
        << strict.err;
    EXPECT_EQ(strict.err.find("refine"), std::string::npos) << strict.err;

    // Declared as metres, no warning.
    write_case(tmp.path / "m", (tmp.path / "tube.stl").string(), "units = \"m\"\n[volume]\nenabled = false\n");
    const CommandResult m = run_scalemesh({"run", (tmp.path / "m").string()});
    ASSERT_EQ(m.exit_code, 0) << m.err;
    EXPECT_EQ(m.err.find("warning"), std::string::npos) << m.err;
}

TEST(OpenSurfaces, AClipPlanePointFarOutsideIsRefusedWithAUnitsHint)
{
    const TempDir tmp;
    write_stl(tmp.path / "tube.stl", tube(2, 20));
    write_case(tmp.path / "case", (tmp.path / "tube.stl").string(),
               "[[openings]]\nname = \"inlet\"\ntype = \"inlet\"\npoint = [0, 0, 10000]\nnormal = [0, 0, 1]\n");
    const CommandResult r = run_scalemesh({"run", (tmp.path / "case").string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("opening 'inlet': its point (0, 0, 10000) mm is 9980 mm outside the surface"), std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("check [input] units"), std::string::npos) << r.err;
}

TEST(OpenSurfaces, TouchingLoopsAreRefusedWithWhereAndWhatToDo)
{
    const TempDir tmp;
    Mesh a = tube(1, 5);
    Mesh b = tube(1, 5);
    const int offset = static_cast<int>(a.points.size());
    // b shifted by 2 in x: its point 16 of the first ring, (-1, 0, 0) + 2,
    // is a's point 0.
    for (auto& p : b.points) p[0] += 2.0;
    for (auto t : b.triangles) {
        for (int& v : t) v = v == 16 ? 0 : v + offset;
        a.triangles.push_back(t);
    }
    a.points.insert(a.points.end(), b.points.begin(), b.points.end());
    write_stl(tmp.path / "pair.stl", a);
    write_case(tmp.path / "case", (tmp.path / "pair.stl").string());
    const CommandResult r = run_scalemesh({"run", (tmp.path / "case").string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("is not a surface with clean open ends: 4 open loops"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("1 vertices where open loops touch"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("Hint: an open-ended surface needs clean boundary loops"), std::string::npos) << r.err;
}

} // namespace
} // namespace scalemesh
