// The surface's quads and caps in the tet mesh: quads put back on their own
// diagonal (repair_surface_quads) or the surface flipped to the tets'
// (flip_surface_quads, surface_flip_allowed), flat caps over the surface
// taken out (peel_surface_caps).

#include "volume/improve.h"

#include "core/adjacency.h"
#include "volume/quality.h"
#include "volume/tet_editor.h"

#include <algorithm>
#include <array>
#include <map>
#include <optional>
#include <utility>
#include <vector>

namespace scalemesh {
namespace {

using improvement::oriented;
using improvement::place_split_point;
using improvement::split_at;
using improvement::TetEditor;
using improvement::volume_floor6;

// Edge removal for a quad repair: triangulates the polygon `ring` (open
// chain from ring.front() to ring.back(), closed by that pair) so that every
// triangle t gives positive tets (b, t) with orientation `sign` and (d, t)
// with the opposite one, maximising the smallest aspect ratio (dynamic
// programming over sub-polygons, cubic in the ring length). Diagonals that
// already are mesh edges are not used. Returns that smallest aspect ratio,
// or 0 when no triangulation qualifies; `out` gets the tets.
double triangulate_ring(TetEditor& ed, const std::vector<int32_t>& ring, int32_t b, int32_t d, int sign, double floor6,
                        std::vector<Tet>& out)
{
    const int m = static_cast<int>(ring.size());
    auto cone = [&](int32_t tip, int i, int l, int j, int want, Tet& tet) {
        double v6 = 0;
        tet = oriented(ed, tip, ring[i], ring[l], ring[j], v6);
        const int s = tet[1] == ring[i] ? 1 : -1;
        if (s != want || !(v6 > floor6)) return 0.0;
        return ed.aspect(tet);
    };
    std::vector<char> usable(m * m, 1); // diagonal (i, j) not already an edge
    for (int i = 0; i < m; ++i)
        for (int j = i + 2; j < m; ++j)
            if (!(i == 0 && j == m - 1)) usable[i * m + j] = !ed.has_edge(ring[i], ring[j]);
    std::vector<double> best(m * m, 0.0);
    std::vector<int> split(m * m, -1);
    for (int i = 0; i + 1 < m; ++i) best[i * m + i + 1] = 1e300;
    for (int len = 2; len < m; ++len)
        for (int i = 0; i + len < m; ++i) {
            const int j = i + len;
            if (!usable[i * m + j]) continue;
            for (int l = i + 1; l < j; ++l) {
                const double inner = std::min(best[i * m + l], best[l * m + j]);
                if (!(inner > best[i * m + j])) continue;
                Tet tb, td;
                const double q = std::min({inner, cone(b, i, l, j, sign, tb), cone(d, i, l, j, -sign, td)});
                if (q > best[i * m + j]) best[i * m + j] = q, split[i * m + j] = l;
            }
        }
    if (!(best[m - 1] > 0)) return 0.0;
    out.clear();
    std::vector<std::pair<int, int>> stack{{0, m - 1}};
    while (!stack.empty()) {
        const auto [i, j] = stack.back();
        stack.pop_back();
        if (j - i < 2) continue;
        const int l = split[i * m + j];
        Tet tet;
        cone(b, i, l, j, sign, tet);
        out.push_back(tet);
        cone(d, i, l, j, -sign, tet);
        out.push_back(tet);
        stack.push_back({i, l});
        stack.push_back({l, j});
    }
    return best[m - 1];
}

// The fallback of a quad repair: a new interior point m below the middle of
// the stand-in diagonal (b, d) splits every tet (b, d, x, y) at it into
// (m, d, x, y) and (b, m, x, y), and the two tets (a, c, b, m), (a, d, c, m)
// put the quad's own triangles on the boundary. m is taken where the
// smallest aspect ratio of all these tets is best; false (nothing changed)
// when none keeps them all positive.
bool split_quad_diagonal(TetEditor& ed, int32_t a, int32_t b, int32_t c, int32_t d,
                         const std::vector<int32_t>& around)
{
    const Vec3 mid = 0.5 * (ed.point(b) + ed.point(d));
    const Vec3 outward = cross(ed.point(b) - ed.point(a), ed.point(c) - ed.point(a)) +
                         cross(ed.point(c) - ed.point(a), ed.point(d) - ed.point(a));
    if (!(norm2(outward) > 0)) return false;
    const Vec3 inward = -normalized(outward);
    const double length = distance(ed.point(b), ed.point(d));
    const int32_t m = ed.add_point(mid);
    std::vector<Tet> fresh = split_at(ed, around, b, d, m);
    fresh.push_back({a, c, b, m});
    fresh.push_back({a, d, c, m});
    double best = 0;
    Vec3 best_position;
    for (double depth : {0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5}) {
        ed.point(m) = mid + depth * length * inward;
        double worst = 1e300;
        for (const Tet& t : fresh) worst = std::min(worst, ed.aspect(t));
        if (worst > best) best = worst, best_position = ed.point(m);
    }
    return place_split_point(ed, m, best > 1e-6 ? std::optional<Vec3>(best_position) : std::nullopt, around, fresh);
}

} // namespace

std::vector<int32_t> repair_surface_quads(TetMesh& mesh, const std::vector<std::array<int32_t, 4>>& quads)
{
    std::vector<int32_t> failed;
    if (quads.empty()) return failed;
    TetEditor ed(mesh);
    for (size_t qi = 0; qi < quads.size(); ++qi) {
        const auto [a, b, c, d] = quads[qi];
        const std::vector<int32_t> around = ed.around_edge(b, d);
        // The chain a = r_0, r_1, ..., r_{k+1} = c of the tets at (b, d).
        std::vector<int32_t> chain{a};
        std::vector<char> used(around.size(), 0);
        bool ok = !ed.has_edge(a, c);
        while (ok && chain.back() != c) {
            ok = false;
            for (size_t t = 0; t < around.size(); ++t) {
                const int32_t from = chain.back();
                if (used[t] || !TetEditor::contains(ed.tet(around[t]), from)) continue;
                for (int32_t v : ed.tet(around[t]))
                    if (v != b && v != d && v != from) chain.push_back(v);
                used[t] = 1;
                ok = true;
                break;
            }
        }
        ok = ok && chain.size() >= 3 && std::count(used.begin(), used.end(), 1) == int64_t(around.size());
        // The polygon a, r_1, ..., r_k, c (closed by c -> a) is triangulated
        // (edge removal by dynamic programming over its sub-polygons) so that
        // the cones from b and d over its triangles are all clearly positive,
        // b and d on opposite sides, with the best smallest aspect ratio.
        std::vector<Tet> fresh;
        if (ok) {
            std::vector<Tet> old;
            for (int32_t t : around) old.push_back(ed.tet(t));
            const double floor6 = volume_floor6(ed, old);
            ok = false;
            double best = 0;
            for (int sign : {1, -1}) {
                std::vector<Tet> candidate;
                const double q = triangulate_ring(ed, chain, b, d, sign, floor6, candidate);
                if (q > best) best = q, fresh = std::move(candidate), ok = true;
            }
        }
        if (!ok && !split_quad_diagonal(ed, a, b, c, d, around)) {
            failed.push_back(static_cast<int32_t>(qi));
            continue;
        }
        if (ok) ed.replace(around, fresh);
    }
    ed.commit();
    return failed;
}

namespace {

Vec3 unit_normal(const std::vector<Vec3>& points, const Triangle& f)
{
    const Vec3 n = cross(points[f[1]] - points[f[0]], points[f[2]] - points[f[0]]);
    return norm2(n) > 0 ? normalized(n) : Vec3{};
}

// The no-fold rule of a flip of the surface: the new pair of triangles'
// normals within 60 degrees of each other and of the old pair's.
bool flip_folds_little(const std::vector<Vec3>& points, const Triangle& old1, const Triangle& old2,
                       const Triangle& new1, const Triangle& new2)
{
    constexpr double kCos60 = 0.5;
    const Vec3 n1 = unit_normal(points, new1), n2 = unit_normal(points, new2);
    const Vec3 both = unit_normal(points, old1) + unit_normal(points, old2);
    const double reach = kCos60 * norm(both);
    return dot(n1, n2) > kCos60 && dot(n1, both) > reach && dot(n2, both) > reach;
}

} // namespace

bool surface_flip_allowed(const SurfaceMesh& surface, const std::array<int32_t, 4>& quad,
                          const std::array<int32_t, 2>& ids, const EdgeSet& edges)
{
    const auto patch = [&](int32_t t) { return surface.triangle_patch.empty() ? 0 : surface.triangle_patch[t]; };
    const auto [a, b, c, d] = quad;
    if (edges.count(edge_key(b, d)) || patch(ids[0]) != patch(ids[1])) return false;
    return flip_folds_little(surface.points, {a, b, c}, {a, c, d}, {a, b, d}, {b, c, d});
}

int64_t peel_surface_caps(TetMesh& mesh, int32_t surface_points, double threshold)
{
    const std::vector<Vec3>& p = mesh.points;
    std::vector<size_t> caps;
    std::vector<char> involved(mesh.points.size(), 0); // boundary faces may hold any point
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        const Tet& tet = mesh.tets[t];
        if (*std::max_element(tet.begin(), tet.end()) >= surface_points ||
            !(tet_aspect_ratio(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]]) < threshold))
            continue;
        caps.push_back(t);
        for (int32_t v : tet) involved[v] = 1;
    }
    if (caps.empty()) return 0;

    // The boundary faces and edges among the candidates' points.
    const auto key = [](Triangle f) {
        std::sort(f.begin(), f.end());
        return f;
    };
    std::map<Triangle, int32_t> face_id;
    EdgeSet edges;
    for (size_t f = 0; f < mesh.boundary_faces.size(); ++f) {
        const Triangle& tri = mesh.boundary_faces[f];
        if (involved[tri[0]] && involved[tri[1]] && involved[tri[2]]) face_id[key(tri)] = static_cast<int32_t>(f);
        for (int i = 0; i < 3; ++i)
            if (involved[tri[i]] && involved[tri[(i + 1) % 3]]) edges.insert(edge_key(tri[i], tri[(i + 1) % 3]));
    }
    const auto patch = [&](int32_t f) { return mesh.boundary_patch.empty() ? 0 : mesh.boundary_patch[f]; };
    std::vector<char> peeled(mesh.tets.size(), 0);
    int64_t count = 0;
    for (size_t t : caps) {
        const Tet tet = mesh.tets[t];
        // The face opposite each point, counter-clockwise seen from outside the tet.
        const Triangle face[4] = {{tet[1], tet[2], tet[3]}, {tet[0], tet[3], tet[2]}, {tet[0], tet[1], tet[3]},
                                  {tet[0], tet[2], tet[1]}};
        std::array<int32_t, 4> id{};
        std::vector<int> on, off;
        for (int i = 0; i < 4; ++i) {
            const auto it = face_id.find(key(face[i]));
            id[i] = it == face_id.end() ? -1 : it->second;
            (id[i] >= 0 ? on : off).push_back(i);
        }
        if (on.size() != 2) continue;
        // The boundary faces opposite i and j share the edge (k, l); the
        // faces opposite k and l, seen from the tets beyond them, replace them.
        const int i = on[0], j = on[1], k = off[0], l = off[1];
        const Triangle new_k{face[k][0], face[k][2], face[k][1]}, new_l{face[l][0], face[l][2], face[l][1]};
        if (edges.count(edge_key(tet[i], tet[j])) || patch(id[i]) != patch(id[j]) ||
            !flip_folds_little(p, face[i], face[j], new_k, new_l))
            continue;
        mesh.boundary_faces[id[i]] = new_k;
        mesh.boundary_faces[id[j]] = new_l;
        face_id.erase(key(face[i]));
        face_id.erase(key(face[j]));
        face_id[key(new_k)] = id[i];
        face_id[key(new_l)] = id[j];
        edges.erase(edge_key(tet[k], tet[l]));
        edges.insert(edge_key(tet[i], tet[j]));
        peeled[t] = 1;
        ++count;
    }
    size_t kept = 0;
    for (size_t t = 0; t < mesh.tets.size(); ++t)
        if (!peeled[t]) mesh.tets[kept++] = mesh.tets[t];
    mesh.tets.resize(kept);
    return count;
}

std::vector<int32_t> flip_surface_quads(const SurfaceMesh& surface, const std::vector<std::array<int32_t, 4>>& quads,
                                        const std::vector<std::array<int32_t, 2>>& quad_triangles,
                                        const std::vector<int32_t>& which, std::vector<Triangle>& triangles)
{
    std::vector<int32_t> left;
    if (which.empty()) return left;
    EdgeSet edges = edge_set(triangles);
    for (int32_t q : which) {
        const auto [a, b, c, d] = quads[q];
        if (!surface_flip_allowed(surface, quads[q], quad_triangles[q], edges)) {
            left.push_back(q);
            continue;
        }
        triangles[quad_triangles[q][0]] = {a, b, d};
        triangles[quad_triangles[q][1]] = {b, c, d};
        edges.erase(edge_key(a, c));
        edges.insert(edge_key(b, d));
    }
    return left;
}

} // namespace scalemesh
