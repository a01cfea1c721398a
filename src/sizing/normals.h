#pragma once
// Synthetic vertex normals of a piecewise linear surface: paper section 2.1,
// eq. (6), the angle-weighted normal, and the check that it points into the
// geometry (its negative makes a positive dot product with every incident
// triangle normal).

#include "core/adjacency.h"
#include "core/surface_mesh.h"

#include <vector>

namespace scalemesh {

// Per point: sum over the incident triangles of (vertex angle x unit triangle
// normal), normalized. Triangles are counter-clockwise seen from outside
// (SurfaceMesh), so the result points OUTWARD; the inward normal of eq. (3)
// is its negative. Unit length, or the zero vector where the sum vanishes
// (unreferenced points, fans of zero-area triangles, fans folded so that the
// angles cancel). Never throws; degenerate triangles contribute nothing.
std::vector<Vec3> synthetic_normals(const SurfaceMesh& mesh);

// The same from the mesh's vertex_triangles (core/adjacency.h). When
// inward_ok is given it also receives inward_check of the result, judged
// from the triangle normals the sums used.
std::vector<Vec3> synthetic_normals(const SurfaceMesh& mesh, const VertexTable& fans,
                                    std::vector<char>* inward_ok = nullptr);

// Per point: 1 where normals[i] is nonzero and makes a strictly positive dot
// product with the normal of every incident triangle of nonzero area, else 0.
// Where it is 0 the ray of eq. (3) is not trusted and D = L_max (section 2.1).
// Throws InputError when normals.size() != mesh.points.size().
std::vector<char> inward_check(const SurfaceMesh& mesh, const std::vector<Vec3>& normals);
std::vector<char> inward_check(const SurfaceMesh& mesh, const VertexTable& fans, const std::vector<Vec3>& normals);

} // namespace scalemesh
