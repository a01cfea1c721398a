#include "openings/openings.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "openings/plane_triangulation.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <set>
#include <sstream>
#include <unordered_map>

namespace scalemesh {

namespace {

using openings::PlaneBasis;
using Edge = std::array<int32_t, 2>; // a < b

std::string text(const Vec3& x)
{
    std::ostringstream out;
    out << "(" << x.x << ", " << x.y << ", " << x.z << ")";
    return out.str();
}

std::string number(double x)
{
    std::ostringstream out;
    out.precision(3);
    out << x;
    return out.str();
}

double extent(const SurfaceMesh& mesh)
{
    Vec3 lo, hi;
    bounding_box(mesh, lo, hi);
    return std::max(distance(lo, hi), 1e-300);
}

Edge edge(int32_t a, int32_t b) { return {std::min(a, b), std::max(a, b)}; }
uint64_t key(const Edge& e) { return directed_edge_key(e[0], e[1]); }

// Inverse of the 3x3 matrix with columns a[0], a[1], a[2]: rows r[i] with
// r[i] . a[j] = delta_ij.
std::array<Vec3, 3> inverse_rows(const Vec3 a[3])
{
    const double det = dot(a[0], cross(a[1], a[2]));
    if (!(std::abs(det) > 0)) throw InputError("the image axes are degenerate", "check the image's spacing and direction");
    return {cross(a[1], a[2]) / det, cross(a[2], a[0]) / det, cross(a[0], a[1]) / det};
}

// The point where edge e crosses the level s = 0 (s > 0 beyond), from its
// lower-numbered end, so that it does not depend on who asks.
Vec3 crossing_point(const SurfaceMesh& mesh, const std::vector<double>& s, const Edge& e)
{
    const Vec3& a = mesh.points[e[0]];
    const Vec3& b = mesh.points[e[1]];
    return a + (s[e[0]] / (s[e[0]] - s[e[1]])) * (b - a);
}

// A triangle crossing the level s = 0: its piece of the crossing runs from
// the crossing on edge `from` to the one on edge `to`, so that the pieces
// chain into loops (clockwise seen from the beyond side); `beyond` is one of
// its vertices with s > 0.
struct Segment {
    Edge from, to;
    int32_t beyond;
};

std::optional<Segment> segment(const Triangle& t, const std::vector<double>& s)
{
    const bool out[3] = {s[t[0]] > 0, s[t[1]] > 0, s[t[2]] > 0};
    if (out[0] == out[1] && out[1] == out[2]) return std::nullopt;
    const int k = out[0] != out[1] && out[0] != out[2] ? 0 : (out[1] != out[0] && out[1] != out[2] ? 1 : 2);
    const int32_t p = t[k], q = t[(k + 1) % 3], r = t[(k + 2) % 3];
    if (out[k]) return Segment{edge(r, p), edge(p, q), p};
    return Segment{edge(p, q), edge(r, p), q};
}

// Connected parts of the surface where `beyond` is set: per vertex the number
// of its part, -1 where not set.
std::vector<int32_t> parts_beyond(const std::vector<char>& beyond, const VertexTable& neighbours, int32_t& count)
{
    std::vector<int32_t> part(beyond.size(), -1);
    std::vector<int32_t> stack;
    count = 0;
    for (size_t start = 0; start < beyond.size(); ++start) {
        if (!beyond[start] || part[start] >= 0) continue;
        part[start] = count;
        stack.push_back(static_cast<int32_t>(start));
        while (!stack.empty()) {
            const int32_t v = stack.back();
            stack.pop_back();
            for (const int32_t* w = neighbours.begin(v); w != neighbours.end(v); ++w)
                if (beyond[*w] && part[*w] < 0) {
                    part[*w] = count;
                    stack.push_back(*w);
                }
        }
        ++count;
    }
    return part;
}

// A border opening's plane, and which vertices lie within BorderRule::reach
// of the image face (the parts of the lumen holding one are capped).
struct BorderPlacement {
    Plane plane;
    std::vector<char> reaching;
    BorderCut report;
};

// One opening's cut, planned on the input surface.
struct PlannedCut {
    size_t opening = 0;
    Plane plane;
    std::vector<std::vector<Edge>> rims; // the chosen crossings, as crossed edges in loop order
    std::vector<int32_t> faces;          // input triangles the chosen crossings run through, sorted
    std::vector<char> removed;           // per input point: in the part beyond the chosen crossings
};

// Sweeps the rim of `cap` along its normal by `diameters` cap diameters
// into a straight tube and moves the cap to its end.
void extend(SurfaceMesh& mesh, Cap& cap, double diameters)
{
    std::vector<std::array<int32_t, 2>> rim;
    std::vector<std::array<int32_t, 2>> edges;
    for (size_t f = 0; f < mesh.triangles.size(); ++f) {
        if (mesh.triangle_patch[f] != cap.patch) continue;
        const Triangle& t = mesh.triangles[f];
        for (int k = 0; k < 3; ++k) edges.push_back({t[k], t[(k + 1) % 3]});
    }
    std::vector<std::array<int32_t, 2>> sorted = edges;
    std::sort(sorted.begin(), sorted.end());
    double perimeter = 0;
    for (const auto& e : edges)
        if (!std::binary_search(sorted.begin(), sorted.end(), std::array<int32_t, 2>{e[1], e[0]})) {
            rim.push_back(e);
            perimeter += distance(mesh.points[e[0]], mesh.points[e[1]]);
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
            upper[node] = static_cast<int32_t>(mesh.points.size());
            mesh.points.push_back(mesh.points[node] + shift);
        }
        // The wall face on rim edge a -> b runs b -> a; the new band runs a -> b below.
        for (const auto& e : rim) {
            const int32_t a0 = level[e[0]], b0 = level[e[1]], a1 = upper[e[0]], b1 = upper[e[1]];
            mesh.triangles.push_back({a0, b0, b1});
            mesh.triangles.push_back({a0, b1, a1});
            mesh.triangle_patch.insert(mesh.triangle_patch.end(), {0, 0});
        }
        level = std::move(upper);
    }
    for (size_t f = 0; f < mesh.triangles.size(); ++f) {
        if (mesh.triangle_patch[f] != cap.patch) continue;
        for (int32_t& v : mesh.triangles[f]) v = level.at(v);
    }
    cap.plane.point += length * cap.plane.normal;
    cap.centroid += length * cap.plane.normal;
}

// Drops points no triangle uses, keeping the order of the rest.
void compact(SurfaceMesh& mesh)
{
    std::vector<int32_t> index(mesh.points.size(), -1);
    for (const Triangle& t : mesh.triangles)
        for (int32_t v : t) index[v] = 0;
    std::vector<Vec3> points;
    for (size_t i = 0; i < index.size(); ++i)
        if (index[i] == 0) {
            index[i] = static_cast<int32_t>(points.size());
            points.push_back(mesh.points[i]);
        }
    for (Triangle& t : mesh.triangles)
        for (int32_t& v : t) v = index[v];
    mesh.points = std::move(points);
}

class Opener {
public:
    Opener(const SurfaceMesh& surface, const ImageFrame& frame)
        : mesh_(surface), frame_(frame), scale_(extent(surface)), neighbours_(vertex_neighbours(surface))
    {
        referenced_.assign(mesh_.points.size(), 0);
        for (const Triangle& t : mesh_.triangles)
            for (int32_t v : t) referenced_[v] = 1;
    }

    CappedSurface open(const std::vector<OpeningSpec>& openings)
    {
        CappedSurface result;
        std::vector<PlannedCut> cuts;
        for (size_t i = 0; i < openings.size(); ++i) {
            const OpeningSpec& spec = openings[i];
            if (spec.border) {
                BorderPlacement placed = place_border(spec);
                cuts.push_back(plan(spec, placed.plane, &placed.reaching));
                result.borders.push_back(std::move(placed.report));
                warn(result.borders.back(), result.warnings);
            } else {
                cuts.push_back(plan(spec, spec.plane, nullptr));
            }
            cuts.back().opening = i;
        }
        for (size_t i = 0; i < cuts.size(); ++i)
            for (size_t j = i + 1; j < cuts.size(); ++j) check_apart(cuts[i], cuts[j], openings);
        assemble(cuts, openings, result);
        return result;
    }

private:
    // The plane of a border opening: perpendicular to the image axis of the
    // side, at the given inset or where BorderRule puts it.
    BorderPlacement place_border(const OpeningSpec& spec) const
    {
        const std::string who = "opening '" + spec.name + "'";
        static const std::vector<std::string> sides = {"x-", "x+", "y-", "y+", "z-", "z+"};
        const auto it = std::find(sides.begin(), sides.end(), spec.side);
        if (it == sides.end())
            throw InputError(who + ": border side '" + spec.side + "' is not a side",
                             "choose one of x-, x+, y-, y+, z-, z+ (image axes)");
        const int axis = static_cast<int>(it - sides.begin()) / 2;
        const double sign = spec.side[1] == '+' ? 1.0 : -1.0;
        const auto rows = inverse_rows(frame_.axis);
        const double step = norm(frame_.axis[axis]);

        // t: index coordinate along the axis, counted outwards (voxels).
        std::vector<double> t(mesh_.points.size(), -INFINITY);
        double t_out = -INFINITY;
        Vec3 mean_index;
        int64_t used = 0;
        for (size_t i = 0; i < mesh_.points.size(); ++i) {
            if (!referenced_[i]) continue;
            const Vec3 rel = mesh_.points[i] - frame_.origin;
            const Vec3 index{dot(rows[0], rel), dot(rows[1], rel), dot(rows[2], rel)};
            t[i] = sign * index[axis];
            t_out = std::max(t_out, t[i]);
            mean_index += index;
            ++used;
        }
        if (used == 0) throw InputError(who + ": the surface is empty", "check the input");
        mean_index /= static_cast<double>(used);
        const bool face_known = frame_.size[axis] > 0;
        const double t_face = !face_known ? t_out : (sign > 0 ? static_cast<double>(frame_.size[axis]) - 0.5 : 0.5);
        if (t_out < t_face - BorderRule::reach)
            throw InputError(who + ": no part of the lumen reaches the " + spec.side +
                                 " side of the image: the outermost surface point on it lies " +
                                 number(t_face - t_out) + " voxels (" + number((t_face - t_out) * step) +
                                 " mm) inside the image face",
                             "use a clip plane (point and normal) for this opening, or check that the "
                             "segmentation runs off the image there");

        Vec3 normal = normalized(cross(frame_.axis[(axis + 1) % 3], frame_.axis[(axis + 2) % 3]));
        if (dot(normal, frame_.axis[axis]) * sign < 0) normal = -normal;
        const PlaneBasis basis(normal);

        BorderPlacement placed;
        placed.reaching.assign(mesh_.points.size(), 0);
        for (size_t i = 0; i < t.size(); ++i) placed.reaching[i] = t[i] > t_face - BorderRule::reach;
        int32_t seeds = 0;
        const std::vector<int32_t> seed_of = parts_beyond(placed.reaching, neighbours_, seeds);

        // The parts beyond the level t = t_out - depth, their cross-section
        // areas (mm^2) and the reaching piece each holds (-1: none, -2: more
        // than one).
        struct Level {
            std::vector<int32_t> part;
            int32_t count = 0;
            std::vector<double> area;
            std::vector<int32_t> seed;
            std::vector<char> crossed;
        };
        const auto level = [&](double depth) {
            Level L;
            std::vector<double> s(t.size());
            std::vector<char> beyond(t.size());
            for (size_t i = 0; i < t.size(); ++i) {
                s[i] = t[i] - (t_out - depth);
                beyond[i] = s[i] > 0;
            }
            L.part = parts_beyond(beyond, neighbours_, L.count);
            L.area.assign(L.count, 0.0);
            L.seed.assign(L.count, -1);
            L.crossed.assign(L.count, 0);
            for (size_t i = 0; i < t.size(); ++i) {
                if (L.part[i] < 0 || seed_of[i] < 0) continue;
                int32_t& seed = L.seed[L.part[i]];
                seed = seed == -1 || seed == seed_of[i] ? seed_of[i] : -2;
            }
            for (const Triangle& tri : mesh_.triangles) {
                const auto seg = segment(tri, s);
                if (!seg) continue;
                const Vec3 a = crossing_point(mesh_, s, seg->from);
                const Vec3 b = crossing_point(mesh_, s, seg->to);
                const int32_t p = L.part[seg->beyond];
                // The loops run clockwise seen from outside the image: minus the shoelace sum.
                L.area[p] -= 0.5 * (basis.u(a) * basis.v(b) - basis.u(b) * basis.v(a));
                L.crossed[p] = 1;
            }
            return L;
        };

        BorderCut& report = placed.report;
        report.opening = spec.name;
        report.side = spec.side;
        report.voxel = step;
        report.face_known = face_known;
        double depth = 0; // voxels inside t_out
        if (spec.inset) {
            depth = *spec.inset / step;
        } else {
            report.automatic = true;
            std::vector<std::vector<double>> area; // area[k - 1][seed]
            int last = BorderRule::search_depth;
            for (int k = 1; k <= BorderRule::search_depth; ++k) {
                const Level L = level(k);
                if (std::find(L.seed.begin(), L.seed.end(), -2) != L.seed.end()) {
                    last = std::max(1, k - 1);
                    report.joined = true;
                    break;
                }
                std::vector<double> per_seed(seeds, 0.0);
                for (int32_t p = 0; p < L.count; ++p)
                    if (L.seed[p] >= 0) per_seed[L.seed[p]] += L.area[p];
                area.push_back(std::move(per_seed));
            }
            int chosen = 0;
            // From the first plane the rule takes, or from plane 1 where two
            // pieces join before the search passes that plane.
            const int first = last > BorderRule::first_plane ? BorderRule::first_plane : 1;
            for (int k = first; k < last && chosen == 0; ++k) {
                bool settled = true;
                for (int32_t p = 0; p < seeds; ++p)
                    settled = settled && area[k - 1][p] >= (1 - BorderRule::shrink_tolerance) * area[k][p];
                if (settled) chosen = k;
            }
            report.stable = chosen > 0;
            depth = chosen > 0 ? chosen : last;
        }
        report.inset = depth * step;

        // Short pieces: parts beyond the deepest plane considered that run on
        // across it into the image but hold no reaching point.
        const Level deep = level(std::max<double>(BorderRule::search_depth, std::ceil(depth)));
        std::vector<int32_t> tip(deep.count, -1);
        for (size_t i = 0; i < t.size(); ++i) {
            const int32_t p = deep.part[i];
            if (p >= 0 && (tip[p] < 0 || t[i] > t[tip[p]])) tip[p] = static_cast<int32_t>(i);
        }
        for (int32_t p = 0; p < deep.count; ++p)
            if (deep.seed[p] == -1 && deep.crossed[p])
                report.short_pieces.push_back({mesh_.points[tip[p]], (t_face - t[tip[p]]) * step});

        mean_index[axis] = sign * (t_out - depth);
        placed.plane.point = frame_.origin + mean_index.x * frame_.axis[0] + mean_index.y * frame_.axis[1] +
                             mean_index.z * frame_.axis[2];
        placed.plane.normal = normal;
        return placed;
    }

    static void warn(const BorderCut& border, std::vector<std::string>& warnings)
    {
        const std::string who = "opening '" + border.opening + "' (border " + border.side + ")";
        const std::string face = border.face_known ? "the image face" : "the outermost surface point on that side";
        for (const ShortPiece& piece : border.short_pieces)
            warnings.push_back(who + ": a piece of the lumen stops " + number(piece.distance) + " mm (" +
                               number(piece.distance / border.voxel) + " voxels) short of " + face +
                               ", its tip at " + text(piece.tip) +
                               "; it gets no cap and stays a dead end of the lumen. If it carries flow, give it "
                               "its own opening (a clip plane) or extend the segmentation to the image face");
        if (border.automatic && !border.stable)
            warnings.push_back(
                who + ": the cross-section kept shrinking towards the image face" +
                (border.joined ? " until two of its pieces join, " + number(border.inset / border.voxel + 1) +
                                     " voxels inside; cut at the last plane before that, "
                               : " over the " + std::to_string(BorderRule::search_depth) +
                                     " voxels searched; cut at the deepest of them, ") +
                number(border.inset) + " mm (" + number(border.inset / border.voxel) +
                " voxels) inside. Give inset = \"N voxels\" to choose the plane");
    }

    // The crossings of `plane` on the input surface, the ones this opening
    // cuts, and the part beyond them. `reaching` (border openings): a
    // crossing is cut when the part beyond it holds a reaching point.
    PlannedCut plan(const OpeningSpec& spec, Plane plane, const std::vector<char>* reaching) const
    {
        const std::string who = "opening '" + spec.name + "'";
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
                if (referenced_[i]) closest = std::min(closest, std::abs(s[i]));
            }
            if (closest > 1e-9 * scale_ || attempt == 20) break;
            plane.point += 3e-9 * scale_ * plane.normal;
        }

        // The crossings: each crossing triangle leads from one crossed edge
        // to the next.
        struct Step {
            Edge to;
            int32_t face;
        };
        std::unordered_map<uint64_t, Step> next;
        std::unordered_map<uint64_t, Edge> edge_of;
        for (size_t f = 0; f < mesh_.triangles.size(); ++f)
            if (const auto seg = segment(mesh_.triangles[f], s)) {
                next[key(seg->from)] = {seg->to, static_cast<int32_t>(f)};
                edge_of[key(seg->from)] = seg->from;
            }
        std::vector<uint64_t> starts;
        for (const auto& [k, step] : next) starts.push_back(k);
        std::sort(starts.begin(), starts.end());
        std::vector<std::vector<Edge>> loops;
        std::vector<std::vector<int32_t>> loop_faces;
        std::unordered_map<uint64_t, int32_t> loop_of;
        for (uint64_t start : starts) {
            if (loop_of.count(start)) continue;
            std::vector<Edge> loop;
            std::vector<int32_t> faces;
            uint64_t k = start;
            do {
                loop_of[k] = static_cast<int32_t>(loops.size());
                loop.push_back(edge_of.at(k));
                const auto it = next.find(k);
                const Edge e = loop.back();
                if (it == next.end())
                    throw StageError("openings", who + ": the crossing at " +
                                                     text(crossing_point(mesh_, s, e)) +
                                                     " does not close (the surface is not a closed manifold there)");
                faces.push_back(it->second.face);
                k = key(it->second.to);
            } while (k != start && loop.size() <= next.size());
            if (k != start) throw StageError("openings", who + ": a crossing of the plane does not close");
            loops.push_back(std::move(loop));
            loop_faces.push_back(std::move(faces));
        }
        if (loops.empty())
            throw InputError(who + ": the plane through " + text(plane.point) + " with normal " + text(plane.normal) +
                                 " does not cut the surface",
                             "put the plane's point inside the lumen, across the vessel you want to open");

        std::vector<Vec3> centre(loops.size());
        for (size_t l = 0; l < loops.size(); ++l) {
            for (const Edge& e : loops[l]) centre[l] += crossing_point(mesh_, s, e);
            centre[l] /= static_cast<double>(loops[l].size());
        }
        const auto beyond_end = [&](const Edge& e) { return s[e[0]] > 0 ? e[0] : e[1]; };

        // Pick the crossings: those of the parts reaching the image face, within
        // radius of the point, or the only one.
        std::vector<char> chosen(loops.size(), 0);
        if (reaching) {
            std::vector<char> beyond(s.size());
            for (size_t i = 0; i < s.size(); ++i) beyond[i] = referenced_[i] && s[i] > 0;
            int32_t count = 0;
            const std::vector<int32_t> part = parts_beyond(beyond, neighbours_, count);
            std::vector<char> reaches(count, 0);
            for (size_t i = 0; i < s.size(); ++i)
                if (part[i] >= 0 && (*reaching)[i]) reaches[part[i]] = 1;
            for (size_t l = 0; l < loops.size(); ++l) chosen[l] = reaches[part[beyond_end(loops[l][0])]];
            if (std::find(chosen.begin(), chosen.end(), 1) == chosen.end())
                throw InputError(who + ": its plane crosses no piece of the lumen that reaches the image face",
                                 "give a smaller inset, or use a clip plane for this opening");
        } else if (spec.radius > 0) {
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
        } else if (loops.size() == 1) {
            chosen[0] = 1;
        } else {
            std::ostringstream msg;
            msg << who << ": the plane crosses the lumen in " << loops.size() << " places (centres";
            for (size_t l = 0; l < loops.size() && l < 6; ++l) msg << " " << text(centre[l]);
            msg << ")";
            throw InputError(msg.str(), "give the opening a radius (mm) so that only the crossing near its point is cut");
        }

        // The part beyond the chosen crossings: the points beyond the plane
        // reached from them without crossing it. Reaching a crossing that is
        // not cut means the part runs back across the plane.
        PlannedCut cut;
        cut.plane = plane;
        cut.removed.assign(mesh_.points.size(), 0);
        std::vector<int32_t> stack;
        for (size_t l = 0; l < loops.size(); ++l) {
            if (!chosen[l]) continue;
            cut.rims.push_back(loops[l]);
            cut.faces.insert(cut.faces.end(), loop_faces[l].begin(), loop_faces[l].end());
            for (const Edge& e : loops[l]) {
                const int32_t v = beyond_end(e);
                if (!cut.removed[v]) {
                    cut.removed[v] = 1;
                    stack.push_back(v);
                }
            }
        }
        while (!stack.empty()) {
            const int32_t v = stack.back();
            stack.pop_back();
            for (const int32_t* w = neighbours_.begin(v); w != neighbours_.end(v); ++w) {
                if (s[*w] > 0) {
                    if (!cut.removed[*w]) {
                        cut.removed[*w] = 1;
                        stack.push_back(*w);
                    }
                    continue;
                }
                const int32_t l = loop_of.at(key(edge(v, *w)));
                if (!chosen[l])
                    throw InputError(who + ": the part of the surface beyond the plane near " + text(centre[l]) +
                                         " reaches back across it elsewhere",
                                     "move the plane so that it cuts the vessel once, or give a radius that "
                                     "includes every crossing of the part to remove");
            }
        }
        std::sort(cut.faces.begin(), cut.faces.end());
        return cut;
    }

    // Refuses two cuts whose crossings meet (a triangle of both) or one of
    // which lies in the part the other removes.
    void check_apart(const PlannedCut& a, const PlannedCut& b, const std::vector<OpeningSpec>& openings) const
    {
        const std::string both =
            "openings '" + openings[a.opening].name + "' and '" + openings[b.opening].name + "'";
        std::vector<int32_t> shared;
        std::set_intersection(a.faces.begin(), a.faces.end(), b.faces.begin(), b.faces.end(),
                              std::back_inserter(shared));
        if (!shared.empty()) {
            const Triangle& t = mesh_.triangles[shared.front()];
            throw InputError("the crossings of " + both + " meet near " +
                                 text((mesh_.points[t[0]] + mesh_.points[t[1]] + mesh_.points[t[2]]) / 3.0) +
                                 ": their caps would cross",
                             "move one of the planes (or give radii) so that they cut the lumen in separate places");
        }
        const auto inside = [&](const PlannedCut& one, const PlannedCut& other) {
            for (int32_t f : one.faces)
                for (int32_t v : mesh_.triangles[f])
                    if (other.removed[v]) return true;
            return false;
        };
        for (const auto& [one, other] : {std::pair{&a, &b}, std::pair{&b, &a}})
            if (inside(*one, *other))
                throw InputError("of " + both + ", opening '" + openings[one->opening].name +
                                     "' lies in the part of the lumen that opening '" + openings[other->opening].name +
                                     "' removes",
                                 "move or flip one of the planes so that neither cuts what the other takes away");
    }

    // Splits the triangles of the chosen crossings, drops the parts beyond
    // them and closes each crossing by a flat cap.
    void assemble(const std::vector<PlannedCut>& cuts, const std::vector<OpeningSpec>& openings,
                  CappedSurface& result) const
    {
        SurfaceMesh& out = result.surface;
        out.points = mesh_.points;
        std::vector<int32_t> owner(mesh_.triangles.size(), -1);
        std::vector<std::unordered_map<uint64_t, int32_t>> cut_point(cuts.size());
        std::vector<std::vector<double>> s(cuts.size());
        for (size_t c = 0; c < cuts.size(); ++c) {
            for (int32_t f : cuts[c].faces) owner[f] = static_cast<int32_t>(c);
            s[c].resize(mesh_.points.size());
            for (size_t i = 0; i < mesh_.points.size(); ++i) s[c][i] = cuts[c].plane.signed_distance(mesh_.points[i]);
            for (const auto& rim : cuts[c].rims)
                for (const Edge& e : rim) {
                    Vec3 x = crossing_point(mesh_, s[c], e);
                    x -= cuts[c].plane.signed_distance(x) * cuts[c].plane.normal;
                    cut_point[c].emplace(key(e), static_cast<int32_t>(out.points.size()));
                    out.points.push_back(x);
                }
        }
        for (size_t f = 0; f < mesh_.triangles.size(); ++f) {
            const Triangle& t = mesh_.triangles[f];
            if (owner[f] < 0) {
                const bool removed = std::any_of(cuts.begin(), cuts.end(), [&](const PlannedCut& cut) {
                    return cut.removed[t[0]] && cut.removed[t[1]] && cut.removed[t[2]];
                });
                if (!removed) out.triangles.push_back(t);
                continue;
            }
            // Keep the part on the lumen's side: the lone vertex p with
            // (p, pq, rp), or the quad (pq, q, r, rp) split along its
            // shorter diagonal.
            const std::vector<double>& sc = s[owner[f]];
            const auto& points = cut_point[owner[f]];
            const bool beyond[3] = {sc[t[0]] > 0, sc[t[1]] > 0, sc[t[2]] > 0};
            const int k = beyond[0] != beyond[1] && beyond[0] != beyond[2] ? 0 : (beyond[1] != beyond[0] && beyond[1] != beyond[2] ? 1 : 2);
            const int32_t p = t[k], q = t[(k + 1) % 3], r = t[(k + 2) % 3];
            const int32_t pq = points.at(key(edge(p, q))), rp = points.at(key(edge(r, p)));
            if (!beyond[k]) {
                out.triangles.push_back({p, pq, rp});
            } else if (norm2(out.points[pq] - out.points[r]) <= norm2(out.points[q] - out.points[rp])) {
                out.triangles.push_back({pq, q, r});
                out.triangles.push_back({pq, r, rp});
            } else {
                out.triangles.push_back({pq, q, rp});
                out.triangles.push_back({q, r, rp});
            }
        }
        out.triangle_patch.assign(out.triangles.size(), 0);
        if (out.triangles.empty()) {
            std::string names;
            for (const OpeningSpec& spec : openings) names += (names.empty() ? "'" : ", '") + spec.name + "'";
            throw InputError("nothing of the surface is left between the planes of openings " + names,
                             "flip the normal of a plane so that it points out of the lumen");
        }

        // Cap the chosen crossings: constrained Delaunay in the plane. The
        // caps of cut c are caps[cap_begin[c] .. cap_begin[c + 1]).
        std::vector<size_t> cap_begin(1, 0);
        for (size_t c = 0; c < cuts.size(); ++c) {
            const PlannedCut& cut = cuts[c];
            const OpeningSpec& spec = openings[cut.opening];
            const std::string who = "opening '" + spec.name + "'";
            const PlaneBasis basis(cut.plane.normal);
            std::vector<int32_t> rim_ids;
            std::vector<std::vector<int32_t>> rim_loops;
            std::vector<double> u, v;
            for (const auto& rim : cut.rims) {
                std::vector<int32_t> local;
                for (const Edge& e : rim) {
                    const int32_t id = cut_point[c].at(key(e));
                    local.push_back(static_cast<int32_t>(rim_ids.size()));
                    rim_ids.push_back(id);
                    u.push_back(basis.u(out.points[id]));
                    v.push_back(basis.v(out.points[id]));
                }
                rim_loops.push_back(std::move(local));
            }
            std::vector<openings::PlanePiece> pieces = openings::triangulate_loops(u, v, rim_loops, "openings");
            if (pieces.empty()) throw StageError("openings", who + ": the cap has no area");
            if (!spec.border && pieces.size() > 1)
                throw InputError(who + ": the chosen crossing of the plane is " + std::to_string(pieces.size()) +
                                     " separate pieces",
                                 "give a smaller radius so that one crossing is cut, or use one opening per piece");
            for (size_t p = 0; p < pieces.size(); ++p) {
                Cap cap;
                cap.name = pieces.size() == 1 ? spec.name : spec.name + "_" + std::to_string(p + 1);
                cap.type = spec.type;
                cap.patch = static_cast<int32_t>(result.caps.size()) + 1;
                cap.plane = cut.plane;
                cap.area = pieces[p].area;
                cap.centroid = cut.plane.point + (pieces[p].cu - basis.u(cut.plane.point)) * basis.e1 +
                               (pieces[p].cv - basis.v(cut.plane.point)) * basis.e2;
                for (const auto& tri : pieces[p].triangles) {
                    out.triangles.push_back({rim_ids[tri[0]], rim_ids[tri[1]], rim_ids[tri[2]]});
                    out.triangle_patch.push_back(cap.patch);
                }
                result.caps.push_back(cap);
            }
            cap_begin.push_back(result.caps.size());
        }
        for (size_t c = 0; c < cuts.size(); ++c) {
            const double diameters = openings[cuts[c].opening].extension;
            if (diameters > 0)
                for (size_t p = cap_begin[c]; p < cap_begin[c + 1]; ++p) extend(out, result.caps[p], diameters);
        }
        compact(out);
    }

    const SurfaceMesh& mesh_;
    const ImageFrame& frame_;
    double scale_;
    VertexTable neighbours_;
    std::vector<char> referenced_;

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
    CappedSurface result = Opener(surface, frame).open(openings);
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
