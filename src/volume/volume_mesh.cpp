#include "volume/volume_mesh.h"

#include "core/adjacency.h"
#include "layers/offset_points.h"
#include "volume/core_mesh.h"
#include "volume/delaunay_insertion.h"
#include "volume/improve.h"
#include "volume/layer_prisms.h"
#include "volume/layer_stack.h"
#include "volume/quality.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Spatial_sort_traits_adapter_3.h>
#include <CGAL/Hilbert_policy_tags.h>
#include <CGAL/Hilbert_sort_3.h>
#include <CGAL/Fuzzy_sphere.h>
#include <CGAL/Kd_tree.h>
#include <CGAL/Search_traits_3.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/property_map.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>
#include <chrono>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace scalemesh {
namespace {

// The interpolation weight the faces between tets are mended to after the
// cell passes (mend_light_faces): a margin over checkMesh's 0.05, since the
// writer's cell centres (OpenFOAM's) differ from the tets' centroids in the
// last bits and a tet may join a neighbour as one cell.
constexpr double kLightFaceTarget = 0.06;

void count_light_faces(const LightFaceCounts& made, VolumeResult& result)
{
    result.light_faces_before = made.faces_before;
    result.light_face_moves = made.moves;
    result.light_face_cap_flips = made.cap_flips;
    result.poor_tet_cap_flips = made.poor_tet_cap_flips;
    result.light_faces_after = made.faces_after;
}

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

void check_params(const VolumeParams& p)
{
    if (!(p.K > 0) || !std::isfinite(p.K)) throw InputError("volume: K must be a positive number", "use K = 4.2");
    if (!(p.L_max > 0) || !std::isfinite(p.L_max))
        throw InputError("volume: L_max must be a positive finite length in mm", "pass the sizing stage's L_max");
    if (p.insertion_passes < 1) throw InputError("volume: insertion_passes must be >= 1", "use 3");
    if (!(p.min_volume_fraction >= 0) || !(p.filter_fraction >= 0) || !(p.filler_filter_fraction >= 0))
        throw InputError("volume: min_volume_fraction, filter_fraction and filler_filter_fraction must be >= 0",
                         "use 1e-3, 0.1 and 0.8");
    if (p.flip_sweeps < 0 || p.sliver_sweeps < 0) throw InputError("volume: sweep counts must be >= 0", "use 10 and 20");
    if (!(p.layer_tolerance > 0) || !std::isfinite(p.layer_tolerance))
        throw InputError("volume: layer_tolerance must be a finite number > 0", "use 0.15");
}

// Renumbers the interior points (ids n and up) in Hilbert order and sorts the
// tets by their smallest point id (sort_tets_by_smallest_point), so that what
// is near in space is near in memory: matching faces here and in the exporters
// touches memory in order, and the solver's matrix has a smaller bandwidth.
// Surface points keep their ids. Deterministic (median Hilbert sort).
void renumber_for_locality(VolumeResult& result, int32_t n)
{
    using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
    TetMesh& mesh = result.mesh;
    const size_t count = mesh.points.size();
    std::vector<Kernel::Point_3> positions;
    positions.reserve(count);
    for (const Vec3& p : mesh.points) positions.emplace_back(p.x, p.y, p.z);
    std::vector<int32_t> order(count - n); // the interior points only: surface points keep their ids
    std::iota(order.begin(), order.end(), n);
    using Traits = CGAL::Spatial_sort_traits_adapter_3<Kernel, CGAL::Pointer_property_map<Kernel::Point_3>::type>;
    // The parallel median sort splits at the same medians: the same order.
    const CGAL::Hilbert_sort_3<Traits, CGAL::Hilbert_sort_median_policy, CGAL::Parallel_if_available_tag> hilbert(
        Traits(CGAL::make_property_map(positions)));
    hilbert(order.begin(), order.end());

    // New ids: surface points unchanged, interior points in Hilbert order.
    std::vector<int32_t> new_id(count);
    std::iota(new_id.begin(), new_id.begin() + n, 0);
    for (size_t r = 0; r < order.size(); ++r) new_id[order[r]] = n + static_cast<int32_t>(r);
    auto permute = [&](auto& values) {
        auto old = values;
        for (size_t i = 0; i < count; ++i) values[new_id[i]] = old[i];
    };
    permute(mesh.points);
    permute(result.point_generator);
    permute(result.point_layer);
    permute(result.point_filler);

    for (Tet& t : mesh.tets)
        for (int32_t& v : t) v = new_id[v];
    sort_tets_by_smallest_point(mesh.tets, count);
}

// Names up to `limit` ids for an error message.
std::string list_ids(const std::vector<int32_t>& ids, size_t limit = 10)
{
    std::ostringstream s;
    for (size_t i = 0; i < ids.size() && i < limit; ++i) s << (i ? ", " : "") << ids[i];
    if (ids.size() > limit) s << ", ...";
    return s.str();
}

std::vector<int32_t> nodes_of(const SurfaceMesh& surface, const std::vector<int32_t>& triangles)
{
    std::vector<int32_t> nodes;
    for (int32_t t : triangles)
        for (int32_t v : surface.triangles[t]) nodes.push_back(v);
    std::sort(nodes.begin(), nodes.end());
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
    return nodes;
}

// Points made by quad repairs and edge splits (appended to the mesh after
// the inserted ones): interior, attributed to the nearest surface point, as
// filler points of layer 1 so that they count for no layer.
void attribute_new_points(VolumeResult& result, int32_t n)
{
    const std::vector<Vec3>& points = result.mesh.points;
    for (size_t p = result.point_generator.size(); p < points.size(); ++p) {
        int32_t nearest = 0;
        double best = 1e300;
        for (int32_t v = 0; v < n; ++v) // a handful of points: a linear search is enough
            if (distance(points[v], points[p]) < best) best = distance(points[v], points[p]), nearest = v;
        result.point_generator.push_back(nearest);
        result.point_layer.push_back(1);
        result.point_filler.push_back(1);
    }
}

// The layer bounds `layers` with the stand-ins held: a layer point (bound
// by layers[p]) within `tolerance` of its spacing of the place of a
// layermaking point of its layer that the interior-point filter took out
// (a raw point missing from `kept`) stands in for that node's point (the
// layer account). Such a point gets a ball about where it is now, inside its
// own ball and every such place's, so a move keeps both; a zero radius is
// kept as a tiny one, since a zero slack would free the point.
std::vector<LayerBound> hold_stand_ins(const TetMesh& mesh, int32_t n, const std::vector<OffsetPoint>& raw,
                                       const std::vector<OffsetPoint>& kept, const std::vector<int32_t>& source,
                                       const std::vector<LayerBound>& layers, double tolerance)
{
    struct Place {
        Vec3 x;
        double radius; // mm
        int32_t layer;
    };
    std::vector<Place> filtered;
    size_t k = 0;
    for (const OffsetPoint& p : raw) {
        const bool survived = k < kept.size() && kept[k].generator == p.generator && kept[k].layer == p.layer;
        if (!survived && !p.filler) filtered.push_back({p.position, tolerance * p.spacing, p.layer});
        k += survived;
    }
    std::vector<LayerBound> held = layers;
    if (filtered.empty()) return held;
    std::sort(filtered.begin(), filtered.end(), [](const Place& a, const Place& b) { return a.x.x < b.x.x; });
    double widest = 0;
    for (const Place& f : filtered) widest = std::max(widest, f.radius);
    for (size_t p = n; p < source.size() && p < layers.size(); ++p) {
        if (!(layers[p].slack > 0)) continue;
        const Vec3& x = mesh.points[p];
        const int32_t layer = kept[source[p] - n].layer;
        double room = layers[p].slack - distance(x, layers[p].home);
        bool serves = false;
        auto f = std::lower_bound(filtered.begin(), filtered.end(), x.x - widest,
                                  [](const Place& a, double v) { return a.x.x < v; });
        for (; f != filtered.end() && f->x.x <= x.x + widest; ++f)
            if (f->layer == layer && distance(f->x, x) <= f->radius)
                serves = true, room = std::min(room, f->radius - distance(f->x, x));
        if (serves) held[p] = {x, layers[p].normal, std::max(room, 1e-12 * layers[p].slack)};
    }
    return held;
}

// VolumeResult::near_wall_anisotropy and its median: each surface node's
// mean incident edge length over the distance of its first layer point.
void measure_near_wall_anisotropy(VolumeResult& result, const SurfaceMesh& surface)
{
    const int32_t n = static_cast<int32_t>(surface.points.size());
    const TetMesh& mesh = result.mesh;
    std::vector<double> first_thickness(n, std::numeric_limits<double>::quiet_NaN());
    for (size_t p = n; p < mesh.points.size(); ++p) {
        const int32_t g = result.point_generator[p], m = result.point_layer[p];
        if (!result.point_filler[p] && m == 1) first_thickness[g] = distance(mesh.points[p], surface.points[g]);
    }
    const VertexTable neighbours = vertex_neighbours(surface);
    result.near_wall_anisotropy.assign(n, std::numeric_limits<double>::quiet_NaN());
    std::vector<double> finite;
    for (int32_t i = 0; i < n; ++i) {
        if (!(first_thickness[i] > 0) || neighbours.size(i) == 0) continue;
        double length = 0;
        for (const int32_t* j = neighbours.begin(i); j != neighbours.end(i); ++j)
            length += distance(surface.points[i], surface.points[*j]);
        result.near_wall_anisotropy[i] = length / neighbours.size(i) / first_thickness[i];
        finite.push_back(result.near_wall_anisotropy[i]);
    }
    if (!finite.empty()) {
        std::nth_element(finite.begin(), finite.begin() + finite.size() / 2, finite.end());
        result.first_layer_anisotropy_median = finite[finite.size() / 2];
    }
}

OffsetParams offset_params(const VolumeParams& params)
{
    OffsetParams offset;
    offset.M = params.M;
    offset.growth = params.growth;
    offset.first_layer = params.first_layer;
    offset.K = params.K;
    offset.L_max = params.L_max;
    offset.filter_fraction = params.filter_fraction;
    offset.filler_filter_fraction = params.filler_filter_fraction;
    offset.repair_normals = true;
    return offset;
}

// The core's sliver removal, with its boundary (the layers' top, the caps)
// frozen.
void remove_core_slivers(TetMesh& core, int32_t frozen, const VolumeParams& params, VolumeResult& result)
{
    const SliverCounts slivers = remove_slivers(core, frozen, params.sliver_aspect_ratio, params.sliver_sweeps);
    result.sliver_flips = slivers.flips, result.sliver_moves = slivers.moves;
    result.sliver_splits = split_surface_slivers(core, frozen, params.sliver_aspect_ratio, kQualityFloor);
}

// Adds what a run of the cell passes changed to the result's counts.
void count_cell_passes(const CellCounts& made, VolumeResult& result)
{
    result.ortho_flips += made.ortho.flips, result.ortho_moves += made.ortho.moves;
    result.ortho_splits += made.ortho.splits;
    result.dihedral_flips += made.dihedral.flips, result.dihedral_moves += made.dihedral.moves;
    result.dihedral_splits += made.dihedral.splits;
}

// How far the top of a shortened column may slide along its column in the
// cell passes, as a fraction of its top layer's thickness.
constexpr double kTopSlide = 0.3;

// The dihedral and non-orthogonality passes, as the Delaunay construction
// runs them, on the stack and core joined (`mesh`, its first `stack.tets`
// tets the stack's): the stack's tets are locked, its points fixed but for
// the top of each column, which slides along its column so that the core's
// tets at the top can be mended, and the prisms stay prisms. A top within
// the layer tolerance of Algorithm 4's place for it (`raw`, the offset
// points) stays within it, so that it still counts for its layer.
void improve_joined(TetMesh& mesh, const SurfaceMesh& surface, const LayerStack& stack,
                    const std::vector<OffsetPoint>& raw, double tolerance, VolumeResult& result)
{
    const int32_t n = static_cast<int32_t>(surface.points.size());
    const int32_t L = stack.layers;
    std::vector<const OffsetPoint*> place(n, nullptr); // each node's layermaking point of layer L
    for (const OffsetPoint& p : raw)
        if (!p.filler && p.layer == L) place[p.generator] = &p;
    std::vector<LayerBound> bounds(mesh.points.size());
    for (size_t k = 0; k < stack.points.size(); ++k) {
        LayerBound& bound = bounds[n + k];
        const int32_t v = stack.point_generator[k];
        if (stack.point_layer[k] != L || L == 0 || stack.first[v] < 0) {
            bound.fixed = true;
            continue;
        }
        const Vec3& top = stack.points[k];
        const Vec3& below = L >= 2 ? stack.points[stack.first[v] + L - 2] : surface.points[v];
        // Within the tolerance of its place while it is there; a top the
        // stack already moved beyond it (a shortened column) kTopSlide of
        // its layer's thickness.
        const double allowed = place[v] ? tolerance * place[v]->spacing : 0.0;
        const double off = place[v] ? distance(top, place[v]->position) : 0.0;
        const double slack = off <= allowed ? allowed - off : kTopSlide * distance(top, below);
        bound.fixed = !(slack > 0);
        bound.home = top;
        bound.normal = normalized(top - below);
        bound.slack = slack;
        bound.on_normal = true;
    }
    const int32_t locked = static_cast<int32_t>(stack.tets.size());
    // The prisms, as the cells the solver will see: each three of the
    // stack's tets, their points known by column and layer.
    PrismCells prisms;
    prisms.generator.assign(mesh.points.size(), -1);
    prisms.layer.assign(mesh.points.size(), -1);
    for (int32_t v = 0; v < n; ++v) prisms.generator[v] = v, prisms.layer[v] = 0;
    for (size_t i = 0; i < stack.rim_columns.size(); ++i)
        if (const int32_t c = stack.rim_columns[i]; c >= 0)
            prisms.generator[c] = static_cast<int32_t>(i / L), prisms.layer[c] = static_cast<int32_t>(i % L) + 1;
    for (size_t k = 0; k < stack.points.size(); ++k)
        prisms.generator[n + k] = stack.point_generator[k], prisms.layer[n + k] = stack.point_layer[k];
    for (size_t i = 0; i + 3 <= stack.tets.size(); i += 3) {
        std::vector<int32_t> six;
        for (size_t j = i; j < i + 3; ++j) six.insert(six.end(), stack.tets[j].begin(), stack.tets[j].end());
        std::sort(six.begin(), six.end());
        six.erase(std::unique(six.begin(), six.end()), six.end());
        if (six.size() != 6) continue;
        std::sort(six.begin(), six.end(), [&](int32_t a, int32_t b) {
            return std::pair(prisms.layer[a], prisms.generator[a]) < std::pair(prisms.layer[b], prisms.generator[b]);
        });
        const std::array<int32_t, 4> key{prisms.generator[six[0]], prisms.generator[six[1]], prisms.generator[six[2]],
                                         prisms.layer[six[5]]};
        prisms.index.emplace(key, static_cast<int64_t>(prisms.points.size()));
        prisms.points.push_back({six[0], six[1], six[2], six[3], six[4], six[5]});
    }
    prisms.start = mesh.points;
    prisms.top_layer = L;
    CellPassParams cell_params;
    cell_params.prism_cells = &prisms;
    const auto cell_passes = Clock::now();
    const CellCounts made = improve_cells(mesh, n, cell_params, bounds, locked);
    count_cell_passes(made, result);
    result.dihedral_tets_before = made.dihedral.tets_before;
    result.ortho_faces_before = made.ortho.faces_before;
    count_light_faces(mend_light_faces(mesh, n, kLightFaceTarget, bounds, locked, &prisms, surface.triangle_patch), result);
    result.seconds_cell_passes = seconds_since(cell_passes);
}

// The `prisms` construction: the layer stack (layer_stack.h) over the wall,
// the core above it meshed by Gmsh (core_mesh.h) and improved with its
// boundary frozen, the two joined. Points: the surface's, the layer points,
// the core's own (fillers of layer floor(M/2) + 1, each attributed to the
// generator of a point it shares a tet with).
void build_stacked_mesh(const SurfaceMesh& surface, const FeatureSize& sizing, const VolumeParams& params,
                        VolumeResult& result)
{
    const int32_t n = static_cast<int32_t>(surface.points.size());
    const bool openings =
        surface.triangle_patch.size() == surface.triangles.size() &&
        std::any_of(surface.triangle_patch.begin(), surface.triangle_patch.end(), [](int32_t p) { return p != 0; });
    if (openings && params.rim_columns.empty())
        throw InputError("volume: layers = \"prisms\" on a surface with openings needs the columns of their rims",
                         "build the caps with RingParams::prism_columns and pass them as VolumeParams::rim_columns");
    auto t0 = Clock::now();
    const OffsetParams offset = offset_params(params);
    const std::vector<OffsetPoint> raw = offset_points(surface, sizing, offset);
    LayerStackParams stack_params;
    stack_params.rim_columns = params.rim_columns;
    // The caps inside their last rings (the cap triangles with no rim node
    // and no ring node below the last) bound the core with the stack's top.
    if (openings) {
        const int32_t L = static_cast<int32_t>(std::floor(params.M / 2));
        std::vector<char> annulus(n, 0);
        for (int32_t v = 0; v < n; ++v)
            if (params.rim_columns[size_t(v) * L] >= 0) {
                annulus[v] = 1;
                for (int32_t m = 1; m < L; ++m) annulus[params.rim_columns[size_t(v) * L + m - 1]] = 1;
            }
        for (size_t f = 0; f < surface.triangles.size(); ++f) {
            const Triangle& t = surface.triangles[f];
            if (surface.triangle_patch[f] != 0 && !annulus[t[0]] && !annulus[t[1]] && !annulus[t[2]])
                stack_params.core_faces.push_back(t);
        }
    }
    const LayerStack stack = build_layer_stack(surface, sizing, layer_columns(surface, sizing, offset), stack_params);
    result.offset_points = static_cast<int64_t>(raw.size());
    result.stack_shortened_nodes = stack.shortened_nodes;
    result.stack_rounds = stack.rounds;
    result.stack_borrowed_columns = stack.borrowed_columns;
    result.stack_lenient_prisms = stack.lenient_prisms;
    result.stack_holes = stack.holes;
    result.seconds_points = seconds_since(t0);

    // The core's boundary: the stack's top and the caps inside their last
    // rings, its points renumbered from 0.
    t0 = Clock::now();
    const int32_t stack_end = n + static_cast<int32_t>(stack.points.size());
    std::vector<int32_t> local(stack_end, -1);
    SurfaceMesh boundary;
    std::vector<int32_t> global; // core boundary point -> mesh point
    std::vector<Triangle> core_faces = stack.top;
    core_faces.insert(core_faces.end(), stack_params.core_faces.begin(), stack_params.core_faces.end());
    for (const Triangle& t : core_faces) {
        Triangle mapped;
        for (int k = 0; k < 3; ++k) {
            int32_t& id = local[t[k]];
            if (id < 0) {
                id = static_cast<int32_t>(global.size());
                global.push_back(t[k]);
                boundary.points.push_back(t[k] < n ? surface.points[t[k]] : stack.points[t[k] - n]);
            }
            mapped[k] = id;
        }
        boundary.triangles.push_back(mapped);
    }
    boundary.triangle_patch.assign(boundary.triangles.size(), 0);
    // Inside, points along each wall node's normal beyond its top, every
    // min(D, L_max) / M (the paper's filler spacing) from half a spacing past
    // the top while within D / 2, thinned by section 4's filter and kept a
    // quarter spacing from every point of the top: in a tube, a row along
    // the axis, which the core's tets reach from each top triangle.
    using Kernel = CGAL::Simple_cartesian<double>;
    using Tree = CGAL::Kd_tree<CGAL::Search_traits_3<Kernel>>;
    std::vector<Kernel::Point_3> tops;
    tops.reserve(boundary.points.size());
    for (const Vec3& x : boundary.points) tops.emplace_back(x.x, x.y, x.z);
    const Tree tree(tops.begin(), tops.end());
    const int32_t L = stack.layers;
    std::vector<OffsetPoint> beyond;
    for (int32_t v = 0; v < n; ++v) {
        if (stack.first[v] < 0 || L == 0) continue;
        const Vec3& top = stack.points[stack.first[v] + L - 1];
        const Vec3 inward = normalized(top - surface.points[v]);
        const double step = std::min(sizing.D[v], params.L_max) / params.M;
        for (double dist = distance(top, surface.points[v]) + 0.5 * step; dist <= sizing.D[v] / 2; dist += step)
            beyond.push_back({surface.points[v] + dist * inward, v, L + 1, true, dist, step});
    }
    std::vector<Vec3> inside;
    for (const OffsetPoint& p : filter_interior_points(beyond, sizing, offset)) {
        const CGAL::Fuzzy_sphere<CGAL::Search_traits_3<Kernel>> ball(
            Kernel::Point_3(p.position.x, p.position.y, p.position.z), 0.25 * p.spacing);
        if (!tree.search_any_point(ball)) inside.push_back(p.position);
    }
    TetMesh core = mesh_core(boundary, inside);
    result.seconds_insertion = seconds_since(t0);
    const int32_t frozen = static_cast<int32_t>(boundary.points.size());
    t0 = Clock::now();
    if (params.improve) remove_core_slivers(core, frozen, params, result);

    // The two joined.
    TetMesh& mesh = result.mesh;
    mesh.points = surface.points;
    mesh.points.insert(mesh.points.end(), stack.points.begin(), stack.points.end());
    for (size_t p = frozen; p < core.points.size(); ++p) global.push_back(stack_end + static_cast<int32_t>(p - frozen));
    mesh.points.insert(mesh.points.end(), core.points.begin() + frozen, core.points.end());
    mesh.tets = stack.tets;
    for (const Tet& t : core.tets) mesh.tets.push_back({global[t[0]], global[t[1]], global[t[2]], global[t[3]]});
    mesh.boundary_faces = surface.triangles;
    mesh.boundary_patch = surface.triangle_patch;
    if (mesh.boundary_patch.size() != mesh.boundary_faces.size()) mesh.boundary_patch.assign(mesh.boundary_faces.size(), 0);
    if (params.improve) improve_joined(mesh, surface, stack, raw, params.layer_tolerance, result);
    result.seconds_slivers = seconds_since(t0);

    // Attribution: surface points themselves, layer points their column,
    // core points a neighbour's generator (passes over the tets until each
    // has one; every core point is joined to the boundary through tets).
    const size_t total = mesh.points.size();
    const int32_t core_layer = stack.layers + 1;
    result.point_generator.assign(total, -1);
    result.point_layer.assign(total, core_layer);
    result.point_filler.assign(total, 1);
    for (int32_t v = 0; v < n; ++v) result.point_generator[v] = v, result.point_layer[v] = 0, result.point_filler[v] = 0;
    // A rim node's column is cap nodes: attributed to the rim node and
    // their layer, as the stack's own points, so that the rim prisms are
    // found as prisms.
    for (int32_t v = 0; v < n && !params.rim_columns.empty(); ++v)
        for (int32_t m = 1; m <= stack.layers; ++m)
            if (const int32_t c = params.rim_columns[size_t(v) * stack.layers + m - 1]; c >= 0)
                result.point_generator[c] = v, result.point_layer[c] = m;
    for (size_t k = 0; k < stack.points.size(); ++k) {
        result.point_generator[n + k] = stack.point_generator[k];
        result.point_layer[n + k] = stack.point_layer[k];
        result.point_filler[n + k] = 0;
    }
    for (bool open = true; open;) {
        open = false;
        for (const Tet& t : mesh.tets) {
            int32_t known = -1;
            for (int32_t v : t) known = std::max(known, result.point_generator[v]);
            for (int32_t v : t)
                if (result.point_generator[v] < 0) {
                    if (known >= 0) result.point_generator[v] = known;
                    else open = true;
                }
        }
    }
    result.inserted_points = static_cast<int64_t>(total) - n;
    result.prism_groups.after_insertion = result.prism_groups.after_flips = result.prism_groups.after_slivers =
        result.prism_groups.after_cell_passes = stack.prisms;

    measure_near_wall_anisotropy(result, surface);
    t0 = Clock::now();
    result.after_slivers = quality_report(mesh);
    result.before_flips = result.after_flips = result.after_slivers;
    result.seconds_quality = seconds_since(t0);

    // The layers as they ended: each of Algorithm 4's layermaking points is
    // its column's point of the same layer, moved where its column was
    // shortened.
    t0 = Clock::now();
    std::vector<InsertionFate> fates(raw.size(), InsertionFate::inserted);
    std::vector<FinalPoint> final_points;
    for (size_t k = 0; k < raw.size(); ++k) {
        const OffsetPoint& p = raw[k];
        if (p.filler || p.layer > stack.layers || stack.first[p.generator] < 0) continue;
        final_points.push_back({static_cast<int32_t>(k), mesh.points[n + stack.first[p.generator] + p.layer - 1]});
    }
    // A prism layer counts wherever its column holds it: the stack shortens
    // whole columns by design, and their heights are reported below.
    result.layers = account_layers(surface, sizing, params.M, params.L_min, raw, raw, fates, final_points,
                                   std::numeric_limits<double>::infinity());
    // The columns themselves: every layer is there as a prism layer where
    // the column is, only thinner where it was shortened. Over the nodes
    // the account owes all layers: those with a column, and its height
    // (wall node to top) over the height Algorithm 4 gave it.
    double height_sum = 0;
    result.stack_whole_columns = 0;
    result.stack_height_min = std::numeric_limits<double>::infinity();
    for (const OffsetPoint& p : raw) {
        const int32_t v = p.generator;
        if (p.filler || p.layer != L || L == 0 || !result.layers.eligible[v] || stack.first[v] < 0) continue;
        const double planned = distance(p.position, surface.points[v]);
        if (!(planned > 0)) continue;
        const double h = distance(mesh.points[n + stack.first[v] + L - 1], surface.points[v]) / planned;
        ++result.stack_whole_columns;
        height_sum += h;
        result.stack_height_min = std::min(result.stack_height_min, h);
    }
    result.stack_height_mean = result.stack_whole_columns ? height_sum / double(result.stack_whole_columns) : 0.0;
    if (result.stack_whole_columns == 0) result.stack_height_min = 0;
    result.seconds_quality += seconds_since(t0);
}

// The last steps of either construction: the points renumbered for
// locality, the face adjacency, and the checks every volume mesh passes
// (positive tets, the surface as its boundary, the topology check).
void finish(VolumeResult& result, const SurfaceMesh& surface, const VolumeParams& params, Clock::time_point start)
{
    const int32_t n = static_cast<int32_t>(surface.points.size());
    TetMesh& mesh = result.mesh;
    const auto t0 = Clock::now();
    renumber_for_locality(result, n);
    result.adjacency = tet_face_adjacency(mesh);
    const TetMeshFacts facts = tet_mesh_facts(mesh, result.adjacency);
    if (facts.nonpositive_tets != 0 || !facts.boundary_matches)
        throw StageError("volume", std::to_string(facts.nonpositive_tets) +
                                       " tets are not positive or the mesh boundary is not the surface (" +
                                       std::to_string(facts.boundary_faces) + " boundary faces for " +
                                       std::to_string(surface.triangles.size()) + " surface triangles)");
    if (params.check_topology) {
        const std::vector<int32_t> failures = topology_check_failures(mesh, n, result.adjacency);
        if (!failures.empty())
            throw VolumeConformityError(std::to_string(failures.size()) +
                                            " surface nodes fail the topology check of section 2.3 (nodes " +
                                            list_ids(failures) + "). Refine the surface there and re-run",
                                        {}, failures);
    }
    result.max_non_orthogonality_deg = max_non_orthogonality_deg(mesh, result.adjacency);
    result.seconds_checks = seconds_since(t0);
    result.seconds_total = seconds_since(start);
}

} // namespace

std::vector<int32_t> topology_check_failures(const TetMesh& mesh, int32_t surface_points)
{
    return topology_check_failures(mesh, surface_points, tet_face_adjacency(mesh));
}

// Each node's star (its tets, in tet order) is searched from
// its first tet across the three faces through the node; the node passes
// when the search reaches the whole star. Nodes in parallel.
std::vector<int32_t> topology_check_failures(const TetMesh& mesh, int32_t surface_points,
                                             const TetFaceAdjacency& adjacency)
{
    if (adjacency.across.size() != 4 * mesh.tets.size())
        throw std::invalid_argument("topology check: the adjacency is not of these tets");
    const VertexTable stars = incident_cells(mesh.tets, surface_points);

    std::vector<char> failed(surface_points, 0);
    tbb::parallel_for(tbb::blocked_range<int32_t>(0, surface_points, 1024), [&](const tbb::blocked_range<int32_t>& range) {
        std::vector<int32_t> queue;
        std::vector<char> seen;
        for (int32_t v = range.begin(); v != range.end(); ++v) {
            const int32_t* first = stars.begin(v);
            const int32_t* last = stars.end(v);
            if (first == last) {
                failed[v] = 1;
                continue;
            }
            // The star is in increasing tet order: a tet's place in it is
            // found by binary search.
            seen.assign(last - first, 0);
            seen[0] = 1;
            queue.assign(1, *first);
            for (size_t next = 0; next < queue.size(); ++next) {
                const int32_t t = queue[next];
                for (int k = 0; k < 4; ++k) {
                    if (mesh.tets[t][k] == v) continue; // face k leaves out corner k: not through v
                    const int32_t u = adjacency.across[4 * size_t(t) + k];
                    if (u < 0) continue;
                    const int32_t* at = std::lower_bound(first, last, u);
                    if (at == last || *at != u || seen[at - first]) continue;
                    seen[at - first] = 1;
                    queue.push_back(u);
                }
            }
            failed[v] = queue.size() != size_t(last - first);
        }
    });
    std::vector<int32_t> failures;
    for (int32_t v = 0; v < surface_points; ++v)
        if (failed[v]) failures.push_back(v);
    return failures;
}

VolumeResult build_volume_mesh(const SurfaceMesh& surface, const FeatureSize& sizing, const VolumeParams& params)
{
    const auto start = Clock::now();
    check_params(params);
    require_closed_manifold(surface, "volume: the surface to mesh");
    const int32_t n = static_cast<int32_t>(surface.points.size());
    VolumeResult result;

    if (params.layers == LayerMode::prisms) {
        build_stacked_mesh(surface, sizing, params, result);
        finish(result, surface, params, start);
        return result;
    }

    auto t0 = Clock::now();
    const OffsetParams offset = offset_params(params);
    const std::vector<OffsetPoint> raw = offset_points(surface, sizing, offset);
    const std::vector<OffsetPoint> points = filter_interior_points(raw, sizing, offset);
    result.offset_points = static_cast<int64_t>(raw.size());
    result.filtered_points = static_cast<int64_t>(raw.size() - points.size());
    result.seconds_points = seconds_since(t0);

    // A quad whose re-triangulation fails takes the Delaunay diagonal into
    // the surface (flip_surface_quads). Where that flip is not allowed,
    // it gets a bounded retry: the whole insertion runs again with its
    // diagonal protected, so no interior point joins it and the tets to
    // re-triangulate are few and simple.
    InsertionParams insertion{params.insertion_passes, params.min_volume_fraction, params.layer_tolerance, {}};
    InsertionResult ins;
    std::vector<int32_t> failed_quads;
    std::vector<Triangle> boundary;
    TetMesh& mesh = result.mesh;
    // Every attempt counts; putting the quads back belongs to removal (the
    // boundary made the surface).
    double seconds_insertion = 0, seconds_removal = 0;
    for (int attempt = 0;; ++attempt) {
        ins = insert_and_classify(surface, points, insertion);
        seconds_insertion += ins.seconds_insertion;
        seconds_removal += ins.seconds_classify;
        if (!ins.missing_triangles.empty()) break;
        t0 = Clock::now();
        mesh = TetMesh{};
        mesh.points = std::move(ins.points);
        mesh.tets = std::move(ins.tets);
        failed_quads = repair_surface_quads(mesh, ins.quads);
        boundary = ins.triangles;
        result.facet_flips = ins.surface_flips;
        if (!failed_quads.empty()) {
            const size_t before = failed_quads.size();
            failed_quads = flip_surface_quads(surface, ins.quads, ins.quad_triangles, failed_quads, boundary);
            result.quad_flips = static_cast<int64_t>(before - failed_quads.size());
        }
        seconds_removal += seconds_since(t0);
        if (failed_quads.empty() || attempt == 2) break;
        for (int32_t q : failed_quads) insertion.protected_edges.push_back({ins.quads[q][1], ins.quads[q][3]});
        result.insertion_retries = attempt + 1;
    }
    result.seconds_insertion = seconds_insertion;
    result.seconds_classify = seconds_removal;
    result.inserted_points = ins.inserted;
    result.deferred_points = ins.deferred;
    result.rejected_small = ins.rejected_small;
    result.rejected_filler = ins.rejected_filler;
    result.rejected_surface = ins.rejected_surface;
    result.rejected_other = ins.rejected_other;
    result.unused_points = ins.unused;
    if (!ins.missing_triangles.empty()) {
        const std::vector<int32_t> nodes = nodes_of(surface, ins.missing_triangles);
        throw VolumeConformityError(std::to_string(ins.missing_triangles.size()) +
                                        " surface triangles are not faces of the Delaunay triangulation of the "
                                        "surface points (triangles " +
                                        list_ids(ins.missing_triangles) + "; nodes " + list_ids(nodes) +
                                        "). Refine the surface there (smaller d) and re-run",
                                    ins.missing_triangles, nodes);
    }
    mesh.boundary_faces = std::move(boundary);
    mesh.boundary_patch = surface.triangle_patch;
    result.surface_quads = static_cast<int64_t>(ins.quads.size());
    if (!failed_quads.empty()) {
        std::vector<int32_t> nodes;
        for (int32_t q : failed_quads) nodes.insert(nodes.end(), ins.quads[q].begin(), ins.quads[q].end());
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
        throw VolumeConformityError(std::to_string(failed_quads.size()) +
                                        " surface quads split along the other diagonal could not be re-triangulated "
                                        "(nodes " + list_ids(nodes) + "). Refine the surface there and re-run",
                                    {}, nodes);
    }
    result.point_generator.resize(ins.source.size());
    result.point_layer.resize(ins.source.size());
    result.point_filler.resize(ins.source.size());
    for (size_t p = 0; p < ins.source.size(); ++p) {
        const int32_t s = ins.source[p];
        if (s < n) {
            result.point_generator[p] = s, result.point_layer[p] = 0, result.point_filler[p] = 0;
        } else {
            const OffsetPoint& op = points[s - n];
            result.point_generator[p] = op.generator, result.point_layer[p] = op.layer;
            result.point_filler[p] = op.filler ? 1 : 0;
        }
    }
    attribute_new_points(result, n);

    // The layer prisms the tets fill, step by step (VolumeResult::prism_groups).
    const auto prism_groups = [&] {
        const auto begin = Clock::now();
        attribute_new_points(result, n);
        const int64_t groups = layer_prism_groups(mesh, result.point_generator, result.point_layer, result.point_filler);
        result.seconds_prism_groups += seconds_since(begin);
        return groups;
    };
    result.prism_groups.after_insertion = prism_groups();
    result.prism_groups.after_flips = result.prism_groups.after_slivers = result.prism_groups.after_cell_passes =
        result.prism_groups.after_insertion;
    // First-layer anisotropy, as inserted.
    t0 = Clock::now();
    const int layermaking = static_cast<int>(std::floor(params.M / 2));
    measure_near_wall_anisotropy(result, surface);
    result.before_flips = quality_report(mesh);
    result.after_flips = result.before_flips;
    result.after_slivers = result.before_flips;
    result.seconds_quality = seconds_since(t0);
    if (params.improve) {
        t0 = Clock::now();
        const FlipCounts flips = flip_volume_criterion(mesh, params.flip_sweeps);
        result.flips_32 = flips.flips_32, result.flips_23 = flips.flips_23, result.flips_44 = flips.flips_44;
        result.seconds_flips = seconds_since(t0);
        result.prism_groups.after_flips = prism_groups();
        t0 = Clock::now();
        result.after_flips = quality_report(mesh);
        result.seconds_quality += seconds_since(t0);
        t0 = Clock::now();
        // Layermaking points stay within layer_tolerance of their layer
        // spacing of their distance from the wall: the layers are what the
        // method is for (paper section 2.3).
        std::vector<LayerBound> layers(mesh.points.size());
        for (size_t p = n; p < ins.source.size(); ++p)
            if (!result.point_filler[p] && result.point_layer[p] >= 1 && result.point_layer[p] <= layermaking) {
                const OffsetPoint& op = points[ins.source[p] - n];
                const Vec3 from_node = op.position - surface.points[op.generator];
                layers[p] = {op.position, normalized(from_node), params.layer_tolerance * op.spacing};
            }
        const SliverCounts slivers =
            remove_slivers(mesh, n, params.sliver_aspect_ratio, params.sliver_sweeps, layers);
        result.sliver_flips = slivers.flips, result.sliver_moves = slivers.moves;
        // Slivers of surface points: a split keeps the surface, so it comes
        // first where its tets reach the floor; a peel changes the surface
        // but beats a split whose point sits among nearly coplanar surface
        // points (tets at 0.005 to 0.018 were left so on a 768 box torus).
        result.sliver_splits = split_surface_slivers(mesh, n, params.sliver_aspect_ratio, kQualityFloor);
        result.caps_peeled = peel_surface_caps(mesh, n, params.sliver_aspect_ratio);
        result.sliver_splits += split_surface_slivers(mesh, n, params.sliver_aspect_ratio, 0.0);
        // Layer points stay on their layers (remove_slivers); a tet still
        // below the floor gets one of its edges split instead, and the new
        // points (free to move) another round of sliver removal; a few times
        // while that helps.
        for (int round = 0; round < 3; ++round) {
            const QualityReport now = quality_report(mesh);
            if (now.min_aspect_ratio >= params.aspect_ratio_floor) break;
            const int64_t splits = split_surface_slivers(mesh, n, params.aspect_ratio_floor, 0.0, false);
            if (splits == 0) break;
            result.sliver_splits += splits;
            const SliverCounts more = remove_slivers(mesh, n, params.sliver_aspect_ratio, params.sliver_sweeps, layers);
            result.sliver_flips += more.flips, result.sliver_moves += more.moves;
        }
        // The passes below also keep the stand-ins (layer_account.h): a
        // layer point within the tolerance of the place of a point the
        // interior-point filter took out keeps its layer there for that
        // node, so it stays in a ball inside both tolerances.
        result.prism_groups.after_slivers = prism_groups();
        const std::vector<LayerBound> held = hold_stand_ins(mesh, n, raw, points, ins.source, layers, params.layer_tolerance);
        // A finite-volume solver wants no tet flatter than a dihedral angle
        // of 10 degrees and OpenFOAM's solvers face non-orthogonality below
        // 70: flips, moves and interior-edge splits for the tets below 12
        // degrees and the faces beyond 65, keeping the quality floors and
        // the layers' balls, the two passes alternating while either still
        // changes the mesh (each keeps what the other has reached).
        const CellPassParams schedule;
        const auto cell_passes = Clock::now();
        const CellCounts made = improve_cells(mesh, n, schedule, held);
        count_cell_passes(made, result);
        result.dihedral_tets_before = made.dihedral.tets_before;
        result.ortho_faces_before = made.ortho.faces_before;
        // Last resort where cells still miss the solver's floors (a tet
        // below 10 degrees, a face beyond 70): their layer points are held
        // on their layers no longer, and both passes run once more. A cell
        // a solver can use comes before a layer point's exact place; the
        // layer accounting below counts such a point as moved if it leaves
        // the tolerance, so the trade is reported, not hidden.
        std::vector<LayerBound> released = held;
        for (int32_t v : points_missing_floors(mesh, n, 10.0, 70.0))
            if (size_t(v) < released.size() && released[v].slack > 0)
                released[v] = {}, ++result.released_layer_points;
        if (result.released_layer_points > 0) {
            CellPassParams once = schedule;
            once.dihedral_first = false;
            once.rounds = 1;
            once.first_ortho_sweeps = schedule.ortho_sweeps;
            count_cell_passes(improve_cells(mesh, n, once, released), result);
        }
        count_light_faces(mend_light_faces(mesh, n, kLightFaceTarget, released, 0, nullptr, surface.triangle_patch), result);
        result.seconds_cell_passes = seconds_since(cell_passes);
        result.prism_groups.after_cell_passes = prism_groups();
        attribute_new_points(result, n);
        result.seconds_slivers = seconds_since(t0);
        t0 = Clock::now();
        result.after_slivers = quality_report(mesh);
        result.seconds_quality += seconds_since(t0);
    }

    // The layers as they ended: every interior point that came from an
    // offset point, where it is now.
    t0 = Clock::now();
    std::vector<FinalPoint> final_points;
    for (size_t p = n; p < ins.source.size(); ++p)
        final_points.push_back({ins.source[p] - n, mesh.points[p]});
    result.layers = account_layers(surface, sizing, params.M, params.L_min, raw, points, ins.fates, final_points,
                                   params.layer_tolerance);
    result.seconds_quality += seconds_since(t0);

    finish(result, surface, params, start);
    return result;
}

} // namespace scalemesh
