#include "volume/improve.h"

#include "core/adjacency.h"
#include "volume/quality.h"
#include "volume/slabs.h"

#include <algorithm>
#include <optional>
#include <array>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <map>
#include <mutex>
#include <numeric>
#include <stdexcept>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

namespace scalemesh {
namespace {

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

// A flip replaces old tets by new ones on the same polyhedron; the criterion
// decides from their volumes, aspect ratios or face non-orthogonality
// whether it is worth it.
enum class Criterion { volume, quality, orthogonality, dihedral };

// The tets as a mutable set with vertex-to-tet lists (dead entries are
// skipped and dropped lazily), enough for local flips and point moves.
class TetEditor {
public:
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
Tet oriented(const TetEditor& ed, int32_t a, int32_t b, int32_t c, int32_t d, double& volume6)
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
// against the join of the two centroids, points read through at(id); -2
// (below any cosine) when the face or the join is degenerate. The one
// measure of the passes below and of points_missing_floors.
template <class At>
double face_cosine(const At& at, const Tet& t, int k, const Tet& other)
{
    const auto centre = [&](const Tet& x) { return 0.25 * (at(x[0]) + at(x[1]) + at(x[2]) + at(x[3])); };
    const Vec3& a = at(t[(k + 1) % 4]);
    Vec3 normal = cross(at(t[(k + 2) % 4]) - a, at(t[(k + 3) % 4]) - a);
    if (dot(normal, at(t[k]) - a) > 0) normal = -normal; // out of t
    const Vec3 join = centre(other) - centre(t);
    const double scale = norm(normal) * norm(join);
    return scale > 0 ? dot(normal, join) / scale : -2;
}

// face_cosine of the face tets t and `other` share, t's corner off it found.
template <class At>
double shared_face_cosine(const At& at, const Tet& t, const Tet& other)
{
    int k = 0;
    while (TetEditor::contains(other, t[k])) ++k;
    return face_cosine(at, t, k, other);
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
// between an interior face's normal and the join of its two tets'
// centroids, the cell centres of a tet) over the faces `links` of `tets`,
// with the points where they are now. -1 when a join or a face is degenerate.
template <class Tets>
double worst_cosine(const TetEditor& ed, const Tets& tets, const std::vector<FaceLink>& links)
{
    double worst = 1;
    const auto at = [&](int32_t v) -> const Vec3& { return ed.point(v); };
    for (const FaceLink& link : links) {
        const Tet& other = link.inside >= 0 ? tets[link.inside] : ed.tet(link.outside);
        const double cosine = face_cosine(at, tets[link.i], link.k, other);
        if (cosine < -1.5) return -1;
        worst = std::min(worst, cosine);
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

struct Shape {
    double cosine = 1, aspect = 1e300, dihedral = 1e300;
};

template <class Tets>
Shape shape_of(const TetEditor& ed, const Tets& tets, const std::vector<FaceLink>& links)
{
    Shape s;
    for (size_t i = 0; i < tets.size(); ++i) {
        const Tet& t = tets[i];
        s.aspect = std::min(s.aspect, ed.aspect(t));
        s.dihedral = std::min(s.dihedral, tet_min_dihedral_deg(ed.point(t[0]), ed.point(t[1]), ed.point(t[2]),
                                                               ed.point(t[3])));
    }
    if (!(s.aspect > 0)) return s;
    s.cosine = worst_cosine(ed, tets, links);
    return s;
}

// Whether `after` is better for orthogonality than `before` and keeps the floors.
bool ortho_better(const Shape& before, const Shape& after, const OrthoFloors& floors)
{
    return after.aspect > 0 && after.cosine > before.cosine + 1e-9 &&
           after.aspect >= std::min(before.aspect, floors.aspect) &&
           after.dihedral >= std::min(before.dihedral, floors.dihedral);
}

// Whether `after` has a larger smallest dihedral angle than `before` and
// keeps the aspect-ratio floor and the non-orthogonality bound (or the old
// tets' own, where those already miss them).
bool dihedral_better(const Shape& before, const Shape& after, const OrthoFloors& floors)
{
    const double bound = std::cos(floors.ortho * M_PI / 180);
    return after.aspect > 0 && after.dihedral > before.dihedral + 1e-6 &&
           after.aspect >= std::min(before.aspect, floors.aspect) &&
           after.cosine >= std::min(before.cosine, bound) - 1e-12;
}

class Flipper {
public:
    Flipper(TetEditor& ed, Criterion criterion, OrthoFloors floors = {})
        : ed_(ed), criterion_(criterion), floors_(floors)
    {
    }

    // Tries the flips of the edges and faces of tet t, and with `removals`
    // the removal of its edges (the quality passes, for the tet they aim
    // at: not for every tet around it); true when one was made.
    bool improve_tet(int32_t t, FlipCounts& counts, bool removals = false)
    {
        const Tet tet = ed_.tet(t);
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j)
                if (flip_edge(tet[i], tet[j], counts)) return true;
        for (int i = 0; i < 4; ++i)
            if (flip_face(tet[(i + 1) % 4], tet[(i + 2) % 4], tet[(i + 3) % 4], counts)) return true;
        if (removals && (criterion_ == Criterion::dihedral || criterion_ == Criterion::orthogonality))
            for (int i = 0; i < 4; ++i)
                for (int j = i + 1; j < 4; ++j)
                    if (remove_edge(tet[i], tet[j], counts)) return true;
        return false;
    }

private:
    static constexpr int kMaxRing = 7;                 // edge removal up to seven tets around the edge
    using Tets = Few<Tet, 4>;
    using Volumes = std::array<double, 4>;
    using Ring = Few<int32_t, kMaxRing>;
    using RingTets = Few<Tet, 2 * (kMaxRing - 2)>;    // a ring of m triangulated: 2 (m - 2) tets
    using RingVolumes = std::array<double, 2 * (kMaxRing - 2)>;

    // Whether replacing `old` by `fresh` is worth it; the new tets must all
    // be clearly positive (beyond round-off of their size).
    template <class Old, class Fresh, class Volumes6>
    bool accept(const Old& old, const Fresh& fresh, const Volumes6& fresh6)
    {
        Few<Tet, kMaxRing> old_tets;
        for (int32_t t : old) old_tets.push_back(ed_.tet(t));
        const double floor6 = volume_floor6(ed_, old_tets);
        double new_min = 1e300;
        for (size_t k = 0; k < fresh.size(); ++k) new_min = std::min(new_min, fresh6[k]);
        if (!(new_min > floor6)) return false;
        if (criterion_ == Criterion::volume) {
            double old_min = 1e300;
            for (const Tet& t : old_tets) old_min = std::min(old_min, ed_.volume6(t));
            return new_min > 3.0 * old_min;
        }
        if (criterion_ == Criterion::dihedral)
            return dihedral_better(shape_of(ed_, old_tets, face_links(ed_, old_tets, old)),
                                   shape_of(ed_, fresh, face_links(ed_, fresh, old)), floors_);
        if (criterion_ == Criterion::orthogonality)
            return ortho_better(shape_of(ed_, old_tets, face_links(ed_, old_tets, old)),
                                shape_of(ed_, fresh, face_links(ed_, fresh, old)), floors_);
        double old_q = 1e300, new_q = 1e300;
        for (const Tet& t : old_tets) old_q = std::min(old_q, ed_.aspect(t));
        for (const Tet& t : fresh) new_q = std::min(new_q, ed_.aspect(t));
        return new_q > old_q + 1e-6;
    }

    // The ring of the edge (a, b): c_0 .. c_{k-1} with (a, b, c_i, c_{i+1})
    // positive. Empty when the tets around the edge do not close (a surface edge).
    template <class Around>
    Ring ring(int32_t a, int32_t b, const Around& around)
    {
        Few<std::pair<int32_t, int32_t>, kMaxRing> next;
        for (int32_t t : around) {
            int32_t other[2], k = 0;
            for (int32_t v : ed_.tet(t))
                if (v != a && v != b) other[k++] = v;
            if (tet_volume6(ed_.point(a), ed_.point(b), ed_.point(other[0]), ed_.point(other[1])) < 0)
                std::swap(other[0], other[1]);
            next.push_back({other[0], other[1]});
        }
        Ring cycle{next[0].first};
        for (size_t step = 0; step < next.size(); ++step) {
            const int32_t from = cycle.back();
            int32_t to = -1, hits = 0;
            for (const auto& [x, y] : next)
                if (x == from) to = y, ++hits;
            if (hits != 1) return {};
            if (step + 1 == next.size()) return to == cycle.front() ? cycle : Ring{};
            cycle.push_back(to);
        }
        return {};
    }

    bool flip_edge(int32_t a, int32_t b, FlipCounts& counts)
    {
        // The tets around the edge, when there are three or four.
        Few<int32_t, 4> around;
        if (!ed_.tets_at(around, a, b) || (around.size() != 3 && around.size() != 4) || ed_.any_locked(around))
            return false;
        const Ring c = ring(a, b, around);
        if (c.size() != around.size()) return false;
        if (c.size() == 3) {
            if (ed_.has_face(c[0], c[1], c[2])) return false;
            Volumes v6{};
            const Tets fresh{oriented(ed_, c[0], c[1], c[2], a, v6[0]), oriented(ed_, c[0], c[1], c[2], b, v6[1])};
            // a and b must lie on opposite sides of (c0, c1, c2).
            if (fresh[0][1] == fresh[1][1]) return false;
            if (!accept(around, fresh, v6)) return false;
            ed_.replace(around, fresh);
            ++counts.flips_32;
            return true;
        }
        for (int s = 0; s < 2; ++s) {
            const int32_t p = c[s], q = c[s + 1], r = c[s + 2], w = c[(s + 3) % 4];
            if (ed_.has_edge(p, r)) continue;
            Volumes v6{};
            const Tets fresh{oriented(ed_, p, q, r, a, v6[0]), oriented(ed_, p, r, w, a, v6[1]),
                             oriented(ed_, p, q, r, b, v6[2]), oriented(ed_, p, r, w, b, v6[3])};
            // Consistent sides: both a-tets on one side, both b-tets on the other.
            const bool a1 = fresh[0][1] == q, a2 = fresh[1][1] == r, b1 = fresh[2][1] == q, b2 = fresh[3][1] == r;
            if (a1 != a2 || b1 != b2 || a1 == b1) continue;
            if (!accept(around, fresh, v6)) continue;
            ed_.replace(around, fresh);
            ++counts.flips_44;
            return true;
        }
        return false;
    }

    // Edge removal (Shewchuk, "Two discrete optimization algorithms for the
    // topological improvement of tetrahedral meshes", 2002) of an interior
    // edge (a, b) with five to seven tets around it: its ring is
    // triangulated every way (5, 14 or 42 ways), each triangle joined to a
    // and to b, and the best triangulation the criterion accepts replaces
    // the tets. Only the quality passes use it; the paper's flip pass keeps
    // its three flips.
    bool remove_edge(int32_t a, int32_t b, FlipCounts& counts)
    {
        Few<int32_t, kMaxRing> around;
        if (!ed_.tets_at(around, a, b) || around.size() < 5 || ed_.any_locked(around)) return false;
        const Ring c = ring(a, b, around);
        if (c.size() != around.size()) return false;
        const int m = static_cast<int>(c.size());
        Few<Tet, kMaxRing> old_tets;
        for (int32_t t : around) old_tets.push_back(ed_.tet(t));
        const Shape before = shape_of(ed_, old_tets, face_links(ed_, old_tets, around));
        const double floor6 = volume_floor6(ed_, old_tets);
        Shape best = before;
        RingTets chosen;
        bool found = false;
        for (const auto& triangles : polygon_triangulations(m)) {
            bool usable = true;
            for (const auto& [i, j, k] : triangles)
                for (const auto& [p, q] : {std::pair{i, j}, std::pair{j, k}, std::pair{i, k}})
                    if (q - p > 1 && !(p == 0 && q == m - 1) && ed_.has_edge(c[p], c[q])) usable = false;
            if (!usable) continue;
            RingTets fresh;
            RingVolumes v6{};
            // (c_i, c_j, c_k) with i < j < k turns as the ring does: a on one
            // side, b on the other, the same for every triangle.
            for (const auto& [i, j, k] : triangles) {
                const Tet ta = oriented(ed_, c[i], c[j], c[k], a, v6[fresh.size()]);
                usable = usable && ta[1] == c[k];
                fresh.push_back(ta);
                const Tet tb = oriented(ed_, c[i], c[j], c[k], b, v6[fresh.size()]);
                usable = usable && tb[1] == c[j];
                fresh.push_back(tb);
            }
            if (!usable) continue;
            // The cheap tests first: volumes, aspect ratios, dihedral angles;
            // the face links (for the non-orthogonality) only then.
            double smallest6 = 1e300, aspect = 1e300, dihedral = 1e300;
            for (size_t k = 0; k < fresh.size(); ++k) {
                const Tet& t = fresh[k];
                smallest6 = std::min(smallest6, v6[k]);
                aspect = std::min(aspect, ed_.aspect(t));
                dihedral = std::min(dihedral, tet_min_dihedral_deg(ed_.point(t[0]), ed_.point(t[1]), ed_.point(t[2]),
                                                                   ed_.point(t[3])));
            }
            if (!(smallest6 > floor6) || aspect < std::min(before.aspect, floors_.aspect)) continue;
            if (criterion_ == Criterion::dihedral && !(dihedral > best.dihedral + 1e-6)) continue;
            if (criterion_ == Criterion::orthogonality && dihedral < std::min(before.dihedral, floors_.dihedral)) continue;
            const Shape now = shape_of(ed_, fresh, face_links(ed_, fresh, around));
            if (criterion_ == Criterion::dihedral ? dihedral_better(best, now, floors_) : ortho_better(best, now, floors_))
                best = now, chosen = fresh, found = true;
        }
        if (!found) return false;
        ed_.replace(around, chosen);
        ++counts.edge_removals;
        return true;
    }

    // Every triangulation of a convex polygon of m corners (3 to kMaxRing),
    // as triangles (i, j, k) of corner indices with i < j < k.
    static const std::vector<std::vector<std::array<int, 3>>>& polygon_triangulations(int m)
    {
        static const auto table = [] {
            std::vector<std::vector<std::vector<std::array<int, 3>>>> all(kMaxRing + 1);
            // The triangulations of the sub-polygon i..j (j - i >= 2): the
            // triangle on the edge (i, j) has apex l, the rest recurses.
            std::function<std::vector<std::vector<std::array<int, 3>>>(int, int)> of = [&](int i, int j) {
                std::vector<std::vector<std::array<int, 3>>> out;
                if (j - i < 2) return std::vector<std::vector<std::array<int, 3>>>{{}};
                for (int l = i + 1; l < j; ++l)
                    for (const auto& left : of(i, l))
                        for (const auto& right : of(l, j)) {
                            auto t = left;
                            t.insert(t.end(), right.begin(), right.end());
                            t.push_back({i, l, j});
                            out.push_back(std::move(t));
                        }
                return out;
            };
            for (int n = 3; n <= kMaxRing; ++n) all[n] = of(0, n - 1);
            return all;
        }();
        return table[m];
    }

    bool flip_face(int32_t a, int32_t b, int32_t c, FlipCounts& counts)
    {
        Few<int32_t, 2> two;
        if (!ed_.tets_at(two, a, b, c) || two.size() != 2) return false; // a surface face has one tet
        if (ed_.any_locked(two)) return false;
        int32_t d = -1, e = -1;
        for (int32_t v : ed_.tet(two[0]))
            if (v != a && v != b && v != c) d = v;
        for (int32_t v : ed_.tet(two[1]))
            if (v != a && v != b && v != c) e = v;
        if (ed_.has_edge(d, e)) return false;
        Volumes v6{};
        const Tets fresh{oriented(ed_, d, e, a, b, v6[0]), oriented(ed_, d, e, b, c, v6[1]),
                         oriented(ed_, d, e, c, a, v6[2])};
        // The segment (d, e) must cross the triangle: the three new tets turn the same way around it.
        const bool s0 = fresh[0][1] == e, s1 = fresh[1][1] == e, s2 = fresh[2][1] == e;
        if (s0 != s1 || s1 != s2) return false;
        if (!accept(two, fresh, v6)) return false;
        ed_.replace(two, fresh);
        ++counts.flips_23;
        return true;
    }

    TetEditor& ed_;
    Criterion criterion_;
    OrthoFloors floors_;
};

// Smallest aspect ratio over the tets at v (not above 0 when one is flat or
// inverted, or NaN).
double star_quality(TetEditor& ed, int32_t v)
{
    double q = 1e300;
    for (int32_t t : ed.at(v)) {
        const double a = ed.aspect(ed.tet(t));
        if (!(a > 0)) return 0;
        q = std::min(q, a);
    }
    return q;
}

// x, or for a layer point (slack > 0) the nearest place within its slack of
// its home: on its layer and on its node's normal; for a point held on its
// normal (on_normal), the nearest place on that segment.
Vec3 within_layer(const LayerBound& layer, const Vec3& x)
{
    if (!(layer.slack > 0)) return x;
    if (layer.on_normal)
        return layer.home + std::clamp(dot(x - layer.home, layer.normal), -layer.slack, layer.slack) * layer.normal;
    const Vec3 away = x - layer.home;
    const double length = norm(away);
    return length <= layer.slack ? x : layer.home + (layer.slack / length) * away;
}

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

// Moves interior point v to raise the smallest aspect ratio of its star. A
// star holding a nearly flat tet (aspect ratio 1e-11 in a flat slab, where
// the layer points of two wall nodes and the nodes lie in one plane) is the
// one most in need of a move; a new position must beat the old smallest
// aspect ratio by 1e-9, so it never keeps a tet flatter than that.
bool smooth_point(TetEditor& ed, int32_t v, const LayerBound& layer = {})
{
    const double start = star_quality(ed, v);
    if (!(start > 0)) return false;
    const Vec3 origin = ed.point(v);
    int32_t worst = -1;
    double worst_q = 1e300, mean_length = 0;
    int edges = 0;
    for (int32_t t : ed.at(v)) {
        const double q = ed.aspect(ed.tet(t));
        if (q < worst_q) worst_q = q, worst = t;
        for (int32_t w : ed.tet(t))
            if (w != v) mean_length += distance(origin, ed.point(w)), ++edges;
    }
    if (worst < 0 || edges == 0) return false;
    mean_length /= edges;

    // Central differences of the worst tet's aspect ratio.
    const Vec3 gradient = point_gradient(ed, v, 1e-4 * mean_length, [&] { return ed.aspect(ed.tet(worst)); });
    // A layer point stays within its slack of its place.
    auto in_plane = [&](const Vec3& x) { return within_layer(layer, x); };
    Few<Vec3, 8> candidates;
    const Vec3 direction = normalized(gradient);
    if (norm2(direction) > 0)
        for (double step : {0.2, 0.1, 0.05, 0.025, 0.0125, 0.006})
            candidates.push_back(in_plane(origin + step * mean_length * direction));
    Vec3 centroid;
    int count = 0;
    for (int32_t t : ed.at(v))
        for (int32_t w : ed.tet(t))
            if (w != v) centroid += ed.point(w), ++count;
    centroid /= count;
    candidates.push_back(in_plane(centroid));
    candidates.push_back(in_plane(0.5 * (origin + centroid)));

    double best = start;
    Vec3 best_position = origin;
    for (const Vec3& x : candidates) {
        ed.point(v) = x;
        const double q = star_quality(ed, v);
        if (q > best + 1e-9) best = q, best_position = x;
    }
    ed.point(v) = best_position;
    return !(best_position == origin);
}

// Edge removal for a quad repair: triangulates the polygon `ring` (open
// chain from ring.front() to ring.back(), closed by that pair) so that every
// triangle t gives positive tets (b, t) with orientation `sign` and (d, t)
// with the opposite one, maximising the smallest aspect ratio (dynamic
// programming over sub-polygons, cubic in the ring length). Diagonals that
// already are mesh edges are not used. Returns that smallest aspect ratio,
// or 0 when no triangulation qualifies; `out` gets the tets.
double triangulate_ring(TetEditor& ed, const std::vector<int32_t>& ring, int32_t b, int32_t d, int sign, double floor6,
                        std::vector<Tet>& out)
{
    const int m = static_cast<int>(ring.size());
    auto cone = [&](int32_t tip, int i, int l, int j, int want, Tet& tet) {
        double v6 = 0;
        tet = oriented(ed, tip, ring[i], ring[l], ring[j], v6);
        const int s = tet[1] == ring[i] ? 1 : -1;
        if (s != want || !(v6 > floor6)) return 0.0;
        return ed.aspect(tet);
    };
    std::vector<char> usable(m * m, 1); // diagonal (i, j) not already an edge
    for (int i = 0; i < m; ++i)
        for (int j = i + 2; j < m; ++j)
            if (!(i == 0 && j == m - 1)) usable[i * m + j] = !ed.has_edge(ring[i], ring[j]);
    std::vector<double> best(m * m, 0.0);
    std::vector<int> split(m * m, -1);
    for (int i = 0; i + 1 < m; ++i) best[i * m + i + 1] = 1e300;
    for (int len = 2; len < m; ++len)
        for (int i = 0; i + len < m; ++i) {
            const int j = i + len;
            if (!usable[i * m + j]) continue;
            for (int l = i + 1; l < j; ++l) {
                const double inner = std::min(best[i * m + l], best[l * m + j]);
                if (!(inner > best[i * m + j])) continue;
                Tet tb, td;
                const double q = std::min({inner, cone(b, i, l, j, sign, tb), cone(d, i, l, j, -sign, td)});
                if (q > best[i * m + j]) best[i * m + j] = q, split[i * m + j] = l;
            }
        }
    if (!(best[m - 1] > 0)) return 0.0;
    out.clear();
    std::vector<std::pair<int, int>> stack{{0, m - 1}};
    while (!stack.empty()) {
        const auto [i, j] = stack.back();
        stack.pop_back();
        if (j - i < 2) continue;
        const int l = split[i * m + j];
        Tet tet;
        cone(b, i, l, j, sign, tet);
        out.push_back(tet);
        cone(d, i, l, j, -sign, tet);
        out.push_back(tet);
        stack.push_back({i, l});
        stack.push_back({l, j});
    }
    return best[m - 1];
}

// The tets of `around`, which all hold the edge (p, q), split at the point m
// on that edge: each gives one copy with p replaced by m and one with q.
std::vector<Tet> split_at(TetEditor& ed, const std::vector<int32_t>& around, int32_t p, int32_t q, int32_t m)
{
    std::vector<Tet> out;
    out.reserve(2 * around.size());
    for (int32_t t : around) {
        Tet x = ed.tet(t), y = ed.tet(t);
        for (int i = 0; i < 4; ++i) {
            if (x[i] == p) x[i] = m;
            if (y[i] == q) y[i] = m;
        }
        out.push_back(x);
        out.push_back(y);
    }
    return out;
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
    Vec3 best_position;
    bool found = false;
    for (double w : {0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6}) {
        ed.point(m) = (1 - w) * mid + w * centroid;
        double worst = 1e300;
        for (const Tet& t : fresh) worst = std::min(worst, ed.aspect(t));
        if (worst > best + 1e-9) best = worst, best_position = ed.point(m), found = true;
    }
    if (!found) {
        ed.drop_last_point();
        return false;
    }
    ed.point(m) = best_position;
    ed.replace(around, fresh);
    smooth_point(ed, m);
    return true;
}

// The fallback of a quad repair: a new interior point m below the middle of
// the stand-in diagonal (b, d) splits every tet (b, d, x, y) at it into
// (m, d, x, y) and (b, m, x, y), and the two tets (a, c, b, m), (a, d, c, m)
// put the quad's own triangles on the boundary. m is taken where the
// smallest aspect ratio of all these tets is best; false (nothing changed)
// when none keeps them all positive.
bool split_quad_diagonal(TetEditor& ed, int32_t a, int32_t b, int32_t c, int32_t d,
                         const std::vector<int32_t>& around)
{
    const Vec3 mid = 0.5 * (ed.point(b) + ed.point(d));
    const Vec3 outward = cross(ed.point(b) - ed.point(a), ed.point(c) - ed.point(a)) +
                         cross(ed.point(c) - ed.point(a), ed.point(d) - ed.point(a));
    if (!(norm2(outward) > 0)) return false;
    const Vec3 inward = -normalized(outward);
    const double length = distance(ed.point(b), ed.point(d));
    const int32_t m = ed.add_point(mid);
    std::vector<Tet> fresh = split_at(ed, around, b, d, m);
    fresh.push_back({a, c, b, m});
    fresh.push_back({a, d, c, m});
    double best = 0;
    Vec3 best_position;
    for (double depth : {0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5}) {
        ed.point(m) = mid + depth * length * inward;
        double worst = 1e300;
        for (const Tet& t : fresh) worst = std::min(worst, ed.aspect(t));
        if (worst > best) best = worst, best_position = ed.point(m);
    }
    if (!(best > 1e-6)) {
        ed.drop_last_point();
        return false;
    }
    ed.point(m) = best_position;
    ed.replace(around, fresh);
    smooth_point(ed, m);
    return true;
}

} // namespace

std::vector<int32_t> repair_surface_quads(TetMesh& mesh, const std::vector<std::array<int32_t, 4>>& quads)
{
    std::vector<int32_t> failed;
    if (quads.empty()) return failed;
    TetEditor ed(mesh);
    for (size_t qi = 0; qi < quads.size(); ++qi) {
        const auto [a, b, c, d] = quads[qi];
        const std::vector<int32_t> around = ed.around_edge(b, d);
        // The chain a = r_0, r_1, ..., r_{k+1} = c of the tets at (b, d).
        std::vector<int32_t> chain{a};
        std::vector<char> used(around.size(), 0);
        bool ok = !ed.has_edge(a, c);
        while (ok && chain.back() != c) {
            ok = false;
            for (size_t t = 0; t < around.size(); ++t) {
                const int32_t from = chain.back();
                if (used[t] || !TetEditor::contains(ed.tet(around[t]), from)) continue;
                for (int32_t v : ed.tet(around[t]))
                    if (v != b && v != d && v != from) chain.push_back(v);
                used[t] = 1;
                ok = true;
                break;
            }
        }
        ok = ok && chain.size() >= 3 && std::count(used.begin(), used.end(), 1) == int64_t(around.size());
        // The polygon a, r_1, ..., r_k, c (closed by c -> a) is triangulated
        // (edge removal by dynamic programming over its sub-polygons) so that
        // the cones from b and d over its triangles are all clearly positive,
        // b and d on opposite sides, with the best smallest aspect ratio.
        std::vector<Tet> fresh;
        if (ok) {
            std::vector<Tet> old;
            for (int32_t t : around) old.push_back(ed.tet(t));
            const double floor6 = volume_floor6(ed, old);
            ok = false;
            double best = 0;
            for (int sign : {1, -1}) {
                std::vector<Tet> candidate;
                const double q = triangulate_ring(ed, chain, b, d, sign, floor6, candidate);
                if (q > best) best = q, fresh = std::move(candidate), ok = true;
            }
        }
        if (!ok && !split_quad_diagonal(ed, a, b, c, d, around)) {
            failed.push_back(static_cast<int32_t>(qi));
            continue;
        }
        if (ok) ed.replace(around, fresh);
    }
    ed.commit();
    return failed;
}

namespace {

Vec3 unit_normal(const std::vector<Vec3>& points, const Triangle& f)
{
    const Vec3 n = cross(points[f[1]] - points[f[0]], points[f[2]] - points[f[0]]);
    return norm2(n) > 0 ? normalized(n) : Vec3{};
}

// The no-fold rule of a flip of the surface: the new pair of triangles'
// normals within 60 degrees of each other and of the old pair's.
bool flip_folds_little(const std::vector<Vec3>& points, const Triangle& old1, const Triangle& old2,
                       const Triangle& new1, const Triangle& new2)
{
    constexpr double kCos60 = 0.5;
    const Vec3 n1 = unit_normal(points, new1), n2 = unit_normal(points, new2);
    const Vec3 both = unit_normal(points, old1) + unit_normal(points, old2);
    const double reach = kCos60 * norm(both);
    return dot(n1, n2) > kCos60 && dot(n1, both) > reach && dot(n2, both) > reach;
}

} // namespace

bool surface_flip_allowed(const SurfaceMesh& surface, const std::array<int32_t, 4>& quad,
                          const std::array<int32_t, 2>& ids, const EdgeSet& edges)
{
    const auto patch = [&](int32_t t) { return surface.triangle_patch.empty() ? 0 : surface.triangle_patch[t]; };
    const auto [a, b, c, d] = quad;
    if (edges.count(edge_key(b, d)) || patch(ids[0]) != patch(ids[1])) return false;
    return flip_folds_little(surface.points, {a, b, c}, {a, c, d}, {a, b, d}, {b, c, d});
}

int64_t peel_surface_caps(TetMesh& mesh, int32_t surface_points, double threshold)
{
    const std::vector<Vec3>& p = mesh.points;
    std::vector<size_t> caps;
    std::vector<char> involved(mesh.points.size(), 0); // boundary faces may hold any point
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
        const Tet& tet = mesh.tets[t];
        if (*std::max_element(tet.begin(), tet.end()) >= surface_points ||
            !(tet_aspect_ratio(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]]) < threshold))
            continue;
        caps.push_back(t);
        for (int32_t v : tet) involved[v] = 1;
    }
    if (caps.empty()) return 0;

    // The boundary faces and edges among the candidates' points.
    const auto key = [](Triangle f) {
        std::sort(f.begin(), f.end());
        return f;
    };
    std::map<Triangle, int32_t> face_id;
    EdgeSet edges;
    for (size_t f = 0; f < mesh.boundary_faces.size(); ++f) {
        const Triangle& tri = mesh.boundary_faces[f];
        if (involved[tri[0]] && involved[tri[1]] && involved[tri[2]]) face_id[key(tri)] = static_cast<int32_t>(f);
        for (int i = 0; i < 3; ++i)
            if (involved[tri[i]] && involved[tri[(i + 1) % 3]]) edges.insert(edge_key(tri[i], tri[(i + 1) % 3]));
    }
    const auto patch = [&](int32_t f) { return mesh.boundary_patch.empty() ? 0 : mesh.boundary_patch[f]; };
    std::vector<char> peeled(mesh.tets.size(), 0);
    int64_t count = 0;
    for (size_t t : caps) {
        const Tet tet = mesh.tets[t];
        // The face opposite each point, counter-clockwise seen from outside the tet.
        const Triangle face[4] = {{tet[1], tet[2], tet[3]}, {tet[0], tet[3], tet[2]}, {tet[0], tet[1], tet[3]},
                                  {tet[0], tet[2], tet[1]}};
        std::array<int32_t, 4> id{};
        std::vector<int> on, off;
        for (int i = 0; i < 4; ++i) {
            const auto it = face_id.find(key(face[i]));
            id[i] = it == face_id.end() ? -1 : it->second;
            (id[i] >= 0 ? on : off).push_back(i);
        }
        if (on.size() != 2) continue;
        // The boundary faces opposite i and j share the edge (k, l); the
        // faces opposite k and l, seen from the tets beyond them, replace them.
        const int i = on[0], j = on[1], k = off[0], l = off[1];
        const Triangle new_k{face[k][0], face[k][2], face[k][1]}, new_l{face[l][0], face[l][2], face[l][1]};
        if (edges.count(edge_key(tet[i], tet[j])) || patch(id[i]) != patch(id[j]) ||
            !flip_folds_little(p, face[i], face[j], new_k, new_l))
            continue;
        mesh.boundary_faces[id[i]] = new_k;
        mesh.boundary_faces[id[j]] = new_l;
        face_id.erase(key(face[i]));
        face_id.erase(key(face[j]));
        face_id[key(new_k)] = id[i];
        face_id[key(new_l)] = id[j];
        edges.erase(edge_key(tet[k], tet[l]));
        edges.insert(edge_key(tet[i], tet[j]));
        peeled[t] = 1;
        ++count;
    }
    size_t kept = 0;
    for (size_t t = 0; t < mesh.tets.size(); ++t)
        if (!peeled[t]) mesh.tets[kept++] = mesh.tets[t];
    mesh.tets.resize(kept);
    return count;
}

std::vector<int32_t> flip_surface_quads(const SurfaceMesh& surface, const std::vector<std::array<int32_t, 4>>& quads,
                                        const std::vector<std::array<int32_t, 2>>& quad_triangles,
                                        const std::vector<int32_t>& which, std::vector<Triangle>& triangles)
{
    std::vector<int32_t> left;
    if (which.empty()) return left;
    EdgeSet edges = edge_set(triangles);
    for (int32_t q : which) {
        const auto [a, b, c, d] = quads[q];
        if (!surface_flip_allowed(surface, quads[q], quad_triangles[q], edges)) {
            left.push_back(q);
            continue;
        }
        triangles[quad_triangles[q][0]] = {a, b, d};
        triangles[quad_triangles[q][1]] = {b, c, d};
        edges.erase(edge_key(a, c));
        edges.insert(edge_key(b, d));
    }
    return left;
}

namespace {

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
std::vector<char> below_marks(const TetEditor& ed, size_t begin, size_t end, double below)
{
    return parallel_marks(begin, end, [&](size_t t) {
        const auto id = static_cast<int32_t>(t);
        return ed.alive(id) && ed.aspect(ed.tet(id)) < below;
    });
}

// Improvement in parallel. The mesh is cut into parts, each a mesh of its
// own (its tets, with point ids of its own), improved at once, then put
// back. In a part, a flip takes only an edge whose tets close around it or
// a face with two tets (as at the surface), and only a point whose whole
// star is in the part moves (pinned otherwise), so parts touch no tet and
// no moving point of one another and every move and flip is one the whole
// mesh could make. What a part cannot do is left to a second pass over the
// tets near the cuts, made a part too.
struct Part {
    TetMesh mesh;                // the part's points and tets, its own ids
    std::vector<int32_t> global; // part point -> mesh point
    std::vector<char> pinned;    // part point: a surface point, or one with a tet outside the part
};

// How many slabs: one per 100k tets, up to 4. It depends on the mesh
// alone, so the result is the same on any number of threads.
int slab_count(const TetMesh& mesh)
{
    return static_cast<int>(std::clamp<size_t>(mesh.tets.size() / 100000, 1, 4));
}

// Runs improve(part, r) on parts 0 .. count - 1 at once, part r made of the
// tets t with part_of[t] == r (-1: in none), then puts the parts' tets and
// points back: the tets of no part first, in order, then each part's.
template <class Improve>
void improve_in_parts(TetMesh& mesh, int32_t surface_points, const std::vector<int32_t>& part_of, int count,
                      Improve&& improve)
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

// Improves the mesh in slabs at once, then the tets near the cuts: those
// with at least `cut_points` points of a tet across slabs. A flip a slab
// could not make has an edge of such a tet (two such points), a move it
// could not make such a point (one). With poor_below > 0, the points of the
// tets still below it after the slabs count as such points too: the second
// pass then holds their whole stars, so each of them may move there.
template <class Improve>
void improve_in_slabs(TetMesh& mesh, int32_t surface_points, int cut_points, double poor_below, Improve&& improve)
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

FlipCounts flip_sweeps(TetMesh& mesh, int sweeps)
{
    // The first sweep visits every tet; each later one only the tets the
    // previous sweep made, since a flip changes the rings of the edges and
    // faces of its new tets only. A flip the volume criterion accepts has
    // an old tet at least three times smaller than the new ones: in practice
    // a sliver or a needle, so the search starts from the tets with aspect
    // ratio below kSearchBelow only (the well-shaped majority is skipped).
    // No point moves, so a tet's shape, marked before the sweep, holds.
    constexpr double kSearchBelow = 0.3;
    FlipCounts counts;
    TetEditor ed(mesh);
    Flipper flipper(ed, Criterion::volume);
    size_t begin = 0;
    for (int sweep = 0; sweep < sweeps; ++sweep) {
        const size_t end = ed.size();
        if (begin == end) break;
        const std::vector<char> search = below_marks(ed, begin, end, kSearchBelow);
        for (size_t t = begin; t < end; ++t) {
            const int32_t id = static_cast<int32_t>(t);
            if (search[t - begin] && ed.alive(id)) flipper.improve_tet(id, counts);
        }
        begin = end;
    }
    ed.commit();
    return counts;
}

FlipCounts operator+(FlipCounts a, const FlipCounts& b)
{
    return {a.flips_32 + b.flips_32, a.flips_23 + b.flips_23, a.flips_44 + b.flips_44,
            a.edge_removals + b.edge_removals};
}

} // namespace

FlipCounts flip_volume_criterion(TetMesh& mesh, int sweeps)
{
    FlipCounts counts;
    std::mutex adding;
    improve_in_slabs(mesh, 0, 2, 0.0, [&](Part& part, int) {
        const FlipCounts made = flip_sweeps(part.mesh, sweeps);
        const std::lock_guard<std::mutex> lock(adding);
        counts = counts + made;
    });
    return counts;
}

namespace {

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

namespace {

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

// The edge split for a face beyond the floor whose tets have no point that
// may move: where the worst face of the new tets is best (ortho_better, so
// the floors hold); then m is moved as any free point.
bool split_edge_for_orthogonality(TetEditor& ed, int32_t q, int32_t s, const OrthoFloors& floors)
{
    const int32_t m =
        split_edge_where_better(ed, q, s, [&](const Shape& a, const Shape& b) { return ortho_better(a, b, floors); });
    if (m < 0) return false;
    orthogonalize_point(ed, m, {}, floors);
    return true;
}

} // namespace

OrthoCounts improve_orthogonality(TetMesh& mesh, int32_t surface_points, double max_angle_deg, int sweeps,
                                  const std::vector<LayerBound>& layers, int32_t locked_tets)
{
    OrthoCounts counts;
    const double bound = std::cos(max_angle_deg * M_PI / 180);
    TetEditor ed(mesh, locked_tets);
    const OrthoFloors floors;
    Flipper flipper(ed, Criterion::orthogonality, floors);
    FlipCounts flips;
    // A layer point already outside its ball (sliver removal freed it where
    // the mesh was poor) stays where it is.
    std::vector<char> pinned(ed.point_count(), 0);
    for (size_t v = 0; v < pinned.size(); ++v) {
        const bool layer = v < layers.size() && layers[v].slack > 0;
        pinned[v] = int32_t(v) < surface_points || (v < layers.size() && layers[v].fixed) ||
                    (layer && distance(ed.point(int32_t(v)), layers[v].home) > layers[v].slack);
    }
    const auto at = [&](int32_t v) -> const Vec3& { return ed.point(v); };
    // A face between two locked tets (inside a layer prism) is not looked at.
    const auto face_cosine = [&](int32_t t, int32_t u) {
        return ed.locked(t) && ed.locked(u) ? 1.0 : shared_face_cosine(at, ed.tet(t), ed.tet(u));
    };
    // The interior faces beyond the bound, each as (t, k, u): the face
    // opposite corner k of tet t, u the tet across, t < u; in (t, k) order,
    // as a scan of every tet's faces finds them. The first sweep scans every
    // tet; a later one only the tets whose faces can have changed since: the
    // tets made since (ids from `seen` on), those at the points moved since,
    // and the tets of the faces found beyond the bound then. Any other face
    // has the same two tets at the same places, so the same verdict.
    struct BadFace {
        int32_t t, k, u;
    };
    const auto face_order = [](const BadFace& a, const BadFace& b) { return a.t != b.t ? a.t < b.t : a.k < b.k; };
    std::vector<BadFace> bad;
    std::vector<int32_t> moved;
    size_t seen = 0;
    const auto scan = [&] {
        std::vector<int32_t> visit;
        if (seen == 0) {
            // The editor is fresh (every tet alive, ids as in the mesh): the
            // faces from the mesh's adjacency, their angles in parallel
            // (reading only), then in (t, k) order.
            seen = ed.size();
            const TetFaceAdjacency adjacency = tet_face_adjacency(mesh);
            tbb::enumerable_thread_specific<std::vector<BadFace>> local;
            tbb::parallel_for(tbb::blocked_range<size_t>(0, ed.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
                std::vector<BadFace>& out = local.local();
                for (size_t i = r.begin(); i != r.end(); ++i)
                    for (int k = 0; k < 4; ++k) {
                        const int32_t t = int32_t(i), u = adjacency.across[4 * i + k];
                        if (u > t && face_cosine(t, u) < bound) out.push_back({t, k, u});
                    }
            });
            bad.clear();
            for (const auto& part : local) bad.insert(bad.end(), part.begin(), part.end());
            std::sort(bad.begin(), bad.end(), face_order);
            return;
        }
        for (const BadFace& f : bad)
            for (int32_t t : {f.t, f.u})
                if (ed.alive(t)) visit.push_back(t);
        visit = changed_since(ed, std::move(visit), seen, moved);
        std::vector<BadFace> found;
        for (int32_t t : visit) {
            const Tet tet = ed.tet(t);
            for (int k = 0; k < 4; ++k) {
                Few<int32_t, 2> two;
                if (!ed.tets_at(two, tet[(k + 1) % 4], tet[(k + 2) % 4], tet[(k + 3) % 4]) || two.size() != 2) continue;
                const int32_t u = two[0] == t ? two[1] : two[0];
                if (u > t) {
                    if (face_cosine(t, u) < bound) found.push_back({t, k, u});
                } else {
                    // The face as the lower tet's, u's corner off it.
                    const Tet& other = ed.tet(u);
                    int j = 0;
                    while (TetEditor::contains(tet, other[j])) ++j;
                    if (face_cosine(u, t) < bound) found.push_back({u, j, t});
                }
            }
        }
        std::sort(found.begin(), found.end(), face_order);
        found.erase(std::unique(found.begin(), found.end(),
                                [](const BadFace& a, const BadFace& b) { return a.t == b.t && a.k == b.k; }),
                    found.end());
        bad = std::move(found);
    };
    for (int sweep = 0; sweep < sweeps; ++sweep) {
        scan();
        if (sweep == 0) counts.faces_before = static_cast<int64_t>(bad.size());
        int64_t changed = 0;
        for (const auto& [t, k, u] : bad) {
            if (!ed.alive(t) || !ed.alive(u) || !(face_cosine(t, u) < bound)) continue;
            if (flipper.improve_tet(t, flips, true) || flipper.improve_tet(u, flips, true)) {
                ++changed;
                continue;
            }
            const Tet first = ed.tet(t), second = ed.tet(u);
            // A face whose corners are all pinned (surface nodes) may still
            // be flipped away from the tets around its edges.
            bool flipped = false;
            Few<int32_t, 3> face;
            for (int32_t v : first)
                if (TetEditor::contains(second, v)) face.push_back(v);
            for (int e = 0; e < 3 && !flipped && face.size() == 3; ++e)
                for (int32_t w : ed.around_edge(face[e], face[(e + 1) % 3]))
                    if (w != t && w != u && ed.alive(w) && flipper.improve_tet(w, flips)) {
                        flipped = true;
                        break;
                    }
            if (flipped) {
                ++changed;
                continue;
            }
            for (const Tet& tet : {first, second})
                for (int32_t v : tet)
                    if (!pinned[v] && orthogonalize_point(ed, v, size_t(v) < layers.size() ? layers[v] : LayerBound{}, floors))
                        ++counts.moves, ++changed, moved.push_back(v);
        }
        if (changed == 0) break;
    }
    // Last resort for a face still beyond the solver's floor (floors.ortho)
    // where flips and moves found nothing (its tets' points all surface
    // nodes or held layer points): a new free point on an interior edge of
    // one of its two tets, twice at most.
    const double floor_cosine = std::cos(floors.ortho * M_PI / 180);
    const EdgeSet surface_edges = edge_set(mesh.boundary_faces);
    for (int round = 0; round < 2; ++round) {
        scan();
        int64_t splits = 0;
        for (const auto& [t, k, u] : bad) {
            if (!ed.alive(t) || !ed.alive(u) || !(face_cosine(t, u) < floor_cosine)) continue;
            bool split = false;
            for (int32_t w : {t, u}) {
                if (split) break;
                const Tet tet = ed.tet(w);
                for (int i = 0; i < 4 && !split; ++i)
                    for (int j = i + 1; j < 4 && !split; ++j)
                        split = !surface_edges.count(edge_key(tet[i], tet[j])) &&
                                split_edge_for_orthogonality(ed, tet[i], tet[j], floors);
            }
            if (split) {
                ++splits;
                pinned.resize(ed.point_count(), 0);
                moved.push_back(static_cast<int32_t>(ed.point_count()) - 1);
            }
        }
        counts.splits += splits;
        if (splits == 0) break;
    }
    counts.flips = flips.total();
    ed.commit();
    return counts;
}

} // namespace scalemesh

namespace scalemesh {
namespace {

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

// Splits the interior edge (q, s) by a new free point m where the smallest
// dihedral angle of the new tets is best, when that beats the old tets'
// (dihedral_better); then m is smoothed. Never used on a surface edge.
bool split_edge_for_dihedral(TetEditor& ed, int32_t q, int32_t s, const OrthoFloors& floors)
{
    const int32_t m =
        split_edge_where_better(ed, q, s, [&](const Shape& a, const Shape& b) { return dihedral_better(a, b, floors); });
    if (m < 0) return false;
    raise_point_dihedral(ed, m, {}, floors);
    return true;
}

} // namespace

DihedralCounts raise_dihedral_angles(TetMesh& mesh, int32_t surface_points, double target_deg, int sweeps,
                                     const std::vector<LayerBound>& layers, int32_t locked_tets)
{
    DihedralCounts counts;
    TetEditor ed(mesh, locked_tets);
    const OrthoFloors floors;
    Flipper flipper(ed, Criterion::dihedral, floors);
    FlipCounts flips;
    const size_t original_points = ed.point_count();
    std::vector<char> pinned(original_points, 0);
    for (size_t v = 0; v < pinned.size(); ++v) {
        const bool layer = v < layers.size() && layers[v].slack > 0;
        pinned[v] = int32_t(v) < surface_points || (v < layers.size() && layers[v].fixed) ||
                    (layer && distance(ed.point(int32_t(v)), layers[v].home) > layers[v].slack);
    }
    const auto is_pinned = [&](int32_t v) { return size_t(v) < pinned.size() && pinned[v]; };
    const auto dihedral = [&](int32_t t) {
        const Tet& x = ed.tet(t);
        return tet_min_dihedral_deg(ed.point(x[0]), ed.point(x[1]), ed.point(x[2]), ed.point(x[3]));
    };
    // The living tets below the target, in id order. The first call looks
    // at every tet; a later one only at those whose angles can have changed
    // since: the tets made since (ids from `seen` on), those at the points
    // moved since, and the ones found below then.
    std::vector<int32_t> last_poor, moved;
    size_t seen = 0;
    const auto poor_tets = [&] {
        std::vector<int32_t> visit;
        if (seen == 0) {
            // Every tet, its angles in parallel (reading only).
            const std::vector<char> below = parallel_marks(0, ed.size(), [&](size_t i) {
                return ed.alive(int32_t(i)) && !ed.locked(int32_t(i)) && dihedral(int32_t(i)) < target_deg;
            });
            for (size_t i = 0; i < ed.size(); ++i)
                if (below[i]) visit.push_back(int32_t(i));
            seen = ed.size();
        } else {
            visit = changed_since(ed, last_poor, seen, moved);
        }
        last_poor.clear();
        for (int32_t t : visit)
            if (ed.alive(t) && !ed.locked(t) && dihedral(t) < target_deg) last_poor.push_back(t);
        return last_poor;
    };
    // Flips at the tet, then at the tets around its edges, then moves of its
    // free points; true when something changed.
    const auto improve = [&](int32_t t) {
        if (flipper.improve_tet(t, flips, true)) return true;
        const Tet tet = ed.tet(t);
        bool changed = false;
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j)
                for (int32_t w : ed.around_edge(tet[i], tet[j]))
                    if (w != t && ed.alive(w) && flipper.improve_tet(w, flips)) {
                        changed = true;
                        if (!ed.alive(t)) return true;
                    }
        for (int32_t v : tet)
            if (ed.alive(t) && !is_pinned(v) &&
                raise_point_dihedral(ed, v, size_t(v) < layers.size() ? layers[v] : LayerBound{}, floors))
                ++counts.moves, changed = true, moved.push_back(v);
        return changed;
    };
    for (int sweep = 0; sweep < sweeps; ++sweep) {
        const std::vector<int32_t> poor = poor_tets();
        if (sweep == 0) counts.tets_before = static_cast<int64_t>(poor.size());
        int64_t changed = 0;
        for (int32_t t : poor)
            if (ed.alive(t) && dihedral(t) < target_deg && improve(t)) ++changed;
        if (changed == 0) break;
    }
    // Last resort: a new free point on one of the tet's interior edges.
    const EdgeSet surface_edges = edge_set(mesh.boundary_faces);
    for (int round = 0; round < 2; ++round) {
        int64_t splits = 0;
        for (int32_t t : poor_tets()) {
            if (!ed.alive(t) || !(dihedral(t) < target_deg)) continue;
            const Tet tet = ed.tet(t);
            for (int i = 0; i < 4 && ed.alive(t); ++i)
                for (int j = i + 1; j < 4 && ed.alive(t); ++j)
                    if (!surface_edges.count(edge_key(tet[i], tet[j])) && split_edge_for_dihedral(ed, tet[i], tet[j], floors))
                        ++splits;
        }
        counts.splits += splits;
        if (splits == 0) break;
        for (int sweep = 0; sweep < sweeps; ++sweep) {
            int64_t changed = 0;
            for (int32_t t : poor_tets())
                if (ed.alive(t) && dihedral(t) < target_deg && improve(t)) ++changed;
            if (changed == 0) break;
        }
    }
    counts.flips = flips.total();
    ed.commit();
    return counts;
}

std::vector<int32_t> points_missing_floors(const TetMesh& mesh, int32_t surface_points, double dihedral_floor,
                                           double ortho_bound)
{
    const auto& x = mesh.points;
    const auto at = [&](int32_t v) -> const Vec3& { return x[v]; };
    const double bound = std::cos(ortho_bound * M_PI / 180);
    const TetFaceAdjacency adjacency = tet_face_adjacency(mesh);
    // A tet is marked for its own angle or for any of its interior faces,
    // each face measured from its lower tet as the passes measure it.
    const std::vector<char> marked = parallel_marks(0, mesh.tets.size(), [&](size_t i) {
        const Tet& t = mesh.tets[i];
        if (tet_min_dihedral_deg(x[t[0]], x[t[1]], x[t[2]], x[t[3]]) < dihedral_floor) return true;
        for (int k = 0; k < 4; ++k) {
            const int32_t u = adjacency.across[4 * i + k];
            if (u < 0) continue; // boundary or overshared
            const Tet& other = mesh.tets[u];
            const bool lower = u > static_cast<int32_t>(i);
            if (shared_face_cosine(at, lower ? t : other, lower ? other : t) < bound) return true;
        }
        return false;
    });
    std::vector<int32_t> out;
    for (size_t t = 0; t < mesh.tets.size(); ++t)
        if (marked[t])
            for (int32_t v : mesh.tets[t])
                if (v >= surface_points) out.push_back(v);
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
}

double max_non_orthogonality_deg(const TetMesh& mesh, const TetFaceAdjacency& adjacency)
{
    const auto at = [&](int32_t v) -> const Vec3& { return mesh.points[v]; };
    const double worst = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, mesh.tets.size(), 1 << 13), 1.0,
        [&](const tbb::blocked_range<size_t>& range, double lowest) {
            for (size_t i = range.begin(); i != range.end(); ++i)
                for (int k = 0; k < 4; ++k) {
                    const int32_t u = adjacency.across[4 * i + k];
                    if (u > static_cast<int32_t>(i)) // each interior face once
                        lowest = std::min(lowest, face_cosine(at, mesh.tets[i], k, mesh.tets[u]));
                }
            return lowest;
        },
        [](double a, double b) { return std::min(a, b); });
    return std::acos(std::clamp(worst, -1.0, 1.0)) * 180 / M_PI;
}

} // namespace scalemesh
