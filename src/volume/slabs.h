#pragma once
// Slabs of equal point count along the longest side of the points' bounding
// box: the cut both the parallel insertion and the parallel improvement work
// in. It depends on the points alone, so whatever runs on the slabs gives
// the same result on any number of threads.

#include "core/vec3.h"

#include <vector>

namespace scalemesh {

struct SlabCut {
    int axis = 0;               // 0, 1, 2: x, y, z
    std::vector<double> bounds; // count + 1 increasing: the box's low end, the inner cuts, its high end

    int count() const { return static_cast<int>(bounds.size()) - 1; }
    // The slab of a coordinate along `axis`: one at a cut belongs to the
    // slab above it.
    int of(double x) const;
    int of(const Vec3& p) const { return of(p[axis]); }
};

// `count` >= 1 slabs; the inner cuts are the coordinates of ranks n s / count
// (s = 1 .. count - 1) along the axis. No points: count slabs of zero width
// at 0.
SlabCut equal_count_slabs(const std::vector<Vec3>& points, int count);

// count + 1 slabs cut at the middles of equal_count_slabs(points, count)'s
// slabs, along the same axis: the inner cuts are the coordinates of ranks
// n (2 s - 1) / (2 count) (s = 1 .. count), so each cut of the one lies
// inside a slab of the other (the two rounds of the cell passes).
SlabCut middle_slabs(const std::vector<Vec3>& points, int count);

} // namespace scalemesh
