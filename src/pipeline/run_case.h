#pragma once
// `scalemesh run CASE_DIR`: the stages a case asks for, then its outputs and
// report.json written into the case directory, each file atomically. The
// writers (write_case_outputs) are the library's too (src/api/outputs.cpp).

#include "exporters/polymesh_decompose.h"
#include "exporters/polymesh_writer.h"
#include "pipeline/pipeline.h"
#include "volume/layer_prisms.h"

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace scalemesh {

// The quality the cell floors judge: of every tet, or (layers = "prisms")
// of the tets written as cells of their own, with OpenFOAM's worst face.
struct CellFloors {
    double min_aspect_ratio = 1;
    double fraction_below_0_1 = 0; // of the cells measured, those below aspect ratio 0.1
    double min_dihedral_deg = 90;
    double max_non_orthogonality_deg = 0;
    std::string what = "tet";      // the cells measured, for the sentences ("tet", "tet cell")
};

// What a run's writers made of it (write_case_outputs): every field of a
// case's result but the run itself.
struct CaseOutputs {
    std::vector<std::filesystem::path> written; // in the order written, report.json last
    std::vector<std::filesystem::path> removed; // an earlier run's outputs (its report.json's files) this run did
                                                // not write, removed once this run's are in place
    int64_t orphaned_partials = 0;              // unfinished outputs (*.partial-PID*) of runs no longer alive, removed
    std::optional<PolyMeshCounts> polymesh;     // when the OpenFOAM case was written
    std::optional<DecomposeCounts> decomposition; // when it was also written as processor meshes ([output] decompose)
    std::vector<std::string> patch_names;       // of the polyMesh's patches, in the order of its boundary file
    int64_t layer_prisms = 0;                   // its cells of three tets filling a layer prism
    int64_t layer_prisms_refused = 0;           // prisms filled by three tets left as tets (not star-shaped, or a
                                                // face beyond the bound by the tets' or by OpenFOAM's measure)
    int64_t absorbed_tets = 0;                  // layers = "prisms": poor tets joined to a neighbouring cell
                                                // (absorb_poor_tets) rather than written as cells of their own
    std::optional<CellFloors> tet_cells;        // layers = "prisms" with prism cells: the tets written as cells
                                                // of their own, which the cell floors judge
    OpenFoamCellChecks openfoam_checks;         // OpenFOAM's own checks on the written cells (its worst face
                                                // non-orthogonality among them)
    bool flow_case = false;                     // whether 0/U and 0/p were written
    std::vector<std::string> warnings;          // the run's floors it missed (floor_warnings)
    size_t input_warnings = 0;                  // of `warnings`, the first ones are about the input and the case
                                                // (units, face labels, openings that pose no flow), not floors
};

// `scalemesh run`'s result: the run, and what its writers made of it.
struct CaseResult : CaseOutputs {
    PipelineRun run;
};

// The run's warnings about its input (PipelineRun::warnings: an implausible
// size for the declared unit), then one sentence per floor of the case
// ([volume] min_layer_coverage, min_aspect_ratio, min_dihedral_deg) that the
// volume mesh misses, and a face beyond the 70 degrees of non-orthogonality
// that checkMesh counts as severe, with the figure; empty when there are
// none.
// The outputs an earlier run listed in the case directory's report.json
// ("files") that `written` does not hold and that still exist: paths inside
// the case directory only, never scalemesh.toml, report.json, the input
// file or a directory holding it.
std::vector<std::filesystem::path> stale_outputs(const CaseConfig& config,
                                                 const std::vector<std::filesystem::path>& written);

// Removes the unfinished outputs (NAME.partial-PID[.EXT], atomic_file.h)
// in `dir` and its subdirectories to two levels whose process PID is no
// longer alive (a run killed by SIGKILL cannot remove its own); returns how
// many.
int64_t remove_orphaned_partials(const std::filesystem::path& dir);

// With `cells_later`, the cell floors (aspect ratio, dihedral angle,
// non-orthogonality) are left out: the caller judges them on the cells it
// writes (cell_floor_warnings), as for layers = "prisms".
std::vector<std::string> floor_warnings(const CaseConfig& config, const PipelineRun& run, bool cells_later = false);

// The cell floors of the case ([volume] min_aspect_ratio, min_dihedral_deg,
// and checkMesh's 70 degrees of non-orthogonality) against `cells`: one
// sentence per floor missed, naming the kind of cell measured.
std::vector<std::string> cell_floor_warnings(const CaseConfig& config, const CellFloors& cells);

// A sentence when faces of the OpenFOAM cells would still fail checkMesh
// (OpenFoamCellChecks::checkmesh_failures: only faces between single tets
// can, since the prisms on them are split back), empty when none would.
std::vector<std::string> openfoam_check_warnings(const OpenFoamCellChecks& checks);

// The OpenFOAM cells of a run's mesh `mesh` (case_mesh) as write_case_outputs
// writes them: layer prisms joined ([output] layer_prisms), each split back
// where checkMesh would fail it, poor tets joined to neighbours with prism
// layers; OpenFOAM's own checks on them; with prism layers written as
// prism cells, the floors' figures on the tets written as cells.
struct FoamCells {
    LayerPrismCells cells;
    OpenFoamCellChecks checks;
    std::optional<CellFloors> tet_cells;
};
FoamCells foam_cells(const CaseConfig& config, const PipelineRun& run, const TetMesh& mesh);

// With prism layers to be written as prism cells ([output] openfoam and
// layer_prisms): the OpenFOAM cells of the run's volume mesh, as foam_cells
// makes them; empty for other runs. The pipeline keeps them for the writers
// (PipelineRun::prism_cells).
std::shared_ptr<const FoamCells> prism_layer_cells(const CaseConfig& config, const PipelineRun& run);

// The floors of the case the prism layers' cells `foam` would miss and the
// checkMesh failures they would have, as the run's warnings word them ("; "
// between), empty when none. The pipeline gives such prism layers up for
// the paper's.
std::string prism_cells_shortfall(const CaseConfig& config, const FoamCells& foam);

// The layer prisms written as single cells, over the wall faces times the
// layers that make prisms (layers.layermaking): 1 when every wall face
// carries a whole stack of intact prisms. 0 without an OpenFOAM case.
double intact_prism_share(const PipelineRun& run, const CaseOutputs& outputs);
inline double intact_prism_share(const CaseResult& result) { return intact_prism_share(result.run, result); }

// Throws InputError, IoError or StageError; a case that fails writes nothing.
// `threads`, when given, overrides the case file's [run] threads;
// `max_memory` bounds the estimated peak memory (bytes; 0: the machine's
// physical memory, PipelineOptions::max_memory); `decompose`, when given,
// the case file's [output] decompose.
CaseResult run_case(const std::filesystem::path& dir, const StageListener& listener = {},
                    std::optional<int> threads = {}, int64_t max_memory = 0, std::optional<int> decompose = {});

// What write_case_outputs writes besides the outputs `config` lists.
struct OutputRequest {
    bool histograms = true;              // quality.png, the aspect-ratio histograms of Fig. 19
    // The boundary patches of the volume mesh written, in place of the run's
    // (the library's nearest-label patches): one per boundary face, and the
    // name per patch id. Only with a run without openings: every patch is
    // then a wall. Not owned.
    const std::vector<int32_t>* boundary_patch = nullptr;
    const std::vector<std::string>* patch_names = nullptr;
    // Which of an earlier run's outputs (listed in config.directory's
    // report.json) that this one does not write are removed: every one, as
    // `scalemesh run` does, or (false) those of the OpenFOAM case only
    // (constant/, system/, 0/, Allrun), as the library's write_openfoam does,
    // which writes no other.
    bool remove_every_stale_output = true;
    int64_t orphaned_partials = 0;       // reported in report.json
};

// The outputs of `run` that `config` asks for, written into
// config.directory as `scalemesh run` writes them: the [output] surface and
// volume files, quality.png, with [output] openfoam the OpenFOAM case
// (constant/polyMesh with its layer prism cells, after OpenFOAM's own cell
// checks, and system/, constant/, 0/ and Allrun) and last report.json. All
// are finished under temporary names and moved into place together, so a
// failure leaves the directory as it was; then an earlier run's outputs this
// one did not write are removed (OutputRequest::remove_every_stale_output).
// Throws InputError, IoError or StageError (a mesh the writers' validation
// refuses).
CaseOutputs write_case_outputs(const CaseConfig& config, const PipelineRun& run, const OutputRequest& request = {});

// The volume mesh as the writers write it: export_mesh's, with the patches
// of `request` when it gives them. Throws StageError when they do not fit.
TetMesh case_mesh(const CaseConfig& config, const PipelineRun& run, const OutputRequest& request = {});

// The $Comments lines of the .msh files a run writes: the version, the input
// and its checksum, and the parameters.
std::vector<std::string> msh_comments(const CaseConfig& config, const PipelineRun& run);

// report.json of a run: version, input and its checksum, parameters, stage
// times, surface facts, sizing and remeshing statistics, the volume mesh's
// facts and quality histograms (Fig. 19), the OpenFOAM counts and the files
// written (paths relative to config.directory).
std::string report_json(const CaseConfig& config, const PipelineRun& run, const CaseOutputs& outputs);
inline std::string report_json(const CaseConfig& config, const CaseResult& result)
{
    return report_json(config, result.run, result);
}

// Writes `text` to `path` atomically. Throws IoError.
void write_text_file(const std::filesystem::path& path, const std::string& text);

} // namespace scalemesh
