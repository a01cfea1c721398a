#include "openings/openings.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "openings/plane_triangulation.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <set>
#include <sstream>
#include <unordered_map>

namespace scalemesh {

namespace {

using openings::PlaneBasis;

std::string text(const Vec3& x)
{
    std::ostringstream out;
    out << "(" << x.x << ", " << x.y << ", " << x.z << ")";
    return out.str();
}

double extent(const SurfaceMesh& mesh)
{
    Vec3 lo, hi;
    bounding_box(mesh, lo, hi);
    return std::max(distance(lo, hi), 1e-300);
}

// Inverse of the 3x3 matrix with columns a[0], a[1], a[2]: rows r[i] with
// r[i] . a[j] = delta_ij.
std::array<Vec3, 3> inverse_rows(const Vec3 a[3])
{
    const double det = dot(a[0], cross(a[1], a[2]));
    if (!(std::abs(det) > 0)) throw InputError("the image axes are degenerate", "check the image's spacing and direction");
    return {cross(a[1], a[2]) / det, cross(a[2], a[0]) / det, cross(a[0], a[1]) / det};
}

// The plane of a border opening: perpendicular to the image axis of `side`,
// `inset` mm inside the outermost surface point on that side.
Plane border_plane(const SurfaceMesh& mesh, const OpeningSpec& spec, const ImageFrame& frame)
{
    static const std::vector<std::string> sides = {"x-", "x+", "y-", "y+", "z-", "z+"};
    const auto it = std::find(sides.begin(), sides.end(), spec.side);
    if (it == sides.end())
        throw InputError("opening '" + spec.name + "': border side '" + spec.side + "' is not a side",
                         "choose one of x-, x+, y-, y+, z-, z+ (image axes)");
    const int axis = static_cast<int>(it - sides.begin()) / 2;
    const double sign = spec.side[1] == '+' ? 1.0 : -1.0;
    const auto rows = inverse_rows(frame.axis);
    double extreme = -sign * INFINITY;
    Vec3 mean_index;
    int64_t used = 0;
    std::vector<char> referenced(mesh.points.size(), 0);
    for (const Triangle& t : mesh.triangles)
        for (int32_t v : t) referenced[v] = 1;
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        if (!referenced[i]) continue;
        const Vec3 rel = mesh.points[i] - frame.origin;
        const Vec3 index{dot(rows[0], rel), dot(rows[1], rel), dot(rows[2], rel)};
        extreme = sign > 0 ? std::max(extreme, index[axis]) : std::min(extreme, index[axis]);
        mean_index += index;
        ++used;
    }
    if (used == 0) throw InputError("opening '" + spec.name + "': the surface is empty", "check the input");
    mean_index /= static_cast<double>(used);
    const double step = norm(frame.axis[axis]);
    mean_index[axis] = extreme - sign * spec.inset / step;
    Plane plane;
    plane.point = frame.origin + mean_index.x * frame.axis[0] + mean_index.y * frame.axis[1] + mean_index.z * frame.axis[2];
    Vec3 normal = normalized(cross(frame.axis[(axis + 1) % 3], frame.axis[(axis + 2) % 3]));
    if (dot(normal, frame.axis[axis]) * sign < 0) normal = -normal;
    plane.normal = normal;
    return plane;
}

class Cutter {
public:
    Cutter(SurfaceMesh& mesh, std::vector<Cap>& caps) : mesh_(mesh), caps_(caps) {}

    void cut(const OpeningSpec& spec, Plane plane)
    {
        const std::string who = "opening '" + spec.name + "'";
        const double scale = extent(mesh_);
        plane.normal = normalized(plane.normal);
        if (!(norm2(plane.normal) > 0.5))
            throw InputError(who + ": the plane normal is zero", "give the outward normal of the opening, e.g. [0, 0, 1]");

        // Keep every vertex off the plane: shift it by a tiny amount along
        // its normal until none is within round-off of it.
        std::vector<double> s(mesh_.points.size());
        for (int attempt = 0;; ++attempt) {
            double closest = INFINITY;
            for (size_t i = 0; i < s.size(); ++i) {
                s[i] = plane.signed_distance(mesh_.points[i]);
                closest = std::min(closest, std::abs(s[i]));
            }
            if (closest > 1e-9 * scale || attempt == 20) break;
            plane.point += 3e-9 * scale * plane.normal;
        }

        // Split the triangles crossing the plane; the new vertices lie on it.
        std::unordered_map<uint64_t, int32_t> cut_vertex;
        const auto crossing = [&](int32_t a, int32_t b) {
            const uint64_t key = edge_key(a, b);
            if (auto it = cut_vertex.find(key); it != cut_vertex.end()) return it->second;
            const Vec3& pa = mesh_.points[a];
            const Vec3& pb = mesh_.points[b];
            Vec3 x = pa + (s[a] / (s[a] - s[b])) * (pb - pa);
            x -= plane.signed_distance(x) * plane.normal;
            const auto id = static_cast<int32_t>(mesh_.points.size());
            mesh_.points.push_back(x);
            is_cut_.resize(mesh_.points.size(), 0);
            is_cut_[id] = 1;
            cut_vertex.emplace(key, id);
            return id;
        };
        is_cut_.assign(mesh_.points.size(), 0);
        std::vector<Triangle> triangles;
        std::vector<int32_t> patches;
        std::vector<char> inside;
        triangles.reserve(mesh_.triangles.size() + 1024);
        const auto emit = [&](const Triangle& t, int32_t patch, bool in) {
            triangles.push_back(t);
            patches.push_back(patch);
            inside.push_back(in);
        };
        for (size_t f = 0; f < mesh_.triangles.size(); ++f) {
            const Triangle& t = mesh_.triangles[f];
            const int32_t patch = mesh_.triangle_patch[f];
            const bool neg[3] = {s[t[0]] < 0, s[t[1]] < 0, s[t[2]] < 0};
            if (neg[0] == neg[1] && neg[1] == neg[2]) {
                emit(t, patch, neg[0]);
                continue;
            }
            if (patch != 0)
                throw InputError(who + ": its plane cuts the cap of opening '" + caps_[patch - 1].name + "'",
                                 "move the plane so that the openings do not meet");
            // The lone vertex p (the one whose side differs), then q, r in order.
            const int k = neg[0] != neg[1] && neg[0] != neg[2] ? 0 : (neg[1] != neg[0] && neg[1] != neg[2] ? 1 : 2);
            const int32_t p = t[k], q = t[(k + 1) % 3], r = t[(k + 2) % 3];
            const int32_t pq = crossing(p, q), rp = crossing(r, p);
            const bool p_in = neg[k];
            emit({p, pq, rp}, patch, p_in);
            // The quad (pq, q, r, rp) split along its shorter diagonal.
            if (norm2(mesh_.points[pq] - mesh_.points[r]) <= norm2(mesh_.points[q] - mesh_.points[rp])) {
                emit({pq, q, r}, patch, !p_in);
                emit({pq, r, rp}, patch, !p_in);
            } else {
                emit({pq, q, rp}, patch, !p_in);
                emit({q, r, rp}, patch, !p_in);
            }
        }

        // The crossings: inside faces have one edge between two cut vertices,
        // traversed u -> v; each cut vertex starts exactly one such edge.
        std::unordered_map<int32_t, int32_t> next;
        for (size_t f = 0; f < triangles.size(); ++f) {
            if (!inside[f]) continue;
            const Triangle& t = triangles[f];
            for (int k = 0; k < 3; ++k)
                if (is_cut_[t[k]] && is_cut_[t[(k + 1) % 3]]) next[t[k]] = t[(k + 1) % 3];
        }
        std::vector<std::vector<int32_t>> loops;
        std::unordered_map<int32_t, int32_t> loop_of;
        std::vector<int32_t> starts;
        for (const auto& [u, v] : next) starts.push_back(u);
        std::sort(starts.begin(), starts.end());
        for (int32_t start : starts) {
            if (loop_of.count(start)) continue;
            std::vector<int32_t> loop;
            int32_t u = start;
            do {
                loop_of[u] = static_cast<int32_t>(loops.size());
                loop.push_back(u);
                const auto it = next.find(u);
                if (it == next.end())
                    throw StageError("openings", who + ": the crossing at " + text(mesh_.points[u]) +
                                                     " does not close (the surface is not a closed manifold there)");
                u = it->second;
            } while (u != start && loop.size() <= next.size());
            if (u != start) throw StageError("openings", who + ": a crossing of the plane does not close");
            loops.push_back(std::move(loop));
        }
        if (loops.empty())
            throw InputError(who + ": the plane through " + text(plane.point) + " with normal " + text(plane.normal) +
                                 " does not cut the surface",
                             "put the plane's point inside the lumen, across the vessel you want to open");

        // Pick the crossings: within radius of the point, or the only one.
        const PlaneBasis basis(plane.normal);
        std::vector<Vec3> centre(loops.size());
        for (size_t l = 0; l < loops.size(); ++l) {
            for (int32_t u : loops[l]) centre[l] += mesh_.points[u];
            centre[l] /= static_cast<double>(loops[l].size());
        }
        std::vector<char> chosen(loops.size(), 0);
        if (spec.radius > 0) {
            for (size_t l = 0; l < loops.size(); ++l) chosen[l] = distance(centre[l], plane.point) <= spec.radius;
            if (std::find(chosen.begin(), chosen.end(), 1) == chosen.end()) {
                std::ostringstream msg;
                msg << who << ": none of the plane's " << loops.size() << " crossings of the lumen has its centre within "
                    << spec.radius << " mm of " << text(plane.point) << " (nearest centre "
                    << text(*std::min_element(centre.begin(), centre.end(), [&](const Vec3& a, const Vec3& b) {
                           return distance(a, plane.point) < distance(b, plane.point);
                       }))
                    << ")";
                throw InputError(msg.str(), "move the point onto the vessel or enlarge the radius");
            }
        } else if (spec.border || loops.size() == 1) {
            std::fill(chosen.begin(), chosen.end(), 1);
        } else {
            std::ostringstream msg;
            msg << who << ": the plane crosses the lumen in " << loops.size() << " places (centres";
            for (size_t l = 0; l < loops.size() && l < 6; ++l) msg << " " << text(centre[l]);
            msg << ")";
            throw InputError(msg.str(), "give the opening a radius (mm) so that only the crossing near its point is cut");
        }

        // Remove what lies beyond the chosen crossings: the outside faces
        // reached from them without crossing the plane.
        std::unordered_map<uint64_t, int32_t> face_of_edge;
        face_of_edge.reserve(3 * triangles.size());
        for (size_t f = 0; f < triangles.size(); ++f)
            for (int k = 0; k < 3; ++k)
                face_of_edge.emplace(directed_edge_key(triangles[f][k], triangles[f][(k + 1) % 3]), static_cast<int32_t>(f));
        std::vector<char> removed(triangles.size(), 0);
        std::deque<int32_t> queue;
        for (size_t l = 0; l < loops.size(); ++l) {
            if (!chosen[l]) continue;
            for (size_t k = 0; k < loops[l].size(); ++k) {
                const int32_t u = loops[l][k], v = loops[l][(k + 1) % loops[l].size()];
                const auto it = face_of_edge.find(directed_edge_key(v, u));
                if (it == face_of_edge.end() || inside[it->second])
                    throw StageError("openings", who + ": the surface is not a closed manifold at the crossing");
                if (!removed[it->second]) {
                    removed[it->second] = 1;
                    queue.push_back(it->second);
                }
            }
        }
        while (!queue.empty()) {
            const int32_t f = queue.front();
            queue.pop_front();
            for (int k = 0; k < 3; ++k) {
                const int32_t a = triangles[f][k], b = triangles[f][(k + 1) % 3];
                const auto it = face_of_edge.find(directed_edge_key(b, a));
                if (it == face_of_edge.end()) continue;
                const int32_t g = it->second;
                if (inside[g]) {
                    const auto l = loop_of.find(b);
                    if (l != loop_of.end() && !chosen[l->second])
                        throw InputError(who + ": the part of the surface beyond the plane near " +
                                             text(centre[l->second]) + " reaches back across it elsewhere",
                                         "move the plane so that it cuts the vessel once, or give a radius that "
                                         "includes every crossing of the part to remove");
                    continue;
                }
                if (!removed[g]) {
                    removed[g] = 1;
                    queue.push_back(g);
                }
            }
        }

        // Cap the chosen crossings: constrained Delaunay in the plane.
        std::vector<int32_t> rim_ids;
        std::vector<std::vector<int32_t>> rim_loops;
        std::vector<double> u, v;
        for (size_t l = 0; l < loops.size(); ++l) {
            if (!chosen[l]) continue;
            std::vector<int32_t> local;
            for (int32_t id : loops[l]) {
                local.push_back(static_cast<int32_t>(rim_ids.size()));
                rim_ids.push_back(id);
                u.push_back(basis.u(mesh_.points[id]));
                v.push_back(basis.v(mesh_.points[id]));
            }
            rim_loops.push_back(std::move(local));
        }
        std::vector<openings::PlanePiece> pieces = openings::triangulate_loops(u, v, rim_loops, "openings");
        if (pieces.empty()) throw StageError("openings", who + ": the cap has no area");
        if (!spec.border && pieces.size() > 1)
            throw InputError(who + ": the chosen crossing of the plane is " + std::to_string(pieces.size()) +
                                 " separate pieces",
                             "give a smaller radius so that one crossing is cut, or use one opening per piece");

        std::vector<Triangle> kept;
        std::vector<int32_t> kept_patch;
        for (size_t f = 0; f < triangles.size(); ++f) {
            if (removed[f]) continue;
            kept.push_back(triangles[f]);
            kept_patch.push_back(patches[f]);
        }
        for (size_t p = 0; p < pieces.size(); ++p) {
            Cap cap;
            cap.name = pieces.size() == 1 ? spec.name : spec.name + "_" + std::to_string(p + 1);
            cap.type = spec.type;
            cap.patch = static_cast<int32_t>(caps_.size()) + 1;
            cap.plane = plane;
            cap.area = pieces[p].area;
            cap.centroid = plane.point + (pieces[p].cu - basis.u(plane.point)) * basis.e1 +
                           (pieces[p].cv - basis.v(plane.point)) * basis.e2;
            for (const auto& t : pieces[p].triangles) {
                kept.push_back({rim_ids[t[0]], rim_ids[t[1]], rim_ids[t[2]]});
                kept_patch.push_back(cap.patch);
            }
            caps_.push_back(cap);
        }
        mesh_.triangles = std::move(kept);
        mesh_.triangle_patch = std::move(kept_patch);
        if (spec.extension > 0)
            for (size_t p = 0; p < pieces.size(); ++p) extend(caps_[caps_.size() - pieces.size() + p], spec.extension);
        compact();
        if (mesh_.triangles.empty()) throw InputError(who + ": nothing of the surface is left", "flip the plane's normal");
    }

private:
    // Sweeps the rim of `cap` along its normal by `diameters` cap diameters
    // into a straight tube and moves the cap to its end.
    void extend(Cap& cap, double diameters)
    {
        std::vector<std::array<int32_t, 2>> rim;
        std::vector<std::array<int32_t, 2>> edges;
        for (size_t f = 0; f < mesh_.triangles.size(); ++f) {
            if (mesh_.triangle_patch[f] != cap.patch) continue;
            const Triangle& t = mesh_.triangles[f];
            for (int k = 0; k < 3; ++k) edges.push_back({t[k], t[(k + 1) % 3]});
        }
        std::vector<std::array<int32_t, 2>> sorted = edges;
        std::sort(sorted.begin(), sorted.end());
        double perimeter = 0;
        for (const auto& e : edges)
            if (!std::binary_search(sorted.begin(), sorted.end(), std::array<int32_t, 2>{e[1], e[0]})) {
                rim.push_back(e);
                perimeter += distance(mesh_.points[e[0]], mesh_.points[e[1]]);
            }
        const double length = diameters * 2 * std::sqrt(cap.area / std::acos(-1.0));
        const int steps = std::max(1, static_cast<int>(std::ceil(length / (perimeter / rim.size()))));
        // Level k of each rim node, k = 0 the node itself.
        std::unordered_map<int32_t, int32_t> level;
        for (const auto& e : rim) level.emplace(e[0], e[0]);
        for (int k = 1; k <= steps; ++k) {
            const Vec3 shift = (length * k / steps) * cap.plane.normal;
            std::unordered_map<int32_t, int32_t> upper;
            for (const auto& [node, id] : level) {
                upper[node] = static_cast<int32_t>(mesh_.points.size());
                mesh_.points.push_back(mesh_.points[node] + shift);
            }
            // The wall face on rim edge a -> b runs b -> a; the new band runs a -> b below.
            for (const auto& e : rim) {
                const int32_t a0 = level[e[0]], b0 = level[e[1]], a1 = upper[e[0]], b1 = upper[e[1]];
                mesh_.triangles.push_back({a0, b0, b1});
                mesh_.triangles.push_back({a0, b1, a1});
                mesh_.triangle_patch.insert(mesh_.triangle_patch.end(), {0, 0});
            }
            level = std::move(upper);
        }
        for (size_t f = 0; f < mesh_.triangles.size(); ++f) {
            if (mesh_.triangle_patch[f] != cap.patch) continue;
            for (int32_t& v : mesh_.triangles[f]) v = level.at(v);
        }
        cap.plane.point += length * cap.plane.normal;
        cap.centroid += length * cap.plane.normal;
    }

    // Drops points no triangle uses, keeping the order of the rest.
    void compact()
    {
        std::vector<int32_t> index(mesh_.points.size(), -1);
        for (const Triangle& t : mesh_.triangles)
            for (int32_t v : t) index[v] = 0;
        std::vector<Vec3> points;
        for (size_t i = 0; i < index.size(); ++i)
            if (index[i] == 0) {
                index[i] = static_cast<int32_t>(points.size());
                points.push_back(mesh_.points[i]);
            }
        for (Triangle& t : mesh_.triangles)
            for (int32_t& v : t) v = index[v];
        mesh_.points = std::move(points);
    }

    SurfaceMesh& mesh_;
    std::vector<Cap>& caps_;
    std::vector<char> is_cut_;
};

} // namespace

CappedSurface cut_and_cap(const SurfaceMesh& surface, const std::vector<OpeningSpec>& openings,
                          const ImageFrame& frame)
{
    require_closed_manifold(surface, "the surface to open");
    std::set<std::string> names;
    for (const OpeningSpec& spec : openings) {
        if (spec.name.empty()) throw InputError("an opening has no name", "give every opening a name");
        if (spec.name == "wall")
            throw InputError("an opening is named 'wall'", "'wall' is the patch of the vessel wall; choose another name");
        if (!names.insert(spec.name).second)
            throw InputError("two openings are named '" + spec.name + "'", "give every opening its own name");
    }
    CappedSurface result;
    result.surface = surface;
    result.surface.triangle_patch.resize(surface.triangles.size(), 0);
    Cutter cutter(result.surface, result.caps);
    for (const OpeningSpec& spec : openings)
        cutter.cut(spec, spec.border ? border_plane(result.surface, spec, frame) : spec.plane);
    // Project cap vertices onto their planes: they are there to round-off
    // already; this makes the distance a single rounding.
    for (size_t f = 0; f < result.surface.triangles.size(); ++f) {
        const int32_t patch = result.surface.triangle_patch[f];
        if (patch == 0) continue;
        const Plane& plane = result.caps[patch - 1].plane;
        for (int32_t v : result.surface.triangles[f]) {
            Vec3& x = result.surface.points[v];
            x -= plane.signed_distance(x) * plane.normal;
        }
    }
    require_closed_manifold(result.surface, "the surface with its openings capped");
    return result;
}

std::vector<Vec3> patch_normals(const std::vector<Cap>& caps)
{
    std::vector<Vec3> normals(caps.size() + 1, Vec3{0, 0, 0});
    for (const Cap& cap : caps) normals[cap.patch] = cap.plane.normal;
    return normals;
}

} // namespace scalemesh
