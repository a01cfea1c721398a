#pragma once
// Private to src/openings: constrained Delaunay triangulation of points in a
// plane (CGAL), the region inside closed constraint loops, split into its
// connected pieces.

#include "core/vec3.h"

#include <array>
#include <cstdint>
#include <vector>

namespace scalemesh::openings {

// An orthonormal basis (e1, e2) of the plane with unit normal n, e1 x e2 = n:
// counter-clockwise in (e1, e2) coordinates is counter-clockwise seen from +n.
struct PlaneBasis {
    Vec3 e1, e2;
    explicit PlaneBasis(const Vec3& n);
    double u(const Vec3& x) const { return dot(x, e1); }
    double v(const Vec3& x) const { return dot(x, e2); }
};

struct PlanePiece {
    std::vector<std::array<int32_t, 3>> triangles; // ids of the input points, counter-clockwise in (u, v)
    double area = 0;
    double cu = 0, cv = 0; // area centroid in (u, v)
};

// Triangulates the points (u[i], v[i]), id i, with every segment of `loops`
// (closed polygons of point ids) as a constraint, and returns the faces
// inside an odd number of loops, grouped into pieces connected across
// unconstrained edges, largest area first. Points that are not on a loop are
// added as vertices where they fall inside (callers keep them off the loops).
// Throws StageError (stage `what`) when two points coincide, a constraint
// crosses another or passes through a point, or CGAL fails.
std::vector<PlanePiece> triangulate_loops(const std::vector<double>& u, const std::vector<double>& v,
                                          const std::vector<std::vector<int32_t>>& loops, const char* what);

} // namespace scalemesh::openings
