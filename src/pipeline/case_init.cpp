#include "pipeline/case_init.h"

#include "core/errors.h"
#include "importers/image_importer.h"
#include "importers/vdb_importer.h"
#include "openings/open_ends.h"
#include "pipeline/case_config.h"
#include "pipeline/options_table.h"
#include "pipeline/pipeline.h"

#include <algorithm>
#include <cstdio>
#include <sstream>

namespace scalemesh {

namespace {

std::string number(double v)
{
    char text[32];
    std::snprintf(text, sizeof text, "%.6g", v);
    return text;
}

std::string point(const Vec3& p) { return "[" + number(p.x) + ", " + number(p.y) + ", " + number(p.z) + "]"; }

std::string lower_extension(const std::filesystem::path& file)
{
    std::string name = file.filename().string();
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
    if (name.size() > 7 && name.ends_with(".nii.gz")) return ".nii.gz";
    const size_t dot = name.rfind('.');
    return dot == std::string::npos ? "" : name.substr(dot);
}

// Otsu's threshold over a histogram of 256 equal bins on [lo, hi]: the bin
// edge that best separates the voxels into two classes.
double otsu_threshold(const std::vector<int64_t>& histogram, double lo, double hi)
{
    double total = 0, weighted = 0;
    for (size_t b = 0; b < histogram.size(); ++b) total += histogram[b], weighted += b * double(histogram[b]);
    double below = 0, below_weighted = 0, best = -1;
    size_t cut = histogram.size() / 2;
    for (size_t b = 0; b + 1 < histogram.size(); ++b) {
        below += histogram[b], below_weighted += b * double(histogram[b]);
        const double above = total - below;
        if (below == 0 || above == 0) continue;
        const double m0 = below_weighted / below, m1 = (weighted - below_weighted) / above;
        const double between = below * above * (m0 - m1) * (m0 - m1);
        if (between > best) best = between, cut = b + 1;
    }
    return lo + (hi - lo) * double(cut) / double(histogram.size());
}

// How the image's voxels become inside: [input] lines, and notes.
std::string image_reading(const std::filesystem::path& file, int64_t max_memory, std::vector<std::string>& notes)
{
    if (lower_extension(file) == ".vdb") {
        const openvdb::FloatGrid::Ptr grid = read_vdb(file);
        notes.push_back("grid '" + grid->getName() + "'" +
                        (grid->getGridClass() == openvdb::GRID_LEVEL_SET ? ", a level set: inside below 0"
                                                                         : ": inside where the value is above 0.5"));
        return "";
    }
    const ImageValues v = image_values(file, max_memory);
    std::ostringstream lines;
    if (!v.many) {
        std::vector<std::pair<double, int64_t>> labels;
        for (const auto& c : v.counts)
            if (c.first != 0) labels.push_back(c);
        if (labels.size() <= 1) {
            notes.push_back("a mask: every nonzero voxel is inside");
            return "";
        }
        std::string present;
        for (const auto& [value, voxels] : labels)
            present += (present.empty() ? "" : ", ") + number(value) + " (" + std::to_string(voxels) + " voxels)";
        lines << "# Labels present: " << present << ".\n"
              << "# Every nonzero label is inside; to mesh some of them only, list them:\n# labels = [";
        for (size_t i = 0; i < labels.size(); ++i) lines << (i ? ", " : "") << number(labels[i].first);
        lines << "]\n";
        notes.push_back("a label map with " + std::to_string(labels.size()) + " labels: " + present +
                        "; all are meshed as one (see labels in the case file)");
        return lines.str();
    }
    if (!v.integer && v.min < 0 && v.max > 0) {
        lines << "# Values from " << number(v.min) << " to " << number(v.max)
              << ", not integers, negative and positive: read as a signed distance, inside below 0.\n"
              << "level_set = true\n";
        notes.push_back("a level set (values from " + number(v.min) + " to " + number(v.max) + "): inside below 0");
        return lines.str();
    }
    const double t = otsu_threshold(v.histogram, v.min, v.max);
    lines << "# An intensity image, values from " << number(v.min) << " to " << number(v.max)
          << ". The threshold is Otsu's split of its histogram:\n"
          << "# check it against the lumen's intensity (inside is above it).\n"
          << "threshold = " << number(t) << "\n";
    notes.push_back("an intensity image (values from " + number(v.min) + " to " + number(v.max) +
                    "): threshold " + number(t) + " (Otsu's), check it");
    return lines.str();
}

// Runs the case up to its openings: what it finds, or the InputError. The
// case directory need not exist yet: the input file is named absolutely
// (`written` is how the text names it).
PipelineRun inspect(std::string text, const std::filesystem::path& dir, int64_t max_memory,
                    const std::string& written, const std::filesystem::path& absolute)
{
    const std::string line = "file = " + toml_string(written) + "\n";
    text.replace(text.find(line), line.size(), "file = " + toml_string(absolute.string()) + "\n");
    const CaseConfig config = parse_case(text, dir, "scalemesh init");
    return run_pipeline(config, {.sizing = false, .remesh = false, .volume = false, .max_memory = max_memory});
}

// The sections the case leaves at their defaults, commented out, with the
// values the case file reader takes without them: MeshOptions{}'s for the
// meshing options, CaseConfig{}'s for the floors, outputs and flow.
std::string default_sections()
{
    const MeshOptions defaults;
    const CaseConfig config;
    // "# key = value", its comment (if any) from `column` on.
    const auto line = [](const std::string& setting, const std::string& comment = "", size_t column = 24) {
        std::string text = "# " + setting;
        if (comment.empty()) return text + "\n";
        text.resize(std::max(text.size() + 2, column), ' ');
        return text + "# " + comment + "\n";
    };
    const auto list = [](const std::vector<std::string>& names) {
        std::string text;
        for (const std::string& name : names) text += (text.empty() ? "" : ", ") + toml_string(name);
        return "[" + text + "]";
    };
    const MeshLength& L_min = defaults.L_min;
    return "\n# Every other setting has its default; uncomment a line to change it\n"
           "# (docs/case-file.md has them all).\n\n[sizing]\n" +
           line("K = " + number_text(defaults.K), "anisotropy: surface edge length over layer thickness near the wall") +
           line("M = " + number_text(defaults.M), "element layers across a cross-section") +
           line("G = " + number_text(defaults.G), "gradient limit of the feature size") +
           line("L_min = \"" + number_text(L_min.value) + (L_min.voxels ? " voxels\"" : " mm\""),
                "the narrowest diameter that still gets M layers across") +
           line("L_max = \"100 mm\"", "the widest; default: the largest extent of the surface") + "\n[volume]\n" +
           line("min_layer_coverage = " + number_text(config.min_layer_coverage),
                "floors of the run: --strict fails a mesh below them", 30) +
           line("min_aspect_ratio = " + number_text(config.min_aspect_ratio)) +
           line("min_dihedral_deg = " + number_text(config.min_dihedral_deg)) + "\n[output]\n" +
           line("surface = " + list(config.surface_outputs)) + line("volume = " + list(config.volume_outputs)) +
           line(std::string("openfoam = ") + (config.openfoam ? "true" : "false"),
                "constant/polyMesh, system/, 0/ and Allrun") +
           "\n[flow]\n" + line("viscosity = " + number_text(config.viscosity), "m^2/s (blood)") +
           line("inlet_speed = " + number_text(config.inlet_speed), "m/s, uniform over each inlet");
}

} // namespace

InitialCase initial_case(const std::filesystem::path& file, const std::filesystem::path& dir, int64_t max_memory)
{
    InitialCase out;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec)) throw IoError(file.string(), "no such file; check the path");
    const std::filesystem::path absolute = std::filesystem::absolute(file).lexically_normal();
    const std::filesystem::path relative = absolute.lexically_relative(std::filesystem::absolute(dir).lexically_normal());
    // Relative where the file is in or beside the case directory, so that the
    // two move together; absolute where it is farther away.
    const std::string path =
        relative.empty() || relative.string().starts_with("../..") ? absolute.string() : relative.string();

    std::ostringstream input;
    input << "# scalemesh case, written by `scalemesh init` from " << file.filename().string()
          << ".\n# Run it with: scalemesh run " << dir.string() << "\n\n[input]\nfile = " << toml_string(path) << "\n";
    const bool image = is_image_file(file) || lower_extension(file) == ".vdb";
    std::string openings;
    if (image) {
        input << image_reading(file, max_memory, out.notes);
        const PipelineRun run = inspect(input.str(), dir, max_memory, path, absolute);
        std::vector<PipelineRun::BorderContact> sides = run.border_contacts;
        std::sort(sides.begin(), sides.end(), [](const auto& a, const auto& b) { return a.area > b.area; });
        std::ostringstream o;
        int outlets = 0;
        for (const auto& side : sides) {
            const bool inlet = &side == &sides.front();
            const std::string name = inlet ? "inlet" : sides.size() == 2 ? "outlet" : "outlet_" + std::to_string(++outlets);
            o << "\n# The segmentation touches the image's " << side.side << " side over " << number(side.area)
              << " mm^2 (" << side.voxels << " voxels): the vessel runs on beyond the image there.\n"
              << "[[openings]]\nname = " << toml_string(name) << "\ntype = " << (inlet ? "\"inlet\"" : "\"outlet\"")
              << "\nborder = " << toml_string(side.side) << "\n";
            out.notes.push_back("border opening '" + name + "' on the image's " + side.side + " side (" +
                                number(side.area) + " mm^2 touched)");
        }
        openings = (sides.size() > 1 ? "\n# The side touched over the largest area is taken as the inlet; check "
                                       "which way the flow goes.\n"
                                     : "") +
                   o.str();
        if (sides.empty()) out.notes.push_back("the segmentation touches no image side: a closed case, no openings");
        if (sides.size() == 1)
            out.notes.push_back("one opening only: a flow needs an outlet as well; add one (a clip plane with point "
                                "and normal) before running a flow");
    } else {
        // A surface: its unit, then its open ends and labelled caps.
        PipelineRun run = inspect(input.str(), dir, max_memory, path, absolute);
        if (const std::optional<std::string> unit = likely_units(run.surface, CaseConfig{})) {
            input << "units = " << toml_string(*unit) << "   # the file's coordinates are implausible in mm\n";
            out.notes.push_back("units \"" + *unit + "\": in mm the surface would be implausibly small or large");
            run = inspect(input.str(), dir, max_memory, path, absolute);
        }
        for (const LabelPart& part : run.label_parts) {
            const std::string what = part.cap ? "a flat cap, an opening" : part.wall ? "the wall" : "wall (" + why_not_a_cap(part) + ")";
            input << "# face label " << part.label << ": " << what << "\n";
        }
        std::ostringstream o;
        if (!run.caps.empty()) {
            o << "\n# Openings found by themselves (open ends and flat labelled caps), largest first the inlet.\n"
              << "# To rename, retype or reorder them, uncomment and edit (docs/case-file.md, Open ends):\n";
            for (const Cap& cap : run.caps) {
                o << "# [[openings]]\n# name = " << toml_string(cap.name) << "\n# type = "
                  << (cap.type == OpeningType::Inlet ? "\"inlet\"" : "\"outlet\"") << "\n# near = "
                  << point(cap.centroid) << "   # " << number(cap.area) << " mm^2\n";
                out.notes.push_back("opening '" + cap.name + "' (" +
                                    (cap.type == OpeningType::Inlet ? "inlet" : "outlet") + ", " + number(cap.area) +
                                    " mm^2 at " + point(cap.centroid) + ")");
            }
        } else {
            out.notes.push_back("a closed surface without flat labelled caps: a closed case, no openings; add "
                                "[[openings]] with clip planes to let a flow through");
        }
        openings = o.str();
    }

    out.text = input.str() + openings + default_sections();
    // The case as written must run: its input and openings are read and cut
    // once more; openings that fail are left commented out.
    try {
        inspect(out.text, dir, max_memory, path, absolute);
    } catch (const InputError& e) {
        if (openings.empty()) throw;
        std::string commented;
        std::istringstream lines(openings);
        for (std::string line; std::getline(lines, line);)
            commented += (line.empty() || line[0] == '#' ? line : "# " + line) + "\n";
        out.text = input.str() + "\n# These openings could not be cut: " + e.what() + "\n" + commented + default_sections();
        out.notes.push_back(std::string("the openings are commented out: ") + e.what());
        inspect(out.text, dir, max_memory, path, absolute);
    }
    return out;
}

} // namespace scalemesh
