// What the user sees: the progress lines and summary of `scalemesh run` when
// stderr is not a terminal, -q and -v, the quality.png histograms, and
// surface files of every format through the command line.

#include "cli_support.h"
#include "core/errors.h"
#include "core/surface_mesh.h"
#include "exporters/histogram_png.h"
#include "importers/stl_importer.h"
#include "../importers/surface_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <png.h>

#include <array>
#include <cstring>
#include <fstream>
#include <numbers>
#include <regex>
#include <sstream>

#include <sys/wait.h>
#include <unistd.h>

namespace scalemesh {
namespace {

using namespace scalemesh::test;

const std::vector<std::string> kStages = {"import", "isosurface", "smoothing", "sizing", "remeshing", "volume"};

std::filesystem::path small_case(const TempDir& tmp, const std::string& extra = "")
{
    const auto dir = tmp.path / "ball";
    std::filesystem::create_directories(dir);
    write_text(dir / "scalemesh.toml", "[input]\nphantom = \"sphere\"\nvoxel_size = 1.0\n" + extra);
    return dir;
}

nlohmann::json report_of(const std::filesystem::path& dir)
{
    std::ifstream in(dir / "report.json");
    return nlohmann::json::parse(in);
}

std::vector<std::string> lines_of(const std::string& text)
{
    std::vector<std::string> lines;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    return lines;
}

struct Png {
    int width = 0, height = 0;
    std::vector<uint8_t> rgb;
    std::array<uint8_t, 3> at(int x, int y) const
    {
        const size_t i = 3 * (size_t(y) * width + x);
        return {rgb[i], rgb[i + 1], rgb[i + 2]};
    }
};

Png decode_png(const std::filesystem::path& path)
{
    png_image image;
    std::memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&image, path.c_str()))
        throw std::runtime_error(path.string() + " does not decode as PNG: " + image.message);
    image.format = PNG_FORMAT_RGB;
    Png png;
    png.width = static_cast<int>(image.width);
    png.height = static_cast<int>(image.height);
    png.rgb.resize(PNG_IMAGE_SIZE(image));
    if (!png_image_finish_read(&image, nullptr, png.rgb.data(), 0, nullptr))
        throw std::runtime_error(path.string() + " does not decode as PNG: " + image.message);
    return png;
}

// The bar colours of histogram_png.cpp, one per series in order.
const std::array<std::array<uint8_t, 3>, 3> kBarColours{{{170, 170, 170}, {67, 138, 209}, {214, 96, 33}}};

TEST(CliOutput, RunPrintsALinePerStageAndASummaryWhenNotATerminal)
{
    const TempDir tmp;
    const auto dir = small_case(tmp);
    const CommandResult r = run_scalemesh({"run", dir.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    // stderr is a file here: whole lines only, no bar drawn in place.
    EXPECT_EQ(r.err.find('\r'), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find('\x1b'), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find(" ...\n"), std::string::npos) << "stage starts only with -v: " << r.err;

    const nlohmann::json report = report_of(dir);
    const std::vector<std::string> lines = lines_of(r.err);
    for (const std::string& stage : kStages) {
        const std::regex line("scalemesh: " + stage + " +[0-9]+\\.[0-9]{2} s  \\S.*");
        EXPECT_EQ(std::count_if(lines.begin(), lines.end(), [&](const std::string& l) { return std::regex_match(l, line); }), 1)
            << "one line for " << stage << ":\n" << r.err;
    }
    // Every line is a stage line or part of the summary that follows them.
    for (const std::string& l : lines)
        EXPECT_TRUE(l.rfind("scalemesh: ", 0) == 0 || l.rfind("  ", 0) == 0) << "unexpected line '" << l << "'";

    std::smatch m;
    ASSERT_TRUE(std::regex_search(r.err, m, std::regex("\nscalemesh: done in [0-9.]+ s\n"))) << r.err;
    ASSERT_TRUE(std::regex_search(
        r.err, m,
        std::regex("\n  cells +([0-9]+) tetrahedra, ([0-9]+) points; OpenFOAM: ([0-9]+) cells, ([0-9]+) of them layer "
                   "prisms \\(([0-9.]+)% of wall faces x layers intact\\)\n")))
        << r.err;
    EXPECT_EQ(std::stol(m[1]), report["volume"]["tets"].get<long>());
    EXPECT_EQ(std::stol(m[2]), report["volume"]["points"].get<long>());
    EXPECT_EQ(std::stol(m[3]), report["openfoam"]["cells"].get<long>());
    EXPECT_EQ(std::stol(m[4]), report["openfoam"]["layer_prisms"].get<long>());
    // Each prism is three tets in one cell; a tet joined to neighbouring
    // cells (at most 7 tets to a cell) is no cell of its own, and a prism
    // it joined no longer a prism cell.
    const long joined = report["openfoam"]["absorbed_tets"].get<long>();
    const long by_prisms = std::stol(m[1]) - 2 * std::stol(m[4]);
    if (joined == 0) EXPECT_EQ(std::stol(m[3]), by_prisms);
    EXPECT_LE(std::stol(m[3]), by_prisms - joined);
    EXPECT_GE(std::stol(m[3]), by_prisms - 6 * joined);
    EXPECT_GT(std::stol(m[4]), 0);
    EXPECT_NEAR(std::stod(m[5]), 100 * report["openfoam"]["intact_prism_share"].get<double>(), 0.05);
    ASSERT_TRUE(std::regex_search(
        r.err, m, std::regex("\n  layers +([0-9]+) of ([0-9]+) wall nodes with D >= L_min keep all 3 layers [^;\n]*(?:; ([0-9]+) opening nodes)?")))
        << r.err;
    EXPECT_EQ(std::stol(m[1]), report["layers"]["eligible_with_all_layers"].get<long>());
    EXPECT_EQ(std::stol(m[2]), report["layers"]["eligible_wall_nodes"].get<long>());
    EXPECT_EQ(m[3].matched ? std::stol(m[3]) : 0L, report["layers"]["opening_nodes"].get<long>());
    ASSERT_TRUE(std::regex_search(r.err, m, std::regex("\n  quality +worst aspect ratio ([0-9.]+),"))) << r.err;
    // The cells the floors judge: with prism layers written as prism cells
    // the tets written as cells of their own.
    const nlohmann::json& tet_cells = report["openfoam"]["tet_cells_min_aspect_ratio"];
    EXPECT_NEAR(std::stod(m[1]),
                tet_cells.is_number() ? tet_cells.get<double>()
                                      : report["volume"]["quality_after_sliver_removal"]["min_aspect_ratio"].get<double>(),
                5e-5);
    ASSERT_TRUE(std::regex_search(r.err, m, std::regex("\n  time +(.*)\n"))) << r.err;
    for (const auto& stage : report["stages"])
        EXPECT_NE(m[1].str().find(stage["stage"].get<std::string>() + " "), std::string::npos) << m[1];
    ASSERT_TRUE(std::regex_search(r.err, m, std::regex("\n  wrote +(.*) \\(in .*\\)\n"))) << r.err;
    std::vector<std::string> listed;
    std::istringstream words(m[1].str());
    for (std::string w; words >> w;) listed.push_back(w);
    // report.json lists the files written before it; the summary adds it.
    std::vector<std::string> files = report["files"].get<std::vector<std::string>>();
    files.push_back("report.json");
    EXPECT_EQ(listed, files);
}

TEST(CliOutput, QuietPrintsOnlyErrors)
{
    const TempDir tmp;
    const auto dir = small_case(tmp);
    CommandResult r = run_scalemesh({"run", dir.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err, "");
    write_text(dir / "scalemesh.toml", "[input]\nphantom = \"sphere\"\nvoxel_sise = 1.0\n");
    r = run_scalemesh({"-q", "run", dir.string()});
    EXPECT_EQ(r.exit_code, 2);
    ASSERT_EQ(lines_of(r.err).size(), 1u) << r.err;
    EXPECT_EQ(r.err.rfind("scalemesh: error: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find("voxel_sise"), std::string::npos) << r.err;
}

TEST(CliOutput, VerbosePrintsStageStartsAndDetails)
{
    const TempDir tmp;
    const auto dir = small_case(tmp);
    const CommandResult r = run_scalemesh({"run", dir.string(), "-v"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    for (const std::string& stage : kStages) {
        const size_t start = r.err.find("scalemesh: " + stage + " ...\n");
        const size_t end = r.err.find("scalemesh: " + stage + " ", start + 1);
        ASSERT_NE(start, std::string::npos) << stage << ":\n" << r.err;
        EXPECT_NE(end, std::string::npos) << "the stage's line follows its start: " << stage;
    }
    for (const std::string detail : {"before flips", "after flips", "after sliver removal", "flips 3-2", "sizing    K 4.2"})
        EXPECT_NE(r.err.find(detail), std::string::npos) << detail << ":\n" << r.err;
    // Normal output has none of these.
    const CommandResult normal = run_scalemesh({"run", dir.string()});
    EXPECT_EQ(normal.err.find("before flips"), std::string::npos) << normal.err;
}

TEST(CliOutput, RunWritesTheQualityHistogramsAsAPng)
{
    const TempDir tmp;
    const auto dir = small_case(tmp);
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q"}).exit_code, 0);
    const auto files = report_of(dir)["files"].get<std::vector<std::string>>();
    EXPECT_NE(std::find(files.begin(), files.end(), "quality.png"), files.end());
    // The remeshed edges against their target (short of it on this small,
    // curved sphere), not the layers field that came last among the
    // surface's fields (whole numbers 0 to 3, -1 at openings).
    const nlohmann::json ratio = report_of(dir)["remeshing"]["edge_length_ratio"];
    EXPECT_GT(ratio["min"].get<double>(), 0.0) << ratio;
    EXPECT_LT(ratio["max"].get<double>(), 2.0) << ratio;
    EXPECT_NE(ratio["median"].get<double>(), std::round(ratio["median"].get<double>())) << ratio;
    const Png png = decode_png(dir / "quality.png");
    EXPECT_EQ(png.width, 900);
    EXPECT_EQ(png.height, 540);
    std::array<int64_t, 3> bar_pixels{};
    int64_t drawn = 0;
    for (int y = 0; y < png.height; ++y)
        for (int x = 0; x < png.width; ++x) {
            const auto c = png.at(x, y);
            drawn += c != std::array<uint8_t, 3>{255, 255, 255};
            for (size_t s = 0; s < 3; ++s) bar_pixels[s] += c == kBarColours[s];
        }
    EXPECT_GT(drawn, png.width * png.height / 50) << "axes, labels and bars";
    // Beyond the legend's 14 x 14 swatch, every series has bars.
    for (size_t s = 0; s < 3; ++s) EXPECT_GT(bar_pixels[s], 14 * 14 + 100) << "series " << s;
}

TEST(CliOutput, HistogramPngPutsEachCountInItsBin)
{
    const TempDir tmp;
    std::vector<int64_t> one_bin(20, 0);
    one_bin[10] = 1000; // aspect ratio in [0.5, 0.55)
    write_histogram_png({{"only", one_bin}}, tmp.path / "h.png");
    const Png png = decode_png(tmp.path / "h.png");
    int lo = png.width, hi = -1;
    for (int y = 100; y < png.height; ++y) // below the legend
        for (int x = 0; x < png.width; ++x)
            if (png.at(x, y) == kBarColours[0]) lo = std::min(lo, x), hi = std::max(hi, x);
    ASSERT_GE(hi, lo) << "a bar is drawn";
    // The plot spans x = 100 .. 870 for aspect ratio 0 .. 1.
    EXPECT_GT((lo - 100) / 770.0, 0.5);
    EXPECT_LT((hi - 100) / 770.0, 0.55);
    EXPECT_THROW(write_histogram_png({{"a", one_bin}, {"b", {1, 2}}}, tmp.path / "x.png"), InputError);
    EXPECT_THROW(write_histogram_png({}, tmp.path / "x.png"), InputError);
    EXPECT_THROW(write_histogram_png({{"a", one_bin}}, tmp.path / "missing" / "x.png"), IoError);
}

TEST(CliOutput, ReadsSurfaceFilesOfEveryFormatInTheirUnits)
{
    const TempDir tmp;
    const PolyMesh ball = icosphere(3, 0.01); // 10 mm radius, in metres
    const std::vector<std::pair<std::string, std::string>> files = {
        {"ball.ply", ply_text(ball, PlyFormat::BinaryLittle)},
        {"ball.obj", obj_text(ball)},
        {"ball.vtp", vtp_text(ball, VtpFormat::Binary32)},
        {"ball.msh", msh_text(ball)},
    };
    for (const auto& [name, text] : files) {
        write_text(tmp.path / name, text);
        const auto out = tmp.path / (name + ".stl");
        const CommandResult r = run_scalemesh({"surface", (tmp.path / name).string(), "--units", "m", "-o", out.string(), "-q"});
        ASSERT_EQ(r.exit_code, 0) << name << ": " << r.err;
        const SurfaceMesh mesh = read_stl(out);
        EXPECT_EQ(mesh.triangles.size(), 1280u) << name;
        Vec3 lo, hi;
        bounding_box(mesh, lo, hi);
        for (int k = 0; k < 3; ++k) {
            EXPECT_NEAR(lo[k], -10.0, 1e-5) << name;
            EXPECT_NEAR(hi[k], 10.0, 1e-5) << name;
        }
    }
}

TEST(CliOutput, RunsACaseFromASurfaceInCentimetres)
{
    const TempDir tmp;
    const auto dir = tmp.path / "ball";
    std::filesystem::create_directories(dir);
    write_text(dir / "ball.ply", ply_text(icosphere(3, 1.0), PlyFormat::Ascii)); // 1 cm radius
    write_text(dir / "scalemesh.toml", "[input]\nfile = \"ball.ply\"\nunits = \"cm\"\n");
    const CommandResult r = run_scalemesh({"run", dir.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json report = report_of(dir);
    EXPECT_EQ(report["isosurface"]["triangles"].get<int>(), 1280);
    // The icosphere's volume in mm^3, slightly under the ball's 4/3 pi 10^3.
    const double volume = report["isosurface"]["enclosed_volume_mm3"].get<double>();
    EXPECT_GT(volume, 0.97 * 4.0 / 3.0 * std::numbers::pi * 1000.0);
    EXPECT_LT(volume, 4.0 / 3.0 * std::numbers::pi * 1000.0);
    EXPECT_TRUE(report["volume"]["boundary_matches_surface"].get<bool>());
}

TEST(CliOutput, RefusesOpenSurfacesAndBadUnits)
{
    const TempDir tmp;
    PolyMesh open = icosphere(1, 10.0);
    open.faces.pop_back();
    write_text(tmp.path / "open.obj", obj_text(open));
    const auto out = (tmp.path / "out.stl").string();
    CommandResult r = run_scalemesh({"surface", (tmp.path / "open.obj").string(), "-o", out});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("has 1 hole of fewer than 6 edges, too small to be open ends"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(out));

    write_text(tmp.path / "ball.ply", ply_text(icosphere(1, 10.0), PlyFormat::Ascii));
    r = run_scalemesh({"surface", (tmp.path / "ball.ply").string(), "--units", "inch", "-o", out});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("units = \"inch\" is not a unit"), std::string::npos) << r.err;

    const auto dir = small_case(tmp, "units = \"m\"\n");
    r = run_scalemesh({"run", dir.string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("units applies to surface files"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "report.json"));
}

// A run owns what it writes: an earlier run's outputs that a successful run
// did not write are removed, and said so; a failed run leaves everything; the
// unfinished outputs of a killed run go, those of a live run stay.
TEST(CliOutput, ARunRemovesWhatAnEarlierRunWroteAndItDidNot)
{
    const TempDir tmp;
    const auto dir = small_case(tmp);
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q"}).exit_code, 0);
    for (const char* name : {"constant/polyMesh/faces", "constant/transportProperties", "system/controlDict", "Allrun"})
        ASSERT_TRUE(std::filesystem::exists(dir / name)) << name;
    write_text(dir / "notes.txt", "the user's own file\n");
    // A process that has ended: its pid names no live process.
    const pid_t child = fork();
    if (child == 0) _exit(0);
    ASSERT_GT(child, 0);
    waitpid(child, nullptr, 0);
    const auto dead = dir / ("mesh.partial-" + std::to_string(child) + ".msh");
    const auto alive = dir / ("surface.partial-" + std::to_string(getpid()) + ".msh");
    write_text(dead, "unfinished\n");
    write_text(alive, "unfinished\n");

    // A failed run changes nothing.
    write_text(dir / "scalemesh.toml", "[input]\nphantom = \"sphere\"\nvoxel_size = 1.0\n[output]\nopenfoam = 3\n");
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q"}).exit_code, 2);
    EXPECT_TRUE(std::filesystem::exists(dir / "constant/polyMesh/faces"));
    EXPECT_TRUE(std::filesystem::exists(dir / "Allrun"));

    write_text(dir / "scalemesh.toml", "[input]\nphantom = \"sphere\"\nvoxel_size = 1.0\n[output]\nopenfoam = false\n");
    const CommandResult r = run_scalemesh({"run", dir.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::vector<std::string> stale = {"constant/polyMesh", "constant/transportProperties",
                                            "constant/turbulenceProperties", "system", "Allrun"};
    for (const std::string& name : stale) EXPECT_FALSE(std::filesystem::exists(dir / name)) << name;
    EXPECT_FALSE(std::filesystem::exists(dir / "constant")) << "left empty, so removed too";
    EXPECT_TRUE(std::filesystem::exists(alive));
    EXPECT_FALSE(std::filesystem::exists(dead));
    EXPECT_TRUE(std::filesystem::exists(dir / "notes.txt"));
    EXPECT_TRUE(std::filesystem::exists(dir / "mesh.msh"));
    const nlohmann::json report = report_of(dir);
    EXPECT_EQ(report["removed"].get<std::vector<std::string>>(), stale);
    EXPECT_EQ(report["removed_partial_files"], 1);
    EXPECT_NE(r.err.find("\n  removed   5 earlier outputs this run did not write: constant/polyMesh "
                         "constant/transportProperties constant/turbulenceProperties system Allrun\n"),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("\n  removed   1 unfinished outputs of runs that were killed\n"), std::string::npos) << r.err;

    // The next run has nothing more to remove.
    ASSERT_EQ(run_scalemesh({"run", dir.string(), "-q"}).exit_code, 0);
    EXPECT_EQ(report_of(dir)["removed"].size(), 0u);
}

TEST(CliOutput, RefusesTwoOutputsOfOneName)
{
    const TempDir tmp;
    auto dir = small_case(tmp, "[output]\nsurface = [\"mesh.msh\"]\n");
    CommandResult r = run_scalemesh({"run", dir.string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("names \"mesh.msh\", already named in [output] "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("give each output its own file name"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "report.json"));

    write_text(dir / "scalemesh.toml",
               "[input]\nphantom = \"sphere\"\nvoxel_size = 1.0\n[output]\nsurface = [\"a.vtk\", \"a.vtk\"]\n");
    r = run_scalemesh({"run", dir.string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("names \"a.vtk\", already named in [output] surface"), std::string::npos) << r.err;
}

} // namespace
} // namespace scalemesh
