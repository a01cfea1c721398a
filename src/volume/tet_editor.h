#pragma once
// Private to the tet improvement files of src/volume (the passes of
// improve.h): the incremental tet editor every pass edits through, and the
// measures and edits more than one pass needs (a tet's orientation and
// size, OpenFOAM's face non-orthogonality and the shape of a set of tets, a
// point's move for its star's aspect ratio, an edge split's tets, marks made
// in parallel).

#include "core/adjacency.h"
#include "core/face_measures.h"
#include "core/tet_mesh.h"
#include "volume/improve.h"
#include "volume/quality.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <stdexcept>
#include <unordered_map>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace scalemesh::improvement {

// Up to N values in place: the lists of a flip (the tets around an edge, the
// new tets) have at most four, and the flips are tried for every poor tet,
// so they stay off the heap.
template <class T, int N>
class Few {
public:
    Few() = default;
    Few(std::initializer_list<T> values)
    {
        for (const T& v : values) push_back(v);
    }
    void push_back(const T& v) { items_[count_++] = v; }
    bool full() const { return count_ == N; }
    size_t size() const { return static_cast<size_t>(count_); }
    const T& operator[](size_t i) const { return items_[i]; }
    const T& front() const { return items_[0]; }
    const T& back() const { return items_[count_ - 1]; }
    const T* begin() const { return items_.data(); }
    const T* end() const { return items_.data() + count_; }

private:
    std::array<T, N> items_{};
    int count_ = 0;
};

// The centres of the cells a few tets belong to: a layer prism's three
// tets are one cell, whose centre is the prism's (its six points where they
// are now; a point the part does not hold where the passes began).
struct CellCentres {
    const PrismCells* prisms = nullptr;
    const std::vector<int32_t>* global = nullptr; // part point -> mesh point
    std::unordered_map<int32_t, int32_t> local;  // mesh point -> part point
    std::vector<char> stacked;                   // per part point: a wall node or a layer point
    // The prism whose tet x is (its index in `prisms`), or -1.
    int64_t prism_of(const Tet& x) const
    {
        if (!prisms) return -1;
        for (int32_t v : x)
            if (size_t(v) >= stacked.size() || !stacked[v]) return -1;
        return prisms->prism_of({(*global)[x[0]], (*global)[x[1]], (*global)[x[2]], (*global)[x[3]]});
    }
    // Whether tets x and y are two prisms' of which one is in the top layer.
    bool top_prisms_apart(const Tet& x, const Tet& y) const
    {
        const int64_t p = prism_of(x), q = prism_of(y);
        return p >= 0 && q >= 0 && p != q && (prisms->in_top_layer(p) || prisms->in_top_layer(q));
    }
    // The cell's key (its prism's index) and centre, when tet x is a prism's.
    template <class At>
    bool of(const Tet& x, const At& at, Vec3& centre, int64_t* key = nullptr) const
    {
        const int64_t p = prism_of(x);
        if (p < 0) return false;
        const auto position = [&](int32_t v) -> Vec3 {
            const auto it = local.find(v);
            return it != local.end() ? Vec3(at(it->second)) : prisms->start[v];
        };
        const auto& six = prisms->points[p];
        Vec3 q[6];
        for (int k = 0; k < 6; ++k) q[k] = position(six[k]);
        // Volume-weighted centroid of three tets filling the prism.
        const std::array<std::array<int, 4>, 3> split{{{0, 1, 2, 3}, {1, 2, 3, 4}, {2, 3, 4, 5}}};
        Vec3 sum{};
        double volume = 0;
        for (const auto& t : split) {
            const double v = tet_volume6(q[t[0]], q[t[1]], q[t[2]], q[t[3]]);
            sum += v * 0.25 * (q[t[0]] + q[t[1]] + q[t[2]] + q[t[3]]);
            volume += v;
        }
        centre = volume != 0 ? sum / volume : (q[0] + q[1] + q[2] + q[3] + q[4] + q[5]) / 6.0;
        if (key) *key = p;
        return true;
    }
};

// The tets as a mutable set with vertex-to-tet lists (dead entries are
// skipped and dropped lazily), enough for local flips and point moves.
class TetEditor {
public:
    const CellCentres* centres = nullptr; // cells of more than one tet, measured whole
    // The incident tets of every point as one flat table (incident_cells);
    // a point's own list is made from it the first time an edit looks at it
    // or adds a tet to it. An edit touches few of the points, so the editor
    // costs two passes over the tets instead of a heap list per point.
    // The first `locked` tets are never replaced (see replace).
    explicit TetEditor(TetMesh& mesh, int32_t locked = 0) : mesh_(mesh), tets_(mesh.tets), locked_(locked)
    {
        const size_t n = mesh.points.size();
        alive_.assign(tets_.size(), 1);
        initial_ = incident_cells(tets_, static_cast<int32_t>(n));
        incident_.resize(n);
        own_.assign(n, 0);
    }

    // Writes the living tets back to the mesh.
    void commit()
    {
        std::vector<Tet> kept;
        kept.reserve(tets_.size());
        for (size_t t = 0; t < tets_.size(); ++t)
            if (alive_[t]) kept.push_back(tets_[t]);
        mesh_.tets = std::move(kept);
        mesh_.tet_fields.clear();
    }

    size_t size() const { return tets_.size(); }
    size_t point_count() const { return mesh_.points.size(); }
    bool alive(int32_t t) const { return alive_[t] != 0; }
    bool locked(int32_t t) const { return t < locked_; }
    template <class Ids>
    bool any_locked(const Ids& ids) const
    {
        return std::any_of(ids.begin(), ids.end(), [&](int32_t t) { return locked(t); });
    }
    const Tet& tet(int32_t t) const { return tets_[t]; }
    const Vec3& point(int32_t v) const { return mesh_.points[v]; }
    Vec3& point(int32_t v) { return mesh_.points[v]; }
    // Removes the point add_point made last (before any tet uses it).
    void drop_last_point()
    {
        mesh_.points.pop_back();
        incident_.pop_back();
        own_.pop_back();
    }
    int32_t add_point(const Vec3& x)
    {
        mesh_.points.push_back(x);
        incident_.emplace_back();
        own_.push_back(1); // a new point has no tets in the flat array
        return static_cast<int32_t>(mesh_.points.size() - 1);
    }

    // Living tets at v (compacts v's list on the way).
    const std::vector<int32_t>& at(int32_t v)
    {
        auto& list = own_list(v);
        list.erase(std::remove_if(list.begin(), list.end(), [&](int32_t t) { return !alive_[t]; }), list.end());
        return list;
    }

    // The living tets at the edge (a, b), or at the face (a, b, c) when
    // c >= 0, into `out`; false when there are more than it holds.
    template <int N>
    bool tets_at(Few<int32_t, N>& out, int32_t a, int32_t b, int32_t c = -1)
    {
        for (int32_t t : at(a))
            if (contains(tets_[t], b) && (c < 0 || contains(tets_[t], c))) {
                if (out.full()) return false;
                out.push_back(t);
            }
        return true;
    }

    std::vector<int32_t> around_edge(int32_t a, int32_t b)
    {
        std::vector<int32_t> result;
        for (int32_t t : at(a))
            if (contains(tets_[t], b)) result.push_back(t);
        return result;
    }

    bool has_edge(int32_t a, int32_t b)
    {
        for (int32_t t : at(a))
            if (contains(tets_[t], b)) return true;
        return false;
    }

    bool has_face(int32_t a, int32_t b, int32_t c)
    {
        for (int32_t t : at(a))
            if (contains(tets_[t], b) && contains(tets_[t], c)) return true;
        return false;
    }

    double volume6(const Tet& t) const
    {
        return tet_volume6(point(t[0]), point(t[1]), point(t[2]), point(t[3]));
    }
    double aspect(const Tet& t) const
    {
        return tet_aspect_ratio(point(t[0]), point(t[1]), point(t[2]), point(t[3]));
    }

    // Replaces the tets `old` by `fresh` (all already positively oriented).
    // A locked tet is never among `old`: every edit checks any_locked first.
    template <class Old, class Fresh>
    void replace(const Old& old, const Fresh& fresh)
    {
        if (any_locked(old)) throw std::logic_error("TetEditor: an edit would replace a locked tet");
        for (int32_t t : old) alive_[t] = 0;
        for (const Tet& t : fresh) {
            const int32_t id = static_cast<int32_t>(tets_.size());
            tets_.push_back(t);
            alive_.push_back(1);
            for (int32_t v : t) own_list(v).push_back(id);
        }
    }

    static bool contains(const Tet& t, int32_t v) { return t[0] == v || t[1] == v || t[2] == v || t[3] == v; }

private:
    std::vector<int32_t>& own_list(int32_t v)
    {
        std::vector<int32_t>& list = incident_[v];
        if (!own_[v]) {
            own_[v] = 1;
            list.reserve(initial_.size(v) + 4);
            list.assign(initial_.begin(v), initial_.end(v));
        }
        return list;
    }

    TetMesh& mesh_;
    std::vector<Tet> tets_;
    int32_t locked_ = 0; // tets [0, locked_) are never replaced, so they keep their ids through commit
    std::vector<char> alive_;
    VertexTable initial_;                        // each point's tets when the editor was made
    std::vector<char> own_;                      // whether incident_[v] holds v's tets (else initial_ does)
    std::vector<std::vector<int32_t>> incident_;
};

// The tet (a, b, c, d) reordered to positive orientation, and its volume6
// (negative when the four points are flat to the tolerance: rejected).
inline Tet oriented(const TetEditor& ed, int32_t a, int32_t b, int32_t c, int32_t d, double& volume6)
{
    volume6 = tet_volume6(ed.point(a), ed.point(b), ed.point(c), ed.point(d));
    if (volume6 < 0) {
        volume6 = -volume6;
        return {a, c, b, d};
    }
    return {a, b, c, d};
}

template <class Tets>
double longest_edge2(const TetEditor& ed, const Tets& tets)
{
    double l2 = 0;
    for (const Tet& t : tets)
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j) l2 = std::max(l2, norm2(ed.point(t[i]) - ed.point(t[j])));
    return l2;
}

// Six times the smallest volume a new tet must clearly exceed, beyond the
// round-off of the size of the tets it replaces.
template <class Tets>
double volume_floor6(const TetEditor& ed, const Tets& tets)
{
    const double l2 = longest_edge2(ed, tets);
    return 1e-12 * l2 * std::sqrt(l2);
}

// The cosine of OpenFOAM's non-orthogonality of the face of tet t opposite
// its corner k, shared with the tet `other`: the face's normal (out of t)
// against the join of the two cells' centres, points read through at(id);
// -2 (below any cosine) when the face or the join is degenerate. A tet's
// cell is itself (its centre its centroid), or with `centres` the layer
// prism it fills (the prism's centre); 1 for two tets of one prism. The
// measure of the cell passes (cell_passes.cpp); points_missing_floors, which
// picks the cells for the passes' last round, measures tets alone.
// The centre of the cell tet t belongs to, points read through at(id):
// with `centres` the layer prism it fills (the prism's centre, its key in
// *key), else the tet itself (its centroid; *key left as it is).
template <class At>
Vec3 cell_centre(const At& at, const Tet& t, const CellCentres* centres, int64_t* key = nullptr)
{
    Vec3 centre;
    if (centres && centres->of(t, at, centre, key)) return centre;
    return 0.25 * (at(t[0]) + at(t[1]) + at(t[2]) + at(t[3]));
}

// The corner of tet t off the face it shares with `other`.
inline int corner_off(const Tet& t, const Tet& other)
{
    int k = 0;
    while (TetEditor::contains(other, t[k])) ++k;
    return k;
}

template <class At>
double face_cosine(const At& at, const Tet& t, int k, const Tet& other, const CellCentres* centres = nullptr)
{
    int64_t key_t = -1, key_o = -2;
    const Vec3 from = cell_centre(at, t, centres, &key_t), to = cell_centre(at, other, centres, &key_o);
    if (key_t == key_o) return 1.0; // two tets of one cell
    const Vec3& a = at(t[(k + 1) % 4]);
    Vec3 normal = cross(at(t[(k + 2) % 4]) - a, at(t[(k + 3) % 4]) - a);
    if (dot(normal, at(t[k]) - a) > 0) normal = -normal; // out of t
    return face_orthogonality_cosine(normal, to - from, -2);
}

// face_cosine of the face tets t and `other` share, t's corner off it found.
template <class At>
double shared_face_cosine(const At& at, const Tet& t, const Tet& other, const CellCentres* centres = nullptr)
{
    return face_cosine(at, t, corner_off(t, other), other, centres);
}

// An interior face of tets[i] (the face opposite its corner k) and the tet
// across it: tets[inside] when inside >= 0, else the living tet `outside`.
struct FaceLink {
    int i, k, inside;
    int32_t outside;
};

// The interior faces of `tets`, as if the tets with the ids `old` were
// replaced by them: a face's other tet is one of `tets` or a living tet not
// in `old`; a face with none (the boundary) is left out, as OpenFOAM checks
// internal faces only.
template <class Tets, class Old>
std::vector<FaceLink> face_links(TetEditor& ed, const Tets& tets, const Old& old)
{
    const auto has_face = [](const Tet& t, int32_t a, int32_t b, int32_t c) {
        return TetEditor::contains(t, a) && TetEditor::contains(t, b) && TetEditor::contains(t, c);
    };
    std::vector<FaceLink> links;
    for (size_t i = 0; i < tets.size(); ++i) {
        const Tet& t = tets[i];
        for (int k = 0; k < 4; ++k) {
            const int32_t a = t[(k + 1) % 4], b = t[(k + 2) % 4], d = t[(k + 3) % 4];
            FaceLink link{static_cast<int>(i), k, -1, -1};
            for (size_t j = 0; j < tets.size() && link.inside < 0; ++j)
                if (j != i && has_face(tets[j], a, b, d)) link.inside = static_cast<int>(j);
            if (link.inside < 0)
                for (int32_t u : ed.at(a))
                    if (has_face(ed.tet(u), a, b, d) && std::find(old.begin(), old.end(), u) == old.end()) {
                        link.outside = u;
                        break;
                    }
            if (link.inside >= 0 || link.outside >= 0) links.push_back(link);
        }
    }
    return links;
}

// The smallest cosine of OpenFOAM's face non-orthogonality (the angle
// between an interior face's normal and the join of its two cells'
// centres, face_cosine with the editor's `centres`) over the faces `links`
// of `tets`, with the points where they are now. -1 when a join or a face is
// degenerate. A move of a layer prism's top point is judged on the faces of
// its own tets; the faces of its prisms' other tets, whose centre it moves
// too, are left to the export's checks on the cells.
// With `enough`, the faces stop being measured once enough(worst so far)
// holds: the caller has no use for a worse cosine.
template <class Tets, class Enough = bool (*)(double)>
double worst_cosine(const TetEditor& ed, const Tets& tets, const std::vector<FaceLink>& links,
                    Enough enough = [](double) { return false; })
{
    double worst = 1;
    const auto at = [&](int32_t v) -> const Vec3& { return ed.point(v); };
    for (const FaceLink& link : links) {
        const Tet& other = link.inside >= 0 ? tets[link.inside] : ed.tet(link.outside);
        const double cosine = face_cosine(at, tets[link.i], link.k, other, ed.centres);
        if (cosine < -1.5) return -1;
        worst = std::min(worst, cosine);
        if (enough(worst)) return worst;
    }
    return worst;
}

// What a change for face non-orthogonality must keep: the smallest aspect
// ratio and dihedral angle of the tets it makes not below the floors (or
// below the old tets' own, where those already are).
struct OrthoFloors {
    double aspect = 0.1;   // dimensionless
    double dihedral = 10;  // degrees
    double ortho = 70;     // degrees: a change for the dihedral angles leaves no new face beyond it
};

// The worst of a set of tets by each measure: the smallest face cosine
// (worst_cosine), aspect ratio and dihedral angle (degrees).
struct Shape {
    double cosine = 1, aspect = 1e300, dihedral = 1e300;
};

// Tet t's aspect ratio and smallest dihedral angle taken into `s`;
// `largest` is the largest dihedral cosine taken so far: the angle is
// worked out only where a tet's cosine is larger (TetCosineMeasures).
inline void add_to_shape(Shape& s, double& largest, const TetEditor& ed, const Tet& t)
{
    const TetCosineMeasures m = tet_cosine_measures(ed.point(t[0]), ed.point(t[1]), ed.point(t[2]), ed.point(t[3]));
    s.aspect = std::min(s.aspect, m.aspect_ratio);
    if (m.dihedral_cosine > largest) {
        largest = m.dihedral_cosine;
        s.dihedral = std::min(s.dihedral, dihedral_deg(largest));
    }
}

// The worst aspect ratio and dihedral angle of `tets`, the cosine not
// measured (1): the cheap part of shape_of, which the criteria below ask
// first (the face cosines, across faces, cost the most).
template <class Tets>
Shape cell_shape(const TetEditor& ed, const Tets& tets)
{
    Shape s;
    double largest = -HUGE_VAL;
    for (size_t i = 0; i < tets.size(); ++i) add_to_shape(s, largest, ed, tets[i]);
    return s;
}

// `s`, the cell_shape of `tets`, with the worst cosine of their faces
// `links` (not measured where a tet is flat).
template <class Tets>
Shape with_cosine(Shape s, const TetEditor& ed, const Tets& tets, const std::vector<FaceLink>& links)
{
    if (s.aspect > 0) s.cosine = worst_cosine(ed, tets, links);
    return s;
}

template <class Tets>
Shape shape_of(const TetEditor& ed, const Tets& tets, const std::vector<FaceLink>& links)
{
    return with_cosine(cell_shape(ed, tets), ed, tets, links);
}

// What of ortho_better the aspect ratios and dihedral angles decide: when
// false, `after` is not better whatever the cosines.
inline bool ortho_may_beat(const Shape& before, const Shape& after, const OrthoFloors& floors)
{
    return after.aspect > 0 && after.aspect >= std::min(before.aspect, floors.aspect) &&
           after.dihedral >= std::min(before.dihedral, floors.dihedral);
}

// Whether `after` is better for orthogonality than `before` and keeps the floors.
inline bool ortho_better(const Shape& before, const Shape& after, const OrthoFloors& floors)
{
    return ortho_may_beat(before, after, floors) && after.cosine > before.cosine + 1e-9;
}

// What of dihedral_better the aspect ratios and dihedral angles decide.
inline bool dihedral_may_beat(const Shape& before, const Shape& after, const OrthoFloors& floors)
{
    return after.aspect > 0 && after.dihedral > before.dihedral + 1e-6 &&
           after.aspect >= std::min(before.aspect, floors.aspect);
}

// Whether `after` has a larger smallest dihedral angle than `before` and
// keeps the aspect-ratio floor and the non-orthogonality bound (or the old
// tets' own, where those already miss them).
inline bool dihedral_better(const Shape& before, const Shape& after, const OrthoFloors& floors)
{
    const double bound = std::cos(floors.ortho * M_PI / 180);
    return dihedral_may_beat(before, after, floors) && after.cosine >= std::min(before.cosine, bound) - 1e-12;
}

// The order of one cell pass on shapes: `better` (dihedral_better or
// ortho_better) and its cheap part `may_beat`, to ask first.
struct ShapeOrder {
    bool dihedral = false; // dihedral_better, else ortho_better
    OrthoFloors floors;

    bool may_beat(const Shape& before, const Shape& after) const
    {
        return dihedral ? dihedral_may_beat(before, after, floors) : ortho_may_beat(before, after, floors);
    }
    bool better(const Shape& before, const Shape& after) const
    {
        return dihedral ? dihedral_better(before, after, floors) : ortho_better(before, after, floors);
    }
    // Whether a worst face cosine of `cosine` already keeps a shape from
    // being better than `before`, whatever its other measures.
    bool cosine_fails(const Shape& before, double cosine) const
    {
        if (!dihedral) return !(cosine > before.cosine + 1e-9);
        const double bound = std::cos(floors.ortho * M_PI / 180);
        return !(cosine >= std::min(before.cosine, bound) - 1e-12);
    }
};

// with_cosine for a shape `s` of `tets` that only counts where
// order.better(before, it) holds: the faces are measured until their worst
// cosine rules that out (the worst only falls as faces are added). So the
// result is with_cosine's wherever order.better holds, and fails it wherever
// with_cosine's would.
template <class Tets>
Shape with_cosine_against(Shape s, const TetEditor& ed, const Tets& tets, const std::vector<FaceLink>& links,
                          const ShapeOrder& order, const Shape& before)
{
    if (s.aspect > 0)
        s.cosine = worst_cosine(ed, tets, links, [&](double worst) { return order.cosine_fails(before, worst); });
    return s;
}

// cell_shape of `tets` as far as order.may_beat(before, it) can still hold:
// the measuring stops at the first tet that rules it out (the worst of each
// measure only falls as tets are added). So the result is cell_shape's
// wherever may_beat holds, and fails may_beat wherever cell_shape's would.
template <class Tets>
Shape cell_shape_against(const TetEditor& ed, const Tets& tets, const ShapeOrder& order, const Shape& before)
{
    Shape s;
    double largest = -HUGE_VAL;
    for (size_t i = 0; i < tets.size(); ++i) {
        add_to_shape(s, largest, ed, tets[i]);
        if (!order.may_beat(before, s)) break;
    }
    return s;
}

// Marks [begin, end) by is_marked(t), in parallel: the marks are read by
// sequential loops, which then decide as if they had asked in turn.
template <class IsMarked>
std::vector<char> parallel_marks(size_t begin, size_t end, IsMarked&& is_marked)
{
    std::vector<char> marks(end - begin, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(begin, end, 1 << 13), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t t = range.begin(); t != range.end(); ++t) marks[t - begin] = is_marked(t);
    });
    return marks;
}

// Whether each tet of [begin, end) is alive with aspect ratio below `below`.
inline std::vector<char> below_marks(const TetEditor& ed, size_t begin, size_t end, double below)
{
    return parallel_marks(begin, end, [&](size_t t) {
        const auto id = static_cast<int32_t>(t);
        return ed.alive(id) && ed.aspect(ed.tet(id)) < below;
    });
}

// x, or for a layer point (slack > 0) the nearest place within its slack of
// its home: on its layer and on its node's normal; for a point held on its
// normal (on_normal), the nearest place on that segment.
Vec3 within_layer(const LayerBound& layer, const Vec3& x);

// The central-difference gradient, step h, of `measure` (of the mesh as it
// is) in the position of point v; v is put back where it was.
template <class Measure>
Vec3 point_gradient(TetEditor& ed, int32_t v, double h, Measure&& measure)
{
    const Vec3 origin = ed.point(v);
    Vec3 gradient;
    for (int axis = 0; axis < 3; ++axis) {
        Vec3 plus = origin, minus = origin;
        plus[axis] += h;
        minus[axis] -= h;
        ed.point(v) = plus;
        const double up = measure();
        ed.point(v) = minus;
        gradient[axis] = (up - measure()) / (2 * h);
    }
    ed.point(v) = origin;
    return gradient;
}

// Moves interior point v to raise the smallest aspect ratio of its star. A
// star holding a nearly flat tet (aspect ratio 1e-11 in a flat slab, where
// the layer points of two wall nodes and the nodes lie in one plane) is the
// one most in need of a move; a new position must beat the old smallest
// aspect ratio by 1e-9, so it never keeps a tet flatter than that.
bool smooth_point(TetEditor& ed, int32_t v, const LayerBound& layer = {});

// The tets of `around`, which all hold the edge (p, q), split at the point m
// on that edge: each gives one copy with p replaced by m and one with q.
std::vector<Tet> split_at(TetEditor& ed, const std::vector<int32_t>& around, int32_t p, int32_t q, int32_t m);

// The end of a split by the new point m (the point add_point made last, in
// no tet yet): without a `place` for it, m is dropped and nothing changes;
// else m goes there, `fresh` replaces the tets `around`, and m moves for
// its star's aspect ratio (smooth_point). True when m was placed.
bool place_split_point(TetEditor& ed, int32_t m, const std::optional<Vec3>& place, const std::vector<int32_t>& around,
                       const std::vector<Tet>& fresh);

} // namespace scalemesh::improvement
