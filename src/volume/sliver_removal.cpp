// Sliver removal: flips and moves of interior points for the tets below an
// aspect ratio (remove_slivers), and splits of the edges of slivers whose
// points all lie on the surface (split_surface_slivers).

#include "volume/improve.h"

#include "core/adjacency.h"
#include "volume/flips.h"
#include "volume/quality.h"
#include "volume/slab_scheduler.h"
#include "volume/tet_editor.h"

#include <algorithm>
#include <mutex>
#include <numeric>
#include <optional>
#include <vector>

namespace scalemesh {
namespace {

using improvement::below_marks;
using improvement::Criterion;
using improvement::Flipper;
using improvement::improve_in_slabs;
using improvement::Part;
using improvement::place_split_point;
using improvement::smooth_point;
using improvement::split_at;
using improvement::TetEditor;

// The rounds of remove_slivers over one editor. A tet marked at or above
// the threshold (marked in parallel by `mark`) none of whose points has
// moved since is still so: a round skips it without computing its shape,
// and decides as if it had.
class SliverRounds {
public:
    // pinned[v]: point v may not move.
    SliverRounds(TetEditor& ed, const std::vector<char>& pinned)
        : ed_(ed), flipper_(ed, Criterion::quality), pinned_(pinned)
    {
    }

    // Marks the tets at or above `below`, as they are now.
    void mark(double below)
    {
        below_ = below_marks(ed_, 0, ed_.size(), below);
        marked_below_ = below;
        moved_.assign(ed_.point_count(), 0);
    }

    // One round over `visit`: each living tet below `below` gets a flip
    // that raises the worst aspect ratio of the tets it replaces, else
    // moves of its interior points (a layer point within layers[v] when
    // `layers` has it). Returns the changes made. With `next`, adds the
    // tets to visit again: the ones still below and those at moved points
    // (the tets made in the round are the caller's to add).
    int64_t round(const std::vector<int32_t>& visit, double below, const std::vector<LayerBound>& layers,
                  std::vector<int32_t>* next)
    {
        int64_t changed = 0;
        for (int32_t id : visit) {
            if (!ed_.alive(id) || skip(id, below) || ed_.aspect(ed_.tet(id)) >= below) continue;
            if (flipper_.improve_tet(id, flips_)) {
                ++changed;
                continue;
            }
            const Tet tet = ed_.tet(id);
            for (int32_t v : tet)
                if (!pinned_[v] && smooth_point(ed_, v, size_t(v) < layers.size() ? layers[v] : LayerBound{})) {
                    ++moves_, ++changed;
                    if (size_t(v) < moved_.size()) moved_[v] = 1;
                    if (!next) continue;
                    const std::vector<int32_t>& star = ed_.at(v);
                    next->insert(next->end(), star.begin(), star.end());
                }
            if (next && ed_.alive(id)) next->push_back(id);
        }
        return changed;
    }

    SliverCounts counts() const { return {flips_.total(), moves_}; }

private:
    bool skip(int32_t id, double below) const
    {
        if (size_t(id) >= below_.size() || below_[id] || below > marked_below_) return false;
        for (int32_t v : ed_.tet(id))
            if (size_t(v) < moved_.size() && moved_[v]) return false;
        return true;
    }

    TetEditor& ed_;
    Flipper flipper_;
    const std::vector<char>& pinned_;
    FlipCounts flips_;
    int64_t moves_ = 0;
    std::vector<char> below_; // per tet id when marked: below the marked threshold
    double marked_below_ = 0;
    std::vector<char> moved_; // per point: moved since the marks
};

// The rounds of remove_slivers with the points of `pinned` held;
// free_rounds for the last rounds with layer points free.
SliverCounts sliver_rounds(TetMesh& mesh, const std::vector<char>& pinned, double threshold, int sweeps,
                           const std::vector<LayerBound>& layers, bool free_rounds)
{
    constexpr double kFreeBelow = 0.1;
    TetEditor ed(mesh);
    SliverRounds rounds(ed, pinned);
    rounds.mark(std::max(threshold, kFreeBelow));
    // The first sweep visits every tet; each later one the tets still below
    // the threshold, the tets made since, and the tets at moved points (the
    // only ones whose shape can have changed).
    auto every_tet = [&] {
        std::vector<int32_t> all(ed.size());
        std::iota(all.begin(), all.end(), 0);
        return all;
    };
    std::vector<int32_t> visit = every_tet();
    for (int sweep = 0; sweep < sweeps && !visit.empty(); ++sweep) {
        const size_t made_from = ed.size();
        std::vector<int32_t> next;
        if (rounds.round(visit, threshold, layers, &next) == 0) break;
        for (size_t t = made_from; t < ed.size(); ++t) next.push_back(static_cast<int32_t>(t));
        std::sort(next.begin(), next.end());
        next.erase(std::unique(next.begin(), next.end()), next.end());
        visit = std::move(next);
    }
    // Last, a layer point of a tet still below 0.1 may leave its layer as
    // far as the move needs: quality first where it is poor.
    for (int round = 0; round < 3 && free_rounds; ++round)
        if (rounds.round(every_tet(), kFreeBelow, layers, nullptr) == 0) break;
    ed.commit();
    return rounds.counts();
}

// Splits the edge (q, s) of a sliver whose vertices are all surface points
// (flips cannot remove it without changing the surface, and no vertex may
// move) by a new interior point m: every tet (q, s, x, y) at the edge
// becomes (m, s, x, y) and (q, m, x, y). m is taken on the way from the
// edge's midpoint to the centroid of the edge's ring, where the smallest
// aspect ratio of the new tets is best; nothing changes unless that beats
// the old tets' smallest one and `at_least`. Never used on a surface edge.
bool split_surface_sliver_edge(TetEditor& ed, int32_t q, int32_t s, double at_least)
{
    const std::vector<int32_t> around = ed.around_edge(q, s);
    if (around.empty() || ed.any_locked(around)) return false;
    double old_q = 1e300;
    Vec3 centroid;
    int count = 0;
    for (int32_t t : around) {
        old_q = std::min(old_q, ed.aspect(ed.tet(t)));
        for (int32_t v : ed.tet(t))
            if (v != q && v != s) centroid += ed.point(v), ++count;
    }
    centroid /= count;
    const Vec3 mid = 0.5 * (ed.point(q) + ed.point(s));
    const int32_t m = ed.add_point(mid);
    std::vector<Tet> fresh = split_at(ed, around, q, s, m);
    double best = std::max(old_q, at_least);
    std::optional<Vec3> place;
    for (double w : {0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6}) {
        ed.point(m) = (1 - w) * mid + w * centroid;
        double worst = 1e300;
        for (const Tet& t : fresh) worst = std::min(worst, ed.aspect(t));
        if (worst > best + 1e-9) best = worst, place = ed.point(m);
    }
    return place_split_point(ed, m, place, around, fresh);
}

} // namespace

SliverCounts remove_slivers(TetMesh& mesh, int32_t surface_points, double threshold, int sweeps,
                            const std::vector<LayerBound>& layers)
{
    SliverCounts counts;
    std::mutex adding;
    improve_in_slabs(mesh, surface_points, 1, threshold, [&](Part& part, int) {
        std::vector<LayerBound> part_layers;
        if (!layers.empty())
            for (int32_t v : part.global) part_layers.push_back(size_t(v) < layers.size() ? layers[v] : LayerBound{});
        const SliverCounts made = sliver_rounds(part.mesh, part.pinned, threshold, sweeps, part_layers, !layers.empty());
        const std::lock_guard<std::mutex> lock(adding);
        counts.flips += made.flips, counts.moves += made.moves;
    });
    return counts;
}

int64_t split_surface_slivers(TetMesh& mesh, int32_t surface_points, double threshold, double at_least,
                              bool surface_points_only)
{
    const std::vector<Vec3>& p = mesh.points;
    auto surface_sliver = [&](const Tet& t) {
        return (!surface_points_only || *std::max_element(t.begin(), t.end()) < surface_points) &&
               tet_aspect_ratio(p[t[0]], p[t[1]], p[t[2]], p[t[3]]) < threshold;
    };
    if (std::none_of(mesh.tets.begin(), mesh.tets.end(), surface_sliver)) return 0;
    int64_t splits = 0;
    TetEditor ed(mesh);
    const EdgeSet surface_edges = edge_set(mesh.boundary_faces);
    const size_t n = ed.size();
    for (size_t t = 0; t < n; ++t) {
        const int32_t id = static_cast<int32_t>(t);
        if (!ed.alive(id) || !surface_sliver(ed.tet(id))) continue;
        const Tet tet = ed.tet(id);
        for (int i = 0; i < 4 && ed.alive(id); ++i)
            for (int j = i + 1; j < 4 && ed.alive(id); ++j)
                if (!surface_edges.count(edge_key(tet[i], tet[j])) && split_surface_sliver_edge(ed, tet[i], tet[j], at_least))
                    ++splits;
    }
    ed.commit();
    return splits;
}

} // namespace scalemesh
