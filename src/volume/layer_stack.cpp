#include "volume/layer_stack.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "core/face_measures.h"
#include "core/nearest_triangle.h"
#include "volume/layer_prisms.h"
#include "volume/self_intersections.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace scalemesh {

std::array<Tet, 3> prism_split(const std::array<int32_t, 3>& p, const std::array<int32_t, 3>& q,
                               const std::array<int32_t, 3>& column)
{
    // Local corners 0..2 by increasing column id.
    std::array<int, 3> o{0, 1, 2};
    std::sort(o.begin(), o.end(), [&](int a, int b) { return column[a] < column[b]; });
    // Corner ids: 0..2 the bottom, 3..5 the top, in local order; the cuts
    // are p_o0-q_o1, p_o0-q_o2 and p_o1-q_o2.
    const std::array<std::array<int, 4>, 3> local{{{o[0], o[1], o[2], 3 + o[2]},
                                                   {o[0], o[1], 3 + o[1], 3 + o[2]},
                                                   {o[0], 3 + o[0], 3 + o[1], 3 + o[2]}}};
    // A right prism over p (whose normal, +z here, points away from q).
    static const Vec3 ideal[6] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, -1}, {1, 0, -1}, {0, 1, -1}};
    const auto id = [&](int corner) { return corner < 3 ? p[corner] : q[corner - 3]; };
    std::array<Tet, 3> tets;
    for (int k = 0; k < 3; ++k) {
        std::array<int, 4> c = local[k];
        if (tet_volume6(ideal[c[0]], ideal[c[1]], ideal[c[2]], ideal[c[3]]) < 0) std::swap(c[2], c[3]);
        tets[k] = {id(c[0]), id(c[1]), id(c[2]), id(c[3])};
    }
    return tets;
}

namespace {

// A prism's centroid: its split's tets' centroids weighted by their volumes.
Vec3 split_centroid(const std::array<Tet, 3>& tets, const std::vector<Vec3>& at)
{
    Vec3 sum;
    double total = 0;
    for (const Tet& t : tets) {
        const double v = tet_volume6(at[t[0]], at[t[1]], at[t[2]], at[t[3]]);
        sum += v * (at[t[0]] + at[t[1]] + at[t[2]] + at[t[3]]) / 4;
        total += v;
    }
    return total != 0 ? sum / total : (at[tets[0][0]] + at[tets[2][3]]) / 2;
}

// Whether the split of a prism is good: each tet positive and at least
// `fraction` of the three's volume, and the prism star-shaped from its
// centroid as the export asks of a prism cell (layer_prisms.h).
bool good_split(const std::array<Tet, 3>& tets, const std::vector<Vec3>& at, double fraction, bool star = true)
{
    double v[3], total = 0;
    Vec3 centroid;
    for (int k = 0; k < 3; ++k) {
        const Tet& t = tets[k];
        v[k] = tet_volume6(at[t[0]], at[t[1]], at[t[2]], at[t[3]]);
        total += v[k];
        centroid += v[k] * (at[t[0]] + at[t[1]] + at[t[2]] + at[t[3]]) / 4;
    }
    if (!(total > 0) || v[0] < fraction * total || v[1] < fraction * total || v[2] < fraction * total) return false;
    if (!star) return true;
    centroid = centroid / total;
    // The prism's faces: the tets' faces not shared between two of them.
    std::array<Triangle, 12> faces;
    std::array<std::array<int32_t, 3>, 12> keys;
    for (int k = 0; k < 12; ++k) {
        faces[k] = tet_face(tets[k / 4], k % 4);
        keys[k] = faces[k];
        std::sort(keys[k].begin(), keys[k].end());
    }
    static const double min_sine = std::sin(kStarAngleDeg * M_PI / 180);
    for (int k = 0; k < 12; ++k) {
        bool shared = false;
        for (int j = 0; j < 12 && !shared; ++j) shared = j / 4 != k / 4 && keys[j] == keys[k];
        if (!shared && !faces_centre(at[faces[k][0]], at[faces[k][1]], at[faces[k][2]], centroid, min_sine))
            return false;
    }
    return true;
}

// The wall triangle (index into `walls`) across each edge of a wall triangle.
struct EdgeFaces {
    std::unordered_map<uint64_t, int32_t> face_of; // directed edge (a, b) -> the triangle with it
    int32_t other(int32_t a, int32_t b) const
    {
        const auto it = face_of.find(directed_edge_key(b, a));
        return it == face_of.end() ? -1 : it->second;
    }
};

EdgeFaces wall_edge_faces(const SurfaceMesh& surface, const std::vector<int32_t>& walls)
{
    EdgeFaces out;
    for (size_t w = 0; w < walls.size(); ++w) {
        const Triangle& t = surface.triangles[walls[w]];
        for (int k = 0; k < 3; ++k) out.face_of[directed_edge_key(t[k], t[(k + 1) % 3])] = static_cast<int32_t>(w);
    }
    return out;
}

// The core's faces off the wall (the caps inside their last rings), for
// the clearance of the columns' tops: too_near(x) when x is nearer one of
// them than `clearance` times that face's longest edge. The faces are
// binned in a uniform grid, each in every cell its bounding box grown by
// its reach overlaps (the cells as wide as the widest such box, so at most
// two cells a side), and a point looks at the faces of its own cell alone.
// The faces' points are surface points, which never move.
class CapFill {
public:
    CapFill(const std::vector<Vec3>& points, const std::vector<Triangle>& faces, double clearance)
        : points_(points), faces_(faces)
    {
        for (const Triangle& f : faces) {
            const Vec3 &a = points[f[0]], &b = points[f[1]], &c = points[f[2]];
            const double reach2 = clearance * clearance * std::max({norm2(b - a), norm2(c - b), norm2(a - c)});
            reach2_.push_back(reach2);
            cell_ = std::max(cell_, 2 * std::sqrt(reach2) + std::max({norm(b - a), norm(c - b), norm(a - c)}));
        }
        if (!(cell_ > 0)) return; // every face a point: none is near anything
        for (size_t i = 0; i < faces.size(); ++i) {
            const Triangle& f = faces[i];
            const double reach = std::sqrt(reach2_[i]) * (1 + 1e-9); // past the distance's round-off
            std::array<int64_t, 3> lo, hi;
            for (int k = 0; k < 3; ++k) {
                const double a = points[f[0]][k], b = points[f[1]][k], c = points[f[2]][k];
                lo[k] = index(std::min({a, b, c}) - reach);
                hi[k] = index(std::max({a, b, c}) + reach);
            }
            for (int64_t x = lo[0]; x <= hi[0]; ++x)
                for (int64_t y = lo[1]; y <= hi[1]; ++y)
                    for (int64_t z = lo[2]; z <= hi[2]; ++z) cells_[key(x, y, z)].push_back(int32_t(i));
        }
    }
    bool empty() const { return cells_.empty(); }
    bool too_near(const Vec3& x) const
    {
        if (cells_.empty()) return false;
        const auto it = cells_.find(key(index(x[0]), index(x[1]), index(x[2])));
        if (it == cells_.end()) return false;
        for (int32_t i : it->second) {
            const Triangle& f = faces_[i];
            if (point_triangle_distance2(x, points_[f[0]], points_[f[1]], points_[f[2]]) < reach2_[i]) return true;
        }
        return false;
    }

private:
    int64_t index(double x) const { return static_cast<int64_t>(std::floor(x / cell_)); }
    static uint64_t key(int64_t x, int64_t y, int64_t z)
    {
        return (uint64_t(x) & 0x1FFFFF) | (uint64_t(y) & 0x1FFFFF) << 21 | (uint64_t(z) & 0x1FFFFF) << 42;
    }

    const std::vector<Vec3>& points_;
    const std::vector<Triangle>& faces_;
    std::vector<double> reach2_;
    double cell_ = 0;
    std::unordered_map<uint64_t, std::vector<int32_t>> cells_;
};

} // namespace

LayerStack build_layer_stack(const SurfaceMesh& surface, const FeatureSize& sizing, const LayerColumns& columns,
                             const LayerStackParams& params)
{
    const int32_t n = static_cast<int32_t>(surface.points.size());
    const int32_t L = columns.layers;
    if (columns.inward.size() != size_t(n) || columns.dist.size() != size_t(n) * L)
        throw InputError("volume: the layer columns do not match the surface", "build them on the meshed surface");
    LayerStack stack;
    stack.layers = L;
    stack.surface_points = n;
    const bool patched = surface.triangle_patch.size() == surface.triangles.size();
    std::vector<int32_t> walls;
    for (size_t f = 0; f < surface.triangles.size(); ++f)
        if (!patched || surface.triangle_patch[f] == 0) walls.push_back(static_cast<int32_t>(f));

    // Columns of the wall nodes, numbered in node order; a rim node's column
    // is its cap's nodes.
    if (!params.rim_columns.empty() && params.rim_columns.size() != size_t(n) * L)
        throw InputError("volume: the rim columns do not match the surface", "take them from ring_caps");
    stack.rim_columns = params.rim_columns;
    const auto fixed = [&](int32_t v) { return !params.rim_columns.empty() && params.rim_columns[size_t(v) * L] >= 0; };
    stack.first.assign(n, -1);
    for (int32_t f : walls)
        for (int32_t v : surface.triangles[f]) stack.first[v] = 0;
    int32_t count = 0;
    for (int32_t v = 0; v < n; ++v) {
        if (stack.first[v] < 0) continue;
        if (L > 0 && fixed(v)) {
            stack.first[v] = -1;
            continue;
        }
        stack.first[v] = count;
        count += L;
    }
    stack.points.resize(count);
    if (L == 0) return stack;

    // A wall node whose normal could not be made to point into the volume
    // (no column of its own) borrows one: the mean direction and distances
    // of its neighbours' columns, passed on from node to node; the rounds
    // below shorten it where that makes poor prisms.
    const VertexTable neighbours = vertex_neighbours(surface);
    LayerColumns own = columns;
    const auto has_column = [&](int32_t v) { return own.dist[size_t(v) * L + L - 1] > 0; };
    for (bool missing = true; missing;) {
        missing = false;
        bool lent = false;
        for (int32_t v = 0; v < n; ++v) {
            if (stack.first[v] < 0 || has_column(v)) continue;
            Vec3 direction;
            std::vector<double> dist(L, 0.0);
            int count_from = 0;
            for (const int32_t* u = neighbours.begin(v); u != neighbours.end(v); ++u) {
                if (!has_column(*u) || stack.first[*u] < 0) continue;
                direction += own.inward[*u];
                for (int32_t m = 0; m < L; ++m) dist[m] += own.dist[size_t(*u) * L + m];
                ++count_from;
            }
            if (count_from == 0 || !(norm2(direction) > 0)) {
                missing = true;
                continue;
            }
            own.inward[v] = normalized(direction);
            for (int32_t m = 0; m < L; ++m) own.dist[size_t(v) * L + m] = dist[m] / count_from;
            ++stack.borrowed_columns;
            lent = true;
        }
        if (missing && !lent)
            throw InputError("volume: some wall nodes have no layer column, nor a neighbour with one (their normals "
                             "could not be made to point into the volume)",
                             "use [volume] layers = \"delaunay\", which leaves such nodes without layers, or smooth "
                             "the surface more");
    }
    stack.point_generator.resize(count);
    stack.point_layer.resize(count);
    for (int32_t v = 0; v < n; ++v)
        for (int32_t m = 1; m <= L && stack.first[v] >= 0; ++m) {
            stack.point_generator[stack.first[v] + m - 1] = v;
            stack.point_layer[stack.first[v] + m - 1] = m;
        }
    // Each column starts at its full height, cut to half the local diameter.
    stack.scale.assign(n, 1.0);
    for (int32_t v = 0; v < n; ++v) {
        if (stack.first[v] < 0) continue;
        const double reach = (own.repaired[v] ? sizing.d[v] : sizing.D[v]) / 2;
        const double top = own.dist[size_t(v) * L + L - 1];
        if (reach > 0 && top > reach) stack.scale[v] = reach / top;
    }
    std::vector<Vec3> at(n + size_t(count)); // surface points, then layer points
    std::copy(surface.points.begin(), surface.points.end(), at.begin());
    for (const Triangle& f : params.core_faces)
        for (int32_t v : f)
            if (v < 0 || v >= n)
                throw std::invalid_argument("build_layer_stack: a core face's corner " + std::to_string(v) +
                                            " is not a surface point");
    const CapFill fill(surface.points, params.core_faces, params.min_core_clearance);
    const auto place = [&] {
        tbb::parallel_for(int32_t(0), n, [&](int32_t v) {
            if (stack.first[v] < 0) return;
            const std::vector<double> dist = shortened_column(&own.dist[size_t(v) * L], L, stack.scale[v]);
            for (int32_t m = 1; m <= L; ++m)
                at[n + stack.first[v] + m - 1] = surface.points[v] + dist[m - 1] * own.inward[v];
        });
    };
    const auto point = [&](int32_t v, int32_t m) {
        return m == 0 ? v : stack.first[v] >= 0 ? n + stack.first[v] + m - 1 : params.rim_columns[size_t(v) * L + m - 1];
    };
    const auto split = [&](int32_t f, int32_t m) {
        const Triangle& t = surface.triangles[f];
        return prism_split({point(t[0], m - 1), point(t[1], m - 1), point(t[2], m - 1)},
                           {point(t[0], m), point(t[1], m), point(t[2], m)}, t);
    };

    // Rounds: the nodes of poor prisms and of crossing top triangles are
    // shortened, then every column is limited by its neighbours' (slope).
    //
    // Where shortening does not help (the prism's shape no longer changes
    // as its columns shorten: directions tilted far from a face's normal,
    // as at a voxel ridge, or two of its columns the cap's own), from round
    // relax_round on, a prism is accepted as it is when each tet of its split
    // still holds a fifth of min_tet_fraction of its volume; it need not be
    // star-shaped (the export keeps such a prism as three tets). Next to an
    // opening, star-shaped is not asked from the start. No column is
    // shortened below min_scale of its height: a prism still poor there is
    // left bare (below), not made a sliver.
    std::vector<char> poor(walls.size()), lenient(walls.size(), 0);
    // The side faces: the quad between the prisms of one layer over two
    // wall triangles that share an edge turns with the columns, layer by
    // layer (where the wall curves, the columns' directions part or cross),
    // so its non-orthogonality grows with the layer. Where a side face
    // would be beyond max_side_non_orthogonality_deg, both prisms' columns
    // are shortened (thinner layers turn less), in the rounds before
    // relax_round; never made holes for it. An edge whose first layer is
    // already beyond the bound is left alone: the first layer keeps its
    // thickness, and a skewed pair of wall triangles keeps its angle however
    // thin the layers are.
    const EdgeFaces edges = wall_edge_faces(surface, walls);
    const double side_cosine = std::cos(params.max_side_non_orthogonality_deg * M_PI / 180);
    std::vector<char> side_poor(walls.size(), 0);
    const auto side_face_cosine = [&](size_t w, int32_t o, int32_t a, int32_t b, int32_t m) {
        const Vec3 join = split_centroid(split(walls[o], m), at) - split_centroid(split(walls[w], m), at);
        const Vec3 p0 = at[point(a, m - 1)], p1 = at[point(b, m - 1)], p2 = at[point(b, m)], p3 = at[point(a, m)];
        // The quad's area vector, turned from w's side to o's as the wall
        // triangles lie.
        Vec3 area = cross(p2 - p0, p3 - p1);
        const Triangle &tw = surface.triangles[walls[w]], &to = surface.triangles[walls[o]];
        const Vec3 across = (surface.points[to[0]] + surface.points[to[1]] + surface.points[to[2]]) -
                            (surface.points[tw[0]] + surface.points[tw[1]] + surface.points[tw[2]]);
        if (dot(area, across) < 0) area = -area;
        return face_orthogonality_cosine(area, join, -1.0);
    };
    const auto check_sides = [&](size_t w) {
        const Triangle& t = surface.triangles[walls[w]];
        for (int k = 0; k < 3; ++k) {
            const int32_t a = t[k], b = t[(k + 1) % 3], o = edges.other(a, b);
            if (o < 0 || side_face_cosine(w, o, a, b, 1) < side_cosine) continue;
            for (int32_t m = 2; m <= L; ++m)
                if (side_face_cosine(w, o, a, b, m) < side_cosine) {
                    side_poor[w] = 1;
                    return;
                }
        }
    };
    for (size_t w = 0; w < walls.size(); ++w)
        for (int32_t v : surface.triangles[walls[w]])
            if (stack.first[v] < 0) lenient[w] = 1;
    for (;; ++stack.rounds) {
        place();
        // lenient 1: not star-shaped; 2: also tets of a fifth of the fraction.
        const auto fraction = [&](size_t w) {
            return lenient[w] == 2 ? params.min_tet_fraction / 5 : params.min_tet_fraction;
        };
        const auto check = [&](size_t w) {
            poor[w] = 0;
            for (int32_t m = 1; m <= L && !poor[w]; ++m)
                poor[w] = !good_split(split(walls[w], m), at, fraction(w), lenient[w] == 0);
        };
        tbb::parallel_for(size_t(0), walls.size(), check);
        if (stack.rounds >= params.relax_round)
            for (size_t w = 0; w < walls.size(); ++w) {
                const char was = lenient[w];
                for (char level = 2; poor[w] && level <= 2; ++level)
                    if (lenient[w] < level) lenient[w] = level, check(w);
                if (!poor[w] && lenient[w] != was) ++stack.lenient_prisms;
                else if (poor[w]) lenient[w] = was;
            }
        SurfaceMesh top;
        top.points = at;
        for (int32_t f : walls) {
            const Triangle& t = surface.triangles[f];
            top.triangles.push_back({point(t[0], L), point(t[1], L), point(t[2], L)});
        }
        const SelfIntersections crossing = self_intersections(top, size_t(1) << 20);
        for (const auto& pair : crossing.first) poor[pair[0]] = poor[pair[1]] = 1;
        // A top point just over a cap's fill (a wall node next to an opening,
        // its column nearly in the cap's plane and longer than the rim's
        // columns, drawn in to the cap's last ring) leaves the core only flat
        // tets between them: the columns of the wall triangles around it are
        // shortened too. A rim node's top is the cap's last ring: not asked.
        if (!fill.empty()) {
            std::vector<char> near(n, 0);
            tbb::parallel_for(int32_t(0), n, [&](int32_t v) {
                if (stack.first[v] >= 0) near[v] = fill.too_near(at[point(v, L)]);
            });
            for (size_t w = 0; w < walls.size(); ++w)
                for (int32_t v : surface.triangles[walls[w]])
                    if (near[v]) poor[w] = 1;
        }
        std::fill(side_poor.begin(), side_poor.end(), 0);
        if (stack.rounds < params.relax_round) tbb::parallel_for(size_t(0), walls.size(), check_sides);
        const bool any_poor = std::find(poor.begin(), poor.end(), 1) != poor.end();
        const bool any_side = std::find(side_poor.begin(), side_poor.end(), 1) != side_poor.end();
        if ((!any_poor && !any_side) || stack.rounds == params.max_rounds) break;
        std::vector<char> shorten(n, 0);
        for (size_t w = 0; w < walls.size(); ++w)
            if (poor[w] || side_poor[w])
                for (int32_t v : surface.triangles[walls[w]]) shorten[v] = 1;
        bool shortened = false;
        for (int32_t v = 0; v < n; ++v)
            if (shorten[v] && stack.first[v] >= 0 && stack.scale[v] > params.min_scale)
                stack.scale[v] = std::max(params.min_scale, stack.scale[v] * params.shrink), shortened = true;
        if (!shortened) break; // what is left is bare (below)
        for (bool changed = true; changed;) {
            changed = false;
            for (int32_t v = 0; v < n; ++v) {
                if (stack.first[v] < 0) continue;
                for (const int32_t* u = neighbours.begin(v); u != neighbours.end(v); ++u)
                    if ((stack.first[*u] >= 0 || fixed(*u)) && stack.scale[v] > stack.scale[*u] + params.slope)
                        stack.scale[v] = stack.scale[*u] + params.slope, changed = true;
            }
        }
    }

    // What the rounds could not mend stays without layers: a hole in the
    // stack, which the core fills, bounded by the hole's wall triangles, the
    // side faces of the prisms around it and, along a rim edge, the cap's
    // strip between the edge's two columns (the side its prism would have had).
    std::vector<char> hole(walls.size(), 0);
    for (size_t w = 0; w < walls.size(); ++w)
        if (poor[w]) hole[w] = 1, ++stack.holes;

    // The cap triangles of each rim edge's strip, by the edge's directed key
    // (as the wall triangle has it): those whose corners all lie on the two
    // rim nodes' columns, two per layer.
    std::unordered_map<uint64_t, std::vector<int32_t>> strip;
    if (!params.rim_columns.empty()) {
        std::vector<int32_t> owner(n, -1); // the rim node whose column holds a cap node
        for (int32_t v = 0; v < n; ++v)
            if (fixed(v)) {
                owner[v] = v;
                for (int32_t m = 1; m <= L; ++m) owner[params.rim_columns[size_t(v) * L + m - 1]] = v;
            }
        std::unordered_map<uint64_t, std::vector<int32_t>> by_pair;
        for (size_t f = 0; f < surface.triangles.size(); ++f) {
            if (!patched || surface.triangle_patch[f] == 0) continue;
            const Triangle& t = surface.triangles[f];
            const int32_t a = owner[t[0]], b = owner[t[1]], c = owner[t[2]];
            if (a < 0 || b < 0 || c < 0) continue;
            const int32_t lo = std::min({a, b, c}), hi = std::max({a, b, c});
            if (lo != hi && (a == lo || a == hi) && (b == lo || b == hi) && (c == lo || c == hi))
                by_pair[directed_edge_key(lo, hi)].push_back(static_cast<int32_t>(f));
        }
        for (size_t w = 0; w < walls.size(); ++w) {
            const Triangle& t = surface.triangles[walls[w]];
            for (int k = 0; k < 3; ++k) {
                const int32_t a = t[k], b = t[(k + 1) % 3];
                if (!fixed(a) || !fixed(b)) continue;
                const auto it = by_pair.find(directed_edge_key(std::min(a, b), std::max(a, b)));
                if (it != by_pair.end()) strip[directed_edge_key(a, b)] = it->second;
            }
        }
    }
    const auto check_strips = [&](size_t w) {
        const Triangle& t = surface.triangles[walls[w]];
        for (int k = 0; k < 3; ++k) {
            const int32_t a = t[k], b = t[(k + 1) % 3];
            if (edges.other(a, b) >= 0 || !fixed(a) || !fixed(b)) continue;
            const auto it = strip.find(directed_edge_key(a, b));
            if (it == strip.end() || it->second.size() != size_t(2) * L)
                throw StageError("volume", "wall triangle " + std::to_string(walls[w]) +
                                               " next to an opening has poor prism layers, and the cap's strip along "
                                               "its rim edge " + std::to_string(a) + "-" + std::to_string(b) +
                                               " is not two triangles per layer (" +
                                               std::to_string(it == strip.end() ? 0 : it->second.size()) +
                                               "): the caps must be built with RingParams::prism_columns");
        }
    };
    for (size_t w = 0; w < walls.size(); ++w)
        if (hole[w]) check_strips(w);

    for (int pass = 0;; ++pass) {
        stack.tets.clear(), stack.top.clear(), stack.top_of.clear(), stack.prisms = 0;
        for (size_t w = 0; w < walls.size(); ++w) {
            const int32_t f = walls[w];
            const Triangle& t = surface.triangles[f];
            if (hole[w]) {
                stack.top.push_back(t);
                stack.top_of.push_back(f);
                for (int k = 0; k < 3; ++k)
                    if (const auto it = strip.find(directed_edge_key(t[k], t[(k + 1) % 3]));
                        it != strip.end() && edges.other(t[k], t[(k + 1) % 3]) < 0)
                        for (int32_t c : it->second) stack.top.push_back(surface.triangles[c]), stack.top_of.push_back(f);
                continue;
            }
            for (int32_t m = 1; m <= L; ++m)
                for (const Tet& tet : split(f, m)) stack.tets.push_back(tet);
            stack.top.push_back(Triangle{point(t[0], L), point(t[1], L), point(t[2], L)});
            stack.top_of.push_back(f);
            ++stack.prisms;
            for (int k = 0; k < 3; ++k) {
                const int32_t a = t[k], b = t[(k + 1) % 3];
                const int32_t across = edges.other(a, b);
                if (across < 0 || !hole[across]) continue;
                for (int32_t m = 1; m <= L; ++m) {
                    const std::array<int32_t, 4> quad{point(a, m - 1), point(b, m - 1), point(a, m), point(b, m)};
                    for (const Tet& tet : split(f, m))
                        for (int j = 0; j < 4; ++j) {
                            const Triangle face = tet_face(tet, j);
                            if (std::all_of(face.begin(), face.end(), [&](int32_t x) {
                                    return std::find(quad.begin(), quad.end(), x) != quad.end();
                                }))
                                stack.top.push_back(Triangle{face[0], face[2], face[1]}), stack.top_of.push_back(f);
                        }
                }
            }
        }
        SurfaceMesh boundary;
        boundary.points = at;
        boundary.triangles = stack.top;
        for (const Triangle& t : params.core_faces) boundary.triangles.push_back(t);
        const SelfIntersections crossing = self_intersections(boundary, size_t(1) << 20);
        if (crossing.pairs == 0) break;
        if (pass == 5)
            throw StageError("volume", "the core's boundary inside the prism layers still crosses itself (" +
                                           std::to_string(crossing.pairs) + " pairs of triangles) after " +
                                           std::to_string(pass) + " rounds of leaving their wall triangles bare");
        const auto wall_index = [&](int32_t face) {
            return face < int32_t(stack.top_of.size())
                       ? int32_t(std::lower_bound(walls.begin(), walls.end(), stack.top_of[face]) - walls.begin())
                       : -1;
        };
        for (const auto& pair : crossing.first)
            for (int32_t face : pair)
                if (const int32_t w = wall_index(face); w >= 0 && !hole[w]) hole[w] = 1, ++stack.holes, check_strips(w);
    }
    // The layer points in use (of a node with a prism), renumbered.
    std::vector<int32_t> new_id(at.size(), -1);
    for (int32_t v = 0; v < n; ++v) new_id[v] = v;
    std::vector<char> in_use(n, 0);
    for (size_t w = 0; w < walls.size(); ++w)
        if (!hole[w])
            for (int32_t v : surface.triangles[walls[w]]) in_use[v] = 1;
    std::vector<int32_t> first(n, -1);
    std::vector<Vec3> points;
    std::vector<int32_t> generator, layer;
    for (int32_t v = 0; v < n; ++v) {
        if (stack.first[v] < 0 || !in_use[v]) continue;
        first[v] = static_cast<int32_t>(points.size());
        for (int32_t m = 1; m <= L; ++m) {
            new_id[point(v, m)] = n + static_cast<int32_t>(points.size());
            points.push_back(at[point(v, m)]);
            generator.push_back(v);
            layer.push_back(m);
        }
    }
    for (int32_t v = 0; v < n && !params.rim_columns.empty(); ++v)
        for (int32_t m = 1; m <= L; ++m)
            if (const int32_t c = params.rim_columns[size_t(v) * L + m - 1]; c >= 0) new_id[c] = c;
    const auto renumbered = [&](auto cell) {
        for (int32_t& v : cell) v = new_id[v];
        return cell;
    };

    for (Tet& t : stack.tets) t = renumbered(t);
    for (Triangle& t : stack.top) t = renumbered(t);
    stack.prisms *= L;
    stack.first = std::move(first);
    stack.points = std::move(points);
    stack.point_generator = std::move(generator);
    stack.point_layer = std::move(layer);
    for (int32_t v = 0; v < n; ++v)
        if (stack.first[v] >= 0 && stack.scale[v] < 1) ++stack.shortened_nodes;
    return stack;
}

} // namespace scalemesh
