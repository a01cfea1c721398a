#pragma once
// Private to the tet improvement files of src/volume: improvement of the
// mesh in slabs at once, with a result that depends on the mesh alone, not
// on the number of threads.

#include "core/tet_mesh.h"

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

namespace scalemesh::improvement {

// Improvement in parallel. The mesh is cut into parts, each a mesh of its
// own (its tets, with point ids of its own), improved at once, then put
// back. In a part, a flip takes only an edge whose tets close around it or
// a face with two tets (as at the surface), and only a point whose whole
// star is among the part's own tets moves (pinned otherwise), so parts
// touch no tet and no moving point of one another and every move and flip
// is one the whole mesh could make.
struct Part {
    TetMesh mesh;                // the part's points and tets, its own ids; its first `read_only` tets are not its own
    std::vector<int32_t> global; // part point -> mesh point; points the part adds after these are added to the mesh
    std::vector<char> pinned;    // part point: a surface point, or one on its border
    std::vector<char> border;    // part point: it has a tet that is not the part's own (another part's, or a cut's)
    // The first tets of `mesh` the part sees but must never replace: the
    // mesh's locked tets among its own, then the tets of other parts across
    // its faces (so that a face's non-orthogonality is measured whole).
    int32_t read_only = 0;
    std::optional<std::vector<int32_t>> focus; // the part's tets to look at first (ids in `mesh`); none: all of them
};

// Improves the mesh in slabs at once, then the tets near the cuts: those
// with at least `cut_points` points of a tet across slabs. A flip a slab
// could not make has an edge of such a tet (two such points), a move it
// could not make such a point (one). With poor_below > 0, the points of the
// tets still below it after the slabs count as such points too: the second
// pass then holds their whole stars, so each of them may move there.
// One slab per 100k tets, up to 4. A part adds no point.
void improve_in_slabs(TetMesh& mesh, int32_t surface_points, int cut_points, double poor_below,
                      const std::function<void(Part&, int)>& improve);

// Improves the mesh in two rounds of slabs, each round's slabs at once:
// `count` slabs of equal point count, then count + 1 cut at their middles
// (middle_slabs), each of the second round's parts looking first at its
// tets with a point on a tet across the first round's cuts (Part::focus),
// which the first round could not change. A part sees, read-only, the tets
// across its faces, so a measure of a face between its own tets and others
// is whole; it may add points (appended to the mesh, part after part).
// Then, where a cell is near both cuts (slabs thin beside the cells), the
// whole mesh as one part looks first at the tets `left_over` marks, when
// there are any. The mesh's first `locked_tets` tets are never replaced and
// stay first. With count 1, one part: the whole mesh in place.
void improve_in_slab_rounds(TetMesh& mesh, int32_t surface_points, int32_t locked_tets, int count,
                            const std::function<std::vector<char>(const TetMesh&)>& left_over,
                            const std::function<void(Part&, int)>& improve);

} // namespace scalemesh::improvement
