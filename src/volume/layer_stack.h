#pragma once
// Prism layers built explicitly (the volume stage's `prisms` layers): over
// every wall triangle, a stack of floor(M/2) prisms between the columns of
// its three nodes' layermaking points (Algorithm 4's points and heights,
// layer_columns), each prism cut into three tets by the index rule, so that
// every prism is intact by construction. The region above the stack (the
// core) is meshed apart (core_mesh.h), against the stack's top triangles.
//
// The index rule (Dompierre et al., IMR 1999): the side quad of two columns
// a < b between layers m - 1 and m is cut by the diagonal from a's point of
// layer m - 1 to b's point of layer m. Both prisms that share a quad cut it
// the same way, and no prism gets the cyclic (Schoenhardt) cut, since its
// lowest column starts two diagonals.
//
// Where columns would make a poor prism (a tet of its split below a fraction
// of the prism's volume, or a prism not star-shaped from its centroid as a
// cell must be: normals converging or crossing), stacks would collide (top
// triangles crossing) or a column's top would end just over a cap's fill
// (nearer one of `core_faces` than min_core_clearance of its longest edge,
// which leaves the core only flat tets there), whole columns are
// shortened, keeping their number of layers, as Netgen's growth limiter
// does: every wall node keeps all its layers. The first layer keeps its
// thickness (the wall-cell distance), and the others grow less
// (shortened_column, offset_points.h).

#include "core/surface_mesh.h"
#include "core/tet_mesh.h"
#include "layers/offset_points.h"

#include <cstdint>
#include <vector>

namespace scalemesh {

struct LayerStackParams {
    double min_tet_fraction = 0.05; // each tet of a prism's split has at least this fraction of the prism's volume
    double shrink = 0.8;            // a column of a poor prism is shortened by this factor a round,
    double min_scale = 0.1;         // down to this fraction of its height at most
    double slope = 0.3;             // a column's height fraction exceeds a neighbour's by at most this
    int max_rounds = 40;            // rounds of shortening at most
    double max_side_non_orthogonality_deg = 65; // a side face between two prisms of one layer beyond this
                                                // shortens their columns (a margin under the solver's 70)
    int relax_round = 12;           // from this round on, prisms that shortening does not mend are accepted
                                    // with thinner tets (build_layer_stack)
    // Per surface node x floor(M/2): the surface point that is layer m of a
    // rim node's column (RingParams::prism_columns), -1 elsewhere; empty
    // without openings. Such columns are fixed: they are the cap's nodes.
    std::vector<int32_t> rim_columns;
    std::vector<Triangle> core_faces; // the rest of the core's boundary (the caps inside their last rings),
                                      // over surface points (std::invalid_argument otherwise),
                                      // checked with the stack's against crossings, and for the clearance
                                      // of the columns' tops
    double min_core_clearance = 0.2;  // a column's top point nearer a core face than this times the face's
                                      // longest edge shortens the columns of the wall triangles around it
};

struct LayerStack {
    int32_t layers = 0;        // prisms per wall triangle (floor(M/2))
    int32_t surface_points = 0; // n: point ids below n are the surface's
    // The layer points, node by node: point n + first[v] + m - 1 is layer m of
    // wall node v (m = 1..layers); first[v] = -1 for a node without a column
    // of its own (not on the wall, or a rim node whose column is in its cap).
    std::vector<Vec3> points;
    std::vector<int32_t> first;
    std::vector<int32_t> rim_columns; // as given (LayerStackParams::rim_columns), or empty
    std::vector<int32_t> point_generator, point_layer; // per layer point
    std::vector<double> scale; // per surface node: the fraction of its column's height kept (1: all)
    std::vector<Tet> tets;     // three per prism, positively oriented, over ids < n + points.size()
    std::vector<Triangle> top; // the core's boundary along the wall: each prism stack's top, and around a
                               // hole its wall triangles, the side faces of the prisms beside it and,
                               // along a rim edge, the cap's strip between the edge's columns, all
                               // oriented outward from the core
    std::vector<int32_t> top_of; // per top triangle: its wall triangle (for a side face or a strip triangle,
                                 // the prism's or the bare wall triangle it bounds)
    int64_t prisms = 0;
    int64_t holes = 0;         // wall triangles left without layers: their prisms stayed poor after max_rounds
    int64_t shortened_nodes = 0; // nodes whose column is below its full height
    int64_t borrowed_columns = 0; // wall nodes without a trusted normal, given their neighbours' mean column
    int64_t lenient_prisms = 0;   // wall triangles whose prisms were accepted after relax_round (besides
                                  // those next to an opening)
    int rounds = 0;              // rounds of shortening
};

// The stack over the triangles of patch 0 (every other patch is an opening
// and gets no layers). A node of a wall triangle without a column (its
// inward check failed) borrows its neighbours' mean column; InputError when
// a whole region of such nodes has none to borrow. Columns start at their full
// height cut to D / 2 (d / 2 for a repaired normal), proportions kept.
// Wall triangles whose prisms are still poor after max_rounds get no layers
// (holes, which the core fills: along a rim edge, the cap's strip between the
// edge's two columns closes the hole); StageError when that strip is not two
// cap triangles per layer.
LayerStack build_layer_stack(const SurfaceMesh& surface, const FeatureSize& sizing, const LayerColumns& columns,
                             const LayerStackParams& params = {});

// The three tets of the prism with bottom `p` and top `q` (point ids, in
// the orientation of the wall triangle p, whose normal points away from q),
// by the index rule on the columns' ids `column`, each ordered to be
// positive in a right prism over p.
std::array<Tet, 3> prism_split(const std::array<int32_t, 3>& p, const std::array<int32_t, 3>& q,
                               const std::array<int32_t, 3>& column);

} // namespace scalemesh
