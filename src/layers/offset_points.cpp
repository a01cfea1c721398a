#include "layers/offset_points.h"

#include "core/errors.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <unordered_map>

namespace scalemesh {

std::vector<double> layer_fractions(double M, double growth)
{
    if (!(M >= 1) || !std::isfinite(M)) throw InputError("volume: M must be a finite number >= 1", "use M = 7");
    if (!(growth >= 1) || !std::isfinite(growth))
        throw InputError("volume: the layer growth ratio must be finite and >= 1", "use 1 for uniform layers");
    const int layers = static_cast<int>(std::floor(M / 2));
    std::vector<double> lambda(layers, 1.0 / M);
    if (growth == 1.0 || layers == 0) return lambda;
    // The total floor(M/2)/M equals the uniform case's, so the innermost
    // layermaking point sits where it would without grading and the central
    // layer of an odd M survives; for even M it is the paper's 1/2.
    double sum = 0;
    for (int m = 0; m < layers; ++m) sum += std::pow(growth, m);
    const double total = layers / M;
    for (int m = 0; m < layers; ++m) lambda[m] = total * std::pow(growth, m) / sum;
    return lambda;
}

std::vector<double> edge_layer_fractions(const std::vector<double>& lambda, double first)
{
    if (lambda.empty() || !(first > 0) || first >= lambda[0]) return lambda;
    const size_t L = lambda.size();
    double total = 0;
    for (double l : lambda) total += l;
    // first * (1 + r + ... + r^(L-1)) = total; increasing in r, and r = 1 is
    // too small since first < lambda[0] <= total / L.
    auto sum = [&](double r) {
        double s = 0, term = first;
        for (size_t m = 0; m < L; ++m, term *= r) s += term;
        return s;
    };
    if (L == 1) return {total};
    double lo = 1, hi = 2;
    while (sum(hi) < total) hi *= 2;
    for (int i = 0; i < 100; ++i) {
        const double mid = 0.5 * (lo + hi);
        (sum(mid) < total ? lo : hi) = mid;
    }
    const double r = 0.5 * (lo + hi);
    std::vector<double> out(L);
    double term = first;
    for (size_t m = 0; m < L; ++m, term *= r) out[m] = term;
    out[L - 1] += total - sum(r); // the round-off of the bisection, so the last point is where the paper's is
    return out;
}

std::optional<Vec3> repaired_inward_direction(const SurfaceMesh& surface, const VertexTable& fans, int32_t v,
                                              const Vec3& start, double margin)
{
    std::vector<Vec3> faces;
    for (const int32_t* f = fans.begin(v); f != fans.end(v); ++f) {
        const Triangle& t = surface.triangles[*f];
        const Vec3 normal = cross(surface.points[t[1]] - surface.points[t[0]], surface.points[t[2]] - surface.points[t[0]]);
        if (norm2(normal) > 0) faces.push_back(normalized(normal));
    }
    if (faces.empty()) return std::nullopt;
    Vec3 x = norm2(start) > 0 ? normalized(start) : faces[0];
    for (int step = 0; step < 200; ++step) {
        size_t worst = 0;
        for (size_t j = 1; j < faces.size(); ++j)
            if (dot(x, faces[j]) < dot(x, faces[worst])) worst = j;
        const double low = dot(x, faces[worst]);
        if (low >= margin) return x;
        // Rotate towards the worst triangle's normal, a little past where it
        // would be met exactly.
        const Vec3 moved = x + (margin - low + 0.05) * faces[worst];
        if (!(norm2(moved) > 0)) return std::nullopt;
        x = normalized(moved);
    }
    return std::nullopt;
}

LayerColumns layer_columns(const SurfaceMesh& surface, const FeatureSize& sizing, const OffsetParams& params)
{
    const size_t n = surface.points.size();
    if (sizing.d.size() != n || sizing.D.size() != n || sizing.normals.size() != n ||
        (!sizing.inward_ok.empty() && sizing.inward_ok.size() != n))
        throw InputError("volume: the feature size fields do not match the surface points",
                         "compute the sizing on the same surface that is meshed");
    if (!(params.L_max > 0) || !std::isfinite(params.L_max))
        throw InputError("volume: L_max must be a positive finite length in mm", "set L_max as for the sizing stage");
    if (!(params.filter_fraction >= 0) || !(params.filler_filter_fraction >= 0))
        throw InputError("volume: filter_fraction and filler_filter_fraction must be >= 0", "use 0.1 and 0.8");
    const std::vector<double> lambda = layer_fractions(params.M, params.growth);
    if (params.first_layer == FirstLayer::edge && (!(params.K > 0) || !std::isfinite(params.K)))
        throw InputError("volume: K must be a positive number", "use K = 4.2");
    // Wall nodes whose normal failed the inward check: a repaired direction.
    std::vector<Vec3> direction(sizing.normals.begin(), sizing.normals.end());
    std::vector<char> repaired(n, 0);
    if (params.repair_normals && !sizing.inward_ok.empty() &&
        std::count(sizing.inward_ok.begin(), sizing.inward_ok.end(), 0) > 0) {
        const VertexTable fans = vertex_triangles(surface);
        std::vector<char> wall(n, 1);
        if (surface.triangle_patch.size() == surface.triangles.size())
            for (size_t t = 0; t < surface.triangles.size(); ++t)
                if (surface.triangle_patch[t] != 0)
                    for (int32_t v : surface.triangles[t]) wall[v] = 0;
        for (size_t i = 0; i < n; ++i)
            if (!sizing.inward_ok[i] && wall[i])
                if (const auto x = repaired_inward_direction(surface, fans, static_cast<int32_t>(i), sizing.normals[i]))
                    direction[i] = *x, repaired[i] = 1;
    }
    // FirstLayer::edge: each node's mean incident edge length, raised where
    // a triangle of the node is tall from it. The first-layer point over a
    // node caps one of its triangles in the volume mesh; that tet's dihedral
    // angle at the far edge is about atan(thickness * cos(tilt) / height of
    // the triangle from the node), where tilt is the angle between the
    // node's layer direction and the triangle's normal. So the thickness
    // (edge / K) is raised to tan(kCapAngle) times the largest such
    // height / cos(tilt) (a margin over the 10 degrees a finite-volume
    // solver wants), unless the paper's lambda_1 d is thinner still
    // (edge_layer_fractions keeps the smaller). Well-shaped triangles on a
    // smooth wall never reach it (an equilateral one gives 15 degrees at
    // K = 4.2); on a ridge of the wall the layer direction is up to 90
    // degrees from some triangles of the node, and cos(tilt) is taken as
    // kMinTilt at least there, so one fold does not thicken a node's first
    // layer more than fourfold. An opening's triangles count untilted: the
    // layer direction of a rim node lies in the opening's plane by design,
    // and no layer point caps those triangles.
    constexpr double kCapAngle = 12.0 * M_PI / 180;
    constexpr double kMinTilt = 0.25;
    std::vector<double> edge(params.first_layer == FirstLayer::edge ? n : 0, 0.0);
    if (!edge.empty()) {
        const VertexTable neighbours = vertex_neighbours(surface);
        const VertexTable fans = vertex_triangles(surface);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
            for (size_t i = range.begin(); i != range.end(); ++i) {
                double sum = 0;
                for (const int32_t* j = neighbours.begin(i); j != neighbours.end(i); ++j)
                    sum += distance(surface.points[i], surface.points[*j]);
                if (neighbours.size(i) > 0) edge[i] = sum / neighbours.size(i);
                double tallest = 0;
                for (const int32_t* f = fans.begin(i); f != fans.end(i); ++f) {
                    const Triangle& tri = surface.triangles[*f];
                    int k = 0;
                    while (tri[k] != static_cast<int32_t>(i)) ++k;
                    const Vec3& b = surface.points[tri[(k + 1) % 3]];
                    const Vec3& c = surface.points[tri[(k + 2) % 3]];
                    const double base = distance(b, c);
                    const Vec3 twice_area = cross(b - surface.points[i], c - surface.points[i]);
                    if (!(base > 0) || !(norm2(twice_area) > 0)) continue;
                    const bool wall = surface.triangle_patch.size() != surface.triangles.size() ||
                                      surface.triangle_patch[*f] == 0;
                    const double tilt =
                        wall ? std::max(kMinTilt, dot(normalized(direction[i]), normalized(twice_area))) : 1.0;
                    tallest = std::max(tallest, norm(twice_area) / base / tilt);
                }
                edge[i] = std::max(edge[i], params.K * std::tan(kCapAngle) * tallest);
            }
        });
    }

    LayerColumns columns;
    columns.layers = static_cast<int32_t>(lambda.size());
    columns.inward.resize(n);
    columns.dist.assign(n * lambda.size(), std::numeric_limits<double>::quiet_NaN());
    columns.spacing.assign(n * lambda.size(), std::numeric_limits<double>::quiet_NaN());
    columns.repaired = std::move(repaired);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
            columns.inward[i] = -normalized(direction[i]);
            if (!sizing.inward_ok.empty() && !sizing.inward_ok[i] && !columns.repaired[i]) continue;
            const double d = sizing.d[i];
            if (!(d > 0)) continue;
            const std::vector<double> own = edge.empty() || !(edge[i] > 0)
                                                ? std::vector<double>()
                                                : edge_layer_fractions(lambda, edge[i] / params.K / d);
            const std::vector<double>& fractions = own.empty() ? lambda : own;
            double dist = 0;
            for (size_t m = 0; m < fractions.size(); ++m) {
                const double step = fractions[m] * d;
                dist += step;
                columns.dist[i * fractions.size() + m] = dist;
                columns.spacing[i * fractions.size() + m] = step;
            }
        }
    });
    return columns;
}

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

std::vector<OffsetPoint> offset_points(const SurfaceMesh& surface, const FeatureSize& sizing,
                                       const OffsetParams& params)
{
    const LayerColumns columns = layer_columns(surface, sizing, params);
    const size_t n = surface.points.size();
    const size_t L = static_cast<size_t>(columns.layers);
    // Node i's points, passed one by one to `emit`; the count pass and the
    // fill pass walk the same steps, so each node's points land in its own
    // slice of the output and the order does not depend on the threads.
    auto walk = [&](size_t i, auto&& emit) {
        if (!sizing.inward_ok.empty() && !sizing.inward_ok[i] && !columns.repaired[i]) return;
        const double* dist_of = columns.dist.data() + i * L;
        // A repaired node's D is not measured (no ray along its normal): its
        // layermaking points go to d / 2 at most, and it makes no fillers.
        const bool repaired = columns.repaired[i];
        const double d = sizing.d[i], D = repaired ? sizing.d[i] : sizing.D[i];
        if (!(d > 0) || !(D > 0)) return;
        const double filler_step = std::min(D, params.L_max) / params.M;
        double dist = 0;
        for (size_t m = 1;; ++m) {
            const bool filler = m > L;
            if (filler && repaired) break;
            const double step = filler ? filler_step : columns.spacing[i * L + m - 1];
            dist = filler ? dist + step : dist_of[m - 1];
            // For even M and d = D the last layermaking point is the
            // medial axis itself, D / 2 to round-off.
            if (!(dist <= D / 2 * (1 + 1e-12)) || !(step > 0)) break;
            emit(static_cast<int>(m), filler, dist, step);
        }
    };
    std::vector<size_t> first(n + 1, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) walk(i, [&](int, bool, double, double) { ++first[i + 1]; });
    });
    std::partial_sum(first.begin(), first.end(), first.begin());
    std::vector<OffsetPoint> points(first[n]);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const Vec3& inward = columns.inward[i];
            size_t k = first[i];
            walk(i, [&](int m, bool filler, double dist, double step) {
                points[k++] = {surface.points[i] + dist * inward, static_cast<int32_t>(i), m, filler, dist, step};
            });
        }
    });
    return points;
}

std::vector<OffsetPoint> filter_interior_points(const std::vector<OffsetPoint>& points, const FeatureSize& sizing,
                                                const OffsetParams& params)
{
    if (points.empty() || (params.filter_fraction <= 0 && params.filler_filter_fraction <= 0)) return points;
    // The radius within which a point b kept before a drops a: the
    // fraction of the layer spacing for any a; for a filler a, also the
    // fraction of its own filler spacing (its radius bounds every other).
    auto radius = [&](const OffsetPoint& a, const OffsetPoint& b) {
        const double layer = params.filter_fraction * std::min(sizing.d[a.generator], sizing.d[b.generator]) / params.M;
        return a.filler ? std::max(layer, params.filler_filter_fraction * a.spacing) : layer;
    };
    double cell = 0;
    for (const OffsetPoint& p : points) cell = std::max(cell, radius(p, p));
    if (!(cell > 0)) return points;

    // Grid cells of side `cell` (no radius is larger; larger still where
    // the box would need more than 2^20 cells along an axis), packed as
    // (x, y, z) indices of 21 bits each, from 1 so that a neighbour's index
    // is never negative. Sorted by key, the three cells of a column
    // (x, y, z - 1 .. z + 1) are one run, and walking the points in key
    // order moves the start of each of the nine neighbouring columns
    // forward only: the search reads the sorted array in nine streams
    // instead of looking up 27 cells per point.
    const size_t n = points.size();
    if (n > std::numeric_limits<uint32_t>::max())
        throw InputError("volume: " + std::to_string(n) + " interior points are more than the filter can index",
                         "use a larger voxel size or a smaller L_max");
    Vec3 lo = points[0].position, hi = lo;
    for (const OffsetPoint& p : points) {
        lo = {std::min(lo.x, p.position.x), std::min(lo.y, p.position.y), std::min(lo.z, p.position.z)};
        hi = {std::max(hi.x, p.position.x), std::max(hi.y, p.position.y), std::max(hi.z, p.position.z)};
    }
    constexpr double kMaxCells = double(1 << 20);
    // 1e-9 over the largest radius: a pair closer than its radius is then in
    // neighbouring cells despite the rounding of the cell indices.
    cell = (1 + 1e-9) * std::max({cell, (hi.x - lo.x) / kMaxCells, (hi.y - lo.y) / kMaxCells, (hi.z - lo.z) / kMaxCells});
    auto index = [&](double x, double x0) {
        return 1 + static_cast<uint64_t>(std::min(kMaxCells, std::max(0.0, std::floor((x - x0) / cell))));
    };
    auto pack = [](uint64_t i, uint64_t j, uint64_t k) { return i << 42 | j << 21 | k; };
    std::vector<std::pair<uint64_t, uint32_t>> by_cell(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const Vec3& x = points[i].position;
            by_cell[i] = {pack(index(x.x, lo.x), index(x.y, lo.y), index(x.z, lo.z)), static_cast<uint32_t>(i)};
        }
    });
    tbb::parallel_sort(by_cell.begin(), by_cell.end());

    // Section 4's greedy pass, in order of distance to the generator (ties:
    // the earlier point): a point is dropped when a kept point before it
    // clashes with it (another generator, closer than their radius). A point
    // with no clash partner before it at all is kept whatever the others
    // do; those are found first, in parallel, each search stopping at its
    // first partner. Only the few others are walked in order, against the
    // kept points: the first kind from the sorted array (a point of the
    // second kind never is one), the second kind from the cells they were
    // put in as they were kept.
    auto before = [&](uint32_t a, uint32_t b) {
        return points[a].dist < points[b].dist || (points[a].dist == points[b].dist && a < b);
    };
    auto clash = [&](uint32_t a, uint32_t b) {
        const OffsetPoint &p = points[a], &q = points[b];
        return q.generator != p.generator && distance(p.position, q.position) < radius(p, q);
    };
    constexpr uint64_t kField = (uint64_t(1) << 21) - 1;
    auto column_of = [&](uint64_t key, int c) { // the c-th of the nine columns next to the key's cell
        const uint64_t i = key >> 42, j = (key >> 21) & kField;
        return pack(i + c / 3 - 1, j + c % 3 - 1, 0);
    };
    auto first_at_or_after = [](const std::vector<std::pair<uint64_t, uint32_t>>& sorted, uint64_t key) {
        return static_cast<size_t>(std::lower_bound(sorted.begin(), sorted.end(), std::make_pair(key, uint32_t(0))) -
                                   sorted.begin());
    };
    std::vector<char> contested(n, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& range) {
        std::array<size_t, 9> cursor{};
        for (size_t s = range.begin(); s != range.end(); ++s) {
            const uint64_t key = by_cell[s].first, k = key & kField;
            const uint32_t a = by_cell[s].second;
            for (int c = 0; c < 9; ++c) {
                const uint64_t from = column_of(key, c) | (k - 1), to = column_of(key, c) | (k + 1);
                size_t& at = cursor[c];
                if (s == range.begin()) at = first_at_or_after(by_cell, from);
                while (at < n && by_cell[at].first < from) ++at;
                if (contested[a]) continue; // the cursor still moves on
                for (size_t t = at; t < n && by_cell[t].first <= to; ++t)
                    if (before(by_cell[t].second, a) && clash(a, by_cell[t].second)) {
                        contested[a] = 1;
                        break;
                    }
            }
        }
    });
    std::vector<std::pair<uint64_t, uint32_t>> free_by_cell; // the uncontested points, still sorted by cell
    std::vector<std::pair<uint64_t, uint32_t>> walked;       // the contested ones, with their cells
    for (const auto& entry : by_cell) (contested[entry.second] ? walked : free_by_cell).push_back(entry);
    std::sort(walked.begin(), walked.end(), [&](const auto& u, const auto& v) { return before(u.second, v.second); });
    std::vector<char> keep(n, 1);
    std::unordered_map<uint64_t, std::vector<uint32_t>> kept_contested; // cell key -> kept contested points
    for (const auto& [key, a] : walked) {
        const uint64_t k = key & kField;
        bool dropped = false;
        for (int c = 0; c < 9 && !dropped; ++c) {
            const uint64_t from = column_of(key, c) | (k - 1), to = column_of(key, c) | (k + 1);
            for (size_t t = first_at_or_after(free_by_cell, from);
                 t < free_by_cell.size() && free_by_cell[t].first <= to && !dropped; ++t)
                dropped = before(free_by_cell[t].second, a) && clash(a, free_by_cell[t].second);
            for (uint64_t cell_key = from; cell_key <= to && !dropped; ++cell_key)
                if (const auto it = kept_contested.find(cell_key); it != kept_contested.end())
                    for (uint32_t b : it->second)
                        if (clash(a, b)) {
                            dropped = true;
                            break;
                        }
        }
        if (dropped) keep[a] = 0;
        else kept_contested[key].push_back(a);
    }
    std::vector<OffsetPoint> kept;
    kept.reserve(n);
    for (size_t i = 0; i < n; ++i)
        if (keep[i]) kept.push_back(points[i]);
    return kept;
}

} // namespace scalemesh
