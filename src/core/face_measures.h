#pragma once
// The measures of a face between two cells that a finite-volume solver
// checks, shared by the volume stage and the polyMesh writer.

#include "core/vec3.h"

#include <algorithm>
#include <cmath>

namespace scalemesh {

// The cosine of OpenFOAM's face non-orthogonality (primitiveMeshCheck's
// faceOrthogonality): a face's area vector (of any length, out of the owner
// cell) against the join of the owner's centre to the neighbour's;
// `degenerate` when either has no length. The one face measure of the cell
// passes (face_cosine, volume/tet_editor.h), of the merging of poor tets into
// layer cells (absorb_poor_tets, volume/layer_prisms.cpp) and of the
// polyMesh's checks (openfoam_cell_checks, exporters/polymesh_writer.h).
// Each brings its own area vector and centres, since each measures other
// cells: the cell passes a tet against a tet, both centres the mean of the
// four corners, or a layer prism's centre for its tets (CellCentres); absorb_poor_tets a lone tet's corner mean (or, for a union it
// tries, the union's volume-weighted centroid) against the volume-weighted
// centroid of the tets of the cell across, a lone tet's included; the
// polyMesh writer OpenFOAM's own centres (primitiveMeshCellCentresAndVols:
// the face pyramids' centroids weighted by volume), the numbers checkMesh
// reports; the layer stack (layer_stack.cpp) a side face between two of its
// prisms against the join of their centroids. The centres differ in the
// last bits even where they agree in exact arithmetic (a lone tet), and each
// caller decides from its own.
inline double face_orthogonality_cosine(const Vec3& area, const Vec3& join, double degenerate)
{
    const double scale = norm(area) * norm(join);
    return scale > 0 ? dot(area, join) / scale : degenerate;
}

// OpenFOAM's interpolation weight of a face (polyMeshTools::faceWeights,
// judged by checkMesh -allGeometry): the nearer of the two cell centres'
// distances from the face's plane over their sum, the distances along the
// face's area vector (of any length) from its centre. The measure of the
// polyMesh's checks (openfoam_cell_checks) and of the merging of poor tets
// (absorb_poor_tets), each with its own centres as above.
inline double face_interpolation_weight(const Vec3& area, const Vec3& face_centre, const Vec3& owner,
                                        const Vec3& neighbour)
{
    const double to_owner = std::abs(dot(area, face_centre - owner));
    const double to_neighbour = std::abs(dot(area, neighbour - face_centre));
    return std::min(to_owner, to_neighbour) / (to_owner + to_neighbour + 1e-300);
}

} // namespace scalemesh
