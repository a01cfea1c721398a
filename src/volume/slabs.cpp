#include "volume/slabs.h"

#include "core/surface_mesh.h"

#include <algorithm>

namespace scalemesh {

int SlabCut::of(double x) const
{
    const auto it = std::upper_bound(bounds.begin() + 1, bounds.end() - 1, x);
    return static_cast<int>(it - bounds.begin()) - 1;
}

SlabCut equal_count_slabs(const std::vector<Vec3>& points, int count)
{
    SlabCut cut;
    if (points.empty()) {
        cut.bounds.assign(count + 1, 0.0);
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
    for (int s = 1; s < count; ++s) {
        const auto rank = x.begin() + static_cast<std::ptrdiff_t>(x.size() * s / count);
        std::nth_element(from, rank, x.end());
        cut.bounds.push_back(*rank);
        from = rank;
    }
    cut.bounds.push_back(hi[cut.axis]);
    return cut;
}

} // namespace scalemesh
