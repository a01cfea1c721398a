#include "pipeline/run_case.h"

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/version.h"
#include "exporters/histogram_png.h"
#include "exporters/openfoam_case.h"
#include "exporters/polymesh_writer.h"
#include "exporters/surface_writers.h"
#include "exporters/volume_writers.h"
#include "pipeline/memory_estimate.h"
#include "volume/layer_prisms.h"
#include "volume/quality.h"

#include <nlohmann/json.hpp>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include <signal.h>

namespace scalemesh {

namespace {

// checkMesh counts the faces beyond 70 degrees as severely non-orthogonal;
// the merged cells keep a little below it (OpenFOAM's own arithmetic).
constexpr double kSevereNonOrthogonality = 70;

nlohmann::json facts_json(const SurfaceFacts& f)
{
    return {{"vertices", f.vertices},
            {"triangles", f.triangles},
            {"components", f.components},
            {"euler_characteristic", f.euler_characteristic},
            {"closed_manifold", f.closed_manifold()},
            {"enclosed_volume_mm3", f.signed_volume},
            {"area_mm2", f.area}};
}

// Min, median and max of the finite values, and how many were not finite.
nlohmann::json field_stats(const std::vector<double>& values)
{
    std::vector<double> finite;
    std::copy_if(values.begin(), values.end(), std::back_inserter(finite), [](double v) { return std::isfinite(v); });
    nlohmann::json out = {{"count", values.size()}, {"infinite", values.size() - finite.size()}};
    if (!finite.empty()) {
        std::sort(finite.begin(), finite.end());
        out["min"] = finite.front();
        out["median"] = finite[finite.size() / 2];
        out["max"] = finite.back();
    }
    return out;
}

// The layer account (volume/layer_account.h): totals, the fate of each
// short node's first missing layer, and per patch.
nlohmann::json layers_json(const LayerAccount& a, const SurfaceMesh& surface, const std::vector<Cap>& caps)
{
    nlohmann::json losses;
    for (int k = 1; k < kLayerLossKinds; ++k) losses[layer_loss_name(static_cast<LayerLoss>(k))] = a.eligible_losses[k];
    // A node belongs to every patch of its triangles.
    int32_t patches = 1;
    for (int32_t p : surface.triangle_patch) patches = std::max(patches, p + 1);
    std::vector<std::vector<char>> on(patches, std::vector<char>(surface.points.size(), 0));
    for (size_t t = 0; t < surface.triangles.size(); ++t)
        for (int32_t v : surface.triangles[t]) on[t < surface.triangle_patch.size() ? surface.triangle_patch[t] : 0][v] = 1;
    nlohmann::json per_patch = nlohmann::json::array();
    for (int32_t p = 0; p < patches; ++p) {
        int64_t wall = 0, eligible = 0, full = 0, opening = 0;
        for (size_t v = 0; v < surface.points.size(); ++v) {
            if (!on[p][v]) continue;
            if (!a.wall[v]) {
                ++opening;
                continue;
            }
            ++wall;
            if (a.eligible[v]) ++eligible, full += a.realised[v] >= a.layermaking;
        }
        const std::string name = p == 0 ? "wall" : size_t(p - 1) < caps.size() ? caps[p - 1].name : "patch_" + std::to_string(p);
        per_patch.push_back({{"patch", name},
                             {"wall_nodes", wall},
                             {"eligible_wall_nodes", eligible},
                             {"eligible_with_all_layers", full},
                             {"coverage", eligible ? double(full) / double(eligible) : 1.0},
                             {"opening_nodes", opening}});
    }
    return {{"layermaking", a.layermaking},
            {"tolerance", std::isfinite(a.tolerance) ? nlohmann::json(a.tolerance) : nlohmann::json(nullptr)},
            {"wall_nodes", a.wall_nodes},
            {"wall_nodes_with_all_layers", a.wall_full},
            {"eligible_wall_nodes", a.eligible_nodes},
            {"eligible_with_all_layers", a.eligible_full},
            {"coverage", a.coverage()},
            {"mean_layers", a.eligible_mean},
            {"opening_nodes", a.opening_nodes},
            {"first_missing_layer", losses},
            {"max_displacement", a.max_displacement},
            {"stand_ins", a.stand_ins},
            {"per_patch", per_patch}};
}

} // namespace

namespace {

// Patch p of the polyMesh is a wall: patch 0, and any after the caps' own
// (one per cap, in order).
bool is_wall_patch(size_t p, size_t caps) { return p == 0 || p > caps; }

} // namespace

double intact_prism_share(const PipelineRun& run, const CaseOutputs& outputs)
{
    if (!outputs.polymesh || !run.volume) return 0;
    const int layermaking = run.volume->layers.layermaking;
    int64_t wall_faces = 0;
    const std::vector<int64_t>& patches = outputs.polymesh->patch_faces;
    for (size_t p = 0; p < patches.size(); ++p)
        if (is_wall_patch(p, run.caps.size())) wall_faces += patches[p];
    const int64_t wanted = wall_faces * layermaking;
    return wanted > 0 ? static_cast<double>(outputs.layer_prisms) / static_cast<double>(wanted) : 0;
}

std::vector<std::string> openfoam_check_warnings(const OpenFoamCellChecks& checks)
{
    if (checks.checkmesh_failures == 0) return {};
    char line[512];
    std::snprintf(line, sizeof line,
                  "%lld faces of the OpenFOAM cells would fail checkMesh (skewness above 4, or a face pyramid that is "
                  "not positive; worst skewness %.2f); a change of M or K remeshes the cells around them",
                  static_cast<long long>(checks.checkmesh_failures), checks.max_skewness);
    return {line};
}

std::vector<std::string> cell_floor_warnings(const CaseConfig& config, const CellFloors& cells)
{
    std::vector<std::string> warnings;
    char line[512];
    if (cells.min_aspect_ratio < config.min_aspect_ratio) {
        std::snprintf(line, sizeof line,
                      "the worst %s has aspect ratio %.4f, below the floor of %g ([volume] min_aspect_ratio); %.3f%% "
                      "of %ss are below 0.1",
                      cells.what.c_str(), cells.min_aspect_ratio, config.min_aspect_ratio,
                      100 * cells.fraction_below_0_1, cells.what.c_str());
        warnings.push_back(line);
    }
    if (cells.min_dihedral_deg < config.min_dihedral_deg) {
        // Of every tet the sentence is the one it has always been.
        const std::string of = cells.what == "tet" ? "" : " of a " + cells.what;
        std::snprintf(line, sizeof line,
                      "the smallest dihedral angle%s is %.2f degrees, below the floor of %g ([volume] min_dihedral_deg)",
                      of.c_str(), cells.min_dihedral_deg, config.min_dihedral_deg);
        warnings.push_back(line);
    }
    // checkMesh's own floor: it counts a face beyond 70 degrees as
    // severely non-orthogonal (the cell passes could not flip or move it).
    if (cells.max_non_orthogonality_deg > kSevereNonOrthogonality) {
        std::snprintf(line, sizeof line,
                      "the worst interior face is %.2f degrees off orthogonal, beyond the %g that checkMesh counts as "
                      "severe; a change of M or K remeshes the cells around it",
                      cells.max_non_orthogonality_deg, kSevereNonOrthogonality);
        warnings.push_back(line);
    }
    return warnings;
}

std::vector<std::string> floor_warnings(const CaseConfig& config, const PipelineRun& run, bool cells_later)
{
    std::vector<std::string> warnings = run.warnings; // the input's (units)
    if (!run.layer_fallback.empty())
        warnings.push_back("the prism layers were given up (" + run.layer_fallback +
                           "); the method paper's Delaunay layers are built instead, with fewer wall faces x layers "
                           "intact as prism cells ([volume] layers = \"delaunay\" asks for them directly)");
    if (!run.volume) return warnings;
    const VolumeResult& v = *run.volume;
    const LayerAccount& a = v.layers;
    char line[512];
    // Parameters under which the method makes no layer at all pass every
    // coverage floor vacuously: said so, and --strict fails them.
    if (a.wall_nodes > 0 && a.layermaking == 0) {
        std::snprintf(line, sizeof line,
                      "M = %g makes no layers along the wall (floor(M/2) = 0 layers from each side); give M >= 2",
                      config.M);
        warnings.push_back(line);
    } else if (a.wall_nodes > 0 && a.eligible_nodes == 0) {
        std::snprintf(line, sizeof line,
                      "no wall node has a local diameter D of at least L_min = %.4g mm, so none is owed its %d "
                      "layers; give an L_min below the vessels' diameters",
                      run.L_min, a.layermaking);
        warnings.push_back(line);
    }
    if (a.coverage() < config.min_layer_coverage) {
        std::string why;
        for (int k = 1; k < kLayerLossKinds; ++k)
            if (a.eligible_losses[k])
                why += (why.empty() ? "" : ", ") + std::to_string(a.eligible_losses[k]) + " " +
                       layer_loss_name(static_cast<LayerLoss>(k));
        std::snprintf(line, sizeof line,
                      "%lld of %lld wall nodes with D >= L_min keep all %d layers (%.1f%%), below the floor of "
                      "%.1f%% ([volume] min_layer_coverage); first missing layer: %s",
                      static_cast<long long>(a.eligible_full), static_cast<long long>(a.eligible_nodes), a.layermaking,
                      100 * a.coverage(), 100 * config.min_layer_coverage, why.c_str());
        std::string warning = line;
        if (run.layers == LayerMode::prisms) {
            // "moved" there means a shortened column: say what the columns hold.
            std::snprintf(line, sizeof line,
                          "; as prism layers, %lld of them have a column of all %d layers, at %.2f of the height "
                          "Algorithm 4 gave them on average (%.2f at least)",
                          static_cast<long long>(v.stack_whole_columns), a.layermaking, v.stack_height_mean,
                          v.stack_height_min);
            warning += line;
        }
        warnings.push_back(warning);
    }
    if (cells_later) return warnings;
    const QualityReport& q = v.after_slivers;
    for (std::string& w : cell_floor_warnings(config, {.min_aspect_ratio = q.min_aspect_ratio,
                                                       .fraction_below_0_1 = q.fraction_below_0_1,
                                                       .min_dihedral_deg = q.min_dihedral_deg,
                                                       .max_non_orthogonality_deg = v.max_non_orthogonality_deg,
                                                       .what = "tet"}))
        warnings.push_back(std::move(w));
    return warnings;
}

namespace {

// The quality of the tets written as cells of their own (every tet not in
// a cell of several), and OpenFOAM's worst face from `checks`.
CellFloors tet_cell_floors(const TetMesh& mesh, const LayerPrismCells& cells, const OpenFoamCellChecks& checks)
{
    std::vector<int32_t> tets_of(cells.cells, 0);
    for (int32_t c : cells.cell_of_tet) ++tets_of[c];
    CellFloors floors{.min_aspect_ratio = 1, .min_dihedral_deg = 90,
                      .max_non_orthogonality_deg = checks.max_non_orthogonality_deg, .what = "tet cell"};
    int64_t own = 0, below = 0;
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        if (tets_of[cells.cell_of_tet[t]] != 1) continue;
        const Tet& x = mesh.tets[t];
        const Vec3 &a = mesh.points[x[0]], &b = mesh.points[x[1]], &c = mesh.points[x[2]], &d = mesh.points[x[3]];
        const double aspect = tet_aspect_ratio(a, b, c, d);
        floors.min_aspect_ratio = std::min(floors.min_aspect_ratio, aspect);
        floors.min_dihedral_deg = std::min(floors.min_dihedral_deg, tet_min_dihedral_deg(a, b, c, d));
        ++own, below += aspect < 0.1;
    }
    floors.fraction_below_0_1 = own ? static_cast<double>(below) / static_cast<double>(own) : 0.0;
    return floors;
}

} // namespace

FoamCells foam_cells(const CaseConfig& config, const PipelineRun& run, const TetMesh& mesh)
{
    FoamCells out;
    const VolumeResult& v = *run.volume;
    OpenFoamCellChecks& checks = out.checks;
    const auto check = [&](const LayerPrismCells& c) {
        checks = openfoam_cell_checks(mesh, v.adjacency, c.cell_of_tet, c.cells, {},
                                      c.prism_cell.empty() ? nullptr : &c.prism_cell);
        return checks.grouped_cells_failing;
    };
    // With layers = "prisms" a prism is not split for its faces'
    // non-orthogonality alone: its three tets are flatter (their faces
    // further off) than the prism they fill; it is split where checkMesh
    // would fail it (`check`), or for a face at 89 degrees.
    const double prism_bound = run.layers == LayerMode::prisms ? 89.0 : 68.0;
    // With layers = "prisms", a tet cell below the aspect-ratio or
    // dihedral floor, on a face beyond 69.5 degrees or of an interpolation
    // weight below 0.06 (a sliver the
    // core's tets leave in a crease of the layers' top, pinned by the
    // locked prisms) is joined to one to three neighbouring cells where
    // their union is a sound polyhedron (OpenFOAM's checks decide).
    const PoorTetBounds poor{.min_aspect_ratio = config.min_aspect_ratio,
                             .min_dihedral_deg = config.min_dihedral_deg,
                             .max_non_orthogonality_deg = 69.5};
    LayerPrismCells& cells = out.cells;
    if (config.layer_prisms) {
        cells = checked_layer_prism_cells(mesh, v.adjacency, v.point_generator, v.point_layer, v.point_filler,
                                          prism_bound, check, run.layers == LayerMode::prisms ? &poor : nullptr);
    } else {
        cells.cells = static_cast<int32_t>(mesh.tets.size());
        cells.cell_of_tet.resize(mesh.tets.size());
        for (size_t t = 0; t < mesh.tets.size(); ++t) cells.cell_of_tet[t] = static_cast<int32_t>(t);
        check(cells);
    }
    if (run.layers == LayerMode::prisms && config.layer_prisms) out.tet_cells = tet_cell_floors(mesh, cells, checks);
    return out;
}

std::shared_ptr<const FoamCells> prism_layer_cells(const CaseConfig& config, const PipelineRun& run)
{
    if (!run.volume || run.layers != LayerMode::prisms || !config.openfoam || !config.layer_prisms) return nullptr;
    return std::make_shared<const FoamCells>(foam_cells(config, run, case_mesh(config, run)));
}

std::string prism_cells_shortfall(const CaseConfig& config, const FoamCells& foam)
{
    std::vector<std::string> missed = openfoam_check_warnings(foam.checks);
    for (std::string& w : cell_floor_warnings(config, *foam.tet_cells)) missed.push_back(std::move(w));
    std::string text;
    for (const std::string& w : missed) text += (text.empty() ? "" : "; ") + w;
    return text;
}

void write_text_file(const std::filesystem::path& path, const std::string& text)
{
    AtomicOutput out(path);
    {
        std::ofstream file(out.temporary(), std::ios::binary);
        file << text;
        if (!file.flush()) throw IoError(path.string(), "cannot write the file");
    }
    out.commit();
}

std::string report_json(const CaseConfig& config, const PipelineRun& run, const CaseOutputs& result)
{
    nlohmann::json report;
    report["scalemesh_version"] = SCALEMESH_VERSION;
    report["input"] = {{"source", run.input}, {"checksum_fnv1a64", run.input_checksum}, {"voxel_width_mm", run.voxel_width}};
    if (run.inside_voxels >= 0) report["input"]["inside_voxels"] = run.inside_voxels;
    if (config.keep_largest)
        report["input"]["dropped_regions"] = {{"regions", run.islands_dropped}, {"voxels", run.island_voxels}};
    if (!run.open_ends.empty()) {
        nlohmann::json ends = nlohmann::json::array();
        for (const OpenEnd& end : run.open_ends)
            ends.push_back({{"centre_mm", {end.centre.x, end.centre.y, end.centre.z}},
                            {"normal", {end.normal.x, end.normal.y, end.normal.z}},
                            {"area_mm2", end.area},
                            {"radius_mm", end.radius},
                            {"loop_edges", end.loop.size()},
                            {"max_distance_from_plane_mm", end.deviation},
                            {"label", end.label}});
        report["input"]["open_ends"] = ends;
    }
    if (!run.label_source.empty()) {
        nlohmann::json labels = nlohmann::json::array();
        for (const LabelPart& part : run.label_parts) {
            nlohmann::json entry = {{"label", part.label},
                                    {"triangles", part.triangles},
                                    {"area_mm2", part.area},
                                    {"role", part.cap ? "cap" : "wall"}};
            if (const auto name = run.label_names.find(part.label); name != run.label_names.end())
                entry["name"] = name->second;
            labels.push_back(entry);
        }
        report["input"]["face_labels"] = {{"source", run.label_source}, {"labels", labels}};
    }
    report["parameters"] = {{"K", config.K},
                            {"M", config.M},
                            {"G", config.G},
                            {"L_min", config.L_min.text()},
                            {"L_min_mm", run.L_min},
                            {"L_max", config.L_max ? config.L_max->text() : "largest extent of the surface"},
                            {"L_max_mm", run.L_max},
                            {"curvature", config.curvature},
                            {"layers", config.layers == LayerMode::prisms ? "prisms" : "delaunay"},
                            {"first_layer", config.first_layer == FirstLayer::edge ? "edge" : "paper"},
                            {"layer_tolerance", config.layer_tolerance},
                            {"growth", config.growth},
                            {"smoothing_sweeps", config.smoothing.sweeps},
                            {"smoothing_omega", config.smoothing.omega},
                            {"smoothing_max_displacement", config.smoothing_reach.text()},
                            {"connectivity", config.connectivity == InsideConnectivity::Six ? 6 : 26},
                            {"threads", config.threads}};
    nlohmann::json stages = nlohmann::json::array();
    for (const StageTime& s : run.stages) stages.push_back({{"stage", s.name}, {"seconds", s.seconds}, {"summary", s.summary}});
    report["stages"] = stages;
    report["isosurface"] = facts_json(run.isosurface);
    report["surface"] = facts_json(run.facts);
    if (!run.caps.empty()) {
        // Per opening: its plane; on the final surface the area its rim
        // encloses (from the rim edges alone) and how far the cap's vertices
        // lie from the plane; in the volume mesh the faces on its patch and
        // their area.
        const SurfaceMesh& final = final_surface(run);
        nlohmann::json openings = nlohmann::json::array();
        for (const Cap& cap : run.caps) {
            std::vector<std::array<int32_t, 2>> edges;
            double off_plane = 0;
            for (size_t f = 0; f < final.triangles.size(); ++f) {
                if (final.triangle_patch.empty() || final.triangle_patch[f] != cap.patch) continue;
                const Triangle& t = final.triangles[f];
                for (int k = 0; k < 3; ++k) {
                    edges.push_back({t[k], t[(k + 1) % 3]});
                    off_plane = std::max(off_plane, std::abs(cap.plane.signed_distance(final.points[t[k]])));
                }
            }
            std::sort(edges.begin(), edges.end());
            double rim_area = 0;
            int64_t rim_edges = 0;
            for (const auto& e : edges)
                if (!std::binary_search(edges.begin(), edges.end(), std::array<int32_t, 2>{e[1], e[0]})) {
                    rim_area += 0.5 * dot(cross(final.points[e[0]] - cap.plane.point, final.points[e[1]] - cap.plane.point),
                                          cap.plane.normal);
                    ++rim_edges;
                }
            nlohmann::json item = {{"name", cap.name},
                                   {"type", cap.type == OpeningType::Inlet ? "inlet" : "outlet"},
                                   {"patch", cap.patch},
                                   {"point_mm", {cap.plane.point.x, cap.plane.point.y, cap.plane.point.z}},
                                   {"normal", {cap.plane.normal.x, cap.plane.normal.y, cap.plane.normal.z}},
                                   {"cut_area_mm2", cap.area},
                                   {"rim_edges", rim_edges},
                                   {"rim_area_mm2", rim_area},
                                   {"max_distance_from_plane_mm", off_plane}};
            if (run.volume) {
                const TetMesh& mesh = run.volume->mesh;
                int64_t faces = 0;
                double area = 0, mesh_off_plane = 0;
                for (size_t f = 0; f < mesh.boundary_faces.size(); ++f) {
                    if (mesh.boundary_patch.empty() || mesh.boundary_patch[f] != cap.patch) continue;
                    const auto& t = mesh.boundary_faces[f];
                    const Vec3& a = mesh.points[t[0]];
                    area += 0.5 * dot(cross(mesh.points[t[1]] - a, mesh.points[t[2]] - a), cap.plane.normal);
                    for (int32_t v : t)
                        mesh_off_plane = std::max(mesh_off_plane, std::abs(cap.plane.signed_distance(mesh.points[v])));
                    ++faces;
                }
                item["mesh_faces"] = faces;
                item["mesh_area_mm2"] = area;
                item["mesh_max_distance_from_plane_mm"] = mesh_off_plane;
            }
            openings.push_back(item);
        }
        report["openings"] = openings;
        report["opened_surface"] = facts_json(run.opened);
        report["closed_regions_dropped"] = {{"count", run.closed_regions_dropped}, {"volume_mm3", run.closed_regions_volume}};
    }
    if (run.sizing) {
        const FeatureSize& s = *run.sizing;
        report["sizing"] = {{"D_mm", field_stats(s.D)},
                            {"D_out_mm", field_stats(s.D_out)},
                            {"d_mm", field_stats(s.d)},
                            {"inward_check_failures", std::count(s.inward_ok.begin(), s.inward_ok.end(), 0)},
                            {"escaped_inward_rays", s.escaped_inward_rays},
                            {"seconds_bvh", s.seconds_bvh},
                            {"seconds_rays", s.seconds_rays},
                            {"seconds_gradient_limiting", s.seconds_limit}};
    }
    if (run.remeshed) {
        const RemeshResult& r = *run.remeshed;
        const std::vector<VertexField> fields = surface_fields(run, config.K, config.M);
        const auto ratio = std::find_if(fields.begin(), fields.end(),
                                        [](const VertexField& f) { return f.name == "edge_length_ratio"; });
        report["remeshing"] = {{"merges", r.merges},
                               {"merges_in_cubes", r.cube_merges},
                               {"swaps", r.swaps},
                               {"bisections", r.bisections},
                               {"max_damage_mm", r.max_damage},
                               {"edge_length_ratio", field_stats(ratio != fields.end() ? ratio->values
                                                                                       : std::vector<double>{})},
                               {"d_mm", field_stats(r.sizing.d)}};
        report["remeshed_surface"] = facts_json(surface_facts(r.surface));
    }
    if (run.volume) {
        const VolumeResult& v = *run.volume;
        const TetMeshFacts facts = tet_mesh_facts(v.mesh, v.adjacency);
        const auto quality = [](const QualityReport& q) {
            return nlohmann::json{{"tets", q.tets},
                                  {"min_aspect_ratio", q.min_aspect_ratio},
                                  {"mean_aspect_ratio", q.mean_aspect_ratio},
                                  {"min_dihedral_deg", q.min_dihedral_deg},
                                  {"fraction_below_0_1", q.fraction_below_0_1},
                                  {"below_0_02", q.below_0_02},
                                  {"aspect_ratio_histogram_20_bins", q.histogram}};
        };
        report["volume"] = {{"layers_built", run.layers == LayerMode::prisms ? "prisms" : "delaunay"},
                            {"layer_fallback", run.layer_fallback.empty() ? nlohmann::json()
                                                                          : nlohmann::json(run.layer_fallback)},
                            {"points", v.mesh.points.size()},
                            {"tets", v.mesh.tets.size()},
                            {"volume_mm3", facts.volume},
                            {"enclosed_volume_mm3", signed_volume(run.remeshed->surface)},
                            {"boundary_matches_surface", facts.boundary_matches},
                            {"nonpositive_tets", facts.nonpositive_tets},
                            {"first_layer_anisotropy_median", v.first_layer_anisotropy_median},
                            {"max_non_orthogonality_deg", v.max_non_orthogonality_deg},
                            {"inserted_points", v.inserted_points},
                            {"deferred_points", v.deferred_points},
                            {"offset_points", v.offset_points},
                            {"stack_shortened_nodes", v.stack_shortened_nodes},
                            {"stack_rounds", v.stack_rounds},
                            {"stack_borrowed_columns", v.stack_borrowed_columns},
                            {"stack_lenient_prisms", v.stack_lenient_prisms},
                            {"stack_bare_wall_triangles", v.stack_holes},
                            {"stack_whole_columns", v.stack_whole_columns},
                            {"stack_height_mean", v.stack_whole_columns ? nlohmann::json(v.stack_height_mean)
                                                                        : nlohmann::json()},
                            {"stack_height_min", v.stack_whole_columns ? nlohmann::json(v.stack_height_min)
                                                                       : nlohmann::json()},
                            {"flips_3_2", v.flips_32},
                            {"flips_2_3", v.flips_23},
                            {"flips_4_4", v.flips_44},
                            {"surface_quads", v.surface_quads},
                            {"surface_quads_flipped", v.quad_flips},
                            {"surface_facet_flips", v.facet_flips},
                            {"surface_caps_peeled", v.caps_peeled},
                            {"insertion_retries", v.insertion_retries},
                            {"layer_prism_groups",
                             {{"after_insertion", v.prism_groups.after_insertion},
                              {"after_flips", v.prism_groups.after_flips},
                              {"after_slivers", v.prism_groups.after_slivers},
                              {"after_cell_passes", v.prism_groups.after_cell_passes}}},
                            {"non_orthogonality_pass",
                             {{"faces_above_65_deg_before", v.ortho_faces_before},
                              {"flips", v.ortho_flips},
                              {"moves", v.ortho_moves},
                              {"splits", v.ortho_splits}}},
                            {"dihedral_pass",
                             {{"tets_below_12_deg_before", v.dihedral_tets_before},
                              {"flips", v.dihedral_flips},
                              {"moves", v.dihedral_moves},
                              {"splits", v.dihedral_splits},
                              {"released_layer_points", v.released_layer_points}}},
                            {"light_faces",
                             {{"below_0_06_before", v.light_faces_before},
                              {"cap_flips", v.light_face_cap_flips},
                              {"poor_tet_cap_flips", v.poor_tet_cap_flips},
                              {"moves", v.light_face_moves},
                              {"below_0_06_after", v.light_faces_after}}},
                            {"quality_before_flips", quality(v.before_flips)},
                            {"quality_after_flips", quality(v.after_flips)},
                            {"quality_after_sliver_removal", quality(v.after_slivers)},
                            {"seconds",
                             {{"points", v.seconds_points},
                              {"insertion", v.seconds_insertion},
                              {"removal", v.seconds_classify},
                              {"flips", v.seconds_flips},
                              {"slivers", v.seconds_slivers},
                              {"dihedral_and_orthogonality_passes", v.seconds_cell_passes},
                              {"layer_prism_groups", v.seconds_prism_groups},
                              {"quality", v.seconds_quality},
                              {"checks", v.seconds_checks},
                              {"total", v.seconds_total}}}};
        report["layers"] = layers_json(v.layers, final_surface(run), run.caps);
    } else {
        report["volume"] = "not built: [remeshing] cycles = 0 or [volume] enabled = false";
    }
    if (result.polymesh) {
        const OpenFoamCellChecks& checks = result.openfoam_checks;
        report["openfoam"] = {{"cells", result.polymesh->cells},
                              {"faces", result.polymesh->faces},
                              {"internal_faces", result.polymesh->internal_faces},
                              {"layer_prisms", result.layer_prisms},
                              {"layer_prisms_refused", result.layer_prisms_refused},
                              {"absorbed_tets", result.absorbed_tets},
                              {"intact_prism_share", intact_prism_share(run, result)},
                              {"max_non_orthogonality_deg", checks.max_non_orthogonality_deg},
                              {"tet_cells_min_dihedral_deg",
                               result.tet_cells ? nlohmann::json(result.tet_cells->min_dihedral_deg) : nlohmann::json()},
                              {"tet_cells_min_aspect_ratio",
                               result.tet_cells ? nlohmann::json(result.tet_cells->min_aspect_ratio) : nlohmann::json()},
                              {"tet_cells_fraction_below_0_1",
                               result.tet_cells ? nlohmann::json(result.tet_cells->fraction_below_0_1) : nlohmann::json()},
                              {"checks",
                               {{"max_skewness", checks.max_skewness},
                                {"min_pyramid_height", checks.min_pyramid_height},
                                {"min_interpolation_weight", checks.min_weight},
                                {"light_faces", checks.light_faces},
                                {"faces_beyond_orthogonality", checks.faces_beyond_orthogonality},
                                {"skew_faces", checks.skew_faces},
                                {"flat_pyramids", checks.flat_pyramids},
                                {"checkmesh_failures", checks.checkmesh_failures}}},
                              {"quad_faces", result.polymesh->quad_faces},
                              {"patch_faces", result.polymesh->patch_faces},
                              {"units", "m"},
                              {"flow_fields", result.flow_case ? "written (0/U, 0/p)"
                                                               : "not written: the mesh has no inlet and outlet"}};
    }
    if (result.decomposition)
        report["openfoam"]["decomposition"] = {{"processors", result.decomposition->cells.size()},
                                               {"method", "recursive coordinate bisection (decomposeParDict: manual)"},
                                               {"cells", result.decomposition->cells},
                                               {"processor_faces", result.decomposition->processor_faces},
                                               {"processor_patches", result.decomposition->processor_patches}};
    nlohmann::json files = nlohmann::json::array();
    for (const auto& p : result.written) files.push_back(std::filesystem::relative(p, config.directory).string());
    report["files"] = files;
    nlohmann::json removed = nlohmann::json::array();
    for (const auto& p : result.removed) removed.push_back(std::filesystem::relative(p, config.directory).string());
    report["removed"] = removed;
    report["removed_partial_files"] = result.orphaned_partials;
    // The estimates of pipeline/memory_estimate.h beside the measured peak
    // (so far: the outputs are written, report.json is last). The process's
    // peak is reset at each stage's start, so the run's peak is the largest
    // of the stages' and of the peak since the last stage.
    int64_t measured_peak = peak_resident_memory();
    for (const StageMemory& m : run.stage_memory) measured_peak = std::max(measured_peak, m.peak_bytes);
    report["memory"] = {{"bound_bytes", run.memory_bound},
                        {"estimated_peak_bytes_before_remeshing", run.memory_estimate_remeshing},
                        {"estimated_peak_bytes_before_volume", run.memory_estimate_volume},
                        {"measured_peak_bytes", measured_peak}};
    // Per stage (scalemesh run on Linux): its peak, what it left resident,
    // and that per tet of the final mesh.
    nlohmann::json stage_memory = nlohmann::json::array();
    const int64_t tets = run.volume ? static_cast<int64_t>(run.volume->mesh.tets.size()) : 0;
    for (const StageMemory& m : run.stage_memory) {
        nlohmann::json entry = {{"stage", m.stage},
                                {"peak_bytes", m.peak_bytes},
                                {"resident_after_bytes", m.resident_after_bytes}};
        if (tets > 0) entry["resident_after_bytes_per_tet"] = double(m.resident_after_bytes) / double(tets);
        stage_memory.push_back(entry);
    }
    report["memory"]["stages"] = stage_memory;
    report["warnings"] = result.warnings;
    return report.dump(2) + "\n";
}

int64_t remove_orphaned_partials(const std::filesystem::path& dir)
{
    static const std::regex partial(R"(.+\.partial-([0-9]+)(\..*)?)");
    int64_t removed = 0;
    std::error_code ec;
    auto it = std::filesystem::recursive_directory_iterator(dir, ec);
    for (; !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec)) {
        if (it.depth() >= 2) it.disable_recursion_pending(); // outputs lie at most in constant/polyMesh/
        std::smatch m;
        const std::string name = it->path().filename().string();
        if (!it->is_regular_file(ec) || !std::regex_match(name, m, partial)) continue;
        const long pid = std::strtol(m[1].str().c_str(), nullptr, 10);
        if (pid <= 0 || ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM) continue; // its run is alive
        std::error_code gone;
        if (std::filesystem::remove(it->path(), gone)) ++removed;
    }
    return removed;
}

std::vector<std::filesystem::path> stale_outputs(const CaseConfig& config,
                                                 const std::vector<std::filesystem::path>& written)
{
    const std::filesystem::path& dir = config.directory;
    std::ifstream in(dir / "report.json");
    if (!in) return {};
    const nlohmann::json old = nlohmann::json::parse(in, nullptr, false);
    if (old.is_discarded() || !old.is_object() || !old.contains("files") || !old["files"].is_array()) return {};
    std::set<std::string> now;
    for (const std::filesystem::path& p : written) now.insert(std::filesystem::relative(p, dir).generic_string());
    std::error_code ec;
    const std::filesystem::path input =
        config.file.empty() ? std::filesystem::path() : std::filesystem::weakly_canonical(dir / config.file, ec);
    std::vector<std::filesystem::path> stale;
    for (const nlohmann::json& item : old["files"]) {
        if (!item.is_string()) continue;
        const std::filesystem::path name = std::filesystem::path(item.get<std::string>()).lexically_normal();
        // Only what a run writes: a path inside the case directory, never
        // the case file, the report or the input (or a directory holding it).
        if (name.empty() || name.is_absolute() || *name.begin() == ".." || name == "scalemesh.toml" ||
            name == "report.json" || now.count(name.generic_string()))
            continue;
        const std::filesystem::path path = dir / name;
        if (!std::filesystem::exists(std::filesystem::symlink_status(path, ec))) continue;
        const std::filesystem::path full = std::filesystem::weakly_canonical(path, ec);
        if (!input.empty()) {
            const auto [end, at] = std::mismatch(full.begin(), full.end(), input.begin(), input.end());
            if (end == full.end()) continue; // the input, or a directory above it
        }
        stale.push_back(path);
    }
    return stale;
}

namespace {
CaseResult run_and_write(const std::filesystem::path& dir, const CaseConfig& config, const StageListener& listener,
                         int64_t orphans, int64_t max_memory);
} // namespace

CaseResult run_case(const std::filesystem::path& dir, const StageListener& listener, std::optional<int> threads,
                    int64_t max_memory, std::optional<int> decompose)
{
    CaseConfig config = read_case(dir);
    if (threads) {
        if (*threads < 0 || *threads > 1024)
            throw InputError("--threads " + std::to_string(*threads) + " is out of range",
                             "give 0 (all cores) or a thread count");
        config.threads = *threads;
    }
    if (decompose) {
        config.decompose = *decompose;
        config.decompose_on_command_line = true;
    }
    check_decompose(config);
    const int64_t orphans = remove_orphaned_partials(dir);
    // The stages and the export in one arena of the case's threads, so that
    // --threads bounds every parallel step, the writers' included.
    tbb::task_arena arena(config.threads > 0 ? config.threads : tbb::task_arena::automatic);
    return arena.execute([&] { return run_and_write(dir, config, listener, orphans, max_memory); });
}

namespace {

CaseResult run_and_write(const std::filesystem::path& dir, const CaseConfig& config, const StageListener& listener,
                         int64_t orphans, int64_t max_memory)
{
    CaseResult result;
    const bool volume = config.volume && config.remesh_cycles > 0;
    // The memory of each stage: the process's peak reset as a stage starts
    // (the run owns its process), read as it ends.
    std::vector<StageMemory> stage_memory;
    const bool measure = reset_peak_resident_memory() && resident_memory();
    const auto measured = [&](const StageTime& stage) {
        if (measure && stage.seconds < 0) reset_peak_resident_memory();
        if (measure && stage.seconds >= 0)
            if (const auto memory = resident_memory())
                stage_memory.push_back({stage.name, memory->peak_bytes, memory->now_bytes});
        if (listener) listener(stage);
    };
    result.run = run_pipeline(
        config, {.sizing = true, .remesh = config.remesh_cycles > 0, .volume = volume, .max_memory = max_memory},
        measured);
    result.run.stage_memory = std::move(stage_memory);
    CaseConfig at = config;
    at.directory = dir;
    static_cast<CaseOutputs&>(result) = write_case_outputs(at, result.run, {.orphaned_partials = orphans});
    return result;
}

} // namespace

TetMesh case_mesh(const CaseConfig& config, const PipelineRun& run, const OutputRequest& request)
{
    TetMesh mesh = export_mesh(run, config.K, config.M);
    if (request.boundary_patch) {
        if (!run.caps.empty() || request.boundary_patch->size() != mesh.boundary_faces.size() || !request.patch_names)
            throw StageError("export", "the boundary patches given do not fit the run's mesh (" +
                                           std::to_string(request.boundary_patch->size()) + " for " +
                                           std::to_string(mesh.boundary_faces.size()) + " faces, " +
                                           std::to_string(run.caps.size()) + " openings)");
        mesh.boundary_patch = *request.boundary_patch;
        mesh.patch_names = *request.patch_names;
    }
    return mesh;
}

std::vector<std::string> msh_comments(const CaseConfig& config, const PipelineRun& run)
{
    std::ostringstream parameters;
    parameters.precision(12);
    parameters << "parameters K " << config.K << " M " << config.M << " G " << config.G << " L_min " << run.L_min
               << " mm L_max " << run.L_max << " mm";
    return {"scalemesh " SCALEMESH_VERSION,
            "input " + run.input + (run.input_checksum.empty() ? "" : " fnv1a64 " + run.input_checksum),
            parameters.str()};
}

namespace {

// Whether `relative` (to the case directory) is a file or directory of the
// OpenFOAM case the writers make.
bool openfoam_output(const std::filesystem::path& relative)
{
    const std::string first = relative.begin() == relative.end() ? "" : relative.begin()->string();
    return first == "constant" || first == "system" || first == "0" || first == "Allrun" ||
           first.rfind("processor", 0) == 0;
}

} // namespace

CaseOutputs write_case_outputs(const CaseConfig& config, const PipelineRun& run, const OutputRequest& request)
{
    const std::filesystem::path& dir = config.directory;
    CaseOutputs result;
    // The outputs are finished under temporary names first and moved into
    // place only when all are complete, so a failure (or an interruption,
    // through remove_pending_outputs) leaves the case directory as it was.
    // The polyMesh and case writers hand their files over uncommitted; all
    // are moved into place together, with interruptions held back.
    // With layers = "prisms" written as prism cells, the cell floors are
    // judged on the cells the solver gets (below): a layer prism's own
    // tets are flat by design and never reach it.
    const bool prism_cells = run.layers == LayerMode::prisms && config.openfoam && config.layer_prisms;
    result.warnings = floor_warnings(config, run, prism_cells);
    result.input_warnings = std::min(run.warnings.size(), result.warnings.size());
    result.orphaned_partials = request.orphaned_partials;
    StagedOutputs pending;
    const auto stage = [&](const std::string& name) {
        pending.push_back(std::make_unique<AtomicOutput>(dir / name));
        result.written.push_back(dir / name);
        return pending.back()->temporary();
    };
    SurfaceWriteOptions surface_options;
    // Provenance in the .msh files' $Comments section, as in report.json.
    const std::vector<std::string> comments = msh_comments(config, run);
    surface_options.msh_comments = comments;
    surface_options.msh_version = config.msh_version;
    surface_options.msh_binary = config.msh_binary;
    if (!config.surface_outputs.empty()) {
        const std::vector<VertexField> fields = surface_fields(run, config.K, config.M);
        for (const std::string& name : config.surface_outputs)
            write_surface(final_surface(run), fields, stage(name), surface_options);
    }

    if (run.volume) {
        const TetMesh mesh = case_mesh(config, run, request);
        for (const std::string& name : config.volume_outputs) {
            if (std::filesystem::path(name).extension() == ".vtk") write_volume_vtk(mesh, stage(name));
            else write_volume_msh(mesh, stage(name), {.msh_version = config.msh_version, .binary = config.msh_binary,
                                                      .comments = comments, .adjacency = &run.volume->adjacency});
        }
        // Fig. 19: the aspect-ratio histograms before and after improvement.
        const VolumeResult& v = *run.volume;
        const auto bins = [](const QualityReport& q) { return std::vector<int64_t>(q.histogram.begin(), q.histogram.end()); };
        if (request.histograms)
            write_histogram_png({{"before flips", bins(v.before_flips)},
                                 {"after flips", bins(v.after_flips)},
                                 {"after sliver removal", bins(v.after_slivers)}},
                                stage("quality.png"));
        if (config.openfoam) {
            // Walls are OpenFOAM `wall` patches, openings generic `patch`es.
            std::vector<std::string> types = {"wall"};
            for (size_t c = 0; c < run.caps.size(); ++c) types.push_back("patch");
            // OpenFOAM's own checks on the cells before they are written:
            // a layer prism on a face that checkMesh would fail (beyond 70
            // degrees, too skew, or a face pyramid not positive from the
            // prism's centre as OpenFOAM computes it) is split back into its
            // tets, until there is none. What is left on single tets is
            // warned of. The volume stage made these cells for prism cells
            // already, when it judged the prism layers by them.
            const std::shared_ptr<const FoamCells> foam =
                run.prism_cells && config.layer_prisms ? run.prism_cells
                                                       : std::make_shared<const FoamCells>(foam_cells(config, run, mesh));
            const LayerPrismCells& cells = foam->cells;
            const OpenFoamCellChecks& checks = foam->checks;
            result.layer_prisms = cells.prisms;
            result.layer_prisms_refused = cells.refused;
            result.absorbed_tets = cells.absorbed;
            result.openfoam_checks = checks;
            for (const std::string& w : openfoam_check_warnings(checks)) result.warnings.push_back(w);
            if (prism_cells) {
                result.tet_cells = foam->tet_cells;
                for (const std::string& w : cell_floor_warnings(config, *foam->tet_cells)) result.warnings.push_back(w);
            }
            const bool decompose = config.decompose > 1;
            PolyMeshFaces faces;
            const PolyMeshCounts counts =
                write_polymesh(mesh, dir, {.binary = config.openfoam_binary, .scale = 1e-3, .patch_types = types,
                                     .adjacency = &run.volume->adjacency,
                                     .cell_of_tet = config.layer_prisms ? &cells.cell_of_tet : nullptr,
                                     .cells = cells.cells,
                                     .quad_cells = config.layer_prisms ? &cells.prism_cell : nullptr,
                                     .staged = &pending,
                                     .faces = decompose ? &faces : nullptr});
            result.polymesh = counts;
            std::vector<std::string>& names = result.patch_names;
            std::vector<PatchRole> roles;
            for (size_t p = 0; p < counts.patch_faces.size(); ++p) {
                names.push_back(p < mesh.patch_names.size() ? mesh.patch_names[p] : (p == 0 ? "wall" : "patch_" + std::to_string(p)));
                roles.push_back(is_wall_patch(p, run.caps.size()) ? PatchRole::Wall
                                : run.caps[p - 1].type == OpeningType::Inlet ? PatchRole::Inlet
                                                                                    : PatchRole::Outlet);
            }
            if (decompose) {
                types.resize(counts.patch_faces.size(), "wall");
                result.decomposition = write_decomposed_polymesh(
                    mesh.points, faces, counts.patch_faces, dir,
                    {.processors = config.decompose, .scale = 1e-3, .patch_names = names, .patch_types = types,
                     .staged = &pending});
            }
            result.flow_case = write_openfoam_case(dir, names, roles,
                                                   {.kinematic_viscosity = config.viscosity,
                                                    .inlet_speed = config.inlet_speed,
                                                    .processors = config.decompose,
                                                    .staged = &pending});
            if (!result.flow_case && !run.caps.empty()) {
                int inlets = 0;
                for (const PatchRole role : roles) inlets += role == PatchRole::Inlet;
                result.warnings.insert(
                    result.warnings.begin() + static_cast<std::ptrdiff_t>(result.input_warnings++),
                    "the case has " + std::to_string(run.caps.size()) + " opening" +
                    (run.caps.size() == 1 ? "" : "s") + " but " +
                    (inlets == 0 ? std::string("no inlet") : std::string("no outlet")) +
                    ", so no flow is posed: 0/U and 0/p are not written; give [[openings]] at least one "
                    "type = \"inlet\" and one outlet");
            }
            result.written.push_back(dir / "constant" / "polyMesh");
            result.written.push_back(dir / "constant" / "transportProperties");
            result.written.push_back(dir / "constant" / "turbulenceProperties");
            result.written.push_back(dir / "system");
            if (result.flow_case) result.written.push_back(dir / "0");
            result.written.push_back(dir / "Allrun");
            if (decompose) {
                result.written.push_back(dir / "constant" / "cellDecomposition");
                result.written.push_back(dir / "system" / "decomposeParDict");
                for (int32_t i = 0; i < config.decompose; ++i)
                    result.written.push_back(dir / ("processor" + std::to_string(i)));
            }
        }
    }

    result.removed = stale_outputs(config, result.written);
    if (!request.remove_every_stale_output)
        std::erase_if(result.removed, [&](const std::filesystem::path& p) {
            return !openfoam_output(std::filesystem::relative(p, dir));
        });
    write_text_file(stage("report.json"), report_json(config, run, result));
    for (const auto& out : pending)
        if (std::filesystem::is_directory(out->path()))
            throw IoError(out->path().string(), "a directory has this name, so the output cannot be written; "
                                                "rename or remove it");
    commit_all(pending);
    // The run owns what it writes: an earlier run's outputs that this one
    // did not write go once this one's are in place (a failed run leaves
    // the earlier outputs and their report.json as they were).
    for (const std::filesystem::path& p : result.removed) {
        std::error_code ec;
        std::filesystem::remove_all(p, ec);
        if (ec) result.warnings.push_back("could not remove " + p.string() + ", an earlier run's output: " + ec.message());
        // And the directories it leaves empty (constant/ without polyMesh/).
        for (std::filesystem::path up = p.parent_path(); up != dir && std::filesystem::is_empty(up, ec) && !ec;
             up = up.parent_path())
            std::filesystem::remove(up, ec);
    }
    return result;
}

} // namespace scalemesh
