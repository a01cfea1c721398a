#include "volume/offset_points.h"

#include "core/errors.h"

#include <algorithm>
#include <cmath>
#include <numeric>
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

std::vector<OffsetPoint> offset_points(const SurfaceMesh& surface, const FeatureSize& sizing,
                                       const OffsetParams& params)
{
    const size_t n = surface.points.size();
    if (sizing.d.size() != n || sizing.D.size() != n || sizing.normals.size() != n ||
        (!sizing.inward_ok.empty() && sizing.inward_ok.size() != n))
        throw InputError("volume: the feature size fields do not match the surface points",
                         "compute the sizing on the same surface that is meshed");
    if (!(params.L_max > 0) || !std::isfinite(params.L_max))
        throw InputError("volume: L_max must be a positive finite length in mm", "set L_max as for the sizing stage");
    if (!(params.filter_fraction >= 0)) throw InputError("volume: filter_fraction must be >= 0", "use 0.2");
    const std::vector<double> lambda = layer_fractions(params.M, params.growth);

    std::vector<OffsetPoint> points;
    points.reserve(n * (lambda.size() + 2));
    for (size_t i = 0; i < n; ++i) {
        if (!sizing.inward_ok.empty() && !sizing.inward_ok[i]) continue;
        const double d = sizing.d[i], D = sizing.D[i];
        if (!(d > 0) || !(D > 0)) continue;
        const Vec3 inward = -normalized(sizing.normals[i]);
        const double filler_step = std::min(D, params.L_max) / params.M;
        double dist = 0;
        for (int m = 1;; ++m) {
            const bool filler = m > static_cast<int>(lambda.size());
            const double step = filler ? filler_step : lambda[m - 1] * d;
            dist += step;
            if (!(dist <= D / 2) || !(step > 0)) break;
            points.push_back({surface.points[i] + dist * inward, static_cast<int32_t>(i), m, filler, dist, step});
        }
    }
    return points;
}

std::vector<OffsetPoint> filter_interior_points(const std::vector<OffsetPoint>& points, const FeatureSize& sizing,
                                                const OffsetParams& params)
{
    if (points.empty() || params.filter_fraction <= 0) return points;
    auto radius = [&](int32_t a, int32_t b) {
        return params.filter_fraction * std::min(sizing.d[a], sizing.d[b]) / params.M;
    };
    double cell = 0;
    for (const OffsetPoint& p : points) cell = std::max(cell, radius(p.generator, p.generator));
    if (!(cell > 0)) return points;

    auto key = [&](const Vec3& x, int dx, int dy, int dz) {
        const int64_t i = static_cast<int64_t>(std::floor(x.x / cell)) + dx;
        const int64_t j = static_cast<int64_t>(std::floor(x.y / cell)) + dy;
        const int64_t k = static_cast<int64_t>(std::floor(x.z / cell)) + dz;
        return static_cast<uint64_t>(i * 73856093) ^ static_cast<uint64_t>(j * 19349663) ^
               static_cast<uint64_t>(k * 83492791);
    };

    std::vector<size_t> order(points.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return points[a].dist < points[b].dist; });

    std::unordered_multimap<uint64_t, size_t> grid;
    grid.reserve(points.size());
    std::vector<char> keep(points.size(), 0);
    for (size_t idx : order) {
        const OffsetPoint& p = points[idx];
        bool clash = false;
        for (int dx = -1; dx <= 1 && !clash; ++dx)
            for (int dy = -1; dy <= 1 && !clash; ++dy)
                for (int dz = -1; dz <= 1 && !clash; ++dz) {
                    auto range = grid.equal_range(key(p.position, dx, dy, dz));
                    for (auto it = range.first; it != range.second; ++it) {
                        const OffsetPoint& q = points[it->second];
                        if (q.generator == p.generator) continue;
                        if (distance(p.position, q.position) < radius(p.generator, q.generator)) {
                            clash = true;
                            break;
                        }
                    }
                }
        if (clash) continue;
        keep[idx] = 1;
        grid.emplace(key(p.position, 0, 0, 0), idx);
    }
    std::vector<OffsetPoint> kept;
    kept.reserve(points.size());
    for (size_t i = 0; i < points.size(); ++i)
        if (keep[i]) kept.push_back(points[i]);
    return kept;
}

} // namespace scalemesh
