#include "openings/openings.h"

#include "core/errors.h"
#include "layers/offset_points.h"
#include "openings/plane_triangulation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace scalemesh {

namespace {

// RingParams::prism_columns: each triangle of a rim prism's side quad in a
// cap holds at least this share of the quad's area. A quad that tapers more
// (the rings converging, as at the last ring of a tube's cap) makes a prism
// whose index-rule split has a tet of under 5% of its volume (layer_stack.h
// refuses those), which the cap's fixed columns could not mend.
constexpr double kMinCapShare = 0.2;
// Shortest segment of a cap's last ring, as a fraction of the thickness of
// the top layer of its two columns.
constexpr double kMinRingSpacing = 0.8;

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

// Whether (px, py) is inside an odd number of the closed polygons `loops`
// (ids into u, v).
bool inside_loops(const std::vector<double>& u, const std::vector<double>& v,
                  const std::vector<std::vector<int32_t>>& loops, double px, double py)
{
    bool in = false;
    for (const auto& loop : loops)
        for (size_t k = 0; k < loop.size(); ++k) {
            const int32_t a = loop[k], b = loop[(k + 1) % loop.size()];
            if ((v[a] > py) != (v[b] > py) && px < u[a] + (py - v[a]) * (u[b] - u[a]) / (v[b] - v[a])) in = !in;
        }
    return in;
}

// The distance from (px, py) to the nearest segment of `loops`.
double loops_distance(const std::vector<double>& u, const std::vector<double>& v,
                      const std::vector<std::vector<int32_t>>& loops, double px, double py)
{
    double best = std::numeric_limits<double>::infinity();
    for (const auto& loop : loops)
        for (size_t k = 0; k < loop.size(); ++k) {
            const int32_t a = loop[k], b = loop[(k + 1) % loop.size()];
            best = std::min(best, segment_distance(px, py, u[a], v[a], u[b], v[b]));
        }
    return best;
}

// RingParams::prism_columns: cap `cap` rebuilt around the columns of its
// rim nodes. Each rim node's layermaking points, along its in-plane normal
// at the distances of layer_columns (shortened_column where the last would
// pass D / 2, as build_layer_stack starts a column), become cap nodes; the
// rings are joined rim edge by rim edge by the side quads of the rim
// prisms, each cut from the lower column's point below to the higher
// column's point above (the index rule on the new ids); the region inside
// the last ring is triangulated with the filler points inside it.
template <class AddPoint>
void prism_cap(const SurfaceMesh& surface, const Cap& cap, const openings::PlaneBasis& basis,
               const std::vector<std::vector<int32_t>>& loops, const FeatureSize& rim_sizing,
               const OffsetParams& offset, int32_t L, double filter_fraction, const std::vector<int32_t>& index,
               const std::vector<OffsetPoint>& candidates, AddPoint&& add_point, const FeatureSize& sizing,
               SurfaceMesh& result, std::vector<std::array<int32_t, 2>>& column_of, std::vector<int32_t>& column_node)
{
    const LayerColumns columns = layer_columns(surface, rim_sizing, offset);
    const auto in_plane = [&](Vec3 x) {
        x -= cap.plane.signed_distance(x) * cap.plane.normal;
        return x - cap.plane.signed_distance(x) * cap.plane.normal;
    };
    // Each rim node's column in plane coordinates: its node, then its
    // layer points. Converging in-plane normals would cross the rings (at
    // the last ring of a tube's cap, a few degrees of noise in the normals
    // is enough): as build_layer_stack does in 3D, the columns of poor or
    // crossing quads are shortened (by 0.8 a round, neighbours along the
    // rim within 0.3 of each other), the first layer kept; so are the
    // columns of a last-ring segment shorter than kMinRingSpacing of their
    // top layer (converging normals draw the last ring in until the fill
    // inside it can only make needles).
    std::map<int32_t, double> scale;
    for (const auto& loop : loops)
        for (int32_t r : loop) {
            if (L == 0 || !(columns.dist[size_t(r) * L] > 0))
                throw StageError("openings", "rim node " + std::to_string(r) + " of cap '" + cap.name +
                                                 "' has no layer column in the cap's plane");
            const double top = columns.dist[size_t(r) * L + L - 1], reach = sizing.D[r] / 2;
            scale[r] = reach > 0 && top > reach ? reach / top : 1.0;
        }
    using UV = std::array<double, 2>;
    std::map<int32_t, std::vector<UV>> at; // per rim node: its column in (u, v), m = 0..L
    const auto place = [&] {
        for (auto& [r, s] : scale) {
            const std::vector<double> dist = shortened_column(&columns.dist[size_t(r) * L], L, s);
            std::vector<UV>& column = at[r];
            column.assign(1, UV{basis.u(surface.points[r]), basis.v(surface.points[r])});
            for (int32_t m = 1; m <= L; ++m) {
                const Vec3 x = in_plane(surface.points[r] + dist[m - 1] * columns.inward[r]);
                column.push_back({basis.u(x), basis.v(x)});
            }
        }
    };
    const auto area2 = [](const UV& a, const UV& b, const UV& c) {
        return (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    };
    const auto segments_cross = [&](const UV& a, const UV& b, const UV& c, const UV& d) {
        return area2(a, b, c) * area2(a, b, d) < 0 && area2(c, d, a) * area2(c, d, b) < 0;
    };
    for (int round = 0;; ++round) {
        place();
        std::map<int32_t, char> poor;
        for (const auto& loop : loops) {
            double winding = 0; // twice the loop's signed area: > 0 counter-clockwise
            for (size_t k = 0; k < loop.size(); ++k)
                winding += area2({0, 0}, at[loop[k]][0], at[loop[(k + 1) % loop.size()]][0]);
            const double sign = winding > 0 ? 1.0 : -1.0;
            for (size_t k = 0; k < loop.size(); ++k) {
                const int32_t a = loop[k], b = loop[(k + 1) % loop.size()];
                const std::vector<UV>&A = at[a], &B = at[b];
                for (int32_t m = 1; m <= L; ++m) {
                    const UV q[4] = {A[m - 1], B[m - 1], B[m], A[m]};
                    const double quad = sign * (area2(q[0], q[1], q[2]) + area2(q[0], q[2], q[3]));
                    const double t1 = sign * (index[a] < index[b] ? area2(q[0], q[1], q[2]) : area2(q[1], q[2], q[3]));
                    const double t2 = sign * (index[a] < index[b] ? area2(q[0], q[2], q[3]) : area2(q[1], q[3], q[0]));
                    if (!(quad > 0) || t1 < kMinCapShare * quad || t2 < kMinCapShare * quad) poor[a] = poor[b] = 1;
                }
                // The last ring's segment against its columns' top layer: a
                // ring drawn in (shorter than the rim edge) to a fraction of
                // the layer's thickness leaves the fill inside it needles.
                const double top = std::max(std::hypot(A[L][0] - A[L - 1][0], A[L][1] - A[L - 1][1]),
                                            std::hypot(B[L][0] - B[L - 1][0], B[L][1] - B[L - 1][1]));
                const double last = std::hypot(A[L][0] - B[L][0], A[L][1] - B[L][1]);
                if (last < kMinRingSpacing * top && last < std::hypot(A[0][0] - B[0][0], A[0][1] - B[0][1]))
                    poor[a] = poor[b] = 1;
                // The last ring's segment against the others of its loop.
                for (size_t j = k + 2; j < loop.size(); ++j) {
                    if ((j + 1) % loop.size() == k) continue;
                    const int32_t c = loop[j], d = loop[(j + 1) % loop.size()];
                    if (segments_cross(A[L], B[L], at[c][L], at[d][L])) poor[a] = poor[b] = poor[c] = poor[d] = 1;
                }
            }
        }
        if (poor.empty()) break;
        if (round == 40)
            throw StageError("openings", "the layer columns of cap '" + cap.name + "' still make poor quads, cross, "
                                             "or draw its last ring in closer than " +
                                             std::to_string(kMinRingSpacing) + " of their top layer after 40 rounds "
                                             "of shortening (" + std::to_string(poor.size()) + " rim nodes, the "
                                             "first " + std::to_string(poor.begin()->first) +
                                             "); a larger M or a flatter rim (an opening plane across the vessel's "
                                             "axis) lets them fit");
        for (const auto& [r, flag] : poor) scale[r] *= 0.8;
        for (bool changed = true; changed;) {
            changed = false;
            for (const auto& loop : loops)
                for (size_t k = 0; k < loop.size(); ++k)
                    for (const int32_t other : {loop[(k + 1) % loop.size()], loop[(k + loop.size() - 1) % loop.size()]})
                        if (scale[loop[k]] > scale[other] + 0.3) scale[loop[k]] = scale[other] + 0.3, changed = true;
        }
    }

    // The columns as cap nodes: ring[r][m], new ids (m = 0 the node).
    std::map<int32_t, std::vector<int32_t>> ring;
    std::vector<double> u, v;   // plane coordinates of the local points
    std::vector<int32_t> ids;   // their new ids
    std::vector<std::vector<int32_t>> inner_loops; // local ids of the last ring
    for (const auto& loop : loops) {
        std::vector<int32_t> last;
        for (int32_t r : loop) {
            const std::vector<double> dist = shortened_column(&columns.dist[size_t(r) * L], L, scale[r]);
            std::vector<int32_t>& column = ring[r];
            column.push_back(index[r]);
            for (int32_t m = 1; m <= L; ++m) {
                const Vec3 x = in_plane(surface.points[r] + dist[m - 1] * columns.inward[r]);
                column.push_back(add_point(x, sizing.D[r], std::numeric_limits<double>::infinity(), sizing.d[r],
                                           cap.plane.normal, 0));
                column_of.push_back({index[r], m});
                column_node.push_back(column.back());
            }
            last.push_back(static_cast<int32_t>(ids.size()));
            ids.push_back(column.back());
            u.push_back(basis.u(result.points[column.back()]));
            v.push_back(basis.v(result.points[column.back()]));
        }
        inner_loops.push_back(std::move(last));
    }
    const auto add_triangle = [&](int32_t a, int32_t b, int32_t c) {
        const Vec3 &pa = result.points[a], &pb = result.points[b], &pc = result.points[c];
        const double area = (basis.u(pb) - basis.u(pa)) * (basis.v(pc) - basis.v(pa)) -
                            (basis.u(pc) - basis.u(pa)) * (basis.v(pb) - basis.v(pa));
        if (area > 0) result.triangles.push_back({a, b, c});
        else result.triangles.push_back({a, c, b});
        result.triangle_patch.push_back(cap.patch);
    };
    // The annulus: quads (a_{m-1}, b_{m-1}, b_m, a_m) between consecutive rim nodes.
    for (const auto& loop : loops)
        for (size_t k = 0; k < loop.size(); ++k) {
            const std::vector<int32_t>& A = ring[loop[k]];
            const std::vector<int32_t>& B = ring[loop[(k + 1) % loop.size()]];
            const bool a_lower = A[0] < B[0];
            const std::vector<int32_t>& lo = a_lower ? A : B;
            const std::vector<int32_t>& hi = a_lower ? B : A;
            for (int32_t m = 1; m <= L; ++m) {
                add_triangle(lo[m - 1], hi[m - 1], hi[m]);
                add_triangle(lo[m - 1], hi[m], lo[m]);
            }
        }
    // Inside the last ring: the filler points well inside it, then a
    // constrained Delaunay triangulation.
    const auto inside = [&](double px, double py) { return inside_loops(u, v, inner_loops, px, py); };
    const auto ring_distance = [&](double px, double py) { return loops_distance(u, v, inner_loops, px, py); };
    const size_t ring_count = ids.size();
    std::vector<double> spacing;
    for (const OffsetPoint& p : candidates) {
        if (!p.filler) continue;
        const Vec3 x = in_plane(p.position);
        const double px = basis.u(x), py = basis.v(x), radius = filter_fraction * p.spacing;
        if (!inside(px, py) || ring_distance(px, py) < std::max(radius, 0.5 * p.spacing)) continue;
        bool crowded = false;
        for (size_t k = ring_count; k < ids.size() && !crowded; ++k)
            crowded = std::hypot(u[k] - px, v[k] - py) < filter_fraction * std::min(p.spacing, spacing[k - ring_count]);
        if (crowded) continue;
        ids.push_back(add_point(x, sizing.D[p.generator], std::numeric_limits<double>::infinity(),
                                sizing.d[p.generator], cap.plane.normal, 0));
        spacing.push_back(p.spacing);
        u.push_back(px);
        v.push_back(py);
    }
    for (const auto& piece : openings::triangulate_loops(u, v, inner_loops, "openings"))
        for (const auto& t : piece.triangles) add_triangle(ids[t[0]], ids[t[1]], ids[t[2]]);
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
    const int32_t L = static_cast<int32_t>(std::floor(params.M / 2));
    std::vector<std::array<int32_t, 2>> column_of; // (rim node's new id, layer) -> cap node, as pairs
    std::vector<int32_t> column_node;
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
        const auto inside = [&](double px, double py) { return inside_loops(u, v, local_loops, px, py); };
        const auto rim_distance = [&](double px, double py) { return loops_distance(u, v, local_loops, px, py); };

        if (params.prism_columns) {
            prism_cap(surface, cap, basis, loops, rim_sizing, offset, L, params.filter_fraction, index, candidates,
                      add_point, sizing, result, column_of, column_node);
            continue;
        }
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
    if (params.prism_columns) {
        params.prism_columns->assign(result.points.size() * size_t(L), -1);
        for (size_t k = 0; k < column_of.size(); ++k)
            (*params.prism_columns)[size_t(column_of[k][0]) * L + column_of[k][1] - 1] = column_node[k];
    }
    sizing = std::move(out);
    return result;
}

} // namespace scalemesh
