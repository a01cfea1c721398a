#pragma once
// The case file `scalemesh.toml`: what a case directory asks scalemesh to do.
// Every key, its unit and its default are listed in docs/case-file.md; unknown
// keys and values out of range are refused with the valid choices.

#include "isosurface/marching_cubes.h"
#include "openings/openings.h"
#include "pipeline/options_table.h"
#include "smoothing/volume_conserving_smoothing.h"
#include "volume/volume_mesh.h"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace scalemesh {

// A length given in mm or in voxel widths ("2 voxels", "1.5 mm", or a bare
// number meaning mm).
struct Length {
    double value = 0;
    bool voxels = false;
    // In mm, given the voxel width (mm) of the input image.
    double mm(double voxel_width) const { return voxels ? value * voxel_width : value; }
    std::string text() const;
};

struct CaseConfig {
    // The meshing options (mesh_option_table) at MeshOptions{}'s defaults,
    // the rest at the defaults below.
    CaseConfig();

    std::filesystem::path directory; // the case directory; relative paths resolve against it
    std::string source;              // the case file as messages name it (parse_case's `source`)

    // [input]: exactly one of phantom and file.
    std::string phantom;            // phantom shape name
    std::filesystem::path file;     // image (.vdb) relative to the case directory
    double voxel_size = 0.5;        // mm, phantoms only
    double noise = 0.0;             // voxel widths, phantoms only
    uint64_t seed = 1;              // phantoms only
    std::string grid;               // VDB grid name; empty: the first scalar grid
    std::vector<int> labels;        // medical images: label values that are inside; empty: any nonzero voxel
    std::optional<double> threshold; // intensity images: inside where value > threshold
    bool level_set = false;         // medical images: the values are a signed distance, negative inside
    bool keep_largest = false;      // [input] keep = "largest": only the face-connected region of the most inside
                                    // voxels is meshed (stray islands of a segmentation dropped)
    std::optional<double> iso;      // default 0 for level sets, 0.5 for labels
    InsideConnectivity connectivity = InsideConnectivity::Six;
    std::string units = "mm";       // surface files only: the unit of their coordinates, "mm", "cm", "m" or "um"
    double units_to_mm = 1.0;       // the factor `units` gives (importers/surface_importer.h, unit_to_mm)

    // The meshing options: MeshOptions' members as the stages take them,
    // set by config_from_options (their defaults, units and ranges are
    // MeshOptions', include/scalemesh/mesh.h).
    // [smoothing], Algorithm 6's first step; max_displacement is set from
    // smoothing_reach once the voxel width is known.
    SmoothingParams smoothing;
    Length smoothing_reach;         // how far a node may move from where marching cubes put it

    // [sizing], Algorithm 1.
    double K;
    double M;
    double G;
    Length L_min;
    std::optional<Length> L_max;    // empty: the largest extent of the surface
    bool curvature;                 // eq. (12)

    // [remeshing], Algorithm 6's surface loop.
    int remesh_cycles;              // 0 skips remeshing (and the volume mesh)

    // [volume], Algorithms 4 and 5, section 2.4.
    double growth;                  // layer thickness ratio, >= 1; 1 = uniform layers as in the paper
    LayerMode layers;               // "prisms": prism layers built explicitly; "delaunay": the paper's layers
    FirstLayer first_layer;         // "edge": mean surface edge length / K; "paper": lambda_1 d
    double layer_tolerance;         // fraction of its layer spacing a layermaking point may move and still count

    // [run]
    int threads;                    // 0: all cores

    // The case file's own keys, not options of the library.
    bool volume = true;             // [volume] enabled: build the layered volume mesh
    // The run's own floors: missing one is a warning (stderr, report.json),
    // and an error exit with `scalemesh run --strict`.
    double min_layer_coverage = 0.99; // fraction of wall nodes with D >= L_min that keep all floor(M/2) layers
    double min_aspect_ratio = 0.1;    // worst tet aspect ratio (2 sqrt(6) r_in / l_max)
    double min_dihedral_deg = 10;     // smallest dihedral angle, degrees (0: no floor): a solver's cells

    // [[openings]]: inlets and outlets, patches in the file's order. A border
    // opening's explicit inset (spec.inset set) is resolved to mm with the
    // voxel width; "auto", the default, leaves it to cut_and_cap.
    struct Opening {
        OpeningSpec spec;
        Length inset{2.0, true};
        std::optional<Vec3> near;     // an open end of the surface: the one whose centre is nearest this point
        std::optional<int32_t> label; // an open end: the flat cap of this face label
    };
    std::vector<Opening> openings;

    // [flow], the OpenFOAM case (SI units).
    double viscosity = 3.3e-6;      // m^2/s, kinematic; blood about 3.3e-6
    double inlet_speed = 0.1;       // m/s

    // [output]
    std::vector<std::string> surface_outputs{"surface.msh", "surface.vtk"};
    std::vector<std::string> volume_outputs{"mesh.msh"};
    bool openfoam = true;           // constant/polyMesh, system/, constant/ (and 0/ with openings)
    bool openfoam_binary = false;
    int32_t decompose = 1;          // processor meshes for a parallel run (processor0 .. processor<N-1>); 1: none
    bool decompose_on_command_line = false; // decompose is `scalemesh run --decompose`'s, not the case file's
    bool layer_prisms = true; // polyMesh: the three tets filling a layer prism as one cell (layer_prisms.h)
    double msh_version = 4.1;
    bool msh_binary = false;
};

// Reads `dir/scalemesh.toml`. Throws InputError naming the file and key for a
// syntax error, an unknown key (listing the valid ones), a wrong type or a
// value out of range; IoError when the file is missing.
CaseConfig read_case(const std::filesystem::path& dir);

// Throws InputError, naming where decompose was given (the case file's key or
// --decompose), when it is below 1 or asks for processor meshes of a case that
// writes no OpenFOAM case (openfoam = false). Called once, after the command
// line's --decompose, if any, has replaced the case file's value (run_case):
// parse_case leaves these to it. The cell count bounds decompose too, checked
// when the cells are known.
void check_decompose(const CaseConfig& config);

// A TOML basic string for case-file text: quoted, with '"' and '\\' escaped.
std::string toml_string(const std::string& s);

// `config` with the meshing options of `options` (mesh_option_table), each
// checked as parse_case checks its case-file key: InputError naming
// config.source, the section and the key, in parse_case's words ("is out of
// range", "is not a layer construction", ... with what to give instead).
// The rest of `config` (input, openings, flow, outputs) is kept. max_memory
// is checked; the run takes it from MeshOptions (RunOptions::max_memory).
CaseConfig config_from_options(const MeshOptions& options, CaseConfig config);

// `config` with [flow] viscosity (m^2/s) and inlet_speed (m/s), checked as
// parse_case checks them (InputError naming config.source and the key).
CaseConfig flow_from_options(double viscosity, double inlet_speed, CaseConfig config);

// `config` with [output] msh_version (4.1 or 2.2) and msh_binary, checked as
// parse_case checks them.
CaseConfig msh_from_options(double version, bool binary, CaseConfig config);

// `config` reading `file` (an image or a surface file; empty for an input
// handed to run_pipeline in memory) as `image` says, checked as parse_case
// checks [input] (InputError naming config.source and the key).
CaseConfig input_from_options(const std::filesystem::path& file, const ImageOptions& image, CaseConfig config);

// `config` with `openings` as its [[openings]] tables, each checked as
// parse_case checks the table (InputError naming config.source, the
// opening's index from 1 and the key, in parse_case's words). A key counts
// as given when it is not empty (0 for radius and extension).
CaseConfig openings_from_options(const std::vector<MeshOpening>& openings, CaseConfig config);

// Parses a case file's text; `dir` is where relative paths resolve.
CaseConfig parse_case(const std::string& text, const std::filesystem::path& dir, const std::string& source);

} // namespace scalemesh
