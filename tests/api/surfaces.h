#pragma once
// Surfaces built in code for the library tests: an icosphere (closed) and a
// tube open at both ends, as SurfaceInput.

#include "scalemesh/mesh.h"

#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

namespace scalemesh::test {

// An icosphere of radius `r` (mm) around the origin, `levels` times
// subdivided with the new points pushed onto the sphere; outward wound.
inline SurfaceInput icosphere(double r, int levels)
{
    const double t = (1 + std::sqrt(5.0)) / 2;
    std::vector<std::array<double, 3>> p = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                            {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    std::vector<std::array<size_t, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                            {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                            {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                            {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    for (int level = 0; level < levels; ++level) {
        std::map<std::pair<size_t, size_t>, size_t> middle;
        const auto mid = [&](size_t a, size_t b) {
            const auto key = std::minmax(a, b);
            if (auto it = middle.find(key); it != middle.end()) return it->second;
            p.push_back({(p[a][0] + p[b][0]) / 2, (p[a][1] + p[b][1]) / 2, (p[a][2] + p[b][2]) / 2});
            return middle[key] = p.size() - 1;
        };
        std::vector<std::array<size_t, 3>> next;
        for (const auto& [a, b, c] : f) {
            const size_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
            next.insert(next.end(), {{a, ab, ca}, {b, bc, ab}, {c, ca, bc}, {ab, bc, ca}});
        }
        f = std::move(next);
    }
    SurfaceInput s;
    for (auto& q : p) {
        const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        s.points.insert(s.points.end(), {r * q[0] / n, r * q[1] / n, r * q[2] / n});
    }
    for (const auto& tri : f) s.triangles.insert(s.triangles.end(), tri.begin(), tri.end());
    return s;
}

// A tube of radius `r` along z from -length/2 to length/2, `around` points
// per ring and rings about as far apart as the points on a ring, open at
// both ends (two boundary loops of `around` edges); outward wound.
inline SurfaceInput open_tube(double r, double length, int around)
{
    const double pi = std::acos(-1.0);
    const int rings = static_cast<int>(std::ceil(length / (2 * pi * r / around))) + 1;
    SurfaceInput s;
    for (int j = 0; j < rings; ++j)
        for (int i = 0; i < around; ++i) {
            const double a = 2 * pi * (i + 0.5 * (j % 2)) / around; // staggered rings: no long diagonals
            s.points.insert(s.points.end(), {r * std::cos(a), r * std::sin(a), -length / 2 + length * j / (rings - 1)});
        }
    const auto at = [&](int j, int i) { return static_cast<size_t>(j * around + (i % around)); };
    for (int j = 0; j + 1 < rings; ++j)
        for (int i = 0; i < around; ++i) {
            // Counter-clockwise seen from outside (the normal points away from the axis).
            if (j % 2 == 0) {
                s.triangles.insert(s.triangles.end(), {at(j, i), at(j, i + 1), at(j + 1, i)});
                s.triangles.insert(s.triangles.end(), {at(j, i + 1), at(j + 1, i + 1), at(j + 1, i)});
            } else {
                s.triangles.insert(s.triangles.end(), {at(j, i), at(j + 1, i + 1), at(j + 1, i)});
                s.triangles.insert(s.triangles.end(), {at(j, i), at(j, i + 1), at(j + 1, i + 1)});
            }
        }
    return s;
}

} // namespace scalemesh::test
