#include "remeshing/volume_give_back.h"

#include <algorithm>
#include <cmath>

namespace scalemesh::remeshing {

double enclosed_volume(const HalfedgeMesh& mesh)
{
    double six_volume = 0;
    for (int32_t f = 0; f < mesh.face_capacity(); ++f) {
        if (!mesh.face_alive(f)) continue;
        const Vec3 &a = mesh.points[mesh.from(3 * f)], &b = mesh.points[mesh.from(3 * f + 1)],
                   &c = mesh.points[mesh.from(3 * f + 2)];
        six_volume += dot(a, cross(b, c));
    }
    return six_volume / 6;
}

double give_back_volume(HalfedgeMesh& mesh, std::vector<double>& lost, const std::vector<char>& held, double volume)
{
    const int32_t n = mesh.vertex_capacity();
    std::vector<Vec3> area(n); // the area vector N_v of each fan
    for (int32_t f = 0; f < mesh.face_capacity(); ++f) {
        if (!mesh.face_alive(f)) continue;
        const int32_t a = mesh.from(3 * f), b = mesh.from(3 * f + 1), c = mesh.from(3 * f + 2);
        const Vec3 half = 0.5 * cross(mesh.points[b] - mesh.points[a], mesh.points[c] - mesh.points[a]);
        area[a] += half, area[b] += half, area[c] += half;
    }
    auto movable = [&](int32_t v) { return mesh.vertex_alive(v) && !held[v] && norm(area[v]) > 0; };

    // Offset length that gives back lost_v at v alone.
    std::vector<double> offset(n, 0.0);
    for (int32_t v = 0; v < n; ++v)
        if (mesh.vertex_alive(v) && norm(area[v]) > 0) offset[v] = 3 * lost[v] / norm(area[v]);
    std::fill(lost.begin(), lost.end(), 0.0);

    const std::vector<Vec3> original = mesh.points;
    // Area-weighted mean over the closed 1-ring.
    auto average = [&](const std::vector<double>& value) {
        std::vector<double> mean(n, 0.0);
        for (int32_t v = 0; v < n; ++v) {
            if (!mesh.vertex_alive(v)) continue;
            double sum = norm(area[v]) * value[v], weight = norm(area[v]);
            const int32_t start = mesh.outgoing(v);
            int32_t h = start;
            do {
                const int32_t w = mesh.to(h);
                sum += norm(area[w]) * value[w];
                weight += norm(area[w]);
                h = mesh.rotate(h);
            } while (h != start);
            mean[v] = weight > 0 ? sum / weight : 0.0;
        }
        return mean;
    };
    // Twice: a swap's volume comes back spread over its 2-ring.
    const std::vector<double> spread = average(average(offset));
    std::vector<Vec3> move(n), unit(n);
    double moves_slope = 0, offset_slope = 0;
    for (int32_t v = 0; v < n; ++v) {
        if (!movable(v)) continue;
        unit[v] = normalized(area[v]);
        move[v] = spread[v] * unit[v];
        moves_slope += spread[v] * norm(area[v]) / 3;
        offset_slope += norm(area[v]) / 3;
    }
    if (offset_slope == 0) return 0;

    // The moves scaled by the factor that restores the volume to first
    // order, kept in [0, 1]: gains and losses in balance make its slope
    // vanish (Newton's step on it alone threw nodes millions of mm away on a
    // real STL). A common offset along the unit normals, whose slope is
    // positive whatever the signs, takes up the rest, by Newton's method.
    const double error = volume - enclosed_volume(mesh);
    const double factor = moves_slope != 0 ? std::clamp(error / moves_slope, 0.0, 1.0) : 0.0;
    std::vector<Vec3> base(original);
    for (int32_t v = 0; v < n; ++v)
        if (movable(v)) base[v] += factor * move[v];
    auto place = [&](double s) {
        for (int32_t v = 0; v < n; ++v)
            if (movable(v)) mesh.points[v] = base[v] + s * unit[v];
    };
    place(0);
    double s = (volume - enclosed_volume(mesh)) / offset_slope;
    for (int iteration = 0; iteration < 4; ++iteration) {
        place(s);
        const double remaining = enclosed_volume(mesh) - volume;
        if (std::abs(remaining) <= 1e-13 * std::abs(volume)) break;
        s -= remaining / offset_slope;
    }
    double largest = 0;
    for (int32_t v = 0; v < n; ++v) largest = std::max(largest, distance(mesh.points[v], original[v]));
    return largest;
}

} // namespace scalemesh::remeshing
