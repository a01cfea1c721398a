#include "volume/layer_stack.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "volume/layer_prisms.h"
#include "volume/self_intersections.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

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

} // namespace

std::vector<double> shortened_column(const double* dist, int32_t layers, double scale)
{
    std::vector<double> out(dist, dist + layers);
    if (layers == 0 || scale >= 1) return out;
    const double total = scale * dist[layers - 1], first = dist[0];
    std::vector<double> step(layers, total / layers); // uniform, where the first layer no longer fits
    if (layers > 1 && first * layers < total) {
        // first * (1 + r + ... + r^(layers-1)) = total for some r > 1.
        const auto sum = [&](double r) {
            double s = 0, term = first;
            for (int32_t m = 0; m < layers; ++m, term *= r) s += term;
            return s;
        };
        double lo = 1, hi = 2;
        while (sum(hi) < total) hi *= 2;
        for (int i = 0; i < 100; ++i) (sum(0.5 * (lo + hi)) < total ? lo : hi) = 0.5 * (lo + hi);
        double term = first;
        for (int32_t m = 0; m < layers; ++m, term *= 0.5 * (lo + hi)) step[m] = term;
    }
    double at = 0;
    for (int32_t m = 0; m < layers; ++m) out[m] = at += step[m];
    out[layers - 1] = total;
    return out;
}

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
    std::vector<char> poor(walls.size());
    for (;; ++stack.rounds) {
        place();
        tbb::parallel_for(size_t(0), walls.size(), [&](size_t w) {
            poor[w] = 0;
            // Next to an opening, two columns may be the cap's own, fixed:
            // there a prism that is not star-shaped (the export keeps it as
            // three tets) is accepted as long as its tets are good.
            bool star = true;
            for (int32_t v : surface.triangles[walls[w]]) star = star && stack.first[v] >= 0;
            for (int32_t m = 1; m <= L && !poor[w]; ++m)
                poor[w] = !good_split(split(walls[w], m), at, params.min_tet_fraction, star);
        });
        SurfaceMesh top;
        top.points = at;
        for (int32_t f : walls) {
            const Triangle& t = surface.triangles[f];
            top.triangles.push_back({point(t[0], L), point(t[1], L), point(t[2], L)});
        }
        const SelfIntersections crossing = self_intersections(top, size_t(1) << 20);
        for (const auto& pair : crossing.first) poor[pair[0]] = poor[pair[1]] = 1;
        if (std::find(poor.begin(), poor.end(), 1) == poor.end()) {
            stack.top = std::move(top.triangles);
            break;
        }
        if (stack.rounds == params.max_rounds)
            throw StageError("volume", std::to_string(std::count(poor.begin(), poor.end(), 1)) +
                                           " wall triangles still have poor or crossing prism layers after " +
                                           std::to_string(params.max_rounds) + " rounds of shortening");
        std::vector<char> shorten(n, 0);
        for (size_t w = 0; w < walls.size(); ++w)
            if (poor[w])
                for (int32_t v : surface.triangles[walls[w]]) shorten[v] = 1;
        bool shortened = false;
        for (int32_t v = 0; v < n; ++v)
            if (shorten[v] && stack.first[v] >= 0) stack.scale[v] *= params.shrink, shortened = true;
        if (!shortened)
            throw StageError("volume", std::to_string(std::count(poor.begin(), poor.end(), 1)) +
                                           " wall triangles next to an opening have poor prism layers, and their "
                                           "columns are the cap's own");
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

    stack.points.assign(at.begin() + n, at.end());
    stack.top_of = walls;
    stack.tets.reserve(walls.size() * 3 * size_t(L));
    for (int32_t f : walls)
        for (int32_t m = 1; m <= L; ++m)
            for (const Tet& t : split(f, m)) stack.tets.push_back(t);
    stack.prisms = static_cast<int64_t>(walls.size()) * L;
    for (int32_t v = 0; v < n; ++v)
        if (stack.first[v] >= 0 && stack.scale[v] < 1) ++stack.shortened_nodes;
    return stack;
}

} // namespace scalemesh
