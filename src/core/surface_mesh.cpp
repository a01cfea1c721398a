#include "core/surface_mesh.h"

#include "core/adjacency.h"
#include "core/errors.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <numeric>
#include <sstream>
#include <unordered_map>

namespace scalemesh {

namespace {

struct DirectedEdge {
    int32_t a, b;     // as traversed by the triangle
    int32_t triangle;
    int32_t lo() const { return std::min(a, b); }
    int32_t hi() const { return std::max(a, b); }
};

std::vector<DirectedEdge> sorted_directed_edges(const SurfaceMesh& mesh)
{
    std::vector<DirectedEdge> edges;
    edges.reserve(mesh.triangles.size() * 3);
    for (int32_t f = 0; f < static_cast<int32_t>(mesh.triangles.size()); ++f) {
        const Triangle& t = mesh.triangles[f];
        for (int k = 0; k < 3; ++k) edges.push_back({t[k], t[(k + 1) % 3], f});
    }
    std::sort(edges.begin(), edges.end(), [](const DirectedEdge& p, const DirectedEdge& q) {
        return p.lo() != q.lo() ? p.lo() < q.lo() : (p.hi() != q.hi() ? p.hi() < q.hi() : p.triangle < q.triangle);
    });
    return edges;
}

// The sum of term(triangle) over the triangles, in parallel: the range is
// split into the same blocks whatever the thread count and each block is
// summed in order, so the result is the same to the last bit on any number
// of threads.
template <class Term>
double sum_over_triangles(const SurfaceMesh& mesh, const Term& term)
{
    return tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, mesh.triangles.size(), 16384), 0.0,
        [&](const tbb::blocked_range<size_t>& range, double sum) {
            double block = 0;
            for (size_t f = range.begin(); f != range.end(); ++f) block += term(mesh.triangles[f]);
            return sum + block;
        },
        std::plus<>{});
}

int32_t find_root(std::vector<int32_t>& parent, int32_t i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

} // namespace

double signed_volume(const SurfaceMesh& mesh)
{
    const double six_volume = sum_over_triangles(mesh, [&](const Triangle& t) {
        return dot(mesh.points[t[0]], cross(mesh.points[t[1]], mesh.points[t[2]]));
    });
    return six_volume / 6.0;
}

namespace {

// The triangles of v's fan that hold the edge {v, w}, and how they traverse it.
struct FanEdge {
    int32_t w;
    int32_t triangle;
    bool outgoing; // the triangle runs v -> w
};

// Directed fan edges of vertex v, sorted by the other end.
void fan_edges(const SurfaceMesh& mesh, const VertexTable& fans, int32_t v, std::vector<FanEdge>& out)
{
    out.clear();
    for (const int32_t* f = fans.begin(v); f != fans.end(v); ++f) {
        const Triangle& t = mesh.triangles[*f];
        for (int k = 0; k < 3; ++k) {
            if (t[k] != v) continue;
            out.push_back({t[(k + 1) % 3], *f, true});
            out.push_back({t[(k + 2) % 3], *f, false});
        }
    }
    std::sort(out.begin(), out.end(), [](const FanEdge& a, const FanEdge& b) {
        return a.w != b.w ? a.w < b.w : a.triangle < b.triangle;
    });
}

} // namespace

std::vector<int32_t> triangle_components(const SurfaceMesh& mesh, int32_t* count)
{
    const auto nt = static_cast<int32_t>(mesh.triangles.size());
    std::vector<int32_t> parent(nt);
    std::iota(parent.begin(), parent.end(), 0);
    const VertexTable fans = vertex_triangles(mesh);
    std::vector<FanEdge> edges;
    for (int32_t v = 0; v < static_cast<int32_t>(mesh.points.size()); ++v) {
        fan_edges(mesh, fans, v, edges);
        // Triangles sharing the edge {v, w} are adjacent in the sorted list.
        for (size_t i = 1; i < edges.size(); ++i)
            if (edges[i].w == edges[i - 1].w && edges[i].w > v) {
                const int32_t ra = find_root(parent, edges[i].triangle);
                const int32_t rb = find_root(parent, edges[i - 1].triangle);
                if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
            }
    }
    std::vector<int32_t> label(nt, -1), root_label(nt, -1);
    int32_t n = 0;
    for (int32_t f = 0; f < nt; ++f) {
        const int32_t r = find_root(parent, f);
        if (root_label[r] < 0) root_label[r] = n++;
        label[f] = root_label[r];
    }
    if (count) *count = n;
    return label;
}

void bounding_box(const std::vector<Vec3>& points, Vec3& lo, Vec3& hi)
{
    const double inf = std::numeric_limits<double>::infinity();
    lo = {inf, inf, inf};
    hi = {-inf, -inf, -inf};
    for (const Vec3& p : points)
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], p[k]);
            hi[k] = std::max(hi[k], p[k]);
        }
}

void bounding_box(const SurfaceMesh& mesh, Vec3& lo, Vec3& hi)
{
    bounding_box(mesh.points, lo, hi);
}

namespace {

struct FanCounts {
    int64_t edges = 0, boundary = 0, nonmanifold_edges = 0, misoriented = 0, nonmanifold_vertices = 0;
};

using Joins = tbb::enumerable_thread_specific<std::vector<std::pair<int32_t, int32_t>>>;

// Whether the link of vertex v (the far edge of each fan triangle, directed
// as the triangle runs) is a single cycle: each link vertex starts exactly
// one link edge and the walk along them visits all. Where it holds at every
// vertex, every edge {v, w} has one triangle running v -> w and one running
// w -> v: the surface is closed, manifold and consistently oriented.
bool link_is_one_cycle(const SurfaceMesh& mesh, const VertexTable& fans, int32_t v,
                       std::vector<std::pair<int32_t, int32_t>>& link)
{
    link.clear();
    for (const int32_t* f = fans.begin(v); f != fans.end(v); ++f) {
        const Triangle& t = mesh.triangles[*f];
        const int k = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
        link.emplace_back(t[(k + 1) % 3], t[(k + 2) % 3]);
    }
    std::sort(link.begin(), link.end());
    if (std::adjacent_find(link.begin(), link.end(), [](const auto& a, const auto& b) { return a.first == b.first; }) !=
        link.end())
        return false;
    int32_t cur = link.front().first;
    size_t steps = 0;
    do {
        auto it = std::lower_bound(link.begin(), link.end(), std::make_pair(cur, INT32_MIN));
        if (it == link.end() || it->first != cur) return false;
        cur = it->second;
        ++steps;
    } while (cur != link.front().first && steps <= link.size());
    return steps == link.size();
}

// Edges and vertices are judged locally, from each vertex's fan: an edge
// {v, w} (counted at its lower end) is manifold and consistently oriented
// when exactly one fan triangle runs v -> w and one runs w -> v; a vertex
// is manifold when its link edges form a single cycle.
// The vertices are judged in parallel; their counts are integers, so the
// sums do not depend on the split.
// When `joins` is given the same pass lists, for the components, the pairs
// of triangles that share an edge (consecutive ones where more than two do),
// as triangle_components joins them.
FanCounts fan_counts(const SurfaceMesh& mesh, const VertexTable& fans, Joins* joins)
{
    const auto judge = [&](const tbb::blocked_range<int32_t>& range, FanCounts counts) {
        std::vector<FanEdge> edges;
        std::vector<std::pair<int32_t, int32_t>> link;
        auto* join = joins ? &joins->local() : nullptr;
        for (int32_t v = range.begin(); v != range.end(); ++v) {
            if (fans.size(v) == 0) continue;
            fan_edges(mesh, fans, v, edges);
            for (size_t i = 0; i < edges.size();) {
                size_t j = i;
                int outgoing = 0;
                while (j < edges.size() && edges[j].w == edges[i].w) outgoing += edges[j++].outgoing;
                if (edges[i].w > v) {
                    if (join)
                        for (size_t k = i + 1; k < j; ++k) join->emplace_back(edges[k].triangle, edges[k - 1].triangle);
                    const size_t n = j - i;
                    ++counts.edges;
                    if (n == 1) ++counts.boundary;
                    else if (n > 2) ++counts.nonmanifold_edges;
                    else if (outgoing != 1) ++counts.misoriented;
                }
                i = j;
            }

            const bool ok = link_is_one_cycle(mesh, fans, v, link);
            if (!ok) ++counts.nonmanifold_vertices;
        }
        return counts;
    };
    return tbb::parallel_reduce(
        tbb::blocked_range<int32_t>(0, static_cast<int32_t>(mesh.points.size()), 4096), FanCounts{}, judge,
        [](FanCounts a, const FanCounts& b) {
            a.edges += b.edges;
            a.boundary += b.boundary;
            a.nonmanifold_edges += b.nonmanifold_edges;
            a.misoriented += b.misoriented;
            a.nonmanifold_vertices += b.nonmanifold_vertices;
            return a;
        });
}

// Triangles with a repeated vertex.
int64_t degenerate_triangles(const SurfaceMesh& mesh)
{
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, mesh.triangles.size(), 16384), int64_t{0},
        [&](const tbb::blocked_range<size_t>& range, int64_t count) {
            for (size_t f = range.begin(); f != range.end(); ++f) {
                const Triangle& t = mesh.triangles[f];
                count += t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
            }
            return count;
        },
        std::plus<>{});
}

// The surface is closed, manifold and oriented when every used vertex's
// link is one cycle and no triangle repeats a vertex (link_is_one_cycle).
// Vertices in parallel.
bool links_are_cycles(const SurfaceMesh& mesh, const VertexTable& fans)
{
    return tbb::parallel_reduce(
        tbb::blocked_range<int32_t>(0, static_cast<int32_t>(mesh.points.size()), 4096), true,
        [&](const tbb::blocked_range<int32_t>& range, bool ok) {
            std::vector<std::pair<int32_t, int32_t>> link;
            for (int32_t v = range.begin(); ok && v != range.end(); ++v)
                ok = fans.size(v) == 0 || link_is_one_cycle(mesh, fans, v, link);
            return ok;
        },
        std::logical_and<>{});
}

} // namespace

// The usual input is closed and manifold; for it one pass over the links
// settles every count (each edge has two triangles: E = 3T/2) and the
// components are those of the vertices, since triangles that share a
// vertex are joined through its fan. Otherwise every edge and vertex is
// judged from its fan and the triangles are joined across their edges.
SurfaceFacts surface_facts(const SurfaceMesh& mesh)
{
    SurfaceFacts facts;
    facts.triangles = static_cast<int64_t>(mesh.triangles.size());
    facts.area = 0.5 * sum_over_triangles(mesh, [&](const Triangle& t) {
        const Vec3& a = mesh.points[t[0]];
        return norm(cross(mesh.points[t[1]] - a, mesh.points[t[2]] - a));
    });
    facts.signed_volume = signed_volume(mesh);
    facts.degenerate_triangles = degenerate_triangles(mesh);

    const VertexTable fans = vertex_triangles(mesh);
    const auto nv = static_cast<int32_t>(mesh.points.size());
    for (int32_t v = 0; v < nv; ++v) facts.vertices += fans.size(v) > 0;

    if (facts.degenerate_triangles == 0 && links_are_cycles(mesh, fans)) {
        facts.edges = 3 * facts.triangles / 2;
        std::vector<int32_t> parent(nv);
        std::iota(parent.begin(), parent.end(), 0);
        const auto join = [&](int32_t a, int32_t b) {
            const int32_t ra = find_root(parent, a), rb = find_root(parent, b);
            if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
        };
        for (const Triangle& t : mesh.triangles) {
            join(t[0], t[1]);
            join(t[0], t[2]);
        }
        for (int32_t v = 0; v < nv; ++v) facts.components += fans.size(v) > 0 && find_root(parent, v) == v;
    } else {
        Joins joins;
        const FanCounts counts = fan_counts(mesh, fans, &joins);
        facts.edges = counts.edges;
        facts.boundary_edges = counts.boundary;
        facts.nonmanifold_edges = counts.nonmanifold_edges;
        facts.misoriented_edges = counts.misoriented;
        facts.nonmanifold_vertices = counts.nonmanifold_vertices;

        const auto nt = static_cast<int32_t>(mesh.triangles.size());
        std::vector<int32_t> parent(nt);
        std::iota(parent.begin(), parent.end(), 0);
        for (const auto& join : joins)
            for (const auto& [a, b] : join) {
                const int32_t ra = find_root(parent, a), rb = find_root(parent, b);
                if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
            }
        for (int32_t f = 0; f < nt; ++f) facts.components += find_root(parent, f) == f;
    }
    facts.euler_characteristic = facts.vertices - facts.edges + facts.triangles;
    return facts;
}

bool orient_outward(SurfaceMesh& mesh)
{
    if (signed_volume(mesh) >= 0) return false;
    for (Triangle& t : mesh.triangles) std::swap(t[1], t[2]);
    return true;
}

void require_closed_manifold(const SurfaceMesh& mesh, const std::string& what)
{
    require_closed_manifold(mesh, vertex_triangles(mesh), what);
}

// Only the local judgements of surface_facts: no components, area or volume.
void require_closed_manifold(const SurfaceMesh& mesh, const VertexTable& fans, const std::string& what)
{
    if (mesh.triangles.empty())
        throw InputError(what + " has no triangles", "check that the input holds a closed surface");
    const int64_t degenerate = degenerate_triangles(mesh);
    if (degenerate == 0 && links_are_cycles(mesh, fans)) return;

    // Count what is wrong, for the message.
    const FanCounts counts = fan_counts(mesh, fans, nullptr);

    std::ostringstream msg;
    msg << what << " is not a closed, oriented 2-manifold: " << counts.boundary << " open edges, "
        << counts.nonmanifold_edges << " non-manifold edges, " << counts.misoriented
        << " inconsistently oriented edges, " << counts.nonmanifold_vertices << " non-manifold vertices, "
        << degenerate << " degenerate triangles";
    // Name where the first open edges are, so the user can find them.
    const std::vector<DirectedEdge> edges = sorted_directed_edges(mesh);
    int shown = 0;
    for (size_t i = 0; i < edges.size() && shown < 3;) {
        size_t j = i;
        while (j < edges.size() && edges[j].lo() == edges[i].lo() && edges[j].hi() == edges[i].hi()) ++j;
        if (j - i != 2) {
            const Vec3 p = 0.5 * (mesh.points[edges[i].a] + mesh.points[edges[i].b]);
            msg << (shown == 0 ? "; first at (" : ", (") << p.x << ", " << p.y << ", " << p.z << ")";
            ++shown;
        }
        i = j;
    }
    throw InputError(msg.str(), "the method needs a closed surface: repair it (fill holes, remove "
                                "duplicate faces) or start from the segmentation image");
}

} // namespace scalemesh
