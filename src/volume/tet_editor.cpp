// The edits of tet_editor.h that are not templates: a point's move for
// its star's aspect ratio, within its layer, and an edge split's tets and
// new point.

#include "volume/tet_editor.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace scalemesh::improvement {
namespace {

// Smallest aspect ratio over the tets at v (not above 0 when one is flat or
// inverted, or NaN).
double star_quality(TetEditor& ed, int32_t v)
{
    double q = 1e300;
    for (int32_t t : ed.at(v)) {
        const double a = ed.aspect(ed.tet(t));
        if (!(a > 0)) return 0;
        q = std::min(q, a);
    }
    return q;
}

} // namespace

Vec3 within_layer(const LayerBound& layer, const Vec3& x)
{
    if (!(layer.slack > 0)) return x;
    if (layer.on_normal)
        return layer.home + std::clamp(dot(x - layer.home, layer.normal), -layer.slack, layer.slack) * layer.normal;
    const Vec3 away = x - layer.home;
    const double length = norm(away);
    return length <= layer.slack ? x : layer.home + (layer.slack / length) * away;
}

bool smooth_point(TetEditor& ed, int32_t v, const LayerBound& layer)
{
    const double start = star_quality(ed, v);
    if (!(start > 0)) return false;
    const Vec3 origin = ed.point(v);
    int32_t worst = -1;
    double worst_q = 1e300, mean_length = 0;
    int edges = 0;
    for (int32_t t : ed.at(v)) {
        const double q = ed.aspect(ed.tet(t));
        if (q < worst_q) worst_q = q, worst = t;
        for (int32_t w : ed.tet(t))
            if (w != v) mean_length += distance(origin, ed.point(w)), ++edges;
    }
    if (worst < 0 || edges == 0) return false;
    mean_length /= edges;

    // Central differences of the worst tet's aspect ratio.
    const Vec3 gradient = point_gradient(ed, v, 1e-4 * mean_length, [&] { return ed.aspect(ed.tet(worst)); });
    // A layer point stays within its slack of its place.
    auto in_plane = [&](const Vec3& x) { return within_layer(layer, x); };
    Few<Vec3, 8> candidates;
    const Vec3 direction = normalized(gradient);
    if (norm2(direction) > 0)
        for (double step : {0.2, 0.1, 0.05, 0.025, 0.0125, 0.006})
            candidates.push_back(in_plane(origin + step * mean_length * direction));
    Vec3 centroid;
    int count = 0;
    for (int32_t t : ed.at(v))
        for (int32_t w : ed.tet(t))
            if (w != v) centroid += ed.point(w), ++count;
    centroid /= count;
    candidates.push_back(in_plane(centroid));
    candidates.push_back(in_plane(0.5 * (origin + centroid)));

    double best = start;
    Vec3 best_position = origin;
    for (const Vec3& x : candidates) {
        ed.point(v) = x;
        const double q = star_quality(ed, v);
        if (q > best + 1e-9) best = q, best_position = x;
    }
    ed.point(v) = best_position;
    return !(best_position == origin);
}

std::vector<Tet> split_at(TetEditor& ed, const std::vector<int32_t>& around, int32_t p, int32_t q, int32_t m)
{
    std::vector<Tet> out;
    out.reserve(2 * around.size());
    for (int32_t t : around) {
        Tet x = ed.tet(t), y = ed.tet(t);
        for (int i = 0; i < 4; ++i) {
            if (x[i] == p) x[i] = m;
            if (y[i] == q) y[i] = m;
        }
        out.push_back(x);
        out.push_back(y);
    }
    return out;
}

bool place_split_point(TetEditor& ed, int32_t m, const std::optional<Vec3>& place, const std::vector<int32_t>& around,
                       const std::vector<Tet>& fresh)
{
    if (!place) {
        ed.drop_last_point();
        return false;
    }
    ed.point(m) = *place;
    ed.replace(around, fresh);
    smooth_point(ed, m);
    return true;
}

} // namespace scalemesh::improvement
