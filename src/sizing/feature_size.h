#pragma once
// The feature size field of a closed surface: paper section 2.1 and
// Algorithm 1 (Algorithm 6, second and third lines). Raw local diameter D by
// ray casting along the synthetic normal, the outward distance D_out, the
// optional curvature term of section 4 eq. (12), then clamping and gradient
// limiting into the feature size d.

#include "core/feature_size.h"
#include "core/surface_mesh.h"

#include <cstdint>
#include <limits>
#include <vector>

namespace scalemesh {

struct SizingParams {
    double K = 4.2;  // anisotropy of the layer elements, > 0
    double M = 7;    // element layers across a cross-section, >= 1
    double G = 0.85; // gradient limit |d_i - d_j| <= G |x_i - x_j|, dimensionless, > 0
    double L_min = std::numeric_limits<double>::quiet_NaN(); // mm, required, 0 < L_min <= L_max
    double L_max = std::numeric_limits<double>::quiet_NaN(); // mm, required, finite
    bool curvature_term = false; // eq. (12): D = min(D_ray, 2 R_curvature); off as in the paper
    int threads = 0;             // ray casting threads; 0 = TBB default
};


// Algorithm 1 exactly: d = D; d = min(L_max, d); d = max(L_min, d);
// d = min(d, 2 (M/K) D_out); then gradient limiting over the directed surface
// edges: an edge i -> j with positive excess(i, j) = d_i - (d_j + G |x_i - x_j|)
// is relaxed by d_i = d_j + G |x_i - x_j| until no edge has positive excess.
// The paper pops the edge of largest excess; every order ends at the same
// field (below), and a mutable queue of nodes by tentative d, smallest first
// (Dijkstra's order), relaxes each edge once instead of several times.
//
// Guarantees on return, for every surface edge (i, j):
//   |d_i - d_j| <= G |x_i - x_j| (to round-off of the sum), and
//   d_i = min over j of (d0_j + G * (shortest edge-path length from i to j)),
// where d0 is the field after the three clamps: the largest field below d0
// that meets the gradient limit. Hence d <= min(L_max, max(L_min, D)) and
// d <= 2 (M/K) D_out everywhere, and d >= L_min wherever no 2 (M/K) D_out
// bound below L_min is within reach. D = +infinity is allowed (clamped to
// L_max); the result is deterministic.
// Throws InputError on invalid params (see compute_feature_size), when D or
// D_out do not match the points, or hold NaN or negative values.
std::vector<double> limit_feature_size(const SurfaceMesh& mesh, const std::vector<double>& D,
                                       const std::vector<double>& D_out, const SizingParams& params);

// The whole sizing stage: synthetic normals, inward check, rays (D, D_out),
// the curvature term when enabled, and Algorithm 1. d is finite and in
// [0, L_max] everywhere (0 only where the surface touches itself: D_out = 0).
// Throws InputError when the surface is not a closed, oriented 2-manifold, or
// when a parameter is out of range: K > 0, M >= 1, G > 0, 0 < L_min <= L_max,
// all finite, threads >= 0. Throws StageError when Embree fails.
FeatureSize compute_feature_size(const SurfaceMesh& mesh, const SizingParams& params);

} // namespace scalemesh
