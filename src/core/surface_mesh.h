#pragma once
// SurfaceMesh: the triangulated surface handed between stages, as index arrays
// (DESIGN.md). Adjacency is built on demand by the functions below.

#include "core/vec3.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace scalemesh {

using Triangle = std::array<int32_t, 3>;
struct VertexTable; // core/adjacency.h

struct SurfaceMesh {
    std::vector<Vec3> points;           // physical coordinates (mm)
    std::vector<Triangle> triangles;    // counter-clockwise seen from outside
    std::vector<int32_t> triangle_patch; // patch id per triangle; empty means all 0 (wall)
};

// A named per-vertex scalar field (D, D_out, d, ...), for export and inspection.
struct VertexField {
    std::string name;
    std::vector<double> values;
};

// Facts about the combinatorics and geometry of a surface.
struct SurfaceFacts {
    int64_t vertices = 0;          // vertices referenced by at least one triangle
    int64_t edges = 0;             // undirected edges
    int64_t triangles = 0;
    int64_t boundary_edges = 0;    // edges with one triangle
    int64_t nonmanifold_edges = 0; // edges with three or more triangles
    int64_t misoriented_edges = 0; // edges whose two triangles traverse it the same way
    int64_t nonmanifold_vertices = 0; // vertices whose triangle fan is not a single disk
    int64_t degenerate_triangles = 0; // repeated vertex index
    int64_t components = 0;        // edge-connected components of triangles
    int64_t euler_characteristic = 0; // V - E + F
    double signed_volume = 0;      // enclosed volume (positive when normals point out)
    double area = 0;

    bool closed_manifold() const
    {
        return boundary_edges == 0 && nonmanifold_edges == 0 && misoriented_edges == 0 &&
               nonmanifold_vertices == 0 && degenerate_triangles == 0;
    }
};

SurfaceFacts surface_facts(const SurfaceMesh& mesh);

// Enclosed volume by the divergence theorem; exact for closed surfaces.
double signed_volume(const SurfaceMesh& mesh);

// Component label per triangle (edge-connected), and the number of components.
std::vector<int32_t> triangle_components(const SurfaceMesh& mesh, int32_t* count = nullptr);

// Axis-aligned bounding box of the points (lo = +inf, hi = -inf when there
// are none).
void bounding_box(const std::vector<Vec3>& points, Vec3& lo, Vec3& hi);
void bounding_box(const SurfaceMesh& mesh, Vec3& lo, Vec3& hi);

// Reverses every triangle when the enclosed volume is negative (a surface
// wound inwards, as some STL files are), so normals point out. Assumes a
// consistently oriented closed surface. Returns whether it flipped.
bool orient_outward(SurfaceMesh& mesh);

// Throws InputError naming the open or non-manifold edges (count and the first
// few coordinates) when the surface is not a closed, oriented 2-manifold.
// The second form takes the surface's vertex_triangles, for a caller that
// has them already.
void require_closed_manifold(const SurfaceMesh& mesh, const std::string& what);
void require_closed_manifold(const SurfaceMesh& mesh, const VertexTable& fans, const std::string& what);

} // namespace scalemesh
