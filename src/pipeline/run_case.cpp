#include "pipeline/run_case.h"

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/version.h"
#include "exporters/surface_writers.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>

namespace scalemesh {

namespace {

nlohmann::json facts_json(const SurfaceFacts& f)
{
    return {{"vertices", f.vertices},
            {"triangles", f.triangles},
            {"components", f.components},
            {"euler_characteristic", f.euler_characteristic},
            {"closed_manifold", f.closed_manifold()},
            {"enclosed_volume_mm3", f.signed_volume},
            {"area_mm2", f.area}};
}

// Min, median and max of the finite values, and how many were not finite.
nlohmann::json field_stats(const std::vector<double>& values)
{
    std::vector<double> finite;
    std::copy_if(values.begin(), values.end(), std::back_inserter(finite), [](double v) { return std::isfinite(v); });
    nlohmann::json out = {{"count", values.size()}, {"infinite", values.size() - finite.size()}};
    if (!finite.empty()) {
        std::sort(finite.begin(), finite.end());
        out["min"] = finite.front();
        out["median"] = finite[finite.size() / 2];
        out["max"] = finite.back();
    }
    return out;
}

} // namespace

void write_text_file(const std::filesystem::path& path, const std::string& text)
{
    AtomicOutput out(path);
    {
        std::ofstream file(out.temporary(), std::ios::binary);
        file << text;
        if (!file.flush()) throw IoError(path.string(), "cannot write the file");
    }
    out.commit();
}

std::string report_json(const CaseConfig& config, const SurfaceRun& run,
                        const std::vector<std::filesystem::path>& written)
{
    nlohmann::json report;
    report["scalemesh_version"] = SCALEMESH_VERSION;
    report["input"] = {{"source", run.input}, {"checksum_fnv1a64", run.input_checksum}, {"voxel_width_mm", run.voxel_width}};
    if (run.inside_voxels >= 0) report["input"]["inside_voxels"] = run.inside_voxels;
    report["parameters"] = {{"K", config.K},
                            {"M", config.M},
                            {"G", config.G},
                            {"L_min", config.L_min.text()},
                            {"L_min_mm", run.L_min},
                            {"L_max", config.L_max ? config.L_max->text() : "largest extent of the surface"},
                            {"L_max_mm", run.L_max},
                            {"curvature", config.curvature},
                            {"smoothing_sweeps", config.smoothing.sweeps},
                            {"smoothing_omega", config.smoothing.omega},
                            {"smoothing_max_displacement", config.smoothing_reach.text()},
                            {"connectivity", config.connectivity == InsideConnectivity::Six ? 6 : 26}};
    nlohmann::json stages = nlohmann::json::array();
    for (const StageTime& s : run.stages) stages.push_back({{"stage", s.name}, {"seconds", s.seconds}, {"summary", s.summary}});
    report["stages"] = stages;
    report["isosurface"] = facts_json(run.isosurface);
    report["surface"] = facts_json(run.facts);
    if (run.sizing) {
        const FeatureSize& s = *run.sizing;
        report["sizing"] = {{"D_mm", field_stats(s.D)},
                            {"D_out_mm", field_stats(s.D_out)},
                            {"d_mm", field_stats(s.d)},
                            {"inward_check_failures", std::count(s.inward_ok.begin(), s.inward_ok.end(), 0)},
                            {"escaped_inward_rays", s.escaped_inward_rays},
                            {"seconds_bvh", s.seconds_bvh},
                            {"seconds_rays", s.seconds_rays},
                            {"seconds_gradient_limiting", s.seconds_limit}};
    }
    report["volume_mesh"] = "not produced: this version builds the surface and its feature size field only";
    nlohmann::json files = nlohmann::json::array();
    for (const auto& p : written) files.push_back(p.filename().string());
    files.push_back("report.json");
    report["files"] = files;
    return report.dump(2) + "\n";
}

CaseResult run_case(const std::filesystem::path& dir, const StageListener& listener)
{
    const CaseConfig config = read_case(dir);
    CaseResult result;
    result.run = run_surface_pipeline(config, {.sizing = true}, listener);

    // Every output is finished under a temporary name first and moved into
    // place only when all are complete, so a failure (or an interruption,
    // through remove_pending_outputs) leaves the case directory as it was.
    std::vector<std::unique_ptr<AtomicOutput>> pending;
    const std::vector<VertexField> fields = surface_fields(result.run);
    SurfaceWriteOptions options;
    options.msh_version = config.msh_version;
    options.msh_binary = config.msh_binary;
    for (const std::string& name : config.surface_outputs) {
        pending.push_back(std::make_unique<AtomicOutput>(dir / name));
        write_surface(result.run.surface, fields, pending.back()->temporary(), options);
        result.written.push_back(dir / name);
    }
    pending.push_back(std::make_unique<AtomicOutput>(dir / "report.json"));
    write_text_file(pending.back()->temporary(), report_json(config, result.run, result.written));
    result.written.push_back(dir / "report.json");
    for (const auto& out : pending)
        if (std::filesystem::is_directory(out->path()))
            throw IoError(out->path().string(), "a directory has this name, so the output cannot be written; "
                                                "rename or remove it");
    for (auto& out : pending) out->commit();
    return result;
}

} // namespace scalemesh
