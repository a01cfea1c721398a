#pragma once
// scalemesh as a library: a closed surface, or an image, in; a layered
// tetrahedral mesh for CFD out, as flat arrays (the layout of Gmsh's
// gmsh::model::mesh::getNodes and getElements, of NumPy and of libigl's V, F,
// T). The stages, parameters and guarantees are those of `scalemesh run`
// (docs/method.md, docs/case-file.md); the library never prints, never exits
// and changes no process-wide setting (threads run in a TBB arena of its own),
// but for the few that mesh_image and, with layers = "prisms", mesh_surface
// list. Its options are read alike under any LC_NUMERIC; ITK's and Gmsh's
// file readers follow the locale the host set.
//
// Errors are the exceptions of <scalemesh/errors.h>, all derived from
// std::runtime_error: InputError (bad input or options; the message says what
// to change), IoError (a file that cannot be read), StageError (a stage that
// could not establish a fact it promises, naming the stage and elements).
// Include <scalemesh/scalemesh.h> to have both.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace scalemesh {

// A length in mm or in voxel widths. For a surface input the "voxel width" is
// the mean edge length of its triangles, as for a surface file in a case.
struct MeshLength {
    double value = 0;
    bool voxels = false;
    static MeshLength mm(double v) { return {v, false}; }
    static MeshLength in_voxels(double v) { return {v, true}; }
};

// The parameters of a run. A default-constructed MeshOptions holds the
// defaults of the case file scalemesh.toml (the same values, read from the
// case reader, not restated here); the names are the case file's keys, and
// every value is checked as the case file's is (InputError naming the key).
struct MeshOptions {
    MeshOptions();

    // [sizing], the paper's Algorithm 1.
    double K;                          // anisotropy of the elements at the wall
    double M;                          // element layers across a cross-section
    double G;                          // gradient limit of d, |d_i - d_j| <= G |x_i - x_j|
    MeshLength L_min;                  // smallest feature size resolved
    std::optional<MeshLength> L_max;   // largest; empty: the largest extent of the surface
    bool curvature;                    // the curvature term, eq. (12)

    // [smoothing], volume-conserving smoothing before sizing.
    int smoothing_sweeps;              // Gauss-Seidel sweeps, 0 to 10000 (0: none)
    double smoothing_omega;            // under-relaxation, (0, 1]
    MeshLength smoothing_reach;        // how far a node may move from where it started

    // [remeshing]
    int remesh_cycles;                 // 1 to 100 (a volume mesh needs remeshing)

    // [volume], Algorithms 4 and 5.
    double growth;                     // layer thickness ratio, [1, 3]; 1 = uniform layers
    std::string first_layer;           // "edge" (surface edge length / K) or "paper" (d / M)
    std::string layers;                // "delaunay" (the paper's layer points in one Delaunay triangulation)
                                       // or "prisms" (prism layers built explicitly, the core meshed above)
    double layer_tolerance;            // fraction of its layer spacing a layer point may move, (0, 0.5]

    // [run]
    int threads;                       // worker threads of every parallel stage; 0: every core
    std::int64_t max_memory = 0;       // bytes the run may use (estimated before the heavy stages);
                                       // 0: the machine's physical memory

    // Called when a stage starts (seconds < 0) and when it ends, with the
    // stage's one-line summary; on the calling thread. Empty: no calls.
    std::function<void(const std::string& stage, double seconds, const std::string& summary)> progress;
};

// A closed, 2-manifold, triangulated surface in mm, outward or inward wound
// (inward winding is reversed, as for surface files).
struct SurfaceInput {
    std::vector<double> points;          // 3N: x0 y0 z0 x1 y1 z1 ... (mm)
    std::vector<std::size_t> triangles;  // 3M: 0-based indices into points, three per triangle
    // Optional, empty or one per triangle: a label per input triangle. Each
    // boundary triangle of the mesh gets the label of the input triangle
    // nearest its centroid (the mesh follows the input surface within the
    // smoothing reach), as its patch id.
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

// The layered tetrahedral mesh, in mm, as flat arrays.
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

    std::size_t point_count() const { return points.size() / 3; }
    std::size_t tet_count() const { return tets.size() / 4; }
    std::size_t boundary_count() const { return boundary_triangles.size() / 3; }
};

// Meshes a closed surface: volume-conserving smoothing, the feature size
// field, remeshing to K/M d, and the layered volume mesh (the stages of
// `scalemesh run` for a surface file). The input is checked first: InputError
// for a size that is not a multiple of 3, an index out of range, a NaN or
// infinite coordinate, labels of the wrong length, or a surface that is not
// closed and 2-manifold; StageError when a stage fails.
MeshResult mesh_surface(const SurfaceInput& surface, const MeshOptions& options = {});

// Meshes an image (.vdb, .nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd, .vti) or a
// surface file (.stl, .ply, .obj, .vtp, .msh; closed or open-ended, with face
// labels), as `scalemesh run` does a case with `file = path`. Throws IoError
// for a file that cannot be read, InputError and StageError as mesh_surface.
// Three process-wide effects remain on this path: a .msh file is read through
// a Gmsh session of the library's own (gmsh::initialize and finalize), so do
// not call it on a .msh while the host has Gmsh initialised (use
// mesh_gmsh_model, gmsh_model.h, on a model the host merged instead; the
// same holds for both functions with layers = "prisms", whose core Gmsh
// meshes); and a
// MetaImage read swaps std::cerr's buffer while ITK's MetaIO reads (it
// reports truncated compressed data only there), under the importers' lock
// (a NIfTI or NRRD read leaves std::cerr alone); and a NIfTI read leaves
// nifti1_io's debug level at 0, as ITK's NIfTI reader sets it (nifti1_io
// has no way to read a level back, so it cannot be restored).
MeshResult mesh_image(const std::filesystem::path& path, const MeshOptions& options = {},
                      const ImageOptions& image = {});

} // namespace scalemesh
