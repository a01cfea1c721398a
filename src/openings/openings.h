#pragma once
// Inlets and outlets: paper section 3 ("M layers go across the outlet rather
// than into the outlet ... by constraining the physical tissue normals
// adjacent to each outlet to lie in the plane of that outlet").
//
//   cut_and_cap        the closed lumen surface is cut by each opening's plane,
//                      the part beyond it removed and the hole closed by a
//                      flat cap (its own patch, vertices on the plane)
//   cap_feature_size   Algorithm 1 with the normals of rim nodes and of the
//                      wall nodes next to them projected into the cap plane,
//                      so their layers run across the opening
//   ring_caps          after remeshing, each cap is rebuilt from its rim and
//                      the rim nodes' layer points laid out in the plane: the
//                      cap shows the same rings as a wall cross-section
//
// Patch ids of the surfaces made here: 0 is the wall, cap i (0-based, in the
// order of the returned caps) is patch i + 1.

#include "core/surface_mesh.h"
#include "layers/offset_points.h"
#include "sizing/feature_size.h"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace scalemesh {

enum class OpeningType { Inlet, Outlet };

// A plane through `point` whose unit `normal` points out of the lumen, away
// from the part of the anatomy that is kept.
struct Plane {
    Vec3 point;
    Vec3 normal;
    double signed_distance(const Vec3& x) const { return dot(x - point, normal); }
};

// An opening as the case file gives it: a clip plane (optionally with a
// radius picking the crossing whose centre lies within it of the point), or a
// side of the image border ("x-", "x+", "y-", "y+", "z-", "z+"), cut `inset`
// mm inside the outermost surface point on that side.
struct OpeningSpec {
    std::string name;
    OpeningType type = OpeningType::Outlet;
    bool border = false;
    Plane plane;          // clip plane (border == false)
    double radius = 0;    // mm; 0: the plane must cross the lumen exactly once
    std::string side;     // border == true
    std::optional<double> inset; // mm, border openings; empty: "auto", where the cross-section
                                 // stops shrinking (BorderRule)
    double extension = 0; // flow extension: length in diameters of the cap (2 sqrt(area / pi)); 0 = none
};

// The image's index-to-world map, x = origin + i a0 + j a1 + k a2, so that
// border sides follow the image axes (NIfTI direction matrices included).
struct ImageFrame {
    Vec3 origin{0, 0, 0};
    Vec3 axis[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    // Voxels per axis (the grid's "image_size" metadata): voxel centres lie
    // at index 0 .. size - 1, so the image faces are at index -1/2 and
    // size - 1/2, where marching cubes closes a mask that runs off the image.
    // 0: not known (a surface input, a phantom); the face of a side is then
    // taken at the outermost surface point on it.
    std::array<int64_t, 3> size{0, 0, 0};
};

// The automatic inset of a border opening (OpeningSpec::inset empty), in
// voxel widths along the side's axis, counted from the outermost surface
// point on the side:
// - a piece of the lumen "reaches" the side when its outermost point lies
//   within `reach` of the image face; a piece beyond the search depth's last
//   plane that does not is "short": reported, never capped;
// - the cross-section of each reaching piece (the part of the plane inside
//   it, summed over its crossings) is measured on planes 1, 2, ...,
//   `search_depth` voxels inside the outermost point; the search stops before
//   a plane where two reaching pieces are joined beyond it;
// - the inset is the first plane k from `first_plane` (from 1 where the
//   search stops before passing it) whose every reaching piece has at least
//   (1 - shrink_tolerance) of the area it has on plane k + 1 (the taper or
//   the rounding of the image face is behind it); when no plane qualifies
//   the deepest plane searched is used and a warning says so.
// The smoothed surface rounds over its last voxel or so at the image face
// even where the area has settled: on a tube of 7 voxels' radius the
// cross-section 1 voxel in has 98-99% of the straight section's area, but
// the wall there is tilted up to 0.49 (the axis component of its normal;
// 0.16 at 2 voxels, 0.08 on the straight part), and the prism columns on
// the rim triangles of 174 degrees it leaves were flat enough that 30 of 48
// such tubes (radius 6 to 8 voxels) gave their prism layers up; from 2
// voxels in, none did.
struct BorderRule {
    static constexpr int first_plane = 2;             // voxels
    static constexpr int search_depth = 10;           // voxels
    static constexpr double shrink_tolerance = 0.05;  // fraction of area per voxel
    static constexpr double reach = 2.0;              // voxels from the image face
    static_assert(1 <= first_plane && first_plane < search_depth);
};

struct Cap {
    std::string name;
    OpeningType type = OpeningType::Outlet;
    int32_t patch = 0;  // triangle_patch id of its faces
    Plane plane;
    double area = 0;    // mm^2 when made
    Vec3 centroid;      // area centroid when made
};

// A piece of the lumen near a border side that stops short of the image
// face: not capped, it stays a dead end of the lumen it belongs to.
struct ShortPiece {
    Vec3 tip;            // its outermost surface point on the side
    double distance = 0; // mm from the image face to the tip, along the side's axis
};

// Where a border opening was cut, and what it left.
struct BorderCut {
    std::string opening;
    std::string side;
    double inset = 0;       // mm inside the outermost surface point on the side (the plane's depth)
    double voxel = 0;       // mm, the voxel width along the side's axis
    bool automatic = false; // the inset was chosen by BorderRule
    bool stable = true;     // automatic: some plane of the search met the rule
    bool joined = false;    // automatic: the search stopped where two pieces of the cross-section join
    bool face_known = false; // ImageFrame::size was given; else distances are from the outermost point
    std::vector<ShortPiece> short_pieces;
};

struct CappedSurface {
    SurfaceMesh surface; // closed, oriented; triangle_patch set
    std::vector<Cap> caps;
    std::vector<BorderCut> borders;    // one per border opening, in the order given
    std::vector<std::string> warnings; // one line each, naming the opening: short pieces, an inset that never settled
};

// Cuts `surface` (closed, oriented 2-manifold, outward normals) at every
// opening and caps each crossing. A border opening becomes one cap per
// separate piece of its cross-section, named "<name>_1", "<name>_2", ... by
// decreasing area (just "<name>" when there is one piece); only the pieces
// of the lumen that reach the image face are capped (BorderRule), the others
// are listed in CappedSurface::borders and warnings.
//
// Every opening is planned on the input surface, independently of the
// others: its plane, the crossings it cuts, the part beyond them. A plane
// splits only the triangles of its chosen crossings, so planes may meet
// anywhere outside them. The result does not depend on the order of
// `openings` except for the patch numbers: caps are numbered in that order.
//
// With `extension` > 0 the opening is then extruded along its normal by
// that many cap diameters, as the paper did for the rat nose, so that inflow
// can develop before the anatomy: the rim is swept in steps of about its
// mean edge length into a straight tube (wall patch) and the cap moves to the
// end of it (Cap::plane follows). The extrusion is not checked against the
// rest of the anatomy: point it where nothing is in the way.
//
// Guarantees: the result is a closed, oriented 2-manifold; every vertex of a
// cap face lies on its plane to round-off (it is projected onto it); the cap
// faces of one cap tile the cross-section the plane cuts from the lumen.
//
// Throws InputError, naming the opening, when: a plane misses the lumen (or
// no crossing lies within `radius` of its point); a plane crosses the lumen
// in several places and no radius picks one; the part of the surface beyond
// the chosen crossing reaches back across the plane elsewhere (move the
// plane or give a radius); no part of the lumen reaches a border side; and,
// naming both, when the crossings of two openings meet (share a triangle of
// the surface) or one lies in the part another removes; two openings share
// a name; nothing would be left.
CappedSurface cut_and_cap(const SurfaceMesh& surface, const std::vector<OpeningSpec>& openings,
                          const ImageFrame& frame);

// The node classes the cap rules use.
struct CapNodes {
    std::vector<int32_t> cap_of;  // per point: cap index (>= 0) of a rim or cap-interior node, else -1
    std::vector<char> rim;        // per point: 1 on a border between the wall and a cap
    std::vector<char> interior;   // per point: 1 when every face around it is one cap's
    std::vector<char> next_to_rim; // per point: 1 for a wall node joined by an edge to a rim node
};
CapNodes classify_cap_nodes(const SurfaceMesh& surface, const std::vector<Cap>& caps);

// The sizing stage on a capped surface. As compute_feature_size, except:
// - the normal of a rim node, and of a wall node next to one, is its wall
//   normal (angle-weighted over wall faces only) projected into the cap plane
//   (component along the cap normal zero to round-off), then normalised;
// - a rim node's D is measured in the cap plane: along its constrained normal
//   to the far side of the rim polygon;
// - a cap-interior node takes the D of the nearest rim node of its cap;
// - rim and cap-interior nodes have D_out = +infinity and inward_ok = 0:
//   they shoot no layer points into the domain (their layer points lie in
//   the cap, see ring_caps).
// Throws as compute_feature_size does.
FeatureSize cap_feature_size(const SurfaceMesh& surface, const std::vector<Cap>& caps, const SizingParams& params);

struct RingParams {
    double M = 7;
    double growth = 1.0;           // as VolumeParams::growth
    FirstLayer first_layer = FirstLayer::paper; // as VolumeParams::first_layer, so the rings match the wall's layers
    double K = 4.2;                // the first layer's anisotropy with FirstLayer::edge
    double L_max = 0;              // mm, filler spacing min(D, L_max) / M
    double filter_fraction = 0.3;  // a point closer than this fraction of its spacing to a kept one is dropped
    // For prism layers ([volume] layers = "prisms"): each rim node's layer
    // points are the column its prisms stand on (layer_stack.h), laid
    // exactly (no shift, no filter, shortened as the stack shortens a column
    // that would pass D / 2), the rings joined by the quads of the rim
    // prisms' sides, each cut by the index rule as the prisms cut it; only
    // the region inside the last ring is triangulated with the filler points.
    std::vector<int32_t>* prism_columns = nullptr; // filled, when given: per node of the result x floor(M/2),
                                                   // the cap node of each layer of a rim node's column, -1
                                                   // for every other node
};

// Rebuilds every cap of `surface` (sized by cap_feature_size) from its rim:
// the rim nodes' Algorithm 4 points laid along their in-plane normals (layer
// points at lambda_m d, filler points at min(D, L_max)/M, up to D/2), kept
// when inside the rim and not crowding a kept point, triangulated with the rim
// as constraint (constrained Delaunay in the plane). Wall faces and rim nodes
// are kept with their ids; the old cap-interior nodes are dropped.
//
// `sizing` is replaced by the sizing of the result: the kept nodes keep
// theirs, a new node takes its generator's d and D, the cap normal, D_out =
// +infinity and inward_ok = 0. The new points follow the kept ones.
//
// Guarantees: closed oriented 2-manifold with the same Euler characteristic,
// cap vertices on their planes to round-off. Throws StageError when a cap
// cannot be triangulated (a rim crossing itself).
SurfaceMesh ring_caps(const SurfaceMesh& surface, const std::vector<Cap>& caps, FeatureSize& sizing,
                      const RingParams& params);

// The outward normal of each patch: zero for the wall (patch 0), the cap
// plane's normal for each cap, indexed by patch id.
std::vector<Vec3> patch_normals(const std::vector<Cap>& caps);

} // namespace scalemesh
