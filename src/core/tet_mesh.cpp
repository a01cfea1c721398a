#include "core/tet_mesh.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <limits>
#include <stdexcept>
#include <string>

namespace scalemesh {

double tet_volume6(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d)
{
    return dot(b - a, cross(c - a, d - a));
}

namespace {

// Rotates a triangle so that its smallest index comes first (same orientation).
Triangle canonical(Triangle t)
{
    while (t[0] > t[1] || t[0] > t[2]) t = {t[1], t[2], t[0]};
    return t;
}

// A tet face in the bucket of its smallest point: the other two, sorted,
// packed into one key, and the face's slot 4 t + k.
struct BucketFace {
    uint64_t others;
    int32_t slot;
    bool operator<(const BucketFace& o) const { return others != o.others ? others < o.others : slot < o.slot; }
};

uint64_t pack(int32_t second, int32_t third)
{
    return (static_cast<uint64_t>(static_cast<uint32_t>(second)) << 32) | static_cast<uint32_t>(third);
}

} // namespace

TetFaceAdjacency tet_face_adjacency(const TetMesh& mesh)
{
    const size_t n_points = mesh.points.size();
    const size_t n_tets = mesh.tets.size();
    auto smallest = [&](const Triangle& f) { return std::min({f[0], f[1], f[2]}); };

    // A counting sort of the faces by their smallest point, the tets cut into
    // one chunk per thread, each chunk with its own counts and write cursors.
    // The buckets are then sorted on the whole face, so the result does not
    // depend on the number of chunks.
    const size_t chunks = std::clamp<size_t>(tbb::this_task_arena::max_concurrency(), 1, n_tets / 65536 + 1);
    auto chunk_range = [&](size_t c) { return std::make_pair(n_tets * c / chunks, n_tets * (c + 1) / chunks); };
    std::vector<std::vector<int64_t>> cursor(chunks, std::vector<int64_t>(n_points, 0));
    tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
        const auto [first, last] = chunk_range(c);
        std::vector<int64_t>& count = cursor[c];
        for (size_t t = first; t < last; ++t) {
            for (int32_t v : mesh.tets[t])
                if (v < 0 || static_cast<size_t>(v) >= n_points)
                    throw std::out_of_range("a tet names point " + std::to_string(v) + " of a mesh with " +
                                            std::to_string(n_points) + " points");
            for (int k = 0; k < 4; ++k) ++count[smallest(tet_face(mesh.tets[t], k))];
        }
    });
    std::vector<int64_t> offsets(n_points + 1, 0);
    int64_t running = 0;
    for (size_t v = 0; v < n_points; ++v) {
        offsets[v] = running;
        for (size_t c = 0; c < chunks; ++c) {
            const int64_t count = cursor[c][v];
            cursor[c][v] = running;
            running += count;
        }
    }
    offsets[n_points] = running;
    std::vector<BucketFace> buckets(4 * n_tets);
    tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
        const auto [first, last] = chunk_range(c);
        std::vector<int64_t>& fill = cursor[c];
        for (size_t t = first; t < last; ++t) {
            for (int k = 0; k < 4; ++k) {
                std::array<int32_t, 3> f = tet_face(mesh.tets[t], k);
                std::sort(f.begin(), f.end());
                buckets[fill[f[0]]++] = {pack(f[1], f[2]), static_cast<int32_t>(4 * t + k)};
            }
        }
    });

    TetFaceAdjacency result;
    result.across.assign(4 * n_tets, TetFaceAdjacency::kBoundary);
    std::atomic<int64_t> overshared{0};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n_points, 4096), [&](const tbb::blocked_range<size_t>& range) {
        int64_t local_overshared = 0;
        for (size_t v = range.begin(); v != range.end(); ++v) {
            BucketFace* first = buckets.data() + offsets[v];
            BucketFace* last = buckets.data() + offsets[v + 1];
            std::sort(first, last);
            for (BucketFace* i = first; i != last;) {
                BucketFace* j = i + 1;
                while (j != last && j->others == i->others) ++j;
                if (j - i == 2) {
                    result.across[i[0].slot] = i[1].slot / 4;
                    result.across[i[1].slot] = i[0].slot / 4;
                } else if (j - i > 2) {
                    ++local_overshared;
                    for (BucketFace* f = i; f != j; ++f) result.across[f->slot] = TetFaceAdjacency::kOvershared;
                }
                i = j;
            }
        }
        overshared += local_overshared;
    });
    result.overshared_faces = overshared;
    return result;
}

void sort_tets_by_smallest_point(std::vector<Tet>& tets, size_t point_count)
{
    std::vector<int64_t> start(point_count + 1, 0);
    for (const Tet& t : tets) ++start[std::min({t[0], t[1], t[2], t[3]}) + 1];
    for (size_t v = 0; v < point_count; ++v) start[v + 1] += start[v];
    std::vector<Tet> placed(tets.size());
    {
        std::vector<int64_t> fill(start.begin(), start.end() - 1);
        for (const Tet& t : tets) placed[fill[std::min({t[0], t[1], t[2], t[3]})]++] = t;
    }
    // Within a group, by the tet's points sorted (the smallest is the
    // group's): a handful of tets each, keyed once.
    struct Keyed {
        Tet sorted, tet;
        bool operator<(const Keyed& o) const { return sorted < o.sorted; }
    };
    tbb::parallel_for(tbb::blocked_range<size_t>(0, point_count, 4096), [&](const tbb::blocked_range<size_t>& range) {
        std::vector<Keyed> group;
        for (size_t v = range.begin(); v != range.end(); ++v) {
            if (start[v + 1] - start[v] < 2) continue;
            group.clear();
            for (int64_t t = start[v]; t < start[v + 1]; ++t) {
                Keyed& k = group.emplace_back(Keyed{placed[t], placed[t]});
                std::sort(k.sorted.begin(), k.sorted.end());
            }
            std::sort(group.begin(), group.end());
            for (size_t i = 0; i < group.size(); ++i) placed[start[v] + i] = group[i].tet;
        }
    });
    tets = std::move(placed);
}

TetMeshFacts tet_mesh_facts(const TetMesh& mesh)
{
    return tet_mesh_facts(mesh, tet_face_adjacency(mesh));
}

TetMeshFacts tet_mesh_facts(const TetMesh& mesh, const TetFaceAdjacency& adjacency)
{
    if (adjacency.across.size() != 4 * mesh.tets.size())
        throw std::invalid_argument("the face adjacency is not that of this mesh (" +
                                    std::to_string(adjacency.across.size()) + " faces for " +
                                    std::to_string(mesh.tets.size()) + " tets)");
    TetMeshFacts facts;
    facts.min_tet_volume = std::numeric_limits<double>::infinity();
    std::vector<Triangle> boundary;
    for (size_t i = 0; i < mesh.tets.size(); ++i) {
        const Tet& t = mesh.tets[i];
        const double v = tet_volume6(mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]], mesh.points[t[3]]) / 6.0;
        facts.volume += v;
        facts.min_tet_volume = std::min(facts.min_tet_volume, v);
        if (!(v > 0)) ++facts.nonpositive_tets;
        for (int k = 0; k < 4; ++k)
            if (adjacency.across[4 * i + k] == TetFaceAdjacency::kBoundary) boundary.push_back(canonical(tet_face(t, k)));
    }
    facts.overshared_faces = adjacency.overshared_faces;
    facts.boundary_faces = static_cast<int64_t>(boundary.size());
    std::vector<Triangle> expected;
    expected.reserve(mesh.boundary_faces.size());
    for (const Triangle& t : mesh.boundary_faces) expected.push_back(canonical(t));
    std::sort(boundary.begin(), boundary.end());
    std::sort(expected.begin(), expected.end());
    facts.boundary_matches = boundary == expected;
    return facts;
}

} // namespace scalemesh
