#include "openings/openings.h"

#include "core/errors.h"
#include "openings/plane_triangulation.h"
#include "volume/offset_points.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace scalemesh {

namespace {

// Largest tangential shift of a cap point, as a fraction of its spacing.
constexpr double kTangentialShift = 0.1;

// Ordered rim loops of the faces of `patch`: each directed boundary edge of
// the patch, chained.
std::vector<std::vector<int32_t>> patch_loops(const SurfaceMesh& surface, int32_t patch)
{
    std::map<std::pair<int32_t, int32_t>, int> count;
    std::vector<std::array<int32_t, 2>> edges;
    for (size_t f = 0; f < surface.triangles.size(); ++f) {
        if (surface.triangle_patch[f] != patch) continue;
        const Triangle& t = surface.triangles[f];
        for (int k = 0; k < 3; ++k) edges.push_back({t[k], t[(k + 1) % 3]});
    }
    std::vector<std::array<int32_t, 2>> sorted = edges;
    std::sort(sorted.begin(), sorted.end());
    std::map<int32_t, int32_t> next;
    for (const auto& e : edges)
        if (!std::binary_search(sorted.begin(), sorted.end(), std::array<int32_t, 2>{e[1], e[0]})) {
            if (!next.emplace(e[0], e[1]).second)
                throw StageError("openings", "the rim of a cap touches itself at node " + std::to_string(e[0]));
        }
    std::vector<std::vector<int32_t>> loops;
    std::map<int32_t, char> seen;
    for (const auto& [start, unused] : next) {
        (void)unused;
        if (seen.count(start)) continue;
        std::vector<int32_t> loop;
        int32_t u = start;
        do {
            seen[u] = 1;
            loop.push_back(u);
            const auto it = next.find(u);
            if (it == next.end()) throw StageError("openings", "the rim of a cap is not closed");
            u = it->second;
        } while (u != start && loop.size() <= next.size());
        if (u != start) throw StageError("openings", "the rim of a cap is not closed");
        loops.push_back(std::move(loop));
    }
    return loops;
}

// A deterministic number in [-1, 1] for (generator, layer).
double jitter(int32_t generator, int32_t layer)
{
    uint64_t z = (static_cast<uint64_t>(static_cast<uint32_t>(generator)) << 32 | static_cast<uint32_t>(layer)) +
                 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) / static_cast<double>(1ull << 52) - 1.0;
}

double segment_distance(double px, double py, double ax, double ay, double bx, double by)
{
    const double ex = bx - ax, ey = by - ay;
    const double len2 = ex * ex + ey * ey;
    double s = len2 > 0 ? ((px - ax) * ex + (py - ay) * ey) / len2 : 0;
    s = std::clamp(s, 0.0, 1.0);
    return std::hypot(px - ax - s * ex, py - ay - s * ey);
}

} // namespace

SurfaceMesh ring_caps(const SurfaceMesh& surface, const std::vector<Cap>& caps, FeatureSize& sizing,
                      const RingParams& params)
{
    if (caps.empty()) return surface;
    const size_t n = surface.points.size();
    if (sizing.d.size() != n || sizing.D.size() != n || sizing.normals.size() != n || sizing.inward_ok.size() != n ||
        sizing.D_out.size() != n)
        throw InputError("openings: the sizing does not match the surface", "size the surface with cap_feature_size");
    const CapNodes nodes = classify_cap_nodes(surface, caps);

    // Kept points: all but the cap-interior ones, in order; then the new ones.
    SurfaceMesh result;
    std::vector<int32_t> index(n, -1);
    FeatureSize out;
    out.escaped_inward_rays = sizing.escaped_inward_rays;
    out.seconds_bvh = sizing.seconds_bvh;
    out.seconds_rays = sizing.seconds_rays;
    out.seconds_limit = sizing.seconds_limit;
    const auto add_point = [&](const Vec3& x, double D, double D_out, double d, const Vec3& normal, char ok) {
        result.points.push_back(x);
        out.D.push_back(D);
        out.D_out.push_back(D_out);
        out.d.push_back(d);
        out.normals.push_back(normal);
        out.inward_ok.push_back(ok);
        return static_cast<int32_t>(result.points.size() - 1);
    };
    for (size_t i = 0; i < n; ++i)
        if (!nodes.interior[i])
            index[i] = add_point(surface.points[i], sizing.D[i], sizing.D_out[i], sizing.d[i], sizing.normals[i],
                                 sizing.inward_ok[i]);
    for (size_t f = 0; f < surface.triangles.size(); ++f) {
        if (surface.triangle_patch[f] != 0) continue;
        const Triangle& t = surface.triangles[f];
        result.triangles.push_back({index[t[0]], index[t[1]], index[t[2]]});
        result.triangle_patch.push_back(0);
    }

    OffsetParams offset;
    offset.M = params.M;
    offset.growth = params.growth;
    offset.L_max = params.L_max;
    offset.first_layer = params.first_layer;
    offset.K = params.K;
    for (const Cap& cap : caps) {
        const std::vector<std::vector<int32_t>> loops = patch_loops(surface, cap.patch);
        if (loops.empty()) throw StageError("openings", "cap '" + cap.name + "' has no faces left");
        const openings::PlaneBasis basis(cap.plane.normal);

        // Algorithm 4 from this cap's rim nodes, along their in-plane normals.
        FeatureSize rim_sizing = sizing;
        std::fill(rim_sizing.inward_ok.begin(), rim_sizing.inward_ok.end(), 0);
        for (const auto& loop : loops)
            for (int32_t r : loop) rim_sizing.inward_ok[r] = 1;
        std::vector<OffsetPoint> candidates = offset_points(surface, rim_sizing, offset);
        std::stable_sort(candidates.begin(), candidates.end(),
                         [](const OffsetPoint& a, const OffsetPoint& b) { return a.dist < b.dist; });

        // The rim in plane coordinates.
        std::vector<double> u, v;
        std::vector<int32_t> ids; // surface ids of the local points (rim first), -1 for new ones
        std::vector<std::vector<int32_t>> local_loops;
        for (const auto& loop : loops) {
            std::vector<int32_t> local;
            for (int32_t r : loop) {
                local.push_back(static_cast<int32_t>(ids.size()));
                ids.push_back(r);
                u.push_back(basis.u(surface.points[r]));
                v.push_back(basis.v(surface.points[r]));
            }
            local_loops.push_back(std::move(local));
        }
        const size_t rim_count = ids.size();
        const auto inside = [&](double px, double py) {
            bool in = false;
            for (const auto& loop : local_loops)
                for (size_t k = 0; k < loop.size(); ++k) {
                    const int32_t a = loop[k], b = loop[(k + 1) % loop.size()];
                    if ((v[a] > py) != (v[b] > py) && px < u[a] + (py - v[a]) * (u[b] - u[a]) / (v[b] - v[a])) in = !in;
                }
            return in;
        };
        const auto rim_distance = [&](double px, double py) {
            double best = std::numeric_limits<double>::infinity();
            for (const auto& loop : local_loops)
                for (size_t k = 0; k < loop.size(); ++k) {
                    const int32_t a = loop[k], b = loop[(k + 1) % loop.size()];
                    best = std::min(best, segment_distance(px, py, u[a], v[a], u[b], v[b]));
                }
            return best;
        };

        // Points of neighbouring rim nodes at the same layer make isosceles
        // trapezoids with them, four points on a circle, whose diagonal the
        // volume stage's 3D Delaunay triangulation would choose by its own
        // tie-break, not ours. A small tangential shift per point, fixed by
        // (node, layer), makes every choice clear-cut.
        std::vector<OffsetPoint> shifted = candidates;
        for (OffsetPoint& p : shifted) {
            const Vec3 tangent = normalized(cross(cap.plane.normal, sizing.normals[p.generator]));
            p.position += kTangentialShift * p.spacing * jitter(p.generator, p.layer) * tangent;
        }
        candidates = std::move(shifted);

        std::vector<const OffsetPoint*> kept;
        for (const OffsetPoint& p : candidates) {
            const Vec3 x = p.position - cap.plane.signed_distance(p.position) * cap.plane.normal;
            const double px = basis.u(x), py = basis.v(x);
            const double radius = params.filter_fraction * p.spacing;
            if (!inside(px, py) || rim_distance(px, py) < radius) continue;
            bool crowded = false;
            for (size_t k = rim_count; k < ids.size() && !crowded; ++k)
                crowded = std::hypot(u[k] - px, v[k] - py) < params.filter_fraction * std::min(p.spacing, kept[k - rim_count]->spacing);
            if (crowded) continue;
            kept.push_back(&p);
            ids.push_back(-1);
            u.push_back(px);
            v.push_back(py);
        }

        const std::vector<openings::PlanePiece> pieces = openings::triangulate_loops(u, v, local_loops, "openings");
        for (size_t k = rim_count; k < ids.size(); ++k) {
            const OffsetPoint& p = *kept[k - rim_count];
            Vec3 x = p.position - cap.plane.signed_distance(p.position) * cap.plane.normal;
            x -= cap.plane.signed_distance(x) * cap.plane.normal;
            const int32_t g = p.generator;
            ids[k] = add_point(x, sizing.D[g], std::numeric_limits<double>::infinity(), sizing.d[g], cap.plane.normal, 0);
        }
        for (size_t k = 0; k < rim_count; ++k) ids[k] = index[ids[k]];
        for (const auto& piece : pieces)
            for (const auto& t : piece.triangles) {
                result.triangles.push_back({ids[t[0]], ids[t[1]], ids[t[2]]});
                result.triangle_patch.push_back(cap.patch);
            }
    }
    require_closed_manifold(result, "the surface with its caps rebuilt");
    sizing = std::move(out);
    return result;
}

} // namespace scalemesh
