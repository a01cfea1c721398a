// The library's outputs (include/scalemesh/mesh.h): write_openfoam, write_msh
// and report_json write what `scalemesh run` writes, through the command
// line's own writers and checks (pipeline/run_case.h), from the run kept
// behind a MeshResult (api/run_state.h).
//
// Like api.cpp, this file does not include scalemesh/scalemesh.h: the
// exceptions are those of core/errors.h.

#include "scalemesh/mesh.h"

#include "api/run_state.h"
#include "core/errors.h"
#include "exporters/volume_writers.h"
#include "gmsh_io/gmsh_session.h"
#include "pipeline/run_case.h"

#include <tbb/task_arena.h>

#include <optional>

namespace scalemesh {

namespace {

const detail::RunState& state_of(const MeshResult& result, const std::string& function)
{
    if (!result.run)
        throw InputError(function + ": the result carries no run (MeshResult::run is empty)",
                         "pass a MeshResult that mesh_surface, mesh_image or mesh_gmsh_model returned, or a copy");
    if (!result.run->run.volume)
        throw InputError(function + ": the result's run built no volume mesh", "mesh with remesh_cycles >= 1");
    return *result.run;
}

// The mesh_surface labels' patches, where the result has them.
OutputRequest request_for(const detail::RunState& state)
{
    OutputRequest request;
    if (!state.boundary_patch.empty()) {
        request.boundary_patch = &state.boundary_patch;
        request.patch_names = &state.patch_names;
    }
    return request;
}

// The writers in an arena of the run's threads, as run_case runs them.
template <class F> auto in_arena(const CaseConfig& config, F&& f)
{
    tbb::task_arena arena(config.threads > 0 ? config.threads : tbb::task_arena::automatic);
    return arena.execute(std::forward<F>(f));
}

} // namespace

OpenFoamCase write_openfoam(const MeshResult& result, const std::filesystem::path& case_dir,
                            const OpenFoamOptions& options)
{
    const detail::RunState& state = state_of(result, "write_openfoam");
    if (case_dir.empty()) throw InputError("write_openfoam: the case directory is empty", "give a directory path");
    CaseConfig config = state.config;
    config.source = "write_openfoam options";
    config = flow_from_options(options.viscosity, options.inlet_speed, std::move(config));
    config.openfoam_binary = options.binary;
    config.layer_prisms = options.layer_prisms;
    config.openfoam = true;
    config.surface_outputs.clear();
    config.volume_outputs.clear();

    const std::filesystem::path dir = std::filesystem::absolute(case_dir).lexically_normal();
    std::error_code ec;
    if (std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
        throw IoError(dir.string(), "is not a directory; give a directory for the OpenFOAM case");
    // The directories this call makes, innermost first, removed again (when
    // empty) if the case cannot be written.
    std::vector<std::filesystem::path> made;
    for (std::filesystem::path p = dir; !p.empty() && !std::filesystem::exists(p, ec); p = p.parent_path()) {
        made.push_back(p);
        if (p == p.parent_path()) break;
    }
    std::filesystem::create_directories(dir, ec);
    if (ec) throw IoError(dir.string(), "cannot make the case directory: " + ec.message());
    config.directory = dir;

    CaseOutputs out;
    try {
        OutputRequest request = request_for(state);
        request.histograms = false;
        request.remove_every_stale_output = false;
        request.orphaned_partials = remove_orphaned_partials(dir);
        out = in_arena(config, [&] { return write_case_outputs(config, state.run, request); });
    } catch (...) {
        for (const std::filesystem::path& p : made) {
            std::error_code ignored;
            std::filesystem::remove(p, ignored); // only an empty directory goes
        }
        throw;
    }
    OpenFoamCase written;
    if (out.polymesh) {
        written.cells = out.polymesh->cells;
        written.faces = out.polymesh->faces;
        written.internal_faces = out.polymesh->internal_faces;
        written.patch_faces = out.polymesh->patch_faces;
    }
    written.layer_prisms = out.layer_prisms;
    written.patch_names = out.patch_names;
    written.flow_fields = out.flow_case;
    written.warnings = out.warnings;
    return written;
}

void write_msh(const MeshResult& result, const std::filesystem::path& path, const MshOptions& options)
{
    const detail::RunState& state = state_of(result, "write_msh");
    if (path.extension() != ".msh")
        throw InputError("write_msh: '" + path.string() + "' does not end in .msh",
                         "give a path ending in .msh (Gmsh's writer follows the extension)");
    CaseConfig config = state.config;
    config.source = "write_msh options";
    config = msh_from_options(options.version, options.binary, std::move(config));
    const TetMesh mesh = case_mesh(config, state.run, request_for(state));
    // The host's session, adopted: write_volume_msh's own session nests in
    // it and neither initialises nor finalises Gmsh.
    std::optional<GmshSession> host;
    if (options.host_gmsh_session) {
        detail::require_gmsh_session("call gmsh::initialize (gmsh.initialize() in Python) first, or leave "
                                     "host_gmsh_session false for a session of the library's own");
        host.emplace(GmshSession::Host{});
    }
    in_arena(config, [&] {
        write_volume_msh(mesh, path,
                         {.msh_version = config.msh_version,
                          .binary = config.msh_binary,
                          .comments = msh_comments(config, state.run),
                          .adjacency = &state.run.volume->adjacency});
    });
}

std::string report_json(const MeshResult& result)
{
    const detail::RunState& state = state_of(result, "report_json");
    CaseConfig config = state.config;
    config.openfoam = false;
    config.surface_outputs.clear();
    config.volume_outputs.clear();
    CaseOutputs outputs;
    outputs.warnings = floor_warnings(config, state.run);
    outputs.input_warnings = std::min(state.run.warnings.size(), outputs.warnings.size());
    return in_arena(config, [&] { return report_json(config, state.run, outputs); });
}

} // namespace scalemesh
