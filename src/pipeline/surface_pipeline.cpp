#include "pipeline/surface_pipeline.h"

#include "core/errors.h"
#include "importers/stl_importer.h"
#include "importers/vdb_importer.h"
#include "isosurface/marching_cubes.h"
#include "phantom/phantom.h"
#include "smoothing/volume_conserving_smoothing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace scalemesh {

namespace {

class StageClock {
public:
    StageClock(SurfaceRun& run, const StageListener& listener, std::string name)
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
    SurfaceRun& run_;
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

} // namespace

SurfaceRun run_surface_pipeline(const CaseConfig& config, const SurfaceRunOptions& options,
                                const StageListener& listener)
{
    SurfaceRun run;
    SurfaceMesh surface;
    const std::filesystem::path file = config.file.empty() || config.file.is_absolute() || config.directory == "."
                                           ? config.file
                                           : config.directory / config.file;
    const std::string ext = file.extension().string();

    if (!config.file.empty() && (ext == ".stl" || ext == ".STL")) {
        StageClock clock(run, listener, "import");
        surface = read_stl(file);
        require_closed_manifold(surface, file.string());
        const bool flipped = orient_outward(surface);
        run.input = file.string();
        run.input_checksum = file_checksum(file);
        run.voxel_width = mean_edge_length(surface);
        run.isosurface = surface_facts(surface);
        clock.done("read " + std::to_string(surface.triangles.size()) + " triangles" +
                   (flipped ? ", wound inwards: reversed" : ""));
    } else {
        openvdb::FloatGrid::Ptr grid;
        {
            StageClock clock(run, listener, "import");
            if (!config.phantom.empty()) {
                const auto shape = make_shape(config.phantom, config.voxel_size);
                grid = voxelize(*shape, {config.voxel_size, config.noise, config.seed});
                run.input = "phantom:" + config.phantom;
            } else if (ext == ".vdb") {
                grid = read_vdb(file, {config.grid});
                run.input = file.string();
                run.input_checksum = file_checksum(file);
            } else {
                throw InputError("cannot read '" + file.string() + "': unknown input format '" + ext + "'",
                                 "give an OpenVDB image (.vdb) or a closed surface (.stl)");
            }
            const openvdb::Vec3d spacing = grid->voxelSize();
            run.voxel_width = std::min({spacing.x(), spacing.y(), spacing.z()});
            if (!is_level_set(*grid)) run.inside_voxels = static_cast<int64_t>(grid->activeVoxelCount());
            clock.done(std::to_string(grid->activeVoxelCount()) + " active voxels of " +
                       std::to_string(run.voxel_width) + " mm");
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
        smooth_volume_conserving(surface, smoothing);
        run.facts = surface_facts(surface);
        clock.done(std::to_string(config.smoothing.sweeps) + " sweeps, omega " + std::to_string(config.smoothing.omega) +
                   ", volume change " + std::to_string(run.facts.signed_volume - run.isosurface.signed_volume) + " mm^3");
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

    if (options.sizing) {
        StageClock clock(run, listener, "sizing");
        SizingParams params;
        params.K = config.K;
        params.M = config.M;
        params.G = config.G;
        params.L_min = run.L_min;
        params.L_max = run.L_max;
        params.curvature_term = config.curvature;
        params.threads = config.threads;
        run.sizing = compute_feature_size(surface, params);
        const auto [dmin, dmax] = std::minmax_element(run.sizing->d.begin(), run.sizing->d.end());
        std::ostringstream summary;
        summary << "d in [" << *dmin << ", " << *dmax << "] mm, " << run.sizing->D.size() * 2 << " rays";
        clock.done(summary.str());
    }
    run.surface = std::move(surface);
    return run;
}

std::vector<VertexField> surface_fields(const SurfaceRun& run)
{
    std::vector<VertexField> fields;
    if (run.sizing) {
        fields.push_back({"D", run.sizing->D});
        // Readers of legacy VTK and MSH choke on "inf": an escaped outward
        // ray (D_out infinite) is written as -1.
        std::vector<double> D_out = run.sizing->D_out;
        for (double& v : D_out)
            if (!std::isfinite(v)) v = -1.0;
        fields.push_back({"D_out", std::move(D_out)});
        fields.push_back({"d", run.sizing->d});
    }
    return fields;
}

} // namespace scalemesh
