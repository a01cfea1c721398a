#pragma once
// Private to the tet improvement files of src/volume: the flips (2-3, 3-2,
// 4-4) and edge removals of every pass, made through the editor where the
// pass's criterion accepts them.

#include "volume/improve.h"
#include "volume/tet_editor.h"

#include <array>
#include <cstdint>
#include <vector>

namespace scalemesh::improvement {

// A flip replaces old tets by new ones on the same polyhedron; the criterion
// decides from their volumes, aspect ratios or face non-orthogonality
// whether it is worth it.
enum class Criterion { volume, quality, orthogonality, dihedral };

// The flips and edge removals at a tet, each made through the editor where
// `criterion` accepts it (the new tets keeping `floors` where the criterion
// asks for them).
class Flipper {
public:
    Flipper(TetEditor& ed, Criterion criterion, OrthoFloors floors = {})
        : ed_(ed), criterion_(criterion), floors_(floors)
    {
    }

    // Tries the flips of the edges and faces of tet t, and with `removals`
    // the removal of its edges (the quality passes, for the tet they aim
    // at: not for every tet around it); true when one was made.
    bool improve_tet(int32_t t, FlipCounts& counts, bool removals = false);

private:
    static constexpr int kMaxRing = 7;                 // edge removal up to seven tets around the edge
    using Tets = Few<Tet, 4>;
    using Volumes = std::array<double, 4>;
    using Ring = Few<int32_t, kMaxRing>;
    using RingTets = Few<Tet, 2 * (kMaxRing - 2)>;    // a ring of m triangulated: 2 (m - 2) tets

    // Whether replacing `old` by `fresh` is worth it; the new tets must all
    // be clearly positive (beyond round-off of their size).
    template <class Old, class Fresh, class Volumes6>
    bool accept(const Old& old, const Fresh& fresh, const Volumes6& fresh6);

    // The ring of the edge (a, b): c_0 .. c_{k-1} with (a, b, c_i, c_{i+1})
    // positive. Empty when the tets around the edge do not close (a surface edge).
    template <class Around>
    Ring ring(int32_t a, int32_t b, const Around& around);

    bool flip_edge(int32_t a, int32_t b, FlipCounts& counts);

    // Edge removal (Shewchuk, "Two discrete optimization algorithms for the
    // topological improvement of tetrahedral meshes", 2002) of an interior
    // edge (a, b) with five to seven tets around it: its ring is
    // triangulated every way (5, 14 or 42 ways), each triangle joined to a
    // and to b, and the best triangulation the criterion accepts replaces
    // the tets. Only the quality passes use it; the paper's flip pass keeps
    // its three flips.
    bool remove_edge(int32_t a, int32_t b, FlipCounts& counts);

    // Every triangulation of a convex polygon of m corners (3 to kMaxRing),
    // as triangles (i, j, k) of corner indices with i < j < k.
    static const std::vector<std::vector<std::array<int, 3>>>& polygon_triangulations(int m);

    bool flip_face(int32_t a, int32_t b, int32_t c, FlipCounts& counts);

    TetEditor& ed_;
    Criterion criterion_;
    OrthoFloors floors_;
};

} // namespace scalemesh::improvement
