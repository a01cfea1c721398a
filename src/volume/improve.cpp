#include "volume/improve.h"

#include "volume/quality.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace scalemesh {
namespace {

// A flip replaces old tets by new ones on the same polyhedron; the criterion
// decides from their volumes or aspect ratios whether it is worth it.
enum class Criterion { volume, quality };

// The tets as a mutable set with vertex-to-tet lists (dead entries are
// skipped and dropped lazily), enough for local flips and point moves.
class TetEditor {
public:
    explicit TetEditor(TetMesh& mesh) : mesh_(mesh), tets_(mesh.tets), incident_(mesh.points.size())
    {
        alive_.assign(tets_.size(), 1);
        for (size_t t = 0; t < tets_.size(); ++t)
            for (int32_t v : tets_[t]) incident_[v].push_back(static_cast<int32_t>(t));
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
    bool alive(int32_t t) const { return alive_[t] != 0; }
    const Tet& tet(int32_t t) const { return tets_[t]; }
    const Vec3& point(int32_t v) const { return mesh_.points[v]; }
    Vec3& point(int32_t v) { return mesh_.points[v]; }

    // Living tets at v (compacts v's list on the way).
    const std::vector<int32_t>& at(int32_t v)
    {
        auto& list = incident_[v];
        list.erase(std::remove_if(list.begin(), list.end(), [&](int32_t t) { return !alive_[t]; }), list.end());
        return list;
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
    void replace(const std::vector<int32_t>& old, const std::vector<Tet>& fresh)
    {
        for (int32_t t : old) alive_[t] = 0;
        for (const Tet& t : fresh) {
            const int32_t id = static_cast<int32_t>(tets_.size());
            tets_.push_back(t);
            alive_.push_back(1);
            for (int32_t v : t) incident_[v].push_back(id);
        }
    }

    static bool contains(const Tet& t, int32_t v) { return t[0] == v || t[1] == v || t[2] == v || t[3] == v; }

private:
    TetMesh& mesh_;
    std::vector<Tet> tets_;
    std::vector<char> alive_;
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

double longest_edge2(const TetEditor& ed, const std::vector<Tet>& tets)
{
    double l2 = 0;
    for (const Tet& t : tets)
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j) l2 = std::max(l2, norm2(ed.point(t[i]) - ed.point(t[j])));
    return l2;
}

class Flipper {
public:
    Flipper(TetEditor& ed, Criterion criterion) : ed_(ed), criterion_(criterion) {}

    // Tries the flips of the edges and faces of tet t; true when one was made.
    bool improve_tet(int32_t t, FlipCounts& counts)
    {
        const Tet tet = ed_.tet(t);
        for (int i = 0; i < 4; ++i)
            for (int j = i + 1; j < 4; ++j)
                if (flip_edge(tet[i], tet[j], counts)) return true;
        for (int i = 0; i < 4; ++i)
            if (flip_face(tet[(i + 1) % 4], tet[(i + 2) % 4], tet[(i + 3) % 4], counts)) return true;
        return false;
    }

private:
    // Whether replacing `old` by `fresh` is worth it; the new tets must all
    // be clearly positive (beyond round-off of their size).
    bool accept(const std::vector<int32_t>& old, const std::vector<Tet>& fresh, const std::vector<double>& fresh6)
    {
        std::vector<Tet> old_tets;
        for (int32_t t : old) old_tets.push_back(ed_.tet(t));
        const double l2 = longest_edge2(ed_, old_tets);
        const double floor6 = 1e-12 * l2 * std::sqrt(l2);
        double new_min = 1e300;
        for (double v : fresh6) new_min = std::min(new_min, v);
        if (!(new_min > floor6)) return false;
        if (criterion_ == Criterion::volume) {
            double old_min = 1e300;
            for (const Tet& t : old_tets) old_min = std::min(old_min, ed_.volume6(t));
            return new_min > 3.0 * old_min;
        }
        double old_q = 1e300, new_q = 1e300;
        for (const Tet& t : old_tets) old_q = std::min(old_q, ed_.aspect(t));
        for (const Tet& t : fresh) new_q = std::min(new_q, ed_.aspect(t));
        return new_q > old_q + 1e-6;
    }

    // The ring of the edge (a, b): c_0 .. c_{k-1} with (a, b, c_i, c_{i+1})
    // positive. Empty when the tets around the edge do not close (a surface edge).
    std::vector<int32_t> ring(int32_t a, int32_t b, const std::vector<int32_t>& around)
    {
        std::vector<std::pair<int32_t, int32_t>> next;
        for (int32_t t : around) {
            int32_t other[2], k = 0;
            for (int32_t v : ed_.tet(t))
                if (v != a && v != b) other[k++] = v;
            if (tet_volume6(ed_.point(a), ed_.point(b), ed_.point(other[0]), ed_.point(other[1])) < 0)
                std::swap(other[0], other[1]);
            next.emplace_back(other[0], other[1]);
        }
        std::vector<int32_t> cycle{next[0].first};
        for (size_t step = 0; step < next.size(); ++step) {
            const int32_t from = cycle.back();
            int32_t to = -1, hits = 0;
            for (const auto& [x, y] : next)
                if (x == from) to = y, ++hits;
            if (hits != 1) return {};
            if (step + 1 == next.size()) return to == cycle.front() ? cycle : std::vector<int32_t>{};
            cycle.push_back(to);
        }
        return {};
    }

    bool flip_edge(int32_t a, int32_t b, FlipCounts& counts)
    {
        const std::vector<int32_t> around = ed_.around_edge(a, b);
        if (around.size() != 3 && around.size() != 4) return false;
        const std::vector<int32_t> c = ring(a, b, around);
        if (c.size() != around.size()) return false;
        if (c.size() == 3) {
            if (ed_.has_face(c[0], c[1], c[2])) return false;
            std::vector<double> v6(2);
            const std::vector<Tet> fresh{oriented(ed_, c[0], c[1], c[2], a, v6[0]),
                                         oriented(ed_, c[0], c[1], c[2], b, v6[1])};
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
            std::vector<double> v6(4);
            const std::vector<Tet> fresh{oriented(ed_, p, q, r, a, v6[0]), oriented(ed_, p, r, w, a, v6[1]),
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

    bool flip_face(int32_t a, int32_t b, int32_t c, FlipCounts& counts)
    {
        std::vector<int32_t> two;
        for (int32_t t : ed_.at(a))
            if (TetEditor::contains(ed_.tet(t), b) && TetEditor::contains(ed_.tet(t), c)) two.push_back(t);
        if (two.size() != 2) return false; // a surface face has one tet
        int32_t d = -1, e = -1;
        for (int32_t v : ed_.tet(two[0]))
            if (v != a && v != b && v != c) d = v;
        for (int32_t v : ed_.tet(two[1]))
            if (v != a && v != b && v != c) e = v;
        if (ed_.has_edge(d, e)) return false;
        std::vector<double> v6(3);
        const std::vector<Tet> fresh{oriented(ed_, d, e, a, b, v6[0]), oriented(ed_, d, e, b, c, v6[1]),
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
};

// Smallest aspect ratio over the tets at v, or -1 when one is not clearly positive.
double star_quality(TetEditor& ed, int32_t v)
{
    double q = 1e300;
    for (int32_t t : ed.at(v)) {
        const Tet& tet = ed.tet(t);
        const double a = ed.aspect(tet);
        if (!(a > 1e-9)) return -1;
        q = std::min(q, a);
    }
    return q;
}

// Moves interior point v to raise the smallest aspect ratio of its star.
bool smooth_point(TetEditor& ed, int32_t v)
{
    const double start = star_quality(ed, v);
    if (start < 0) return false;
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
    const double h = 1e-4 * mean_length;
    Vec3 gradient;
    for (int axis = 0; axis < 3; ++axis) {
        Vec3 plus = origin, minus = origin;
        plus[axis] += h;
        minus[axis] -= h;
        ed.point(v) = plus;
        const double qp = ed.aspect(ed.tet(worst));
        ed.point(v) = minus;
        const double qm = ed.aspect(ed.tet(worst));
        gradient[axis] = (qp - qm) / (2 * h);
    }
    ed.point(v) = origin;

    std::vector<Vec3> candidates;
    const Vec3 direction = normalized(gradient);
    if (norm2(direction) > 0)
        for (double step : {0.2, 0.1, 0.05, 0.025, 0.0125, 0.006}) candidates.push_back(origin + step * mean_length * direction);
    Vec3 centroid;
    int count = 0;
    for (int32_t t : ed.at(v))
        for (int32_t w : ed.tet(t))
            if (w != v) centroid += ed.point(w), ++count;
    centroid /= count;
    candidates.push_back(centroid);
    candidates.push_back(0.5 * (origin + centroid));

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
        // The polygon a, r_1, ..., r_k, c (closed by c -> a) is fanned from
        // each of its vertices in turn; the first fan whose cones from b and
        // d are all clearly positive, on opposite sides, is taken.
        std::vector<Tet> fresh;
        if (ok) {
            std::vector<Tet> old;
            for (int32_t t : around) old.push_back(ed.tet(t));
            const double l2 = longest_edge2(ed, old);
            const double floor6 = 1e-12 * l2 * std::sqrt(l2);
            const size_t np = chain.size();
            ok = false;
            for (size_t apex = 0; apex < np && !ok; ++apex) {
                fresh.clear();
                bool good = true;
                int sign_b = 0;
                for (size_t step = 1; good && step + 1 < np; ++step) {
                    const int32_t p = chain[apex], q = chain[(apex + step) % np], r = chain[(apex + step + 1) % np];
                    if (step + 1 < np - 1 && step > 1 && ed.has_edge(p, q)) good = false;
                    for (int32_t tip : {b, d}) {
                        double v6 = 0;
                        const Tet t = oriented(ed, tip, p, q, r, v6);
                        const int sign = t[1] == p ? 1 : -1;
                        if (tip == b && sign_b == 0) sign_b = sign;
                        if (!(v6 > floor6) || sign != (tip == b ? sign_b : -sign_b)) good = false;
                        fresh.push_back(t);
                    }
                }
                ok = good;
            }
        }
        if (!ok) {
            failed.push_back(static_cast<int32_t>(qi));
            continue;
        }
        ed.replace(around, fresh);
    }
    ed.commit();
    return failed;
}

FlipCounts flip_volume_criterion(TetMesh& mesh, int sweeps)
{
    FlipCounts counts;
    TetEditor ed(mesh);
    Flipper flipper(ed, Criterion::volume);
    for (int sweep = 0; sweep < sweeps; ++sweep) {
        const int64_t before = counts.flips_32 + counts.flips_23 + counts.flips_44;
        const size_t n = ed.size();
        for (size_t t = 0; t < n; ++t)
            if (ed.alive(static_cast<int32_t>(t))) flipper.improve_tet(static_cast<int32_t>(t), counts);
        if (counts.flips_32 + counts.flips_23 + counts.flips_44 == before) break;
    }
    ed.commit();
    return counts;
}

SliverCounts remove_slivers(TetMesh& mesh, int32_t surface_points, double threshold, int sweeps)
{
    SliverCounts counts;
    TetEditor ed(mesh);
    Flipper flipper(ed, Criterion::quality);
    FlipCounts flips;
    for (int sweep = 0; sweep < sweeps; ++sweep) {
        int64_t changed = 0;
        const size_t n = ed.size();
        for (size_t t = 0; t < n; ++t) {
            const int32_t id = static_cast<int32_t>(t);
            if (!ed.alive(id) || ed.aspect(ed.tet(id)) >= threshold) continue;
            if (flipper.improve_tet(id, flips)) {
                ++changed;
                continue;
            }
            const Tet tet = ed.tet(id);
            for (int32_t v : tet)
                if (v >= surface_points && smooth_point(ed, v)) ++counts.moves, ++changed;
        }
        if (changed == 0) break;
    }
    counts.flips = flips.flips_32 + flips.flips_23 + flips.flips_44;
    ed.commit();
    return counts;
}

} // namespace scalemesh
