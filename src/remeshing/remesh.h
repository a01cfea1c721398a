#pragma once
// Surface remeshing to the feature size: paper section 2.2 and the surface
// loop of Algorithm 6. Node merging (Algorithm 3, damage and fold checks of
// Appendix A), edge swaps (Fig. 9, damage of Appendix B) and Rivara edge
// bisection (Algorithm 2) bring the edge length at x to between K/(2M) d(x)
// and K/M d(x), alternated with volume-conserving smoothing.

#include "core/surface_mesh.h"
#include "sizing/feature_size.h"

#include <cstdint>
#include <vector>

namespace scalemesh {

struct RemeshParams {
    double K = 4.2;  // anisotropy: target edge length K/M d, > 0
    double M = 7;    // layers across a cross-section, >= 1
    int cycles = 3;  // Algorithm 6's "For i = 1,3": merge/swap, bisect, smooth; >= 0
    int smoothing_sweeps = 10;     // volume-conserving smoothing after each cycle, >= 0
    double smoothing_omega = 0.1;  // its under-relaxation, in (0, 1]
    double max_displacement = 0;   // mm a node may move in one smoothing call; 0 = unbounded
    // Keep the enclosed volume: each merge moves the surviving node along its
    // fan's area normal by the amount that keeps the volume exactly, and
    // after each cycle's merges and swaps the volume the swaps changed is
    // given back by small moves along the normals. Without it a convex
    // surface loses a few percent of its volume at the paper's sizes, since
    // every merge there cuts a chord. false: the paper's merge, j stays put.
    bool conserve_volume = true;
    // Per triangle patch id (SurfaceMesh::triangle_patch): the normal (any
    // length) of the plane a flat patch lies in (an inlet or outlet cap,
    // every point of its triangles on one plane), or the zero vector for a
    // curved patch (the wall, patch 0). Ids past the end are curved.
    std::vector<Vec3> patch_normals;
    // In the last cycle (before its merges and after its bisections), even
    // out the nodes along each rim of a flat patch (an opening's cap): each
    // rim node moves along the input's rim (the polyline of its border
    // edges as given, on the cap's plane and the wall) toward the middle of
    // its two rim neighbours. Merges along a rim may only end on an input
    // point and only where the chord stays close to the curve, which leaves
    // short rim edges between long ones; the prism layers' columns of their
    // nodes, which run across the cap, then close in on each other and the
    // cap's fill makes needles there (the tube at M = 14 gives its prisms up
    // for one). The pipeline sets it for the prism layers only (the paper's
    // layers, built on the same cap by Delaunay insertion, keep the
    // remeshing as it was). With it, the bend of
    // validation/curved_validation.py at M = 28 made Gmsh's boundary
    // recovery of the prism layers' core crash (a segmentation fault in
    // TetGen's flip31, Gmsh 4.8), which the core's child process turns into
    // the paper's layers (core_mesh.h); bounding the moves further gave the
    // prisms up on the multiscale study's stepped tube.
    bool relax_rims = false;
    // Merges in parallel: in a cycle that starts with at least this many
    // vertices (live faces / 2), each merge_nodes call (the merges to their
    // fixed point, once per round of merges and swaps) over 2,048 dirty
    // nodes or more first merges
    // in the cubes of a grid, all cubes at once, each node only while every
    // node within two edges of it lies in its cube; then once more on the
    // grid shifted by half a cube, so that the nodes left along the first
    // grid's faces merge inside cubes too; the nodes left then go to the
    // serial merges, to the fixed point as without it. The cube's side is
    // parallel_merge_cube target edge lengths K/M d at the median d, but no
    // more than a quarter of the surface's longest side and no less than 4
    // of those lengths. The cubes depend on the surface and these numbers
    // alone, never on the thread count, so the result is the same on any
    // number of threads. 0 or less: serial merges only.
    int32_t parallel_merge_vertices = 65536;
    double parallel_merge_cube = 12; // > 0
    SizingParams sizing; // recomputes the stable d on the final surface (section 2.1); L_min, L_max required
};

// What one Algorithm 6 cycle did.
struct RemeshCycle {
    int64_t merges = 0;
    int64_t cube_merges = 0; // of merges, those made in cubes at once (RemeshParams::parallel_merge_vertices)
    int64_t swaps = 0;
    int64_t bisections = 0;
    int64_t triangles = 0; // after the cycle's smoothing
    double max_volume_offset = 0; // mm, largest node move giving back the swaps' volume
    double seconds = 0;
};

struct RemeshResult {
    SurfaceMesh surface;           // closed, oriented; same topology as the input
    std::vector<double> target_d;  // mm per point: the input d carried along (interpolated on bisection)
    FeatureSize sizing;            // recomputed on `surface` with params.sizing: the stable d
    int64_t merges = 0;
    int64_t cube_merges = 0;      // of merges, those made in cubes at once
    int64_t swaps = 0;
    int64_t bisections = 0;
    double max_damage = 0;         // mm, largest damage of an accepted merge or swap
    std::vector<RemeshCycle> cycles;
    double seconds_sizing = 0;     // the final compute_feature_size
};

// Algorithm 6, surface part:
//   for cycle in 1..cycles {
//     do { merge_nodes (Algorithm 3); swap_edges (Fig. 9, Appendix B) } until nothing changes;
//     bisect_long_edges (Algorithm 2);
//     smooth_volume_conserving(smoothing_sweeps, smoothing_omega, max_displacement);
//   }
// with relax_rims, the last cycle's rims evened before its merges and after
// its bisections (the volume it moves given back); on a large surface each
// merge_nodes over many dirty nodes starts in cubes at once
// (RemeshParams::parallel_merge_vertices).
// then compute_feature_size on the result with params.sizing.
//
// `d` is the feature size (mm) per input point (compute_feature_size(...).d);
// values below L_min/10 are raised to it, so that a surface touching itself
// (d = 0 there) is not refined without end. With t(x) = K/M d(x):
// - merge i -> j only when |x_i - x_j| < t(x_i)/2, the damage of eq. (A.1)
//   is below t(x_i)/30 (with conserve_volume: the height of x_i over the new
//   triangles with j moved, or of j's total volume-keeping move over them,
//   whichever is larger), no new triangle normal makes a non-positive dot
//   product with the area-weighted normal (A.2) of the fan it came from
//   (A.3), and the smallest inscribed radius of the changed triangles is at
//   least half what it was, or at least what it was when that was below
//   t(x_i)/20 (the paper's "tightened further"); neighbours j are tried by
//   increasing distance.
// - swap an edge when that raises the smallest of the six angles of its two
//   triangles, the damage of merging the edge midpoint into the new edge
//   (Appendix B) is below t/30 (d averaged over the old edge), and A.3 holds.
// - bisect at the midpoint every edge longer than the smaller t of its ends,
//   refining the terminal edge of its Rivara chain first; d is interpolated.
// Merges and swaps never change topology: a merge needs the link condition
// (i and j share exactly the two neighbours opposite their edge) and leaves
// every vertex with at least three neighbours; a swap never creates an edge
// that exists.
//
// Patches (surface.triangle_patch, with params.patch_normals): every face
// keeps its patch, and edges between patches are never swapped (swaps inside
// a patch, flat or not, are). A node inside a patch may merge into any
// neighbour, a wall node into a rim node too. A rim node (on the border
// between exactly two patches, one of them flat, with exactly two border
// edges) may merge into the neighbour along one of its border edges when
// that neighbour is an input point, which stays put: the rim keeps to its
// input polyline and to the cap's plane (with relax_rims, the last cycle
// slides rim nodes along that polyline, each move made only where no
// triangle of its fan turns more than 30 degrees or keeps less than a
// fifth of its area). The usual tests apply to the
// triangles on both sides, the fold test against each side's own fan
// normal, and the damage also counts the sagitta of the arc through the rim
// node and its two rim neighbours over the chord that replaces them.
// Corners (three or more patches), other border nodes and borders between
// two curved patches are never merged away. With conserve_volume, nodes on
// a border or inside a flat patch never make the volume-keeping moves (a
// merge into them keeps the volume change, given back by the free nodes
// nearby). Bisection splits rim and cap edges at their midpoints, on the
// plane to round-off. Smoothing keeps border nodes fixed and moves nodes
// inside a flat patch only within its plane.
//
// Guarantees: the result is a closed, oriented 2-manifold with the input's
// Euler characteristic and component count, and every face on its input
// patch; points of flat patches stay on their planes to round-off; every
// accepted merge and swap has damage below t/30 at its node; no edge is
// longer than t at the smaller d of its ends after the last bisection (but
// next to a rim node the rims' relaxation moved, whose edges it may
// lengthen; the last smoothing then moves nodes a little); with conserve_volume the
// enclosed volume is the input's to round-off. Deterministic for a given
// input and parameters, whatever the number of threads (the cubes' merges,
// the smoothing and the sizing run in parallel, the rest serially).
//
// Coarsening stops where the next merge would exceed the damage limit, not
// only at merge_length: where the surface bends with a radius near d/2 (a
// tube or sphere whose d is its diameter) edges stay at about 0.3 to 0.5 t,
// since a chord of length L there lies L^2/(4d) off the surface and t/30 =
// d/50 allows L up to about 0.47 t at best. The band [t/2, t] of section 2.2
// is reached where d is well below the radius of curvature (d clamped by
// L_max, as in the paper's examples).
//
// Throws InputError when the surface is not a closed, oriented 2-manifold,
// when d does not hold one finite value >= 0 per point, or when a
// parameter is out of range (K > 0, M >= 1, cycles >= 0, sweeps >= 0,
// omega in (0, 1], max_displacement >= 0, parallel_merge_cube > 0, sizing L_min/L_max as
// compute_feature_size requires), when a patch normal is not finite, or
// when the points of a patch given as flat lie farther than 1e-6 of the
// bounding box diagonal from one plane with its normal. Throws StageError
// if sizing fails.
RemeshResult remesh_to_feature_size(const SurfaceMesh& surface, const std::vector<double>& d,
                                    const RemeshParams& params);

// Per point: the mean over its edges of length / (K/M d_edge), d_edge the
// mean of d at the edge's two ends; the view `scalemesh surface --remesh`
// writes. 0 for points without edges. Throws InputError when d does not hold
// one value per point.
std::vector<double> edge_length_ratio(const SurfaceMesh& surface, const std::vector<double>& d, double K, double M);

} // namespace scalemesh
