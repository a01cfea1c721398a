#pragma once
// Tet mesh improvement, paper section 2.4: flips with the volume criterion,
// then sliver removal (own design, in the spirit of the paper's tet crushing).
// The surface's quads and caps: surface_repair.cpp; the flips: flips.cpp;
// sliver removal: sliver_removal.cpp; the passes for face
// non-orthogonality and dihedral angles: cell_passes.cpp, their measures
// cell_measures.cpp; all edit through the tet editor of tet_editor.h, and
// the flips and sliver removal run in slabs (slab_scheduler.h).

#include "core/adjacency.h"
#include "core/surface_mesh.h"
#include "core/tet_mesh.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace scalemesh {

// Re-triangulates the tets at edge (b, d) of each quad so that the quad's
// own triangles (a, b, c), (a, c, d) bound the mesh instead of (a, b, d),
// (b, c, d): the chain of tets b d r_i r_{i+1} from a to c becomes the cones
// from b and from d over a triangulation of the polygon a r_1 ... r_k c
// (edge removal, the best smallest aspect ratio). Where no triangulation
// keeps every tet positive, a new interior point m below the middle of
// (b, d) (appended to mesh.points) splits the tets at (b, d), and the tets
// (a, c, b, m), (a, d, c, m) close the quad. Returns the quads where both
// fail, leaving them as they were.
std::vector<int32_t> repair_surface_quads(TetMesh& mesh, const std::vector<std::array<int32_t, 4>>& quads);

// A surface quad (a, b, c, d) that repair_surface_quads could not put back
// on its diagonal (a, c) is still meshed, on the inside, up to the Delaunay
// facets (a, b, d), (b, c, d) that stood in for it. The surface can take
// those two triangles instead: an edge flip of the surface, which moves the
// enclosed volume by the tet (a, b, c, d) alone. For each quad in `which`
// (indices into `quads`, whose triangles (a, b, c), (a, c, d) have the ids
// `quad_triangles`), the flip is made in `triangles` (a copy of
// surface.triangles, the two ids keeping their patch) when
// surface_flip_allowed. Returns the quads of `which` not flipped.
// Whether the surface may flip the diagonal (a, c) of its triangles
// `ids` = {(a, b, c), (a, c, d)} of `triangles` to (b, d): (b, d) is not
// in `edges` (the surface's undirected edges, (min, max)), both triangles
// are in one patch, and the normals of (a, b, d) and (b, c, d) are within 60
// degrees of each other and of the quad's.
bool surface_flip_allowed(const SurfaceMesh& surface, const std::array<int32_t, 4>& quad,
                          const std::array<int32_t, 2>& ids, const EdgeSet& edges);

std::vector<int32_t> flip_surface_quads(const SurfaceMesh& surface, const std::vector<std::array<int32_t, 4>>& quads,
                                        const std::vector<std::array<int32_t, 2>>& quad_triangles,
                                        const std::vector<int32_t>& which, std::vector<Triangle>& triangles);

// A flat tet of four surface points with two faces on the boundary, sharing
// the edge (p, q), is a cap over the surface that no flip or interior move
// can improve. Taking it out of the mesh makes its other two faces, which
// each had one more tet, the boundary: the surface's diagonal (p, q) flips to
// the tet's other edge (r, s). Made for tets with aspect ratio below
// `threshold` where that keeps the boundary a 2-manifold with the same
// patches and no fold: (r, s) is not already a boundary edge, both faces are
// in one patch, and the new faces' normals are within 60 degrees of each
// other and of the old pair's. The two boundary faces keep their ids and
// patch. Returns the number of tets taken out.
int64_t peel_surface_caps(TetMesh& mesh, int32_t surface_points, double threshold);

struct FlipCounts {
    int64_t flips_32 = 0, flips_23 = 0, flips_44 = 0;
    int64_t edge_removals = 0; // five to seven tets around an edge, by the quality passes only
    int64_t total() const { return flips_32 + flips_23 + flips_44 + edge_removals; }
};

// Section 2.4: a 3-2 flip of an interior edge with three tets is made when
// the smaller of the two new tets has more than 3 times the volume of the
// smallest of the three old ones; the 2-3 flips of interior faces and the
// 4-4 flips of interior edges with four tets that meet the same criterion
// are made too. The search starts from tets with aspect ratio below 0.3
// (see flips.cpp). Sweeps until nothing flips, at most `sweeps` times.
// Surface faces (faces with one tet) are never touched, no point moves, the
// boundary faces stay the same, every new tet is positively oriented, and
// the union of the tets is unchanged (so is the total volume, to round-off).
// mesh.tet_fields are cleared (they no longer match the tets).
// From 200k tets on, the mesh is cut into up to four slabs (one per 100k
// tets) improved at once, then the tets near the cuts (slab_scheduler.h); the
// result depends on the mesh alone, not on the number of threads.
FlipCounts flip_volume_criterion(TetMesh& mesh, int sweeps);

struct SliverCounts {
    int64_t flips = 0; // quality-improving flips
    int64_t moves = 0; // accepted interior point moves
};

// Sliver removal for tets with aspect ratio below `threshold`: first flips
// (2-3, 3-2, 4-4) that raise the smallest aspect ratio of the tets they
// replace, then small moves of interior points (ids >= surface_points) of
// such tets, each accepted only when it raises the smallest aspect ratio of
// the point's incident tets and keeps all of them positively oriented
// (line search along the gradient of the worst incident tet's aspect ratio,
// and the star's centroid). At most `sweeps` rounds. Surface points never
// move, so the boundary is bit-identical. A point v with layers[v].slack
// > 0 (a layer point) stays within that distance of the plane through
// layers[v].home at right angles to layers[v].normal (its direction from
// its surface node), so it stays on its layer; an empty `layers`, or a zero
// slack, leaves a point free. Then, for at most 3 rounds, the tets still
// below 0.1 get flips and moves with every interior point free: a layer
// point leaves its layer only where the mesh is poor. In slabs at once, as
// flip_volume_criterion, with the same result on any number of threads.
struct LayerBound {
    Vec3 home, normal;   // the point's place on its layer, the unit normal of the layer there
    double slack = 0;    // how far it may leave the layer along the normal
    bool on_normal = false; // it moves only along `normal` through `home` (within slack), not in a ball
    bool fixed = false;  // it never moves, as a surface point (improve_orthogonality, raise_dihedral_angles)
};
SliverCounts remove_slivers(TetMesh& mesh, int32_t surface_points, double threshold, int sweeps,
                            const std::vector<LayerBound>& layers = {});

// A tet below `threshold` whose four vertices are surface points (what
// remove_slivers cannot touch) gets one of its edges that is not a surface
// edge split by a new interior point (appended to mesh.points), placed where
// the new tets are best, when their smallest aspect ratio beats the old
// tets' and `at_least`. No surface edge is split, so the boundary is
// bit-identical (mesh.boundary_faces must hold it). Returns the splits;
// scans the tets and returns 0 without building anything when there is no
// such tet. The volume stage splits where that reaches the quality floor,
// then peels caps (peel_surface_caps), then splits what is left wherever
// that is better at all. With surface_points_only false, any tet below
// `threshold` qualifies: the last resort for a sliver whose interior points
// are layer points held on their layers.
int64_t split_surface_slivers(TetMesh& mesh, int32_t surface_points, double threshold, double at_least,
                              bool surface_points_only = true);

struct OrthoCounts {
    int64_t faces_before = 0; // interior faces beyond the bound at the start
    int64_t flips = 0, moves = 0;
    int64_t splits = 0; // interior edges split for a face beyond 70 degrees (the last resort)
};

// Face non-orthogonality as OpenFOAM measures it (the angle between an
// interior face's normal and the join of its two tets' centroids): for at
// most `sweeps` rounds, each interior face beyond `max_angle_deg` gets a
// flip (2-3, 3-2, 4-4) or an edge removal (an interior edge with five to
// seven tets replaced by the best triangulation of its ring) at one of its
// two tets, else moves of their interior
// points, each accepted when it lowers the worst non-orthogonality of the
// faces it changes and leaves no new tet below aspect ratio 0.1 or a
// dihedral angle of 10 degrees (or the old tets' own, if lower). Surface
// points never move; a layer point stays within layers[v].slack of
// layers[v].home (one already outside stays put). Then, as a last resort,
// a face still beyond 70 degrees gets an interior edge of one of its tets
// split by a new free point under the same rule (no surface edge is split,
// so the boundary is bit-identical), twice at most. In slabs at once, as
// improve_cells: the same result on any number of threads.
//
// `locked_tets`: the first that many tets of mesh.tets (the layer prisms of
// layers = "prisms") are never replaced, neither flipped nor split, and are
// not improved for their own sake; a point move keeps them positive and
// within the floors as any tet at the point, and they stay the first tets.
OrthoCounts improve_orthogonality(TetMesh& mesh, int32_t surface_points, double max_angle_deg, int sweeps,
                                  const std::vector<LayerBound>& layers = {}, int32_t locked_tets = 0);

struct DihedralCounts {
    int64_t tets_before = 0; // tets below the target at the start
    int64_t flips = 0, moves = 0, splits = 0;
};

// Raises the smallest dihedral angle of the tets below `target_deg`
// (degrees): for at most `sweeps` rounds, each such tet gets a flip (2-3,
// 3-2, 4-4) or an edge removal at it, else a flip at one of the tets around
// its edges, else moves of
// its interior points (an optimisation of the worst dihedral angle of the
// point's star, a layer point within layers[v].slack of layers[v].home); a
// change is kept when it raises the smallest dihedral angle of the tets it
// replaces and leaves no new tet below aspect ratio 0.1 or face beyond 70
// degrees of non-orthogonality (or the old tets' own, where those already
// miss them). Then a tet still below gets one of its interior edges split
// by a new free point under the same rule, twice at most. Surface points
// never move and no surface edge is split: the boundary is bit-identical
// (mesh.boundary_faces must hold it). In slabs at once, as improve_cells:
// the same result on any number of threads. `locked_tets` as for
// improve_orthogonality.
DihedralCounts raise_dihedral_angles(TetMesh& mesh, int32_t surface_points, double target_deg, int sweeps,
                                     const std::vector<LayerBound>& layers = {}, int32_t locked_tets = 0);

// The prisms of a layer stack as the cells the solver will see (the
// `prisms` layers, layer_stack.h): the cell passes measure a face of a
// prism's tet from the prism's centre, not the tet's, since the prism is
// written as one cell (layer_prisms.h).
struct PrismCells {
    std::vector<int32_t> generator, layer;      // per mesh point: its column's wall node and layer; -1 elsewhere
    std::vector<std::array<int32_t, 6>> points; // per prism: its bottom's three points, then its top's, by wall node
    std::vector<Vec3> start;                    // the mesh's points as the passes begin
    int32_t top_layer = 0;                      // the layer of the stack's top points
    struct KeyHash {
        size_t operator()(const std::array<int32_t, 4>& k) const
        {
            uint64_t h = 0xcbf29ce484222325ull;
            for (int32_t x : k) h = (h ^ uint32_t(x)) * 0x100000001b3ull;
            return size_t(h);
        }
    };
    std::unordered_map<std::array<int32_t, 4>, int64_t, KeyHash> index; // (wall nodes ascending, top layer) -> prism

    bool in_top_layer(int64_t p) const { return layer[points[p][5]] == top_layer; }
    // The prism whose three tets include one with the mesh points g, or -1.
    int64_t prism_of(const std::array<int32_t, 4>& g) const
    {
        std::array<int32_t, 4> key{-1, -1, -1, -1};
        int count = 0, lo = 1 << 30, hi = -1;
        for (int32_t v : g) {
            if (size_t(v) >= generator.size() || generator[v] < 0) return -1;
            lo = std::min(lo, layer[v]), hi = std::max(hi, layer[v]);
            if (std::find(key.begin(), key.begin() + count, generator[v]) == key.begin() + count) {
                if (count == 3) return -1;
                key[count++] = generator[v];
            }
        }
        if (count != 3 || hi != lo + 1) return -1;
        std::sort(key.begin(), key.begin() + 3);
        key[3] = hi;
        const auto it = index.find(key);
        if (it == index.end()) return -1;
        const auto& six = points[it->second];
        for (int32_t v : g)
            if (std::find(six.begin(), six.end(), v) == six.end()) return -1;
        return it->second;
    }
};

// The schedule of the two passes above as the volume stage runs them
// (improve_cells): a dihedral pass, then rounds of a non-orthogonality pass
// and a dihedral pass while either still changes the mesh.
struct CellPassParams {
    double dihedral_target_deg = 12; // degrees: the tets below it are raised (a margin over the floor of 10)
    int dihedral_sweeps = 8;         // sweeps of each dihedral pass
    double ortho_bound_deg = 65;     // degrees: the faces beyond it are mended (a margin under OpenFOAM's 70)
    int first_ortho_sweeps = 12;     // sweeps of the first round's non-orthogonality pass
    int ortho_sweeps = 4;            // of each later round's, on the few faces left
    int rounds = 3;                  // (non-orthogonality pass, dihedral pass) rounds at most
    bool dihedral_first = true;      // a dihedral pass before the rounds
    // The mesh is cut into one slab per tets_per_slab tets, up to
    // max_slabs, improved at once: a count of the mesh alone. More slabs
    // put more of the mesh near a cut (the cells up to L_max across), where
    // the first round leaves the targets to the second.
    int64_t tets_per_slab = 16384;
    int max_slabs = 4;
    const PrismCells* prism_cells = nullptr; // the stack's prisms, measured as cells (none: every tet a cell)
};

struct CellCounts {
    DihedralCounts dihedral; // tets_before: below the target at the start
    OrthoCounts ortho;       // faces_before: beyond the bound at the start
};

// The cell passes as `params` schedules them, the floors and rules of
// improve_orthogonality and raise_dihedral_angles kept by every change.
// Each pass looks at every tet once; after that, at the cells changed
// since its last look only (the targets it found then, the tets made since
// and the tets at the points moved since, by either pass). In parallel:
// the mesh is cut into slabs of equal point count, improved at once, then
// into slabs cut at their middles, improved at once from the cells the
// first cut held still (a point moves, and a tet changes, in one slab
// only, the tets across a slab's faces seen read-only), and last the whole
// mesh from the cells still beyond the solver's floors (10 degrees, 70),
// which both cuts held still; so the result depends on the mesh alone:
// the same on any number of threads. Points the
// passes add are appended to mesh.points; `locked_tets` stay the first
// tets. The counts before are those of the first cut's slabs (the tets
// across its cuts left out).
CellCounts improve_cells(TetMesh& mesh, int32_t surface_points, const CellPassParams& params,
                         const std::vector<LayerBound>& layers = {}, int32_t locked_tets = 0);

// OpenFOAM's interpolation weight of a face (face_interpolation_weight,
// core/face_measures.h), which checkMesh -allGeometry fails below 0.05, is
// small where one cell's centre lies near the face's plane against the
// other's: a flattish tet next to a tall one. Neither the cell passes
// (their order on shapes has no weight: counting light faces there cost
// the exact cylinder its prism layers at M = 14) nor the joining of poor
// tets (no star-shaped union) mend every such face. mend_light_faces takes
// each interior face whose weight is below `target_weight` between two
// tets beyond the first `locked_tets`; not a face to a locked tet (a layer
// prism's: the moves for those cost a stepped tube its prism layers). The
// centres are the cells' as the cell passes measure them: a tet's
// centroid, a layer prism's centre (from `prisms`) for a face of a moved
// point's star.
//
// First, a light face over a flat cap is flipped: where its two tets each
// have a boundary face on one edge of it, both of one opening's patch
// (`boundary_patch`, per mesh.boundary_faces; 0 is the wall's) and in one
// plane, the tets are a pyramid over that boundary quad, and the light
// face's weight is set by the quad's two apexes' distances from the shared
// edge alone, which no move changes (a thin triangle at a cap's rim). The
// quad's other diagonal then takes its place, in the tets and in
// mesh.boundary_faces (the two ids keep their patch; the cap's plane is
// unchanged), where the quad is convex and the new tets keep what a move
// keeps with a heavier lightest face. Then the same flip is made under a tet
// (beyond the first `locked_tets`) still below the solver's floors
// (OrthoFloors: 10 degrees, aspect ratio 0.1) with a face on an opening's
// flat cap, where the flip raises the two tets' smallest dihedral angle,
// keeps the aspect ratio floor and non-orthogonality within 70 degrees (or
// the old tets' worst: dihedral_better) and leaves no face lighter than the
// target (or the old tets' lightest): a tet on a cap triangle with an angle
// near 180 degrees is as flat as that triangle wherever its apex is.
//
// Then the free points of the other faces' tets (not surface points, nor
// `layers`' fixed ones; a layer point within its bound, a ball or a
// segment of its normal) are moved, one at a time, to raise the lightest
// face of the point's star, where every tet of it stays positive, above the
// aspect ratio floor (OrthoFloors) and within the cell passes' targets
// (CellPassParams: 12 degrees, 65), or the star's own worst where that
// already misses them. A point with a locked tet in its star is not moved,
// nor, without `prisms`, one whose star has a face to a locked tet.
// Serial but for the scans for light faces and poor tets: the faces are
// few, after the passes. Returns the faces below the target before and after, the flips
// of each kind and the moves.
struct LightFaceCounts {
    int64_t faces_before = 0, faces_after = 0; // faces below the target
    int64_t cap_flips = 0, moves = 0;
    int64_t poor_tet_cap_flips = 0; // flips of a flat cap's quad under a tet below the floors
};
LightFaceCounts mend_light_faces(TetMesh& mesh, int32_t surface_points, double target_weight,
                                 const std::vector<LayerBound>& layers = {}, int32_t locked_tets = 0,
                                 const PrismCells* prisms = nullptr, const std::vector<int32_t>& boundary_patch = {});

// The interior points (ids from surface_points on) of the cells a
// finite-volume solver would still object to: the tets whose smallest
// dihedral angle is below `dihedral_floor` degrees, and both tets of each
// interior face whose non-orthogonality (the angle between the face's
// normal and the join of the two tets' centroids, as OpenFOAM measures it)
// is above `ortho_bound` degrees. Sorted, each once. The same measures as
// the two passes above (they take what this finds); the tets are looked at
// in parallel.
std::vector<int32_t> points_missing_floors(const TetMesh& mesh, int32_t surface_points, double dihedral_floor,
                                           double ortho_bound);

// The tets points_missing_floors looks at: per tet, whether it is below
// `dihedral_floor` degrees or has an interior face beyond `ortho_bound`.
std::vector<char> tets_missing_floors(const TetMesh& mesh, double dihedral_floor, double ortho_bound);

// The largest face non-orthogonality over the interior faces of `mesh`
// (`adjacency` its tet_face_adjacency), in degrees, measured as the passes
// above and OpenFOAM's checkMesh measure it; 0 without interior faces, 180
// for a degenerate face. In parallel, the same on any number of threads.
double max_non_orthogonality_deg(const TetMesh& mesh, const TetFaceAdjacency& adjacency);

} // namespace scalemesh
