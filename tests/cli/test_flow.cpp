// Flow validation of the sample cases with openings: OpenFOAM's simpleFoam
// runs on what `scalemesh run` writes, without hand editing. On the straight
// tube the developed pressure gradient matches Hagen-Poiseuille for the
// mesh's own cross-section; on the bifurcation the inflow equals the sum of
// the outflows.

#include "cli_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <numbers>
#include <regex>
#include <sstream>

namespace scalemesh {
namespace {

bool have_openfoam() { return std::system("command -v simpleFoam >/dev/null 2>&1") == 0; }
bool have_mpirun() { return std::system("command -v mpirun >/dev/null 2>&1") == 0; }

std::string slurp(const std::filesystem::path& path)
{
    std::ifstream in(path);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Runs an OpenFOAM command in `dir`; returns its exit code, the log in `log`.
int openfoam(const std::string& command, const std::filesystem::path& dir, std::string& log)
{
    const std::filesystem::path file = dir / "openfoam.log";
    const std::string cmd = "cd '" + dir.string() + "' && WM_PROJECT_DIR=/usr/share/openfoam " + command + " > '" +
                            file.string() + "' 2>&1";
    const int code = std::system(cmd.c_str());
    log = slurp(file);
    return code;
}

// Copies a sample case into `dir`, appending `extra` to its case file.
void copy_case(const std::string& name, const std::filesystem::path& dir, const std::string& extra)
{
    std::filesystem::create_directories(dir);
    std::ofstream(dir / "scalemesh.toml") << slurp(std::filesystem::path("cases") / name / "scalemesh.toml") << "\n"
                                          << extra;
}

// Replaces `pattern` by `replacement` in the case file in `dir`; false when
// the pattern is not there.
bool edit_case(const std::filesystem::path& dir, const std::string& pattern, const std::string& replacement)
{
    const std::string text = slurp(dir / "scalemesh.toml");
    const std::string edited = std::regex_replace(text, std::regex(pattern), replacement);
    if (edited == text) return false;
    std::ofstream(dir / "scalemesh.toml") << edited;
    return true;
}

// The latest time directory simpleFoam wrote.
std::filesystem::path latest_time(const std::filesystem::path& dir)
{
    double best = -1;
    std::filesystem::path path;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        const std::string name = entry.path().filename().string();
        char* end = nullptr;
        const double t = std::strtod(name.c_str(), &end);
        if (end && *end == '\0' && !name.empty() && t > best) best = t, path = entry.path();
    }
    return path;
}

// The internalField of an ASCII volScalarField (components 1) or
// volVectorField (components 3), flattened.
std::vector<double> internal_field(const std::filesystem::path& file, int components)
{
    const std::string text = slurp(file);
    const size_t at = text.find("internalField");
    if (at == std::string::npos) throw std::runtime_error("no internalField in " + file.string());
    std::istringstream in(text.substr(at));
    std::string word, kind;
    in >> word >> kind;
    if (kind != "nonuniform") throw std::runtime_error("a uniform internalField in " + file.string());
    in >> word; // List<scalar> or List<vector>
    size_t n = 0;
    in >> n;
    std::vector<double> values;
    values.reserve(n * components);
    char c;
    in >> c; // (
    for (size_t i = 0; i < n; ++i) {
        if (components == 3) in >> c;
        for (int k = 0; k < components; ++k) {
            double v;
            in >> v;
            values.push_back(v);
        }
        if (components == 3) in >> c;
    }
    if (!in) throw std::runtime_error("a short internalField in " + file.string());
    return values;
}

// The area average over `patch` of a field at the latest time, by
// postProcess's patchAverage: one value for a scalar, three for a vector.
std::vector<double> patch_average(const std::filesystem::path& dir, const std::string& patch, const std::string& field)
{
    std::string log;
    EXPECT_EQ(openfoam("postProcess -case . -latestTime -func 'patchAverage(name=" + patch + "," + field + ")'", dir,
                       log),
              0)
        << log;
    std::smatch m;
    if (!std::regex_search(log, m, std::regex("areaAverage\\(" + patch + "\\) of " + field + " = \\(?([^)\n]+)"))) {
        ADD_FAILURE() << "no average of " << field << " over " << patch << " in " << log;
        return {};
    }
    std::istringstream in(m[1].str());
    std::vector<double> values;
    for (double v; in >> v;) values.push_back(v);
    return values;
}

// The pressure drop over the middle third of the tube against
// Hagen-Poiseuille's, with either layer construction: the paper's layers at
// M = 10, from where the study (docs/validation.md) measures it within 1%;
// the prism layers at the sample case's own M = 7 (-1.06% in the study,
// validation/notes-prisms.md; at M = 10 the voxel tube's are +2.15% off,
// the exact cylinder's +0.32%, and from M = 14 on the tube the prisms' cells
// miss the dihedral floor and the run builds the paper's layers instead).
void check_tube_pressure_drop(const std::string& layers, int M)
{
    const TempDir tmp;
    const std::filesystem::path dir = tmp.path / "tube";
    // Reynolds number 0.6 (6 mm, 0.1 m/s, 1e-3 m^2/s): the flow is developed
    // within about a diameter of the inlet, so the middle third of the
    // 24 mm tube sees Poiseuille flow.
    constexpr double nu = 1e-3, U = 0.1;
    copy_case("tube", dir, "[flow]\nviscosity = 1e-3\ninlet_speed = 0.1\n");
    // (The paper's layers at M = 7 are 5% off, docs/validation.md: -4.98%,
    // the discretisation's own error at 7 layers across.)
    if (M != 7)
        ASSERT_TRUE(edit_case(dir, R"((^|\n)M = 7 )", "$1M = " + std::to_string(M) + " "))
            << "no M = 7 line in cases/tube/scalemesh.toml";
    ASSERT_TRUE(edit_case(dir, R"((^|\n)\[volume\]\n)", "$1[volume]\nlayers = \"" + layers + "\"\n"))
        << "no [volume] table in cases/tube/scalemesh.toml";
    const CommandResult r = run_scalemesh({"run", dir.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::string log;
    ASSERT_EQ(openfoam("simpleFoam -case .", dir, log), 0) << log;
    EXPECT_NE(log.find("SIMPLE solution converged"), std::string::npos) << log.substr(log.size() > 3000 ? log.size() - 3000 : 0);
    ASSERT_EQ(openfoam("postProcess -case . -latestTime -func writeCellCentres", dir, log), 0) << log;
    ASSERT_EQ(openfoam("postProcess -case . -latestTime -func writeCellVolumes", dir, log), 0) << log;

    const std::filesystem::path time = latest_time(dir);
    const std::vector<double> p = internal_field(time / "p", 1);
    const std::vector<double> C = internal_field(time / "C", 3);
    const std::vector<double> V = internal_field(time / "V", 1);
    ASSERT_EQ(C.size(), 3 * p.size());
    ASSERT_EQ(V.size(), p.size());

    // Volume-weighted mean kinematic pressure over 2 mm slabs at z = -4 and +4 mm.
    const auto slab_pressure = [&](double z) {
        double pv = 0, v = 0;
        for (size_t i = 0; i < p.size(); ++i)
            if (std::abs(C[3 * i + 2] - z) < 1e-3) pv += p[i] * V[i], v += V[i];
        return pv / v;
    };
    const double L = 8e-3;
    const double dp = slab_pressure(-4e-3) - slab_pressure(4e-3);

    const nlohmann::json report = nlohmann::json::parse(slurp(dir / "report.json"));
    // The mesh's own cross-section: its volume over its length (24 mm), in m^2.
    const double area = report["volume"]["volume_mm3"].get<double>() / 24.0 * 1e-6;
    // The flow rate the inlet imposes: U over the inlet patch's area.
    double inlet_area = 0;
    for (const auto& cap : report["openings"])
        if (cap["name"] == "inlet") inlet_area = cap["mesh_area_mm2"].get<double>() * 1e-6;
    ASSERT_GT(inlet_area, 0);
    const double Q = U * inlet_area;
    // Hagen-Poiseuille with the circle of the same area: dp = 8 pi nu L Q / A^2.
    const double expected = 8 * std::numbers::pi * nu * L * Q / (area * area);
    std::printf("tube, %s layers, M = %d: pressure drop over %g mm %g m^2/s^2, Hagen-Poiseuille %g, ratio %.4f\n",
                layers.c_str(), M, L * 1e3, dp, expected, dp / expected);
    EXPECT_EQ(report["volume"]["layers_built"], layers);
    EXPECT_NEAR(dp / expected, 1.0, 0.02) << layers << " layers, M = " << M;
}

TEST(SampleCaseFlow, TubePressureDropMatchesHagenPoiseuille)
{
    if (!have_openfoam()) GTEST_SKIP() << "OpenFOAM is not installed";
    check_tube_pressure_drop("prisms", 7);
    check_tube_pressure_drop("delaunay", 10);
}

TEST(SampleCaseFlow, BifurcationInflowEqualsTheSumOfOutflows)
{
    if (!have_openfoam()) GTEST_SKIP() << "OpenFOAM is not installed";
    const TempDir tmp;
    const std::filesystem::path dir = tmp.path / "bifurcation";
    copy_case("bifurcation", dir, "");
    const CommandResult r = run_scalemesh({"run", dir.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::string log;
    ASSERT_EQ(openfoam("simpleFoam -case .", dir, log), 0) << log;
    EXPECT_NE(log.find("SIMPLE solution converged"), std::string::npos) << log.substr(log.size() > 3000 ? log.size() - 3000 : 0);
    const auto flow_rate = [&](const std::string& patch) {
        std::string out;
        EXPECT_EQ(openfoam("postProcess -case . -latestTime -func 'flowRatePatch(name=" + patch + ")'", dir, out), 0) << out;
        std::smatch m;
        if (!std::regex_search(out, m, std::regex("sum\\(" + patch + "\\) of phi = ([0-9.eE+-]+)")))
            ADD_FAILURE() << "no flow rate for " << patch << " in " << out;
        return m.empty() ? NAN : std::stod(m[1]);
    };
    const double in = -flow_rate("inlet");
    const double out = flow_rate("outlet_left") + flow_rate("outlet_right");
    std::printf("bifurcation: inflow %g m^3/s, outflows %g m^3/s, relative difference %.2e\n", in, out,
                std::abs(in - out) / in);
    EXPECT_GT(in, 0);
    EXPECT_NEAR(out, in, 1e-3 * in);
}

// [output] decompose = 2 on the tube: the two processor meshes pass
// checkMesh -parallel, hold the serial mesh's cells (reconstructPar gives
// back each cell's volume), and the flow solved on them with mpirun has the
// serial solve's pressure drop and mean wall shear stress within 0.1%.
TEST(SampleCaseFlow, TwoProcessorsGiveTheSerialCellsPressureDropAndWallShear)
{
    if (!have_openfoam() || !have_mpirun()) GTEST_SKIP() << "OpenFOAM or mpirun is not installed";
    const TempDir tmp;
    const std::filesystem::path parallel = tmp.path / "parallel", serial = tmp.path / "serial";
    copy_case("tube", parallel, "");
    ASSERT_TRUE(edit_case(parallel, R"((^|\n)\[output\]\n)", "$1[output]\ndecompose = 2\n"))
        << "no [output] table in cases/tube/scalemesh.toml";
    const CommandResult r = run_scalemesh({"run", parallel.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json report = nlohmann::json::parse(slurp(parallel / "report.json"));
    const nlohmann::json& pieces = report["openfoam"]["decomposition"];
    ASSERT_EQ(pieces["cells"].size(), 2u);
    EXPECT_EQ(pieces["cells"][0].get<int64_t>() + pieces["cells"][1].get<int64_t>(),
              report["openfoam"]["cells"].get<int64_t>());
    EXPECT_GT(pieces["processor_faces"].get<int64_t>(), 0);

    // The serial case: the same files but the processor meshes.
    std::filesystem::copy(parallel, serial, std::filesystem::copy_options::recursive);
    for (const char* piece : {"processor0", "processor1"}) {
        ASSERT_TRUE(std::filesystem::is_directory(parallel / piece / "constant" / "polyMesh")) << piece;
        std::filesystem::remove_all(serial / piece);
    }

    std::string log;
    // checkMesh, checkMesh -parallel, simpleFoam -parallel and reconstructPar.
    ASSERT_EQ(openfoam("./Allrun", parallel, log), 0) << log;
    EXPECT_NE(slurp(parallel / "log.checkMesh.parallel").find("\nMesh OK."), std::string::npos);
    EXPECT_NE(slurp(parallel / "log.simpleFoam.parallel").find("SIMPLE solution converged"), std::string::npos);
    ASSERT_EQ(openfoam("simpleFoam -case .", serial, log), 0) << log;
    EXPECT_NE(log.find("SIMPLE solution converged"), std::string::npos);

    // Each piece's cell volumes, as the pieces measure them, mapped back.
    const std::string mpirun = "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
                               "OMPI_MCA_rmaps_base_oversubscribe=1 mpirun -np 2 ";
    ASSERT_EQ(openfoam(mpirun + "postProcess -parallel -case . -latestTime -func writeCellVolumes", parallel, log), 0)
        << log;
    ASSERT_EQ(openfoam("reconstructPar -case . -latestTime -fields '(V)'", parallel, log), 0) << log;
    ASSERT_EQ(openfoam("postProcess -case . -latestTime -func writeCellVolumes", serial, log), 0) << log;
    const std::vector<double> v_parallel = internal_field(latest_time(parallel) / "V", 1);
    const std::vector<double> v_serial = internal_field(latest_time(serial) / "V", 1);
    ASSERT_EQ(v_parallel.size(), v_serial.size());
    ASSERT_EQ(static_cast<int64_t>(v_serial.size()), report["openfoam"]["cells"].get<int64_t>());
    double total_parallel = 0, total_serial = 0;
    size_t differing = 0;
    for (size_t c = 0; c < v_serial.size(); ++c) {
        // Eight significant digits (controlDict writePrecision).
        differing += std::abs(v_parallel[c] - v_serial[c]) > 1e-7 * std::abs(v_serial[c]);
        total_parallel += v_parallel[c], total_serial += v_serial[c];
    }
    EXPECT_EQ(differing, 0u);
    EXPECT_NEAR(total_parallel, total_serial, 1e-7 * total_serial);

    // The pressure drop (inlet minus outlet, area-averaged) and the mean wall
    // shear stress of each solution (the parallel one as reconstructPar put it back).
    const auto flow = [&](const std::filesystem::path& dir) {
        std::string out;
        EXPECT_EQ(openfoam("simpleFoam -case . -postProcess -latestTime -func wallShearStress", dir, out), 0) << out;
        const std::vector<double> in = patch_average(dir, "inlet", "p"), outlet = patch_average(dir, "outlet", "p");
        const std::vector<double> wss = patch_average(dir, "wall", "wallShearStress");
        EXPECT_EQ(in.size(), 1u);
        EXPECT_EQ(outlet.size(), 1u);
        EXPECT_EQ(wss.size(), 3u);
        if (in.size() != 1 || outlet.size() != 1 || wss.size() != 3) return std::pair<double, double>(NAN, NAN);
        return std::pair<double, double>(in[0] - outlet[0], std::hypot(wss[0], wss[1], wss[2]));
    };
    const auto [dp_parallel, wss_parallel] = flow(parallel);
    const auto [dp_serial, wss_serial] = flow(serial);
    std::printf("tube on 2 processors: pressure drop %g (serial %g, ratio %.6f), mean wall shear stress %g (serial %g, "
                "ratio %.6f) m^2/s^2\n",
                dp_parallel, dp_serial, dp_parallel / dp_serial, wss_parallel, wss_serial, wss_parallel / wss_serial);
    EXPECT_GT(dp_serial, 0);
    EXPECT_GT(wss_serial, 0);
    EXPECT_NEAR(dp_parallel / dp_serial, 1.0, 1e-3);
    EXPECT_NEAR(wss_parallel / wss_serial, 1.0, 1e-3);
}

} // namespace
} // namespace scalemesh
