#pragma once
// The layers as prism cells for a finite volume solver: the three tets that
// fill a layer prism become one cell of the OpenFOAM export.

#include "core/tet_mesh.h"

#include <cstdint>
#include <functional>
#include <vector>

namespace scalemesh {

struct LayerPrismCells {
    std::vector<int32_t> cell_of_tet; // per tet: its cell, numbered in the order of each cell's first tet
    int32_t cells = 0;
    int64_t prisms = 0;  // cells of three tets
    int64_t refused = 0; // prisms filled by three tets left as tets: not star-shaped from their centroid,
                         // or a face beyond the non-orthogonality bound
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

// layer_prism_cells, then the prisms among the cells `failing_cells` names
// split back into tets, and again, until it names no prism. The cells
// returned are the last ones checked.
LayerPrismCells checked_layer_prism_cells(const TetMesh& mesh, const TetFaceAdjacency& adjacency,
                                          const std::vector<int32_t>& point_generator,
                                          const std::vector<int32_t>& point_layer,
                                          const std::vector<char>& point_filler, double max_non_orthogonality_deg,
                                          const FailingCells& failing_cells);

} // namespace scalemesh
