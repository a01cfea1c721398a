// The cell passes for a finite-volume solver: face non-orthogonality
// (improve_orthogonality) and the smallest dihedral angle
// (raise_dihedral_angles), and their schedule (improve_cells). One driver
// (CellPass) runs both; each pass is the objective it is given: what it
// measures and finds short of its bound, what counts as better, how a
// point moves for it. They run in slabs at once (improve_in_slab_rounds),
// each slab's passes over one editor (PartPasses).

#include "volume/improve.h"

#include "core/adjacency.h"
#include "volume/flips.h"
#include "volume/quality.h"
#include "volume/slab_scheduler.h"
#include "volume/tet_editor.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>
#include <optional>
#include <unordered_map>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

namespace scalemesh {
namespace {

using improvement::CellCentres;
using improvement::cell_shape_against;
using improvement::Criterion;
using improvement::face_links;
using improvement::FaceLink;
using improvement::Few;
using improvement::Flipper;
using improvement::improve_in_slab_rounds;
using improvement::OrthoFloors;
using improvement::parallel_marks;
using improvement::Part;
using improvement::point_gradient;
using improvement::shape_of;
using improvement::Shape;
using improvement::ShapeOrder;
using improvement::shared_face_cosine;
using improvement::split_at;
using improvement::TetEditor;
using improvement::with_cosine_against;
using improvement::within_layer;
using improvement::worst_cosine;

// What every change of the passes keeps (OrthoFloors): the solver's floors.
constexpr OrthoFloors kFloors{};

// The edits the passes over one editor made, as the passes' later looks
// and skips need them: the points moved, in order, and for each point when
// it last changed (it moved, or a tet of it was made). The clock is the
// count of tets made and moves so far: it only grows.
class EditLog {
public:
    explicit EditLog(const TetEditor& ed) : ed_(ed), made_(ed.size()) {}

    void moved(int32_t v) { moves_.push_back(v); }
    const std::vector<int32_t>& moves() const { return moves_; }
    int64_t now() const { return static_cast<int64_t>(ed_.size() + moves_.size()); }

    // Whether no point within three rings of `points` (joined through tets)
    // changed since the time `since`. A flip, removal or split replaces tets
    // by tets on the same points (and a new one), so a change to a tet at a
    // point within two rings marks that point, and a move its point.
    template <class Points>
    bool quiet_since(TetEditor& ed, const Points& points, int64_t since)
    {
        stamp();
        ++pass_;
        visited_.resize(changed_.size(), 0);
        ring_.clear();
        for (int32_t v : points) {
            if (changed_[v] > since) return false;
            visited_[v] = pass_, ring_.push_back(v);
        }
        for (int rings = 0, begin = 0; rings < 3; ++rings) {
            const int end = static_cast<int>(ring_.size());
            for (int i = begin; i < end; ++i)
                for (int32_t t : ed.at(ring_[i]))
                    for (int32_t w : ed.tet(t)) {
                        if (visited_[w] == pass_) continue;
                        if (changed_[w] > since) return false;
                        visited_[w] = pass_, ring_.push_back(w);
                    }
            begin = end;
        }
        return true;
    }

    // Brings the points' times up to now: those of the tets made and the
    // moves since the last call.
    void stamp()
    {
        changed_.resize(ed_.point_count(), 0);
        const int64_t time = now();
        for (; made_ < ed_.size(); ++made_)
            for (int32_t v : ed_.tet(static_cast<int32_t>(made_))) changed_[v] = time;
        for (; stamped_ < moves_.size(); ++stamped_) changed_[moves_[stamped_]] = time;
    }

private:
    const TetEditor& ed_;
    std::vector<int32_t> moves_;   // the points moved, in order
    std::vector<int64_t> changed_; // per point: the time it last changed (0: never)
    size_t made_ = 0;              // the tets from this id on are not stamped yet
    size_t stamped_ = 0;           // nor the moves from this one on
    std::vector<int64_t> visited_; // per point: the search (pass_) that last reached it
    int64_t pass_ = 0;
    std::vector<int32_t> ring_;
};

// The tets a pass looks at again after its first look: `visit` (what it
// found then) with the living tets made since (ids from `seen` on) and the
// tets at the points moved since (the log's moves from `logged` on),
// sorted, each once; `seen` and `logged` then move to now. A tet in none of
// these has the same points at the same places as at the last look, so the
// same verdict.
std::vector<int32_t> changed_since(TetEditor& ed, std::vector<int32_t> visit, size_t& seen, const EditLog& log,
                                   size_t& logged)
{
    const std::vector<int32_t>& moved = log.moves();
    for (size_t i = seen; i < ed.size(); ++i)
        if (ed.alive(int32_t(i))) visit.push_back(int32_t(i));
    for (size_t i = logged; i < moved.size(); ++i)
        for (int32_t t : ed.at(moved[i])) visit.push_back(t);
    std::sort(visit.begin(), visit.end());
    visit.erase(std::unique(visit.begin(), visit.end()), visit.end());
    seen = ed.size();
    logged = moved.size();
    return visit;
}

// Point v's star as a move of v sees it: its tets and their interior faces
// (a move keeps both), and its size and middle: the mean distance from v
// to the other corners and their mean position, each corner counted once
// per tet.
struct Star {
    std::vector<Tet> tets;
    std::vector<FaceLink> links;
    double mean_length = 0;
    Vec3 centroid;
};

// A move of free point v for an objective, from where it is: up to
// `rounds` line searches, each along the directions `directions(star,
// best)` gives (v where the search is) by steps of 0.2 down to 0.003 of the
// star's mean edge length, and toward the star's centroid (all the way,
// half, a quarter), a layer point within its ball. v goes to the last
// candidate whose shape is order.better(best so far, its shape), the first
// round's best starting from v's own; a round that finds none ends the
// search. No move for a point without a star or with a flat tet in it.
// True when v moved.
template <class Directions>
bool move_point(TetEditor& ed, int32_t v, const LayerBound& layer, int rounds, const Directions& directions,
                const ShapeOrder& order)
{
    Star star;
    const std::vector<int32_t> ids = ed.at(v);
    for (int32_t t : ids) star.tets.push_back(ed.tet(t));
    const Vec3 origin = ed.point(v);
    int corners = 0;
    for (const Tet& t : star.tets)
        for (int32_t w : t)
            if (w != v) star.mean_length += distance(origin, ed.point(w)), star.centroid += ed.point(w), ++corners;
    if (corners == 0) return false;
    star.mean_length /= corners;
    star.centroid /= corners;
    star.links = face_links(ed, star.tets, ids);

    ed.point(v) = origin;
    Shape best = shape_of(ed, star.tets, star.links);
    if (!(best.aspect > 0)) return false;
    Vec3 position = origin;
    for (int round = 0; round < rounds; ++round) {
        ed.point(v) = position;
        std::vector<Vec3> candidates;
        for (const Vec3& d : directions(star, best))
            if (norm2(d) > 0)
                for (double step : {0.2, 0.1, 0.05, 0.025, 0.0125, 0.006, 0.003})
                    candidates.push_back(within_layer(layer, position + step * star.mean_length * d));
        for (double w : {1.0, 0.5, 0.25})
            candidates.push_back(within_layer(layer, position + w * (star.centroid - position)));
        bool gained = false;
        Vec3 next = position;
        for (const Vec3& x : candidates) {
            ed.point(v) = x;
            // Its cosine only when the rest may beat the best.
            const Shape s = cell_shape_against(ed, star.tets, order, best);
            if (!order.may_beat(best, s)) continue;
            const Shape whole = with_cosine_against(s, ed, star.tets, star.links, order, best);
            if (order.better(best, whole)) best = whole, next = x, gained = true;
        }
        position = next;
        if (!gained) break;
    }
    ed.point(v) = position;
    return !(position == origin);
}

// Moves interior point v to lower the worst face non-orthogonality of the
// faces of its star: one line search along the gradient of that worst
// cosine. Accepted on ortho_better (which, holding against the best so far,
// holds against the start).
bool orthogonalize_point(TetEditor& ed, int32_t v, const LayerBound& layer, const ShapeOrder& order)
{
    const auto along_gradient = [&](const Star& star, const Shape&) {
        const Vec3 gradient = point_gradient(ed, v, 1e-4 * star.mean_length,
                                             [&] { return worst_cosine(ed, star.tets, star.links); });
        return Few<Vec3, 2>{normalized(gradient)};
    };
    return move_point(ed, v, layer, 1, along_gradient, order);
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
// the tets within a degree of it, with a line search). Accepted on
// dihedral_better; up to four searches while they gain.
bool raise_point_dihedral(TetEditor& ed, int32_t v, const LayerBound& layer, const ShapeOrder& order)
{
    const auto active_gradients = [&](const Star& star, const Shape& best) {
        // The tets within a degree of the worst angle: the active set.
        const double h = 1e-4 * star.mean_length;
        Few<Vec3, 2> directions;
        Vec3 mean;
        int active = 0;
        for (const Tet& t : star.tets) {
            if (!(tet_min_dihedral_deg(ed.point(t[0]), ed.point(t[1]), ed.point(t[2]), ed.point(t[3])) <
                  best.dihedral + 1))
                continue;
            const std::vector<Tet> one{t};
            const Vec3 g = normalized(point_gradient(ed, v, h, [&] { return star_dihedral(ed, one); }));
            if (directions.size() == 0) directions.push_back(g);
            mean += g;
            ++active;
        }
        if (active > 1 && norm2(mean) > 0) directions.push_back(normalized(mean));
        return directions;
    };
    return move_point(ed, v, layer, 4, active_gradients, order);
}

// Whether the tets `around` the edge (q, s) close around it: each other
// corner is in two of them. Not so at a surface edge, nor where some of
// the tets around it are not in the editor (a slab's cut).
bool closes_around(const TetEditor& ed, const std::vector<int32_t>& around, int32_t q, int32_t s)
{
    if (around.size() < 3) return false;
    std::vector<int32_t> corners;
    for (int32_t t : around)
        for (int32_t v : ed.tet(t))
            if (v != q && v != s) corners.push_back(v);
    std::sort(corners.begin(), corners.end());
    for (size_t i = 0; i < corners.size(); i += 2) {
        const bool pair = i + 1 < corners.size() && corners[i + 1] == corners[i];
        const bool third = i + 2 < corners.size() && corners[i + 2] == corners[i];
        if (!pair || third) return false;
    }
    return true;
}

// Splits the interior edge (q, s) by a new free point m: every tet (q, s,
// x, y) at the edge becomes (m, s, x, y) and (q, m, x, y). m is tried at
// points of the edge pulled towards the centroid of its ring and kept where
// order.better(best so far, new tets' shape) holds last, starting from the
// old tets' shape. Returns m, or -1 with nothing changed when no place
// beats the old tets. Only an edge whose tets all are in the editor and
// close around it (closes_around): never a surface edge.
int32_t split_edge_where_better(TetEditor& ed, int32_t q, int32_t s, const ShapeOrder& order)
{
    const std::vector<int32_t> around = ed.around_edge(q, s);
    if (!closes_around(ed, around, q, s) || ed.any_locked(around)) return -1;
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
            const Shape now = cell_shape_against(ed, fresh, order, best);
            if (!order.may_beat(best, now)) continue;
            const Shape whole = with_cosine_against(now, ed, fresh, links, order, best);
            if (order.better(best, whole)) best = whole, best_position = ed.point(m), found = true;
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
    int64_t moves = 0, splits = 0;
    FlipCounts flips;
    int64_t changes() const { return moves + splits + flips.total(); }
};

PassCounts& operator+=(PassCounts& a, const PassCounts& b)
{
    a.moves += b.moves, a.splits += b.splits;
    a.flips.flips_32 += b.flips.flips_32, a.flips.flips_23 += b.flips.flips_23;
    a.flips.flips_44 += b.flips.flips_44, a.flips.edge_removals += b.flips.edge_removals;
    return a;
}

// The skeleton of both cell passes. For at most `sweeps` rounds, each
// target the objective finds short of its bound (an interior face, a tet)
// gets a flip (2-3, 3-2, 4-4) or an edge removal at one of its tets, else a
// flip at a tet around the target's edges, else moves of its tets' free
// points; every change is one the objective finds better. Then, as a last
// resort, a target still beyond the objective's floor gets an interior edge
// of one of its tets split by a new free point, twice at most. Pinned
// points never move and no surface edge is split.
//
// A pass looks at the whole editor once, when it is made (or at the tets
// it is told to, a slab's focus); every later look, in this run or a later
// one, only at the tets changed since its last (changed_since): the
// targets found then, the tets made since and the tets at points moved
// since by any pass over the editor, whose log (EditLog) the passes share.
// A target whose last turn changed nothing is passed over while nothing
// that turn read has changed (would_fail_again): it would fail the same way.
// A target with a point on the editor's border (a slab's cut: the point
// cannot move, nor the tets beyond it change) is left to the round of
// slabs that holds it whole.
//
// An Objective gives:
//   Target                 what it finds short of the bound (a face, a tet)
//   criterion              the flips' criterion (Flipper)
//   order                  what counts as better (ShapeOrder), the floors every change keeps
//   sweeps_after_splits    whether the sweeps run again after each round of splits
//   all_targets()          the targets among every tet of a fresh editor: the first look
//   targets_among(tets)    the targets among `tets` (sorted ids): a later look
//   short_of_bound(x)      whether a target found earlier is still short of the bound
//   beyond_floor(x)        whether it is still beyond the floor, to be split
//   tets(x)                its tets, one or two
//   key(x)                 a number for it, unique among the targets
//   flip_edges(x)          the edges around which flips are tried for it
//   done_after_flip(x)     whether a flip around those edges ends its turn
//   move_point(v, layer)   moves free point v for the objective; true when it moved
template <class Objective>
class CellPass {
public:
    // `pinned` (per point of the editor): the points that never move
    // (surface points and `border`: the points with tets beyond the
    // editor's); `log`: the edits of the passes over the editor; `focus`:
    // the tets of the first look, all when none.
    CellPass(TetEditor& ed, Objective objective, const std::vector<char>& pinned, const std::vector<char>& border,
             const std::vector<LayerBound>& layers, EditLog& log, const std::optional<std::vector<int32_t>>& focus)
        : ed_(ed), objective_(std::move(objective)), flipper_(ed, Objective::criterion, objective_.order.floors),
          layers_(layers), border_(border), log_(log)
    {
        // A layer point already outside its ball (sliver removal freed it where
        // the mesh was poor) stays where it is.
        pinned_.assign(ed.point_count(), 0);
        for (size_t v = 0; v < pinned_.size(); ++v) {
            const bool layer = v < layers.size() && layers[v].slack > 0;
            pinned_[v] = (v < pinned.size() && pinned[v]) || (v < layers.size() && layers[v].fixed) ||
                         (layer && distance(ed.point(int32_t(v)), layers[v].home) > layers[v].slack);
        }
        if (!focus) {
            found_ = objective_.all_targets();
        } else {
            std::vector<int32_t> tets = *focus;
            std::sort(tets.begin(), tets.end());
            found_ = objective_.targets_among(tets);
        }
        before_ = static_cast<int64_t>(found_.size());
        leave_border_targets();
        seen_ = ed.size();
        logged_ = log_.moves().size();
    }

    // The targets short of the bound at the first look.
    int64_t before() const { return before_; }

    // The sweeps, then the splits; returns what this run made.
    PassCounts run(int sweeps)
    {
        made_ = PassCounts{};
        for (int sweep = 0; sweep < sweeps; ++sweep)
            if (improve_all(find()) == 0) break;
        for (int round = 0; round < 2; ++round) {
            int64_t splits = 0;
            for (const Target& x : find())
                if (objective_.beyond_floor(x) && split(x)) ++splits;
            made_.splits += splits;
            if (splits == 0) break;
            if (Objective::sweeps_after_splits)
                for (int sweep = 0; sweep < sweeps; ++sweep)
                    if (improve_all(find()) == 0) break;
        }
        return made_;
    }

private:
    using Target = typename Objective::Target;

    // The targets short of the bound, in the objective's order: those of the
    // last look, looked at again where something changed since.
    const std::vector<Target>& find()
    {
        if (seen_ == ed_.size() && logged_ == log_.moves().size()) return found_; // nothing changed: the same verdicts
        std::vector<int32_t> visit;
        for (const Target& x : found_)
            for (int32_t t : objective_.tets(x))
                if (ed_.alive(t)) visit.push_back(t);
        found_ = objective_.targets_among(changed_since(ed_, std::move(visit), seen_, log_, logged_));
        leave_border_targets();
        return found_;
    }

    void leave_border_targets()
    {
        const auto on_border = [&](const Target& x) {
            for (int32_t t : objective_.tets(x))
                for (int32_t v : ed_.tet(t))
                    if (size_t(v) < border_.size() && border_[v]) return true;
            return false;
        };
        found_.erase(std::remove_if(found_.begin(), found_.end(), on_border), found_.end());
    }

    // One sweep over `found`; returns the targets changed.
    int64_t improve_all(const std::vector<Target>& found)
    {
        int64_t changed = 0;
        for (const Target& x : found) {
            if (!objective_.short_of_bound(x) || would_fail_again(x)) continue;
            if (improve(x)) ++changed;
            else remember_failure(x);
        }
        return changed;
    }

    // Whether x's last turn changed nothing and nothing it read has changed
    // since: improve(x) reads the tets at the points within two rings of
    // x's points (the tets around the edges of the tets around its edges,
    // their rings, the tets across their faces) and the places of the
    // points within three, so it would fail the same way again.
    bool would_fail_again(const Target& x)
    {
        const auto failed = failed_at_.find(objective_.key(x));
        if (failed == failed_at_.end()) return false;
        Few<int32_t, 8> points;
        for (int32_t t : objective_.tets(x))
            for (int32_t v : ed_.tet(t)) points.push_back(v);
        return log_.quiet_since(ed_, points, failed->second);
    }

    void remember_failure(const Target& x)
    {
        log_.stamp();
        failed_at_[objective_.key(x)] = log_.now();
    }

    // Flips at the target's tets, then at the tets around its edges, then
    // moves of its tets' free points; true when something changed.
    bool improve(const Target& x)
    {
        const Few<int32_t, 2> tets = objective_.tets(x);
        for (int32_t w : tets)
            if (flipper_.improve_tet(w, made_.flips, true)) return true;
        bool changed = false;
        for (const std::array<int32_t, 2>& edge : objective_.flip_edges(x))
            for (int32_t w : ed_.around_edge(edge[0], edge[1]))
                if (std::find(tets.begin(), tets.end(), w) == tets.end() && ed_.alive(w) &&
                    flipper_.improve_tet(w, made_.flips)) {
                    changed = true;
                    if (objective_.done_after_flip(x)) return true;
                }
        for (int32_t w : tets) {
            const Tet tet = ed_.tet(w);
            for (int32_t v : tet)
                if (ed_.alive(w) && !pinned(v) && objective_.move_point(v, layer(v)))
                    ++made_.moves, changed = true, log_.moved(v);
        }
        return changed;
    }

    // The last resort: a new free point on the first edge of the target's
    // tets where a split takes (split_edge).
    bool split(const Target& x)
    {
        for (int32_t w : objective_.tets(x)) {
            const Tet tet = ed_.tet(w);
            for (int i = 0; i < 4; ++i)
                for (int j = i + 1; j < 4; ++j)
                    if (split_edge(tet[i], tet[j])) return true;
        }
        return false;
    }

    // Splits the interior edge (q, s) by a new free point m where the shape
    // of the new tets is best, when that beats the old tets' (the
    // objective's order, so the floors hold); then m is moved as any free
    // point. Never used on a surface edge (split_edge_where_better).
    bool split_edge(int32_t q, int32_t s)
    {
        const int32_t m = split_edge_where_better(ed_, q, s, objective_.order);
        if (m < 0) return false;
        objective_.move_point(m, {});
        log_.moved(m);
        return true;
    }

    bool pinned(int32_t v) const { return size_t(v) < pinned_.size() && pinned_[v]; }
    LayerBound layer(int32_t v) const { return size_t(v) < layers_.size() ? layers_[v] : LayerBound{}; }

    TetEditor& ed_;
    Objective objective_;
    Flipper flipper_;
    const std::vector<LayerBound>& layers_;
    const std::vector<char>& border_; // per point at the start: it has tets beyond the editor's
    std::vector<char> pinned_;      // per point at the start: it never moves (a point made later is free)
    PassCounts made_;               // by the current run
    int64_t before_ = 0;            // the targets the first look found
    std::vector<Target> found_;     // what the last look found
    EditLog& log_;                  // the edits of every pass over the editor
    size_t seen_ = 0;               // the tets from this id on were made since the last look
    size_t logged_ = 0;             // the log's moves from this one on were made since the last look
    std::unordered_map<int64_t, int64_t> failed_at_; // target key -> the log's time when its turn last changed nothing
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
    const ShapeOrder order{false, kFloors};

    FaceOrthogonality(TetEditor& ed, const TetMesh& mesh, double max_angle_deg)
        : ed_(ed), mesh_(mesh), bound_(std::cos(max_angle_deg * M_PI / 180)),
          floor_cosine_(std::cos(order.floors.ortho * M_PI / 180))
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
    // Still beyond the solver's floor (order.floors.ortho) where flips and moves
    // found nothing (its tets' points all surface nodes or held layer points).
    bool beyond_floor(const Target& x) const
    {
        return ed_.alive(x.t) && ed_.alive(x.u) && cosine(x.t, x.u) < floor_cosine_;
    }
    Few<int32_t, 2> tets(const Target& x) const { return {x.t, x.u}; }
    int64_t key(const Target& x) const { return 4 * int64_t(x.t) + x.k; }
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
    bool move_point(int32_t v, const LayerBound& layer) const { return orthogonalize_point(ed_, v, layer, order); }

private:
    // A face between two locked tets (the layer prisms', or across a part's
    // border) is out of the passes' reach and not looked at, but for a face
    // between two layer prisms one of which is in the top layer, whose top
    // points slide.
    double cosine(int32_t t, int32_t u) const
    {
        const auto at = [&](int32_t v) -> const Vec3& { return ed_.point(v); };
        if (ed_.locked(t) && ed_.locked(u) &&
            !(ed_.centres && ed_.centres->top_prisms_apart(ed_.tet(t), ed_.tet(u))))
            return 1.0;
        return shared_face_cosine(at, ed_.tet(t), ed_.tet(u), ed_.centres);
    }
    static bool in_order(const Target& a, const Target& b) { return a.t != b.t ? a.t < b.t : a.k < b.k; }

    TetEditor& ed_;
    const TetMesh& mesh_; // the mesh the editor was made from: the first look's adjacency
    double bound_;        // the cosine of the largest angle wanted
    double floor_cosine_; // the cosine of order.floors.ortho
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
    const ShapeOrder order{true, kFloors};

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
    int64_t key(Target t) const { return t; }
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
    bool move_point(int32_t v, const LayerBound& layer) const { return raise_point_dihedral(ed_, v, layer, order); }

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

// Which passes a part makes.
enum class Passes { orthogonality, dihedral, both };

// The cell passes of one part (a slab, or the whole mesh) over one editor:
// each pass is made, and takes its first look, before any edit, then runs
// as often as the schedule asks, each run looking only at what changed
// since its last look.
class PartPasses {
public:
    PartPasses(Part& part, const std::vector<LayerBound>& layers, const CellPassParams& params, Passes passes)
        : ed_(part.mesh, part.read_only), log_(ed_)
    {
        if (params.prism_cells && !params.prism_cells->points.empty()) {
            centres_.prisms = params.prism_cells;
            centres_.global = &part.global;
            centres_.stacked.resize(part.global.size());
            for (size_t l = 0; l < part.global.size(); ++l) {
                centres_.local.emplace(part.global[l], int32_t(l));
                const size_t v = size_t(part.global[l]);
                centres_.stacked[l] = v < params.prism_cells->generator.size() && params.prism_cells->generator[v] >= 0;
            }
            ed_.centres = &centres_;
        }
        if (!layers.empty())
            for (int32_t v : part.global) layers_.push_back(size_t(v) < layers.size() ? layers[v] : LayerBound{});
        if (passes != Passes::dihedral)
            ortho_.emplace(ed_, FaceOrthogonality(ed_, part.mesh, params.ortho_bound_deg), part.pinned, part.border,
                           layers_, log_, part.focus);
        if (passes != Passes::orthogonality)
            dihedral_.emplace(ed_, DihedralAngle(ed_, params.dihedral_target_deg), part.pinned, part.border, layers_,
                              log_, part.focus);
    }

    PassCounts orthogonality(int sweeps) { return ortho_->run(sweeps); }
    PassCounts dihedral(int sweeps) { return dihedral_->run(sweeps); }
    int64_t faces_before() const { return ortho_ ? ortho_->before() : 0; }
    int64_t tets_before() const { return dihedral_ ? dihedral_->before() : 0; }

    // Writes the part's tets back to its mesh.
    void commit() { ed_.commit(); }

private:
    CellCentres centres_;
    TetEditor ed_;
    EditLog log_;                    // what the passes changed
    std::vector<LayerBound> layers_; // per part point
    std::optional<CellPass<FaceOrthogonality>> ortho_;
    std::optional<CellPass<DihedralAngle>> dihedral_;
};

// What the parts' passes made, added up; the targets before as the first
// round of slabs found them (it looks at every tet of its slabs).
struct Made {
    PassCounts ortho, dihedral;
    int64_t faces_before = 0, tets_before = 0;
};

// Runs schedule(part passes, ortho counts, dihedral counts) on the passes
// of each part of the mesh, in rounds of slabs (improve_in_slab_rounds):
// one slab per params.tets_per_slab tets, up to params.max_slabs, a count
// of the mesh alone, so the result is the same on any number of threads;
// last, the whole mesh where a cell still misses the solver's floors.
template <class Schedule>
Made run_in_slabs(TetMesh& mesh, int32_t surface_points, const std::vector<LayerBound>& layers, int32_t locked_tets,
                  const CellPassParams& params, Passes passes, const Schedule& schedule)
{
    const int64_t slabs = static_cast<int64_t>(mesh.tets.size()) / std::max<int64_t>(params.tets_per_slab, 1);
    const int count = static_cast<int>(std::clamp<int64_t>(slabs, 1, std::max(params.max_slabs, 1)));
    const auto left_over = [](const TetMesh& now) { return tets_missing_floors(now, kFloors.dihedral, kFloors.ortho); };
    Made made;
    std::mutex adding;
    improve_in_slab_rounds(mesh, surface_points, locked_tets, count, left_over, [&](Part& part, int) {
        PartPasses part_passes(part, layers, params, passes);
        PassCounts ortho, dihedral;
        schedule(part_passes, ortho, dihedral);
        part_passes.commit();
        const std::lock_guard<std::mutex> lock(adding);
        made.ortho += ortho, made.dihedral += dihedral;
        if (!part.focus) made.faces_before += part_passes.faces_before(), made.tets_before += part_passes.tets_before();
    });
    return made;
}

OrthoCounts ortho_counts(const Made& made)
{
    return {.faces_before = made.faces_before, .flips = made.ortho.flips.total(), .moves = made.ortho.moves,
            .splits = made.ortho.splits};
}

DihedralCounts dihedral_counts(const Made& made)
{
    return {.tets_before = made.tets_before, .flips = made.dihedral.flips.total(), .moves = made.dihedral.moves,
            .splits = made.dihedral.splits};
}

} // namespace

OrthoCounts improve_orthogonality(TetMesh& mesh, int32_t surface_points, double max_angle_deg, int sweeps,
                                  const std::vector<LayerBound>& layers, int32_t locked_tets)
{
    CellPassParams params;
    params.ortho_bound_deg = max_angle_deg;
    return ortho_counts(run_in_slabs(mesh, surface_points, layers, locked_tets, params, Passes::orthogonality,
                                     [&](PartPasses& passes, PassCounts& ortho, PassCounts&) {
                                         ortho += passes.orthogonality(sweeps);
                                     }));
}

DihedralCounts raise_dihedral_angles(TetMesh& mesh, int32_t surface_points, double target_deg, int sweeps,
                                     const std::vector<LayerBound>& layers, int32_t locked_tets)
{
    CellPassParams params;
    params.dihedral_target_deg = target_deg;
    return dihedral_counts(run_in_slabs(mesh, surface_points, layers, locked_tets, params, Passes::dihedral,
                                        [&](PartPasses& passes, PassCounts&, PassCounts& dihedral) {
                                            dihedral += passes.dihedral(sweeps);
                                        }));
}

CellCounts improve_cells(TetMesh& mesh, int32_t surface_points, const CellPassParams& params,
                         const std::vector<LayerBound>& layers, int32_t locked_tets)
{
    const Passes passes = params.rounds > 0 ? Passes::both : Passes::dihedral;
    const Made made = run_in_slabs(
        mesh, surface_points, layers, locked_tets, params, passes,
        [&](PartPasses& part, PassCounts& ortho, PassCounts& dihedral) {
            if (params.dihedral_first) dihedral += part.dihedral(params.dihedral_sweeps);
            // Each pass keeps what the other has reached; a change made for
            // one opens changes for the other, so the two alternate while
            // either still changes the mesh.
            for (int round = 0; round < params.rounds; ++round) {
                const PassCounts by_ortho = part.orthogonality(round == 0 ? params.first_ortho_sweeps : params.ortho_sweeps);
                const PassCounts by_dihedral = part.dihedral(params.dihedral_sweeps);
                ortho += by_ortho, dihedral += by_dihedral;
                if (by_ortho.flips.total() + by_ortho.moves + by_dihedral.changes() == 0) break;
            }
        });
    return {.dihedral = dihedral_counts(made), .ortho = ortho_counts(made)};
}

} // namespace scalemesh
