#pragma once
// The marching cubes case table, built at start-up from one face rule instead
// of typed in, so that its consistency between neighbouring cubes follows
// from construction (see marching_cubes.h).
//
// Corner c of a cube sits at offset (c & 1, (c >> 1) & 1, (c >> 2) & 1).
// Edge e joins corners kEdgeCorners[e][0] and kEdgeCorners[e][1], which differ
// along axis kEdgeAxis[e] (the first corner has the lower coordinate).

#include "isosurface/marching_cubes.h"

#include <array>
#include <cstdint>
#include <vector>

namespace scalemesh::mc {

extern const std::array<std::array<int, 2>, 12> kEdgeCorners;
extern const std::array<int, 12> kEdgeAxis;

struct CubeCase {
    // Triangles as triples of vertex ids, counter-clockwise seen from the
    // outside side (normals point from inside corners to outside corners).
    // Ids 0..11 are the crossings on cube edges; id 12 + j is a vertex inside
    // the cube at the mean of the crossings of centre_loops[j].
    std::vector<std::array<uint8_t, 3>> triangles;
    std::vector<std::vector<uint8_t>> centre_loops;
};

// Table indexed by the 8-bit mask of inside corners (bit c set: corner c inside).
const std::array<CubeCase, 256>& cube_table(InsideConnectivity connectivity);

} // namespace scalemesh::mc
