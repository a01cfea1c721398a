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

TEST(SampleCaseFlow, TubePressureDropMatchesHagenPoiseuille)
{
    if (!have_openfoam()) GTEST_SKIP() << "OpenFOAM is not installed";
    const TempDir tmp;
    const std::filesystem::path dir = tmp.path / "tube";
    // Reynolds number 0.6 (6 mm, 0.1 m/s, 1e-3 m^2/s): the flow is developed
    // within about a diameter of the inlet, so the middle third of the
    // 24 mm tube sees Poiseuille flow.
    constexpr double nu = 1e-3, U = 0.1;
    copy_case("tube", dir, "[flow]\nviscosity = 1e-3\ninlet_speed = 0.1\n");
    // At M = 10: the sample case's M = 7 is 5% off (docs/validation.md:
    // -4.98% with the layer prisms), the discretisation's own error at 7
    // layers across, so a check there would sit on its tolerance; from
    // M = 10 on the study measures the pressure drop within 1%.
    {
        const std::string text = slurp(dir / "scalemesh.toml");
        const std::string at_10 = std::regex_replace(text, std::regex(R"((^|\n)M = 7 )"), "$1M = 10 ");
        ASSERT_NE(at_10, text) << "no M = 7 line in cases/tube/scalemesh.toml";
        std::ofstream(dir / "scalemesh.toml") << at_10;
    }
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
    std::printf("tube: pressure drop over %g mm %g m^2/s^2, Hagen-Poiseuille %g, ratio %.4f\n", L * 1e3, dp, expected,
                dp / expected);
    EXPECT_NEAR(dp / expected, 1.0, 0.02);
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

} // namespace
} // namespace scalemesh
