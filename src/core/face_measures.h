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

// OpenFOAM's cell determinant (primitiveMeshTools::cellDeterminant, judged
// by checkMesh -allGeometry, which fails a cell below 0.001): over a
// cell's internal faces only, the determinant of the sum of the outer
// products of their area vectors, each over the faces' mean area, over 8 (a
// cube's is 1); 0 for a cell without internal faces. Small where the
// internal faces' normals all but miss a direction, as for a tall tet on a
// small, obtuse boundary triangle: the solver's least-squares gradients
// are then ill-posed. Add each internal face's area vector (of either
// orientation), then read determinant().
class CellDeterminant {
public:
    void add(const Vec3& area)
    {
        xx_ += area[0] * area[0], xy_ += area[0] * area[1], xz_ += area[0] * area[2];
        yy_ += area[1] * area[1], yz_ += area[1] * area[2], zz_ += area[2] * area[2];
        area_ += norm(area), ++faces_;
    }
    double determinant() const
    {
        if (faces_ == 0 || !(area_ > 0)) return 0;
        const double mean = area_ / faces_, scale = mean * mean * mean * mean * mean * mean;
        const double det = xx_ * (yy_ * zz_ - yz_ * yz_) - xy_ * (xy_ * zz_ - yz_ * xz_) + xz_ * (xy_ * yz_ - yy_ * xz_);
        return std::abs(det) / scale / 8;
    }

private:
    double xx_ = 0, xy_ = 0, xz_ = 0, yy_ = 0, yz_ = 0, zz_ = 0, area_ = 0;
    int faces_ = 0;
};

} // namespace scalemesh
