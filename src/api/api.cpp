// The library face of scalemesh (include/scalemesh/mesh.h): a case made from
// MeshOptions, run through run_pipeline, its mesh handed back as flat arrays.
//
// This file does not include scalemesh/scalemesh.h: the exceptions of
// scalemesh/errors.h are those of core/errors.h (the installed copy of that
// header), and one translation unit cannot see both copies.

#include "scalemesh/mesh.h"

#include "api/run_state.h"
#include "core/errors.h"
#include "core/nearest_triangle.h"
#include "core/surface_mesh.h"
#include "gmsh_io/gmsh_session.h"
#include "importers/image_importer.h"
#include "pipeline/case_config.h"
#include "pipeline/pipeline.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

namespace scalemesh {

namespace {

// The case a run through the library amounts to, every value checked, and
// named, as in a scalemesh.toml: `file` the input image or surface file
// (empty: run_pipeline is handed the input in memory).
CaseConfig case_for(const std::filesystem::path& file, const MeshOptions& o, const ImageOptions& image)
{
    CaseConfig config;
    config.directory = ".";
    config.source = "mesh options";
    config = input_from_options(file, image, std::move(config));
    config = openings_from_options(o.openings, std::move(config));
    config = config_from_options(o, std::move(config));
    if (config.remesh_cycles < 1)
        throw InputError("mesh options: remesh_cycles = 0 builds no volume mesh",
                         "give 1 to 100 cycles (default " + std::to_string(MeshOptions{}.remesh_cycles) + ")");
    return config;
}

// `surface` or `image`: the input in memory, instead of the case's [input] file.
PipelineRun run_for_mesh(const CaseConfig& config, const MeshOptions& options,
                         const LabelledSurface* surface = nullptr, const VoxelArray* image = nullptr)
{
    StageListener listener;
    if (options.progress)
        listener = [&](const StageTime& s) { options.progress(s.name, s.seconds, s.summary); };
    // The host's session, adopted: the stages' own sessions nest in it and
    // neither initialise nor finalise Gmsh.
    std::optional<GmshSession> host;
    if (options.host_gmsh_session) {
        detail::require_gmsh_session("call gmsh::initialize (gmsh.initialize() in Python) first, or leave "
                                     "host_gmsh_session false for a session of the library's own");
        host.emplace(GmshSession::Host{});
    }
    return run_pipeline(config,
                        {.sizing = true,
                         .remesh = true,
                         .volume = true,
                         .max_memory = options.max_memory,
                         .surface = surface,
                         .image = image},
                        listener);
}

// The arrays of `run`'s mesh.
MeshResult to_result(const PipelineRun& run, const CaseConfig& config)
{
    const TetMesh mesh = export_mesh(run, config.K, config.M);
    MeshResult out;
    const size_t n = mesh.points.size();
    out.points.reserve(3 * n);
    for (const Vec3& p : mesh.points) out.points.insert(out.points.end(), {p.x, p.y, p.z});
    out.tets.reserve(4 * mesh.tets.size());
    for (const Tet& t : mesh.tets)
        for (int32_t v : t) out.tets.push_back(static_cast<size_t>(v));
    out.surface_points = run.remeshed->surface.points.size();
    out.boundary_triangles.reserve(3 * mesh.boundary_faces.size());
    for (const Triangle& t : mesh.boundary_faces)
        for (int32_t v : t) out.boundary_triangles.push_back(static_cast<size_t>(v));
    out.boundary_patch = mesh.boundary_patch.empty() ? std::vector<int32_t>(mesh.boundary_faces.size(), 0)
                                                     : mesh.boundary_patch;
    out.patch_names = mesh.patch_names;

    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (const VertexField& field : mesh.point_fields) {
        std::vector<double>* target = field.name == "D"        ? &out.D
                                      : field.name == "D_out"  ? &out.D_out
                                      : field.name == "d"      ? &out.d
                                      : field.name == "layers" ? &out.layers
                                                               : nullptr;
        if (!target) continue;
        *target = field.values;
        target->resize(n, nan); // the fields cover the surface nodes, the first points
    }
    out.point_layer = run.volume->point_layer;
    out.point_generator = run.volume->point_generator;
    out.point_filler.assign(run.volume->point_filler.begin(), run.volume->point_filler.end());
    for (const auto& [name, values] : mesh.tet_fields) {
        if (name == "aspect_ratio") out.aspect_ratio = values;
        if (name == "layer")
            for (double v : values) out.tet_layer.push_back(static_cast<int32_t>(v));
    }
    out.layers_built = run.layers == LayerMode::prisms ? "prisms" : "delaunay";
    return out;
}

// Keeps the run behind `result`'s arrays, for the writers; with
// `relabelled`, the patches of the arrays (mesh_surface's labels) in place
// of the run's.
void keep_run(MeshResult& result, PipelineRun&& run, const CaseConfig& config, bool relabelled)
{
    auto state = std::make_shared<detail::RunState>();
    state->config = config;
    state->run = std::move(run);
    if (relabelled) {
        state->boundary_patch = result.boundary_patch;
        state->patch_names = result.patch_names;
    }
    result.run = std::move(state);
}

// The input surface as a SurfaceMesh, checked: sizes, indices, coordinates
// and labels (whether it is closed and 2-manifold, or 2-manifold with open
// ends, the import stage checks, as for a surface file).
SurfaceMesh checked_surface(const SurfaceInput& in)
{
    if (in.points.size() % 3 != 0)
        throw InputError("the surface's points hold " + std::to_string(in.points.size()) +
                             " numbers, not a multiple of 3",
                         "give x, y, z per point, flat: 3N numbers");
    if (in.triangles.size() % 3 != 0)
        throw InputError("the surface's triangles hold " + std::to_string(in.triangles.size()) +
                             " indices, not a multiple of 3",
                         "give three 0-based point indices per triangle, flat: 3M indices");
    if (in.triangles.empty()) throw InputError("the surface has no triangles", "give a closed triangulated surface");
    const size_t n = in.points.size() / 3;
    if (n > static_cast<size_t>(std::numeric_limits<int32_t>::max()))
        throw InputError("the surface has " + std::to_string(n) + " points, more than scalemesh indexes",
                         "give fewer than 2^31 points");
    for (size_t i = 0; i < in.points.size(); ++i)
        if (!std::isfinite(in.points[i]))
            throw InputError("coordinate " + std::to_string(i % 3) + " of point " + std::to_string(i / 3) +
                                 " of the surface is not a finite number",
                             "remove NaN and infinite coordinates");
    const size_t m = in.triangles.size() / 3;
    if (!in.labels.empty() && in.labels.size() != m)
        throw InputError("the surface has " + std::to_string(in.labels.size()) + " labels for " + std::to_string(m) +
                             " triangles",
                         "give one label per triangle, or none");
    for (int32_t label : in.labels)
        if (label < 0)
            throw InputError("the surface has a negative label (" + std::to_string(label) + ")",
                             "give labels 0, 1, 2, ...");
    SurfaceMesh mesh;
    mesh.points.reserve(n);
    for (size_t i = 0; i < n; ++i) mesh.points.push_back({in.points[3 * i], in.points[3 * i + 1], in.points[3 * i + 2]});
    mesh.triangles.reserve(m);
    for (size_t t = 0; t < m; ++t) {
        Triangle tri;
        for (int k = 0; k < 3; ++k) {
            const size_t v = in.triangles[3 * t + k];
            if (v >= n)
                throw InputError("triangle " + std::to_string(t) + " names point " + std::to_string(v) + " of " +
                                     std::to_string(n),
                                 "give 0-based indices below the point count");
            tri[k] = static_cast<int32_t>(v);
        }
        mesh.triangles.push_back(tri);
    }
    return mesh;
}

// The label of the input triangle nearest each boundary triangle's centroid.
std::vector<int32_t> nearest_labels(const SurfaceMesh& input, const std::vector<int32_t>& labels,
                                    const MeshResult& mesh)
{
    std::vector<Vec3> centroids(mesh.boundary_count());
    for (size_t f = 0; f < centroids.size(); ++f) {
        Vec3 centroid{0, 0, 0};
        for (int c = 0; c < 3; ++c) {
            const size_t v = mesh.boundary_triangles[3 * f + c];
            centroid = centroid + Vec3{mesh.points[3 * v], mesh.points[3 * v + 1], mesh.points[3 * v + 2]} * (1.0 / 3);
        }
        centroids[f] = centroid;
    }
    std::vector<int32_t> out;
    out.reserve(centroids.size());
    for (int32_t t : nearest_triangles(input, centroids)) out.push_back(labels[t]);
    return out;
}

VoxelArray voxel_array(const ImageView& view)
{
    VoxelArray out;
    out.data = view.data;
    using T = ImageView::Type;
    switch (view.type) {
    case T::uint8: out.type = VoxelType::UInt8; break;
    case T::int8: out.type = VoxelType::Int8; break;
    case T::uint16: out.type = VoxelType::UInt16; break;
    case T::int16: out.type = VoxelType::Int16; break;
    case T::uint32: out.type = VoxelType::UInt32; break;
    case T::int32: out.type = VoxelType::Int32; break;
    case T::uint64: out.type = VoxelType::UInt64; break;
    case T::int64: out.type = VoxelType::Int64; break;
    case T::float32: out.type = VoxelType::Float32; break;
    case T::float64: out.type = VoxelType::Float64; break;
    default: throw InputError("the image's voxel type is not one of ImageView::Type", "give one of its types");
    }
    out.size = view.size;
    out.strides = view.strides;
    if (view.strides == std::array<int64_t, 3>{0, 0, 0}) out.strides = {1, view.size[0], view.size[0] * view.size[1]};
    out.spacing = view.spacing;
    out.origin = view.origin;
    return out;
}

} // namespace

MeshResult mesh_surface(const SurfaceInput& surface, const MeshOptions& options)
{
    const SurfaceMesh input = checked_surface(surface);
    const CaseConfig config = case_for({}, options, {}); // run_pipeline takes the surface in memory
    if (!surface.labels.empty()) {
        // The labels name patches by the nearest input triangle, which an
        // opening's cap (a new, flat face) has none of.
        const int64_t open_edges = surface_facts(input).boundary_edges;
        if (!config.openings.empty() || open_edges > 0)
            throw InputError(open_edges > 0 ? "the input surface is open (" + std::to_string(open_edges) +
                                                  " edges on one triangle only) and has labels (patches by the "
                                                  "nearest input triangle, as mesh_gmsh_model's physical surfaces)"
                                            : "the input surface has labels and the options give openings",
                             "labels name the patches of a closed surface without openings (mesh_gmsh_model meshes "
                             "closed surfaces only); for inlets and outlets give the surface without labels, "
                             "with openings (an open surface's ends become openings of their own)");
    }
    const LabelledSurface given{input, {}};
    PipelineRun run = run_for_mesh(config, options, &given);
    MeshResult result = to_result(run, config);
    if (!surface.labels.empty()) {
        result.boundary_patch = nearest_labels(input, surface.labels, result);
        const int32_t top = *std::max_element(surface.labels.begin(), surface.labels.end());
        result.patch_names.clear();
        for (int32_t p = 0; p <= top; ++p)
            result.patch_names.push_back(static_cast<size_t>(p) < surface.label_names.size() &&
                                                 !surface.label_names[p].empty()
                                             ? surface.label_names[p]
                                             : "patch_" + std::to_string(p));
    }
    keep_run(result, std::move(run), config, !surface.labels.empty());
    return result;
}

MeshResult mesh_image(const std::filesystem::path& path, const MeshOptions& options, const ImageOptions& image)
{
    const CaseConfig config = case_for(std::filesystem::absolute(path), options, image);
    PipelineRun run = run_for_mesh(config, options);
    MeshResult result = to_result(run, config);
    keep_run(result, std::move(run), config, false);
    return result;
}

MeshResult mesh_image(const ImageView& image, const MeshOptions& options, const ImageOptions& how)
{
    if (!how.grid.empty())
        throw InputError("ImageOptions::grid names a grid of a .vdb file, and an image in memory is none",
                         "leave grid empty");
    if (how.units != "mm")
        throw InputError("ImageOptions::units is the length unit of a surface file, and an image in memory is none",
                         "give the spacing and origin in mm and leave units \"mm\"");
    const VoxelArray voxels = voxel_array(image);
    const CaseConfig config = case_for({}, options, how); // run_pipeline takes the voxels in memory
    PipelineRun run = run_for_mesh(config, options, nullptr, &voxels);
    MeshResult result = to_result(run, config);
    keep_run(result, std::move(run), config, false);
    return result;
}

} // namespace scalemesh
