#pragma once
// Raw local diameter by ray casting: paper section 2.1, eq. (3) and the
// outward interrogation D_out. One ray per vertex along the inward synthetic
// normal and one along the outward one, through an Embree 3 BVH (the paper's
// AABB tree).

#include "core/adjacency.h"
#include "core/surface_mesh.h"

#include <cstdint>
#include <vector>

namespace scalemesh {

struct RayResults {
    std::vector<double> D;     // mm, per point: distance along -normal to the first re-intersection
    std::vector<double> D_out; // mm, per point: same along +normal; +infinity where the ray escapes
    int64_t rays = 0;          // rays cast
    int64_t escaped_inward = 0; // inward rays that left the surface (a leak): D = L_max there
    double bvh_seconds = 0;    // wall time of the BVH build
    double ray_seconds = 0;    // wall time of the ray casts
};

// Casts the rays from every point referenced by a triangle. Hits on the
// triangles incident to the ray's own origin vertex are ignored (the ray
// starts on them), every other triangle counts, at any distance of at least
// 1e-6 of the diagonal of the triangles' bounding box (nearer hits are
// below the single-precision resolution of the BVH, see below).
//
// Where inward_ok[i] is 0 no ray is cast: D = L_max (section 2.1) and
// D_out = +infinity (the normal is not trusted, so it sets no bound). Where an
// inward ray escapes, which on a closed surface is a numerical leak, D = L_max
// and escaped_inward counts it; D is therefore finite everywhere. Points
// without triangles get D = L_max and D_out = +infinity.
//
// The BVH holds the vertices in single precision, shifted to the centre of the
// bounding box; distances are accurate to about 1e-7 of the mesh extent.
// Results are bit-identical for every thread count. threads > 0 limits the
// worker threads (tbb::task_arena); 0 uses the TBB default.
//
// Expects a closed surface (the caller checks, see compute_feature_size).
// Throws InputError when the normal or flag arrays do not match the points,
// when L_max is not positive and finite, or when threads < 0; StageError when
// Embree reports an error.
RayResults cast_local_diameter(const SurfaceMesh& mesh, const std::vector<Vec3>& outward_normals,
                               const std::vector<char>& inward_ok, double L_max, int threads = 0);

// The same with the mesh's vertex_triangles (core/adjacency.h) given.
RayResults cast_local_diameter(const SurfaceMesh& mesh, const VertexTable& fans,
                               const std::vector<Vec3>& outward_normals, const std::vector<char>& inward_ok,
                               double L_max, int threads = 0);

} // namespace scalemesh
