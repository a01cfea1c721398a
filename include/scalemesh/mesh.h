#pragma once
// scalemesh as a library: a surface (closed or open-ended), or an image, in;
// a layered tetrahedral mesh for CFD out, as flat arrays (the layout of Gmsh's
// gmsh::model::mesh::getNodes and getElements, of NumPy and of libigl's V, F,
// T), and from it what `scalemesh run` writes: the OpenFOAM case
// (write_openfoam), the .msh with physical groups and views (write_msh) and
// the report (report_json). The stages, parameters and guarantees are those
// of `scalemesh run` (docs/method.md, docs/case-file.md); the library never
// prints, never exits and changes no process-wide setting (threads run in a
// TBB arena of its own), but for the few that mesh_image on a file,
// write_msh and, with the default layers = "prisms", mesh_surface list (a host that holds
// a Gmsh session says so: MeshOptions::host_gmsh_session,
// MshOptions::host_gmsh_session). Its options are read alike under any
// LC_NUMERIC; ITK's and Gmsh's file readers follow the locale the host set.
//
// Errors are the exceptions of <scalemesh/errors.h>, all derived from
// std::runtime_error: InputError (bad input or options; the message says what
// to change), IoError (a file that cannot be read), StageError (a stage that
// could not establish a fact it promises, naming the stage and elements).
// Include <scalemesh/scalemesh.h> to have both.

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

// The functions of the library: the only symbols libscalemesh.so exports
// (its own code is compiled with hidden visibility, the stage libraries in it
// hidden at its link). Everything else here is defined in the headers.
#ifndef SCALEMESH_API
#define SCALEMESH_API __attribute__((visibility("default")))
#endif

namespace scalemesh {

namespace detail {
struct RunState; // the run behind a MeshResult (MeshResult::run), private to the library
}

// A length in mm or in voxel widths. For a surface input the "voxel width" is
// the mean edge length of its triangles, as for a surface file in a case.
struct MeshLength {
    double value = 0;
    bool voxels = false;
    static MeshLength mm(double v) { return {v, false}; }
    static MeshLength in_voxels(double v) { return {v, true}; }
};

// An inlet or outlet: a [[openings]] table of the case file (docs/case-file.md),
// the same keys, checked as the case file's are (InputError naming the
// opening and the key). Where it is, by exactly one of:
//   - a clip plane, point and normal (and optionally radius): the lumen is
//     cut there and capped flat;
//   - border, a side of the image (mesh_image): the cross-sections where the
//     segmentation runs off the image, cut `inset` inside it;
//   - near, an open end of an open surface: the end whose centre is nearest
//     the point, cut flat just inside its rim;
//   - label, a flat cap of a surface file's face labels (mesh_image on a
//     .vtp or .msh; mesh_surface's labels are patches, not caps).
// Each opening becomes a patch of its name; an open end no opening names
// becomes one of its own ("inlet" for the largest when no opening is an
// inlet, then outlet_1, outlet_2, ...).
struct MeshOpening {
    std::string name = {};                     // the patch: letters, digits and '_', not a digit first, not "wall"
    std::string type = {};                     // "inlet" or "outlet" (the flow enters at inlets)
    std::optional<std::array<double, 3>> point = {};  // clip plane: a point inside the lumen (mm)
    std::optional<std::array<double, 3>> normal = {}; // clip plane: its normal, pointing out of the lumen
    double radius = 0;                         // clip plane: only the crossing within this distance of `point`
                                               // is cut (mm); 0: the plane must cross the lumen exactly once
    std::string border = {};                   // "x-", "x+", "y-", "y+", "z-" or "z+"; empty: not a border opening
    std::optional<MeshLength> inset = {};      // border: how far inside the image face to cut; empty: "auto"
    std::optional<std::array<double, 3>> near = {}; // open end: the one nearest this point (mm)
    std::optional<std::int32_t> label = {};    // open end: the flat cap of this face label
    double extension = 0;                      // flow extension: a straight tube this many cap diameters long
                                               // added beyond the cap; 0: none, at most 100
};

// The parameters of a run, with their defaults: those of the case file
// scalemesh.toml too, whose reader takes them from here (the one place they
// are set). The names are the case file's keys (the [smoothing] keys as
// sweeps, omega, max_displacement, [remeshing] cycles) and Python's keywords;
// every value is checked as the case file's is (InputError naming the
// section and key). Ranges are written [a, b] (closed) and (a, b] (a left
// out); a length is in mm or voxel widths (MeshLength) and positive.
// `scalemesh options` lists them with their case-file keys, ranges and
// meanings (`--json` for programs).
struct MeshOptions {
    // [sizing], the paper's Algorithm 1.
    double K = 4.2;                          // anisotropy of the elements at the wall, surface edge length over
                                             // layer thickness (dimensionless), (0, 1000]
    double M = 7;                            // element layers across a cross-section, [1, 1000]
    double G = 0.85;                         // gradient limit of d, |d_i - d_j| <= G |x_i - x_j| (dimensionless),
                                             // (0, 1000]
    MeshLength L_min = {0.5, true};          // smallest feature size resolved: half a voxel (paper section 3)
    std::optional<MeshLength> L_max = {};    // largest, >= L_min; empty: the largest extent of the surface
    bool curvature = false;                  // the curvature term, eq. (12)

    // [smoothing], volume-conserving smoothing before sizing.
    int smoothing_sweeps = 10;               // Gauss-Seidel sweeps, [0, 10000] (0: none)
    double smoothing_omega = 1.0;            // under-relaxation (dimensionless), (0, 1]
    MeshLength smoothing_reach = {0.5, true}; // how far a node may move from where it started: half a voxel

    // [remeshing]
    int remesh_cycles = 3;                   // [1, 100] (a volume mesh needs remeshing; a case file may give 0)

    // [volume], Algorithms 4 and 5.
    double growth = 1.0;                     // layer thickness ratio, [1, 3]; 1 = uniform layers
    std::string first_layer = "edge";        // "edge" (surface edge length / K) or "paper" (d / M)
    std::string layers = "prisms";           // "prisms" (prism layers built explicitly, the core meshed above by
                                             // Gmsh) or "delaunay" (the paper's layer points in one Delaunay
                                             // triangulation, no Gmsh)
    double layer_tolerance = 0.15;           // fraction of its layer spacing a layer point may move, (0, 0.5]
                                             // (with "prisms": a column's top, along its column)

    // [run]
    int threads = 0;                         // worker threads of every parallel stage, [0, 1024]; 0: every core
    std::int64_t max_memory = 0;             // bytes the run may use (estimated before the heavy stages), >= 0;
                                             // 0: the machine's physical memory (not a case-file key: the
                                             // command line's run --max-memory)

    // [[openings]], in order: patches 1, 2, ... of the mesh (patch 0 is
    // "wall"). Empty: a closed surface has none; an open one gets one per
    // open end, named as MeshOpening says.
    std::vector<MeshOpening> openings;

    // Called when a stage starts (seconds < 0) and when it ends, with the
    // stage's one-line summary; on the calling thread. Empty: no calls.
    std::function<void(const std::string& stage, double seconds, const std::string& summary)> progress;

    // The host has Gmsh initialised (gmsh::initialize; gmsh.initialize() in
    // Python): the stages that reach Gmsh (reading a .msh input, meshing the
    // core with layers = "prisms") work through the host's session, on
    // scratch models of their own that are removed afterwards, the host's
    // current model and options as they were (InputError when Gmsh has no
    // model: not initialised). false: through a session of the library's own,
    // gmsh::initialize before and gmsh::finalize after, which would end a
    // session the host holds. As MshOptions::host_gmsh_session.
    bool host_gmsh_session = false;
};

// A triangulated surface in mm, outward or inward wound (inward winding is
// reversed, as for surface files): closed and 2-manifold, or open-ended as
// the clipped vessels of VMTK, SimVascular or 3D Slicer are, a 2-manifold
// whose open boundary loops (of 6 edges or more) are the vessels' ends; each
// end is cut flat and capped, and becomes an opening (MeshOptions::openings).
struct SurfaceInput {
    std::vector<double> points;          // 3N: x0 y0 z0 x1 y1 z1 ... (mm)
    std::vector<std::size_t> triangles;  // 3M: 0-based indices into points, three per triangle
    // Optional, empty or one per triangle: a label per input triangle. Each
    // boundary triangle of the mesh gets the label of the input triangle
    // nearest its centroid (the mesh follows the input surface within the
    // smoothing reach), as its patch id. Closed surfaces without openings
    // only (InputError otherwise); write_openfoam writes every such patch as
    // a wall, so a flow case needs openings instead.
    std::vector<std::int32_t> labels;
    // Optional names of the labels: label_names[i] names label i; missing
    // names become "patch_<i>".
    std::vector<std::string> label_names;
};

// Image input: how an image's voxels become inside and outside, as in the
// case file's [input] section.
struct ImageOptions {
    std::string grid;                    // VDB grid name; empty: the first scalar grid
    std::vector<int> labels;             // label values that are inside; empty: any nonzero voxel
    std::optional<double> threshold;     // intensity images: inside where value > threshold
    bool level_set = false;              // values are a signed distance, negative inside
    std::optional<double> iso;           // default 0 for level sets, 0.5 for labels
    int connectivity = 6;                // inside voxel connectivity, 6 or 26
    std::string units = "mm";            // surface files only: "mm", "cm", "m" or "um"
};

// An image in memory, as a file would hold it: a label map, a mask, an
// intensity image or a level set (ImageOptions says which), voxel (i, j, k)
// centred at origin + (i spacing[0], j spacing[1], k spacing[2]) mm, the
// index axes along the world axes x, y, z. A NumPy array vol[i, j, k]
// (pygalmesh's generate_from_array convention) is this view with its strides
// divided by its item size: for a C-ordered array strides (ny nz, nz, 1), for
// a Fortran-ordered one (NIfTI's layout, x fastest) (1, nx, nx ny). The
// voxels are read, never written, and need only live during the call.
struct ImageView {
    enum class Type { uint8, int8, uint16, int16, uint32, int32, uint64, int64, float32, float64 };
    const void* data = nullptr;                   // voxel (0, 0, 0)
    Type type = Type::uint8;
    std::array<std::int64_t, 3> size = {};        // voxels along i, j, k
    std::array<std::int64_t, 3> strides = {};     // elements (not bytes) from a voxel to its neighbour along
                                                  // i, j, k; may be negative; all 0: x fastest, packed
                                                  // (1, size[0], size[0] size[1])
    std::array<double, 3> spacing = {1, 1, 1};    // mm between voxel centres along i, j, k
    std::array<double, 3> origin = {0, 0, 0};     // mm: the centre of voxel (0, 0, 0)
};

// The layered tetrahedral mesh, in mm, as flat arrays, and the run that made
// it (`run`), from which write_openfoam, write_msh and report_json write
// what `scalemesh run` writes.
struct MeshResult {
    std::vector<double> points;          // 3N: x y z per point (mm)
    std::vector<std::size_t> tets;       // 4T: 0-based point indices, positively oriented:
                                         // (b - a) . ((c - a) x (d - a)) > 0
    std::size_t surface_points = 0;      // points [0, surface_points) are the boundary nodes
    std::vector<std::size_t> boundary_triangles; // 3B: counter-clockwise seen from outside
    std::vector<std::int32_t> boundary_patch;    // B: patch id per boundary triangle
    std::vector<std::string> patch_names;        // name per patch id

    // Per point (N values). Feature size fields of Algorithm 1 on the boundary
    // nodes, NaN at interior points: D (inward ray distance, mm), D_out
    // (outward, mm; -1 where the ray escapes), d (the stable sizing field, mm).
    std::vector<double> D, D_out, d;
    // Realised element layers of each boundary node (-1 at opening nodes),
    // NaN at interior points.
    std::vector<double> layers;
    // Layer index of each point: 0 on the boundary, m for the m-th layer.
    std::vector<std::int32_t> point_layer;
    // The boundary node each point was made from (itself on the boundary;
    // for a point of a sliver's edge split, the nearest boundary node), and
    // 1 for filler points and edge-split points, 0 for the boundary nodes and
    // their layer points. The column of boundary node i is the points with
    // generator i and filler 0, in the order of their point_layer.
    std::vector<std::int32_t> point_generator;
    std::vector<std::uint8_t> point_filler;

    // Per tet (T values): aspect ratio 2 sqrt(6) r_in / l_max (1 for the
    // regular tet), and the largest layer index of its points.
    std::vector<double> aspect_ratio;
    std::vector<std::int32_t> tet_layer;

    // The layers the run built, as report.json's volume.layers_built:
    // "prisms" (prism layers, the core meshed by Gmsh) or "delaunay" (the
    // paper's layer points in one Delaunay triangulation). MeshOptions::layers,
    // but for prism layers given up because their mesh missed a floor: then
    // "delaunay", and report_json's volume.layer_fallback says why.
    std::string layers_built;

    // The run behind the arrays: the stages' own results (the volume mesh
    // with its adjacency, the sizing fields, the layer columns, the openings'
    // caps, the stage times) and the options, checked. Shared by copies of
    // the result and never changed: the writers write the mesh as the run
    // made it, so changing the arrays above changes nothing they write (and
    // clearing them, to save memory, loses nothing they need). It holds the
    // run's memory (the volume mesh again, its face adjacency, the prism
    // layers' OpenFOAM cells and the stages' surfaces) until the last copy
    // is gone; reset it when no writer will be called. Empty in a
    // MeshResult the library did not make; the writers then throw
    // InputError.
    std::shared_ptr<const detail::RunState> run;

    std::size_t point_count() const { return points.size() / 3; }
    std::size_t tet_count() const { return tets.size() / 4; }
    std::size_t boundary_count() const { return boundary_triangles.size() / 3; }
};

// Meshes a surface: its open ends (if any) closed for the stages, volume-
// conserving smoothing, the openings cut and capped, the feature size field,
// remeshing to K/M d, and the layered volume mesh (the stages of
// `scalemesh run` for a surface file). The input is checked first: InputError
// for a size that is not a multiple of 3, an index out of range, a NaN or
// infinite coordinate, labels of the wrong length, labels on an open surface
// or with openings, a surface that is neither closed and 2-manifold nor a
// 2-manifold with open ends, or one that crosses itself, and for openings as
// the case reader checks [[openings]] (naming the opening and the key) and as
// the openings stage finds them (a point outside the surface, an open end no
// opening can name); StageError when a stage fails.
SCALEMESH_API MeshResult mesh_surface(const SurfaceInput& surface, const MeshOptions& options = {});

// Meshes an image (.vdb, .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd, .vti) or a
// surface file (.stl, .ply, .obj, .vtp, .msh; closed or open-ended, with face
// labels), as `scalemesh run` does a case with `file = path`. Throws IoError
// for a file that cannot be read, InputError and StageError as mesh_surface.
// A .msh file is read through a Gmsh session: the host's with
// MeshOptions::host_gmsh_session, else one of the library's own
// (gmsh::initialize and finalize, which would end a session the host holds;
// the same holds for both functions with layers = "prisms", whose core Gmsh
// meshes). Two process-wide effects remain on this path: a MetaImage read
// swaps std::cerr's buffer while ITK's MetaIO reads (MetaIO writes to
// std::cerr itself, not through ITK's output window, and reports truncated
// data and header faults only there), under the importers' lock (a NIfTI or
// NRRD read leaves std::cerr alone); and a NIfTI read leaves nifti1_io's
// debug level at 0, as ITK's NIfTI reader sets it in its constructor
// (nifti1_io has no way to read a level back, so it cannot be restored).
// An image in memory (the overload below) has neither effect.
SCALEMESH_API MeshResult mesh_image(const std::filesystem::path& path, const MeshOptions& options = {},
                                    const ImageOptions& image = {});

// Meshes an image in memory exactly as mesh_image meshes a file holding the
// same voxels with the same spacing and origin and an identity direction
// (a MetaImage with Offset = origin and ElementSpacing = spacing; a NIfTI
// whose ITK (LPS) origin and directions are these). ImageOptions as for a
// file (labels, threshold, level_set, iso, connectivity); grid and units,
// which name parts of files, must be left empty and "mm". No process-wide
// effect, but with layers = "prisms" and no host_gmsh_session the core is
// meshed in a Gmsh session of its own (initialised and finalised here). Throws InputError for a null data pointer, a size below 1 voxel
// along an axis, more than 2^31 voxels, a non-positive or non-finite
// spacing, a non-finite origin, NaN or infinite values, no voxel inside (as
// for a file), and as mesh_surface for the options; StageError as
// mesh_surface.
SCALEMESH_API MeshResult mesh_image(const ImageView& image, const MeshOptions& options = {},
                                    const ImageOptions& how = {});

// The OpenFOAM case's settings: the case file's [flow] and the OpenFOAM keys
// of its [output], with its defaults, checked as the case file's are
// (InputError naming the key).
struct OpenFoamOptions {
    double viscosity = 3.3e-6;   // m^2/s, kinematic, (0, 1]; blood is about 3.3e-6
    double inlet_speed = 0.1;    // m/s, uniform inflow normal to each inlet, (0, 1000]
    bool binary = false;         // polyMesh "format binary" (openfoam_format = "binary")
    bool layer_prisms = true;    // the three tets filling a layer prism written as one prism cell
};

// What write_openfoam wrote (report.json's "openfoam" section holds more).
struct OpenFoamCase {
    std::int64_t cells = 0, faces = 0, internal_faces = 0;
    std::int64_t layer_prisms = 0;           // cells that are whole layer prisms
    std::vector<std::string> patch_names;    // in the order of constant/polyMesh/boundary
    std::vector<std::int64_t> patch_faces;   // per patch, same order
    bool flow_fields = false;                // 0/U and 0/p written: the mesh has an inlet and an outlet
    std::vector<std::string> warnings;       // as report.json's: doubts about the input, floors the mesh misses,
                                             // faces checkMesh would fail, openings that pose no flow
};

// Writes the OpenFOAM case of `result` into `case_dir` (made if missing) as
// `scalemesh run` writes it, by the same writers after the same checks:
// constant/polyMesh (points, faces, owner, neighbour, boundary; metres; the
// layer prisms as prism cells where OpenFOAM's own cell checks pass them;
// patch "wall" of type wall, one patch per opening), constant/
// transportProperties and turbulenceProperties, system/ (controlDict,
// fvSchemes, fvSolution for simpleFoam), 0/U and 0/p when there are an inlet
// and an outlet, an executable Allrun (checkMesh, then simpleFoam), and
// report.json (report_json's, with the "openfoam" section and the files).
// Every file is finished under a temporary name and all are moved into place
// together: a failure leaves `case_dir` as it was (and removes it when this
// call made it). Files of an earlier case that this one does not write (0/
// when the flow fields are not) are removed when the earlier report.json
// lists them. Throws InputError for a result the library did not make or bad
// options, IoError when a file cannot be written, StageError when the mesh
// fails the writers' validation. No process-wide effect.
SCALEMESH_API OpenFoamCase write_openfoam(const MeshResult& result, const std::filesystem::path& case_dir,
                                          const OpenFoamOptions& options = {});

// The .msh file's format: the case file's [output] msh_version and
// msh_binary, and whose Gmsh session writes it.
struct MshOptions {
    double version = 4.1;        // 4.1 or 2.2 (gmshToFoam and older tools read 2.2)
    bool binary = false;
    // The host has Gmsh initialised (gmsh::initialize; gmsh.initialize() in
    // Python): the file is written through the host's session, on a scratch
    // model of its own that is removed afterwards, the host's current model
    // and options as they were (InputError when Gmsh has no model: not
    // initialised). false: through a session of the library's own,
    // gmsh::initialize before and gmsh::finalize after, which would end a
    // session the host holds.
    bool host_gmsh_session = false;
};

// Writes the volume mesh of `result` to `path` (.msh) as `scalemesh run`
// writes its mesh.msh: the tets in a physical volume "fluid", the boundary
// triangles in one physical surface per patch (named as patch_names), the
// views D, D_out, d, edge_length_ratio and layers (NodeData on the boundary
// nodes) and aspect_ratio and layer (ElementData on the tets), a $Comments
// section with the version, input and parameters. The mesh is validated
// first and the file appears whole or not at all. One process-wide effect:
// without MshOptions::host_gmsh_session, the Gmsh session of the library's
// own (gmsh::initialize, gmsh::finalize), so do not call it so while the
// host has Gmsh initialised. Throws InputError for a path not ending in
// .msh, a result the library did not make or bad options, IoError,
// StageError as write_openfoam.
SCALEMESH_API void write_msh(const MeshResult& result, const std::filesystem::path& path,
                             const MshOptions& options = {});

// The report of the run behind `result`, the JSON text the report.json of
// `scalemesh run` holds (docs/case-file.md) for a run that wrote no files:
// version, input, parameters, stage times and summaries, surface facts,
// sizing and remeshing statistics, the volume mesh's facts and quality
// histograms, the layer account, openings, memory and warnings. Throws
// InputError for a result the library did not make.
SCALEMESH_API std::string report_json(const MeshResult& result);

} // namespace scalemesh
