// The cell passes for a finite-volume solver: face non-orthogonality
// (improve_orthogonality) and the smallest dihedral angle
// (raise_dihedral_angles). One driver (CellPass) runs both; each pass is
// the objective it is given: what it measures and finds short of its
// bound, what counts as better, how a point moves for it.

#include "volume/improve.h"

#include "core/adjacency.h"
#include "volume/flips.h"
#include "volume/quality.h"
#include "volume/tet_editor.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

namespace scalemesh {
namespace {

using improvement::Criterion;
using improvement::dihedral_better;
using improvement::face_links;
using improvement::FaceLink;
using improvement::Few;
using improvement::Flipper;
using improvement::ortho_better;
using improvement::OrthoFloors;
using improvement::parallel_marks;
using improvement::point_gradient;
using improvement::shape_of;
using improvement::Shape;
using improvement::shared_face_cosine;
using improvement::split_at;
using improvement::TetEditor;
using improvement::within_layer;
using improvement::worst_cosine;

// The tets a pass looks at again after its first look: `visit` (what it
// found then) with the living tets made since (ids from `seen` on) and the
// tets at the points moved since, sorted, each once; `seen` and `moved`
// then start over. A tet in none of these has the same points at the same
// places as at the last look, so the same verdict.
std::vector<int32_t> changed_since(TetEditor& ed, std::vector<int32_t> visit, size_t& seen, std::vector<int32_t>& moved)
{
    for (size_t i = seen; i < ed.size(); ++i)
        if (ed.alive(int32_t(i))) visit.push_back(int32_t(i));
    for (int32_t v : moved)
        for (int32_t t : ed.at(v)) visit.push_back(t);
    std::sort(visit.begin(), visit.end());
    visit.erase(std::unique(visit.begin(), visit.end()), visit.end());
    seen = ed.size();
    moved.clear();
    return visit;
}

// The size and middle of point v's star (`tets`, v at `origin`): the mean
// distance from v to the other corners and their mean position, each corner
// counted once per tet; nothing when v has no star.
struct StarSpan {
    double mean_length = 0;
    Vec3 centroid;
};
std::optional<StarSpan> star_span(TetEditor& ed, const std::vector<Tet>& tets, int32_t v, const Vec3& origin)
{
    StarSpan span;
    int edges = 0;
    for (const Tet& t : tets)
        for (int32_t w : t)
            if (w != v) span.mean_length += distance(origin, ed.point(w)), span.centroid += ed.point(w), ++edges;
    if (edges == 0) return std::nullopt;
    span.mean_length /= edges;
    span.centroid /= edges;
    return span;
}

// Moves interior point v to lower the worst face non-orthogonality of the
// faces of its star: a line search along the gradient of that worst
// cosine, and toward the star's centroid, a layer point within its ball.
// Accepted on ortho_better.
bool orthogonalize_point(TetEditor& ed, int32_t v, const LayerBound& layer, const OrthoFloors& floors)
{
    const std::vector<int32_t> star = ed.at(v);
    std::vector<Tet> tets;
    for (int32_t t : star) tets.push_back(ed.tet(t));
    const Vec3 origin = ed.point(v);
    const std::vector<FaceLink> links = face_links(ed, tets, star); // a move keeps them
    const auto shape_at = [&](const Vec3& x) {
        ed.point(v) = x;
        return shape_of(ed, tets, links);
    };
    const Shape start = shape_at(origin);
    const auto span = star_span(ed, tets, v, origin);
    if (!span) return false;
    const auto& [mean_length, centroid] = *span;

    const Vec3 gradient = point_gradient(ed, v, 1e-4 * mean_length, [&] { return worst_cosine(ed, tets, links); });
    const auto in_ball = [&](const Vec3& x) { return within_layer(layer, x); };
    std::vector<Vec3> candidates;
    const Vec3 direction = normalized(gradient);
    if (norm2(direction) > 0)
        for (double step : {0.2, 0.1, 0.05, 0.025, 0.0125, 0.006, 0.003})
            candidates.push_back(in_ball(origin + step * mean_length * direction));
    for (double w : {1.0, 0.5, 0.25}) candidates.push_back(in_ball(origin + w * (centroid - origin)));

    Shape best = start;
    Vec3 best_position = origin;
    for (const Vec3& x : candidates) {
        const Shape s = shape_at(x);
        if (ortho_better(best, s, floors) && ortho_better(start, s, floors)) best = s, best_position = x;
    }
    ed.point(v) = best_position;
    return !(best_position == origin);
}

double star_dihedral(TetEditor& ed, const std::vector<Tet>& tets)
{
    double worst = 1e300;
    for (const Tet& t : tets)
        worst = std::min(worst, tet_min_dihedral_deg(ed.point(t[0]), ed.point(t[1]), ed.point(t[2]), ed.point(t[3])));
    return worst;
}

// Moves interior point v to raise the smallest dihedral angle of its star
// (in the spirit of Freitag and Ollivier-Gooch's optimisation-based
// smoothing: the worst angle is a max-min objective, climbed along the
// gradient of the worst tet's angle and along the mean of the gradients of
// the tets within a degree of it, with a line search), a layer point within
// its ball. Accepted on dihedral_better; repeated while it gains.
bool raise_point_dihedral(TetEditor& ed, int32_t v, const LayerBound& layer, const OrthoFloors& floors)
{
    const std::vector<int32_t> star = ed.at(v);
    std::vector<Tet> tets;
    for (int32_t t : star) tets.push_back(ed.tet(t));
    const Vec3 origin = ed.point(v);
    const std::vector<FaceLink> links = face_links(ed, tets, star);
    const auto shape_at = [&](const Vec3& x) {
        ed.point(v) = x;
        return shape_of(ed, tets, links);
    };
    const auto span = star_span(ed, tets, v, origin);
    if (!span) return false;
    const auto& [mean_length, centroid] = *span;
    const double h = 1e-4 * mean_length;
    const auto in_ball = [&](const Vec3& x) { return within_layer(layer, x); };

    Vec3 position = origin;
    Shape best = shape_at(origin);
    if (!(best.aspect > 0)) {
        ed.point(v) = origin;
        return false;
    }
    for (int iteration = 0; iteration < 4; ++iteration) {
        ed.point(v) = position;
        // The tets within a degree of the worst angle: the active set.
        std::vector<Tet> active;
        for (const Tet& t : tets)
            if (tet_min_dihedral_deg(ed.point(t[0]), ed.point(t[1]), ed.point(t[2]), ed.point(t[3])) < best.dihedral + 1)
                active.push_back(t);
        std::vector<Vec3> directions;
        Vec3 mean;
        for (const Tet& t : active) {
            const std::vector<Tet> one{t};
            const Vec3 g = normalized(point_gradient(ed, v, h, [&] { return star_dihedral(ed, one); }));
            if (directions.empty()) directions.push_back(g);
            mean += g;
        }
        if (active.size() > 1 && norm2(mean) > 0) directions.push_back(normalized(mean));
        std::vector<Vec3> candidates;
        for (const Vec3& d : directions)
            if (norm2(d) > 0)
                for (double step : {0.2, 0.1, 0.05, 0.025, 0.0125, 0.006, 0.003})
                    candidates.push_back(in_ball(position + step * mean_length * d));
        for (double w : {1.0, 0.5, 0.25}) candidates.push_back(in_ball(position + w * (centroid - position)));
        bool gained = false;
        Vec3 next = position;
        for (const Vec3& x : candidates) {
            const Shape s = shape_at(x);
            if (dihedral_better(best, s, floors)) best = s, next = x, gained = true;
        }
        position = next;
        if (!gained) break;
    }
    ed.point(v) = position;
    return !(position == origin);
}

// Splits the interior edge (q, s) by a new free point m: every tet (q, s,
// x, y) at the edge becomes (m, s, x, y) and (q, m, x, y). m is tried at
// points of the edge pulled towards the centroid of its ring and kept where
// `better(best so far, new tets' shape)` holds last, starting from the old
// tets' shape. Returns m, or -1 with nothing changed when no place beats the
// old tets. Never used on a surface edge.
template <class Better>
int32_t split_edge_where_better(TetEditor& ed, int32_t q, int32_t s, const Better& better)
{
    const std::vector<int32_t> around = ed.around_edge(q, s);
    if (around.empty() || ed.any_locked(around)) return -1;
    std::vector<Tet> old;
    for (int32_t t : around) old.push_back(ed.tet(t));
    const Shape before = shape_of(ed, old, face_links(ed, old, around));
    Vec3 centroid;
    int count = 0;
    for (const Tet& t : old)
        for (int32_t v : t)
            if (v != q && v != s) centroid += ed.point(v), ++count;
    centroid /= count;
    const int32_t m = ed.add_point(0.5 * (ed.point(q) + ed.point(s)));
    const std::vector<Tet> fresh = split_at(ed, around, q, s, m);
    const std::vector<FaceLink> links = face_links(ed, fresh, around);
    Shape best = before;
    Vec3 best_position;
    bool found = false;
    for (double along : {0.5, 0.35, 0.65})
        for (double w : {0.0, 0.05, 0.1, 0.2, 0.3, 0.4}) {
            ed.point(m) = (1 - w) * ((1 - along) * ed.point(q) + along * ed.point(s)) + w * centroid;
            const Shape now = shape_of(ed, fresh, links);
            if (better(best, now)) best = now, best_position = ed.point(m), found = true;
        }
    if (!found) {
        ed.drop_last_point();
        return -1;
    }
    ed.point(m) = best_position;
    ed.replace(around, fresh);
    return m;
}

// What a cell pass made.
struct PassCounts {
    int64_t before = 0; // the targets short of the bound at the start
    int64_t moves = 0, splits = 0;
    FlipCounts flips;
};

// The skeleton of both cell passes. For at most `sweeps` rounds, each
// target the objective finds short of its bound (an interior face, a tet)
// gets a flip (2-3, 3-2, 4-4) or an edge removal at one of its tets, else a
// flip at a tet around the target's edges, else moves of its tets' free
// points; every change is one the objective finds better. Then, as a last
// resort, a target still beyond the objective's floor gets an interior edge
// of one of its tets split by a new free point, twice at most. Surface
// points never move and no surface edge is split.
//
// An Objective gives:
//   Target                 what it finds short of the bound (a face, a tet)
//   criterion, floors      the flips' criterion (Flipper), what every change keeps
//   sweeps_after_splits    whether the sweeps run again after each round of splits
//   all_targets()          the targets among every tet: the first look
//   targets_among(tets)    the targets among `tets` (sorted ids): a later look
//   short_of_bound(x)      whether a target found earlier is still short of the bound
//   beyond_floor(x)        whether it is still beyond the floor, to be split
//   tets(x)                its tets, one or two
//   flip_edges(x)          the edges around which flips are tried for it
//   done_after_flip(x)     whether a flip around those edges ends its turn
//   better(before, after)  whether the shape `after` beats `before`, the floors kept
//   move_point(v, layer)   moves free point v for the objective; true when it moved
template <class Objective>
class CellPass {
public:
    CellPass(TetEditor& ed, const Objective& objective, int32_t surface_points, const std::vector<LayerBound>& layers)
        : ed_(ed), objective_(objective), flipper_(ed, Objective::criterion, objective.floors), layers_(layers)
    {
        // A layer point already outside its ball (sliver removal freed it where
        // the mesh was poor) stays where it is.
        pinned_.assign(ed.point_count(), 0);
        for (size_t v = 0; v < pinned_.size(); ++v) {
            const bool layer = v < layers.size() && layers[v].slack > 0;
            pinned_[v] = int32_t(v) < surface_points || (v < layers.size() && layers[v].fixed) ||
                         (layer && distance(ed.point(int32_t(v)), layers[v].home) > layers[v].slack);
        }
    }

    // `surface_edges`: the boundary's edges (edge_key), never split.
    PassCounts run(int sweeps, const EdgeSet& surface_edges)
    {
        for (int sweep = 0; sweep < sweeps; ++sweep) {
            const std::vector<Target>& found = find();
            if (sweep == 0) counts_.before = static_cast<int64_t>(found.size());
            if (improve_all(found) == 0) break;
        }
        for (int round = 0; round < 2; ++round) {
            int64_t splits = 0;
            for (const Target& x : find())
                if (objective_.beyond_floor(x) && split(x, surface_edges)) ++splits;
            counts_.splits += splits;
            if (splits == 0) break;
            if (Objective::sweeps_after_splits)
                for (int sweep = 0; sweep < sweeps; ++sweep)
                    if (improve_all(find()) == 0) break;
        }
        counts_.flips = flips_;
        return counts_;
    }

private:
    using Target = typename Objective::Target;

    // The targets short of the bound, in the objective's order. The first
    // call looks at every tet; a later one only at the tets whose verdict
    // can have changed since: the tets made since, those at the points
    // moved since, and the living tets of the targets found then
    // (changed_since).
    const std::vector<Target>& find()
    {
        if (seen_ == 0) {
            seen_ = ed_.size();
            found_ = objective_.all_targets();
        } else {
            std::vector<int32_t> visit;
            for (const Target& x : found_)
                for (int32_t t : objective_.tets(x))
                    if (ed_.alive(t)) visit.push_back(t);
            found_ = objective_.targets_among(changed_since(ed_, std::move(visit), seen_, moved_));
        }
        return found_;
    }

    // One sweep over `found`; returns the targets changed.
    int64_t improve_all(const std::vector<Target>& found)
    {
        int64_t changed = 0;
        for (const Target& x : found)
            if (objective_.short_of_bound(x) && improve(x)) ++changed;
        return changed;
    }

    // Flips at the target's tets, then at the tets around its edges, then
    // moves of its tets' free points; true when something changed.
    bool improve(const Target& x)
    {
        const Few<int32_t, 2> tets = objective_.tets(x);
        for (int32_t w : tets)
            if (flipper_.improve_tet(w, flips_, true)) return true;
        bool changed = false;
        for (const std::array<int32_t, 2>& edge : objective_.flip_edges(x))
            for (int32_t w : ed_.around_edge(edge[0], edge[1]))
                if (std::find(tets.begin(), tets.end(), w) == tets.end() && ed_.alive(w) &&
                    flipper_.improve_tet(w, flips_)) {
                    changed = true;
                    if (objective_.done_after_flip(x)) return true;
                }
        for (int32_t w : tets) {
            const Tet tet = ed_.tet(w);
            for (int32_t v : tet)
                if (ed_.alive(w) && !pinned(v) && objective_.move_point(v, layer(v)))
                    ++counts_.moves, changed = true, moved_.push_back(v);
        }
        return changed;
    }

    // The last resort: a new free point on the first interior edge of the
    // target's tets where a split takes (split_edge).
    bool split(const Target& x, const EdgeSet& surface_edges)
    {
        for (int32_t w : objective_.tets(x)) {
            const Tet tet = ed_.tet(w);
            for (int i = 0; i < 4; ++i)
                for (int j = i + 1; j < 4; ++j)
                    if (!surface_edges.count(edge_key(tet[i], tet[j])) && split_edge(tet[i], tet[j])) return true;
        }
        return false;
    }

    // Splits the interior edge (q, s) by a new free point m where the shape
    // of the new tets is best, when that beats the old tets' (the
    // objective's better, so the floors hold); then m is moved as any free
    // point. Never used on a surface edge.
    bool split_edge(int32_t q, int32_t s)
    {
        const int32_t m = split_edge_where_better(
            ed_, q, s, [&](const Shape& before, const Shape& after) { return objective_.better(before, after); });
        if (m < 0) return false;
        objective_.move_point(m, {});
        moved_.push_back(m);
        return true;
    }

    bool pinned(int32_t v) const { return size_t(v) < pinned_.size() && pinned_[v]; }
    LayerBound layer(int32_t v) const { return size_t(v) < layers_.size() ? layers_[v] : LayerBound{}; }

    TetEditor& ed_;
    const Objective& objective_;
    Flipper flipper_;
    const std::vector<LayerBound>& layers_;
    std::vector<char> pinned_;   // per point at the start: it never moves (a point made later is free)
    FlipCounts flips_;
    PassCounts counts_;
    std::vector<Target> found_;  // what the last look found
    std::vector<int32_t> moved_; // the points moved since the last look
    size_t seen_ = 0;            // the tets from this id on were made since the last look
};

// Face non-orthogonality as OpenFOAM measures it (the angle between an
// interior face's normal and the join of its two tets' centroids): the
// targets are the interior faces beyond the bound, made better as
// ortho_better says.
class FaceOrthogonality {
public:
    // The face opposite corner k of tet t, u the tet across, t < u; in
    // (t, k) order, as a scan of every tet's faces finds them.
    struct Target {
        int32_t t, k, u;
    };
    static constexpr Criterion criterion = Criterion::orthogonality;
    // The splits are the last resort: no sweeps after them.
    static constexpr bool sweeps_after_splits = false;
    const OrthoFloors floors{};

    FaceOrthogonality(TetEditor& ed, const TetMesh& mesh, double max_angle_deg)
        : ed_(ed), mesh_(mesh), bound_(std::cos(max_angle_deg * M_PI / 180)),
          floor_cosine_(std::cos(floors.ortho * M_PI / 180))
    {
    }

    std::vector<Target> all_targets() const
    {
        // The editor is fresh (every tet alive, ids as in the mesh): the
        // faces from the mesh's adjacency, their angles in parallel
        // (reading only), then in (t, k) order.
        const TetFaceAdjacency adjacency = tet_face_adjacency(mesh_);
        tbb::enumerable_thread_specific<std::vector<Target>> local;
        tbb::parallel_for(tbb::blocked_range<size_t>(0, ed_.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
            std::vector<Target>& out = local.local();
            for (size_t i = r.begin(); i != r.end(); ++i)
                for (int k = 0; k < 4; ++k) {
                    const int32_t t = int32_t(i), u = adjacency.across[4 * i + k];
                    if (u > t && cosine(t, u) < bound_) out.push_back({t, k, u});
                }
        });
        std::vector<Target> found;
        for (const auto& part : local) found.insert(found.end(), part.begin(), part.end());
        std::sort(found.begin(), found.end(), in_order);
        return found;
    }

    std::vector<Target> targets_among(const std::vector<int32_t>& visit) const
    {
        std::vector<Target> found;
        for (int32_t t : visit) {
            const Tet tet = ed_.tet(t);
            for (int k = 0; k < 4; ++k) {
                Few<int32_t, 2> two;
                if (!ed_.tets_at(two, tet[(k + 1) % 4], tet[(k + 2) % 4], tet[(k + 3) % 4]) || two.size() != 2) continue;
                const int32_t u = two[0] == t ? two[1] : two[0];
                if (u > t) {
                    if (cosine(t, u) < bound_) found.push_back({t, k, u});
                } else {
                    // The face as the lower tet's, u's corner off it.
                    const Tet& other = ed_.tet(u);
                    int j = 0;
                    while (TetEditor::contains(tet, other[j])) ++j;
                    if (cosine(u, t) < bound_) found.push_back({u, j, t});
                }
            }
        }
        std::sort(found.begin(), found.end(), in_order);
        found.erase(std::unique(found.begin(), found.end(),
                                [](const Target& a, const Target& b) { return a.t == b.t && a.k == b.k; }),
                    found.end());
        return found;
    }

    bool short_of_bound(const Target& x) const
    {
        return ed_.alive(x.t) && ed_.alive(x.u) && cosine(x.t, x.u) < bound_;
    }
    // Still beyond the solver's floor (floors.ortho) where flips and moves
    // found nothing (its tets' points all surface nodes or held layer points).
    bool beyond_floor(const Target& x) const
    {
        return ed_.alive(x.t) && ed_.alive(x.u) && cosine(x.t, x.u) < floor_cosine_;
    }
    Few<int32_t, 2> tets(const Target& x) const { return {x.t, x.u}; }
    // A face whose corners are all pinned (surface nodes) may still be
    // flipped away from the tets around its edges; the first such flip ends
    // its turn.
    Few<std::array<int32_t, 2>, 6> flip_edges(const Target& x) const
    {
        const Tet first = ed_.tet(x.t), second = ed_.tet(x.u);
        Few<int32_t, 3> face;
        for (int32_t v : first)
            if (TetEditor::contains(second, v)) face.push_back(v);
        Few<std::array<int32_t, 2>, 6> edges;
        for (int e = 0; e < 3 && face.size() == 3; ++e) edges.push_back({face[e], face[(e + 1) % 3]});
        return edges;
    }
    bool done_after_flip(const Target&) const { return true; }
    bool better(const Shape& before, const Shape& after) const { return ortho_better(before, after, floors); }
    bool move_point(int32_t v, const LayerBound& layer) const { return orthogonalize_point(ed_, v, layer, floors); }

private:
    // A face between two locked tets (inside a layer prism) is not looked at.
    double cosine(int32_t t, int32_t u) const
    {
        const auto at = [&](int32_t v) -> const Vec3& { return ed_.point(v); };
        return ed_.locked(t) && ed_.locked(u) ? 1.0 : shared_face_cosine(at, ed_.tet(t), ed_.tet(u));
    }
    static bool in_order(const Target& a, const Target& b) { return a.t != b.t ? a.t < b.t : a.k < b.k; }

    TetEditor& ed_;
    const TetMesh& mesh_; // the mesh the editor was made from: the first look's adjacency
    double bound_;        // the cosine of the largest angle wanted
    double floor_cosine_; // the cosine of floors.ortho
};

// The smallest dihedral angle of a tet: the targets are the tets below the
// target angle (the locked ones aside), made better as dihedral_better says.
class DihedralAngle {
public:
    using Target = int32_t; // a tet
    static constexpr Criterion criterion = Criterion::dihedral;
    // A split's new tets may still be below the target: the sweeps run
    // again after each round of splits.
    static constexpr bool sweeps_after_splits = true;
    const OrthoFloors floors{};

    DihedralAngle(TetEditor& ed, double target_deg) : ed_(ed), target_deg_(target_deg) {}

    std::vector<Target> all_targets() const
    {
        // Every tet, its angles in parallel (reading only).
        const std::vector<char> below = parallel_marks(0, ed_.size(), [&](size_t i) { return poor(int32_t(i)); });
        std::vector<Target> found;
        for (size_t i = 0; i < ed_.size(); ++i)
            if (below[i]) found.push_back(int32_t(i));
        return found;
    }

    std::vector<Target> targets_among(const std::vector<int32_t>& visit) const
    {
        std::vector<Target> found;
        for (int32_t t : visit)
            if (poor(t)) found.push_back(t);
        return found;
    }

    bool short_of_bound(Target t) const { return ed_.alive(t) && dihedral(t) < target_deg_; }
    bool beyond_floor(Target t) const { return short_of_bound(t); }
    Few<int32_t, 2> tets(Target t) const { return {t}; }
    // The tet's six edges; the flips around them go on while the tet lives.
    Few<std::array<int32_t, 2>, 6> flip_edges(Target t) const
    {
        const Tet tet = ed_.tet(t);
        Few<std::array<int32_t, 2>, 6> edges;
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j) edges.push_back({tet[i], tet[j]});
        return edges;
    }
    bool done_after_flip(Target t) const { return !ed_.alive(t); }
    bool better(const Shape& before, const Shape& after) const { return dihedral_better(before, after, floors); }
    bool move_point(int32_t v, const LayerBound& layer) const { return raise_point_dihedral(ed_, v, layer, floors); }

private:
    bool poor(int32_t t) const { return ed_.alive(t) && !ed_.locked(t) && dihedral(t) < target_deg_; }
    double dihedral(int32_t t) const
    {
        const Tet& x = ed_.tet(t);
        return tet_min_dihedral_deg(ed_.point(x[0]), ed_.point(x[1]), ed_.point(x[2]), ed_.point(x[3]));
    }

    TetEditor& ed_;
    double target_deg_; // degrees
};

} // namespace

OrthoCounts improve_orthogonality(TetMesh& mesh, int32_t surface_points, double max_angle_deg, int sweeps,
                                  const std::vector<LayerBound>& layers, int32_t locked_tets)
{
    TetEditor ed(mesh, locked_tets);
    const FaceOrthogonality objective(ed, mesh, max_angle_deg);
    const PassCounts made =
        CellPass<FaceOrthogonality>(ed, objective, surface_points, layers).run(sweeps, edge_set(mesh.boundary_faces));
    ed.commit();
    return {.faces_before = made.before, .flips = made.flips.total(), .moves = made.moves, .splits = made.splits};
}

DihedralCounts raise_dihedral_angles(TetMesh& mesh, int32_t surface_points, double target_deg, int sweeps,
                                     const std::vector<LayerBound>& layers, int32_t locked_tets)
{
    TetEditor ed(mesh, locked_tets);
    const DihedralAngle objective(ed, target_deg);
    const PassCounts made =
        CellPass<DihedralAngle>(ed, objective, surface_points, layers).run(sweeps, edge_set(mesh.boundary_faces));
    ed.commit();
    return {.tets_before = made.before, .flips = made.flips.total(), .moves = made.moves, .splits = made.splits};
}

} // namespace scalemesh
