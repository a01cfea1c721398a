#pragma once
// What became of each surface node's layermaking points (paper section 2.3:
// floor(M/2) points from every wall node, "layers" across the whole lumen).
// A node's realised layers are its consecutive layermaking points m = 1, 2, ...
// that are in the final mesh within a stated tolerance of where Algorithm 4
// put them; for a node short of floor(M/2), the first missing layer's fate
// says why.

#include "core/feature_size.h"
#include "core/surface_mesh.h"
#include "layers/offset_points.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace scalemesh {

// Why a node's first missing layermaking point is missing. In the order the
// volume stage meets them.
enum class LayerLoss : int8_t {
    none = 0,    // all floor(M/2) layers
    normal,      // the node's inward check failed: no points along an untrusted normal
    short_ray,   // Algorithm 4 laid fewer: D / 2 reached first (d above D, as where D < L_min)
    filtered,    // the interior-point filter (section 4) dropped it for a nearby point of another node
    tiny_tet,    // Algorithm 5 (i): every cavity it could have had made a tet below the volume floor
    hidden,      // its cavity shrank to nothing: it saw no cavity facet strictly (or a protected edge)
    outside,     // located outside the surface (its ray crossed a wall) or on a vertex
    unused,      // inserted, but no inside tet kept it
    moved,       // in the mesh, but the improvement moved it beyond the tolerance
};
constexpr int kLayerLossKinds = 9;
const char* layer_loss_name(LayerLoss loss); // "none", "normal", "short_ray", ...

// The insertion's verdict on one offset point (delaunay_insertion.h).
enum class InsertionFate : int8_t { inserted = 0, tiny_tet, filler, hidden, outside };

struct LayerAccount {
    int32_t layermaking = 0;       // floor(M/2)
    double tolerance = 0;          // fraction of its layer spacing a point may have moved and still count
                                   // (infinite: wherever it is, as a prism layer in its column)
    std::vector<int32_t> realised; // per surface node: consecutive layermaking points in the mesh
    std::vector<LayerLoss> loss;   // per surface node: the first missing one's fate (none when all are there)
    std::vector<char> wall;        // per surface node: every triangle at it is in patch 0 (it casts its own
                                   // layer points); the others are opening nodes (cap rims and caps, whose
                                   // layers across the opening are the cap's rings)
    std::vector<char> eligible;    // per surface node: a wall node with D >= L_min (the paper's promise)

    int64_t wall_nodes = 0, opening_nodes = 0, eligible_nodes = 0;
    int64_t eligible_full = 0;     // eligible nodes with all floor(M/2) layers
    int64_t wall_full = 0;         // wall nodes with all of them
    double eligible_mean = 0;      // mean realised layers (at most floor(M/2)) over eligible nodes
    std::array<int64_t, kLayerLossKinds> eligible_losses{}; // eligible nodes by the fate of their first missing layer
    double max_displacement = 0;   // largest distance of a counted layermaking point from its place, over its
                                   // layer spacing
    int64_t stand_ins = 0;         // layermaking points not in the mesh (or moved too far) whose place has
                                   // another node's point of the same layer within the tolerance: where the
                                   // normals of several nodes converge, one point is on all their layers

    // eligible_full / eligible_nodes (1 with no eligible node).
    double coverage() const { return eligible_nodes ? double(eligible_full) / double(eligible_nodes) : 1.0; }
};

// One layermaking or filler point as it ended: which offset point it was
// (index into `kept`), and where it is now.
struct FinalPoint {
    int32_t offset = -1; // index into the kept offset points
    Vec3 position;
};

// Builds the account. `raw` are Algorithm 4's points, `kept` the filter's
// survivors (a subsequence of raw, in order), `fates` the insertion's verdict
// per kept point, `final_points` every interior point of the mesh that came
// from a kept point. A node's layer m is realised when a layermaking point of
// layer m is in the mesh within `tolerance` times the spacing of layer m of
// that node from the place Algorithm 4 gave the node's point: its own point,
// or (a stand-in) another node's. An infinite `tolerance` counts a node's own
// point wherever it ended and no stand-in (prism layers: the point is layer m
// of the node's column, shortened or not). Throws std::invalid_argument on sizes that
// do not match.
LayerAccount account_layers(const SurfaceMesh& surface, const FeatureSize& sizing, double M, double L_min,
                            const std::vector<OffsetPoint>& raw, const std::vector<OffsetPoint>& kept,
                            const std::vector<InsertionFate>& fates, const std::vector<FinalPoint>& final_points,
                            double tolerance);

} // namespace scalemesh
