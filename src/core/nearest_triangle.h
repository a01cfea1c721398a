#pragma once
// Nearest triangle of a surface to each of many points: used to carry a
// surface's per-triangle labels over to another triangulation of it.

#include "core/surface_mesh.h"
#include "core/vec3.h"

#include <cstdint>
#include <vector>

namespace scalemesh {

// Squared distance from p to the triangle abc (closed, degenerate triangles
// included). Ericson, Real-Time Collision Detection, 5.1.5.
double point_triangle_distance2(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// For each point, the index into surface.triangles of the triangle nearest to
// it (the lowest index among equally near ones). Exact: the triangles are
// binned in a uniform grid of their bounding boxes (about two per cell), and
// the grid is searched in growing shells until no nearer triangle can remain.
// The surface must have at least one triangle.
std::vector<int32_t> nearest_triangles(const SurfaceMesh& surface, const std::vector<Vec3>& points);

} // namespace scalemesh
