// The slab scheduler of the improvement passes (slab_scheduler.h): the mesh
// cut into parts by slabs, the parts improved at once and put back.

#include "volume/slab_scheduler.h"

#include "volume/quality.h"
#include "volume/slabs.h"
#include "volume/tet_editor.h"

#include <algorithm>
#include <functional>
#include <numeric>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace scalemesh::improvement {
namespace {

// How many slabs: one per 100k tets, up to 4. It depends on the mesh
// alone, so the result is the same on any number of threads.
int slab_count(const TetMesh& mesh)
{
    return static_cast<int>(std::clamp<size_t>(mesh.tets.size() / 100000, 1, 4));
}

// Which part each tet is for: own[t], the part that may change it (-1:
// none), and, when `seen` is not empty, seen[t], the part that only sees it.
struct Sharing {
    int count = 0;
    std::vector<int32_t> own, seen;
};

// The parts of `sharing`, each with its tets (the read-only ones first: its
// own locked tets, then those it sees, so that its editor locks them; then
// its own) and points. With `focus_points`, a part's focus is its tets with
// such a point.
std::vector<Part> make_parts(const TetMesh& mesh, int32_t surface_points, int32_t locked, const Sharing& sharing,
                             const std::vector<char>* focus_points)
{
    const size_t n = mesh.points.size(), first_free = std::min<size_t>(locked, mesh.tets.size());
    const auto seen_by = [&](size_t t) { return sharing.seen.empty() ? -1 : sharing.seen[t]; };
    std::vector<std::vector<int32_t>> ids(sharing.count);
    for (size_t t = 0; t < first_free; ++t)
        if (sharing.own[t] >= 0) ids[sharing.own[t]].push_back(static_cast<int32_t>(t));
    for (size_t t = 0; t < mesh.tets.size(); ++t)
        if (seen_by(t) >= 0) ids[seen_by(t)].push_back(static_cast<int32_t>(t));
    std::vector<Part> parts(sharing.count);
    for (int r = 0; r < sharing.count; ++r) {
        parts[r].read_only = static_cast<int32_t>(ids[r].size());
        if (focus_points) parts[r].focus.emplace();
    }
    for (size_t t = first_free; t < mesh.tets.size(); ++t)
        if (sharing.own[t] >= 0) ids[sharing.own[t]].push_back(static_cast<int32_t>(t));

    std::vector<int32_t> degree(n, 0), local(n, -1), inside(n, 0);
    for (const Tet& t : mesh.tets)
        for (int32_t v : t) ++degree[v];
    for (int r = 0; r < sharing.count; ++r) {
        Part& part = parts[r];
        part.mesh.tets.reserve(ids[r].size());
        for (size_t i = 0; i < ids[r].size(); ++i) {
            const int32_t t = ids[r][i];
            Tet tet;
            bool focus = false;
            for (int k = 0; k < 4; ++k) {
                const int32_t v = mesh.tets[t][k];
                if (local[v] < 0) {
                    local[v] = static_cast<int32_t>(part.global.size());
                    part.global.push_back(v);
                    part.mesh.points.push_back(mesh.points[v]);
                }
                inside[v] += sharing.own[t] == r;
                focus = focus || (focus_points && (*focus_points)[v]);
                tet[k] = local[v];
            }
            part.mesh.tets.push_back(tet);
            if (focus) part.focus->push_back(static_cast<int32_t>(i));
        }
        part.pinned.resize(part.global.size());
        part.border.resize(part.global.size());
        for (size_t l = 0; l < part.global.size(); ++l) {
            const int32_t v = part.global[l];
            part.border[l] = inside[v] < degree[v];
            part.pinned[l] = v < surface_points || part.border[l];
            local[v] = -1, inside[v] = 0;
        }
    }
    return parts;
}

// Puts the parts' tets and points back: the mesh's first `locked` tets
// first (no part replaces them), then the other tets of no part, in order,
// then each part's own; the points the parts added after the mesh's.
void put_back(TetMesh& mesh, int32_t locked, const Sharing& sharing, std::vector<Part>& parts)
{
    const size_t first_free = std::min<size_t>(locked, mesh.tets.size());
    std::vector<Tet> kept(mesh.tets.begin(), mesh.tets.begin() + first_free);
    for (size_t t = first_free; t < mesh.tets.size(); ++t)
        if (sharing.own[t] < 0) kept.push_back(mesh.tets[t]);
    for (Part& part : parts) {
        const size_t old_points = part.pinned.size();
        for (size_t l = 0; l < old_points; ++l)
            if (!part.pinned[l]) mesh.points[part.global[l]] = part.mesh.points[l];
        for (size_t l = old_points; l < part.mesh.points.size(); ++l) {
            part.global.push_back(static_cast<int32_t>(mesh.points.size()));
            mesh.points.push_back(part.mesh.points[l]);
        }
        for (size_t i = part.read_only; i < part.mesh.tets.size(); ++i) {
            const Tet& t = part.mesh.tets[i];
            kept.push_back({part.global[t[0]], part.global[t[1]], part.global[t[2]], part.global[t[3]]});
        }
        part.mesh = TetMesh{};
    }
    mesh.tets = std::move(kept);
    mesh.tet_fields.clear();
}

// Runs improve(part, r) on the parts of `sharing` at once, then puts them back.
void improve_in_parts(TetMesh& mesh, int32_t surface_points, int32_t locked, const Sharing& sharing,
                      const std::vector<char>* focus_points, const std::function<void(Part&, int)>& improve)
{
    std::vector<Part> parts = make_parts(mesh, surface_points, locked, sharing, focus_points);
    tbb::parallel_for(0, sharing.count, [&](int r) { improve(parts[r], r); });
    put_back(mesh, locked, sharing, parts);
}

// The whole mesh as one part, improved in place: its surface pinned, its
// first `locked` tets read-only, `focus` its focus.
void improve_whole(TetMesh& mesh, int32_t surface_points, int32_t locked, std::optional<std::vector<int32_t>> focus,
                   const std::function<void(Part&, int)>& improve)
{
    Part whole;
    whole.focus = std::move(focus);
    whole.global.resize(mesh.points.size());
    std::iota(whole.global.begin(), whole.global.end(), 0);
    whole.pinned.assign(mesh.points.size(), 0);
    whole.border.assign(mesh.points.size(), 0);
    std::fill_n(whole.pinned.begin(), std::min<size_t>(surface_points, mesh.points.size()), 1);
    whole.read_only = locked;
    whole.mesh = std::move(mesh);
    improve(whole, 0);
    mesh = std::move(whole.mesh);
    mesh.tet_fields.clear();
}

// Each point's slab, in parallel.
std::vector<int32_t> slabs_of(const std::vector<Vec3>& points, const SlabCut& slabs)
{
    std::vector<int32_t> slab(points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, slab.size(), 1 << 14), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t v = range.begin(); v != range.end(); ++v) slab[v] = slabs.of(points[v]);
    });
    return slab;
}

// The tets shared by slab: a tet with its four points in one slab is that
// slab's own, one with three points in a slab is seen by it (the tets
// across the faces of a slab's own are among these); `on_cut` marks the
// points of the tets across slabs, which no slab may move.
Sharing share_by_slabs(const TetMesh& mesh, const SlabCut& slabs, std::vector<char>& on_cut)
{
    const std::vector<int32_t> slab = slabs_of(mesh.points, slabs);
    Sharing sharing;
    sharing.count = slabs.count();
    sharing.own.assign(mesh.tets.size(), -1);
    sharing.seen.assign(mesh.tets.size(), -1);
    on_cut.assign(mesh.points.size(), 0);
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        const Tet& tet = mesh.tets[t];
        // A slab with three or four of the points holds point 0 or point 1.
        for (int32_t k : {0, 1}) {
            const int32_t s = slab[tet[k]];
            const int times = (slab[tet[0]] == s) + (slab[tet[1]] == s) + (slab[tet[2]] == s) + (slab[tet[3]] == s);
            if (times == 4) sharing.own[t] = s;
            if (times == 3) sharing.seen[t] = s;
            if (times >= 3) break;
        }
        if (sharing.own[t] < 0)
            for (int32_t v : tet) on_cut[v] = 1;
    }
    return sharing;
}

} // namespace

void improve_in_slabs(TetMesh& mesh, int32_t surface_points, int cut_points, double poor_below,
                      const std::function<void(Part&, int)>& improve)
{
    const int count = slab_count(mesh);
    if (count == 1) {
        improve_whole(mesh, surface_points, 0, std::nullopt, improve);
        return;
    }
    const std::vector<int32_t> slab = slabs_of(mesh.points, equal_count_slabs(mesh.points, count));
    Sharing slabs{count, std::vector<int32_t>(mesh.tets.size(), 0), {}};
    std::vector<char> cut(mesh.points.size(), 0);
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        const Tet& tet = mesh.tets[t];
        const int32_t s = slab[tet[0]];
        if (slab[tet[1]] == s && slab[tet[2]] == s && slab[tet[3]] == s) {
            slabs.own[t] = s;
        } else {
            slabs.own[t] = -1;
            for (int32_t v : tet) cut[v] = 1;
        }
    }
    improve_in_parts(mesh, surface_points, 0, slabs, nullptr, improve);
    if (poor_below > 0) {
        const std::vector<Vec3>& p = mesh.points;
        const std::vector<char> poor = parallel_marks(0, mesh.tets.size(), [&](size_t t) {
            const Tet& tet = mesh.tets[t];
            return tet_aspect_ratio(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]]) < poor_below;
        });
        for (size_t t = 0; t < mesh.tets.size(); ++t)
            if (poor[t])
                for (int32_t v : mesh.tets[t]) cut[v] = 1;
    }
    Sharing near_cuts{1, std::vector<int32_t>(mesh.tets.size()), {}};
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        const Tet& tet = mesh.tets[t];
        near_cuts.own[t] = cut[tet[0]] + cut[tet[1]] + cut[tet[2]] + cut[tet[3]] >= cut_points ? 0 : -1;
    }
    improve_in_parts(mesh, surface_points, 0, near_cuts, nullptr, improve);
}

void improve_in_slab_rounds(TetMesh& mesh, int32_t surface_points, int32_t locked_tets, int count,
                            const std::function<std::vector<char>(const TetMesh&)>& left_over,
                            const std::function<void(Part&, int)>& improve)
{
    if (count <= 1) {
        improve_whole(mesh, surface_points, locked_tets, std::nullopt, improve);
        return;
    }
    // Both cuts from the points as they are, so that each second-round cut
    // lies in the middle of a first-round slab.
    const SlabCut first = equal_count_slabs(mesh.points, count), second = middle_slabs(mesh.points, count);
    std::vector<char> on_first_cut, on_second_cut;
    improve_in_parts(mesh, surface_points, locked_tets, share_by_slabs(mesh, first, on_first_cut), nullptr, improve);
    on_first_cut.resize(mesh.points.size(), 0); // the points the first round added are on no cut
    improve_in_parts(mesh, surface_points, locked_tets, share_by_slabs(mesh, second, on_second_cut), &on_first_cut,
                     improve);
    const std::vector<char> left = left_over(mesh);
    std::vector<int32_t> focus;
    for (size_t t = 0; t < left.size(); ++t)
        if (left[t]) focus.push_back(static_cast<int32_t>(t));
    if (!focus.empty()) improve_whole(mesh, surface_points, locked_tets, std::move(focus), improve);
}

} // namespace scalemesh::improvement
