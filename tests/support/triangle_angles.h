#pragma once
// The smallest corner angle of a surface triangle, for tests of the surface
// stages.

#include "core/surface_mesh.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace scalemesh {

inline double min_angle_degrees(const SurfaceMesh& mesh, const Triangle& t)
{
    double smallest = 180;
    for (int k = 0; k < 3; ++k) {
        const Vec3 u = mesh.points[t[(k + 1) % 3]] - mesh.points[t[k]];
        const Vec3 v = mesh.points[t[(k + 2) % 3]] - mesh.points[t[k]];
        smallest = std::min(smallest, std::atan2(norm(cross(u, v)), dot(u, v)) * 180 / std::numbers::pi);
    }
    return smallest;
}

} // namespace scalemesh
