#pragma once
// Algorithm 5 on CGAL's Delaunay_triangulation_3, and the exterior removal:
// the one translation unit of the volume stage that includes CGAL.

#include "core/surface_mesh.h"
#include "core/tet_mesh.h"
#include "layers/offset_points.h"
#include "volume/layer_account.h"

#include <array>
#include <cstdint>
#include <vector>

namespace scalemesh {

struct InsertionParams {
    int passes = 3;                    // passes over the not yet inserted points, >= 1
    double min_volume_fraction = 1e-3; // (i): no new tet below this fraction of spacing^3 (cavity shrunk)
    double layer_shift = 0.15;         // a refused layermaking point is tried again up to this fraction of its
                                       // spacing along its normal (the layer tolerance), 0: not at all
    std::vector<std::array<int32_t, 2>> protected_edges; // surface-point pairs no new tet may contain (the
                                                         // cavity is shrunk; diagonals of failed quads)
};

struct InsertionResult {
    std::vector<Vec3> points;       // surface points 0..n-1, then the interior points used by `tets`
    std::vector<int32_t> source;    // per point: the surface node (< n) or n + index into the offset points
    std::vector<Tet> tets;          // the cells inside the surface, positively oriented
    std::vector<int32_t> missing_triangles; // surface triangles that are not facets, or whose sides clash
    std::vector<std::array<int32_t, 4>> quads; // surface quads (a, b, c, d), triangles (a, b, c) and (a, c, d),
                                               // meshed through their stand-ins (a, b, d) and (b, c, d)
    std::vector<std::array<int32_t, 2>> quad_triangles; // per quad: the ids of (a, b, c) and (a, c, d)
    std::vector<Triangle> triangles; // the surface triangles, ids kept, after the flips below
    int64_t surface_flips = 0; // surface edges flipped before insertion so that both triangles are facets
    int64_t inserted = 0, rejected_small = 0, rejected_filler = 0;
    int64_t rejected_surface = 0; // the point does not see a surface triangle bounding its cavity
    int64_t rejected_other = 0;   // outside the surface or on a vertex
    int64_t unused = 0; // inserted interior points with no inside cell
    int64_t deferred = 0; // points handed from a parallel task to the sequential pass, once a pass
    std::vector<InsertionFate> fates; // per offset point: the last verdict on it
    double seconds_insertion = 0, seconds_classify = 0;
};

// Inserts the surface points (spatially sorted), finds the sides of the
// cells exactly, without coordinates: every surface triangle that is a facet
// separates an inner from an outer cell (by the exact orientation of its
// outward normal against the opposite vertex), and a flood fill through the
// other facets carries the side to every cell; the infinite cells are
// outside. Then inserts the offset points layer by layer (each layer
// spatially sorted) with the conditions of Algorithm 5, `passes` times, each
// insertion cavity confined to the inside so that the surface triangles stay
// facets (see the .cpp), and returns the inside cells. Quads of two surface triangles that the Delaunay triangulation
// splits along the other diagonal are listed in `quads`; `tets` are then
// bounded by their stand-in triangles (a, b, d), (b, c, d), to be repaired
// by repair_surface_quads. When another surface triangle is missing the
// result lists it, no point is inserted and `tets` is empty. Throws InputError when two surface points coincide.
InsertionResult insert_and_classify(const SurfaceMesh& surface, const std::vector<OffsetPoint>& points,
                                    const InsertionParams& params);

} // namespace scalemesh
