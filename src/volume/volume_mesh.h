#pragma once
// The layered volume mesh of a closed surface: paper sections 2.3 to 2.5,
// Algorithms 4, 5 and 6 (last three lines), section 4's interior-point filter,
// and the quality statistics of section 3 (Fig. 19).
//
//   offset points (Algorithm 4) -> interior-point filter (section 4)
//   -> surface points, sides of the cells -> conditional insertion layer by
//      layer, each layer spatially sorted, cavities confined to the inside
//      (Algorithm 5) -> inside cells, quad repair -> topology check
//   -> 3-2 / 2-3 / 4-4 flips with the volume criterion (section 2.4)
//   -> sliver removal (own design, see improve.h)

#include "core/errors.h"
#include "core/feature_size.h"
#include "core/surface_mesh.h"
#include "core/tet_mesh.h"
#include "volume/layer_account.h"
#include "volume/quality.h"

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace scalemesh {

// How the layers are built. `delaunay`: the paper's (Algorithms 4 and 5),
// the layer points inserted into one conditional Delaunay triangulation
// with the rest, prisms where the tets happen to fill them. `prisms`: the
// layer points joined into prisms over every wall triangle explicitly
// (layer_stack.h), intact by construction, and the core above them meshed
// against the stack's top (core_mesh.h).
enum class LayerMode { delaunay, prisms };

struct VolumeParams {
    LayerMode layers = LayerMode::delaunay;
    std::vector<int32_t> rim_columns; // LayerMode::prisms on a surface with openings: per surface node x
                                      // floor(M/2), the cap node that is layer m of a rim node's column
                                      // (RingParams::prism_columns), -1 elsewhere
    double K = 4.2;      // anisotropy of the first layer (FirstLayer::edge) and of the report
    double M = 7;        // element layers across a cross-section, >= 1
    double growth = 1.0; // layer growth ratio lambda_{m+1} / lambda_m, >= 1; 1 = uniform (see layer_fractions)
    FirstLayer first_layer = FirstLayer::edge; // the first layer's thickness: the node's mean surface edge
                                               // length / K, or the paper's lambda_1 d (offset_points.h)
    double L_max = std::numeric_limits<double>::quiet_NaN(); // mm, required: filler spacing min(D, L_max) / M
    double L_min = std::numeric_limits<double>::quiet_NaN(); // mm, for the layer account only: wall nodes with
                                                             // D >= L_min are owed floor(M/2) layers (NaN: all)
    double layer_tolerance = 0.15; // a layermaking point counts for its layer while it stays within this
                                  // fraction of its layer spacing of where Algorithm 4 put it; the
                                  // improvement keeps it there (the rings of a cross-section stay within
                                  // 15% of their spacing, section 2.3)
    double filter_fraction = 0.1;      // interior-point filter radius, fraction of min(d_a, d_b) / M
                                       // (0.2 dropped the innermost layer point of ~7% of the wall
                                       // nodes on the tube, where the rays converge at the axis)
    double filler_filter_fraction = 0.8; // and for a filler point at least this fraction of its own spacing
                                         // (where the fillers of many nodes converge; see offset_points.h;
                                         // at 0.5 they stayed about twice as dense as their spacing there, and
                                         // a sphere 24 L_max across kept 13.9% of its tets below 0.1 after the
                                         // flips, against 0.13% at 0.8)
    double min_volume_fraction = 1e-3; // Algorithm 5 (i): no new tet of a point has volume below this
                                       // fraction of s^3, s = the point's spacing (lambda_m d or
                                       // min(D, L_max) / M, mm): the cavity is shrunk, or the point
                                       // refused when the cell holding it would go
    int insertion_passes = 3;    // passes of Algorithm 5 over the not yet inserted points, >= 1
    bool improve = true;         // run flips and sliver removal (section 2.4)
    int flip_sweeps = 10;        // at most this many sweeps of volume-criterion flips, >= 0
    int sliver_sweeps = 20;      // at most this many sweeps of sliver removal, >= 0
    double sliver_aspect_ratio = 0.15; // sliver removal works on tets with aspect ratio below this
    double aspect_ratio_floor = 0.1;   // a tet still below this after sliver removal gets an edge split
                                       // (the case's [volume] min_aspect_ratio)
    bool check_topology = true;  // section 2.3 check of every surface node (linear time)
};

struct VolumeResult {
    TetMesh mesh; // points 0..n-1 are the surface points, boundary_faces the surface triangles
    TetFaceAdjacency adjacency; // tet_face_adjacency(mesh), for the exporters' checks
    QualityReport before_flips, after_flips, after_slivers;
    LayerAccount layers; // per surface node: realised layers, wall or opening node, why a layer is missing
    std::vector<int32_t> point_generator; // per mesh point: generating surface node (itself for surface points;
                                          // for a point made by a sliver edge split, the nearest surface point)
    std::vector<int32_t> point_layer;     // per mesh point: m (0 on the surface; 1 for edge-split points)
    std::vector<char> point_filler;       // per mesh point: 1 for filler points and edge-split points
    double first_layer_anisotropy_median = 0; // median over nodes with a first layer point
    std::vector<double> near_wall_anisotropy; // per surface node: mean incident surface edge length /
                                              // first-layer thickness; NaN without a first layer point
    int64_t offset_points = 0;   // points made by Algorithm 4
    int64_t stack_shortened_nodes = 0; // LayerMode::prisms: wall nodes whose column was shortened (layer_stack.h)
    int stack_rounds = 0;              // and the rounds of shortening it took
    int64_t stack_borrowed_columns = 0; // LayerMode::prisms: wall nodes given their neighbours' mean column,
    int64_t stack_lenient_prisms = 0;   // and wall triangles whose prisms were accepted less strictly, and those
    int64_t stack_holes = 0;            // left without layers (LayerStack)
    int64_t stack_whole_columns = 0;    // LayerMode::prisms: wall nodes owed all layers (LayerAccount::eligible)
                                        // whose column holds them all, as prism layers
    double stack_height_mean = 0;       // and those columns' height over the height Algorithm 4 gave them:
    double stack_height_min = 0;        // mean and smallest (below 1 where a column was shortened; 0 with
                                        // no column)
    int64_t filtered_points = 0; // removed by the interior-point filter
    int64_t inserted_points = 0; // interior points in the triangulation after insertion
    int64_t rejected_small = 0;  // final rejections for (i), tiny tets
    int64_t rejected_filler = 0; // final rejections for (ii), filler to surface point
    int64_t rejected_surface = 0; // final rejections for not seeing a surface triangle of the cavity
    int64_t rejected_other = 0;  // outside the surface, or on a vertex
    int64_t unused_points = 0;
    int64_t deferred_points = 0; // points a parallel task handed to the sequential pass (its walk
                                 // or cavity left the task's region), counted once a pass
    int64_t insertion_retries = 0; // re-runs of the insertion with failed quad diagonals protected
    int64_t surface_quads = 0;   // surface quads split the other way by Delaunay, re-triangulated
    int64_t quad_flips = 0;      // of those, the ones whose surface diagonal was flipped to the
                                 // Delaunay one instead (flip_surface_quads)
    int64_t facet_flips = 0;     // surface edges flipped before insertion so that a triangle that was
                                 // not a Delaunay facet becomes two that are (delaunay_insertion.cpp)
    int64_t caps_peeled = 0;     // flat tets of four surface points with two faces on the surface taken
                                 // out of the mesh, their other two faces the surface there (improve.h)
    int64_t flips_32 = 0, flips_23 = 0, flips_44 = 0;
    int64_t sliver_flips = 0, sliver_moves = 0;
    int64_t ortho_faces_before = 0; // interior faces beyond 65 degrees of non-orthogonality before the cell passes
    int64_t ortho_flips = 0, ortho_moves = 0; // the non-orthogonality pass's changes (improve_cells)
    int64_t ortho_splits = 0;                 // its edge splits for a face beyond 70 degrees
    int64_t dihedral_tets_before = 0; // tets below 12 degrees of dihedral angle before the cell passes
    int64_t dihedral_flips = 0, dihedral_moves = 0, dihedral_splits = 0; // the dihedral pass's changes, every run
    int64_t released_layer_points = 0; // layer points let off their layers for a last round where cells still
                                       // missed 10 degrees of dihedral angle or 70 of non-orthogonality
    int64_t sliver_splits = 0;   // edges of surface-point slivers split by a new interior point
    int64_t light_faces_before = 0, light_face_cap_flips = 0, light_face_moves = 0, light_faces_after = 0;
                                 // faces between two tets of interpolation weight below 0.06 after the
                                 // cell passes, the flat cap quads flipped for them,
                                 // the point moves made for them (mend_light_faces), the faces left
    int64_t poor_tet_cap_flips = 0; // flat cap quads flipped under a tet below the floors (mend_light_faces)
    // seconds_classify is the removal: the surface points' triangulation,
    // inside and outside, the output and the quads put back.
    double seconds_points = 0, seconds_insertion = 0, seconds_classify = 0, seconds_flips = 0,
           seconds_slivers = 0, seconds_quality = 0, seconds_checks = 0, seconds_total = 0;
    double seconds_cell_passes = 0; // of seconds_slivers: the dihedral and non-orthogonality passes
    double seconds_prism_groups = 0; // counting prism_groups, within the steps' own times
    double max_non_orthogonality_deg = 0; // of the final mesh's interior faces, as checkMesh measures it
    // Layer prisms filled by exactly three tets (layer_prism_groups) after
    // each step: what the Delaunay insertion makes of the layers, and what
    // the flips, the sliver removal and the cell passes keep of it.
    struct PrismGroups {
        int64_t after_insertion = 0, after_flips = 0, after_slivers = 0, after_cell_passes = 0;
    } prism_groups;
};

// Thrown when the mesh cannot conform to the surface: some surface triangles
// are not faces of the Delaunay triangulation of the surface points (no
// interior point can bring them back), or the section 2.3 topology check
// fails. failing_nodes lists the surface nodes to refine (reduce d there and
// remesh), the recovery of paper section 2.3 that the caller performs.
class VolumeConformityError : public StageError {
public:
    VolumeConformityError(const std::string& what, std::vector<int32_t> triangles, std::vector<int32_t> nodes)
        : StageError("volume", what), failing_triangles(std::move(triangles)), failing_nodes(std::move(nodes))
    {
    }
    std::vector<int32_t> failing_triangles;
    std::vector<int32_t> failing_nodes;
};

// Builds the layered tet mesh inside `surface` (closed, oriented 2-manifold,
// outward normals, possibly several components and cavities) with the sizing
// from compute_feature_size on the same surface.
//
// Guarantees on return: mesh.points[0..n) are surface.points unchanged;
// mesh.boundary_faces == surface.triangles (same order, same orientation)
// except at the quad_flips + facet_flips pairs of triangles whose diagonal
// was flipped to the Delaunay one, the caps_peeled pairs whose flat tet
// was taken out and the poor_tet_cap_flips and light_face_cap_flips pairs
// of an opening's flat cap whose diagonal was flipped for a tet below the
// floors or a light face (each pair keeps its two ids and patch),
// boundary_patch == surface.triangle_patch; every tet is positively oriented;
// the tets fill exactly the region the surface encloses (tet_mesh_facts gives
// boundary_matches and the enclosed volume to round-off); each surface node's
// incident tets are one face-connected component (check_topology). Interior
// points are never on the surface; improvement moves interior points only.
// Besides the offset points, a few interior points may be made where a
// surface quad cannot be re-triangulated otherwise or a sliver of four
// surface points is left (improve.h); they are attributed as filler points.
// Each insertion cavity is confined to the inside of the surface and shrunk
// to be star-shaped (delaunay_insertion.cpp), so the inside is a Delaunay
// triangulation constrained by the surface rather than an exact one.
//
// Throws InputError when the surface is not a closed oriented 2-manifold, the
// sizing does not match it, or a parameter is out of range; throws
// VolumeConformityError (a StageError) naming the surface triangles and nodes
// where conformity or the topology check fails.
VolumeResult build_volume_mesh(const SurfaceMesh& surface, const FeatureSize& sizing, const VolumeParams& params);

// Section 2.3 topology check: surface nodes (ids < surface_points) whose
// incident tets do not form one face-connected component, or that have no
// tet at all. Linear in the mesh size. The second form takes the tets' face
// adjacency (std::invalid_argument when it is of other tets).
std::vector<int32_t> topology_check_failures(const TetMesh& mesh, int32_t surface_points);
std::vector<int32_t> topology_check_failures(const TetMesh& mesh, int32_t surface_points,
                                             const TetFaceAdjacency& adjacency);

} // namespace scalemesh
