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

// Runs improve(part, r) on parts 0 .. count - 1 at once, part r made of the
// tets t with part_of[t] == r (-1: in none), then puts the parts' tets and
// points back: the tets of no part first, in order, then each part's.
void improve_in_parts(TetMesh& mesh, int32_t surface_points, const std::vector<int32_t>& part_of, int count,
                      const std::function<void(Part&, int)>& improve)
{
    const size_t n = mesh.points.size();
    std::vector<int32_t> degree(n, 0), local(n, -1), inside(n, 0);
    for (const Tet& t : mesh.tets)
        for (int32_t v : t) ++degree[v];
    std::vector<Part> parts(count);
    std::vector<Tet> kept;
    std::vector<std::vector<int32_t>> ids(count);
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        if (part_of[t] < 0) kept.push_back(mesh.tets[t]);
        else ids[part_of[t]].push_back(static_cast<int32_t>(t));
    }
    for (int r = 0; r < count; ++r) {
        Part& part = parts[r];
        part.mesh.tets.reserve(ids[r].size());
        for (int32_t t : ids[r]) {
            Tet tet;
            for (int i = 0; i < 4; ++i) {
                const int32_t v = mesh.tets[t][i];
                if (local[v] < 0) {
                    local[v] = static_cast<int32_t>(part.global.size());
                    part.global.push_back(v);
                    part.mesh.points.push_back(mesh.points[v]);
                }
                ++inside[v];
                tet[i] = local[v];
            }
            part.mesh.tets.push_back(tet);
        }
        part.pinned.resize(part.global.size());
        for (size_t l = 0; l < part.global.size(); ++l) {
            const int32_t v = part.global[l];
            part.pinned[l] = v < surface_points || inside[v] < degree[v];
            local[v] = -1, inside[v] = 0;
        }
    }
    tbb::parallel_for(0, count, [&](int r) { improve(parts[r], r); });
    for (Part& part : parts) {
        for (const Tet& t : part.mesh.tets)
            kept.push_back({part.global[t[0]], part.global[t[1]], part.global[t[2]], part.global[t[3]]});
        for (size_t l = 0; l < part.global.size(); ++l)
            if (!part.pinned[l]) mesh.points[part.global[l]] = part.mesh.points[l];
        part.mesh = TetMesh{};
    }
    mesh.tets = std::move(kept);
    mesh.tet_fields.clear();
}

} // namespace

void improve_in_slabs(TetMesh& mesh, int32_t surface_points, int cut_points, double poor_below,
                      const std::function<void(Part&, int)>& improve)
{
    const int count = slab_count(mesh);
    if (count == 1) {
        // One part: the whole mesh, improved in place, its surface pinned.
        Part whole;
        whole.global.resize(mesh.points.size());
        std::iota(whole.global.begin(), whole.global.end(), 0);
        whole.pinned.assign(mesh.points.size(), 0);
        std::fill_n(whole.pinned.begin(), std::min<size_t>(surface_points, mesh.points.size()), 1);
        whole.mesh = std::move(mesh);
        improve(whole, 0);
        mesh = std::move(whole.mesh);
        mesh.tet_fields.clear();
        return;
    }
    const SlabCut slabs = equal_count_slabs(mesh.points, count);
    std::vector<int32_t> slab(mesh.points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, slab.size(), 1 << 14), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t v = range.begin(); v != range.end(); ++v) slab[v] = slabs.of(mesh.points[v]);
    });
    std::vector<int32_t> part_of(mesh.tets.size(), 0);
    std::vector<char> cut(mesh.points.size(), 0);
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        const Tet& tet = mesh.tets[t];
        const int32_t s = slab[tet[0]];
        if (slab[tet[1]] == s && slab[tet[2]] == s && slab[tet[3]] == s) {
            part_of[t] = s;
        } else {
            part_of[t] = -1;
            for (int32_t v : tet) cut[v] = 1;
        }
    }
    improve_in_parts(mesh, surface_points, part_of, count, improve);
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
    part_of.resize(mesh.tets.size());
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        const Tet& tet = mesh.tets[t];
        part_of[t] = cut[tet[0]] + cut[tet[1]] + cut[tet[2]] + cut[tet[3]] >= cut_points ? 0 : -1;
    }
    improve_in_parts(mesh, surface_points, part_of, 1, improve);
}

} // namespace scalemesh::improvement
