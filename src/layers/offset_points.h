#pragma once
// Interior points of the layered volume mesh: paper Algorithm 4 (offset
// points along the inward synthetic normal) and the interior-point filter of
// section 4. The layer columns are shared: the volume stage lays its layers
// and prism stacks on them (layer_stack.h), the openings a cap's rings on
// its rim nodes' columns (ring_caps, openings.h).

#include "core/adjacency.h"
#include "core/feature_size.h"
#include "core/surface_mesh.h"

#include <cstdint>
#include <optional>
#include <vector>

namespace scalemesh {

// How thick the first layer is. `paper`: lambda_1 d (Algorithm 4, uniform
// d/M with growth 1), so the near-wall anisotropy is the surface's edge
// length over d/M, below K where the remeshed edges end short of K/M d.
// `edge`: the node's mean incident surface edge length over K (the
// anisotropy K that section 2.5 asks for near the wall), at most lambda_1 d;
// the other layermaking layers then grow geometrically so that the last one
// ends where the paper's does (floor(M/2)/M d from the wall): still
// floor(M/2) layers on each side, the M layers across.
enum class FirstLayer { paper, edge };

struct OffsetParams {
    double M = 7;         // element layers across a cross-section, >= 1 (Algorithm 4)
    double growth = 1.0;  // ratio lambda_{m+1} / lambda_m of the layermaking spacing, >= 1;
                          // 1 = uniform lambda_m = 1/M (the paper's default)
    FirstLayer first_layer = FirstLayer::paper;
    double K = 4.2;       // anisotropy of the first layer with FirstLayer::edge, > 0
    bool repair_normals = false; // a wall node whose normal failed the inward check gets its layermaking
                                 // points along a repaired direction (repaired_inward_direction), up to
                                 // d / 2 and no fillers; off, it gets no points
    double L_max = 0;     // mm, > 0: filler spacing is min(D, L_max) / M
    double filter_fraction = 0.1; // interior-point filter radius, fraction of min(d_a, d_b) / M, >= 0
    double filler_filter_fraction = 0.8; // a filler point's radius is at least this fraction of its own spacing
};

// One interior point x_i^m = x_i - dist n_i (n_i the outward unit normal).
struct OffsetPoint {
    Vec3 position;      // mm
    int32_t generator;  // surface node i
    int32_t layer;      // m >= 1
    bool filler;        // m > floor(M/2) (or past the layermaking range): a filler point
    double dist;        // mm from the generator along its inward normal
    double spacing;     // mm, the spacing lambda_m d_i or min(D_i, L_max) / M that placed it
};

// Layermaking spacings lambda_m, m = 1..floor(M/2), as fractions of d: all
// 1/M when growth == 1; otherwise geometric, lambda_{m+1} = growth lambda_m,
// scaled so that they sum to floor(M/2) / M (1/2 for even M, as the paper's
// uniform case reaches for odd M). Throws InputError when M < 1 or growth < 1.
std::vector<double> layer_fractions(double M, double growth);

// Spacings of node i's layermaking layers, as fractions of d_i, given its
// first layer's fraction `first` (FirstLayer::edge): first, then geometric
// to the same total as `lambda` (first is capped at lambda[0]; the ratio is
// found by bisection). Returns lambda itself when first >= lambda[0].
std::vector<double> edge_layer_fractions(const std::vector<double>& lambda, double first);

// A direction x for node v, as an outward normal, with dot(x, f) >= margin
// for every nonzero triangle normal f of its fan (so -x points into the
// volume from every triangle at v), found from `start` by pushing away from
// the worst triangle; nullopt when none is found (a fan folded so far that
// no such direction exists, or one too narrow for the margin).
std::optional<Vec3> repaired_inward_direction(const SurfaceMesh& surface, const VertexTable& fans, int32_t v,
                                              const Vec3& start, double margin = 0.1);

// Each surface node's column of layermaking points, as Algorithm 4 lays
// them (with FirstLayer::edge, the fractions of edge_layer_fractions) but
// not cut short at D / 2: what offset_points walks, and what a stack of
// prism layers is built from (layer_stack.h).
struct LayerColumns {
    int32_t layers = 0;          // floor(M / 2), the points per column
    std::vector<Vec3> inward;    // per node: the unit direction of its points into the volume
    std::vector<double> dist;    // per node, `layers` entries: mm from the node of its points m = 1..layers;
                                 // NaN for a node with no column (its inward check failed and its normal
                                 // was not repaired, or d <= 0)
    std::vector<double> spacing; // likewise: the spacing of each point, dist[m] - dist[m - 1]
    std::vector<char> repaired;  // per node: its direction is repaired_inward_direction's
};
LayerColumns layer_columns(const SurfaceMesh& surface, const FeatureSize& sizing, const OffsetParams& params);

// A column's distances `dist` (layers entries, increasing) shortened to
// `scale` (<= 1) of its height: the first layer as thick as before, the
// others growing geometrically to the new height; all layers equal where
// the first no longer fits that way. `dist` itself for scale >= 1.
std::vector<double> shortened_column(const double* dist, int32_t layers, double scale);

// Algorithm 4 for every surface node i: layermaking points at cumulative
// distances sum_{k<=m} lambda_k d_i for m = 1..floor(M/2) (with
// FirstLayer::edge, the fractions of edge_layer_fractions), then filler points
// every min(D_i, L_max) / M, all while dist <= D_i / 2. A node whose inward
// check failed (sizing.inward_ok[i] == 0) or with d_i <= 0 gets no points:
// its normal cannot be trusted to point into the volume. Points are ordered
// by node, then by layer (the nodes are processed in parallel, each into its
// own slice). Throws InputError when the sizing fields do not
// match the surface or a parameter is out of range.
std::vector<OffsetPoint> offset_points(const SurfaceMesh& surface, const FeatureSize& sizing,
                                       const OffsetParams& params);

// Section 4's interior-point filter: of two points from different generators
// closer than filter_fraction * min(d_a, d_b) / M, the one farther from its
// generator is dropped (ties: the later one); a filler point is dropped as
// well when the other is closer than filler_filter_fraction times the
// filler's own spacing (fillers of many generators converge on the axis of
// a tube much wider than L_max). Greedy in order of distance to the
// generator: a point goes when a point kept before it is that close.
// Over the points sorted by the cell of a uniform grid, the points with no
// close point before them at all (nearly all) are found in parallel and
// kept; only the others are walked in order. Memory stays linear in the
// points however many are close together. Returns the kept points in their
// input order; the result does not depend on the number of threads.
std::vector<OffsetPoint> filter_interior_points(const std::vector<OffsetPoint>& points, const FeatureSize& sizing,
                                                const OffsetParams& params);

} // namespace scalemesh
