#pragma once
// Algorithm 6 in order: import, marching cubes (or a closed surface read
// from a file), volume-conserving smoothing, the feature size field, surface
// remeshing to it, and the layered volume mesh. Only this folder knows the
// order of the stages.

#include "core/surface_mesh.h"
#include "importers/surface_importer.h"
#include "openings/open_ends.h"
#include "openings/openings.h"
#include "pipeline/case_config.h"
#include "remeshing/remesh.h"
#include "sizing/feature_size.h"
#include "volume/volume_mesh.h"

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace scalemesh {

struct FoamCells;  // pipeline/run_case.h
struct VoxelArray; // importers/image_importer.h

struct StageTime {
    std::string name;
    double seconds = 0;
    std::string summary; // one line of what the stage made
};

// Called when a stage starts (seconds < 0) and when it ends.
using StageListener = std::function<void(const StageTime&)>;

// The memory of one stage of a run that owns its process (scalemesh run):
// the peak resident set while it ran and the resident set when it ended.
struct StageMemory {
    std::string stage;
    int64_t peak_bytes = 0;
    int64_t resident_after_bytes = 0;
};

struct PipelineRun {
    std::string input;            // what was read: a path or "phantom:<shape>"
    std::string input_checksum;   // FNV-1a 64 of the input file's bytes, hex; empty for phantoms
    double voxel_width = 0;       // mm: the smallest voxel spacing, or for surface
                                  // input the mean edge length of its triangles
    int64_t inside_voxels = -1;   // active voxels of the label (phantoms and label grids)
    int64_t islands_dropped = 0;  // keep = "largest": face-connected regions of inside voxels left out
    int64_t island_voxels = 0;    // and their voxels
    SurfaceFacts isosurface;      // facts of the surface before smoothing
    SurfaceMesh surface;          // after smoothing, and cut and capped at the openings
    std::vector<Cap> caps;        // the openings' caps: cap i is surface patch i + 1
    std::vector<OpenEnd> open_ends; // of an open-ended surface input (or its labelled caps), closed by fans
                                    // until the openings stage cuts them flat
    std::vector<LabelPart> label_parts; // the face labels of the input file, as the import judged them
    std::map<int32_t, std::string> label_names; // names of label values the file gives
    std::string label_source;     // where those labels came from ("cell array ModelFaceID", ...)
    std::vector<std::string> warnings; // what the run found doubtful in its input (units), for report.json
    struct BorderContact {
        std::string side;  // "x-", "x+", "y-", "y+", "z-" or "z+"
        double area = 0;   // mm^2 of the image face the inside voxels touch
        int64_t voxels = 0;
        bool opened = false; // a border opening of the case is on this side
    };
    std::vector<BorderContact> border_contacts; // image inputs: the sides the segmentation touches
    SurfaceFacts opened;          // facts of `surface` after the openings were cut (facts: before)
    int64_t closed_regions_dropped = 0;    // separate regions without an opening, left out of the mesh
    double closed_regions_volume = 0;      // mm^3 they enclosed
    SurfaceFacts facts;           // facts of the smoothed surface
    std::optional<FeatureSize> sizing;    // on `surface`
    double L_min = 0, L_max = 0;  // mm, as used by sizing
    std::optional<RemeshResult> remeshed; // the surface remeshed to K/M d, with its stable d
    std::optional<VolumeResult> volume;   // the layered tet mesh inside the remeshed surface
    // The layers built: the case's, or the paper's Delaunay layers where the
    // prism layers asked for could not be built (layer_fallback says why).
    LayerMode layers = LayerMode::delaunay;
    std::string layer_fallback;
    // Prism layers to be written as prism cells ([output] openfoam and
    // layer_prisms): the OpenFOAM cells of `volume` the volume stage judged
    // them by (prism_layer_cells), which the writers write. Empty otherwise.
    std::shared_ptr<const FoamCells> prism_cells;
    struct Refinement {
        int attempt;              // 1 for the first retry
        int64_t failing_nodes;    // surface nodes the volume stage named
        int64_t refined_points;   // points of the smoothed surface whose d was reduced
        std::string reason;
    };
    std::vector<Refinement> refinements; // section 2.3 local refinements, in order
    std::vector<StageTime> stages;
    int64_t memory_bound = 0;               // bytes the run was allowed (PipelineOptions::max_memory resolved)
    double memory_estimate_remeshing = 0;   // bytes, peak estimated before remeshing (0: not estimated)
    double memory_estimate_volume = 0;      // bytes, peak estimated before the (last) volume stage
    std::vector<StageMemory> stage_memory;  // per stage, in order (scalemesh run on Linux; empty elsewhere)
};

struct PipelineOptions {
    bool sizing = true;  // compute the feature size field
    bool remesh = false; // remesh the surface to it (needs sizing)
    bool volume = false; // build the volume mesh (needs remesh)
    int64_t max_memory = 0; // bytes: a run whose estimated peak memory exceeds this stops with an
                            // InputError before sizing, remeshing and the volume stage; 0: the
                            // machine's physical memory
    // The input surface in memory (the library API), instead of the case's
    // [input]: read as a surface file would be (mm, welded, every triangle
    // used), its labels as a file's face labels (flat labelled caps become
    // openings, open ends are cut flat). Not owned; must outlive the call.
    const LabelledSurface* surface = nullptr;
    // The input image in memory (the library API), instead of the case's
    // [input] file: read as an image file holding these voxels would be
    // (importers/image_importer.h, image_grid). Not owned; must outlive the call.
    const VoxelArray* image = nullptr;
};

// For a surface implausibly small or large in the case's unit (outside 0.5 mm
// to 2 m across): the unit ("um", "mm", "cm" or "m") that makes it about 5 cm
// across; nullopt when it is plausible.
std::optional<std::string> likely_units(const SurfaceMesh& surface, const CaseConfig& config);

// Runs the stages for `config`. Throws InputError, IoError or StageError.
PipelineRun run_pipeline(const CaseConfig& config, const PipelineOptions& options,
                                const StageListener& listener = {});

// The surface the run ends with: remeshed when it was, else smoothed.
const SurfaceMesh& final_surface(const PipelineRun& run);

// Per-vertex fields of the final surface for export: D, D_out and d (mm) when
// sized; D_out is -1 where the outward ray escapes (infinite); with a
// remeshed surface also the edge-length ratio of remeshing/remesh.h (mean
// incident edge length over K/M d with the stable d, 1 on target), and with a
// volume mesh the realised layers of each wall node (-1 at opening nodes).
std::vector<VertexField> surface_fields(const PipelineRun& run, double K, double M);

// The volume mesh ready for export: the surface fields on the surface nodes,
// and per tet its aspect ratio (2 sqrt(6) r_in / l_max) and layer (the largest
// layer index of its points, 0 for tets of surface points only).
TetMesh export_mesh(const PipelineRun& run, double K, double M);

} // namespace scalemesh
