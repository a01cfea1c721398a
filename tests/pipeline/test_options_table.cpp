// The meshing options' table (pipeline/options_table.h): one default per
// option (MeshOptions{}'s), and a case file and MeshOptions that say the same
// give the same case, or the same refusal.

#include "core/errors.h"
#include "pipeline/case_config.h"
#include "pipeline/options_table.h"
#include "support/comma_locale.h"
#include "support/temp_dir.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace scalemesh {
namespace {

// The meshing fields of a case, as text: equal texts, equal options.
std::string meshing_fields(const CaseConfig& c)
{
    const auto length = [](const std::optional<Length>& l) { return l ? l->text() : std::string("unset"); };
    std::ostringstream out;
    out.precision(17);
    out << "sweeps " << c.smoothing.sweeps << ", omega " << c.smoothing.omega << ", reach "
        << c.smoothing_reach.text() << ", K " << c.K << ", M " << c.M << ", G " << c.G << ", L_min "
        << c.L_min.text() << ", L_max " << length(c.L_max) << ", curvature " << c.curvature << ", cycles "
        << c.remesh_cycles << ", growth " << c.growth << ", first_layer " << static_cast<int>(c.first_layer)
        << ", layers " << static_cast<int>(c.layers) << ", tolerance " << c.layer_tolerance << ", threads "
        << c.threads;
    return out.str();
}

const std::string phantom = "[input]\nphantom = \"sphere\"\n";

// A value of `option` other than its default, valid, as case-file text, set
// into `options` too.
std::string other_value(const OptionInfo& option, MeshOptions& options)
{
    std::ostringstream text;
    text.precision(17);
    std::visit(
        [&](auto member) {
            auto& value = options.*member;
            using T = std::decay_t<decltype(value)>;
            if constexpr (std::is_same_v<T, bool>) {
                value = !value;
                text << (value ? "true" : "false");
            } else if constexpr (std::is_same_v<T, std::string>) {
                value = option.choices.front() == value ? option.choices.back() : option.choices.front();
                text << '"' << value << '"';
            } else if constexpr (std::is_arithmetic_v<T>) {
                value = static_cast<T>((option.min + option.max) / 2);
                text << value;
                if (option.kind == OptionKind::number && text.str().find('.') == std::string::npos) text << ".0";
            } else {
                value = MeshLength::in_voxels(1.5);
                text << "\"1.5 voxels\"";
            }
        },
        option.member);
    return text.str();
}

// An invalid value of `option` as case-file text, set into `options` too;
// empty for a boolean, which has none.
std::string invalid_value(const OptionInfo& option, MeshOptions& options)
{
    std::string text;
    std::visit(
        [&](auto member) {
            auto& value = options.*member;
            using T = std::decay_t<decltype(value)>;
            if constexpr (std::is_same_v<T, std::string>) {
                value = "sideways";
                text = "\"sideways\"";
            } else if constexpr (std::is_same_v<T, double>) {
                value = option.min - 1;
                std::ostringstream out;
                out << value;
                text = out.str();
            } else if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>) {
                value = static_cast<T>(option.min - 1);
                text = std::to_string(value);
            } else if constexpr (!std::is_same_v<T, bool>) {
                value = MeshLength::mm(-1);
                text = "-1";
            }
        },
        option.member);
    return text;
}

std::string refusal(const std::function<void()>& f)
{
    try {
        f();
    } catch (const InputError& e) {
        return e.what();
    }
    return "(accepted)";
}

TEST(OptionsTable, EveryOptionOnceWithItsKeyAndADoc)
{
    std::set<std::string> keywords, keys;
    for (const OptionInfo& option : mesh_option_table()) {
        EXPECT_TRUE(keywords.insert(option.keyword).second) << option.keyword << " twice";
        EXPECT_TRUE(keys.insert(option.section + "." + option.key).second) << option.key << " twice";
        EXPECT_FALSE(option.doc.empty()) << option.keyword;
        EXPECT_EQ(option.kind == OptionKind::choice, !option.choices.empty()) << option.keyword;
        if (option.kind == OptionKind::number || option.kind == OptionKind::integer) {
            EXPECT_LT(option.min, option.max) << option.keyword;
        }
    }
    // The case file's sections each take some options; max_memory is the
    // library's (and the command line's --max-memory) alone.
    for (const std::string section : {"smoothing", "sizing", "remeshing", "volume", "run"})
        EXPECT_TRUE(std::any_of(keys.begin(), keys.end(), [&](const std::string& k) { return k.starts_with(section + "."); }))
            << section;
    EXPECT_TRUE(keys.count(".max_memory"));
}

TEST(OptionsTable, OneDefaultPerOptionMeshOptionsOwn)
{
    const MeshOptions defaults;
    const CaseConfig config;
    EXPECT_EQ(config.K, defaults.K);
    EXPECT_EQ(config.M, defaults.M);
    EXPECT_EQ(config.G, defaults.G);
    EXPECT_EQ(config.L_min.value, defaults.L_min.value);
    EXPECT_EQ(config.L_min.voxels, defaults.L_min.voxels);
    EXPECT_EQ(config.L_max.has_value(), defaults.L_max.has_value());
    EXPECT_EQ(config.curvature, defaults.curvature);
    EXPECT_EQ(config.smoothing.sweeps, defaults.smoothing_sweeps);
    EXPECT_EQ(config.smoothing.omega, defaults.smoothing_omega);
    EXPECT_EQ(config.smoothing_reach.value, defaults.smoothing_reach.value);
    EXPECT_EQ(config.smoothing_reach.voxels, defaults.smoothing_reach.voxels);
    EXPECT_EQ(config.remesh_cycles, defaults.remesh_cycles);
    EXPECT_EQ(config.growth, defaults.growth);
    EXPECT_EQ(config.first_layer == FirstLayer::edge ? "edge" : "paper", defaults.first_layer);
    EXPECT_EQ(config.layers == LayerMode::prisms ? "prisms" : "delaunay", defaults.layers);
    EXPECT_EQ(config.layer_tolerance, defaults.layer_tolerance);
    EXPECT_EQ(config.threads, defaults.threads);
    // A case file that gives none of them has them too.
    EXPECT_EQ(meshing_fields(parse_case(phantom, ".", "scalemesh.toml")), meshing_fields(config));

    // The table's JSON (what `scalemesh options --json` prints) states
    // MeshOptions{}'s value as each default.
    const nlohmann::json table = nlohmann::json::parse(mesh_options_json());
    ASSERT_EQ(table.size(), mesh_option_table().size());
    for (const nlohmann::json& item : table) {
        const OptionInfo* option = find_option(item["keyword"]);
        ASSERT_NE(option, nullptr) << item;
        std::visit(
            [&](auto member) {
                const auto& value = defaults.*member;
                using T = std::decay_t<decltype(value)>;
                if constexpr (std::is_same_v<T, std::optional<MeshLength>>) {
                    EXPECT_EQ(item["default"].is_null(), !value);
                } else if constexpr (std::is_same_v<T, MeshLength>) {
                    std::ostringstream voxels;
                    voxels << value.value << " voxels";
                    EXPECT_EQ(item["default"], value.voxels ? nlohmann::json(voxels.str()) : nlohmann::json(value.value));
                } else {
                    EXPECT_EQ(item["default"], nlohmann::json(value)) << option->keyword;
                }
            },
            option->member);
    }
}

TEST(OptionsTable, ACaseFileAndMeshOptionsSayingTheSameGiveTheSameCase)
{
    MeshOptions options;
    std::map<std::string, std::string> sections; // each section's lines, as TOML allows a table once
    for (const OptionInfo& option : mesh_option_table())
        if (!option.section.empty()) // a case-file key
            sections[option.section] += option.key + " = " + other_value(option, options) + "\n";
    std::string text = phantom;
    for (const auto& [section, keys] : sections) text += "[" + section + "]\n" + keys;

    const CaseConfig from_file = parse_case(text, ".", "scalemesh.toml");
    const CaseConfig from_options = config_from_options(options, parse_case(phantom, ".", "scalemesh.toml"));
    EXPECT_EQ(meshing_fields(from_file), meshing_fields(from_options)) << text;
    EXPECT_NE(meshing_fields(from_file), meshing_fields(CaseConfig{})) << "the case changed no option";
}

TEST(OptionsTable, AnOutOfRangeValueIsRefusedInTheSameWordsEitherWay)
{
    CaseConfig named;
    named.source = "scalemesh.toml";
    for (const OptionInfo& option : mesh_option_table()) {
        MeshOptions options;
        const std::string value = invalid_value(option, options);
        if (value.empty()) continue; // a boolean: nothing to refuse
        const std::string by_options = refusal([&] { config_from_options(options, named); });
        EXPECT_NE(by_options.find(named.source + ": "), std::string::npos) << by_options;
        EXPECT_NE(by_options.find(option.key), std::string::npos) << by_options;
        EXPECT_NE(by_options.find("Hint: "), std::string::npos) << by_options;
        if (option.section.empty()) continue; // not a case-file key
        const std::string by_file = refusal([&] {
            parse_case(phantom + "[" + option.section + "]\n" + option.key + " = " + value + "\n", ".", "scalemesh.toml");
        });
        EXPECT_EQ(by_file, by_options) << option.keyword << " = " << value;
    }
    // L_max below L_min, a rule between two options, in the same words too.
    MeshOptions options;
    options.L_max = MeshLength::in_voxels(0.25);
    EXPECT_EQ(refusal([&] { parse_case(phantom + "[sizing]\nL_max = \"0.25 voxels\"\n", ".", "scalemesh.toml"); }),
              refusal([&] { config_from_options(options, named); }));
}

// The library's openings and image options are checked by the case
// reader's own code: the same refusal either way.
TEST(OptionsTable, OpeningsAndImageOptionsAreRefusedInTheCaseFilesWords)
{
    CaseConfig named;
    named.source = "scalemesh.toml";
    const auto opening = [](std::string name, std::string type) {
        MeshOpening o;
        o.name = std::move(name);
        o.type = std::move(type);
        return o;
    };
    std::vector<std::pair<std::string, MeshOpening>> openings;
    openings.emplace_back("name = \"in\"\nnear = [0, 0, 1]\n", opening("in", ""));
    openings.back().second.near = {{0, 0, 1}};
    openings.emplace_back("name = \"in\"\ntype = \"sideways\"\nnear = [0, 0, 1]\n", opening("in", "sideways"));
    openings.back().second.near = {{0, 0, 1}};
    openings.emplace_back("name = \"wall\"\ntype = \"inlet\"\nborder = \"z-\"\n", opening("wall", "inlet"));
    openings.back().second.border = "z-";
    openings.emplace_back("name = \"in\"\ntype = \"inlet\"\nborder = \"w+\"\n", opening("in", "inlet"));
    openings.back().second.border = "w+";
    openings.emplace_back("name = \"in\"\ntype = \"inlet\"\nnear = [0, 0, 1]\npoint = [0, 0, 0]\n", opening("in", "inlet"));
    openings.back().second.near = {{0, 0, 1}};
    openings.back().second.point = {{0, 0, 0}};
    openings.emplace_back("name = \"in\"\ntype = \"inlet\"\nlabel = 3\nextension = 200\n", opening("in", "inlet"));
    openings.back().second.label = 3;
    openings.back().second.extension = 200;
    for (const auto& pair : openings) {
        const std::string& toml = pair.first; // a reference, not a structured binding: lambdas capture it
        const MeshOpening& given = pair.second;
        const std::string by_file =
            refusal([&] { parse_case(phantom + "[[openings]]\n" + toml, ".", "scalemesh.toml"); });
        EXPECT_NE(by_file, "(accepted)") << toml;
        EXPECT_EQ(refusal([&] { openings_from_options({given}, named); }), by_file);
    }
    // An accepted opening is the same opening either way.
    MeshOpening inlet = opening("in", "inlet");
    inlet.point = {{0, 0, -1}};
    inlet.normal = {{0, 0, -2}};
    inlet.radius = 3;
    const CaseConfig from_file = parse_case(
        phantom + "[[openings]]\nname = \"in\"\ntype = \"inlet\"\npoint = [0, 0, -1]\nnormal = [0, 0, -2]\nradius = 3\n", ".",
        "scalemesh.toml");
    const CaseConfig from_options = openings_from_options({inlet}, named);
    ASSERT_EQ(from_file.openings.size(), 1u);
    ASSERT_EQ(from_options.openings.size(), 1u);
    EXPECT_EQ(from_options.openings[0].spec.plane.normal.z, from_file.openings[0].spec.plane.normal.z);
    EXPECT_EQ(from_options.openings[0].spec.radius, from_file.openings[0].spec.radius);
    EXPECT_EQ(from_options.openings[0].spec.type, from_file.openings[0].spec.type);

    const std::string image = "[input]\nfile = \"image.nii\"\n";
    ImageOptions units;
    units.units = "cm";
    EXPECT_EQ(refusal([&] { input_from_options("image.nii", units, named); }),
              refusal([&] { parse_case(image + "units = \"cm\"\n", ".", "scalemesh.toml"); }));
    ImageOptions both;
    both.labels = {1};
    both.threshold = 0.5;
    EXPECT_EQ(refusal([&] { input_from_options("image.nii", both, named); }),
              refusal([&] { parse_case(image + "labels = [1]\nthreshold = 0.5\n", ".", "scalemesh.toml"); }));
    ImageOptions diagonal;
    diagonal.connectivity = 8;
    EXPECT_EQ(refusal([&] { input_from_options("image.nii", diagonal, named); }),
              refusal([&] { parse_case(image + "connectivity = 8\n", ".", "scalemesh.toml"); }));
}


// A refused value and its range read as the case file wrote them, whatever
// the process's numeric locale: a host that set a comma LC_NUMERIC (a Qt
// application) gets "K = 1500.5", not "1500,500000".
TEST(OptionsTable, ARefusedValueReadsAsWrittenUnderACommaLocale)
{
    const CommaNumericLocale comma;
    ASSERT_EQ(comma.failure(), "");
    const std::string message = refusal([] { parse_case(phantom + "[sizing]\nK = 1500.5\n", ".", "scalemesh.toml"); });
    EXPECT_NE(message.find("[sizing] K = 1500.5 is out of range"), std::string::npos) << message;
    EXPECT_NE(message.find("(0, 1000]"), std::string::npos) << message;
    MeshOptions options;
    options.K = 1500.5;
    CaseConfig named;
    named.source = "scalemesh.toml";
    EXPECT_EQ(refusal([&] { config_from_options(options, named); }), message);
}

} // namespace
} // namespace scalemesh
