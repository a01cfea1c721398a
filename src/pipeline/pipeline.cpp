#include "pipeline/pipeline.h"
#include "pipeline/run_case.h"

#include "core/errors.h"
#include "importers/image_importer.h"
#include "volume/self_intersections.h"
#include "importers/surface_importer.h"
#include "importers/vdb_importer.h"
#include "isosurface/marching_cubes.h"
#include "phantom/phantom.h"
#include "pipeline/memory_estimate.h"
#include "smoothing/volume_conserving_smoothing.h"
#include "volume/quality.h"

#include <openvdb/tools/LevelSetUtil.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>

namespace scalemesh {

namespace {

// Attempts of the volume stage, and how much d shrinks near failing nodes
// between them (section 2.3's "re-run with a higher surface density").
constexpr int kConformityAttempts = 5;
constexpr double kRefinementFactor = 0.7;

class StageClock {
public:
    StageClock(PipelineRun& run, const StageListener& listener, std::string name)
        : run_(run), listener_(listener), name_(std::move(name)), start_(std::chrono::steady_clock::now())
    {
        if (listener_) listener_({name_, -1.0, ""});
    }
    void done(std::string summary)
    {
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
        run_.stages.push_back({name_, seconds, std::move(summary)});
        if (listener_) listener_(run_.stages.back());
    }

private:
    PipelineRun& run_;
    const StageListener& listener_;
    std::string name_;
    std::chrono::steady_clock::time_point start_;
};

std::string file_checksum(const std::filesystem::path& path)
{
    std::ifstream in(path, std::ios::binary);
    uint64_t hash = 0xcbf29ce484222325ull;
    char buffer[1 << 16];
    while (in) {
        in.read(buffer, sizeof buffer);
        for (std::streamsize i = 0; i < in.gcount(); ++i) {
            hash ^= static_cast<unsigned char>(buffer[i]);
            hash *= 0x100000001b3ull;
        }
    }
    char text[17];
    std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(hash));
    return text;
}

std::string describe(const SurfaceFacts& f)
{
    std::ostringstream out;
    out << f.triangles << " triangles, " << f.vertices << " vertices, " << f.components << " component"
        << (f.components == 1 ? "" : "s") << ", Euler characteristic " << f.euler_characteristic << ", volume "
        << f.signed_volume << " mm^3";
    return out.str();
}

double mean_edge_length(const SurfaceMesh& mesh)
{
    double sum = 0;
    for (const Triangle& t : mesh.triangles)
        for (int k = 0; k < 3; ++k) sum += distance(mesh.points[t[k]], mesh.points[t[(k + 1) % 3]]);
    return mesh.triangles.empty() ? 0.0 : sum / (3.0 * static_cast<double>(mesh.triangles.size()));
}

// Scales d down at the points of `surface` near the remeshed surface's
// failing nodes: within one target edge length (K/M d) of one. Returns how
// many points changed.
int64_t refine_near(const SurfaceMesh& surface, const SurfaceMesh& remeshed, const std::vector<int32_t>& failing,
                    double K_over_M, std::vector<double>& d)
{
    int64_t changed = 0;
    for (size_t i = 0; i < surface.points.size(); ++i) {
        const double reach = K_over_M * d[i];
        for (int32_t node : failing)
            if (norm2(surface.points[i] - remeshed.points[node]) <= reach * reach) {
                d[i] *= kRefinementFactor;
                ++changed;
                break;
            }
    }
    return changed;
}

// With openings, a separate region of the lumen that no opening reaches
// carries no flow and leaves the pressure equation without a reference there
// (simpleFoam fails on it): the components of the surface that bound such a
// region from outside (positive enclosed volume, no cap triangle) are removed.
// A component with negative volume is the wall of a cavity inside another
// region and stays. Returns how many components were removed and their volume.
std::pair<int64_t, double> drop_closed_regions(SurfaceMesh& surface)
{
    int32_t count = 0;
    const std::vector<int32_t> component = triangle_components(surface, &count);
    std::vector<double> volume(count, 0.0);
    std::vector<char> capped(count, 0);
    for (size_t f = 0; f < surface.triangles.size(); ++f) {
        const Triangle& t = surface.triangles[f];
        volume[component[f]] += dot(surface.points[t[0]], cross(surface.points[t[1]], surface.points[t[2]])) / 6.0;
        if (!surface.triangle_patch.empty() && surface.triangle_patch[f] != 0) capped[component[f]] = 1;
    }
    std::vector<char> drop(count, 0);
    int64_t dropped = 0;
    double dropped_volume = 0;
    for (int32_t c = 0; c < count; ++c)
        if (!capped[c] && volume[c] > 0) drop[c] = 1, ++dropped, dropped_volume += volume[c];
    if (dropped == 0) return {0, 0.0};

    SurfaceMesh kept;
    std::vector<int32_t> index(surface.points.size(), -1);
    for (size_t f = 0; f < surface.triangles.size(); ++f) {
        if (drop[component[f]]) continue;
        Triangle t = surface.triangles[f];
        for (int32_t& v : t) {
            if (index[v] < 0) {
                index[v] = static_cast<int32_t>(kept.points.size());
                kept.points.push_back(surface.points[v]);
            }
            v = index[v];
        }
        kept.triangles.push_back(t);
        if (!surface.triangle_patch.empty()) kept.triangle_patch.push_back(surface.triangle_patch[f]);
    }
    surface = std::move(kept);
    return {dropped, dropped_volume};
}

// What a memory estimate counted, for its message.
std::string points_basis(double points, double M, const std::string& from)
{
    std::ostringstream out;
    out << "about ";
    if (points < 1e12) out << std::llround(points);
    else out << std::setprecision(3) << points; // beyond what llround holds
    out << " volume mesh points for M = " << M << " layers, " << from;
    return out.str();
}

// Algorithm 1's parameters for a case, with L_min and L_max in mm as the run
// resolved them.
SizingParams sizing_params(const CaseConfig& config, const PipelineRun& run)
{
    SizingParams params;
    params.K = config.K;
    params.M = config.M;
    params.G = config.G;
    params.L_min = run.L_min;
    params.L_max = run.L_max;
    params.curvature_term = config.curvature;
    params.threads = config.threads;
    return params;
}

// Whether `name` can be an opening's patch name: a word of letters, digits
// and '_' not starting with a digit, and not "wall".
bool patch_name(const std::string& name)
{
    return !name.empty() && name != "wall" && !std::isdigit(static_cast<unsigned char>(name[0])) &&
           std::all_of(name.begin(), name.end(),
                       [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; });
}

// The warning for a surface whose size is implausible for a vessel, an
// airway or a heart in its declared unit, with the likely unit; empty when
// it is plausible (0.5 mm to 2 m across).
struct Unit {
    const char* name;
    double to_mm;
};
constexpr Unit kUnits[] = {{"um", 1e-3}, {"mm", 1}, {"cm", 10}, {"m", 1000}};

double surface_size(const SurfaceMesh& surface)
{
    Vec3 lo, hi;
    bounding_box(surface, lo, hi);
    return std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
}

// The unit that puts the size closest to 50 mm (on a log scale), when the
// size (mm, read in config's unit) is outside 0.5 mm to 2 m.
const Unit* likely_unit(double size, const CaseConfig& config)
{
    if (size >= 0.5 && size <= 2000) return nullptr;
    const double file_size = size / config.units_to_mm;
    const Unit* likely = &kUnits[0];
    for (const Unit& u : kUnits)
        if (std::abs(std::log(file_size * u.to_mm / 50)) < std::abs(std::log(file_size * likely->to_mm / 50)))
            likely = &u;
    return likely;
}

std::string units_warning(const SurfaceMesh& surface, const CaseConfig& config)
{
    const double size = surface_size(surface);
    const Unit* likely = likely_unit(size, config);
    if (!likely) return "";
    const double file_size = size / config.units_to_mm;
    char line[400];
    std::snprintf(line, sizeof line,
                  "the surface is %.4g mm across, implausible for an anatomy read in %s; if the file is in %s, "
                  "set [input] units = \"%s\" (it would be %.4g mm across)",
                  size, config.units.c_str(), likely->name, likely->name, file_size * likely->to_mm);
    return line;
}

// Where `surface` crosses itself, in words ("" where it does not).
std::string crossing_text(const SurfaceMesh& surface, const std::string& what)
{
    const SelfIntersections crossing = self_intersections(surface, 1);
    if (crossing.pairs == 0) return "";
    const auto centre = [&](int32_t t) {
        const Triangle& f = surface.triangles[t];
        return (surface.points[f[0]] + surface.points[f[1]] + surface.points[f[2]]) / 3;
    };
    const Vec3 where = (centre(crossing.first[0][0]) + centre(crossing.first[0][1])) / 2;
    std::ostringstream msg;
    msg << what << " intersects itself: " << crossing.pairs << (crossing.pairs == 1 ? " pair" : " pairs")
        << " of triangles cross, the first near (" << where.x << ", " << where.y << ", " << where.z << ") mm";
    return msg.str();
}

// A surface that crosses itself is refused before any stage runs on it:
// the feature size falls to nothing at the crossing and remeshing would
// refine there without end.
void require_no_self_intersections(const SurfaceMesh& surface, const std::string& what)
{
    if (const std::string crossing = crossing_text(surface, what); !crossing.empty())
        throw InputError(crossing, "a surface that crosses itself encloses no one region to mesh; remove the "
                                   "overlapping or duplicated parts, or repair the crossings (a self-intersection "
                                   "repair such as MeshLab's or meshfix), and re-run");
}

// Reads a surface file into `surface`, closed and oriented outwards. Labelled
// flat caps are taken out and every open end is closed by a fan, to be cut
// flat by the openings stage (openings/open_ends.h). Returns the import
// stage's line.
std::string import_surface(LabelledSurface read, const std::string& what, const CaseConfig& config, PipelineRun& run,
                           SurfaceMesh& surface)
{
    surface = std::move(read.mesh);
    std::ostringstream note;
    note << "read " << surface.triangles.size() << " triangles"
         << (config.units == "mm" ? "" : " in " + config.units + ", scaled to mm");
    std::vector<int32_t> loop_labels;
    if (!read.labels.empty()) {
        LabelCaps caps = remove_label_caps(surface, read.labels.per_triangle);
        run.label_source = read.labels.source;
        run.label_names = read.labels.names;
        run.label_parts = caps.parts;
        note << "; " << caps.parts.size() << " face label" << (caps.parts.size() == 1 ? "" : "s") << " ("
             << read.labels.source << "):";
        for (const LabelPart& part : caps.parts) {
            note << " " << part.label;
            const auto name = read.labels.names.find(part.label);
            if (name != read.labels.names.end()) note << " '" << name->second << "'";
            note << (part.cap ? " flat cap" : " wall");
            // A label nearly flat but refused as a cap is most likely a cap
            // the tolerance missed: why, and by how much.
            if (!part.cap && !part.wall && part.flatness <= 1e-3) {
                note << " (" << why_not_a_cap(part) << ")";
                run.warnings.push_back("face label " + std::to_string(part.label) + " of " + what +
                                       " is nearly flat but taken as wall, not as an opening: " + why_not_a_cap(part));
            }
            note << (&part == &caps.parts.back() ? "" : ",");
        }
        surface = std::move(caps.surface);
        loop_labels = std::move(caps.loop_label);
    }
    run.voxel_width = mean_edge_length(surface);
    if (surface_facts(surface).boundary_edges > 0) {
        ClosedEnds closed = close_open_ends(surface, what, loop_labels);
        surface = std::move(closed.surface);
        run.open_ends = std::move(closed.ends);
        int64_t own = 0;
        for (const OpenEnd& end : run.open_ends) own += end.label < 0;
        if (own > 0) note << "; " << own << " open end" << (own == 1 ? "" : "s") << ", to be cut flat and capped";
        if (closed.flipped) note << "; wound inwards: reversed";
    } else {
        require_closed_manifold(surface, what);
        if (orient_outward(surface)) note << "; wound inwards: reversed";
    }
    require_no_self_intersections(surface, what);
    run.isosurface = surface_facts(surface);
    if (const std::string warning = units_warning(surface, config); !warning.empty()) run.warnings.push_back(warning);
    return note.str();
}

// A segmentation that reaches a side of its image was most likely cut there
// by the scan: without a border opening on that side the vessel is meshed
// closed at the image's edge. Warned of, with the area it touches.
void warn_of_border_contact(const openvdb::FloatGrid& grid, const ImageFrame& frame, const CaseConfig& config,
                            PipelineRun& run)
{
    std::array<int64_t, 6> touching{}; // voxels on the sides x-, x+, y-, y+, z-, z+
    for (auto v = grid.cbeginValueOn(); v; ++v) {
        const openvdb::Coord c = v.getCoord();
        for (int k = 0; k < 3; ++k) {
            touching[2 * k] += c[k] == 0;
            touching[2 * k + 1] += c[k] == frame.size[k] - 1;
        }
    }
    static const char* const kSides[6] = {"x-", "x+", "y-", "y+", "z-", "z+"};
    for (int s = 0; s < 6; ++s) {
        if (touching[s] == 0) continue;
        bool opened = false;
        for (const CaseConfig::Opening& opening : config.openings)
            opened = opened || (opening.spec.border && opening.spec.side == kSides[s]);
        const int k = s / 2;
        const double face = norm(cross(frame.axis[(k + 1) % 3], frame.axis[(k + 2) % 3]));
        run.border_contacts.push_back({kSides[s], face * static_cast<double>(touching[s]), touching[s], opened});
        if (opened) continue;
        char line[400];
        std::snprintf(line, sizeof line,
                      "the segmentation touches the image's %s side over %.4g mm^2 (%lld voxels) and is meshed "
                      "closed there; if the vessel runs on beyond the image, add an opening with border = \"%s\"",
                      kSides[s], face * static_cast<double>(touching[s]), static_cast<long long>(touching[s]),
                      kSides[s]);
        run.warnings.push_back(line);
    }
}

// A clip plane's point belongs inside the lumen: one farther from the
// surface's bounding box than the box is large is refused, with the units
// it would fit.
void check_opening_points(const CaseConfig& config, const SurfaceMesh& surface)
{
    Vec3 lo, hi;
    bounding_box(surface, lo, hi);
    const double size = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    for (const CaseConfig::Opening& opening : config.openings) {
        const bool plane = !opening.spec.border && !opening.near && !opening.label;
        const std::optional<Vec3> point = plane ? std::optional<Vec3>(opening.spec.plane.point) : opening.near;
        if (!point) continue;
        Vec3 outside;
        for (int k = 0; k < 3; ++k) outside[k] = std::max({lo[k] - (*point)[k], 0.0, (*point)[k] - hi[k]});
        if (norm(outside) <= size) continue;
        std::ostringstream msg;
        msg << "opening '" << opening.spec.name << "': its point (" << point->x << ", " << point->y << ", "
            << point->z << ") mm is " << norm(outside) << " mm outside the surface, which spans (" << lo.x << ", "
            << lo.y << ", " << lo.z << ") to (" << hi.x << ", " << hi.y << ", " << hi.z << ") mm";
        std::string hint = "give a point inside the lumen, in mm";
        if (norm(*point) > 100 * size) hint += "; the point looks like it is in smaller units than the surface "
                                               "(check [input] units and the point's unit)";
        else if (norm(*point) * 100 < size) hint += "; the point looks like it is in larger units (metres?) "
                                                    "than the surface (points are in mm)";
        throw InputError(msg.str(), hint);
    }
}

// Smoothing keeps the open ends where they are: the fan centres fixed and
// the loop nodes within their end's plane, so that the openings stage cuts
// them flat just inside the loop.
SmoothingConstraint open_end_constraint(const PipelineRun& run, size_t points)
{
    SmoothingConstraint constraint;
    if (run.open_ends.empty()) return constraint;
    constraint.fixed.assign(points, 0);
    constraint.plane_normal.assign(points, Vec3{0, 0, 0});
    for (const OpenEnd& end : run.open_ends) {
        constraint.fixed[end.centre_point] = 1;
        for (int32_t p : end.loop) constraint.plane_normal[p] = end.normal;
    }
    return constraint;
}

// The openings of the open ends: those the case file names by `near` or
// `label`, in the file's order, then the others by decreasing area, the
// largest named "inlet" when the case file gives no inlet, the others
// outlet_1, outlet_2, ... (a labelled cap without a case-file name: its
// label's name from the file, else cap_<label>).
std::vector<OpeningSpec> end_openings(const CaseConfig& config, const PipelineRun& run)
{
    std::vector<OpeningSpec> specs;
    for (const CaseConfig::Opening& opening : config.openings)
        if ((opening.near || opening.label) && run.open_ends.empty())
            throw InputError("opening '" + opening.spec.name + "' names an open end (near or label), but " +
                                 (run.input.empty() ? "the input" : run.input) +
                                 " has no open ends or flat labelled caps",
                             "give a clip plane (point and normal) or a border side instead");
    if (run.open_ends.empty()) return specs;
    std::vector<char> taken(run.open_ends.size(), 0);
    std::set<std::string> used;
    bool inlet = false;
    for (const CaseConfig::Opening& opening : config.openings) {
        used.insert(opening.spec.name);
        inlet |= opening.spec.type == OpeningType::Inlet;
    }
    const auto margin = [](const OpenEnd& end) { return 0.25 * end.mean_edge; };
    for (const CaseConfig::Opening& opening : config.openings) {
        if (!opening.near && !opening.label) continue;
        size_t best = run.open_ends.size();
        if (opening.label) {
            for (size_t i = 0; i < run.open_ends.size(); ++i)
                if (run.open_ends[i].label == *opening.label) best = i;
            if (best == run.open_ends.size()) {
                std::string have, why;
                for (const LabelPart& part : run.label_parts) {
                    if (part.cap) have += (have.empty() ? "" : ", ") + std::to_string(part.label);
                    if (part.label == *opening.label && !part.cap) why = ": label " + std::to_string(part.label) +
                                                                       " is there, but " + why_not_a_cap(part);
                }
                throw InputError("opening '" + opening.spec.name + "': no flat labelled cap has label " +
                                     std::to_string(*opening.label) +
                                     (run.label_source.empty() ? " (the input has no face labels)"
                                                               : " (" + run.label_source + ")") + why,
                                 have.empty() ? "name the opening by near = [x, y, z] or give a clip plane"
                                              : "choose one of the cap labels: " + have);
            }
        } else {
            double nearest = INFINITY;
            for (size_t i = 0; i < run.open_ends.size(); ++i) {
                const double d = distance(run.open_ends[i].centre, *opening.near);
                if (d < nearest) {
                    nearest = d;
                    best = i;
                }
            }
            const OpenEnd& end = run.open_ends[best];
            if (nearest > 2 * end.radius + 0.5 * end.mean_edge) {
                std::ostringstream msg;
                msg << "opening '" << opening.spec.name << "': near = (" << opening.near->x << ", " << opening.near->y
                    << ", " << opening.near->z << ") mm is " << nearest << " mm from the nearest open end, centred at ("
                    << end.centre.x << ", " << end.centre.y << ", " << end.centre.z << ") with radius " << end.radius
                    << " mm";
                throw InputError(msg.str(), "give a point within the end's radius of its centre (the open ends are "
                                            "listed on the import line); if it is far off, check [input] units");
            }
        }
        if (taken[best])
            throw InputError("opening '" + opening.spec.name + "' names the same open end as an earlier opening",
                             "give each opening its own end");
        taken[best] = 1;
        specs.push_back(end_opening(run.open_ends[best], opening.spec.name, opening.spec.type, margin(run.open_ends[best])));
        specs.back().extension = opening.spec.extension;
    }
    int outlet = 0;
    for (size_t i = 0; i < run.open_ends.size(); ++i) {
        if (taken[i]) continue;
        const OpenEnd& end = run.open_ends[i];
        const OpeningType type = inlet ? OpeningType::Outlet : OpeningType::Inlet;
        std::string name;
        if (end.label >= 0) {
            const auto it = run.label_names.find(end.label);
            name = it != run.label_names.end() && patch_name(it->second) ? it->second
                                                                          : "cap_" + std::to_string(end.label);
        } else if (type == OpeningType::Inlet) {
            name = "inlet";
        } else {
            do name = "outlet_" + std::to_string(++outlet);
            while (used.count(name));
        }
        if (!used.insert(name).second)
            throw InputError("open end at (" + std::to_string(end.centre.x) + ", " + std::to_string(end.centre.y) +
                                 ", " + std::to_string(end.centre.z) + ") would be named '" + name +
                                 "', which another opening has",
                             "name this end in the case file: [[openings]] with name, type and near = [x, y, z]");
        inlet = true;
        specs.push_back(end_opening(end, name, type, margin(end)));
    }
    return specs;
}

} // namespace

namespace {

// The stages in order; run_pipeline runs them inside the case's task arena.
PipelineRun run_stages(const CaseConfig& config, const PipelineOptions& options, const StageListener& listener)
{
    PipelineRun run;
    SurfaceMesh surface;
    // Index-to-world map of the image, for border openings; for a surface
    // input the world axes with voxel-width steps.
    ImageFrame frame;
    const std::filesystem::path file = config.file.empty() || config.file.is_absolute() || config.directory == "."
                                           ? config.file
                                           : config.directory / config.file;
    const std::string ext = file.extension().string();

    if (options.surface) {
        StageClock clock(run, listener, "import");
        run.input = "surface given by the caller";
        clock.done(import_surface(*options.surface, "the input surface", config, run, surface));
    } else if (!config.file.empty() && is_surface_file(file)) {
        StageClock clock(run, listener, "import");
        run.input = file.string();
        run.input_checksum = file_checksum(file);
        clock.done(import_surface(read_labelled_surface(file, config.units_to_mm), file.string(), config, run, surface));
    } else {
        openvdb::FloatGrid::Ptr grid;
        {
            StageClock clock(run, listener, "import");
            if (!config.phantom.empty()) {
                const auto shape = make_shape(config.phantom, config.voxel_size);
                grid = voxelize(*shape, {config.voxel_size, config.noise, config.seed});
                run.input = "phantom:" + config.phantom;
            } else if (options.image) {
                grid = image_grid(*options.image, {config.labels, config.threshold, config.level_set,
                                                   options.max_memory > 0 ? options.max_memory : physical_memory()});
                run.input = "image given by the caller";
            } else if (ext == ".vdb") {
                grid = read_vdb(file, {config.grid});
                run.input = file.string();
                run.input_checksum = file_checksum(file);
            } else if (is_image_file(file)) {
                grid = read_image(file, {config.labels, config.threshold, config.level_set,
                                         options.max_memory > 0 ? options.max_memory : physical_memory()});
                run.input = file.string();
                run.input_checksum = file_checksum(file);
            } else {
                throw InputError("cannot read '" + file.string() + "': unknown input format '" + ext + "'",
                                 "give an image (.vdb, .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd, .vti) or a "
                                 "surface (.stl, .ply, .obj, .vtp, .msh)");
            }
            if (config.keep_largest && !is_level_set(*grid)) {
                // Face-connected regions of inside voxels, largest first.
                std::vector<openvdb::FloatGrid::Ptr> regions;
                openvdb::tools::segmentActiveVoxels(*grid, regions);
                if (regions.size() > 1) {
                    run.islands_dropped = static_cast<int64_t>(regions.size() - 1);
                    for (size_t r = 1; r < regions.size(); ++r)
                        run.island_voxels += static_cast<int64_t>(regions[r]->activeVoxelCount());
                    openvdb::FloatGrid::Ptr kept = grid->copyWithNewTree(); // transform and metadata kept
                    kept->setTree(regions.front()->treePtr());
                    grid = kept;
                }
            }
            const openvdb::math::Transform& transform = grid->transform();
            const openvdb::Vec3d origin = transform.indexToWorld(openvdb::Vec3d(0, 0, 0));
            frame.origin = {origin.x(), origin.y(), origin.z()};
            for (int k = 0; k < 3; ++k) {
                openvdb::Vec3d unit(0, 0, 0);
                unit[k] = 1;
                const openvdb::Vec3d axis = transform.indexToWorld(unit) - origin;
                frame.axis[k] = {axis.x(), axis.y(), axis.z()};
            }
            // The image faces, for border openings (phantoms and .vdb grids
            // without the metadata: the outermost surface point stands in).
            if (const auto size = grid->getMetadata<openvdb::Vec3IMetadata>("image_size"))
                for (int k = 0; k < 3; ++k) frame.size[k] = size->value()[k];
            const openvdb::Vec3d spacing = grid->voxelSize();
            run.voxel_width = std::min({spacing.x(), spacing.y(), spacing.z()});
            if (is_level_set(*grid)) {
                clock.done(std::to_string(grid->activeVoxelCount()) + " voxels of a level set, " +
                           std::to_string(run.voxel_width) + " mm");
            } else {
                run.inside_voxels = static_cast<int64_t>(grid->activeVoxelCount());
                if (frame.size[0] > 0) warn_of_border_contact(*grid, frame, config, run);
                std::string islands;
                if (run.islands_dropped > 0)
                    islands = "; the largest region kept, " + std::to_string(run.islands_dropped) + " other" +
                              (run.islands_dropped == 1 ? "" : "s") + " of " + std::to_string(run.island_voxels) +
                              " voxels dropped (keep = \"largest\")";
                clock.done(std::to_string(grid->activeVoxelCount()) + " inside voxels of " +
                           std::to_string(run.voxel_width) + " mm" + islands);
            }
        }
        StageClock clock(run, listener, "isosurface");
        surface = marching_cubes(*grid, {config.iso, config.connectivity});
        run.isosurface = surface_facts(surface);
        clock.done(describe(run.isosurface));
    }

    {
        StageClock clock(run, listener, "smoothing");
        SmoothingParams smoothing = config.smoothing;
        smoothing.max_displacement = config.smoothing_reach.mm(run.voxel_width);
        const SmoothingConstraint ends = open_end_constraint(run, surface.points.size());
        smooth_volume_conserving(surface, smoothing, run.open_ends.empty() ? nullptr : &ends);
        run.facts = surface_facts(surface);
        clock.done(std::to_string(config.smoothing.sweeps) + " sweeps, omega " + std::to_string(config.smoothing.omega) +
                   ", volume change " + std::to_string(run.facts.signed_volume - run.isosurface.signed_volume) + " mm^3");
    }

    check_opening_points(config, surface);
    if (!config.openings.empty() || !run.open_ends.empty()) {
        StageClock clock(run, listener, "openings");
        if (options.surface || (!config.file.empty() && is_surface_file(file))) {
            // No image: border sides follow the world axes.
            for (int k = 0; k < 3; ++k) {
                frame.axis[k] = Vec3{0, 0, 0};
                frame.axis[k][k] = run.voxel_width;
            }
        }
        std::vector<OpeningSpec> specs;
        for (const CaseConfig::Opening& opening : config.openings) {
            if (opening.near || opening.label) continue; // an open end: end_openings below
            specs.push_back(opening.spec);
            if (opening.spec.inset) specs.back().inset = opening.inset.mm(run.voxel_width);
        }
        for (OpeningSpec& end : end_openings(config, run)) specs.push_back(std::move(end));
        CappedSurface capped = cut_and_cap(surface, specs, frame);
        surface = std::move(capped.surface);
        run.caps = std::move(capped.caps);
        run.warnings.insert(run.warnings.end(), capped.warnings.begin(), capped.warnings.end());
        std::tie(run.closed_regions_dropped, run.closed_regions_volume) = drop_closed_regions(surface);
        run.opened = surface_facts(surface);
        std::ostringstream summary;
        summary << run.caps.size() << " cap" << (run.caps.size() == 1 ? "" : "s") << ":";
        for (const Cap& cap : run.caps) summary << " " << cap.name << " (" << cap.area << " mm^2)";
        // Border openings: where the plane went, and the pieces of the lumen
        // that stop short of the image face (no cap, a dead end).
        for (const BorderCut& border : capped.borders) {
            summary << "; " << border.opening << " at " << border.inset << " mm ("
                    << border.inset / border.voxel << " voxels" << (border.automatic ? ", auto" : "")
                    << (border.automatic && !border.stable ? ", never settled" : "") << ") inside the "
                    << border.side << " side";
            for (const ShortPiece& piece : border.short_pieces)
                summary << ", a piece " << piece.distance << " mm short of the "
                        << (border.face_known ? "image face" : "outermost point") << " not capped";
        }
        if (run.closed_regions_dropped > 0)
            summary << "; " << run.closed_regions_dropped << " separate region"
                    << (run.closed_regions_dropped == 1 ? "" : "s") << " without an opening left out ("
                    << run.closed_regions_volume << " mm^3)";
        summary << "; " << describe(run.opened);
        clock.done(summary.str());
    }

    run.L_min = config.L_min.mm(run.voxel_width);
    if (config.L_max) {
        run.L_max = config.L_max->mm(run.voxel_width);
    } else {
        Vec3 lo, hi;
        bounding_box(surface, lo, hi);
        run.L_max = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    }
    if (run.L_min > run.L_max)
        throw InputError("L_min = " + std::to_string(run.L_min) + " mm is above L_max = " + std::to_string(run.L_max) +
                             " mm",
                         "lower [sizing] L_min or raise L_max");
    {
        // d >= L_min wherever the surface is not close to itself outside, so
        // the remeshed edges are at least K/M L_min long: when that is longer
        // than the whole surface, remeshing collapses it (caps vanish first).
        Vec3 lo, hi;
        bounding_box(surface, lo, hi);
        const double across = distance(lo, hi);
        const double shortest_edge = config.K / config.M * run.L_min;
        if (options.remesh && shortest_edge > across) {
            std::ostringstream what;
            what << "L_min = " << run.L_min << " mm asks for surface edges of at least K/M L_min = " << shortest_edge
                 << " mm, longer than the whole surface is across (" << across
                 << " mm, its bounding box's diagonal): remeshing would collapse it";
            throw InputError(what.str(), "give [sizing] L_min below the narrowest vessel diameter to be resolved "
                                         "(L_min is the smallest diameter that gets M layers)");
        }
    }

    // Resource limits: the estimated peak memory is checked before each heavy
    // stage, so that a case too large stops with advice rather than being
    // killed (pipeline/memory_estimate.h).
    run.memory_bound = options.max_memory > 0 ? options.max_memory : physical_memory();
    const auto surface_triangles = static_cast<int64_t>(surface.triangles.size());
    require_memory(estimate_peak_memory(surface_triangles, 0), run.memory_bound,
                   std::to_string(surface_triangles) + " surface triangles");

    if (options.sizing) {
        StageClock clock(run, listener, "sizing");
        run.sizing = run.caps.empty() ? compute_feature_size(surface, sizing_params(config, run))
                                      : cap_feature_size(surface, run.caps, sizing_params(config, run));
        const auto [dmin, dmax] = std::minmax_element(run.sizing->d.begin(), run.sizing->d.end());
        std::ostringstream summary;
        summary << "d in [" << *dmin << ", " << *dmax << "] mm, " << run.sizing->D.size() * 2 << " rays";
        clock.done(summary.str());
    }
    run.surface = std::move(surface);

    if (!options.remesh || !run.sizing) return run;
    if (options.volume) {
        const double points = remeshed_volume_points(run.surface, *run.sizing, config.K, config.M, run.L_max);
        run.memory_estimate_remeshing = estimate_peak_memory(surface_triangles, points);
        require_memory(run.memory_estimate_remeshing, run.memory_bound,
                       points_basis(points, config.M,
                                    "from the feature size on " + std::to_string(surface_triangles) +
                                        " surface triangles"));
    }
    RemeshParams remesh;
    remesh.K = config.K;
    remesh.M = config.M;
    remesh.cycles = config.remesh_cycles;
    remesh.max_displacement = config.smoothing_reach.mm(run.voxel_width);
    remesh.sizing = sizing_params(config, run);
    remesh.patch_normals = patch_normals(run.caps);
    VolumeParams volume;
    volume.K = config.K;
    volume.M = config.M;
    volume.growth = config.growth;
    volume.L_max = run.L_max;
    volume.L_min = run.L_min;
    volume.layer_tolerance = config.layer_tolerance;
    volume.first_layer = config.first_layer;
    volume.layers = config.layers;
    volume.aspect_ratio_floor = config.min_aspect_ratio;

    // Section 2.3: where the volume mesh cannot conform to the surface, the
    // surface is refined there (d reduced around the failing nodes) and
    // remeshed, and the volume stage re-run, a bounded number of times.
    std::vector<double> d = run.sizing->d;
    run.layers = config.layers;
    // Set while a step that builds the layers runs (the caps' rings, the
    // volume stage): only their failures give way to the Delaunay layers.
    bool layering = false;
    for (int attempt = 0;; ++attempt) try {
        {
            StageClock clock(run, listener, attempt == 0 ? "remeshing" : "remeshing (retry " + std::to_string(attempt) + ")");
            // Evened rims for the prism layers' columns across the caps (the
            // paper's layers, built on the same cap by Delaunay insertion,
            // keep the remeshing as it was).
            remesh.relax_rims = run.layers == LayerMode::prisms;
            run.remeshed = remesh_to_feature_size(run.surface, d, remesh);
            // The remeshed surface is checked as the input was, before and
            // after its caps are rebuilt: a crossing would give a volume
            // mesh of no one region (or a later stage's error about
            // something else).
            if (const std::string crossing = crossing_text(run.remeshed->surface, "the remeshed surface");
                !crossing.empty())
                throw StageError("remeshing", crossing + "; a surface that crosses itself encloses no one region. "
                                                         "Another [sizing] M or K remeshes it differently; if that "
                                                         "does not help, report the case");
            if (!run.caps.empty()) {
                // The stable d with the cap rules, then each cap rebuilt
                // from its rim's layer points (section 3's layers across
                // the opening).
                run.remeshed->sizing = cap_feature_size(run.remeshed->surface, run.caps, remesh.sizing);
                layering = true;
                run.remeshed->surface =
                    ring_caps(run.remeshed->surface, run.caps, run.remeshed->sizing,
                              {.M = config.M,
                               .growth = config.growth,
                               .first_layer = config.first_layer,
                               .K = config.K,
                               .L_max = run.L_max,
                               .prism_columns = run.layers == LayerMode::prisms ? &volume.rim_columns : nullptr});
                layering = false;
            }
            if (!run.caps.empty())
                if (const std::string crossing =
                        crossing_text(run.remeshed->surface, "the remeshed surface with its caps rebuilt from the "
                                                             "layers' rings");
                    !crossing.empty())
                    throw StageError("openings", crossing + "; check that each opening's plane cuts the vessel "
                                                            "squarely, away from a branch, and report the case");
            const SurfaceFacts facts = surface_facts(run.remeshed->surface);
            std::ostringstream summary;
            summary << run.remeshed->merges << " merges, " << run.remeshed->swaps << " swaps, "
                    << run.remeshed->bisections << " bisections; " << describe(facts);
            clock.done(summary.str());
        }
        if (!options.volume) return run;
        const double points = volume_points(run.remeshed->sizing, config.M, run.L_max);
        run.memory_estimate_volume = estimate_peak_memory(surface_triangles, points);
        require_memory(run.memory_estimate_volume, run.memory_bound,
                       points_basis(points, config.M,
                                    "on " + std::to_string(run.remeshed->surface.points.size()) +
                                        " remeshed surface nodes"));
        StageClock clock(run, listener, attempt == 0 ? "volume" : "volume (retry " + std::to_string(attempt) + ")");
        try {
            layering = true;
            run.volume = build_volume_mesh(run.remeshed->surface, run.remeshed->sizing, volume);
            layering = false;
        } catch (const VolumeConformityError& e) {
            layering = false;
            if (attempt + 1 >= kConformityAttempts) throw;
            const int64_t refined = refine_near(run.surface, run.remeshed->surface, e.failing_nodes, config.K / config.M, d);
            run.refinements.push_back({attempt + 1, static_cast<int64_t>(e.failing_nodes.size()), refined, e.what()});
            clock.done(std::string("did not conform: ") + e.what() + "; d reduced at " + std::to_string(refined) +
                       " nodes, remeshing again");
            continue;
        }
        // The surface is the mesh's boundary, with any diagonals the volume
        // stage flipped (to Delaunay facets, by peeling a flat cap, or in an
        // opening's cap for a poor tet or a light face).
        const int64_t flips = run.volume->quad_flips + run.volume->facet_flips + run.volume->caps_peeled +
                              run.volume->poor_tet_cap_flips + run.volume->light_face_cap_flips;
        run.remeshed->surface.triangles = run.volume->mesh.boundary_faces;
        const QualityReport& q = run.volume->after_slivers;
        std::ostringstream summary;
        summary << q.tets << " tets, " << run.volume->mesh.points.size() << " points; aspect ratio min "
                << q.min_aspect_ratio << ", below 0.1: " << 100 * q.fraction_below_0_1 << "%";
        if (flips > 0) summary << "; " << flips << " surface diagonals flipped";
        // Prism layers whose OpenFOAM cells would miss the case's floors
        // (or fail checkMesh) give way to the paper's layers, which the
        // cell passes mend freely: thin layers over a wall that folds back
        // on itself, or at a large M.
        layering = true;
        run.prism_cells = prism_layer_cells(config, run);
        if (run.prism_cells)
            if (const std::string shortfall = prism_cells_shortfall(config, *run.prism_cells); !shortfall.empty())
                throw StageError("volume", "the prism layers' OpenFOAM cells would miss the case's floors: " + shortfall);
        layering = false;
        clock.done(summary.str());
        return run;
    } catch (const StageError& e) {
        // Prism layers that cannot be built (a cap whose rim columns stay
        // poor, a core Gmsh refuses) give way to the paper's layers, which
        // need no columns; the run says so (floor_warnings). A failure of
        // another step would recur there; a surface the volume stage could
        // not conform to after its refinements is the surface's, not the
        // layers'.
        if (run.layers != LayerMode::prisms || !layering || dynamic_cast<const VolumeConformityError*>(&e)) throw;
        layering = false;
        run.layers = LayerMode::delaunay;
        run.layer_fallback = e.what();
        run.prism_cells = nullptr;
        volume.layers = LayerMode::delaunay;
        volume.rim_columns.clear();
        d = run.sizing->d;
        run.refinements.clear();
        attempt = -1;
    }
}

} // namespace

std::optional<std::string> likely_units(const SurfaceMesh& surface, const CaseConfig& config)
{
    const Unit* likely = likely_unit(surface_size(surface), config);
    return likely ? std::optional<std::string>(likely->name) : std::nullopt;
}

PipelineRun run_pipeline(const CaseConfig& config, const PipelineOptions& options, const StageListener& listener)
{
    // Every parallel stage (TBB, and Embree's TBB tasks) within the case's
    // thread count, in an arena of the run's own rather than through
    // tbb::global_control: a library must not change the parallelism of the
    // process it is part of. 0 leaves TBB's default, every core.
    tbb::task_arena arena(config.threads > 0 ? config.threads : tbb::task_arena::automatic);
    return arena.execute([&] { return run_stages(config, options, listener); });
}

const SurfaceMesh& final_surface(const PipelineRun& run) { return run.remeshed ? run.remeshed->surface : run.surface; }

std::vector<VertexField> surface_fields(const PipelineRun& run, double K, double M)
{
    std::vector<VertexField> fields;
    const FeatureSize* sizing = run.remeshed ? &run.remeshed->sizing : (run.sizing ? &*run.sizing : nullptr);
    if (!sizing) return fields;
    fields.push_back({"D", sizing->D});
    // Readers of legacy VTK and MSH choke on "inf": an escaped outward ray
    // (D_out infinite) is written as -1.
    std::vector<double> D_out = sizing->D_out;
    for (double& v : D_out)
        if (!std::isfinite(v)) v = -1.0;
    fields.push_back({"D_out", std::move(D_out)});
    fields.push_back({"d", sizing->d});
    if (run.remeshed) fields.push_back({"edge_length_ratio", edge_length_ratio(run.remeshed->surface, sizing->d, K, M)});
    if (run.volume) {
        // Realised layers per wall node; -1 at opening nodes, whose layers
        // across the opening are the cap's rings.
        const LayerAccount& a = run.volume->layers;
        std::vector<double> layers(a.realised.size());
        for (size_t i = 0; i < layers.size(); ++i) layers[i] = a.wall[i] ? a.realised[i] : -1.0;
        fields.push_back({"layers", std::move(layers)});
    }
    return fields;
}

TetMesh export_mesh(const PipelineRun& run, double K, double M)
{
    TetMesh mesh = run.volume->mesh;
    mesh.patch_names = {"wall"};
    for (const Cap& cap : run.caps) mesh.patch_names.push_back(cap.name);
    mesh.point_fields = surface_fields(run, K, M);
    std::vector<double> aspect(mesh.tets.size()), layer(mesh.tets.size());
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        const Tet& tet = mesh.tets[t];
        aspect[t] = tet_aspect_ratio(mesh.points[tet[0]], mesh.points[tet[1]], mesh.points[tet[2]], mesh.points[tet[3]]);
        int32_t top = 0;
        for (int32_t v : tet) top = std::max(top, run.volume->point_layer[v]);
        layer[t] = top;
    }
    mesh.tet_fields.push_back({"aspect_ratio", std::move(aspect)});
    mesh.tet_fields.push_back({"layer", std::move(layer)});
    return mesh;
}

} // namespace scalemesh
