#include "volume/slabs.h"

#include "core/surface_mesh.h"

#include <algorithm>

namespace scalemesh {

int SlabCut::of(double x) const
{
    const auto it = std::upper_bound(bounds.begin() + 1, bounds.end() - 1, x);
    return static_cast<int>(it - bounds.begin()) - 1;
}

namespace {

// Slabs along the longest side of the points' box, cut at the coordinates
// of the ranks n s / d for the numerators s (increasing, below d).
SlabCut slabs_at_ranks(const std::vector<Vec3>& points, const std::vector<size_t>& numerators, size_t d)
{
    SlabCut cut;
    if (points.empty()) {
        cut.bounds.assign(numerators.size() + 2, 0.0);
        return cut;
    }
    Vec3 lo, hi;
    bounding_box(points, lo, hi);
    const Vec3 size = hi - lo;
    cut.axis = size.x >= size.y && size.x >= size.z ? 0 : size.y >= size.z ? 1 : 2;
    std::vector<double> x;
    x.reserve(points.size());
    for (const Vec3& p : points) x.push_back(p[cut.axis]);
    cut.bounds.push_back(lo[cut.axis]);
    // Each rank by selection in what is left above the previous one.
    auto from = x.begin();
    for (size_t s : numerators) {
        const auto rank = x.begin() + static_cast<std::ptrdiff_t>(x.size() * s / d);
        std::nth_element(from, rank, x.end());
        cut.bounds.push_back(*rank);
        from = rank;
    }
    cut.bounds.push_back(hi[cut.axis]);
    return cut;
}

} // namespace

SlabCut equal_count_slabs(const std::vector<Vec3>& points, int count)
{
    std::vector<size_t> numerators;
    for (int s = 1; s < count; ++s) numerators.push_back(s);
    return slabs_at_ranks(points, numerators, count);
}

SlabCut middle_slabs(const std::vector<Vec3>& points, int count)
{
    std::vector<size_t> numerators;
    for (int s = 1; s <= count; ++s) numerators.push_back(2 * s - 1);
    return slabs_at_ranks(points, numerators, 2 * count);
}

} // namespace scalemesh
