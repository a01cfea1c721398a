#pragma once
// Triangles of a surface that cross each other: a surface that intersects
// itself (overlapping copies, a fold, two parts pushed into each other)
// encloses no one region, and every later stage runs away on it (the local
// feature size falls to nothing across the crossing). Checked on every
// surface a run reads, before it is meshed.

#include "core/surface_mesh.h"

#include <array>
#include <cstdint>
#include <vector>

namespace scalemesh {

struct SelfIntersections {
    int64_t pairs = 0;                          // pairs of triangles that intersect, other than at the edge or
                                                // corner they share
    std::vector<std::array<int32_t, 2>> first;  // up to `keep` of them (triangle ids), lowest first
};

// CGAL Polygon Mesh Processing's self_intersections on `surface` (a
// triangle mesh whose triangles can be linked into a manifold; a triangle
// that cannot is left out of the test), in parallel. Exact predicates:
// triangles that only touch along a shared edge or at a shared corner do
// not count, two that meet anywhere else do.
SelfIntersections self_intersections(const SurfaceMesh& surface, size_t keep = 10);

} // namespace scalemesh
