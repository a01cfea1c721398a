#include "openings/open_ends.h"

#include "core/adjacency.h"
#include "core/errors.h"

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <numeric>
#include <sstream>
#include <unordered_map>

namespace scalemesh {

namespace {

std::string text(const Vec3& x)
{
    std::ostringstream out;
    out << "(" << x.x << ", " << x.y << ", " << x.z << ")";
    return out.str();
}

constexpr size_t kMinEndEdges = 6;

const char* const kRepairHint =
    "an open-ended surface needs clean boundary loops: repair it (VMTK's vmtksurfacecleaner, MeshLab's "
    "'Repair non Manifold Edges/Vertices', Slicer's Surface Toolbox), or start from the segmentation image";

} // namespace

std::vector<std::vector<int32_t>> boundary_loops(const SurfaceMesh& surface, const std::string& what)
{
    if (surface.triangles.empty()) throw InputError(what + " has no triangles", "check the input file");
    std::unordered_map<uint64_t, int32_t> directed;   // directed edge -> times used
    std::unordered_map<uint64_t, int32_t> undirected; // edge -> triangles
    directed.reserve(surface.triangles.size() * 3);
    undirected.reserve(surface.triangles.size() * 2);
    int64_t degenerate = 0;
    for (const Triangle& t : surface.triangles) {
        if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) {
            ++degenerate;
            continue;
        }
        for (int k = 0; k < 3; ++k) {
            ++directed[directed_edge_key(t[k], t[(k + 1) % 3])];
            ++undirected[edge_key(t[k], t[(k + 1) % 3])];
        }
    }
    int64_t nonmanifold = 0, misoriented = 0;
    Vec3 first_bad;
    bool have_bad = false;
    const auto mark = [&](uint64_t key) {
        if (have_bad) return;
        const auto a = static_cast<int32_t>(key >> 32), b = static_cast<int32_t>(key & 0xffffffffu);
        first_bad = 0.5 * (surface.points[a] + surface.points[b]);
        have_bad = true;
    };
    for (const auto& [key, count] : undirected)
        if (count > 2) {
            ++nonmanifold;
            mark(key);
        }
    for (const auto& [key, count] : directed)
        if (count > 1) {
            ++misoriented;
            mark(key);
        }

    // next[a] = b for every boundary edge a -> b (its reverse is in no triangle).
    std::unordered_map<int32_t, int32_t> next;
    int64_t touching = 0;
    for (const auto& [key, count] : directed) {
        const auto a = static_cast<int32_t>(key >> 32), b = static_cast<int32_t>(key & 0xffffffffu);
        if (count != 1 || undirected[edge_key(a, b)] != 1) continue;
        if (!next.emplace(a, b).second) {
            ++touching;
            if (!have_bad) {
                first_bad = surface.points[a];
                have_bad = true;
            }
        }
    }

    std::vector<std::vector<int32_t>> loops;
    std::unordered_map<int32_t, char> visited;
    std::vector<int32_t> starts;
    starts.reserve(next.size());
    for (const auto& [a, b] : next) starts.push_back(a);
    std::sort(starts.begin(), starts.end()); // a deterministic order
    int64_t unclosed = 0;
    for (int32_t start : starts) {
        if (visited.count(start)) continue;
        std::vector<int32_t> loop;
        int32_t v = start;
        bool closed = false;
        while (!visited.count(v)) {
            visited[v] = 1;
            loop.push_back(v);
            const auto it = next.find(v);
            if (it == next.end()) break;
            v = it->second;
            if (v == start) {
                closed = true;
                break;
            }
        }
        if (!closed) ++unclosed;
        loops.push_back(std::move(loop));
    }

    if (degenerate + nonmanifold + misoriented + touching + unclosed > 0) {
        std::ostringstream msg;
        msg << what << " is not a surface with clean open ends: " << loops.size() << " open loop"
            << (loops.size() == 1 ? "" : "s");
        for (size_t i = 0; i < loops.size() && i < 4; ++i) {
            Vec3 c;
            for (int32_t p : loops[i]) c += surface.points[p];
            msg << (i == 0 ? " (around " : ", ") << text(c / static_cast<double>(loops[i].size())) << " with "
                << loops[i].size() << " edges";
        }
        if (!loops.empty()) msg << (loops.size() > 4 ? ", ...)" : ")");
        msg << ", " << nonmanifold << " non-manifold edges, " << misoriented << " inconsistently oriented edges, "
            << touching << " vertices where open loops touch, " << degenerate << " degenerate triangles";
        if (have_bad) msg << "; first problem at " << text(first_bad);
        throw InputError(msg.str(), kRepairHint);
    }
    return loops;
}

ClosedEnds close_open_ends(const SurfaceMesh& surface, const std::string& what, const std::vector<int32_t>& labels)
{
    const std::vector<std::vector<int32_t>> loops = boundary_loops(surface, what);
    if (!labels.empty() && labels.size() != loops.size())
        throw StageError("close_open_ends", std::to_string(labels.size()) + " labels for " +
                         std::to_string(loops.size()) + " loops");
    // A loop of a few edges is a hole in the surface (a missing triangle or
    // fan), not the cut end of a vessel.
    std::vector<size_t> holes;
    for (size_t i = 0; i < loops.size(); ++i)
        if (loops[i].size() < kMinEndEdges) holes.push_back(i);
    if (!holes.empty()) {
        std::ostringstream msg;
        msg << what << " has " << holes.size() << " hole" << (holes.size() == 1 ? "" : "s") << " of fewer than "
            << kMinEndEdges << " edges, too small to be open ends";
        for (size_t k = 0; k < holes.size() && k < 4; ++k) {
            Vec3 c;
            for (int32_t p : loops[holes[k]]) c += surface.points[p];
            msg << (k == 0 ? " (around " : ", ") << text(c / static_cast<double>(loops[holes[k]].size()));
        }
        msg << (holes.size() > 4 ? ", ...)" : ")");
        throw InputError(msg.str(), "fill the holes (MeshLab's 'Close Holes', VMTK's vmtksurfacecapper on a "
                                    "clean surface, Slicer's Surface Toolbox) and keep only the vessel ends open");
    }
    ClosedEnds result;
    result.surface = surface;
    SurfaceMesh& mesh = result.surface;
    const size_t fan_start = mesh.triangles.size();
    std::vector<OpenEnd> ends(loops.size());
    for (size_t i = 0; i < loops.size(); ++i) {
        OpenEnd& end = ends[i];
        end.loop = loops[i];
        end.label = labels.empty() ? -1 : labels[i];
        const size_t n = end.loop.size();
        double perimeter = 0;
        Vec3 centre;
        for (size_t k = 0; k < n; ++k) {
            const Vec3& a = mesh.points[end.loop[k]];
            const Vec3& b = mesh.points[end.loop[(k + 1) % n]];
            const double length = distance(a, b);
            perimeter += length;
            centre += length * 0.5 * (a + b);
        }
        if (!(perimeter > 0)) throw InputError(what + ": an open loop has zero length", kRepairHint);
        end.centre = centre / perimeter;
        end.mean_edge = perimeter / static_cast<double>(n);
        end.centre_point = static_cast<int32_t>(mesh.points.size());
        mesh.points.push_back(end.centre);
        // The loop runs a -> b in the surface's triangles: the fan runs b -> a.
        for (size_t k = 0; k < n; ++k)
            mesh.triangles.push_back({end.loop[(k + 1) % n], end.loop[k], end.centre_point});
    }
    if (!mesh.triangle_patch.empty()) mesh.triangle_patch.resize(mesh.triangles.size(), 0);
    require_closed_manifold(mesh, what + " with its open ends closed by fans");
    result.flipped = orient_outward(mesh);

    size_t fan = fan_start;
    for (OpenEnd& end : ends) {
        Vec3 vector_area;
        for (size_t k = 0; k < end.loop.size(); ++k, ++fan) {
            const Triangle& t = mesh.triangles[fan];
            vector_area += 0.5 * cross(mesh.points[t[1]] - mesh.points[t[0]], mesh.points[t[2]] - mesh.points[t[0]]);
        }
        end.area = norm(vector_area);
        if (!(end.area > 1e-12 * end.mean_edge * end.mean_edge))
            throw InputError(what + ": the open loop around " + text(end.centre) +
                                 " encloses no area (a slit or a crack, not an open end)",
                             kRepairHint);
        end.normal = vector_area / end.area;
        for (int32_t p : end.loop) {
            end.radius = std::max(end.radius, distance(mesh.points[p], end.centre));
            end.deviation = std::max(end.deviation, std::abs(dot(mesh.points[p] - end.centre, end.normal)));
        }
    }
    std::stable_sort(ends.begin(), ends.end(), [](const OpenEnd& a, const OpenEnd& b) { return a.area > b.area; });
    result.ends = std::move(ends);
    return result;
}

std::string why_not_a_cap(const LabelPart& part)
{
    if (part.cap) return "";
    if (part.wall) return "it is the wall (the label of the largest area)";
    char text[200];
    if (!std::isfinite(part.flatness)) return "its faces do not face one way (not a plane)";
    if (part.flatness > part.tolerance) {
        std::snprintf(text, sizeof text, "not flat: its points leave its plane by up to %.3g of sqrt(area), beyond %.3g",
                      part.flatness, part.tolerance);
        return text;
    }
    std::snprintf(text, sizeof text, "its faces are %d separate pieces", part.pieces);
    return text;
}

LabelCaps remove_label_caps(const SurfaceMesh& surface, const std::vector<int32_t>& labels, double flat_tolerance)
{
    if (labels.size() != surface.triangles.size())
        throw StageError("remove_label_caps", std::to_string(labels.size()) + " labels for " +
                         std::to_string(surface.triangles.size()) + " triangles");
    // Per label: vector area, area, centroid, triangles.
    struct Sums {
        Vec3 vector_area, centroid;
        double area = 0;
        std::vector<int32_t> triangles;
    };
    std::map<int32_t, Sums> sums;
    for (size_t t = 0; t < surface.triangles.size(); ++t) {
        const Triangle& tri = surface.triangles[t];
        const Vec3 n = 0.5 * cross(surface.points[tri[1]] - surface.points[tri[0]],
                                   surface.points[tri[2]] - surface.points[tri[0]]);
        Sums& s = sums[labels[t]];
        s.vector_area += n;
        s.area += norm(n);
        s.centroid += norm(n) * (surface.points[tri[0]] + surface.points[tri[1]] + surface.points[tri[2]]) / 3.0;
        s.triangles.push_back(static_cast<int32_t>(t));
    }
    int32_t wall = sums.begin()->first;
    for (const auto& [label, s] : sums)
        if (s.area > sums[wall].area) wall = label;

    LabelCaps result;
    std::vector<char> removed(surface.triangles.size(), 0);
    for (auto& [label, s] : sums) {
        LabelPart part;
        part.label = label;
        part.triangles = static_cast<int64_t>(s.triangles.size());
        part.area = s.area;
        part.flatness = INFINITY;
        part.tolerance = flat_tolerance;
        part.wall = label == wall;
        if (s.area > 0 && norm(s.vector_area) > 0.5 * s.area) {
            const Vec3 normal = normalized(s.vector_area);
            const Vec3 centroid = s.centroid / s.area;
            double deviation = 0, largest = 0;
            for (int32_t t : s.triangles)
                for (int32_t p : surface.triangles[t]) {
                    deviation = std::max(deviation, std::abs(dot(surface.points[p] - centroid, normal)));
                    largest = std::max({largest, std::abs(surface.points[p].x), std::abs(surface.points[p].y),
                                        std::abs(surface.points[p].z)});
                }
            part.flatness = deviation / std::sqrt(s.area);
            // A float32 coordinate is within 2^-24 of its value relative to
            // itself: a cap that is flat in the file's own precision.
            constexpr double kSingleRounding = 5.9604644775390625e-08; // 2^-24
            part.tolerance = std::max(flat_tolerance, 8 * kSingleRounding * largest / std::sqrt(s.area));
        }
        SurfaceMesh piece;
        piece.points = surface.points;
        for (int32_t t : s.triangles) piece.triangles.push_back(surface.triangles[t]);
        triangle_components(piece, &part.pieces);
        part.cap = !part.wall && part.flatness <= part.tolerance && part.pieces == 1;
        if (part.cap)
            for (int32_t t : s.triangles) removed[t] = 1;
        result.parts.push_back(part);
    }

    // The cap faces' edges, so that each new loop can be named by its cap.
    std::unordered_map<uint64_t, int32_t> cap_edge_label;
    for (size_t t = 0; t < surface.triangles.size(); ++t)
        if (removed[t])
            for (int k = 0; k < 3; ++k)
                cap_edge_label[edge_key(surface.triangles[t][k], surface.triangles[t][(k + 1) % 3])] = labels[t];

    std::vector<int32_t> renumbered(surface.points.size(), -1);
    std::vector<int32_t> original;
    for (size_t t = 0; t < surface.triangles.size(); ++t) {
        if (removed[t]) continue;
        Triangle tri = surface.triangles[t];
        for (int32_t& v : tri) {
            if (renumbered[v] < 0) {
                renumbered[v] = static_cast<int32_t>(result.surface.points.size());
                result.surface.points.push_back(surface.points[v]);
                original.push_back(v);
            }
            v = renumbered[v];
        }
        result.surface.triangles.push_back(tri);
    }
    if (result.surface.triangles.empty())
        throw InputError("every face of the surface is on a flat labelled cap", "check the file's face labels");
    if (cap_edge_label.empty()) return result;
    for (const std::vector<int32_t>& loop : boundary_loops(result.surface, "the surface without its labelled caps")) {
        const auto it = cap_edge_label.find(edge_key(original[loop[0]], original[loop[1]]));
        result.loop_label.push_back(it == cap_edge_label.end() ? -1 : it->second);
    }
    return result;
}

OpeningSpec end_opening(const OpenEnd& end, const std::string& name, OpeningType type, double margin)
{
    OpeningSpec spec;
    spec.name = name;
    spec.type = type;
    spec.plane.normal = end.normal;
    spec.plane.point = end.centre - (end.deviation + margin) * end.normal;
    // The crossing just inside a loop is centred within about the loop's
    // deviation of its centre; another branch's crossing is at least a radius
    // away.
    spec.radius = 0.5 * end.radius + end.deviation + margin;
    return spec;
}

} // namespace scalemesh
