// Every directory under cases/ runs through `scalemesh run` (on a copy, so the
// source tree stays clean) and its report.json meets the case's expected.toml.

#include "cli_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <toml++/toml.h>

#include <fstream>
#include <regex>
#include <sstream>

namespace scalemesh {
namespace {

std::vector<std::string> case_names()
{
    std::vector<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator("cases"))
        if (std::filesystem::exists(entry.path() / "scalemesh.toml")) names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

// [lo, hi] from an expected.toml array.
std::pair<double, double> bounds(const toml::node& node)
{
    const toml::array* a = node.as_array();
    if (!a || a->size() != 2) throw std::runtime_error("a bound must be [lo, hi]");
    return {*a->get(0)->value<double>(), *a->get(1)->value<double>()};
}

class SampleCase : public ::testing::TestWithParam<std::string> {};

TEST_P(SampleCase, RunsAndMeetsItsExpectedBounds)
{
    const TempDir tmp;
    const std::filesystem::path dir = tmp.path / GetParam();
    const std::filesystem::path source = std::filesystem::path("cases") / GetParam();
    std::filesystem::create_directories(dir);
    for (const char* name : {"scalemesh.toml", "expected.toml"}) std::filesystem::copy(source / name, dir / name);
    // An input file named relative to the case resolves against the original.
    {
        std::ifstream in(dir / "scalemesh.toml");
        const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        std::smatch m;
        if (std::regex_search(text, m, std::regex(R"re(file = "([^"/][^"]*)")re"))) {
            const std::string absolute = std::filesystem::absolute(source / m[1].str()).lexically_normal().string();
            std::ofstream(dir / "scalemesh.toml") << m.prefix() << "file = \"" << absolute << "\"" << m.suffix();
        }
    }
    // --strict: a missed floor of the case file (layer coverage, worst
    // aspect ratio) fails the run.
    const CommandResult r = run_scalemesh({"run", dir.string(), "-q", "--strict"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.err.empty()) << "-q must print nothing: " << r.err;

    std::ifstream in(dir / "report.json");
    ASSERT_TRUE(in) << "no report.json";
    const nlohmann::json report = nlohmann::json::parse(in);
    for (const auto& name : report["files"]) EXPECT_TRUE(std::filesystem::exists(dir / name.get<std::string>())) << name;

    const toml::table expected = toml::parse_file((dir / "expected.toml").string());
    ASSERT_TRUE(expected.contains("surface")) << "expected.toml needs a [surface] section";
    const nlohmann::json& surface = report["surface"];
    for (const auto& [key, value] : *expected["surface"].as_table()) {
        const std::string k(key.str());
        if (k == "closed_manifold") EXPECT_EQ(surface["closed_manifold"].get<bool>(), *value.value<bool>());
        else if (k == "components") EXPECT_EQ(surface["components"].get<int64_t>(), *value.value<int64_t>());
        else if (k == "euler_characteristic")
            EXPECT_EQ(surface["euler_characteristic"].get<int64_t>(), *value.value<int64_t>());
        else if (k == "volume_vs_voxels") {
            const double h = report["input"]["voxel_width_mm"].get<double>();
            const double voxels = report["input"]["inside_voxels"].get<double>() * h * h * h;
            EXPECT_LE(std::abs(surface["enclosed_volume_mm3"].get<double>() / voxels - 1.0), *value.value<double>());
        } else ADD_FAILURE() << "unknown key [surface] " << k << " in expected.toml";
    }
    // Every volume mesh must pass OpenFOAM's own check, with our counts.
    if (report.contains("openfoam") && std::system("command -v checkMesh >/dev/null 2>&1") == 0) {
        // checkMesh's output with `options`, kept as `log_name` in the case
        // (it exits 0 whatever its checks find: the verdict is in the text).
        const auto check_mesh = [&](const std::string& options, const std::string& log_name) {
            const std::string log = (dir / log_name).string();
            const std::string cmd = "cd '" + dir.string() + "' && WM_PROJECT_DIR=/usr/share/openfoam checkMesh -case . " +
                                    options + " > '" + log + "' 2>&1";
            EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
            std::ifstream in(log);
            return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        };
        const std::string text = check_mesh("", "checkMesh.log");
        EXPECT_NE(text.find("\nMesh OK."), std::string::npos) << text;
        std::smatch cells, volume;
        ASSERT_TRUE(std::regex_search(text, cells, std::regex(R"(cells:\s+(\d+))")));
        EXPECT_EQ(std::stol(cells[1]), report["openfoam"]["cells"].get<long>());
        ASSERT_TRUE(std::regex_search(text, volume, std::regex(R"(Total volume = ([0-9.eE+-]+))")));
        // The patch table: one line per patch after the "Patch Faces" header,
        // in the order of the boundary file. (checkMesh left-aligns its
        // columns for an all-triangle mesh, right-aligns them otherwise.)
        std::smatch header;
        ASSERT_TRUE(std::regex_search(text, header, std::regex(R"(\n *Patch +Faces +Points)"))) << text;
        const size_t table = static_cast<size_t>(header.position(0)) + 1;
        std::istringstream rows(text.substr(text.find('\n', table) + 1));
        const nlohmann::json& expected_faces = report["openfoam"]["patch_faces"];
        std::vector<std::string> patch_names;
        for (size_t p = 0; p < expected_faces.size(); ++p) {
            std::string name;
            long faces = -1;
            rows >> name >> faces;
            std::string rest;
            std::getline(rows, rest);
            EXPECT_EQ(faces, expected_faces[p].get<long>()) << "patch " << name;
            patch_names.push_back(name);
        }
        // The patches are the wall and the openings, named as in the case file.
        std::vector<std::string> expected_names = {"wall"};
        if (const toml::array* names = expected["openings"]["names"].as_array())
            for (const auto& n : *names) expected_names.push_back(*n.value<std::string>());
        EXPECT_EQ(patch_names, expected_names);
        // OpenFOAM's face non-orthogonality: the run measured it on its
        // cells as checkMesh does (layer prisms included), and the case
        // may bound it.
        std::smatch ortho;
        ASSERT_TRUE(std::regex_search(text, ortho, std::regex(R"(non-orthogonality Max: ([0-9.eE+-]+))"))) << text;
        const double worst = std::stod(ortho[1]);
        ASSERT_TRUE(report["openfoam"]["max_non_orthogonality_deg"].is_number()) << report["openfoam"].dump();
        EXPECT_NEAR(report["openfoam"]["max_non_orthogonality_deg"].get<double>(), worst, 1e-4)
                << "report.json's worst face against checkMesh's";
        if (const auto bound = expected["volume"]["max_non_orthogonality_deg"].value<double>()) {
            EXPECT_LT(worst, *bound) << "checkMesh's worst face non-orthogonality";
        }
        // OpenFOAM's checks as the run made them before writing: the same
        // worst skewness as checkMesh's, and no face it would fail.
        const nlohmann::json& checks = report["openfoam"]["checks"];
        std::smatch skew;
        ASSERT_TRUE(std::regex_search(text, skew, std::regex(R"(Max skewness = ([0-9.eE+-]+))"))) << text;
        EXPECT_NEAR(checks["max_skewness"].get<double>(), std::stod(skew[1]), 1e-4)
            << "report.json's worst skewness against checkMesh's";
        EXPECT_EQ(checks["checkmesh_failures"].get<int64_t>(), 0);
        EXPECT_GT(checks["min_pyramid_height"].get<double>(), 0.0);
        // The smallest interpolation weight, which checkMesh measures with
        // -allGeometry only.
        const std::string all_text = check_mesh("-allGeometry", "checkMesh-allGeometry.log");
        std::smatch weight;
        ASSERT_TRUE(std::regex_search(all_text, weight,
                                      std::regex(R"(Face interpolation weight : minimum: ([0-9.eE+-]+))")))
            << all_text;
        EXPECT_NEAR(checks["min_interpolation_weight"].get<double>(), std::stod(weight[1]), 1e-6)
            << "report.json's smallest interpolation weight against checkMesh's";
        // How many faces or cells checkMesh -allGeometry fails by a check:
        // the count its failure line gives, else 0 where it says the check
        // is OK.
        const auto failed_by = [&](const std::string& failure, const std::string& ok) -> int64_t {
            std::smatch found;
            if (std::regex_search(all_text, found, std::regex(failure + R"( found, number of (?:faces|cells): ([0-9]+))")))
                return std::stoll(found[1]);
            EXPECT_NE(all_text.find(ok), std::string::npos) << all_text;
            return 0;
        };
        // Faces checkMesh -allGeometry fails for their weight (below 0.05):
        // none where mend_light_faces' cap flips and moves mend them, so
        // none but as many as the case allows ([volume] max_light_faces).
        EXPECT_LE(failed_by(R"(Faces with small interpolation weight \(< 0.05\))", "Face interpolation weight check OK."),
                  expected["volume"]["max_light_faces"].value_or(int64_t{0}))
            << "faces of small weight";
        // Cells checkMesh -allGeometry fails for their determinant: where
        // the layers are prisms, a tet cell below 0.002 is joined to a
        // neighbour (PoorTetBounds::min_determinant), so none but as many
        // as the case allows ([volume] max_small_determinant_cells: tets
        // that no star-shaped union with their neighbours takes). The
        // Delaunay layers' tets are cells as they are.
        if (report["volume"]["layers_built"] == "prisms") {
            EXPECT_LE(failed_by(R"(Cells with small determinant \(< 0.001\))", "Cell determinant check OK."),
                      expected["volume"]["max_small_determinant_cells"].value_or(int64_t{0}))
                << "cells of small determinant";
        }
        // checkMesh works in metres, the report in mm.
        EXPECT_NEAR(std::stod(volume[1]) * 1e9, report["volume"]["volume_mm3"].get<double>(),
                    1e-6 * report["volume"]["volume_mm3"].get<double>());
    }
    if (const toml::table* volume = expected["volume"].as_table()) {
        const nlohmann::json& v = report["volume"];
        ASSERT_TRUE(v.is_object()) << "no volume mesh in the report";
        for (const auto& [key, value] : *volume) {
            const std::string k(key.str());
            if (k == "boundary_matches_surface") EXPECT_EQ(v["boundary_matches_surface"].get<bool>(), *value.value<bool>());
            else if (k == "volume_vs_surface")
                EXPECT_LE(std::abs(v["volume_mm3"].get<double>() / v["enclosed_volume_mm3"].get<double>() - 1.0),
                          *value.value<double>());
            // The cell floors, on the cells the run judges them on: every tet,
            // or with prism layers written as prism cells the tets written as
            // cells of their own (a layer prism's three tets are as flat as
            // the layer is thin; the solver sees the prism).
            else if (k == "min_aspect_ratio" || k == "max_fraction_below_0_1") {
                const nlohmann::json& foam = report.contains("openfoam") ? report["openfoam"] : nlohmann::json();
                const bool cells = foam.is_object() && foam["tet_cells_min_aspect_ratio"].is_number();
                if (report["parameters"]["layers"] == "prisms") {
                    EXPECT_TRUE(cells) << "prism layers written as cells: the floors are the tet cells'";
                }
                if (k == "min_aspect_ratio")
                    EXPECT_GE(cells ? foam["tet_cells_min_aspect_ratio"].get<double>()
                                    : v["quality_after_sliver_removal"]["min_aspect_ratio"].get<double>(),
                              *value.value<double>());
                else
                    EXPECT_LE(cells ? foam["tet_cells_fraction_below_0_1"].get<double>()
                                    : v["quality_after_sliver_removal"]["fraction_below_0_1"].get<double>(),
                              *value.value<double>());
            }
            else if (k == "min_layer_coverage") {
                // Wall nodes with D >= L_min that keep all floor(M/2) layers.
                const nlohmann::json& layers = report["layers"];
                EXPECT_GT(layers["eligible_wall_nodes"].get<int64_t>(), 0);
                EXPECT_GE(layers["coverage"].get<double>(), *value.value<double>()) << layers.dump();
                EXPECT_EQ(layers["coverage"].get<double>(),
                          layers["eligible_with_all_layers"].get<double>() / layers["eligible_wall_nodes"].get<double>());
            } else if (k == "max_small_determinant_cells" || k == "max_light_faces") {
                ASSERT_TRUE(report.contains("openfoam")) << "bounded with checkMesh, which needs the OpenFOAM case";
            } else if (k == "max_non_orthogonality_deg") {
                ASSERT_TRUE(report.contains("openfoam")) << "bounded with checkMesh, which needs the OpenFOAM case";
            } else if (k == "min_intact_prism_share") {
                // The layer prisms written as one cell each, over wall faces
                // times floor(M/2) layers.
                ASSERT_TRUE(report.contains("openfoam")) << "the share is of the OpenFOAM cells";
                const nlohmann::json& foam = report["openfoam"];
                const nlohmann::json& patches = foam["patch_faces"];
                const size_t caps = report.contains("openings") ? report["openings"].size() : 0;
                int64_t wall_faces = 0;
                for (size_t p = 0; p < patches.size(); ++p)
                    if (p == 0 || p > caps) wall_faces += patches[p].get<int64_t>();
                const double share = foam["layer_prisms"].get<double>() /
                                     (static_cast<double>(wall_faces) * report["layers"]["layermaking"].get<double>());
                EXPECT_DOUBLE_EQ(foam["intact_prism_share"].get<double>(), share);
                EXPECT_GE(share, *value.value<double>());
            } else if (k == "anisotropy_median") {
                const auto [lo, hi] = bounds(value);
                const double a = v["first_layer_anisotropy_median"].get<double>();
                EXPECT_GE(a, lo);
                EXPECT_LE(a, hi);
            }
            else ADD_FAILURE() << "unknown key [volume] " << k << " in expected.toml";
        }
        // The stage's own timers: each part measured, none negative, and
        // together no more than the stage (the rest is bookkeeping).
        const nlohmann::json& seconds = v["seconds"];
        double parts = 0;
        for (const char* part : {"points", "insertion", "removal", "flips", "slivers", "quality", "checks"}) {
            ASSERT_TRUE(seconds.contains(part)) << "no volume time for " << part;
            EXPECT_GE(seconds[part].get<double>(), 0.0) << part;
            parts += seconds[part].get<double>();
        }
        EXPECT_LE(parts, seconds["total"].get<double>() * (1 + 1e-9));
    }
    if (const toml::table* openings = expected["openings"].as_table()) {
        ASSERT_TRUE(report.contains("openings")) << "no openings in the report";
        const nlohmann::json& caps = report["openings"];
        for (const auto& [key, value] : *openings) {
            const std::string k(key.str());
            if (k == "names") {
                std::vector<std::string> names;
                for (const auto& cap : caps) names.push_back(cap["name"].get<std::string>());
                std::vector<std::string> want;
                for (const auto& n : *value.as_array()) want.push_back(*n.value<std::string>());
                EXPECT_EQ(names, want);
            } else if (k == "plane_tolerance") {
                // Every cap vertex on its plane, relative to the cap's size.
                for (const auto& cap : caps) {
                    const double size = std::sqrt(cap["rim_area_mm2"].get<double>());
                    EXPECT_LE(cap["max_distance_from_plane_mm"].get<double>(), *value.value<double>() * size) << cap["name"];
                    EXPECT_LE(cap["mesh_max_distance_from_plane_mm"].get<double>(), *value.value<double>() * size)
                        << cap["name"];
                }
            } else if (k == "area_tolerance") {
                // The volume mesh's faces on the patch cover exactly what the rim encloses.
                for (const auto& cap : caps) {
                    const double rim = cap["rim_area_mm2"].get<double>();
                    EXPECT_GT(cap["mesh_faces"].get<int64_t>(), 0) << cap["name"];
                    EXPECT_NEAR(cap["mesh_area_mm2"].get<double>(), rim, *value.value<double>() * rim) << cap["name"];
                }
            } else if (k == "closed_regions_dropped") {
                // Separate regions no opening reaches are left out of the mesh.
                EXPECT_EQ(report["closed_regions_dropped"]["count"].get<int64_t>(), *value.value<int64_t>());
                EXPECT_EQ(report["opened_surface"]["components"].get<int64_t>(),
                          report["surface"]["components"].get<int64_t>() - *value.value<int64_t>());
            } else ADD_FAILURE() << "unknown key [openings] " << k << " in expected.toml";
        }
        EXPECT_TRUE(std::filesystem::exists(dir / "0" / "U"));
        EXPECT_TRUE(std::filesystem::exists(dir / "0" / "p"));
    }
    if (const toml::table* sizing = expected["sizing"].as_table()) {
        const nlohmann::json& s = report["sizing"];
        for (const auto& [key, value] : *sizing) {
            const std::string k(key.str());
            if (k == "D_median_mm" || k == "d_min_mm" || k == "D_out_min_mm") {
                const auto [lo, hi] = bounds(value);
                const double v = k == "D_median_mm" ? s["D_mm"]["median"].get<double>()
                                 : k == "d_min_mm"   ? s["d_mm"]["min"].get<double>()
                                                     : s["D_out_mm"]["min"].get<double>();
                EXPECT_GE(v, lo) << k;
                EXPECT_LE(v, hi) << k;
            } else if (k == "D_out_infinite") {
                EXPECT_EQ(s["D_out_mm"]["infinite"].get<int64_t>(), s["D_out_mm"]["count"].get<int64_t>()) << k;
            } else ADD_FAILURE() << "unknown key [sizing] " << k << " in expected.toml";
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Cases, SampleCase, ::testing::ValuesIn(case_names()),
                         [](const auto& info) { return info.param; });

// cases/tube run at another M, without its surface outputs, `output`
// added to its [output] table and `volume` to its [volume] table (with
// --strict: its floors must hold); its report.json. A null report after a
// failure the test has recorded.
nlohmann::json run_tube_at(int M, const std::string& output, const std::string& volume)
{
    const TempDir tmp;
    const std::filesystem::path dir = tmp.path / "tube";
    std::filesystem::create_directories(dir);
    std::ifstream in("cases/tube/scalemesh.toml");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::string at_M = std::regex_replace(text, std::regex(R"((^|\n)M = 7 )"), "$1M = " + std::to_string(M) + " ");
    if (at_M == text) {
        ADD_FAILURE() << "no M = 7 line in cases/tube/scalemesh.toml";
        return {};
    }
    at_M = std::regex_replace(at_M, std::regex(R"((^|\n)surface = \[[^\]]*\])"), "$1surface = []\n" + output);
    const std::string with_volume = std::regex_replace(at_M, std::regex(R"((^|\n)\[volume\]\n)"), "$1[volume]\n" + volume);
    if (!volume.empty() && with_volume == at_M) {
        ADD_FAILURE() << "no [volume] table in cases/tube/scalemesh.toml";
        return {};
    }
    std::ofstream(dir / "scalemesh.toml") << with_volume;
    const CommandResult r = run_scalemesh({"run", dir.string(), "-q", "--strict"});
    if (r.exit_code != 0) {
        ADD_FAILURE() << "M = " << M << ": exit code " << r.exit_code << "\n" << r.err;
        return {};
    }
    std::ifstream report_in(dir / "report.json");
    return nlohmann::json::parse(report_in);
}

// The tube at M = 20 with the paper's layers has a face whose two tets are
// all surface nodes, beyond 70 degrees after the flips and moves (70.14): the
// non-orthogonality pass's last resort splits an interior edge of one of
// them by a free point, and no face is left beyond the 70 degrees checkMesh
// counts as severe.
TEST(FinerSampleCase, TubeAtM20KeepsEveryFaceBelowSevereNonOrthogonality)
{
    const nlohmann::json report = run_tube_at(20, "openfoam = false\n", "layers = \"delaunay\"\n");
    ASSERT_FALSE(report.is_null());
    EXPECT_EQ(report["volume"]["layers_built"], "delaunay");
    EXPECT_LT(report["volume"]["max_non_orthogonality_deg"].get<double>(), 70.0);
    EXPECT_TRUE(report["warnings"].empty()) << report["warnings"].dump();
    EXPECT_GE(report["volume"]["quality_after_sliver_removal"]["min_dihedral_deg"].get<double>(), 10.0);
}

// The tube at M = 14 with the default prism layers. Its rims once kept a
// short edge (0.37 mm beside 1.2 mm ones: a rim merge must end on an input
// point and keep its chord near the curve); the layer columns of its two
// nodes ran across the cap 0.14 mm apart, and the cap's fill made a needle
// tet on them (6.6 degrees) that gave the prism layers up. The remeshing's
// rim relaxation evens each rim along the input's.
TEST(FinerSampleCase, TubeAtM14KeepsItsPrismLayers)
{
    const nlohmann::json report = run_tube_at(14, "", "");
    ASSERT_FALSE(report.is_null());
    EXPECT_EQ(report["volume"]["layers_built"], "prisms") << report["warnings"].dump();
    EXPECT_TRUE(report["warnings"].empty()) << report["warnings"].dump();
    EXPECT_GE(report["openfoam"]["intact_prism_share"].get<double>(), 0.95);
    EXPECT_GE(report["openfoam"]["tet_cells_min_dihedral_deg"].get<double>(), 10.0);
}

} // namespace
} // namespace scalemesh
