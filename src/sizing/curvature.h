#pragma once
// Principal curvature estimate for the curvature term of the feature size,
// paper section 4, eq. (12): D = min(D_ray, 2 R_curvature), with R_curvature
// the principal radius of curvature of smallest magnitude.

#include "core/surface_mesh.h"

#include <vector>

namespace scalemesh {

// Per point: 1 / max(|kappa_1|, |kappa_2|) in mm, from a least-squares fit of
// the height function z = a x^2 + b xy + c y^2 + d x + e y over the 1-ring (and
// the 2-ring where the 1-ring has fewer than 5 points), in the frame of the
// given normal at the point. The linear terms absorb a tilt of the normal.
// Exact for points sampled from a quadric graph; on a sphere of radius R
// sampled at edge length h it is R to O(h^2 / R^2). +infinity where the
// surface is flat, the normal is zero or the fit is singular (no bound).
// Throws InputError when normals.size() != mesh.points.size().
std::vector<double> curvature_radius(const SurfaceMesh& mesh, const std::vector<Vec3>& normals);

} // namespace scalemesh
