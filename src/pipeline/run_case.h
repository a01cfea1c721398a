#pragma once
// `scalemesh run CASE_DIR`: the stages a case asks for, then its outputs and
// report.json written into the case directory, each file atomically.

#include "exporters/polymesh_writer.h"
#include "pipeline/pipeline.h"

#include <filesystem>
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

struct CaseResult {
    PipelineRun run;
    std::vector<std::filesystem::path> written; // in the order written, report.json last
    std::vector<std::filesystem::path> removed; // an earlier run's outputs (its report.json's files) this run did
                                                // not write, removed once this run's are in place
    int64_t orphaned_partials = 0;              // unfinished outputs (*.partial-PID*) of runs no longer alive, removed
    std::optional<PolyMeshCounts> polymesh;     // when the OpenFOAM case was written
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

// The layer prisms written as single cells, over the wall faces times the
// layers that make prisms (layers.layermaking): 1 when every wall face
// carries a whole stack of intact prisms. 0 without an OpenFOAM case.
double intact_prism_share(const CaseResult& result);

// Throws InputError, IoError or StageError; a case that fails writes nothing.
// `threads`, when given, overrides the case file's [run] threads;
// `max_memory` bounds the estimated peak memory (bytes; 0: the machine's
// physical memory, PipelineOptions::max_memory).
CaseResult run_case(const std::filesystem::path& dir, const StageListener& listener = {},
                    std::optional<int> threads = {}, int64_t max_memory = 0);

// report.json of a run: version, input and its checksum, parameters, stage
// times, surface facts, sizing and remeshing statistics, the volume mesh's
// facts and quality histograms (Fig. 19), the OpenFOAM counts and the files
// written.
std::string report_json(const CaseConfig& config, const CaseResult& result);

// Writes `text` to `path` atomically. Throws IoError.
void write_text_file(const std::filesystem::path& path, const std::string& text);

} // namespace scalemesh
