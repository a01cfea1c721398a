#include "pipeline/case_config.h"

#include "core/errors.h"
#include "importers/surface_importer.h"
#include "phantom/phantom.h"

#include <toml++/toml.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <climits>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <sstream>

namespace scalemesh {

std::string Length::text() const
{
    return number_text(value) + (voxels ? " voxels" : " mm");
}

namespace {

std::string join(const std::vector<std::string>& items)
{
    std::string out;
    for (const std::string& s : items) out += (out.empty() ? "" : ", ") + s;
    return out;
}

// Whether `v` is not a finite number in [lo, hi] ((lo, hi] with lo_open).
bool outside(double v, double lo, double hi, bool lo_open)
{
    return !std::isfinite(v) || v > hi || (lo_open ? v <= lo : v < lo);
}

// `v`, refused unless finite and in [lo, hi] ((lo, hi] with lo_open):
// "<where> = <v> is out of range".
double in_range(const std::string& where, double v, double lo, double hi, bool lo_open = false)
{
    if (outside(v, lo, hi, lo_open))
        throw InputError(where + " = " + number_text(v) + " is out of range",
                         "choose a value in " + interval_text(lo, hi, lo_open));
    return v;
}

// Refuses `v` unless it is one of `choices`: "<where> = "v" is not <what>",
// with `hint` (by default the choices quoted, as in: choose "ascii" or "binary").
void one_of(const std::string& where, const std::string& v, const std::vector<std::string>& choices,
            const std::string& what, std::string hint = "")
{
    if (std::find(choices.begin(), choices.end(), v) != choices.end()) return;
    if (hint.empty()) {
        hint = "choose";
        for (size_t i = 0; i < choices.size(); ++i)
            hint += std::string(i == 0 ? " " : i + 1 == choices.size() ? " or " : ", ") + "\"" + choices[i] + "\"";
    }
    throw InputError(where + " = \"" + v + "\" is not " + what, hint);
}

// Reads one table, refusing keys it does not know.
class Section {
public:
    Section(const toml::table* table, std::string name, std::string source, std::vector<std::string> keys)
        : table_(table), name_(std::move(name)), source_(std::move(source)), keys_(std::move(keys))
    {
        if (!table_) return;
        for (const auto& [key, value] : *table_) {
            (void)value;
            if (std::find(keys_.begin(), keys_.end(), std::string(key.str())) == keys_.end())
                throw InputError(where(std::string(key.str())) + " is not a known key",
                                 "the keys of [" + name_ + "] are: " + join(keys_));
        }
    }

    bool has(const std::string& key) const { return table_ && table_->contains(key); }

    template <typename T>
    std::optional<T> get(const std::string& key) const
    {
        if (!has(key)) return std::nullopt;
        const toml::node& node = *table_->get(key);
        if constexpr (std::is_same_v<T, double>) {
            if (auto v = node.value<double>()) return *v; // integers convert too
            throw InputError(where(key) + " must be a number", "write e.g. " + key + " = 1.0");
        } else if constexpr (std::is_same_v<T, int64_t>) {
            if (node.is_integer()) return *node.value<int64_t>();
            throw InputError(where(key) + " must be a whole number", "write e.g. " + key + " = 10");
        } else if constexpr (std::is_same_v<T, bool>) {
            if (node.is_boolean()) return *node.value<bool>();
            throw InputError(where(key) + " must be true or false", "write " + key + " = true");
        } else if constexpr (std::is_same_v<T, std::string>) {
            if (node.is_string()) return *node.value<std::string>();
            throw InputError(where(key) + " must be a string", "write " + key + " = \"...\"");
        }
        return std::nullopt;
    }

    double number(const std::string& key, double fallback, double lo, double hi, bool lo_open = false) const
    {
        return in_range(where(key), get<double>(key).value_or(fallback), lo, hi, lo_open);
    }

    // The string `key` if given, refused unless it is one of `choices`: the
    // error says `key = "value" is not <what>`, with `hint` (by default the
    // choices quoted, as in: choose "ascii" or "binary").
    std::optional<std::string> choice(const std::string& key, const std::vector<std::string>& choices,
                                      const std::string& what, std::string hint = "") const
    {
        const std::optional<std::string> v = get<std::string>(key);
        if (v) one_of(where(key), *v, choices, what, hint);
        return v;
    }

    Length length(const std::string& key) const
    {
        const toml::node& node = *table_->get(key);
        Length out;
        if (auto v = node.value<double>()) {
            out.value = *v;
        } else if (auto s = node.value<std::string>()) {
            std::istringstream in(*s);
            std::string unit;
            if (!(in >> out.value) || !(in >> unit) || (unit != "mm" && unit != "voxels" && unit != "voxel"))
                throw InputError(where(key) + " = \"" + *s + "\" is not a length",
                                 "write a number of mm, or a string such as \"1.5 mm\" or \"2 voxels\"");
            out.voxels = unit != "mm";
        } else {
            throw InputError(where(key) + " is not a length", "write a number of mm or a string such as \"2 voxels\"");
        }
        if (!(out.value > 0) || !std::isfinite(out.value))
            throw InputError(where(key) + " must be a positive length", "give a positive number of mm or voxels");
        return out;
    }

    std::string where(const std::string& key) const { return source_ + ": [" + name_ + "] " + key; }

private:
    const toml::table* table_;
    std::string name_, source_;
    std::vector<std::string> keys_;
};

// The case-file keys of `section`: its meshing options' (mesh_option_table),
// then its `own`.
std::vector<std::string> option_keys(const std::string& section, std::vector<std::string> own = {})
{
    std::vector<std::string> keys;
    for (const OptionInfo& option : mesh_option_table())
        if (option.section == section) keys.push_back(option.key);
    keys.insert(keys.end(), own.begin(), own.end());
    return keys;
}

[[noreturn]] void out_of_range(const OptionInfo& option, const std::string& where, const std::string& value)
{
    throw InputError(where + " = " + value + " is out of range",
                     option.hint.empty() ? "choose a value in " + range_text(option) : option.hint);
}

void check_integer(const OptionInfo& option, int64_t value, const std::string& where)
{
    if (value < option.min || value > option.max) out_of_range(option, where, std::to_string(value));
}

// The checks of an option's value, one per member type; `where` names the
// option ("<source>: [section] key").
void check_value(const OptionInfo& option, double value, const std::string& where)
{
    if (outside(value, option.min, option.max, option.min_open)) out_of_range(option, where, number_text(value));
}

void check_value(const OptionInfo& option, int value, const std::string& where)
{
    check_integer(option, value, where);
}

void check_value(const OptionInfo& option, int64_t value, const std::string& where)
{
    check_integer(option, value, where);
}

void check_value(const OptionInfo&, bool, const std::string&) {}

void check_value(const OptionInfo& option, const std::string& value, const std::string& where)
{
    one_of(where, value, option.choices, option.what, option.hint);
}

void check_value(const OptionInfo&, const MeshLength& value, const std::string& where)
{
    if (!(value.value > 0) || !std::isfinite(value.value))
        throw InputError(where + " must be a positive length", "give a positive number of mm or voxels");
}

void check_value(const OptionInfo& option, const std::optional<MeshLength>& value, const std::string& where)
{
    if (value) check_value(option, *value, where);
}

// The option's key of `section`, if given, into its member of `options`.
void read_option(const Section& section, const OptionInfo& option, MeshOptions& options)
{
    if (!section.has(option.key)) return;
    std::visit(
        [&](auto member) {
            auto& value = options.*member;
            using T = std::decay_t<decltype(value)>;
            if constexpr (std::is_same_v<T, double> || std::is_same_v<T, bool> || std::is_same_v<T, std::string>) {
                value = *section.get<T>(option.key);
            } else if constexpr (std::is_integral_v<T>) {
                const int64_t given = *section.get<int64_t>(option.key);
                check_integer(option, given, section.where(option.key));
                value = static_cast<T>(given);
            } else {
                const Length length = section.length(option.key);
                value = MeshLength{length.value, length.voxels};
            }
        },
        option.member);
}

Length case_length(const MeshLength& length) { return {length.value, length.voxels}; }

// The meshing options into `config`, unchecked.
void set_options(CaseConfig& config, const MeshOptions& options)
{
    config.smoothing.sweeps = options.smoothing_sweeps;
    config.smoothing.omega = options.smoothing_omega;
    config.smoothing_reach = case_length(options.smoothing_reach);
    config.K = options.K;
    config.M = options.M;
    config.G = options.G;
    config.L_min = case_length(options.L_min);
    config.L_max.reset();
    if (options.L_max) config.L_max = case_length(*options.L_max);
    config.curvature = options.curvature;
    config.remesh_cycles = options.remesh_cycles;
    config.growth = options.growth;
    config.first_layer = options.first_layer == "paper" ? FirstLayer::paper : FirstLayer::edge;
    config.layers = options.layers == "delaunay" ? LayerMode::delaunay : LayerMode::prisms;
    config.layer_tolerance = options.layer_tolerance;
    config.threads = options.threads;
}

const std::vector<std::string> opening_keys = {"name",   "type",  "point",     "normal", "radius",
                                                "border", "inset", "extension", "near",   "label"};

[[noreturn]] void refuse_label(const std::string& where)
{
    throw InputError(where + " must be a face label, an integer >= 0",
                     "write label = 2 (the ModelFaceID or physical surface of the cap)");
}

// Opening `index` (from 0) of the case, as `given` holds it, checked: `has`
// says which of its keys were given; `names` holds the names of the
// openings before it. InputError naming "<source>: [openings] [index + 1] key".
CaseConfig::Opening checked_opening(const MeshOpening& given, const std::function<bool(const std::string&)>& has,
                                    const std::string& source, size_t index, std::set<std::string>& names)
{
    const auto where = [&](const std::string& key) {
        return source + ": [openings] [" + std::to_string(index + 1) + "] " + key;
    };
    CaseConfig::Opening item;
    OpeningSpec& spec = item.spec;
    spec.name = given.name;
    const bool word = !spec.name.empty() && !std::isdigit(static_cast<unsigned char>(spec.name[0])) &&
                      std::all_of(spec.name.begin(), spec.name.end(), [](char c) {
                          return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
                      });
    if (!word)
        throw InputError(where("name") + " = \"" + spec.name + "\" is not a valid patch name",
                         "give a name of letters, digits and '_' not starting with a digit, e.g. \"inlet\"");
    if (spec.name == "wall")
        throw InputError(where("name") + " = \"wall\" is the name of the vessel wall", "choose another name, e.g. \"inlet\"");
    if (!names.insert(spec.name).second)
        throw InputError(where("name") + ": two openings are named '" + spec.name + "'", "give every opening its own name");
    if (!has("type"))
        throw InputError(where("type") + " is missing: opening '" + spec.name + "' needs a type",
                         "add type = \"inlet\" or type = \"outlet\" (the flow enters at inlets)");
    one_of(where("type"), given.type, {"inlet", "outlet"}, "an opening type");
    spec.type = given.type == "inlet" ? OpeningType::Inlet : OpeningType::Outlet;
    const auto vector = [&](const std::string& key, const std::array<double, 3>& xyz) {
        if (!std::all_of(xyz.begin(), xyz.end(), [](double v) { return std::isfinite(v); }))
            throw InputError(where(key) + " must be a list of 3 numbers", "write " + key + " = [0, 0, 1]");
        return Vec3{xyz[0], xyz[1], xyz[2]};
    };
    const bool plane = has("point") || has("normal");
    if (has("near") || has("label")) {
        // An open end of the surface (or a flat labelled cap), found at import.
        if (plane || has("border") || has("radius") || has("inset") || (has("near") && has("label")))
            throw InputError(source + ": opening '" + spec.name + "' names an open end by " +
                                 (has("near") ? "near" : "label") + " and must not also give " +
                                 (has("near") && has("label") ? "label" : "a plane, border, radius or inset"),
                             "keep near = [x, y, z] (a point near the end's loop) or label = N, not both, "
                             "and no plane");
        if (given.near) item.near = vector("near", *given.near);
        if (given.label) {
            if (*given.label < 0) refuse_label(where("label"));
            item.label = *given.label;
        }
        spec.extension = in_range(where("extension"), given.extension, 0, 100);
        return item;
    }
    if (plane == has("border"))
        throw InputError(source + ": opening '" + spec.name + "' needs either point and normal (a clip plane) "
                         "or border (a side of the image)",
                         "write point = [x, y, z] and normal = [nx, ny, nz] in mm, or border = \"z-\"");
    if (plane) {
        if (!given.point || !given.normal)
            throw InputError(source + ": opening '" + spec.name + "' needs both point and normal",
                             "write point = [x, y, z] (mm) and normal = [nx, ny, nz] (pointing out of the lumen)");
        spec.plane.point = vector("point", *given.point);
        const Vec3 normal = vector("normal", *given.normal);
        if (!(norm(normal) > 0))
            throw InputError(where("normal") + " is the zero vector",
                             "give the direction pointing out of the lumen, e.g. [0, 0, 1]");
        spec.plane.normal = normalized(normal);
        spec.radius = in_range(where("radius"), given.radius, 0, 1e9);
        if (has("inset")) throw InputError(where("inset") + " applies to border openings only", "remove it");
    } else {
        spec.border = true;
        static const std::vector<std::string> sides = {"x-", "x+", "y-", "y+", "z-", "z+"};
        one_of(where("border"), given.border, sides, "a side of the image", "choose one of: " + join(sides));
        spec.side = given.border;
        if (has("radius"))
            throw InputError(where("radius") + " applies to clip planes only",
                             "remove it: every piece of the border cross-section becomes an opening");
        // inset: "auto" (empty, the default) leaves spec.inset empty for
        // cut_and_cap to choose; a length is kept in item.inset and marks
        // spec.inset as given, resolved to mm once the voxel width is known.
        if (given.inset) {
            if (!(given.inset->value > 0) || !std::isfinite(given.inset->value))
                throw InputError(where("inset") + " must be a positive length", "give a positive number of mm or voxels");
            item.inset = {given.inset->value, given.inset->voxels};
            spec.inset = 0.0;
        }
    }
    spec.extension = in_range(where("extension"), given.extension, 0, 100);
    return item;
}

[[noreturn]] void refuse_connectivity(const std::string& where, int64_t connectivity)
{
    throw InputError(where + " = " + std::to_string(connectivity) + " is not valid",
                     "choose 6 (diagonal voxels stay apart, the default) or 26 (they join)");
}

// `config` (its file set) with the [input] keys of an image or surface file
// as `image` holds them, checked; `has` says which keys were given.
// InputError naming "<config.source>: [input] key".
CaseConfig checked_input(const ImageOptions& image, const std::function<bool(const std::string&)>& has,
                         CaseConfig config)
{
    const auto where = [&](const std::string& key) { return config.source + ": [input] " + key; };
    config.grid = image.grid;
    config.labels = image.labels;
    if (image.threshold) config.threshold = in_range(where("threshold"), *image.threshold, -1e30, 1e30);
    config.level_set = image.level_set;
    if (int(!config.labels.empty()) + int(config.threshold.has_value()) + int(config.level_set) > 1)
        throw InputError(config.source + ": [input] labels, threshold and level_set exclude each other",
                         "give labels for a label map, threshold for an intensity image, or level_set = true");
    if (image.iso) config.iso = in_range(where("iso"), *image.iso, -1e30, 1e30);
    if (image.connectivity != 6 && image.connectivity != 26) refuse_connectivity(where("connectivity"), image.connectivity);
    config.connectivity = image.connectivity == 6 ? InsideConnectivity::Six : InsideConnectivity::TwentySix;
    if (has("units")) {
        if (!is_surface_file(config.file))
            throw InputError(where("units") + " applies to surface files (.stl, .ply, .obj, .vtp, .msh) only",
                             "images carry their own spacing and phantoms are in mm; remove the key");
        config.units = image.units;
        try {
            config.units_to_mm = unit_to_mm(config.units);
        } catch (const InputError&) {
            throw InputError(where("units") + " = \"" + config.units + "\" is not a unit",
                             "choose \"mm\" (the default), \"cm\", \"m\" or \"um\"");
        }
    }
    return config;
}

} // namespace

CaseConfig::CaseConfig() { set_options(*this, MeshOptions{}); }

CaseConfig config_from_options(const MeshOptions& options, CaseConfig config)
{
    for (const OptionInfo& option : mesh_option_table()) {
        const std::string where = config.source + ": " +
                                  (option.section.empty() ? "" : "[" + option.section + "] ") + option.key;
        std::visit([&](auto member) { check_value(option, options.*member, where); }, option.member);
    }
    const std::optional<MeshLength>& L_max = options.L_max;
    if (L_max && L_max->voxels == options.L_min.voxels && L_max->value < options.L_min.value)
        throw InputError(config.source + ": [sizing] L_max (" + case_length(*L_max).text() + ") is below L_min (" +
                             case_length(options.L_min).text() + ")",
                         "L_min <= L_max is required: the zone of scale invariance is [L_min, L_max]");
    set_options(config, options);
    return config;
}

CaseConfig flow_from_options(double viscosity, double inlet_speed, CaseConfig config)
{
    config.viscosity = in_range(config.source + ": [flow] viscosity", viscosity, 0, 1, true);
    config.inlet_speed = in_range(config.source + ": [flow] inlet_speed", inlet_speed, 0, 1e3, true);
    return config;
}

CaseConfig msh_from_options(double version, bool binary, CaseConfig config)
{
    if (version != 4.1 && version != 2.2)
        throw InputError(config.source + ": [output] msh_version must be 4.1 or 2.2",
                         "4.1 is Gmsh's current format; 2.2 is read by older tools and gmshToFoam");
    config.msh_version = version;
    config.msh_binary = binary;
    return config;
}

CaseConfig input_from_options(const std::filesystem::path& file, const ImageOptions& image, CaseConfig config)
{
    config.file = file;
    const auto has = [&](const std::string& key) { return key == "units" && image.units != "mm"; };
    return checked_input(image, has, std::move(config));
}

CaseConfig openings_from_options(const std::vector<MeshOpening>& openings, CaseConfig config)
{
    config.openings.clear();
    std::set<std::string> names;
    for (size_t i = 0; i < openings.size(); ++i) {
        const MeshOpening& o = openings[i];
        const auto has = [&](const std::string& key) {
            return key == "type"     ? !o.type.empty()
                   : key == "point"  ? o.point.has_value()
                   : key == "normal" ? o.normal.has_value()
                   : key == "radius" ? o.radius != 0
                   : key == "border" ? !o.border.empty()
                   : key == "inset"  ? o.inset.has_value()
                   : key == "near"   ? o.near.has_value()
                   : key == "label"  ? o.label.has_value()
                                     : false;
        };
        config.openings.push_back(checked_opening(o, has, config.source, i, names));
    }
    return config;
}

std::string toml_string(const std::string& s)
{
    std::string out = "\"";
    for (char c : s) {
        if (c == '"' || c == '\\') out += '\\';
        out += c;
    }
    return out + "\"";
}

CaseConfig parse_case(const std::string& text, const std::filesystem::path& dir, const std::string& source)
{
    toml::table root;
    try {
        root = toml::parse(text, source);
    } catch (const toml::parse_error& e) {
        std::ostringstream msg;
        msg << source << ":" << e.source().begin.line << ":" << e.source().begin.column << ": " << e.description();
        throw InputError(msg.str(), "fix the TOML syntax at that line");
    }
    static const std::vector<std::string> sections = {"input",  "smoothing", "sizing", "remeshing",
                                                      "volume", "flow",      "output", "run", "openings"};
    for (const auto& [key, value] : root) {
        if (key.str() == "openings") {
            if (!value.is_array_of_tables())
                throw InputError(source + ": 'openings' must be an array of tables",
                                 "write each opening as a [[openings]] table (see docs/case-file.md)");
            continue;
        }
        if (std::find(sections.begin(), sections.end(), std::string(key.str())) == sections.end() || !value.is_table())
            throw InputError(source + ": '" + std::string(key.str()) + "' is not a known section",
                             "the sections are: [" + join(sections) + "]");
    }

    CaseConfig config;
    config.directory = dir;
    config.source = source;

    const Section input(root["input"].as_table(), "input", source,
                        {"phantom", "file", "voxel_size", "noise", "seed", "grid", "iso", "connectivity", "labels",
                         "threshold", "level_set", "units", "keep"});
    config.phantom = input.get<std::string>("phantom").value_or("");
    config.file = input.get<std::string>("file").value_or("");
    if (config.phantom.empty() == config.file.empty())
        throw InputError(source + ": [input] needs exactly one of 'phantom' and 'file'",
                         "write phantom = \"sphere\" (one of: " + join(phantom_names()) +
                             ") or file = \"image.vdb\"");
    if (!config.phantom.empty()) make_shape(config.phantom, 1.0); // refuses unknown names with the list
    if (!config.file.empty() && (input.has("voxel_size") || input.has("noise") || input.has("seed")))
        throw InputError(source + ": [input] voxel_size, noise and seed apply to phantoms only",
                         "an image file carries its own voxel size; remove those keys");
    config.voxel_size = input.number("voxel_size", config.voxel_size, 1e-5, 1e6); // OpenVDB cannot invert a smaller transform
    config.noise = input.number("noise", config.noise, 0, 10);
    const int64_t seed = input.get<int64_t>("seed").value_or(1);
    if (seed < 0) throw InputError(input.where("seed") + " must not be negative", "give a seed >= 0");
    config.seed = static_cast<uint64_t>(seed);
    // The keys of an image or surface file as the library's ImageOptions
    // holds them, read as their type; checked_input checks the values.
    ImageOptions image;
    image.grid = input.get<std::string>("grid").value_or("");
    if (input.has("labels")) {
        const toml::array* labels = root["input"]["labels"].as_array();
        if (!labels) throw InputError(input.where("labels") + " must be a list of integers", "write labels = [1]");
        for (const auto& item : *labels) {
            const auto v = item.value<int64_t>();
            if (!v || !item.is_integer() || *v < INT32_MIN || *v > INT32_MAX)
                throw InputError(input.where("labels") + " holds a value that is not an integer", "write labels = [1, 2]");
            image.labels.push_back(static_cast<int>(*v));
        }
    }
    image.threshold = input.get<double>("threshold");
    image.level_set = input.get<bool>("level_set").value_or(false);
    image.iso = input.get<double>("iso");
    const int64_t connectivity = input.get<int64_t>("connectivity").value_or(6);
    if (connectivity != 6 && connectivity != 26) refuse_connectivity(input.where("connectivity"), connectivity);
    image.connectivity = static_cast<int>(connectivity);
    image.units = input.get<std::string>("units").value_or("mm");
    config = checked_input(image, [&](const std::string& key) { return input.has(key); }, std::move(config));
    const std::string keep =
        input.choice("keep", {"all", "largest"}, "valid",
                     "choose \"all\" (every region of the segmentation, the default) or \"largest\" (the region "
                     "of the most voxels; stray islands are dropped)")
            .value_or("all");
    if (keep == "largest" && (config.level_set || is_surface_file(config.file)))
        throw InputError(input.where("keep") + " = \"largest\" applies to label images and phantoms",
                         "a level set or a surface file keeps its regions; remove the key");
    config.keep_largest = keep == "largest";

    // The meshing options, read as their kind (integers range-checked before
    // they are narrowed to their member), then checked and set by
    // config_from_options in the words it uses for the library's options.
    const Section smoothing(root["smoothing"].as_table(), "smoothing", source, option_keys("smoothing"));
    const Section sizing(root["sizing"].as_table(), "sizing", source, option_keys("sizing"));
    const Section remeshing(root["remeshing"].as_table(), "remeshing", source, option_keys("remeshing"));
    const Section volume(root["volume"].as_table(), "volume", source,
                         option_keys("volume", {"enabled", "min_layer_coverage", "min_aspect_ratio", "min_dihedral_deg"}));
    const Section run(root["run"].as_table(), "run", source, option_keys("run"));
    const std::map<std::string, const Section*> option_sections = {
        {"smoothing", &smoothing}, {"sizing", &sizing}, {"remeshing", &remeshing}, {"volume", &volume}, {"run", &run}};
    MeshOptions options;
    for (const OptionInfo& option : mesh_option_table())
        if (!option.section.empty()) read_option(*option_sections.at(option.section), option, options);
    config = config_from_options(options, std::move(config));

    config.volume = volume.get<bool>("enabled").value_or(true);
    config.min_layer_coverage = volume.number("min_layer_coverage", 0.99, 0.0, 1.0);
    config.min_aspect_ratio = volume.number("min_aspect_ratio", 0.1, 0.0, 1.0);
    config.min_dihedral_deg = volume.number("min_dihedral_deg", 10.0, 0.0, 70.0);

    if (const toml::array* openings = root["openings"].as_array()) {
        std::set<std::string> names;
        for (size_t i = 0; i < openings->size(); ++i) {
            const toml::table* table = (*openings)[i].as_table();
            const Section opening(table, "openings] [" + std::to_string(i + 1), source, opening_keys);
            // The table's keys as the library's MeshOpening holds them, read
            // as their type; checked_opening checks the values.
            MeshOpening given;
            given.name = opening.get<std::string>("name").value_or("");
            given.type = opening.get<std::string>("type").value_or("");
            const auto vector = [&](const std::string& key) -> std::optional<std::array<double, 3>> {
                if (!opening.has(key)) return std::nullopt;
                const toml::array* xyz = (*table)[key].as_array();
                std::array<double, 3> out;
                if (!xyz || xyz->size() != 3)
                    throw InputError(opening.where(key) + " must be a list of 3 numbers", "write " + key + " = [0, 0, 1]");
                for (size_t k = 0; k < 3; ++k) {
                    const auto value = (*xyz)[k].value<double>();
                    if (!value)
                        throw InputError(opening.where(key) + " must be a list of 3 numbers", "write " + key + " = [0, 0, 1]");
                    out[k] = *value;
                }
                return out;
            };
            given.point = vector("point");
            given.normal = vector("normal");
            given.near = vector("near");
            given.radius = opening.get<double>("radius").value_or(0);
            given.border = opening.get<std::string>("border").value_or("");
            // inset: "auto" (the default) leaves it empty.
            if (opening.has("inset") && opening.get<std::string>("inset").value_or("") != "auto") {
                const Length inset = opening.length("inset");
                given.inset = MeshLength{inset.value, inset.voxels};
            }
            if (opening.has("label")) {
                const auto label = opening.get<int64_t>("label");
                if (!label || *label < 0 || *label > std::numeric_limits<int32_t>::max()) refuse_label(opening.where("label"));
                given.label = static_cast<int32_t>(*label);
            }
            given.extension = opening.get<double>("extension").value_or(0);
            config.openings.push_back(checked_opening(given, [&](const std::string& key) { return opening.has(key); },
                                                      source, i, names));
        }
    }

    const Section flow(root["flow"].as_table(), "flow", source, {"viscosity", "inlet_speed"});
    config = flow_from_options(flow.get<double>("viscosity").value_or(config.viscosity),
                               flow.get<double>("inlet_speed").value_or(config.inlet_speed), std::move(config));

    const Section output(root["output"].as_table(), "output", source,
                         {"surface", "volume", "openfoam", "openfoam_format", "layer_prisms", "msh_version",
                          "msh_binary", "decompose"});
    // A list of output file names with one of the given extensions.
    const auto file_list = [&](const std::string& key, const std::vector<std::string>& extensions,
                               std::vector<std::string>& into) {
        if (!output.has(key)) return;
        const toml::array* files = root["output"][key].as_array();
        const std::string valid = join(extensions);
        if (!files)
            throw InputError(output.where(key) + " must be a list of file names",
                             "write " + key + " = [\"" + key + extensions.front() + "\"]");
        into.clear();
        for (const auto& item : *files) {
            const auto name = item.value<std::string>();
            const std::string ext = name ? std::filesystem::path(*name).extension().string() : "";
            if (!name || std::find(extensions.begin(), extensions.end(), ext) == extensions.end() ||
                std::filesystem::path(*name).has_parent_path())
                throw InputError(output.where(key) + " holds an invalid entry",
                                 "give file names without directories ending in " + valid);
            into.push_back(*name);
        }
    };
    file_list("surface", {".msh", ".vtk", ".stl"}, config.surface_outputs);
    file_list("volume", {".msh", ".vtk"}, config.volume_outputs);
    // Each output is written under its own name: two outputs of one name
    // would share one temporary file, and one named as a file the run reads
    // or writes besides would overwrite it.
    {
        std::map<std::string, std::string> taken = {{"report.json", "the name of the run's report"},
                                                    {"quality.png", "the name of the quality histograms"},
                                                    {"Allrun", "the name of the OpenFOAM case's script"},
                                                    {"scalemesh.toml", "the name of the case file"},
                                                    {"log.scalemesh", "the name of the run's log"}};
        if (!config.file.empty() && !config.file.has_parent_path())
            taken.emplace(config.file.string(), "the name of the input file");
        for (const auto& [key, names] : {std::pair<std::string, const std::vector<std::string>*>{"surface", &config.surface_outputs},
                                         {"volume", &config.volume_outputs}})
            for (const std::string& name : *names) {
                const auto [at, fresh] = taken.emplace(name, "named in [output] " + key);
                if (!fresh)
                    throw InputError(output.where(key) + " names \"" + name + "\", already " + at->second,
                                     "give each output its own file name");
            }
    }
    config.openfoam = output.get<bool>("openfoam").value_or(true);
    config.openfoam_binary =
        output.choice("openfoam_format", {"ascii", "binary"}, "a format").value_or("ascii") == "binary";
    config.layer_prisms = output.get<bool>("layer_prisms").value_or(true);
    config = msh_from_options(output.get<double>("msh_version").value_or(config.msh_version),
                              output.get<bool>("msh_binary").value_or(config.msh_binary), std::move(config));
    const int64_t decompose = output.get<int64_t>("decompose").value_or(1);
    if (decompose > std::numeric_limits<int32_t>::max())
        throw InputError(output.where("decompose") + " is more processor meshes than a mesh can have cells",
                         "give the number of processor meshes for a parallel run, e.g. decompose = 4");
    // Below 1, or with openfoam = false, refused by check_decompose once the
    // command line may have replaced it; the cell count bounds it too, checked
    // when the cells are known.
    config.decompose = static_cast<int32_t>(std::max<int64_t>(decompose, std::numeric_limits<int32_t>::min()));

    return config;
}

void check_decompose(const CaseConfig& config)
{
    const std::string key = config.decompose_on_command_line ? "--decompose" : "decompose";
    const std::string where = config.decompose_on_command_line
                                  ? "--decompose " + std::to_string(config.decompose)
                                  : config.source + ": [output] decompose";
    const std::string example = config.decompose_on_command_line ? "--decompose 4" : "decompose = 4";
    if (config.decompose < 1)
        throw InputError(where + " must be at least 1",
                         "give the number of processor meshes for a parallel run, e.g. " + example + ", or leave it out");
    if (config.decompose > 1 && !config.openfoam)
        throw InputError(where + " asks for processor meshes, but the case's [output] openfoam = false writes no "
                                 "OpenFOAM case",
                         "set openfoam = true in the case file, or leave " + key + " out");
}

CaseConfig read_case(const std::filesystem::path& dir)
{
    const std::filesystem::path file = dir / "scalemesh.toml";
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec))
        throw IoError(dir.string(), "no such case directory; give a directory holding scalemesh.toml");
    if (std::filesystem::exists(file, ec) && !std::filesystem::is_regular_file(file, ec))
        throw IoError(file.string(), "is not a file (a directory?); the case file must be a TOML text file");
    std::ifstream in(file);
    if (!in) throw IoError(file.string(), "no case file; a case directory needs a scalemesh.toml (see docs/case-file.md)");
    std::stringstream text;
    text << in.rdbuf();
    return parse_case(text.str(), dir, file.string());
}

} // namespace scalemesh
