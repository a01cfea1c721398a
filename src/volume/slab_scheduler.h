#pragma once
// Private to the tet improvement files of src/volume: improvement of the
// mesh in slabs at once, then of the tets near the cuts, with a result that
// depends on the mesh alone, not on the number of threads.

#include "core/tet_mesh.h"

#include <cstdint>
#include <functional>
#include <vector>

namespace scalemesh::improvement {

// Improvement in parallel. The mesh is cut into parts, each a mesh of its
// own (its tets, with point ids of its own), improved at once, then put
// back. In a part, a flip takes only an edge whose tets close around it or
// a face with two tets (as at the surface), and only a point whose whole
// star is in the part moves (pinned otherwise), so parts touch no tet and
// no moving point of one another and every move and flip is one the whole
// mesh could make. What a part cannot do is left to a second pass over the
// tets near the cuts, made a part too.
struct Part {
    TetMesh mesh;                // the part's points and tets, its own ids
    std::vector<int32_t> global; // part point -> mesh point
    std::vector<char> pinned;    // part point: a surface point, or one with a tet outside the part
};

// Improves the mesh in slabs at once, then the tets near the cuts: those
// with at least `cut_points` points of a tet across slabs. A flip a slab
// could not make has an edge of such a tet (two such points), a move it
// could not make such a point (one). With poor_below > 0, the points of the
// tets still below it after the slabs count as such points too: the second
// pass then holds their whole stars, so each of them may move there.
void improve_in_slabs(TetMesh& mesh, int32_t surface_points, int cut_points, double poor_below,
                      const std::function<void(Part&, int)>& improve);

} // namespace scalemesh::improvement
