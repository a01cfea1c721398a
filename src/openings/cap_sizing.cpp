#include "openings/openings.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "openings/plane_triangulation.h"
#include "sizing/local_diameter.h"
#include "sizing/normals.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace scalemesh {

CapNodes classify_cap_nodes(const SurfaceMesh& surface, const std::vector<Cap>& caps)
{
    const size_t n = surface.points.size();
    CapNodes nodes;
    nodes.cap_of.assign(n, -1);
    nodes.rim.assign(n, 0);
    nodes.interior.assign(n, 0);
    nodes.next_to_rim.assign(n, 0);
    if (surface.triangle_patch.empty() || caps.empty()) return nodes;
    if (surface.triangle_patch.size() != surface.triangles.size())
        throw InputError("the surface's patch list does not match its triangles", "give one patch id per triangle");

    // Per point: the patches around it (-1 none yet, -2 several caps).
    std::vector<char> on_wall(n, 0);
    std::vector<int32_t> cap_patch(n, -1);
    for (size_t f = 0; f < surface.triangles.size(); ++f) {
        const int32_t patch = surface.triangle_patch[f];
        if (patch < 0 || patch > static_cast<int32_t>(caps.size()))
            throw InputError("triangle " + std::to_string(f) + " has patch " + std::to_string(patch) +
                                 " but there are " + std::to_string(caps.size()) + " caps",
                             "patch ids are 0 (wall) and 1..number of caps");
        for (int32_t v : surface.triangles[f]) {
            if (patch == 0) {
                on_wall[v] = 1;
            } else if (cap_patch[v] == -1) {
                cap_patch[v] = patch;
            } else if (cap_patch[v] != patch) {
                cap_patch[v] = -2;
            }
        }
    }
    for (size_t i = 0; i < n; ++i) {
        if (cap_patch[i] < 0) continue; // wall only, unused, or a corner of two caps
        nodes.cap_of[i] = cap_patch[i] - 1;
        if (on_wall[i])
            nodes.rim[i] = 1;
        else
            nodes.interior[i] = 1;
    }
    for (const Triangle& t : surface.triangles)
        for (int k = 0; k < 3; ++k) {
            const int32_t a = t[k], b = t[(k + 1) % 3];
            if (nodes.rim[a] && cap_patch[b] == -1 && on_wall[b]) nodes.next_to_rim[b] = 1;
            if (nodes.rim[b] && cap_patch[a] == -1 && on_wall[a]) nodes.next_to_rim[a] = 1;
        }
    return nodes;
}

namespace {

// The cap a wall node next to a rim takes its plane from: the cap of its
// first rim neighbour.
std::vector<int32_t> rim_neighbour_cap(const SurfaceMesh& surface, const CapNodes& nodes)
{
    std::vector<int32_t> cap(surface.points.size(), -1);
    for (const Triangle& t : surface.triangles)
        for (int k = 0; k < 3; ++k)
            for (int e = 1; e <= 2; ++e) {
                const int32_t a = t[k], b = t[(k + e) % 3];
                if (nodes.next_to_rim[a] && nodes.rim[b] && cap[a] == -1) cap[a] = nodes.cap_of[b];
            }
    return cap;
}

// The rim loops of each cap, as directed rim edges of its faces that no
// other face of the cap shares.
std::vector<std::vector<std::array<int32_t, 2>>> rim_edges(const SurfaceMesh& surface, size_t caps)
{
    std::vector<std::vector<std::array<int32_t, 2>>> edges(caps);
    std::vector<std::vector<std::array<int32_t, 2>>> all(caps);
    for (size_t f = 0; f < surface.triangles.size(); ++f) {
        const int32_t patch = surface.triangle_patch[f];
        if (patch <= 0) continue;
        const Triangle& t = surface.triangles[f];
        for (int k = 0; k < 3; ++k) all[patch - 1].push_back({t[k], t[(k + 1) % 3]});
    }
    for (size_t c = 0; c < caps; ++c) {
        auto sorted = all[c];
        std::sort(sorted.begin(), sorted.end());
        for (const auto& e : all[c])
            if (!std::binary_search(sorted.begin(), sorted.end(), std::array<int32_t, 2>{e[1], e[0]})) edges[c].push_back(e);
    }
    return edges;
}

} // namespace

FeatureSize cap_feature_size(const SurfaceMesh& surface, const std::vector<Cap>& caps, const SizingParams& params)
{
    if (caps.empty()) return compute_feature_size(surface, params);
    const VertexTable fans = vertex_triangles(surface);
    require_closed_manifold(surface, fans, "the surface to size");
    const size_t n = surface.points.size();
    const CapNodes nodes = classify_cap_nodes(surface, caps);

    // Wall normals: angle-weighted over the wall faces only.
    SurfaceMesh wall;
    wall.points = surface.points;
    for (size_t f = 0; f < surface.triangles.size(); ++f)
        if (surface.triangle_patch[f] == 0) wall.triangles.push_back(surface.triangles[f]);
    const std::vector<Vec3> wall_normals = synthetic_normals(wall);

    FeatureSize result;
    result.normals = synthetic_normals(surface, fans);
    const std::vector<int32_t> near_cap = rim_neighbour_cap(surface, nodes);
    for (size_t i = 0; i < n; ++i) {
        const int32_t c = nodes.rim[i] ? nodes.cap_of[i] : (nodes.next_to_rim[i] ? near_cap[i] : -1);
        if (nodes.interior[i]) {
            result.normals[i] = caps[nodes.cap_of[i]].plane.normal;
        } else if (c >= 0) {
            const Vec3& cn = caps[c].plane.normal;
            Vec3 projected = wall_normals[i] - dot(wall_normals[i], cn) * cn;
            projected = normalized(projected);
            projected -= dot(projected, cn) * cn; // one more rounding off the plane's normal
            result.normals[i] = normalized(projected);
        }
    }
    result.inward_ok = inward_check(surface, fans, result.normals);
    std::vector<char> cast = result.inward_ok;
    for (size_t i = 0; i < n; ++i)
        if (nodes.rim[i] || nodes.interior[i]) cast[i] = 0;
    RayResults rays = cast_local_diameter(surface, fans, result.normals, cast, params.L_max, params.threads);
    result.D = std::move(rays.D);
    result.D_out = std::move(rays.D_out);
    result.escaped_inward_rays = rays.escaped_inward;
    result.seconds_bvh = rays.bvh_seconds;
    result.seconds_rays = rays.ray_seconds;

    // Rim nodes: D across the cap, in its plane, to the far side of the rim.
    const auto edges = rim_edges(surface, caps.size());
    for (size_t c = 0; c < caps.size(); ++c) {
        const openings::PlaneBasis basis(caps[c].plane.normal);
        std::vector<int32_t> rim_nodes;
        for (const auto& e : edges[c]) rim_nodes.push_back(e[0]);
        for (int32_t i : rim_nodes) {
            const Vec3 x = surface.points[i];
            const Vec3 dir = -result.normals[i];
            const double ox = basis.u(x), oy = basis.v(x), dx = basis.u(dir), dy = basis.v(dir);
            double best = std::numeric_limits<double>::infinity();
            for (const auto& e : edges[c]) {
                if (e[0] == i || e[1] == i) continue;
                const double ax = basis.u(surface.points[e[0]]) - ox, ay = basis.v(surface.points[e[0]]) - oy;
                const double bx = basis.u(surface.points[e[1]]) - ox, by = basis.v(surface.points[e[1]]) - oy;
                // Solve t dir = a + s (b - a), s in [0, 1], t > 0.
                const double ex = bx - ax, ey = by - ay;
                const double den = dx * ey - dy * ex;
                if (den == 0) continue;
                const double t = (ax * ey - ay * ex) / den;
                const double s = (ax * dy - ay * dx) / den;
                // A ray through a rim node hits both its edges; a little slack
                // keeps it from slipping between them.
                if (t > 0 && s >= -1e-9 && s <= 1 + 1e-9) best = std::min(best, t);
            }
            result.D[i] = std::isfinite(best) ? best : params.L_max;
            result.D_out[i] = std::numeric_limits<double>::infinity();
        }
        // Cap-interior nodes: the D of the nearest rim node.
        for (size_t i = 0; i < n; ++i) {
            if (!nodes.interior[i] || nodes.cap_of[i] != static_cast<int32_t>(c)) continue;
            double nearest = std::numeric_limits<double>::infinity();
            for (int32_t r : rim_nodes) {
                const double dist = norm2(surface.points[i] - surface.points[r]);
                if (dist < nearest) {
                    nearest = dist;
                    result.D[i] = result.D[r];
                }
            }
            result.D_out[i] = std::numeric_limits<double>::infinity();
        }
    }
    for (size_t i = 0; i < n; ++i)
        if (nodes.rim[i] || nodes.interior[i]) result.inward_ok[i] = 0;

    result.d = limit_feature_size(surface, result.D, result.D_out, params);
    return result;
}

} // namespace scalemesh
