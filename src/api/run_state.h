#pragma once
// The run behind a MeshResult (MeshResult::run, include/scalemesh/mesh.h):
// what the library keeps of a run so that write_openfoam, write_msh and
// report_json write what `scalemesh run` writes, through its writers.
// Private to the library's translation units (api.cpp, outputs.cpp,
// gmsh_model.cpp).

#include "pipeline/case_config.h"
#include "pipeline/pipeline.h"

#include <optional>
#include <string>
#include <vector>

namespace scalemesh::detail {

struct RunState {
    CaseConfig config;  // the options as the case reader checked them ([output] and [flow] at their defaults)
    PipelineRun run;    // the stages' results, the volume mesh among them
    // mesh_surface's labels: the patch of each boundary face and the name
    // of each patch, in place of the run's (a closed surface without
    // openings only: all walls). Empty: the run's own patches.
    std::vector<int32_t> boundary_patch;
    std::vector<std::string> patch_names;
};

// Throws InputError, with `hint`, unless the process's Gmsh session is
// initialised and holds a model (Gmsh 4.8 cannot be asked otherwise).
void require_gmsh_session(const std::string& hint);

} // namespace scalemesh::detail
