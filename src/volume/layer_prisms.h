#pragma once
// The layers as prism cells for a finite volume solver: the three tets that
// fill a layer prism become one cell of the OpenFOAM export.

#include "core/tet_mesh.h"

#include <array>
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

namespace scalemesh {

struct LayerPrismCells {
    std::vector<int32_t> cell_of_tet; // per tet: its cell, numbered in the order of each cell's first tet
    int32_t cells = 0;
    int64_t prisms = 0;  // intact layer prisms: cells of exactly a prism's three tets
    int64_t refused = 0; // prisms filled by three tets left as tets: not star-shaped from their centroid,
                         // or a face beyond the non-orthogonality bound
    int64_t absorbed = 0; // poor tets joined to a neighbouring cell (absorb_poor_tets); `prisms` counts
                          // the prism cells that took none
    std::vector<char> prism_cell; // per cell: an intact layer prism (PolyMeshOptions::quad_cells)
};

// A layer prism is the wedge between the points of three boundary nodes a,
// b and c in layer m and in layer m + 1 (m = 0: the nodes themselves) of
// their columns: the points made from a, b and c (point_generator) that are
// not fillers (point_filler), by their point_layer. Where exactly three tets
// have all their points in one such prism, each with the three generators,
// they fill it, and become one cell. (a, b, c) need not be a boundary
// triangle: where the Delaunay insertion joined a layer's points across the
// other diagonal of a quad of the surface, the prisms above it stand on
// the triangles of that layer. They stay three tets where a face of
// the union is not seen from the union's centroid at an angle of more than
// about 3 degrees (OpenFOAM's face-pyramid check would fail, and the cell
// centre would lie outside a face), or where a face to another cell would
// be more than `max_non_orthogonality_deg` off the join of the two cells'
// centroids (a cell's centroid moves when its tets become one); the second
// test is repeated until no more prisms are refused, since each refusal
// moves centroids again. The default bound is 2 degrees inside the volume
// stage's 70: OpenFOAM's centre of a polyhedron (by pyramids on its faces'
// centres) and area of a warped quad differ slightly from the centroid and
// the triangles measured here. Every other tet is a cell of its own.
//
// Why: a prism's faces to the prisms above, below and beside it are close to
// orthogonal to the lines between the cell centres, where the three tets'
// faces are up to 70 degrees off (docs/validation.md measures what this buys
// a simpleFoam solution).
// `adjacency` is tet_face_adjacency(mesh). A prism with a tet marked in
// `apart` (one entry per tet) is refused too: the caller's own check, such
// as openfoam_cell_checks on the cells, found a face beyond its bound.
LayerPrismCells layer_prism_cells(const TetMesh& mesh, const TetFaceAdjacency& adjacency,
                                  const std::vector<int32_t>& point_generator, const std::vector<int32_t>& point_layer,
                                  const std::vector<char>& point_filler, double max_non_orthogonality_deg = 68,
                                  const std::vector<char>* apart = nullptr);

// Tets that would be cells of their own although they are poor finite
// volumes: an aspect ratio below `min_aspect_ratio` or a smallest dihedral
// angle below `min_dihedral_deg` (slivers,
// such as those the core's tets leave in a shallow crease of the layers'
// top, where no flip can reach), or a face to another cell beyond
// `max_non_orthogonality_deg` from the join of the two cells' centroids or
// skewed beyond `max_skewness` (the face centre's offset from where that
// join crosses it, over the face's extent that way, as checkMesh has it) or
// with an interpolation weight below `min_weight` (its centre near the
// face's plane against the other cell's), or a cell determinant below
// `min_determinant` (CellDeterminant: a tall tet on a small, obtuse cap
// triangle, whose internal faces' normals all but miss a direction). A
// union that takes a poor tet has a determinant of at least that bound, or
// of the tet's own where that is lower.
struct PoorTetBounds {
    double min_aspect_ratio = 0.1; // tet_aspect_ratio (quality.h)
    double min_dihedral_deg = 10;
    double max_non_orthogonality_deg = 68;
    double max_skewness = 3.5; // a face's skewness as checkMesh measures it (checkMesh fails beyond 4)
    double min_weight = 0.06;  // a face's interpolation weight (checkMesh -allGeometry fails below 0.05)
    double min_determinant = 0.002; // the cell's (checkMesh -allGeometry fails below 0.001)
    int32_t max_cell_tets = 7; // no cell grows beyond this many tets (7: a sliver and two prisms)
};

// Joins each poor tet cell (worst dihedral angle first) to the neighbouring
// cell across one of its faces, a tet or a prism, or to two or three of them
// (a flat tet's two faces on one side may lie on two cells, and only their
// union sees its other faces from inside), so that the solver sees one
// polyhedral cell where it would see a sliver: the union that is
// star-shaped from its centroid (as layer_prism_cells asks of a prism) and
// has no face beyond the bound, the one of the least non-orthogonality
// among them, leaving every point of its tets on one of its faces (a point
// inside a cell would be on no face, which OpenFOAM refuses). A tet with no
// such union stays a cell of its own. Cells are
// renumbered in the order of their first tet, and `prism_cell` with them
// (a prism that took a tet is none). Returns the tets joined.
//
// A union is named by the lowest tet of each cell joined, ascending, -1
// after them. `refused` names, per poor tet, the unions not to make again;
// `chosen` (if given) receives the union each tet joined, keyed by the tet,
// but for a tet whose cell a later union took in (that later union is the
// one to refuse if the cell fails). Both hold the poor tets only; the
// call's own bookkeeping is a tet index per tet and an offset per cell
// besides, so that it stays small beside the mesh at tens of millions of
// tets.
using TetUnion = std::array<int32_t, 3>;
using RefusedUnions = std::unordered_map<int32_t, std::vector<TetUnion>>;
using ChosenUnions = std::unordered_map<int32_t, TetUnion>;
int64_t absorb_poor_tets(const TetMesh& mesh, const TetFaceAdjacency& adjacency, LayerPrismCells& cells,
                         const PoorTetBounds& bounds, const RefusedUnions& refused = {},
                         ChosenUnions* chosen = nullptr);

// How far inside a cell its centre must be seen from each of its faces
// (degrees) for the cell to be star-shaped enough for OpenFOAM's face
// pyramids, and the test itself: whether triangle (p, q, r), counter-
// clockwise seen from outside the cell, has `centre` on its inner side at
// more than the angle whose sine is `min_sine`.
constexpr double kStarAngleDeg = 3.0;
bool faces_centre(const Vec3& p, const Vec3& q, const Vec3& r, const Vec3& centre, double min_sine);

// How many layer prisms (as layer_prism_cells finds them) are filled by
// exactly three tets, whether or not they would be accepted as cells: what
// the tets keep of the layers as prisms.
int64_t layer_prism_groups(const TetMesh& mesh, const std::vector<int32_t>& point_generator,
                           const std::vector<int32_t>& point_layer, const std::vector<char>& point_filler);

// The caller's own check of a set of cells (such as OpenFOAM's, in
// exporters/polymesh_writer.h): the cells it fails, any order.
using FailingCells = std::function<std::vector<int32_t>(const LayerPrismCells&)>;

// layer_prism_cells (then absorb_poor_tets with `absorb`, if given), then
// the cells `failing_cells` names undone: a cell that absorbed a tet gives
// it back (that union is refused from then on; the tet may join another);
// in a round that gives none back, each prism named is split back into
// tets. Again, until a round does neither. The cells returned are the last
// ones checked.
LayerPrismCells checked_layer_prism_cells(const TetMesh& mesh, const TetFaceAdjacency& adjacency,
                                          const std::vector<int32_t>& point_generator,
                                          const std::vector<int32_t>& point_layer,
                                          const std::vector<char>& point_filler, double max_non_orthogonality_deg,
                                          const FailingCells& failing_cells, const PoorTetBounds* absorb = nullptr);

} // namespace scalemesh
