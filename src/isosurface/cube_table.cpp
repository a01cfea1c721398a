#include "isosurface/cube_table.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

namespace scalemesh::mc {

namespace {

constexpr std::array<std::array<int, 2>, 12> make_edge_corners()
{
    std::array<std::array<int, 2>, 12> edges{};
    int e = 0;
    for (int axis = 0; axis < 3; ++axis)
        for (int c = 0; c < 8; ++c)
            if (!(c & (1 << axis))) edges[e++] = {c, c | (1 << axis)};
    return edges;
}

int edge_between(int a, int b)
{
    if (a > b) std::swap(a, b);
    for (int e = 0; e < 12; ++e)
        if (kEdgeCorners[e][0] == a && kEdgeCorners[e][1] == b) return e;
    throw std::logic_error("corners are not joined by a cube edge");
}

struct Point {
    double v[3];
};

Point edge_midpoint(int e)
{
    Point p{};
    for (int k = 0; k < 3; ++k)
        p.v[k] = 0.5 * (((kEdgeCorners[e][0] >> k) & 1) + ((kEdgeCorners[e][1] >> k) & 1));
    return p;
}

// Corners of each of the six faces in cyclic order, counter-clockwise seen
// from outside the cube.
std::array<std::array<int, 4>, 6> face_cycles()
{
    std::array<std::array<int, 4>, 6> faces{};
    for (int axis = 0; axis < 3; ++axis) {
        // (u, v, axis) right-handed, so (0,0) (1,0) (1,1) (0,1) in (u, v) is
        // counter-clockwise seen from the +axis side.
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        for (int side = 0; side < 2; ++side) {
            std::array<int, 4> cycle{};
            const int uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
            for (int k = 0; k < 4; ++k)
                cycle[k] = (side << axis) | (uv[k][0] << u) | (uv[k][1] << v);
            if (side == 0) std::reverse(cycle.begin(), cycle.end());
            faces[axis * 2 + side] = cycle;
        }
    }
    return faces;
}

// Face segments for one case: next[e] = the crossing edge a segment leads to
// from crossing edge e. Segments run from where the face cycle enters the
// inside to where it leaves it; which entry pairs with which exit on a face
// with two inside runs is the face rule.
std::array<int, 12> face_segments(int inside_mask, bool separate_inside)
{
    std::array<int, 12> next;
    next.fill(-1);
    for (const auto& cycle : face_cycles()) {
        bool in[4];
        for (int k = 0; k < 4; ++k) in[k] = (inside_mask >> cycle[k]) & 1;
        // Crossing edges in cycle order: edge k joins cycle[k] and cycle[k+1].
        std::vector<int> enters, exits; // positions k in the cycle
        for (int k = 0; k < 4; ++k) {
            const bool a = in[k], b = in[(k + 1) % 4];
            if (!a && b) enters.push_back(k);
            if (a && !b) exits.push_back(k);
        }
        auto edge_at = [&](int k) { return edge_between(cycle[k], cycle[(k + 1) % 4]); };
        for (int enter : enters) {
            // Separate inside: an entry pairs with the first exit after it (the
            // segment cuts off that inside run). Join inside: with the exit
            // before it (the segment cuts off the outside run behind it).
            int best = -1, best_gap = 5;
            for (int exit : exits) {
                const int gap = separate_inside ? (exit - enter + 4) % 4 : (enter - exit + 4) % 4;
                if (gap < best_gap) best_gap = gap, best = exit;
            }
            next[edge_at(enter)] = edge_at(best);
        }
    }
    return next;
}

// Bit f set: cube edge e lies on face f (faces numbered axis * 2 + side).
int edge_faces(int e)
{
    int faces = 0;
    const int a = kEdgeCorners[e][0];
    for (int axis = 0; axis < 3; ++axis)
        if (axis != kEdgeAxis[e]) faces |= 1 << (axis * 2 + ((a >> axis) & 1));
    return faces;
}

// A chord between two crossings on one cube face could be drawn by the
// neighbouring cube too, giving an edge of four triangles. Fan from a vertex
// whose chords avoid that; where none does, fan around a vertex inside the
// cube, which no other cube shares.
void triangulate_loop(const std::vector<int>& loop, CubeCase& result)
{
    const size_t n = loop.size();
    for (size_t s = 0; s < n && n > 3; ++s) {
        bool ok = true;
        for (size_t k = 2; k + 1 < n && ok; ++k) ok = !(edge_faces(loop[s]) & edge_faces(loop[(s + k) % n]));
        if (!ok) continue;
        for (size_t k = 1; k + 1 < n; ++k)
            result.triangles.push_back({uint8_t(loop[s]), uint8_t(loop[(s + k) % n]), uint8_t(loop[(s + k + 1) % n])});
        return;
    }
    if (n == 3) {
        result.triangles.push_back({uint8_t(loop[0]), uint8_t(loop[1]), uint8_t(loop[2])});
        return;
    }
    const auto centre = static_cast<uint8_t>(12 + result.centre_loops.size());
    result.centre_loops.emplace_back(loop.begin(), loop.end());
    for (size_t k = 0; k < n; ++k) result.triangles.push_back({centre, uint8_t(loop[k]), uint8_t(loop[(k + 1) % n])});
}

CubeCase build_case(int inside_mask, bool separate_inside)
{
    const std::array<int, 12> next = face_segments(inside_mask, separate_inside);
    std::vector<std::vector<int>> loops;
    std::array<bool, 12> seen{};
    for (int e = 0; e < 12; ++e) {
        if (next[e] < 0 || seen[e]) continue;
        std::vector<int> loop;
        for (int cur = e; !seen[cur]; cur = next[cur]) {
            if (next[cur] < 0) throw std::logic_error("open segment chain in a cube case");
            seen[cur] = true;
            loop.push_back(cur);
        }
        loops.push_back(loop);
    }

    CubeCase result;
    const int inside_count = __builtin_popcount(inside_mask);
    const int outside_mask = ~inside_mask & 0xff;
    const bool opposite_pair_outside =
        separate_inside && inside_count == 6 && ((outside_mask & 0x81) == 0x81 || (outside_mask & 0x42) == 0x42 ||
                                                 (outside_mask & 0x24) == 0x24 || (outside_mask & 0x18) == 0x18);
    if (opposite_pair_outside && loops.size() == 2 && loops[0].size() == 3 && loops[1].size() == 3) {
        // The two outside corners are 26-adjacent through the cube's interior:
        // join their corner triangles by a tunnel (an antiprism side strip).
        const int c0 = __builtin_ctz(outside_mask);
        const int c1 = 7 - c0;
        Point axis{}, origin{};
        for (int k = 0; k < 3; ++k) {
            origin.v[k] = (c0 >> k) & 1;
            axis.v[k] = ((c1 >> k) & 1) - origin.v[k];
        }
        // A reference direction orthogonal to the axis, and its cross product.
        Point ref{}, ref2{};
        {
            const double a[3] = {axis.v[0], axis.v[1], axis.v[2]};
            const double t[3] = {1, 0, 0};
            const double along = (t[0] * a[0] + t[1] * a[1] + t[2] * a[2]) / 3.0;
            for (int k = 0; k < 3; ++k) ref.v[k] = t[k] - along * a[k];
            ref2.v[0] = a[1] * ref.v[2] - a[2] * ref.v[1];
            ref2.v[1] = a[2] * ref.v[0] - a[0] * ref.v[2];
            ref2.v[2] = a[0] * ref.v[1] - a[1] * ref.v[0];
        }
        auto angle = [&](int e) {
            const Point p = edge_midpoint(e);
            double x = 0, y = 0;
            for (int k = 0; k < 3; ++k) {
                x += (p.v[k] - 0.5) * ref.v[k];
                y += (p.v[k] - 0.5) * ref2.v[k];
            }
            return std::atan2(y, x);
        };
        // Loop A is the one around c0. Its directed edges run one way around
        // the axis and loop B's the other; the strip keeps every loop edge in
        // its direction, so it joins the rest of the surface consistently.
        const std::vector<int>& A = (kEdgeCorners[loops[0][0]][0] == c0 || kEdgeCorners[loops[0][0]][1] == c0)
                                        ? loops[0] : loops[1];
        const std::vector<int>& B = (&A == &loops[0]) ? loops[1] : loops[0];
        // Each edge of one loop is closed into a triangle by the vertex of
        // the other loop that lies angularly between the edge's two ends.
        auto strip = [&](const std::vector<int>& loop, const std::vector<int>& other) {
            for (int i = 0; i < 3; ++i) {
                const int from = loop[i], to = loop[(i + 1) % 3];
                const double lo = angle(from), hi = angle(to);
                const double mid = std::atan2(std::sin(lo) + std::sin(hi), std::cos(lo) + std::cos(hi));
                int best = other[0];
                double best_gap = 1e9;
                for (int v : other) {
                    const double gap = std::fabs(std::remainder(angle(v) - mid, 2 * M_PI));
                    if (gap < best_gap) best_gap = gap, best = v;
                }
                result.triangles.push_back({uint8_t(from), uint8_t(to), uint8_t(best)});
            }
        };
        strip(A, B);
        strip(B, A);
        return result;
    }

    for (const std::vector<int>& loop : loops) triangulate_loop(loop, result);
    return result;
}

// Loops run so that their right-hand normal points from the outside corners
// to the inside ones; flip every triangle if the construction turned out the
// other way (decided once, on the single-corner case).
bool construction_points_inward()
{
    const CubeCase one = build_case(1, true);
    const auto& t = one.triangles.at(0);
    const Point a = edge_midpoint(t[0]), b = edge_midpoint(t[1]), c = edge_midpoint(t[2]);
    double ab[3], ac[3];
    for (int k = 0; k < 3; ++k) ab[k] = b.v[k] - a.v[k], ac[k] = c.v[k] - a.v[k];
    const double n[3] = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]};
    // Corner 0 is inside: outward is towards (+1, +1, +1).
    return n[0] + n[1] + n[2] < 0;
}

std::array<CubeCase, 256> build_table(bool separate_inside)
{
    const bool flip = construction_points_inward();
    std::array<CubeCase, 256> table;
    for (int mask = 0; mask < 256; ++mask) {
        table[mask] = build_case(mask, separate_inside);
        if (flip)
            for (auto& t : table[mask].triangles) std::swap(t[1], t[2]);
    }
    return table;
}

} // namespace

const std::array<std::array<int, 2>, 12> kEdgeCorners = make_edge_corners();
const std::array<int, 12> kEdgeAxis = {0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2};

const std::array<CubeCase, 256>& cube_table(InsideConnectivity connectivity)
{
    static const std::array<CubeCase, 256> six = build_table(true);
    static const std::array<CubeCase, 256> twenty_six = [] {
        // Inside 26-connected is outside 6-connected: the complement's table
        // with the orientation reversed.
        const std::array<CubeCase, 256> base = build_table(true);
        std::array<CubeCase, 256> table;
        for (int mask = 0; mask < 256; ++mask) {
            table[mask] = base[~mask & 0xff];
            for (auto& t : table[mask].triangles) std::swap(t[1], t[2]);
        }
        return table;
    }();
    return connectivity == InsideConnectivity::Six ? six : twenty_six;
}

} // namespace scalemesh::mc
