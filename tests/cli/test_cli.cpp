// The command line: outputs appear complete, and bad input gets one line on
// stderr, a non-zero exit and no output file.

#include "cli_support.h"
#include "core/surface_mesh.h"
#include "importers/stl_importer.h"
#include "importers/vdb_importer.h"
#include "reliability/hostile_support.h"
#include "scalemesh/mesh.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <toml++/toml.h>

#include <fstream>
#include <set>
#include <sstream>

namespace scalemesh {
namespace {

int line_count(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

int error_lines(const std::string& s)
{
    int n = 0;
    for (size_t at = s.find("error"); at != std::string::npos; at = s.find("error", s.find('\n', at))) ++n;
    return n;
}

void expect_refused(const CommandResult& r, int code, const std::string& mentions)
{
    EXPECT_EQ(r.exit_code, code) << r.err;
    // Progress lines of the stages that ran may come first; the error is one
    // line, the last.
    EXPECT_EQ(error_lines(r.err), 1) << "one error line on stderr: " << r.err;
    const size_t last = r.err.rfind('\n', r.err.size() - 2);
    const std::string last_line = r.err.substr(last == std::string::npos ? 0 : last + 1);
    EXPECT_EQ(last_line.rfind("scalemesh: error: ", 0), 0u) << r.err;
    EXPECT_NE(last_line.find(mentions), std::string::npos) << r.err;
}

TEST(Cli, PhantomThenSurfaceInEveryFormat)
{
    const TempDir tmp;
    const std::string vdb = (tmp.path / "torus.vdb").string();
    ASSERT_EQ(run_scalemesh({"phantom", "torus", "-o", vdb, "--voxel-size", "0.5"}).exit_code, 0);
    const auto grid = read_vdb(vdb);
    EXPECT_DOUBLE_EQ(grid->voxelSize().x(), 0.5);
    EXPECT_EQ(grid->getName(), "label");
    for (const std::string ext : {".stl", ".msh", ".vtk"}) {
        const std::string out = (tmp.path / ("torus" + ext)).string();
        const CommandResult r = run_scalemesh({"surface", vdb, "-o", out, "-q"});
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_TRUE(std::filesystem::file_size(out) > 0);
    }
    const SurfaceMesh mesh = read_stl(tmp.path / "torus.stl");
    const SurfaceFacts facts = surface_facts(mesh);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_EQ(facts.euler_characteristic, 0);
    // Nothing but the outputs: no temporary files left over.
    EXPECT_EQ(tmp.files(), (std::vector<std::string>{"torus.msh", "torus.stl", "torus.vdb", "torus.vtk"}));
}

TEST(Cli, SurfaceWithSizingWritesTheFields)
{
    const TempDir tmp;
    const std::string vdb = (tmp.path / "sphere.vdb").string();
    ASSERT_EQ(run_scalemesh({"phantom", "sphere", "-o", vdb}).exit_code, 0);
    const std::string out = (tmp.path / "sphere.vtk").string();
    const CommandResult r = run_scalemesh({"surface", vdb, "--sizing", "-o", out});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("sizing"), std::string::npos) << "a progress line per stage: " << r.err;
    std::ifstream in(out);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (const std::string field : {"SCALARS D double", "SCALARS D_out double", "SCALARS d double"})
        EXPECT_NE(text.find(field), std::string::npos) << field;
}

TEST(Cli, SurfaceRemeshWritesTheRemeshedSurfaceWithItsViews)
{
    const TempDir tmp;
    const std::string vdb = (tmp.path / "torus.vdb").string(), out = (tmp.path / "torus.msh").string();
    ASSERT_EQ(run_scalemesh({"phantom", "torus", "-o", vdb}).exit_code, 0);
    const CommandResult r = run_scalemesh({"surface", vdb, "--remesh", "-o", out});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("remeshing"), std::string::npos) << r.err;
    std::ifstream in(out);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (const std::string view : {"\"d\"", "\"edge_length_ratio\""}) EXPECT_NE(text.find(view), std::string::npos) << view;
    // The remeshed surface is far coarser than the marching cubes one.
    const std::string raw = (tmp.path / "raw.stl").string(), remeshed = (tmp.path / "remeshed.stl").string();
    ASSERT_EQ(run_scalemesh({"surface", vdb, "-o", raw, "-q"}).exit_code, 0);
    ASSERT_EQ(run_scalemesh({"surface", vdb, "--remesh", "-o", remeshed, "-q"}).exit_code, 0);
    const SurfaceFacts a = surface_facts(read_stl(raw)), b = surface_facts(read_stl(remeshed));
    EXPECT_TRUE(b.closed_manifold());
    EXPECT_EQ(b.euler_characteristic, 0);
    EXPECT_LT(b.triangles * 5, a.triangles);
}

TEST(Cli, SurfaceInputIsOrientedOutwardAndSized)
{
    // The shared aorta surface is closed and genus 0 but wound inwards.
    const TempDir tmp;
    const std::string out = (tmp.path / "aorta.stl").string();
    const CommandResult r = run_scalemesh({"surface", "../shared/data/vmtk_aorta_capped.stl", "--sizing",
                                           "--L-min", "0.5 mm", "--L-max", "40 mm", "-o", out});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("reversed"), std::string::npos) << r.err;
    const SurfaceFacts facts = surface_facts(read_stl(out));
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_EQ(facts.euler_characteristic, 2);
    EXPECT_EQ(facts.triangles, 12932);
    EXPECT_GT(facts.signed_volume, 13000.0);
}

TEST(Cli, CheckReportsTheQualityOfTheMeshARunWrote)
{
    const TempDir tmp;
    std::ofstream(tmp.path / "scalemesh.toml") << "[input]\nphantom = \"torus\"\nvoxel_size = 0.5\n";
    ASSERT_EQ(run_scalemesh({"run", tmp.path.string(), "-q"}).exit_code, 0);
    const std::string out = (tmp.path / "check.txt").string();
    const std::string cmd = "'" + std::string(std::getenv("SCALEMESH_BINARY")) + "' check '" +
                            (tmp.path / "mesh.msh").string() + "' > '" + out + "'";
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    std::ifstream in(out);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("tets with volume <= 0: 0;"), std::string::npos) << text;
    EXPECT_NE(text.find("valid"), std::string::npos) << text;
    EXPECT_EQ(text.find("INVALID"), std::string::npos) << text;
    EXPECT_NE(text.find("aspect ratio histogram"), std::string::npos) << text;
    // A surface mesh is not a volume mesh; a file that is not .msh is refused.
    expect_refused(run_scalemesh({"check", (tmp.path / "surface.msh").string()}), 2, "no tetrahedra");
    expect_refused(run_scalemesh({"check", (tmp.path / "report.json").string()}), 2, ".msh");
    // A damaged .msh that once crashed Gmsh's reader is refused before Gmsh reads it.
    expect_refused(run_scalemesh({"check", "fuzz/regressions/msh/element-node-tag-beyond-int-segfaults-gmsh.msh"}), 2,
                   "is not a valid MSH file");
}

TEST(Cli, RefusesBadPhantomArguments)
{
    const TempDir tmp;
    const std::string out = (tmp.path / "x.vdb").string();
    expect_refused(run_scalemesh({"phantom", "cube", "-o", out}), 2, "sphere, torus");
    expect_refused(run_scalemesh({"phantom", "sphere", "-o", out, "--voxel-size", "-1"}), 2, "voxel size");
    expect_refused(run_scalemesh({"phantom", "sphere", "-o", out, "--voxel-size", "0.001"}), 2, "2048");
    expect_refused(run_scalemesh({"phantom", "sphere", "-o", (tmp.path / "x.stl").string()}), 2, ".vdb");
    EXPECT_TRUE(tmp.files().empty());
}

TEST(Cli, RefusesBadImagesWithoutWritingOutput)
{
    const TempDir tmp;
    const std::string out = (tmp.path / "out.msh").string();
    expect_refused(run_scalemesh({"surface", (tmp.path / "missing.vdb").string(), "-o", out}), 3, "no such file");

    const std::string text = (tmp.path / "text.vdb").string();
    std::ofstream(text) << "not a vdb file\n";
    expect_refused(run_scalemesh({"surface", text, "-o", out}), 2, "not an OpenVDB file");

    const std::string vdb = (tmp.path / "tube.vdb").string();
    ASSERT_EQ(run_scalemesh({"phantom", "tube", "-o", vdb}).exit_code, 0);
    expect_refused(run_scalemesh({"surface", vdb, "--grid", "density", "-o", out}), 2, "'label'");
    expect_refused(run_scalemesh({"surface", vdb, "--iso", "5", "-o", out}), 2, "no voxel is inside");
    expect_refused(run_scalemesh({"surface", vdb, "-o", (tmp.path / "out.obj").string()}), 2, ".msh, .vtk or .stl");

    // A truncated VDB keeps its magic number but not its grids.
    const std::string truncated = (tmp.path / "truncated.vdb").string();
    {
        std::ifstream in(vdb, std::ios::binary);
        std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        std::ofstream(truncated, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    }
    const CommandResult r = run_scalemesh({"surface", truncated, "-o", out});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(error_lines(r.err), 1) << r.err;

    const std::string empty = (tmp.path / "empty.vdb").string();
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("label");
    write_vdb(*grid, empty);
    expect_refused(run_scalemesh({"surface", empty, "-o", out}), 2, "empty");

    EXPECT_FALSE(std::filesystem::exists(out));
    for (const std::string& f : tmp.files()) EXPECT_EQ(f.find("partial"), std::string::npos) << f;
}

TEST(Cli, RefusesBadCaseFilesWithoutWritingOutput)
{
    const TempDir tmp;
    expect_refused(run_scalemesh({"run", (tmp.path / "nowhere").string()}), 3, "no such case directory");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 3, "scalemesh.toml");

    const auto write_case = [&](const std::string& text) { std::ofstream(tmp.path / "scalemesh.toml") << text; };
    write_case("[input]\nphantom = \"tube\"\nvoxel_sise = 0.5\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2, "voxel_sise");
    write_case("[input]\nphantom = \"tube\"\n[sizing]\nL_min = \"2 voxels\"\nL_max = \"1 voxels\"\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2, "L_min");
    write_case("[input]\nphantom = \"tube\"\n[sizing]\nK = -1\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2, "K");
    write_case("[input]\nphantom = \"tube\"\n[meshing]\nK = 1\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2, "meshing");
    write_case("[input]\nphantom = \"tube\"\nvoxel_size = 1e-10\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2, "voxel_size");
    write_case("[input]\nphantom = \"tube\"\n[[openings]]\nname = \"inlet\"\npoint = [0, 0, -12]\nnormal = [0, 0, -1]\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2,
                   "type is missing: opening 'inlet' needs a type. Hint: add type = \"inlet\" or type = \"outlet\"");
    write_case("[input\nphantom = \"tube\"\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2, "scalemesh.toml:1");
    EXPECT_EQ(tmp.files(), std::vector<std::string>{"scalemesh.toml"});

    // A case file that is a directory is named as such.
    const TempDir odd;
    std::filesystem::create_directories(odd.path / "scalemesh.toml");
    expect_refused(run_scalemesh({"run", odd.path.string()}), 3, "scalemesh.toml: is not a file (a directory?)");
}

std::string read_text(const std::filesystem::path& path)
{
    std::ifstream in(path);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// `scalemesh init` writes a case that runs as written: border openings where
// a mask runs off its image, the unit of a surface in metres; it never
// replaces a case file unasked, and a missing input leaves nothing behind.
TEST(Cli, InitWritesACaseThatRunsAsWritten)
{
    const TempDir tmp;
    // A tube of 4 voxels radius along z that runs off the image at both ends,
    // wider where it leaves through z-.
    write_label_mha(tmp.path / "tube.mha", {20, 20, 30}, 0.5, [](int i, int j, int k) {
        return std::hypot(i - 9.5, j - 9.5) < (k < 3 ? 5 : 4);
    });
    const std::filesystem::path image_case = tmp.path / "image_case";
    CommandResult r = run_scalemesh({"init", image_case.string(), (tmp.path / "tube.mha").string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string text = read_text(image_case / "scalemesh.toml");
    EXPECT_NE(text.find("file = \"../tube.mha\""), std::string::npos) << text;
    EXPECT_NE(text.find("name = \"inlet\"\ntype = \"inlet\"\nborder = \"z-\""), std::string::npos) << text;
    EXPECT_NE(text.find("name = \"outlet\"\ntype = \"outlet\"\nborder = \"z+\""), std::string::npos) << text;
    EXPECT_NE(r.err.find("border opening 'inlet' on the image's z- side"), std::string::npos) << r.err;
    // The defaults it lists, commented out, are MeshOptions{}'s.
    const scalemesh::MeshOptions defaults;
    for (const auto& [key, value] : {std::pair{"K", defaults.K}, std::pair{"M", defaults.M}, std::pair{"G", defaults.G}}) {
        const size_t at = text.find(std::string("\n# ") + key + " = ");
        ASSERT_NE(at, std::string::npos) << key << "\n" << text;
        const std::string line = text.substr(at + 3, text.find('\n', at + 1) - at - 3); // "K = 4.2  # ..."
        EXPECT_EQ(toml::parse(line)[key].value<double>(), value) << line;
    }
    r = run_scalemesh({"run", image_case.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json report = nlohmann::json::parse(read_text(image_case / "report.json"));
    ASSERT_EQ(report["openings"].size(), 2u) << report["openings"];
    EXPECT_EQ(report["openings"][0]["name"], "inlet");
    EXPECT_EQ(report["openings"][0]["type"], "inlet");
    EXPECT_EQ(report["openings"][1]["name"], "outlet");
    EXPECT_LT(report["openings"][0]["point_mm"][2].get<double>(), report["openings"][1]["point_mm"][2].get<double>());
    EXPECT_EQ(report["warnings"].dump().find("touches the image"), std::string::npos) << report["warnings"];

    // The case file is not replaced unasked.
    expect_refused(run_scalemesh({"init", image_case.string(), (tmp.path / "tube.mha").string()}), 2,
                   "scalemesh.toml exists already. Hint: give another case directory, or --force");
    EXPECT_EQ(run_scalemesh({"init", image_case.string(), (tmp.path / "tube.mha").string(), "--force", "-q"}).exit_code,
              0);

    // A closed 20 mm cube written in metres: units = "m", and the run has no units warning.
    const double L = 0.02;
    const Vec3 a{0, 0, L}, b{L, 0, L}, c{L, L, L}, d{0, L, L}, e{0, 0, 0}, f{L, 0, 0}, g{L, L, 0}, h{0, L, 0};
    write_stl(tmp.path / "cube.stl", {{a, b, c}, {a, c, d}, {e, g, f}, {e, h, g}, {e, f, b}, {e, b, a},
                                      {f, g, c}, {f, c, b}, {g, h, d}, {g, d, c}, {h, e, a}, {h, a, d}});
    const std::filesystem::path surface_case = tmp.path / "surface_case";
    r = run_scalemesh({"init", surface_case.string(), (tmp.path / "cube.stl").string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(read_text(surface_case / "scalemesh.toml").find("\nunits = \"m\""), std::string::npos)
        << read_text(surface_case / "scalemesh.toml");
    r = run_scalemesh({"run", surface_case.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(read_text(surface_case / "report.json").find("implausible"), std::string::npos);

    // A missing input: refused, and no case directory is made.
    expect_refused(run_scalemesh({"init", (tmp.path / "none").string(), (tmp.path / "missing.mha").string()}), 3,
                   "missing.mha: no such file");
    EXPECT_FALSE(std::filesystem::exists(tmp.path / "none"));
}

// Command-line mistakes end with 2, as bad input does (not CLI11's own 100 and
// up); --help and --version with 0.
TEST(Cli, CommandLineMistakesEndWithTwo)
{
    EXPECT_EQ(run_scalemesh({"run"}).exit_code, 2);                              // a missing argument
    EXPECT_EQ(run_scalemesh({"run", ".", "--threads", "many"}).exit_code, 2);     // a conversion
    EXPECT_EQ(run_scalemesh({"run", ".", "--no-such-flag"}).exit_code, 2);       // an unknown option
    EXPECT_EQ(run_scalemesh({"frobnicate"}).exit_code, 2);                      // an unknown verb
    EXPECT_EQ(run_scalemesh({"--version"}).exit_code, 0);
    EXPECT_EQ(run_scalemesh({"--help"}).exit_code, 0);
}

// Issue 44: `scalemesh options --json` lists the meshing options, as the
// Gmsh GUI client reads them: every one with its fields, a case-file key
// documented under its section of docs/case-file.md.
TEST(Cli, OptionsJsonListsEveryMeshingOption)
{
    const CommandResult r = run_scalemesh({"options", "--json"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json table = nlohmann::json::parse(r.out);
    std::set<std::string> keywords;
    const std::string doc = read_text("docs/case-file.md");
    for (const nlohmann::json& option : table) {
        for (const char* field : {"section", "key", "keyword", "kind", "default", "unit", "doc"})
            EXPECT_TRUE(option.contains(field)) << field << " missing from " << option;
        keywords.insert(option["keyword"].get<std::string>());
        if (option["kind"] == "number" || option["kind"] == "integer") {
            EXPECT_LT(option["min"].get<double>(), option["max"].get<double>()) << option;
        }
        if (option["kind"] == "choice") {
            EXPECT_NE(std::find(option["choices"].begin(), option["choices"].end(), option["default"]),
                      option["choices"].end()) << option;
        }
        const std::string section = option["section"];
        if (section.empty()) continue; // the library's and Python's alone
        const size_t at = doc.find("## [" + section + "]");
        ASSERT_NE(at, std::string::npos) << section;
        const size_t row = doc.find("| `" + option["key"].get<std::string>() + "` |", at);
        ASSERT_LT(row, doc.find("\n## ", at + 1)) << option["key"] << " not documented under [" << section << "]";
        // The row's default column (| `key` | type | default | meaning |)
        // states MeshOptions{}'s value, as the table does.
        std::vector<std::string> cells;
        std::istringstream line(doc.substr(row + 2, doc.find('\n', row) - row - 2));
        for (std::string cell; std::getline(line, cell, '|');) cells.push_back(cell.substr(1, cell.size() - 2));
        ASSERT_GE(cells.size(), 3u) << option["key"];
        const nlohmann::json& value = option["default"];
        if (value.is_string()) {
            EXPECT_EQ(cells[2], "`\"" + value.get<std::string>() + "\"`") << option["key"];
        } else if (value.is_boolean()) {
            EXPECT_EQ(cells[2], value.get<bool>() ? "true" : "false") << option["key"];
        } else if (value.is_number()) {
            EXPECT_EQ(std::stod(cells[2]), value.get<double>()) << option["key"];
        }
    }
    EXPECT_EQ(keywords, (std::set<std::string>{"K", "M", "G", "L_min", "L_max", "curvature", "smoothing_sweeps",
                                               "smoothing_omega", "smoothing_reach", "remesh_cycles", "growth",
                                               "first_layer", "layers", "layer_tolerance", "threads", "max_memory"}));
    const CommandResult text = run_scalemesh({"options"});
    EXPECT_EQ(text.exit_code, 0) << text.err;
    EXPECT_NE(text.out.find("[sizing] K = 4.2"), std::string::npos) << text.out;
}

// The case's floors ([volume] min_layer_coverage, min_aspect_ratio,
// min_dihedral_deg): a mesh that misses one gets a warning line and an entry
// in report.json's warnings; with --strict the run fails with code 6 and
// one error line, its outputs written for inspection.
TEST(Cli, AMissedFloorWarnsAndFailsUnderStrict)
{
    const TempDir tmp;
    // The paper's layers: one floor missed gives one warning (the default
    // prism layers would first be given up for them, a warning of its own).
    const auto write_case = [&](const std::string& volume) {
        std::ofstream(tmp.path / "scalemesh.toml")
            << "[input]\nphantom = \"tube\"\nvoxel_size = 0.5\n[volume]\nlayers = \"delaunay\"\n" << volume;
    };
    const auto warnings = [&] {
        std::ifstream in(tmp.path / "report.json");
        return nlohmann::json::parse(in)["warnings"];
    };
    write_case("min_dihedral_deg = 0\n");
    CommandResult r = run_scalemesh({"run", tmp.path.string(), "--strict"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
    EXPECT_TRUE(warnings().empty());

    write_case("min_dihedral_deg = 60\n"); // no tet mesh of a tube has all its dihedral angles above 60 degrees
    r = run_scalemesh({"run", tmp.path.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("scalemesh: warning: the smallest dihedral angle "), std::string::npos) << r.err;
    ASSERT_EQ(warnings().size(), 1u);
    EXPECT_NE(warnings()[0].get<std::string>().find("min_dihedral_deg"), std::string::npos);
    EXPECT_TRUE(run_scalemesh({"run", tmp.path.string(), "-q"}).err.empty());

    std::filesystem::remove(tmp.path / "mesh.msh");
    r = run_scalemesh({"run", tmp.path.string(), "-q", "--strict"});
    expect_refused(r, 6, "--strict");
    EXPECT_NE(r.err.find("scalemesh: warning: the smallest dihedral angle"), std::string::npos) << r.err;
    EXPECT_TRUE(std::filesystem::exists(tmp.path / "mesh.msh"));

    write_case("first_layer = \"sideways\"\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2, "first_layer");
    write_case("layer_tolerance = 0\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2, "layer_tolerance");
    write_case("min_layer_coverage = 1.5\n");
    expect_refused(run_scalemesh({"run", tmp.path.string()}), 2, "min_layer_coverage");
}

TEST(Cli, AFailedRunLeavesEarlierOutputsUntouched)
{
    const TempDir tmp;
    std::ofstream(tmp.path / "scalemesh.toml")
        << "[input]\nphantom = \"sphere\"\nvoxel_size = 1.0\n[output]\nsurface = [\"surface.msh\"]\n";
    ASSERT_EQ(run_scalemesh({"run", tmp.path.string(), "-q"}).exit_code, 0);
    const auto before = std::filesystem::last_write_time(tmp.path / "surface.msh");
    // The next run's second output cannot be put in place (a directory holds
    // its name): it fails after every stage ran, and must not have replaced
    // the first output either.
    std::filesystem::create_directory(tmp.path / "surface.vtk");
    std::ofstream(tmp.path / "scalemesh.toml")
        << "[input]\nphantom = \"sphere\"\nvoxel_size = 1.0\n[output]\nsurface = [\"surface.msh\", \"surface.vtk\"]\n";
    const auto files = tmp.files();
    const CommandResult r = run_scalemesh({"run", tmp.path.string(), "-q"});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_EQ(line_count(r.err), 1) << r.err;
    EXPECT_EQ(std::filesystem::last_write_time(tmp.path / "surface.msh"), before);
    EXPECT_EQ(tmp.files(), files);
}

// A label image of a tube of 7 voxels' radius along z (20 x 20 x 30 voxels
// of 0.5 mm) in `dir`, and its case file: a border inlet and outlet at its
// ends, cut `inset` in ("": the automatic inset).
void write_border_tube(const std::filesystem::path& dir, const std::string& inset)
{
    write_label_mha(dir / "tube.mha", {20, 20, 30}, 0.5, [](int i, int j, int) {
        return std::hypot(i - 9.5, j - 9.5) < 7;
    });
    const std::string cut = inset.empty() ? "" : "inset = \"" + inset + "\"\n";
    std::ofstream(dir / "scalemesh.toml") << "[input]\nfile = \"tube.mha\"\n[[openings]]\nname = \"inlet\"\ntype = "
                                             "\"inlet\"\nborder = \"z-\"\n"
                                          << cut
                                          << "[[openings]]\nname = \"outlet\"\ntype = \"outlet\"\nborder = \"z+\"\n"
                                          << cut;
}

// The automatic inset of a border opening takes no plane nearer the face
// than 2 voxels (BorderRule::first_plane): 1 voxel in, the smoothed
// surface still rounds over the image face, and the prism columns on the
// rim's flat triangles made a tube of 7 voxels' radius give its prism
// layers up (the test below cuts it there on purpose).
TEST(Cli, TubeWithBorderOpeningsKeepsItsPrismLayers)
{
    const TempDir tmp;
    write_border_tube(tmp.path, "");
    const CommandResult r = run_scalemesh({"run", tmp.path.string(), "--strict"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json report = nlohmann::json::parse(read_text(tmp.path / "report.json"));
    EXPECT_EQ(report["volume"]["layers_built"], "prisms") << report["volume"]["layer_fallback"];
    EXPECT_TRUE(report["warnings"].empty()) << report["warnings"];
    // The inlet's plane 2 voxels inside the surface's lowest point (about
    // 0.1 mm below the image face, which is half a voxel below the first
    // voxel centre at z = 0).
    EXPECT_GT(report["openings"][0]["point_mm"][2].get<double>(), 0.5) << report["openings"][0];
}

// The bifurcation phantom at 0.08 mm voxels with an opening on each branch:
// next to outlet_left, a wall node's column, nearly in the cap's plane and
// longer than the rim's columns (shortened for the cap's last ring), ended
// 0.08 mm over the cap's fill, and the core's tets between them were flat
// (a tet cell of 1.62 degrees): the run gave its prism layers up. A top
// point nearer a core face than LayerStackParams::min_core_clearance of the
// face's longest edge now shortens its columns.
TEST(Cli, FineBifurcationKeepsItsPrismLayersAtItsOpenings)
{
    const TempDir tmp;
    std::ofstream(tmp.path / "scalemesh.toml") << R"([input]
phantom = "bifurcation"
voxel_size = 0.08
[sizing]
L_min = "0.5 voxels"
L_max = "40 voxels"
[[openings]]
name = "inlet"
type = "inlet"
point = [0, 0, -12]
normal = [0, 0, -1]
[[openings]]
name = "outlet_left"
type = "outlet"
point = [-6.0, 0, 10.392]
normal = [-0.5, 0, 0.866]
radius = 3
[[openings]]
name = "outlet_right"
type = "outlet"
point = [6.0, 0, 10.392]
normal = [0.5, 0, 0.866]
radius = 3
[output]
volume = []
surface = []
)";
    const CommandResult r = run_scalemesh({"run", tmp.path.string(), "--strict"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json report = nlohmann::json::parse(read_text(tmp.path / "report.json"));
    EXPECT_EQ(report["volume"]["layers_built"], "prisms") << report["volume"]["layer_fallback"];
    EXPECT_TRUE(report["warnings"].empty()) << report["warnings"];
    EXPECT_GE(report["openfoam"]["intact_prism_share"].get<double>(), 0.95);
}

// Where the prism layers cannot be built, the run builds the paper's
// Delaunay layers instead and says so, rather than failing: a tube of 7
// voxels' radius whose border inlet and outlet are cut 1 voxel in, where
// the smoothed surface still rounds over the image face, so that the prism
// columns on the rim's flat triangles leave slivers (below 1 degree) that
// no union with their neighbours mends. (The automatic inset, from 2 voxels
// in, builds this tube's prisms. Floors made a poor case: the unions of
// poor tets with their neighbours came to meet a dihedral floor of 20 and
// then of any angle; so did other geometry, each case found coming to
// build its prisms as the remeshing and the core improved.)
TEST(Cli, PrismLayersThatCannotBeBuiltGiveWayToTheDelaunayLayers)
{
    const TempDir tmp;
    write_border_tube(tmp.path, "1 voxel");
    const CommandResult r = run_scalemesh({"run", tmp.path.string()});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json report = nlohmann::json::parse(read_text(tmp.path / "report.json"));
    EXPECT_EQ(report["parameters"]["layers"], "prisms");
    EXPECT_EQ(report["volume"]["layers_built"], "delaunay");
    ASSERT_TRUE(report["volume"]["layer_fallback"].is_string());
    EXPECT_NE(report["volume"]["layer_fallback"].get<std::string>().find(
                  "the smallest dihedral angle of a tet cell is"),
              std::string::npos)
        << report["volume"]["layer_fallback"];
    EXPECT_NE(report["warnings"].dump().find("the prism layers were given up"), std::string::npos)
        << report["warnings"];
    EXPECT_NE(r.err.find("the prism layers were given up"), std::string::npos) << r.err;
    // The Delaunay layers' mesh, whole: a closed boundary and the OpenFOAM case.
    EXPECT_TRUE(report["volume"]["boundary_matches_surface"].get<bool>());
    EXPECT_EQ(report["openfoam"]["checks"]["checkmesh_failures"].get<int64_t>(), 0);
    EXPECT_TRUE(report["openfoam"]["tet_cells_min_dihedral_deg"].is_null());
}

// [volume] layers: the explicit prism layers reach OpenFOAM intact (at
// least 95% of wall faces x layers as single prism cells, none of
// checkMesh's failing checks), on a closed torus and on a tube with an
// inlet and an outlet whose caps carry the rim prisms' sides; the paper's
// Delaunay layers on the same torus do not.
TEST(Cli, PrismLayersReachOpenFoamIntactWhereDelaunayLayersDoNot)
{
    const std::string tube_openings = "[[openings]]\nname = \"inlet\"\ntype = \"inlet\"\npoint = [0, 0, -12]\n"
                                      "normal = [0, 0, -1]\n[[openings]]\nname = \"outlet\"\ntype = \"outlet\"\n"
                                      "point = [0, 0, 12]\nnormal = [0, 0, 1]\n";
    struct Run {
        std::string phantom, layers, openings;
    };
    for (const Run& run : {Run{"torus", "prisms", ""}, Run{"tube", "prisms", tube_openings},
                           Run{"torus", "delaunay", ""}}) {
        const TempDir tmp;
        std::ofstream(tmp.path / "scalemesh.toml") << "[input]\nphantom = \"" << run.phantom
                                                   << "\"\nvoxel_size = 0.5\n[volume]\nlayers = \"" << run.layers
                                                   << "\"\n" << run.openings;
        const std::string what = run.phantom + " with " + run.layers;
        const CommandResult result = run_scalemesh({"run", tmp.path.string(), "-q"});
        ASSERT_EQ(result.exit_code, 0) << what << ": " << result.err;
        const nlohmann::json report = nlohmann::json::parse(read_text(tmp.path / "report.json"));
        EXPECT_EQ(report["parameters"]["layers"], run.layers);
        const double share = report["openfoam"]["intact_prism_share"].get<double>();
        EXPECT_EQ(report["openfoam"]["checks"]["checkmesh_failures"].get<int64_t>(), 0) << what;
        EXPECT_EQ(report["volume"]["nonpositive_tets"].get<int64_t>(), 0) << what;
        EXPECT_TRUE(report["volume"]["boundary_matches_surface"].get<bool>()) << what;
        if (run.layers == "prisms") EXPECT_GE(share, 0.95) << what;
        else EXPECT_LT(share, 0.95) << what;
        // The cell floors are judged on the tets written as cells of their
        // own where the layers are built as prisms.
        const auto& tet_cells = report["openfoam"]["tet_cells_min_dihedral_deg"];
        if (run.layers == "prisms") EXPECT_TRUE(tet_cells.is_number()) << what;
        else EXPECT_TRUE(tet_cells.is_null()) << what;
        // Slivers the core leaves against the locked prisms are joined to
        // their neighbours: on the closed torus no tet cell is left below
        // the dihedral floor and no face reaches 70 degrees. The paper's
        // layers join none.
        if (run.layers != "prisms") {
            EXPECT_EQ(report["openfoam"]["absorbed_tets"].get<int64_t>(), 0) << what;
        }
        // What the prism columns hold: every node owed its layers that keeps
        // them at their places has a whole column, and a column is no
        // taller than Algorithm 4 made it but for the slide of its top
        // (layer_tolerance, 0.15 of a layer).
        const auto& volume = report["volume"];
        const int64_t whole = volume["stack_whole_columns"].get<int64_t>();
        if (run.layers == "prisms") {
            EXPECT_GE(whole, report["layers"]["eligible_with_all_layers"].get<int64_t>()) << what;
            EXPECT_LE(whole, report["layers"]["eligible_wall_nodes"].get<int64_t>()) << what;
            EXPECT_GT(volume["stack_height_min"].get<double>(), 0.0) << what;
            EXPECT_LE(volume["stack_height_min"].get<double>(), volume["stack_height_mean"].get<double>()) << what;
            EXPECT_LE(volume["stack_height_mean"].get<double>(), 1.15) << what;
        } else {
            EXPECT_EQ(whole, 0) << what;
        }
        if (run.phantom == "torus" && run.layers == "prisms") {
            EXPECT_GE(tet_cells.get<double>(), 10.0) << what;
            EXPECT_LT(report["openfoam"]["max_non_orthogonality_deg"].get<double>(), 70.0) << what;
        }
    }
}

} // namespace
} // namespace scalemesh
