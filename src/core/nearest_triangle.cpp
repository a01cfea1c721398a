#include "core/nearest_triangle.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace scalemesh {

double point_triangle_distance2(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c)
{
    // The closest point by Voronoi regions of the triangle.
    const Vec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return norm2(ap);
    const Vec3 bp = p - b;
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return norm2(bp);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return norm2(ap - ab * (d1 / (d1 - d3)));
    const Vec3 cp = p - c;
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return norm2(cp);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return norm2(ap - ac * (d2 / (d2 - d6)));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return norm2(bp - (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
    const double denom = 1 / (va + vb + vc);
    return norm2(ap - ab * (vb * denom) - ac * (vc * denom));
}

std::vector<int32_t> nearest_triangles(const SurfaceMesh& surface, const std::vector<Vec3>& points)
{
    Vec3 lo, hi;
    bounding_box(surface, lo, hi);
    const Vec3 extent = hi - lo;
    const double volume = std::max(extent.x, 1e-12) * std::max(extent.y, 1e-12) * std::max(extent.z, 1e-12);
    // About two triangles per cell.
    const double cell = std::max(std::cbrt(2 * volume / static_cast<double>(surface.triangles.size())),
                                 1e-9 * std::max({extent.x, extent.y, extent.z, 1.0}));
    std::array<int64_t, 3> dims;
    for (int k = 0; k < 3; ++k) dims[k] = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(extent[k] / cell)));
    const auto coord = [&](double x, int k) {
        return std::clamp<int64_t>(static_cast<int64_t>(std::floor((x - lo[k]) / cell)), 0, dims[k] - 1);
    };
    const auto index = [&](int64_t i, int64_t j, int64_t k) { return (k * dims[1] + j) * dims[0] + i; };
    std::vector<std::vector<int32_t>> cells(static_cast<size_t>(dims[0] * dims[1] * dims[2]));
    for (size_t t = 0; t < surface.triangles.size(); ++t) {
        Vec3 tlo = surface.points[surface.triangles[t][0]], thi = tlo;
        for (int32_t v : surface.triangles[t])
            for (int k = 0; k < 3; ++k) {
                tlo[k] = std::min(tlo[k], surface.points[v][k]);
                thi[k] = std::max(thi[k], surface.points[v][k]);
            }
        for (int64_t k = coord(tlo.z, 2); k <= coord(thi.z, 2); ++k)
            for (int64_t j = coord(tlo.y, 1); j <= coord(thi.y, 1); ++j)
                for (int64_t i = coord(tlo.x, 0); i <= coord(thi.x, 0); ++i)
                    cells[index(i, j, k)].push_back(static_cast<int32_t>(t));
    }
    std::vector<int32_t> out(points.size());
    for (size_t p = 0; p < points.size(); ++p) {
        const Vec3& point = points[p];
        const int64_t ci = coord(point.x, 0), cj = coord(point.y, 1), ck = coord(point.z, 2);
        double best = std::numeric_limits<double>::infinity();
        int32_t best_triangle = 0;
        const int64_t max_shell = std::max({dims[0], dims[1], dims[2]});
        for (int64_t r = 0; r <= max_shell; ++r) {
            for (int64_t k = ck - r; k <= ck + r; ++k)
                for (int64_t j = cj - r; j <= cj + r; ++j)
                    for (int64_t i = ci - r; i <= ci + r; ++i) {
                        if (std::max({std::abs(i - ci), std::abs(j - cj), std::abs(k - ck)}) != r) continue;
                        if (i < 0 || j < 0 || k < 0 || i >= dims[0] || j >= dims[1] || k >= dims[2]) continue;
                        for (int32_t t : cells[index(i, j, k)]) {
                            const Triangle& tri = surface.triangles[t];
                            const double d2 = point_triangle_distance2(point, surface.points[tri[0]],
                                                                       surface.points[tri[1]], surface.points[tri[2]]);
                            if (d2 < best || (d2 == best && t < best_triangle)) best = d2, best_triangle = t;
                        }
                    }
            // Every triangle not yet seen lies outside the searched shells,
            // at least r cells from the point's cell.
            if (best <= (r * cell) * (r * cell)) break;
        }
        out[p] = best_triangle;
    }
    return out;
}

} // namespace scalemesh
