#pragma once
// The surface half of Algorithm 6 in order: import, marching cubes (or a
// closed surface read from a file), volume-conserving smoothing, and the
// feature size field. Only this folder knows the order of the stages.

#include "core/surface_mesh.h"
#include "pipeline/case_config.h"
#include "sizing/feature_size.h"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace scalemesh {

struct StageTime {
    std::string name;
    double seconds = 0;
    std::string summary; // one line of what the stage made
};

// Called when a stage starts (seconds < 0) and when it ends.
using StageListener = std::function<void(const StageTime&)>;

struct SurfaceRun {
    std::string input;            // what was read: a path or "phantom:<shape>"
    std::string input_checksum;   // FNV-1a 64 of the input file's bytes, hex; empty for phantoms
    double voxel_width = 0;       // mm: the smallest voxel spacing, or for surface
                                  // input the mean edge length of its triangles
    int64_t inside_voxels = -1;   // active voxels of the label (phantoms and label grids)
    SurfaceFacts isosurface;      // facts of the surface before smoothing
    SurfaceMesh surface;          // after smoothing
    SurfaceFacts facts;           // facts of `surface`
    std::optional<FeatureSize> sizing;
    double L_min = 0, L_max = 0;  // mm, as used by sizing
    std::vector<StageTime> stages;
};

struct SurfaceRunOptions {
    bool sizing = true; // compute the feature size field
};

// Runs the stages for `config`. Throws InputError, IoError or StageError.
SurfaceRun run_surface_pipeline(const CaseConfig& config, const SurfaceRunOptions& options,
                                const StageListener& listener = {});

// Per-vertex fields of a run for export: D, D_out and d (mm) when sized;
// D_out is -1 where the outward ray escapes (infinite).
std::vector<VertexField> surface_fields(const SurfaceRun& run);

} // namespace scalemesh
