#include "volume/delaunay_insertion.h"

#include "core/errors.h"

#include <CGAL/Delaunay_triangulation_3.h>
#include <CGAL/Delaunay_triangulation_cell_base_3.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_cell_base_with_info_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

namespace scalemesh {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_3<int32_t, Kernel>;
using Cb = CGAL::Triangulation_cell_base_with_info_3<int8_t, Kernel, CGAL::Delaunay_triangulation_cell_base_3<Kernel>>;
using Tds = CGAL::Triangulation_data_structure_3<Vb, Cb>;
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

enum class Verdict { inserted, small, filler, surface, other };

// Holds the triangulation and the surface while points are inserted.
class ConditionalDelaunay {
public:
    ConditionalDelaunay(const SurfaceMesh& surface, const std::vector<OffsetPoint>& points,
                        const InsertionParams& params)
        : surface_(surface), points_(points), params_(params), n_(static_cast<int32_t>(surface.points.size()))
    {
        for (const auto& e : params.protected_edges) protected_edges_.insert(edge_key(e[0], e[1]));
        barrier_.reserve(surface.triangles.size());
        for (const Triangle& tri : surface.triangles) barrier_.emplace(make_key(tri[0], tri[1], tri[2]), tri);
    }

    void insert_surface()
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
        find_quads();
    }

    // A surface quad (a, b, c, d) split along (a, c) whose four points are
    // (nearly) cospherical often comes out of the Delaunay triangulation split
    // along (b, d) instead. Such a pair of triangles cannot appear later (an
    // insertion never creates a facet between old vertices), so the stage
    // takes the Delaunay facets (a, b, d) and (b, c, d) as stand-ins: they
    // separate inside from outside like the quad, are protected like surface
    // triangles, and the tets at (b, d) on the inner side are re-triangulated
    // onto the quad afterwards (repair_surface_quads).
    void find_quads()
    {
        std::vector<int32_t> missing;
        for (size_t t = 0; t < surface_.triangles.size(); ++t) {
            const Triangle& tri = surface_.triangles[t];
            if (!has_facet(surface_vertex_[tri[0]], surface_vertex_[tri[1]], surface_vertex_[tri[2]]))
                missing.push_back(static_cast<int32_t>(t));
        }
        std::unordered_map<uint64_t, int32_t> missing_edge; // directed edge -> missing triangle
        auto edge_key = [](int32_t u, int32_t v) { return (uint64_t(uint32_t(u)) << 32) | uint32_t(v); };
        for (int32_t t : missing)
            for (int e = 0; e < 3; ++e)
                missing_edge[edge_key(surface_.triangles[t][e], surface_.triangles[t][(e + 1) % 3])] = t;
        std::vector<char> used(surface_.triangles.size(), 0);
        for (int32_t t : missing) {
            if (used[t]) continue;
            const Triangle& tri = surface_.triangles[t];
            for (int e = 0; e < 3; ++e) {
                // tri = (a, b, c) with the shared edge c -> a; the other triangle has a -> c.
                const int32_t a = tri[(e + 2) % 3], b = tri[e], c = tri[(e + 1) % 3];
                const auto it = missing_edge.find(edge_key(a, c));
                if (it == missing_edge.end() || used[it->second]) continue;
                const Triangle& other = surface_.triangles[it->second];
                int32_t d = -1;
                for (int32_t v : other)
                    if (v != a && v != c) d = v;
                const Vertex_handle va = surface_vertex_[a], vb = surface_vertex_[b], vc = surface_vertex_[c],
                                    vd = surface_vertex_[d];
                if (!has_facet(va, vb, vd) || !has_facet(vb, vc, vd)) continue;
                used[t] = used[it->second] = 1;
                quads_.push_back({a, b, c, d});
                quad_triangles_.emplace_back(t, it->second);
                barrier_.emplace(make_key(a, b, d), Triangle{a, b, d});
                barrier_.emplace(make_key(b, c, d), Triangle{b, c, d});
                break;
            }
        }
    }

    // Algorithm 5: layer by layer, node by node, `passes` times over the
    // points not yet inserted.
    void insert_layers(InsertionResult& result)
    {
        int max_layer = 0;
        for (const OffsetPoint& p : points_) max_layer = std::max(max_layer, p.layer);
        std::vector<std::vector<int32_t>> by_layer(max_layer + 1);
        for (size_t k = 0; k < points_.size(); ++k) by_layer[points_[k].layer].push_back(static_cast<int32_t>(k));

        verdict_.assign(points_.size(), Verdict::other);
        std::vector<char> done(points_.size(), 0);
        for (int pass = 0; pass < std::max(1, params_.passes); ++pass) {
            bool any = false;
            for (int m = 1; m <= max_layer; ++m)
                for (int32_t k : by_layer[m]) {
                    if (done[k]) continue;
                    verdict_[k] = try_insert(k);
                    if (verdict_[k] == Verdict::inserted) done[k] = 1, any = true;
                }
            if (!any) break;
        }
        for (Verdict v : verdict_) {
            result.inserted += v == Verdict::inserted;
            result.rejected_small += v == Verdict::small;
            result.rejected_filler += v == Verdict::filler;
            result.rejected_surface += v == Verdict::surface;
            result.rejected_other += v == Verdict::other;
        }
    }

    // Exterior removal by the sides of the surface triangles, then the output.
    void classify(InsertionResult& result)
    {
        for (auto c = dt_.all_cells_begin(); c != dt_.all_cells_end(); ++c) c->info() = dt_.is_infinite(c) ? 0 : -1;

        std::vector<Cell_handle> stack;
        std::vector<char> in_quad(n_, 0);
        for (const auto& q : quads_)
            for (int32_t v : q) in_quad[v] = 1;
        for (size_t t = 0; t < surface_.triangles.size(); ++t) {
            const Triangle& tri = surface_.triangles[t];
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
        result.quads = quads_;
        while (!stack.empty()) {
            const Cell_handle c = stack.back();
            stack.pop_back();
            for (int i = 0; i < 4; ++i) {
                if (is_surface_facet(c, i)) continue;
                const Cell_handle nb = c->neighbor(i);
                if (nb->info() == -1) {
                    nb->info() = c->info();
                    stack.push_back(nb);
                }
            }
        }

        result.points.assign(surface_.points.begin(), surface_.points.end());
        result.source.resize(n_);
        for (int32_t i = 0; i < n_; ++i) result.source[i] = i;
        std::unordered_map<int32_t, int32_t> index; // triangulation info -> output point
        for (auto c = dt_.finite_cells_begin(); c != dt_.finite_cells_end(); ++c) {
            if (c->info() != 1) continue;
            Tet tet;
            for (int i = 0; i < 4; ++i) {
                const int32_t id = c->vertex(i)->info();
                if (id < n_) {
                    tet[i] = id;
                    continue;
                }
                auto [it, fresh] = index.emplace(id, static_cast<int32_t>(result.points.size()));
                if (fresh) {
                    result.points.push_back(points_[id - n_].position);
                    result.source.push_back(id);
                }
                tet[i] = it->second;
            }
            result.tets.push_back(tet); // CGAL cells are positively oriented
        }
        result.unused = result.inserted - static_cast<int64_t>(index.size());
    }

private:
    bool has_facet(Vertex_handle a, Vertex_handle b, Vertex_handle c) const
    {
        Cell_handle cell;
        int i, j, k;
        return dt_.is_facet(a, b, c, cell, i, j, k);
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
        Cell_handle c;
        int i, j, k;
        if (!dt_.is_facet(surface_vertex_[tri[0]], surface_vertex_[tri[1]], surface_vertex_[tri[2]], c, i, j, k))
            return false;
        const int l = 6 - i - j - k;
        const Cell_handle other = c->neighbor(l);
        int8_t side_c = 0;
        if (!dt_.is_infinite(c)) {
            // The opposite vertex is inside exactly when (a, b, c, q) is negatively oriented.
            const auto o = CGAL::orientation(to_point(surface_.points[tri[0]]), to_point(surface_.points[tri[1]]),
                                             to_point(surface_.points[tri[2]]), c->vertex(l)->point());
            side_c = o == CGAL::NEGATIVE ? 1 : 0;
        }
        return assign(c, side_c, stack) && assign(other, int8_t(1 - side_c), stack);
    }

    bool assign(Cell_handle c, int8_t side, std::vector<Cell_handle>& stack)
    {
        if (c->info() == -1) {
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

    // The conditions of Algorithm 5 on the conflict cavity of point k:
    // (i) no new tet (k joined to a boundary facet of the cavity) with volume
    //     below min_volume_fraction * spacing^3: such a tet is a sliver the
    //     flips could not repair and a sign of a point that duplicates another;
    // (ii) a filler point joins no surface point (paper section 2.3);
    // and, with protect_surface, no surface triangle that is a facet now is
    // inside the cavity. A Delaunay insertion never creates a facet between
    // old vertices, so a surface triangle destroyed here would stay missing
    // for good; refusing the point instead keeps the surface conforming from
    // the surface-only triangulation onwards, which is what the paper's
    // topology check and local refinement establish after the fact.
    Verdict try_insert(int32_t k)
    {
        const OffsetPoint& op = points_[k];
        const Point p = to_point(op.position);
        Delaunay::Locate_type lt;
        int li, lj;
        const Cell_handle c = dt_.locate(p, lt, li, lj, hint_);
        if (lt == Delaunay::VERTEX || lt == Delaunay::OUTSIDE_CONVEX_HULL || lt == Delaunay::OUTSIDE_AFFINE_HULL)
            return Verdict::other;

        boundary_.clear();
        cells_.clear();
        internal_.clear();
        dt_.find_conflicts(p, c, std::back_inserter(boundary_), std::back_inserter(cells_),
                           std::back_inserter(internal_));

        if (params_.protect_surface)
            for (const Facet& f : internal_)
                if (is_surface_facet(f.first, f.second)) return Verdict::surface;

        const double limit = 6.0 * params_.min_volume_fraction * op.spacing * op.spacing * op.spacing;
        for (const Facet& f : boundary_) {
            const Cell_handle fc = f.first;
            Vec3 v[3];
            int32_t ids[3];
            bool finite = true;
            int j = 0;
            for (int i = 0; i < 4; ++i) {
                if (i == f.second) continue;
                const Vertex_handle vh = fc->vertex(i);
                if (dt_.is_infinite(vh)) {
                    finite = false;
                    break;
                }
                if (op.filler && vh->info() < n_) return Verdict::filler;
                const Point& q = vh->point();
                ids[j] = vh->info();
                v[j++] = {q.x(), q.y(), q.z()};
            }
            if (!finite) continue;
            if (touches_protected_edge(ids)) return Verdict::surface;
            if (std::abs(tet_volume6(v[0], v[1], v[2], op.position)) < limit) return Verdict::small;
        }

        const Vertex_handle v =
            dt_.insert_in_hole(p, cells_.begin(), cells_.end(), boundary_.front().first, boundary_.front().second);
        v->info() = n_ + k;
        hint_ = v->cell();
        return Verdict::inserted;
    }

    static uint64_t edge_key(int32_t u, int32_t v)
    {
        if (u > v) std::swap(u, v);
        return (uint64_t(uint32_t(u)) << 32) | uint32_t(v);
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
    const std::vector<OffsetPoint>& points_;
    const InsertionParams& params_;
    const int32_t n_;
    Delaunay dt_;
    std::vector<Vertex_handle> surface_vertex_;
    std::unordered_map<TriangleKey, Triangle, TriangleKeyHash> barrier_; // surface triangles and quad stand-ins, oriented outwards
    std::vector<std::array<int32_t, 4>> quads_;
    std::vector<std::pair<int32_t, int32_t>> quad_triangles_;
    std::vector<Verdict> verdict_;
    Cell_handle hint_;
    std::vector<Facet> boundary_, internal_;
    std::vector<Cell_handle> cells_;
};

} // namespace

InsertionResult insert_and_classify(const SurfaceMesh& surface, const std::vector<OffsetPoint>& points,
                                    const InsertionParams& params)
{
    InsertionResult result;
    ConditionalDelaunay cd(surface, points, params);
    auto t0 = Clock::now();
    cd.insert_surface();
    cd.insert_layers(result);
    result.seconds_insertion = seconds_since(t0);
    t0 = Clock::now();
    cd.classify(result);
    result.seconds_classify = seconds_since(t0);
    return result;
}

} // namespace scalemesh
