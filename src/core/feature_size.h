#pragma once
// FeatureSize: the sizing stage's field on a surface's vertices
// (sizing/feature_size.h computes it), handed to the stages that place
// points and layers by it (volume, openings, remeshing) as plain arrays, so
// that they need not link the sizing stage.

#include "core/vec3.h"

#include <cstdint>
#include <vector>

namespace scalemesh {

struct FeatureSize {
    std::vector<double> D;     // mm, raw local diameter (with the curvature term when enabled)
    std::vector<double> D_out; // mm, outward local diameter, +infinity where the ray escapes
    std::vector<double> d;     // mm, feature size after Algorithm 1
    std::vector<Vec3> normals; // outward unit synthetic normals, eq. (6)
    std::vector<char> inward_ok; // 1 where the normal passed the inward check
    int64_t escaped_inward_rays = 0; // inward rays that leaked out (D = L_max there)
    double seconds_rays = 0;   // ray casting wall time
    double seconds_bvh = 0;    // BVH build wall time
    double seconds_limit = 0;  // Algorithm 1 wall time
};

} // namespace scalemesh
