#pragma once
// Volume-conserving Laplacian smoothing of a closed surface: paper section 2
// and Algorithm 6 ([13] Algorithm 4), 10 sweeps with omega = 1 after marching
// cubes, 10 sweeps with omega = 0.1 after each remeshing pass.
//
// The enclosed volume is V = (1/3) x_i . N_i + (terms without x_i), with
// N_i = (1/2) sum over the triangles (i, j, k) at i of (x_j x x_k) (DESIGN.md).
// Free nodes are relaxed in pairs, as [13] does for surfaces: a node and the
// neighbour whose Laplacian move changes the volume most in the opposite
// sense both make their full Laplacian moves, then one shared correction
// that restores the volume exactly (the change is linear in it). A single
// node moved orthogonally to N_i keeps the volume too, but cannot move along
// the normal at all, so it hardly removes the marching cubes staircase; it is
// the fallback for constrained nodes and for nodes without such a partner.
// Either way the volume is unchanged to round-off after every move.

#include "core/surface_mesh.h"

#include <vector>

namespace scalemesh {

struct SmoothingParams {
    int sweeps = 10;    // Gauss-Seidel sweeps through all nodes, >= 0
    double omega = 1.0; // under-relaxation of the Laplacian move, in (0, 1]
    double max_displacement = 0; // mm from a node's starting position; 0 = unbounded
};

// Optional per-node restrictions, for caps and openings. Each vector is either
// empty (no restriction of that kind) or holds one entry per mesh point.
struct SmoothingConstraint {
    std::vector<char> fixed;         // nonzero: the node never moves
    std::vector<Vec3> plane_normal;  // zero: free; else the node moves only within the
                                     // plane through it with this normal (any length)
};

// Smooths `mesh` in place. Each sweep is a Gauss-Seidel sweep (later nodes
// see earlier moves) in a fixed order: the nodes are put in a grid of cubic
// cells of side just over three times the longest edge, the cells coloured by
// the parity of their grid indices (eight colours), and a sweep takes the
// colours in turn, the cells of one colour in parallel and each cell's nodes
// in index order. Nodes in different cells of one colour are more than three
// edges apart, while a move reads only within two edges and writes within
// one, so the parallel sweep equals the sequential one in that order. The Laplacian move of node i
// is omega * (mean of its edge neighbours - x_i). A free node is relaxed with
// a free partner as above; otherwise its move has the component along N_i
// removed. With a plane constraint the move is also kept in the plane: it is
// projected orthogonally to both N_i and the plane normal (the line
// orthogonal to both); when the two are parallel to round-off the fan already
// lies in the plane and the move is kept in the plane only, which is then
// orthogonal to N_i as well. Nodes without triangles are left alone.
//
// With max_displacement > 0 no node ends farther than that from where it
// started: a pair move that would take a node farther is not made (the node
// falls back to the single-node move), and a single-node move is shortened
// along its own direction, which keeps it orthogonal to N_i.
//
// Guarantees: the signed volume (surface_facts) is conserved to round-off,
// fixed nodes keep their bit-exact positions, plane-constrained nodes stay in
// their plane to round-off, connectivity is untouched, and the result is a
// deterministic function of the input (bit-identical on every run and on any
// number of threads).
//
// Throws InputError when the mesh is not a closed, oriented 2-manifold or has
// a point that is not finite, when
// sweeps < 0, omega is outside (0, 1], max_displacement is negative or not
// finite, or when a constraint vector is
// neither empty nor the size of mesh.points.
void smooth_volume_conserving(SurfaceMesh& mesh, const SmoothingParams& params,
                              const SmoothingConstraint* constraint = nullptr);

} // namespace scalemesh
