// The flips of every pass (Flipper), and paper section 2.4's flip pass with
// the volume criterion (flip_volume_criterion).

#include "volume/flips.h"

#include "volume/improve.h"
#include "volume/slab_scheduler.h"
#include "volume/tet_editor.h"

#include <algorithm>
#include <array>
#include <functional>
#include <mutex>
#include <utility>
#include <vector>

namespace scalemesh::improvement {

bool Flipper::improve_tet(int32_t t, FlipCounts& counts, bool removals)
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

template <class Old, class Fresh, class Volumes6>
bool Flipper::accept(const Old& old, const Fresh& fresh, const Volumes6& fresh6)
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
    if (criterion_ == Criterion::dihedral || criterion_ == Criterion::orthogonality) {
        // The face cosines (the faces across the old tets' hull) only where
        // the aspect ratios and dihedral angles let the flip through.
        const ShapeOrder order{criterion_ == Criterion::dihedral, floors_};
        Shape before = cell_shape(ed_, old_tets);
        const Shape after = cell_shape_against(ed_, fresh, order, before);
        if (!order.may_beat(before, after)) return false;
        before = with_cosine(before, ed_, old_tets, face_links(ed_, old_tets, old));
        return order.better(before, with_cosine_against(after, ed_, fresh, face_links(ed_, fresh, old), order, before));
    }
    double old_q = 1e300, new_q = 1e300;
    for (const Tet& t : old_tets) old_q = std::min(old_q, ed_.aspect(t));
    for (const Tet& t : fresh) new_q = std::min(new_q, ed_.aspect(t));
    return new_q > old_q + 1e-6;
}

template <class Around>
Flipper::Ring Flipper::ring(int32_t a, int32_t b, const Around& around)
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

bool Flipper::flip_edge(int32_t a, int32_t b, FlipCounts& counts)
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

bool Flipper::remove_edge(int32_t a, int32_t b, FlipCounts& counts)
{
    Few<int32_t, kMaxRing> around;
    if (!ed_.tets_at(around, a, b) || around.size() < 5 || ed_.any_locked(around)) return false;
    const Ring c = ring(a, b, around);
    if (c.size() != around.size()) return false;
    const int m = static_cast<int>(c.size());
    Few<Tet, kMaxRing> old_tets;
    for (int32_t t : around) old_tets.push_back(ed_.tet(t));
    const Shape before = shape_of(ed_, old_tets, face_links(ed_, old_tets, around));
    const ShapeOrder order{criterion_ == Criterion::dihedral, floors_};
    const double floor6 = volume_floor6(ed_, old_tets);
    Shape best = before;
    RingTets chosen;
    bool found = false;
    // A triangle of the ring is in many triangulations (35 triangles in the
    // 42 of a ring of seven): whether its corners are joined by an edge of
    // the mesh, and its two tets (to a and to b) with their volumes and
    // measures, are found once, when a triangulation first asks.
    std::array<std::array<int8_t, kMaxRing>, kMaxRing> joined;
    for (auto& row : joined) row.fill(-1);
    const auto has_edge = [&](int p, int q) {
        if (joined[p][q] < 0) joined[p][q] = ed_.has_edge(c[p], c[q]) ? 1 : 0;
        return joined[p][q] == 1;
    };
    struct Side {
        Tet tet;
        double volume6;
        TetMeasures measures;
    };
    struct Triangle {
        Side a, b;
        bool turns; // a on one side, b on the other, as the ring turns
    };
    std::array<int8_t, kMaxRing * kMaxRing * kMaxRing> slot;
    slot.fill(-1);
    constexpr int kRingTriangles = kMaxRing * (kMaxRing - 1) * (kMaxRing - 2) / 6;
    static_assert(kRingTriangles <= 127, "a triangle's slot fits an int8_t");
    Few<Triangle, kRingTriangles> made;
    const auto side = [&](int i, int j, int k, int32_t apex) {
        Side s;
        s.tet = oriented(ed_, c[i], c[j], c[k], apex, s.volume6);
        const Tet& t = s.tet;
        s.measures = tet_measures(ed_.point(t[0]), ed_.point(t[1]), ed_.point(t[2]), ed_.point(t[3]));
        return s;
    };
    const auto triangle = [&](int i, int j, int k) -> const Triangle& {
        int8_t& at = slot[(i * kMaxRing + j) * kMaxRing + k];
        if (at < 0) {
            Triangle t{side(i, j, k, a), side(i, j, k, b), false};
            // (c_i, c_j, c_k) with i < j < k turns as the ring does: a on
            // one side, b on the other, the same for every triangle.
            t.turns = t.a.tet[1] == c[k] && t.b.tet[1] == c[j];
            at = static_cast<int8_t>(made.size());
            made.push_back(t);
        }
        return made[at];
    };
    for (const auto& triangles : polygon_triangulations(m)) {
        bool usable = true;
        for (const auto& [i, j, k] : triangles)
            for (const auto& [p, q] : {std::pair{i, j}, std::pair{j, k}, std::pair{i, k}})
                if (q - p > 1 && !(p == 0 && q == m - 1) && has_edge(p, q)) usable = false;
        if (!usable) continue;
        RingTets fresh;
        // The cheap tests first: volumes, aspect ratios, dihedral angles;
        // the face links (for the non-orthogonality) only then.
        double smallest6 = 1e300, aspect = 1e300, dihedral = 1e300;
        for (const auto& [i, j, k] : triangles) {
            const Triangle& t = triangle(i, j, k);
            usable = usable && t.turns;
            for (const Side* s : {&t.a, &t.b}) {
                fresh.push_back(s->tet);
                smallest6 = std::min(smallest6, s->volume6);
                aspect = std::min(aspect, s->measures.aspect_ratio);
                dihedral = std::min(dihedral, s->measures.min_dihedral_deg);
            }
        }
        if (!usable) continue;
        if (!(smallest6 > floor6) || aspect < std::min(before.aspect, floors_.aspect)) continue;
        if (criterion_ == Criterion::dihedral && !(dihedral > best.dihedral + 1e-6)) continue;
        if (criterion_ == Criterion::orthogonality && dihedral < std::min(before.dihedral, floors_.dihedral)) continue;
        const Shape now =
            with_cosine_against(Shape{1, aspect, dihedral}, ed_, fresh, face_links(ed_, fresh, around), order, best);
        if (order.better(best, now)) best = now, chosen = fresh, found = true;
    }
    if (!found) return false;
    ed_.replace(around, chosen);
    ++counts.edge_removals;
    return true;
}

const std::vector<std::vector<std::array<int, 3>>>& Flipper::polygon_triangulations(int m)
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

bool Flipper::flip_face(int32_t a, int32_t b, int32_t c, FlipCounts& counts)
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

} // namespace scalemesh::improvement

namespace scalemesh {
namespace {

using improvement::below_marks;
using improvement::Criterion;
using improvement::Flipper;
using improvement::improve_in_slabs;
using improvement::Part;
using improvement::TetEditor;

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

} // namespace scalemesh
