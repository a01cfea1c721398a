#include "volume/delaunay_insertion.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "volume/improve.h"
#include "volume/slabs.h"

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>
#include <CGAL/property_map.h>
#include <CGAL/spatial_sort.h>
#include <CGAL/Spatial_sort_traits_adapter_3.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <unordered_map>
#include <unordered_set>

namespace scalemesh {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_3<int32_t, Kernel>;
// Sides of the cells. The cells an insertion makes get the default side,
// inside: every insertion happens inside the surface (see try_insert).
constexpr int8_t kInside = 0, kOutside = 1, kUnknown = -1;
struct CellSide {
    int8_t value = kInside;
    CellSide& operator=(int8_t v)
    {
        value = v;
        return *this;
    }
    operator int8_t() const { return value; }
};

using Cb = CGAL::Triangulation_cell_base_with_info_3<CellSide, Kernel, CGAL::Delaunay_triangulation_cell_base_3<Kernel>>;
// The concurrent containers of Parallel_tag let insertions in disjoint slabs
// create and delete cells at once (see insert_layers). No lock data
// structure is given: CGAL's own operations on it stay sequential.
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb, CGAL::Parallel_tag>;
using Delaunay = CGAL::Delaunay_triangulation_3<Kernel, Tds>;
using Point = Kernel::Point_3;
using Vertex_handle = Delaunay::Vertex_handle;
using Cell_handle = Delaunay::Cell_handle;
using Facet = Delaunay::Facet;

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

Point to_point(const Vec3& p) { return {p.x, p.y, p.z}; }

struct TriangleKey {
    int32_t a, b, c; // sorted
    bool operator==(const TriangleKey&) const = default;
};
TriangleKey make_key(int32_t a, int32_t b, int32_t c)
{
    if (a > b) std::swap(a, b);
    if (b > c) std::swap(b, c);
    if (a > b) std::swap(a, b);
    return {a, b, c};
}
struct TriangleKeyHash {
    size_t operator()(const TriangleKey& k) const
    {
        uint64_t h = static_cast<uint32_t>(k.a);
        h = h * 0x9E3779B97F4A7C15ull ^ static_cast<uint32_t>(k.b);
        h = h * 0x9E3779B97F4A7C15ull ^ static_cast<uint32_t>(k.c);
        return static_cast<size_t>(h ^ (h >> 29));
    }
};

enum class Verdict { inserted, small, filler, hidden, outside, deferred };

// Where a parallel insertion may work: the cells whose four vertices are
// finite with coordinate `axis` in [lo, hi). Null for sequential insertion.
struct Region {
    int axis = 0;
    double lo = 0, hi = 0;
    bool holds(const Point& p) const { return p[axis] >= lo && p[axis] < hi; }
};

// What one insertion needs of its own: the walk's start and the cavity.
struct Scratch {
    Cell_handle hint;
    std::vector<Facet> boundary;
    std::vector<Cell_handle> cells, touched, removed, kept;
    bool tiny = false; // the last shrink took out a cell for a tiny tet
    std::minstd_rand random;
};

// Holds the triangulation and the surface while points are inserted.
class ConditionalDelaunay {
public:
    ConditionalDelaunay(const SurfaceMesh& surface, const std::vector<OffsetPoint>& points,
                        const InsertionParams& params)
        : surface_(surface), triangles_(surface.triangles), points_(points), params_(params),
          n_(static_cast<int32_t>(surface.points.size()))
    {
        for (const auto& e : params.protected_edges) protected_edges_.insert(edge_key(e[0], e[1]));
        stamp_.assign(static_cast<size_t>(n_) + points.size(), 0);
    }

    // The Delaunay triangulation of the surface points, its quads and the
    // sides of its cells. False when a surface triangle is missing (listed
    // in result.missing_triangles).
    bool insert_surface(InsertionResult& result)
    {
        std::vector<std::pair<Point, int32_t>> input;
        input.reserve(n_);
        for (int32_t i = 0; i < n_; ++i) input.emplace_back(to_point(surface_.points[i]), i);
        dt_.insert(input.begin(), input.end()); // spatially sorted by CGAL
        if (dt_.number_of_vertices() != static_cast<size_t>(n_))
            throw InputError("volume: the surface has coincident points (" + std::to_string(n_ - int32_t(dt_.number_of_vertices())) +
                                 " duplicates)",
                             "merge duplicate vertices before meshing the volume");
        if (dt_.dimension() < 3)
            throw InputError("volume: the surface points are coplanar", "the surface must enclose a volume");
        surface_vertex_.resize(n_);
        for (auto v = dt_.finite_vertices_begin(); v != dt_.finite_vertices_end(); ++v) surface_vertex_[v->info()] = v;
        index_facets();
        result.surface_flips = flip_to_facets();
        barrier_.reserve(triangles_.size());
        for (const Triangle& tri : triangles_) barrier_.emplace(make_key(tri[0], tri[1], tri[2]), tri);
        find_quads();
        classify_sides(result);
        facets_ = {}; // the insertions to come change the facets
        return result.missing_triangles.empty();
    }

    // Algorithm 5: layer by layer, `passes` times over the points not yet
    // inserted. Each layer is spatially sorted (Hilbert order on random
    // rounds) and every walk starts from the previous point's cell, so a
    // point is found in a few steps.
    //
    // In parallel, and with the same result on any number of threads: the
    // points are cut into slabs of equal count along the longest axis (their
    // number depends on the points only). The even slabs are inserted at
    // once, each by one task in sorted order, then the odd ones. A task
    // works only on cells whose four vertices lie in its region: its slab
    // and half of each idle neighbour, so no two tasks ever read a cell the
    // other changes (a cell next to one of a task's cells shares three of
    // its vertices, so it is no other task's). A point whose walk or cavity
    // would leave the region is deferred, and the deferred points are then
    // inserted one by one in their order. What a task does depends on its
    // own region alone, never on the timing of the others.
    void insert_layers(InsertionResult& result)
    {
        int max_layer = 0;
        for (const OffsetPoint& p : points_) max_layer = std::max(max_layer, p.layer);
        std::vector<Point> positions;
        positions.reserve(points_.size());
        for (const OffsetPoint& p : points_) positions.push_back(to_point(p.position));
        const Slabs slabs = make_slabs(points_);
        // Per layer and slab, the points in Hilbert order.
        std::vector<std::vector<std::vector<std::size_t>>> by_layer(
            max_layer + 1, std::vector<std::vector<std::size_t>>(slabs.count()));
        for (size_t k = 0; k < points_.size(); ++k)
            by_layer[points_[k].layer][slabs.of(points_[k].position)].push_back(k);
        using Traits = CGAL::Spatial_sort_traits_adapter_3<Kernel, CGAL::Pointer_property_map<Point>::type>;
        const Traits traits(CGAL::make_property_map(positions));
        // Each (layer, slab) list sorted on its own, the lists in parallel.
        tbb::parallel_for(size_t(0), by_layer.size() * slabs.count(), [&](size_t k) {
            auto& slab = by_layer[k / slabs.count()][k % slabs.count()];
            CGAL::spatial_sort(slab.begin(), slab.end(), traits);
        });

        Scratch sequential;
        tbb::enumerable_thread_specific<Scratch> scratch;
        verdict_.assign(points_.size(), Verdict::outside);
        vertex_of_.assign(points_.size(), Vertex_handle());
        std::vector<char> done(points_.size(), 0);
        std::vector<std::vector<std::size_t>> deferred(slabs.count());
        std::vector<Cell_handle> start(slabs.count());
        for (int pass = 0; pass < std::max(1, params_.passes); ++pass) {
            const auto inserted_before = std::count(done.begin(), done.end(), 1);
            for (int m = 1; m <= max_layer; ++m) {
                for (int parity = 0; parity < 2; ++parity) {
                    // Each task's first walk starts where a sequential
                    // locate puts the slab's first pending point.
                    for (int s = parity; s < slabs.count(); s += 2)
                        for (std::size_t k : by_layer[m][s])
                            if (!done[k]) {
                                start[s] = locate_start(k, positions[k]);
                                break;
                            }
                    tbb::parallel_for(0, (slabs.count() - parity + 1) / 2, [&](int task) {
                        const int s = parity + 2 * task;
                        const Region region = slabs.region(s);
                        Scratch& own = scratch.local();
                        own.hint = start[s];
                        own.random.seed(static_cast<unsigned>(s));
                        deferred[s].clear();
                        for (std::size_t k : by_layer[m][s]) {
                            if (done[k]) continue;
                            verdict_[k] = insert_point(static_cast<int32_t>(k), positions[k], &region, own);
                            if (verdict_[k] == Verdict::deferred) deferred[s].push_back(k);
                            done[k] = verdict_[k] == Verdict::inserted;
                        }
                    });
                }
                for (int s = 0; s < slabs.count(); ++s)
                    for (std::size_t k : deferred[s]) {
                        ++result.deferred;
                        // The tasks may have taken the last hint's cell.
                        if (k == deferred[s].front()) sequential.hint = locate_start(k, positions[k]);
                        verdict_[k] = insert_point(static_cast<int32_t>(k), positions[k], nullptr, sequential);
                        done[k] = verdict_[k] == Verdict::inserted;
                    }
            }
            if (std::count(done.begin(), done.end(), 1) == inserted_before) break;
        }
        result.fates.reserve(verdict_.size());
        for (Verdict v : verdict_) {
            result.fates.push_back(v == Verdict::inserted ? InsertionFate::inserted
                                   : v == Verdict::small  ? InsertionFate::tiny_tet
                                   : v == Verdict::filler ? InsertionFate::filler
                                   : v == Verdict::hidden ? InsertionFate::hidden
                                                          : InsertionFate::outside);
            result.inserted += v == Verdict::inserted;
            result.rejected_small += v == Verdict::small;
            result.rejected_filler += v == Verdict::filler;
            result.rejected_surface += v == Verdict::hidden;
            result.rejected_other += v == Verdict::outside;
        }
    }

    // The inside cells as output, in an order that depends on the cells
    // alone (not on where the concurrent containers put them): interior
    // points numbered in the order of the offset points, tets sorted by
    // their points.
    void output(InsertionResult& result)
    {
        result.quads = quads_;
        for (const auto& [first, second] : quad_triangles_) result.quad_triangles.push_back({first, second});
        result.points.assign(surface_.points.begin(), surface_.points.end());
        result.source.resize(n_);
        for (int32_t i = 0; i < n_; ++i) result.source[i] = i;
        std::vector<int32_t> index(points_.size(), -1); // offset point -> output point
        for (auto c = dt_.finite_cells_begin(); c != dt_.finite_cells_end(); ++c) {
            if (c->info() != kInside) continue;
            for (int i = 0; i < 4; ++i)
                if (const int32_t id = c->vertex(i)->info(); id >= n_) index[id - n_] = 0;
        }
        int64_t used = 0;
        for (size_t k = 0; k < points_.size(); ++k) {
            if (index[k] < 0) continue;
            index[k] = static_cast<int32_t>(result.points.size());
            const Point& at = vertex_of_[k]->point(); // where it went in (insert_point)
            result.points.push_back({at.x(), at.y(), at.z()});
            result.source.push_back(n_ + static_cast<int32_t>(k));
            ++used;
        }
        result.tets.reserve(dt_.number_of_finite_cells() / 2);
        for (auto c = dt_.finite_cells_begin(); c != dt_.finite_cells_end(); ++c) {
            if (c->info() != kInside) continue;
            Tet& tet = result.tets.emplace_back(); // CGAL cells are positively oriented
            for (int i = 0; i < 4; ++i) {
                const int32_t id = c->vertex(i)->info();
                tet[i] = id < n_ ? id : index[id - n_];
            }
        }
        sort_tets_by_smallest_point(result.tets, result.points.size());
        result.unused = result.inserted - used;
    }

    const std::vector<Triangle>& triangles() const { return triangles_; }

private:
    // The finite facets of the surface points' triangulation by their
    // points, each with one of its two cells: the surface checks below look
    // up thousands of triangles, and CGAL's is_facet gathers a vertex's
    // cells for each (with the concurrent containers, into a set).
    void index_facets()
    {
        facets_.reserve(7 * size_t(n_) + 16);
        for (auto c = dt_.finite_cells_begin(); c != dt_.finite_cells_end(); ++c)
            for (int l = 0; l < 4; ++l) {
                int32_t v[3], k = 0;
                for (int j = 0; j < 4; ++j)
                    if (j != l) v[k++] = c->vertex(j)->info();
                facets_.try_emplace(make_key(v[0], v[1], v[2]), c, l);
            }
        // A facet on the convex hull has one finite cell: the loop saw it.
    }

    // The facet with points tri, or a null cell when it is not one.
    Facet find_facet(const Triangle& tri) const
    {
        const auto it = facets_.find(make_key(tri[0], tri[1], tri[2]));
        return it == facets_.end() ? Facet() : it->second;
    }

    bool is_facet(const Triangle& tri) const { return find_facet(tri).first != Cell_handle(); }

    // A surface triangle (a, b, c) that is not a Delaunay facet while its
    // neighbour (a, c, d) is one often has the other split of their quad,
    // (a, b, d) and (b, c, d), as facets: then a flip of the surface edge
    // (a, c) to (b, d) makes the surface conform there, where refining the
    // surface around it, remeshing and building the volume again would
    // otherwise be needed. More generally a flip is made wherever it gives
    // the pair more facets than it had (a fan of such triangles around one
    // node takes a few in turn), the one of a triangle's three edges that
    // gains most, where surface_flip_allowed. Returns the number of flips.
    int64_t flip_to_facets()
    {
        std::vector<int32_t> missing;
        for (size_t t = 0; t < triangles_.size(); ++t)
            if (!is_facet(triangles_[t])) missing.push_back(static_cast<int32_t>(t));
        if (missing.empty()) return 0;
        std::unordered_map<uint64_t, int32_t> triangle_of; // directed edge -> triangle
        const auto directed = directed_edge_key;
        for (size_t t = 0; t < triangles_.size(); ++t)
            for (int e = 0; e < 3; ++e)
                triangle_of[directed(triangles_[t][e], triangles_[t][(e + 1) % 3])] = static_cast<int32_t>(t);
        EdgeSet edges = edge_set(triangles_);
        // Each flip makes more of the pair facets than were before, so the
        // passes end. A pair whose flip makes both facets from none is a
        // quad, left to find_quads (its stand-ins keep the surface's own
        // diagonal where the repair succeeds).
        int64_t flips = 0;
        for (bool again = true; again;) {
            again = false;
            for (int32_t t : missing) {
                if (is_facet(triangles_[t])) continue;
                int best = -1, best_gain = 0, best_o = -1, best_d = -1;
                for (int e = 0; e < 3; ++e) {
                    const Triangle& tri = triangles_[t];
                    const int32_t a = tri[(e + 2) % 3], b = tri[e], c = tri[(e + 1) % 3];
                    const auto it = triangle_of.find(directed(a, c));
                    if (it == triangle_of.end()) continue;
                    const int32_t o = it->second;
                    int32_t d = -1;
                    for (int32_t v : triangles_[o])
                        if (v != a && v != c) d = v;
                    const int before = is_facet(triangles_[o]);
                    const int after = int(is_facet({a, b, d})) + int(is_facet({b, c, d}));
                    if ((before == 0 && after == 2) || after - before <= best_gain ||
                        !surface_flip_allowed(surface_, {a, b, c, d}, {t, o}, edges))
                        continue;
                    best = e, best_gain = after - before, best_o = o, best_d = d;
                }
                if (best < 0) continue;
                const Triangle tri = triangles_[t];
                const int32_t a = tri[(best + 2) % 3], b = tri[best], c = tri[(best + 1) % 3], o = best_o, d = best_d;
                triangles_[t] = {a, b, d};
                triangles_[o] = {b, c, d};
                for (const auto& [u, v] : {std::pair{a, c}, std::pair{c, a}}) triangle_of.erase(directed(u, v));
                triangle_of[directed(a, b)] = t, triangle_of[directed(b, d)] = t, triangle_of[directed(d, a)] = t;
                triangle_of[directed(b, c)] = o, triangle_of[directed(c, d)] = o, triangle_of[directed(d, b)] = o;
                edges.erase(edge_key(a, c));
                edges.insert(edge_key(b, d));
                ++flips;
                again = true;
            }
        }
        return flips;
    }

    // A surface quad (a, b, c, d) split along (a, c) whose four points are
    // (nearly) cospherical often comes out of the Delaunay triangulation split
    // along (b, d) instead. Such a pair of triangles cannot appear later (an
    // insertion never creates a facet between old vertices), so the stage
    // takes the Delaunay facets (a, b, d) and (b, c, d) as stand-ins: they
    // separate inside from outside like the quad, bound every cavity like
    // surface triangles, and the tets at (b, d) on the inner side are
    // re-triangulated onto the quad afterwards (repair_surface_quads).
    void find_quads()
    {
        std::vector<int32_t> missing;
        for (size_t t = 0; t < triangles_.size(); ++t) {
            if (!is_facet(triangles_[t])) missing.push_back(static_cast<int32_t>(t));
        }
        std::unordered_map<uint64_t, int32_t> missing_edge; // directed edge -> missing triangle
        const auto directed = directed_edge_key;
        for (int32_t t : missing)
            for (int e = 0; e < 3; ++e)
                missing_edge[directed(triangles_[t][e], triangles_[t][(e + 1) % 3])] = t;
        std::vector<char> used(triangles_.size(), 0);
        for (int32_t t : missing) {
            if (used[t]) continue;
            const Triangle& tri = triangles_[t];
            for (int e = 0; e < 3; ++e) {
                // tri = (a, b, c) with the shared edge c -> a; the other triangle has a -> c.
                const int32_t a = tri[(e + 2) % 3], b = tri[e], c = tri[(e + 1) % 3];
                const auto it = missing_edge.find(directed(a, c));
                if (it == missing_edge.end() || used[it->second]) continue;
                const Triangle& other = triangles_[it->second];
                int32_t d = -1;
                for (int32_t v : other)
                    if (v != a && v != c) d = v;
                if (!is_facet({a, b, d}) || !is_facet({b, c, d})) continue;
                used[t] = used[it->second] = 1;
                quads_.push_back({a, b, c, d});
                quad_triangles_.emplace_back(t, it->second);
                barrier_.emplace(make_key(a, b, d), Triangle{a, b, d});
                barrier_.emplace(make_key(b, c, d), Triangle{b, c, d});
                break;
            }
        }
    }

    // The sides, exactly and without coordinates: every surface triangle
    // (or quad stand-in) that is a facet separates an inner from an outer
    // cell, by the exact orientation of its outward normal against the
    // opposite vertex, and a flood fill through the other facets carries the
    // side to every cell; the infinite cells are outside.
    void classify_sides(InsertionResult& result)
    {
        for (auto c = dt_.all_cells_begin(); c != dt_.all_cells_end(); ++c)
            c->info() = dt_.is_infinite(c) ? kOutside : kUnknown;
        std::vector<Cell_handle> stack;
        std::vector<char> in_quad(n_, 0);
        for (const auto& q : quads_)
            for (int32_t v : q) in_quad[v] = 1;
        for (size_t t = 0; t < triangles_.size(); ++t) {
            const Triangle& tri = triangles_[t];
            if (!seed(tri, stack)) {
                if (in_quad[tri[0]] && in_quad[tri[1]] && in_quad[tri[2]] && quad_triangle(tri)) continue;
                result.missing_triangles.push_back(static_cast<int32_t>(t));
            }
        }
        for (size_t i = 0; i < quads_.size(); ++i) {
            const auto& q = quads_[i];
            for (const Triangle& tri : {Triangle{q[0], q[1], q[3]}, Triangle{q[1], q[2], q[3]}})
                if (!seed(tri, stack)) {
                    result.missing_triangles.push_back(quad_triangles_[i].first);
                    result.missing_triangles.push_back(quad_triangles_[i].second);
                }
        }
        while (!stack.empty()) {
            const Cell_handle c = stack.back();
            stack.pop_back();
            for (int i = 0; i < 4; ++i) {
                if (is_surface_facet(c, i)) continue;
                const Cell_handle nb = c->neighbor(i);
                if (nb->info() == kUnknown) {
                    nb->info() = c->info();
                    stack.push_back(nb);
                }
            }
        }
        // Cells no seed reaches touch no surface triangle: outside.
        for (auto c = dt_.all_cells_begin(); c != dt_.all_cells_end(); ++c)
            if (c->info() == kUnknown) c->info() = kOutside;
    }

    bool quad_triangle(const Triangle& tri) const
    {
        const TriangleKey k = make_key(tri[0], tri[1], tri[2]);
        for (const auto& q : quads_)
            if (k == make_key(q[0], q[1], q[2]) || k == make_key(q[0], q[2], q[3])) return true;
        return false;
    }

    // Sides of the two cells at the barrier triangle tri (outward
    // counter-clockwise): false when it is not a facet or the sides clash.
    bool seed(const Triangle& tri, std::vector<Cell_handle>& stack)
    {
        const auto [c, l] = find_facet(tri);
        if (c == Cell_handle()) return false;
        const Cell_handle other = c->neighbor(l);
        int8_t side_c = kOutside;
        if (!dt_.is_infinite(c)) {
            // The opposite vertex is inside exactly when (a, b, c, q) is negatively oriented.
            const auto o = CGAL::orientation(to_point(surface_.points[tri[0]]), to_point(surface_.points[tri[1]]),
                                             to_point(surface_.points[tri[2]]), c->vertex(l)->point());
            side_c = o == CGAL::NEGATIVE ? kInside : kOutside;
        }
        return assign(c, side_c, stack) && assign(other, side_c == kInside ? kOutside : kInside, stack);
    }

    bool assign(Cell_handle c, int8_t side, std::vector<Cell_handle>& stack)
    {
        if (c->info() == kUnknown) {
            c->info() = side;
            stack.push_back(c);
            return true;
        }
        return c->info() == side;
    }

    bool is_surface_facet(Cell_handle c, int i) const
    {
        int32_t v[3], k = 0;
        for (int j = 0; j < 4; ++j) {
            if (j == i) continue;
            if (dt_.is_infinite(c->vertex(j))) return false;
            v[k] = c->vertex(j)->info();
            if (v[k] >= n_) return false;
            ++k;
        }
        return barrier_.count(make_key(v[0], v[1], v[2])) != 0;
    }

    // Four slabs of equal point count along the longest axis of the points'
    // bounding box: two tasks at once, each region half the box. More slabs
    // give more tasks but narrower regions: on the torus of a 768 box six
    // deferred 17.7% of the points (the first layers' cavities span the
    // tube) against 1.5% with four, and the mesh before flips had 12.84% of
    // its tets below 0.1 against 12.48% (12.39% inserted in one sequence).
    static constexpr int kSlabs = 4;
    // The slabs' outer ends lie 1 mm beyond the points, so that the halves
    // next to the end slabs have room.
    struct Slabs : SlabCut {
        double middle(int s) const { return 0.5 * (bounds[s] + bounds[s + 1]); }
        // Slab s and the halves of its neighbours next to it.
        Region region(int s) const
        {
            constexpr double kInfinity = std::numeric_limits<double>::infinity();
            return {axis, s == 0 ? -kInfinity : middle(s - 1), s + 1 == count() ? kInfinity : middle(s + 1)};
        }
    };

    static Slabs make_slabs(const std::vector<OffsetPoint>& points)
    {
        std::vector<Vec3> where;
        where.reserve(points.size());
        for (const OffsetPoint& p : points) where.push_back(p.position);
        Slabs slabs{equal_count_slabs(where, kSlabs)};
        slabs.bounds.front() -= 1.0;
        slabs.bounds.back() += 1.0;
        return slabs;
    }

    // Whether a task with `region` may work on cell c.
    bool owns(const Region* region, Cell_handle c) const
    {
        if (!region) return true;
        for (int i = 0; i < 4; ++i) {
            const Vertex_handle v = c->vertex(i);
            if (dt_.is_infinite(v) || !region->holds(v->point())) return false;
        }
        return true;
    }

    // The cell that holds offset point k, found by CGAL's locate from the
    // cell of its surface node (vertices live for good; their cell is a
    // living one next to them).
    Cell_handle locate_start(std::size_t k, const Point& p) const
    {
        Delaunay::Locate_type lt;
        int li, lj;
        return dt_.locate(p, lt, li, lj, surface_vertex_[points_[k].generator]->cell());
    }

    // A visibility walk (facets tried from a random one) from own.hint to
    // the cell that holds p, through cells of the region only; a null
    // handle when it would leave the region, meet a point on a vertex or
    // take too long. Steps across a facet only when p is strictly beyond
    // it (never the facet just crossed, which p is strictly before), so it
    // ends in a cell that holds p (in it or on its boundary).
    Cell_handle walk(const Point& p, Cell_handle from, const Region* region, Scratch& own) const
    {
        Cell_handle c = from;
        if (c == Cell_handle() || !owns(region, c)) return {};
        Cell_handle previous;
        for (int step = 0; step < 10000; ++step) {
            const int first = static_cast<int>(own.random() % 4);
            bool moved = false;
            for (int r = 0; r < 4 && !moved; ++r) {
                const int i = (first + r) % 4;
                const Cell_handle next = c->neighbor(i);
                if (next == previous) continue;
                const Point* q[4];
                for (int j = 0; j < 4; ++j) q[j] = j == i ? &p : &c->vertex(j)->point();
                if (CGAL::orientation(*q[0], *q[1], *q[2], *q[3]) != CGAL::NEGATIVE) continue;
                if (!owns(region, next)) return {};
                previous = c;
                c = next;
                moved = true;
            }
            if (!moved) {
                for (int j = 0; j < 4; ++j)
                    if (c->vertex(j)->point() == p) return {};
                return c;
            }
        }
        return {};
    }

    // Algorithm 5 for point k at its place p; a layermaking point refused
    // for a tiny tet or a cavity shrunk to nothing (where the normals of
    // nearby nodes converge, its neighbours of the same layer crowd it) is
    // tried again a little along its normal, within the layer tolerance of
    // its spacing: its layer then still has a point at this node.
    Verdict insert_point(int32_t k, const Point& p, const Region* region, Scratch& own)
    {
        Verdict verdict = try_insert(k, p, region, own);
        const OffsetPoint& op = points_[k];
        if ((verdict != Verdict::small && verdict != Verdict::hidden) || op.filler || !(op.dist > 0)) return verdict;
        const Vec3& node = surface_.points[op.generator];
        const Vec3 inward = (op.position - node) / op.dist;
        const double most = 0.9 * params_.layer_shift;
        for (double shift : {-most, most, -0.5 * most, 0.5 * most}) {
            const Vec3 q = op.position + shift * op.spacing * inward;
            const Verdict again = try_insert(k, to_point(q), region, own);
            if (again == Verdict::inserted || again == Verdict::deferred) return again;
        }
        return verdict;
    }

    // Algorithm 5 for point k, with the insertion cavity confined to the
    // inside: the cells whose circumspheres hold the point, reached from
    // the cell that contains it without crossing the surface. A Delaunay
    // cavity that crossed a surface triangle would destroy it for good (an
    // insertion never makes a facet between old vertices); confined, the
    // surface stays a set of facets. Where the conflicts reach through the
    // surface (near-cospherical surface points, flat outer slivers) the
    // outer cells simply stay as they are.
    //
    // The cavity must be star-shaped from the point, and (i) no new tet
    // (the point joined to a boundary facet of the cavity) may have a volume
    // below min_volume_fraction * spacing^3 (a sliver the flips could not
    // repair). For a layermaking point, a cell whose boundary facet breaks
    // either is taken out of the cavity, with whatever then hangs on it only
    // through it, until the cavity is good; the point is refused when that
    // would take out the cell holding it. A filler is refused at the first
    // such cell, as the paper says. Such a cell stays though the point is in its
    // circumsphere: the inside is then no longer exactly Delaunay, which
    // the flips of section 2.4 are there to repair. A new tet holding a
    // protected quad diagonal is kept out the same way. Refused as well: a
    // point outside the surface or on a vertex; a cavity that would swallow
    // a vertex; (ii) a filler point that would join a surface point (paper
    // section 2.3).
    //
    // With a region (parallel insertion) only the region's cells are
    // marked or changed; the point is deferred when its walk or its cavity
    // would need another cell. The neighbours of the region's cells are
    // only read: their vertices and side never change while tasks run.
    Verdict try_insert(int32_t k, const Point& p, const Region* region, Scratch& own)
    {
        const OffsetPoint& op = points_[k];
        Cell_handle c;
        if (region) {
            // The walk starts next to the point of the layer before from the
            // same surface node (or next to the node), else where the last
            // one ended: a walk from one point to the next in Hilbert order
            // often leaves the region through the big outer cells.
            Cell_handle from = own.hint;
            const Vertex_handle before =
                k > 0 && points_[k - 1].generator == op.generator && points_[k - 1].layer == op.layer - 1
                    ? vertex_of_[k - 1]
                    : op.layer == 1 ? surface_vertex_[op.generator] : Vertex_handle();
            if (before != Vertex_handle() && region->holds(before->point())) from = before->cell();
            c = walk(p, from, region, own);
            if (c == Cell_handle() && from != own.hint) c = walk(p, own.hint, region, own);
            if (c == Cell_handle()) return Verdict::deferred;
            own.hint = c;
            if (c->info() != kInside) return Verdict::outside;
        } else {
            Delaunay::Locate_type lt;
            int li, lj;
            c = dt_.locate(p, lt, li, lj, own.hint);
            own.hint = c;
            if (lt == Delaunay::VERTEX || lt == Delaunay::OUTSIDE_CONVEX_HULL ||
                lt == Delaunay::OUTSIDE_AFFINE_HULL || c->info() != kInside)
                return Verdict::outside;
        }

        // Breadth-first over the conflicting inside cells, marked in
        // conflict; the cells tested and found not in conflict are marked on
        // boundary until the search is over (the region's cells only).
        std::vector<Cell_handle>& cells = own.cells;
        cells.clear();
        own.touched.clear();
        c->tds_data().mark_in_conflict();
        cells.push_back(c);
        bool leaves_region = false;
        for (size_t i = 0; i < cells.size() && !leaves_region; ++i) {
            const Cell_handle cc = cells[i];
            for (int j = 0; j < 4; ++j) {
                const Cell_handle nb = cc->neighbor(j);
                if (!nb->tds_data().is_clear()) continue;
                const bool conflict = nb->info() == kInside && dt_.side_of_sphere(nb, p, true) == CGAL::ON_BOUNDED_SIDE;
                if (!owns(region, nb)) {
                    if (conflict) {
                        leaves_region = true;
                        break;
                    }
                    continue;
                }
                if (conflict) {
                    nb->tds_data().mark_in_conflict();
                    cells.push_back(nb);
                } else {
                    nb->tds_data().mark_on_boundary();
                    own.touched.push_back(nb);
                }
            }
        }
        for (const Cell_handle& t : own.touched) t->tds_data().clear();
        if (leaves_region) {
            for (const Cell_handle& t : cells) t->tds_data().clear();
            return Verdict::deferred;
        }

        // The floor's length: a filler's spacing; for a layermaking point
        // the mean spacing of its layers so far (its own spacing when they
        // are uniform; graded layers, FirstLayer::edge or growth, would
        // otherwise judge the thick inner layers by their own thickness where
        // their points crowd, as at a sphere's centre).
        const double s = op.filler || op.layer < 1 ? op.spacing : std::min(op.spacing, op.dist / op.layer);
        const double limit = 6.0 * params_.min_volume_fraction * s * s * s;
        Verdict verdict = Verdict::inserted;
        for (int round = 0;; ++round) {
            const bool shrunk = shrink_cavity(p, c, limit, verdict, own);
            if (verdict != Verdict::inserted) break;
            // A filler is refused rather than its cavity shrunk (the
            // paper's rule (i)): fillers only fill, and every cell a shrink
            // keeps in conflict makes the next layer's cavities larger and
            // less often star-shaped.
            if (shrunk && op.filler) {
                verdict = own.tiny ? Verdict::small : Verdict::hidden;
                break;
            }
            if (!shrunk) {
                verdict = check_cavity(op, own);
                break;
            }
            if (round == 32) {
                verdict = Verdict::hidden;
                break;
            }
        }
        if (verdict != Verdict::inserted) {
            for (const Cell_handle& t : own.cells) t->tds_data().clear();
            return verdict;
        }
        // CGAL's own insertion takes the small-hole path for cavities of up
        // to 128 facets (a fixed table instead of a recursive walk); both
        // expect the cavity marked in conflict, as it is here. Both write
        // the facing neighbour link of each cell around the cavity (a
        // neighbour of a region's cell is no other task's) and the cell of
        // each boundary vertex (in the region).
        const Vertex_handle v =
            dt_.tds().is_small_hole(own.boundary.size())
                ? dt_._insert_in_small_hole(p, own.cells, own.boundary)
                : dt_.insert_in_hole(p, own.cells.begin(), own.cells.end(), own.boundary.front().first,
                                     own.boundary.front().second);
        v->info() = n_ + k;
        vertex_of_[k] = v;
        own.hint = v->cell();
        return Verdict::inserted;
    }

    // One round of cavity shrinking: collects the boundary facets, takes out
    // the cells with a facet the point does not strictly see, that makes a
    // tet below `limit` (6 V) or one with a protected edge, and keeps the part still connected to the
    // cell `start` that holds the point. True when cells were taken out;
    // `verdict` turns to a refusal when `start` itself would go.
    bool shrink_cavity(const Point& p, Cell_handle start, double limit, Verdict& verdict, Scratch& own) const
    {
        std::vector<Cell_handle>& cells = own.cells;
        own.boundary.clear();
        own.removed.clear();
        bool start_tiny = false; // the holding cell goes for the volume floor alone
        own.tiny = false;
        for (const Cell_handle& cc : cells) {
            bool bad = false;
            for (int j = 0; j < 4; ++j) {
                if (cc->neighbor(j)->tds_data().is_in_conflict()) continue;
                own.boundary.emplace_back(cc, j);
                if (bad) continue;
                const Point* q[4];
                int32_t ids[3], n = 0;
                for (int i = 0; i < 4; ++i) {
                    q[i] = i == j ? &p : &cc->vertex(i)->point();
                    if (i != j) ids[n++] = cc->vertex(i)->info();
                }
                if (touches_protected_edge(ids)) {
                    bad = true;
                    continue;
                }
                const double v6 = tet_volume6({q[0]->x(), q[0]->y(), q[0]->z()}, {q[1]->x(), q[1]->y(), q[1]->z()},
                                              {q[2]->x(), q[2]->y(), q[2]->z()}, {q[3]->x(), q[3]->y(), q[3]->z()});
                // Above a positive limit the sign of v6 is beyond round-off;
                // without one, the exact predicate decides.
                bad = v6 < limit || (limit <= 0 && CGAL::orientation(*q[0], *q[1], *q[2], *q[3]) != CGAL::POSITIVE);
                // Seen from the point but below the floor: a tiny tet, (i).
                if (bad && limit > 0 && CGAL::orientation(*q[0], *q[1], *q[2], *q[3]) == CGAL::POSITIVE) {
                    own.tiny = true;
                    start_tiny = start_tiny || cc == start;
                }
            }
            if (bad) own.removed.push_back(cc);
        }
        if (own.removed.empty()) return false;
        for (const Cell_handle& cc : own.removed) {
            if (cc == start) {
                verdict = start_tiny ? Verdict::small : Verdict::hidden;
                return true;
            }
            cc->tds_data().clear();
        }
        // The part connected to start, found by re-marking it on boundary.
        size_t kept = 0;
        start->tds_data().mark_on_boundary();
        std::swap(cells, own.kept);
        cells.clear();
        cells.push_back(start);
        for (size_t i = 0; i < cells.size(); ++i)
            for (int j = 0; j < 4; ++j) {
                const Cell_handle nb = cells[i]->neighbor(j);
                if (!nb->tds_data().is_in_conflict()) continue;
                nb->tds_data().mark_on_boundary();
                cells.push_back(nb);
            }
        for (const Cell_handle& cc : own.kept)
            if (cc->tds_data().is_in_conflict()) cc->tds_data().clear(); // cut off
        for (const Cell_handle& cc : cells) cc->tds_data().mark_in_conflict(), ++kept;
        return kept > 0;
    }

    // The refusals that no shrinking cures, on the final cavity.
    // The points on the cavity's boundary are stamped with a value no other
    // check has used; a task stamps only points of its region.
    Verdict check_cavity(const OffsetPoint& op, const Scratch& own)
    {
        const uint32_t stamp = ++stamp_value_;
        for (const Facet& f : own.boundary) {
            int32_t ids[3], j = 0;
            for (int i = 0; i < 4; ++i) {
                if (i == f.second) continue;
                ids[j] = f.first->vertex(i)->info();
                stamp_[ids[j++]] = stamp;
            }
            if (op.filler && (ids[0] < n_ || ids[1] < n_ || ids[2] < n_)) return Verdict::filler;
        }
        for (const Cell_handle& cc : own.cells)
            for (int i = 0; i < 4; ++i)
                if (stamp_[cc->vertex(i)->info()] != stamp) return Verdict::hidden;
        return Verdict::inserted;
    }

    // True when the new tet (facet + new point) contains a protected edge.
    bool touches_protected_edge(const int32_t ids[3]) const
    {
        if (protected_edges_.empty()) return false;
        for (int i = 0; i < 3; ++i)
            for (int j = i + 1; j < 3; ++j)
                if (ids[i] < n_ && ids[j] < n_ && protected_edges_.count(edge_key(ids[i], ids[j]))) return true;
        return false;
    }

    std::unordered_set<uint64_t> protected_edges_;
    const SurfaceMesh& surface_;
    std::vector<Triangle> triangles_; // surface_.triangles with the flips of flip_to_facets
    const std::vector<OffsetPoint>& points_;
    const InsertionParams& params_;
    const int32_t n_;
    Delaunay dt_;
    std::vector<Vertex_handle> surface_vertex_;
    std::unordered_map<TriangleKey, Triangle, TriangleKeyHash> barrier_; // surface triangles and quad stand-ins, oriented outwards
    std::unordered_map<TriangleKey, Facet, TriangleKeyHash> facets_;      // while the surface is checked (index_facets)
    std::vector<std::array<int32_t, 4>> quads_;
    std::vector<std::pair<int32_t, int32_t>> quad_triangles_;
    std::vector<Verdict> verdict_;
    std::vector<Vertex_handle> vertex_of_; // per offset point, once inserted
    std::vector<uint32_t> stamp_;          // per point id: the last check_cavity that saw it on the boundary
    std::atomic<uint32_t> stamp_value_{0};
};

} // namespace

InsertionResult insert_and_classify(const SurfaceMesh& surface, const std::vector<OffsetPoint>& points,
                                    const InsertionParams& params)
{
    InsertionResult result;
    ConditionalDelaunay cd(surface, points, params);
    auto t0 = Clock::now();
    const bool conforming = cd.insert_surface(result);
    result.triangles = cd.triangles();
    result.seconds_classify = seconds_since(t0);
    if (!conforming) return result;
    t0 = Clock::now();
    cd.insert_layers(result);
    result.seconds_insertion = seconds_since(t0);
    t0 = Clock::now();
    cd.output(result);
    result.seconds_classify += seconds_since(t0);
    return result;
}

} // namespace scalemesh
