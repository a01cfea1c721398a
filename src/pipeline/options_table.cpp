#include "pipeline/options_table.h"

#include <nlohmann/json.hpp>

#include <array>
#include <charconv>
#include <cmath>
#include <locale>
#include <sstream>

namespace scalemesh {

const std::vector<OptionInfo>& mesh_option_table()
{
    using K = OptionKind;
    using M = MeshOptions;
    static const std::vector<OptionInfo> table = {
        {.section = "smoothing", .key = "sweeps", .keyword = "smoothing_sweeps", .kind = K::integer,
         .member = &M::smoothing_sweeps, .min = 0, .max = 10000, .hint = "choose 0 to 10000 sweeps",
         .doc = "Gauss-Seidel sweeps of volume-conserving smoothing (0: none)"},
        {.section = "smoothing", .key = "omega", .keyword = "smoothing_omega", .kind = K::number,
         .member = &M::smoothing_omega, .min = 0, .max = 1, .min_open = true,
         .doc = "under-relaxation of the smoothing"},
        {.section = "smoothing", .key = "max_displacement", .keyword = "smoothing_reach", .kind = K::length,
         .member = &M::smoothing_reach, .unit = "mm or voxels",
         .doc = "how far smoothing may move a node from where marching cubes put it"},
        {.section = "sizing", .key = "K", .keyword = "K", .kind = K::number, .member = &M::K, .min = 0, .max = 1e3,
         .min_open = true, .doc = "anisotropy of the elements at the wall: surface edge length over layer thickness"},
        {.section = "sizing", .key = "M", .keyword = "M", .kind = K::number, .member = &M::M, .min = 1, .max = 1e3,
         .doc = "element layers across a cross-section"},
        {.section = "sizing", .key = "G", .keyword = "G", .kind = K::number, .member = &M::G, .min = 0, .max = 1e3,
         .min_open = true, .doc = "gradient limit of the feature size d, |d_i - d_j| <= G |x_i - x_j|"},
        {.section = "sizing", .key = "L_min", .keyword = "L_min", .kind = K::length, .member = &M::L_min,
         .unit = "mm or voxels", .doc = "smallest feature size resolved"},
        {.section = "sizing", .key = "L_max", .keyword = "L_max", .kind = K::length, .member = &M::L_max,
         .unit = "mm or voxels", .doc = "largest feature size, at least L_min; unset: the largest extent of the surface"},
        {.section = "sizing", .key = "curvature", .keyword = "curvature", .kind = K::boolean, .member = &M::curvature,
         .doc = "the curvature term of the feature size, eq. (12)"},
        {.section = "remeshing", .key = "cycles", .keyword = "remesh_cycles", .kind = K::integer,
         .member = &M::remesh_cycles, .min = 0, .max = 100,
         .hint = "choose 0 (no remeshing, no volume mesh) to 100; the paper uses 3",
         .doc = "remeshing cycles of the surface; 0 (a case file only): none, and no volume mesh"},
        {.section = "volume", .key = "growth", .keyword = "growth", .kind = K::number, .member = &M::growth, .min = 1,
         .max = 3, .doc = "thickness ratio of successive layers; 1: uniform layers as in the paper"},
        {.section = "volume", .key = "first_layer", .keyword = "first_layer", .kind = K::choice,
         .member = &M::first_layer, .choices = {"edge", "paper"}, .what = "a first-layer rule",
         .hint = "write first_layer = \"edge\" (thickness = surface edge length / K) or \"paper\" (the paper's d/M)",
         .doc = "first layer thickness: \"edge\" surface edge length / K, \"paper\" d / M"},
        {.section = "volume", .key = "layers", .keyword = "layers", .kind = K::choice, .member = &M::layers,
         .choices = {"delaunay", "prisms"}, .what = "a layer construction",
         .hint = "write layers = \"delaunay\" (the method paper's layer points in one Delaunay triangulation) or "
                 "\"prisms\" (prism layers built explicitly, the core meshed above them)",
         .doc = "\"prisms\": prism layers built explicitly, the core meshed above them; \"delaunay\": the paper's "
                "layer points in one Delaunay triangulation"},
        {.section = "volume", .key = "layer_tolerance", .keyword = "layer_tolerance", .kind = K::number,
         .member = &M::layer_tolerance, .min = 0, .max = 0.5, .min_open = true, .unit = "fraction of a layer spacing",
         .doc = "how far a layer point may move and still count as on its layer"},
        {.section = "run", .key = "threads", .keyword = "threads", .kind = K::integer, .member = &M::threads,
         .min = 0, .max = 1024, .hint = "give 0 (all cores) or a thread count",
         .doc = "worker threads of every parallel stage; 0: every core"},
        {.section = "", .key = "max_memory", .keyword = "max_memory", .kind = K::integer, .member = &M::max_memory,
         .min = 0, .max = 9.2e18, .hint = "give bytes, or 0 for no bound", .unit = "bytes",
         .doc = "memory the run may use, estimated before the heavy stages; 0: the machine's physical memory "
                "(the command line's run --max-memory)"},
    };
    return table;
}

const OptionInfo* find_option(const std::string& keyword)
{
    for (const OptionInfo& option : mesh_option_table())
        if (option.keyword == keyword) return &option;
    return nullptr;
}

std::string number_text(double v)
{
    if (std::isnan(v)) return "nan";
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    std::array<char, 64> text;
    const auto end = std::to_chars(text.data(), text.data() + text.size(), v).ptr;
    return std::string(text.data(), end);
}

std::string interval_text(double lo, double hi, bool lo_open)
{
    return (lo_open ? "(" : "[") + number_text(lo) + ", " + number_text(hi) + "]";
}

std::string range_text(const OptionInfo& option)
{
    return interval_text(option.min, option.max, option.min_open);
}

const char* option_kind_name(OptionKind kind)
{
    static const char* const names[] = {"number", "integer", "boolean", "choice", "length"};
    return names[static_cast<int>(kind)];
}

namespace {

// MeshOptions{}'s value of `option`: a length as "0.5 voxels" or a number of
// mm, an unset L_max as null.
nlohmann::json default_value(const OptionInfo& option)
{
    static const MeshOptions defaults;
    const auto length = [](const MeshLength& l) {
        std::ostringstream text;
        text.imbue(std::locale::classic());
        text << l.value << " voxels";
        return l.voxels ? nlohmann::json(text.str()) : nlohmann::json(l.value);
    };
    return std::visit(
        [&](auto member) -> nlohmann::json {
            const auto& value = defaults.*member;
            using T = std::decay_t<decltype(value)>;
            if constexpr (std::is_same_v<T, MeshLength>) return length(value);
            else if constexpr (std::is_same_v<T, std::optional<MeshLength>>)
                return value ? length(*value) : nlohmann::json(nullptr);
            else return value;
        },
        option.member);
}

} // namespace

std::string mesh_options_json()
{
    nlohmann::json out = nlohmann::json::array();
    for (const OptionInfo& option : mesh_option_table()) {
        nlohmann::json item = {{"section", option.section}, {"key", option.key},   {"keyword", option.keyword},
                               {"kind", option_kind_name(option.kind)},  {"default", default_value(option)},
                               {"unit", option.unit},             {"doc", option.doc}};
        if (option.kind == OptionKind::number || option.kind == OptionKind::integer) {
            item["min"] = option.min;
            item["max"] = option.max;
            item["min_open"] = option.min_open;
        }
        if (option.kind == OptionKind::choice) item["choices"] = option.choices;
        out.push_back(item);
    }
    return out.dump(1) + "\n";
}

std::string mesh_options_text()
{
    std::ostringstream out;
    out.imbue(std::locale::classic());
    for (const OptionInfo& option : mesh_option_table()) {
        if (option.section.empty()) out << option.key << " (library and Python only)";
        else out << "[" << option.section << "] " << option.key;
        const nlohmann::json value = default_value(option);
        out << " = " << (value.is_null() ? "unset" : value.dump()) << "  (" << option_kind_name(option.kind);
        if (option.kind == OptionKind::number || option.kind == OptionKind::integer) out << " in " << range_text(option);
        if (option.kind == OptionKind::choice) out << ": " << nlohmann::json(option.choices).dump();
        if (!option.unit.empty()) out << ", " << option.unit;
        if (option.keyword != option.key) out << "; Python " << option.keyword;
        out << "): " << option.doc << "\n";
    }
    return out.str();
}

} // namespace scalemesh
