#include "volume/layer_prisms.h"

#include "core/face_measures.h"
#include "core/vec3.h"
#include "volume/quality.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace scalemesh {

namespace {

// A layer prism: its three generators, ascending, and the layer of its floor.
struct PrismKey {
    std::array<int32_t, 3> generators;
    int32_t layer;
    bool operator<(const PrismKey& o) const
    {
        return generators != o.generators ? generators < o.generators : layer < o.layer;
    }
    bool operator==(const PrismKey& o) const { return generators == o.generators && layer == o.layer; }
};

constexpr int32_t kNoPrism = -1;

// The key of the prism tet t lies in, or layer kNoPrism: all its points
// layer points (or boundary nodes) of two consecutive layers, made from
// exactly three generators.
PrismKey prism_of(const Tet& tet, const std::vector<int32_t>& generator, const std::vector<int32_t>& layer,
                  const std::vector<char>& filler)
{
    PrismKey key{{}, kNoPrism};
    int32_t low = layer[tet[0]], high = low;
    std::array<int32_t, 4> g{};
    for (int i = 0; i < 4; ++i) {
        if (filler[tet[i]]) return key;
        low = std::min(low, layer[tet[i]]);
        high = std::max(high, layer[tet[i]]);
        g[i] = generator[tet[i]];
    }
    if (high != low + 1) return key;
    std::sort(g.begin(), g.end());
    const auto end = std::unique(g.begin(), g.end());
    if (end - g.begin() != 3) return key;
    return {{g[0], g[1], g[2]}, low};
}

// The tets of each layer prism filled by exactly three tets, ascending, in
// the order of the prisms' keys.
std::vector<std::array<int32_t, 3>> three_tet_groups(const TetMesh& mesh, const std::vector<int32_t>& point_generator,
                                                     const std::vector<int32_t>& point_layer,
                                                     const std::vector<char>& point_filler)
{
    // Each tet's prism, where it has one.
    const size_t tets = mesh.tets.size();
    std::vector<PrismKey> key(tets);
    tbb::parallel_for(size_t(0), tets,
                      [&](size_t t) { key[t] = prism_of(mesh.tets[t], point_generator, point_layer, point_filler); });
    std::vector<int32_t> candidates;
    for (size_t t = 0; t < tets; ++t)
        if (key[t].layer != kNoPrism) candidates.push_back(static_cast<int32_t>(t));
    tbb::parallel_sort(candidates.begin(), candidates.end(), [&](int32_t a, int32_t b) {
        return key[a] == key[b] ? a < b : key[a] < key[b];
    });
    std::vector<std::array<int32_t, 3>> groups;
    for (size_t i = 0; i < candidates.size();) {
        size_t j = i + 1;
        while (j < candidates.size() && key[candidates[j]] == key[candidates[i]]) ++j;
        if (j - i == 3) groups.push_back({candidates[i], candidates[i + 1], candidates[i + 2]});
        i = j;
    }
    return groups;
}

// The volume-weighted sum of the centroids of a set of tets, and their
// volume: a cell's centre, as OpenFOAM's is near it.
struct Moment {
    Vec3 sum{};
    double volume = 0;
    void add(const TetMesh& mesh, int32_t t)
    {
        const Tet& x = mesh.tets[t];
        const Vec3 &a = mesh.points[x[0]], &b = mesh.points[x[1]], &c = mesh.points[x[2]], &d = mesh.points[x[3]];
        const double v = tet_volume6(a, b, c, d) / 6;
        sum += v * (a + b + c + d) / 4, volume += v;
    }
    void add(const Moment& other) { sum += other.sum, volume += other.volume; }
    Vec3 centre() const { return sum / volume; }
};

// The volume-weighted centroid of tets `group`, or nothing if their volume
// is not positive.
std::optional<Vec3> group_centroid(const TetMesh& mesh, const std::array<int32_t, 3>& group)
{
    Moment m;
    for (int32_t t : group) m.add(mesh, t);
    if (!(m.volume > 0)) return std::nullopt;
    return m.centre();
}

// Whether each outer face of tets `group` (a face whose neighbour across,
// in `group_of`, is not group `g`) sees `centroid` at more than about 3
// degrees on its inner side.
bool star_shaped(const TetMesh& mesh, const TetFaceAdjacency& adjacency, const std::vector<int32_t>& group_of,
                 int32_t g, const std::array<int32_t, 3>& group, const Vec3& centroid)
{
    const double min_sine = std::sin(kStarAngleDeg * 3.14159265358979323846 / 180);
    for (int32_t t : group) {
        for (int k = 0; k < 4; ++k) {
            const int32_t across = adjacency.across[4 * t + k];
            if (across >= 0 && group_of[across] == g) continue;
            const Triangle f = tet_face(mesh.tets[t], k);
            if (!faces_centre(mesh.points[f[0]], mesh.points[f[1]], mesh.points[f[2]], centroid, min_sine))
                return false;
        }
    }
    return true;
}

} // namespace

bool faces_centre(const Vec3& p, const Vec3& q, const Vec3& r, const Vec3& centre, double min_sine)
{
    const Vec3 n = cross(q - p, r - p); // outward: tet faces are counter-clockwise from outside
    const Vec3 out = (p + q + r) / 3 - centre;
    return dot(n, out) > min_sine * norm(n) * norm(out);
}

LayerPrismCells layer_prism_cells(const TetMesh& mesh, const TetFaceAdjacency& adjacency,
                                  const std::vector<int32_t>& point_generator, const std::vector<int32_t>& point_layer,
                                  const std::vector<char>& point_filler, double max_non_orthogonality_deg,
                                  const std::vector<char>* apart)
{
    if (adjacency.across.size() != 4 * mesh.tets.size())
        throw std::invalid_argument("layer_prism_cells: the face adjacency is not that of this mesh");
    const size_t n = mesh.points.size();
    if (apart && apart->size() != mesh.tets.size())
        throw std::invalid_argument("layer_prism_cells: `apart` has " + std::to_string(apart->size()) +
                                    " entries for " + std::to_string(mesh.tets.size()) + " tets");
    if (point_generator.size() != n || point_layer.size() != n || point_filler.size() != n)
        throw std::invalid_argument("layer_prism_cells: per-point arrays of " + std::to_string(point_generator.size()) +
                                    ", " + std::to_string(point_layer.size()) + " and " +
                                    std::to_string(point_filler.size()) + " entries for " + std::to_string(n) +
                                    " points");
    // Runs of exactly three tets of one prism become one cell, led by the
    // first of them.
    const size_t tets = mesh.tets.size();
    LayerPrismCells out;
    std::vector<int32_t> leader(tets, -1);
    const std::vector<std::array<int32_t, 3>> groups =
        three_tet_groups(mesh, point_generator, point_layer, point_filler);
    // Each tet's centroid, and each prism's in place of its tets' while it
    // is accepted: star-shaped from its centroid, and (below) no face beyond
    // the bound.
    std::vector<Vec3> centre(tets);
    std::vector<int32_t> group_of(tets, -1);
    tbb::parallel_for(size_t(0), tets, [&](size_t t) {
        const Tet& tet = mesh.tets[t];
        centre[t] = (mesh.points[tet[0]] + mesh.points[tet[1]] + mesh.points[tet[2]] + mesh.points[tet[3]]) / 4;
    });
    for (size_t g = 0; g < groups.size(); ++g)
        for (int32_t t : groups[g]) group_of[t] = static_cast<int32_t>(g);
    std::vector<char> accepted(groups.size());
    std::vector<Vec3> group_centre(groups.size());
    tbb::parallel_for(size_t(0), groups.size(), [&](size_t g) {
        const std::optional<Vec3> c = group_centroid(mesh, groups[g]);
        if (!c) return;
        if (apart && ((*apart)[groups[g][0]] || (*apart)[groups[g][1]] || (*apart)[groups[g][2]])) return;
        group_centre[g] = *c;
        accepted[g] = star_shaped(mesh, adjacency, group_of, static_cast<int32_t>(g), groups[g], *c);
    });
    const double min_cosine = std::cos(max_non_orthogonality_deg * 3.14159265358979323846 / 180);
    const auto cell_centre = [&](int32_t t) {
        const int32_t g = group_of[t];
        return g >= 0 && accepted[g] ? group_centre[g] : centre[t];
    };
    for (bool changed = true; changed;) {
        std::vector<char> refuse(groups.size(), 0);
        tbb::parallel_for(size_t(0), groups.size(), [&](size_t g) {
            if (!accepted[g]) return;
            for (int32_t t : groups[g])
                for (int k = 0; k < 4; ++k) {
                    const int32_t across = adjacency.across[4 * t + k];
                    if (across < 0 || group_of[across] == static_cast<int32_t>(g)) continue;
                    const Triangle f = tet_face(mesh.tets[t], k);
                    const Vec3 n = cross(mesh.points[f[1]] - mesh.points[f[0]], mesh.points[f[2]] - mesh.points[f[0]]);
                    const Vec3 d = cell_centre(across) - group_centre[g];
                    if (!(dot(n, d) > min_cosine * norm(n) * norm(d))) {
                        refuse[g] = 1;
                        return;
                    }
                }
        });
        changed = false;
        for (size_t g = 0; g < groups.size(); ++g)
            if (refuse[g]) {
                accepted[g] = 0;
                changed = true;
            }
    }
    for (size_t g = 0; g < groups.size(); ++g) {
        if (!accepted[g]) {
            ++out.refused;
            continue;
        }
        ++out.prisms;
        for (int32_t t : groups[g]) leader[t] = groups[g][0];
    }

    // Cells numbered in the order of their first tet.
    out.cell_of_tet.assign(tets, -1);
    for (size_t t = 0; t < tets; ++t) {
        const int32_t lead = leader[t] < 0 ? static_cast<int32_t>(t) : leader[t];
        if (out.cell_of_tet[lead] < 0) {
            out.cell_of_tet[lead] = out.cells++;
            out.prism_cell.push_back(leader[t] >= 0);
        }
        out.cell_of_tet[t] = out.cell_of_tet[lead];
    }
    return out;
}

namespace {

// Each cell's tets: the cells as given in one flat array (cell by cell), and
// beside it the few cells that joins have changed. Memory: a tet index per
// tet and an offset per cell, where a vector per cell would cost an
// allocation each at tens of millions of cells.
class CellMembers {
public:
    CellMembers(const std::vector<int32_t>& cell_of_tet, int32_t cells)
        : start_(static_cast<size_t>(cells) + 1, 0), tets_(cell_of_tet.size())
    {
        for (const int32_t c : cell_of_tet) ++start_[static_cast<size_t>(c) + 1];
        std::partial_sum(start_.begin(), start_.end(), start_.begin());
        std::vector<int64_t> next(start_.begin(), start_.end() - 1);
        for (size_t t = 0; t < cell_of_tet.size(); ++t) tets_[next[cell_of_tet[t]]++] = static_cast<int32_t>(t);
    }
    std::span<const int32_t> of(int32_t c) const
    {
        if (const auto changed = changed_.find(c); changed != changed_.end()) return changed->second;
        return {tets_.data() + start_[c], static_cast<size_t>(start_[c + 1] - start_[c])};
    }
    int32_t lowest(int32_t c) const
    {
        const std::span<const int32_t> tets = of(c);
        return *std::min_element(tets.begin(), tets.end());
    }
    void move(int32_t tet, int32_t from, int32_t into)
    {
        std::vector<int32_t>& source = changed(from);
        source.erase(std::find(source.begin(), source.end(), tet));
        changed(into).push_back(tet);
    }

private:
    std::vector<int32_t>& changed(int32_t c)
    {
        const auto [it, added] = changed_.try_emplace(c);
        if (added) it->second.assign(tets_.begin() + start_[c], tets_.begin() + start_[c + 1]);
        return it->second;
    }
    std::vector<int64_t> start_;
    std::vector<int32_t> tets_;
    std::unordered_map<int32_t, std::vector<int32_t>> changed_;
};

} // namespace

int64_t absorb_poor_tets(const TetMesh& mesh, const TetFaceAdjacency& adjacency, LayerPrismCells& cells,
                         const PoorTetBounds& bounds, const RefusedUnions& refused, ChosenUnions* chosen)
{
    const size_t tets = mesh.tets.size();
    if (cells.cell_of_tet.size() != tets || adjacency.across.size() != 4 * tets)
        throw std::invalid_argument("absorb_poor_tets: the cells or the adjacency are not of this mesh");
    if (chosen) chosen->clear();
    std::vector<int32_t>& cell = cells.cell_of_tet;
    CellMembers members(cell, cells.cells);
    // A tet's centroid, and a cell's moment and centre, computed where
    // needed: a cell holds seven tets at most.
    const auto centroid = [&](int32_t t) {
        const Tet& x = mesh.tets[t];
        return (mesh.points[x[0]] + mesh.points[x[1]] + mesh.points[x[2]] + mesh.points[x[3]]) / 4;
    };
    const auto moment_of = [&](int32_t c) {
        Moment m;
        for (const int32_t t : members.of(c)) m.add(mesh, t);
        return m;
    };
    const auto centre = [&](int32_t c) { return moment_of(c).centre(); };
    const double min_cosine = std::cos(bounds.max_non_orthogonality_deg * 3.14159265358979323846 / 180);
    const double min_sine = std::sin(kStarAngleDeg * 3.14159265358979323846 / 180);
    // The area vector of face k of tet t.
    const auto face_area = [&](int32_t t, int k) {
        const Triangle f = tet_face(mesh.tets[t], k);
        return cross(mesh.points[f[1]] - mesh.points[f[0]], mesh.points[f[2]] - mesh.points[f[0]]);
    };

    // The determinant of tet t as a cell of its own (its internal faces).
    const auto lone_determinant = [&](int32_t t) {
        CellDeterminant d;
        for (int k = 0; k < 4; ++k)
            if (adjacency.across[4 * t + k] >= 0) d.add(face_area(t, k));
        return d.determinant();
    };

    // The cosine of face k of tet t against the join from `from` to the
    // centre of the cell across; NaN for a flat face or a zero join, which
    // sticks in the comparisons below.
    const auto face_cosine = [&](int32_t t, int k, const Vec3& from) {
        return face_orthogonality_cosine(face_area(t, k), centre(cell[adjacency.across[4 * t + k]]) - from,
                                         std::numeric_limits<double>::quiet_NaN());
    };

    // The skewness of face k of tet t (OpenFOAM's faceSkewness): the face
    // centre's offset from where the join of the two cells' centres
    // crosses the face, over the face's extent in that direction (at least
    // a fifth of the join).
    const auto face_skewness = [&](int32_t t, int k) {
        const Triangle f = tet_face(mesh.tets[t], k);
        const Vec3 &p = mesh.points[f[0]], &q = mesh.points[f[1]], &r = mesh.points[f[2]];
        const Vec3 centre_f = (p + q + r) / 3, area = face_area(t, k);
        const Vec3 from = centroid(t);
        const Vec3 d = centre(cell[adjacency.across[4 * t + k]]) - from;
        const Vec3 to_face = centre_f - from;
        const Vec3 offset = to_face - (dot(area, to_face) / (dot(area, d) + 1e-300)) * d;
        const Vec3 along = offset / (norm(offset) + 1e-300);
        double extent = 0.2 * norm(d) + 1e-300;
        for (const Vec3* x : {&p, &q, &r}) extent = std::max(extent, std::abs(dot(along, *x - centre_f)));
        return norm(offset) / extent;
    };

    // The interpolation weight of face k of tet t against the cell across.
    const auto face_weight = [&](int32_t t, int k) {
        const Triangle f = tet_face(mesh.tets[t], k);
        return face_interpolation_weight(face_area(t, k),
                                         (mesh.points[f[0]] + mesh.points[f[1]] + mesh.points[f[2]]) / 3, centroid(t),
                                         centre(cell[adjacency.across[4 * t + k]]));
    };

    // The poor tet cells, worst dihedral angle first; the tets looked at in
    // parallel, as marks a sequential loop then collects.
    std::vector<char> is_poor(tets, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tets, 1 << 14), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const auto t = static_cast<int32_t>(i);
            if (members.of(cell[t]).size() != 1) continue;
            const Tet& x = mesh.tets[t];
            const Vec3 &a = mesh.points[x[0]], &b = mesh.points[x[1]], &c = mesh.points[x[2]], &d = mesh.points[x[3]];
            bool bad = tet_min_dihedral_deg(a, b, c, d) < bounds.min_dihedral_deg ||
                       tet_aspect_ratio(a, b, c, d) < bounds.min_aspect_ratio;
            for (int k = 0; k < 4 && !bad; ++k)
                if (adjacency.across[4 * t + k] >= 0 &&
                    (!(face_cosine(t, k, centroid(t)) > min_cosine) || !(face_skewness(t, k) <= bounds.max_skewness) ||
                     !(face_weight(t, k) >= bounds.min_weight)))
                    bad = true;
            if (!bad && !(lone_determinant(t) >= bounds.min_determinant)) bad = true;
            is_poor[i] = bad;
        }
    });
    std::vector<std::pair<double, int32_t>> poor;
    for (size_t i = 0; i < tets; ++i)
        if (is_poor[i]) {
            const Tet& x = mesh.tets[i];
            poor.emplace_back(
                tet_min_dihedral_deg(mesh.points[x[0]], mesh.points[x[1]], mesh.points[x[2]], mesh.points[x[3]]),
                static_cast<int32_t>(i));
        }
    std::vector<char>().swap(is_poor);
    std::sort(poor.begin(), poor.end());

    const size_t cell_count = static_cast<size_t>(cells.cells);
    std::vector<char> was_prism(cell_count, 0), grew(cell_count, 0);
    for (size_t c = 0; c < cell_count && c < cells.prism_cell.size(); ++c) was_prism[c] = cells.prism_cell[c];
    int64_t joined = 0;
    for (const auto& worst_first : poor) {
        const int32_t t = worst_first.second; // a variable, not a binding: the lambdas below capture it
        if (members.of(cell[t]).size() != 1) continue; // another tet joined it meanwhile
        // The cells across its faces, and the union of the tet with one of
        // them or with two: a flat tet's two faces on one side may lie on
        // two cells, and only their union sees its other faces from inside.
        std::vector<int32_t> across_cells;
        for (int k = 0; k < 4; ++k)
            if (const int32_t a = adjacency.across[4 * t + k]; a >= 0 && cell[a] != cell[t] &&
                                                               std::find(across_cells.begin(), across_cells.end(),
                                                                         cell[a]) == across_cells.end())
                across_cells.push_back(cell[a]);
        // A union's name: the lowest tet of each of its cells, ascending, -1
        // after them.
        const auto name = [&](const TetUnion& cells_joined) {
            TetUnion u{-1, -1, -1};
            size_t k = 0;
            for (const int32_t c : cells_joined)
                if (c >= 0) u[k++] = members.lowest(c);
            for (size_t a = 0; a + 1 < k; ++a) // at most three: a bubble sort
                for (size_t b = 0; b + 1 < k - a; ++b)
                    if (u[b] > u[b + 1]) std::swap(u[b], u[b + 1]);
            return u;
        };
        // A union's determinant reaches the bound, or the tet's own where
        // that is lower already (a sliver of one internal face has none).
        const double min_determinant = std::min(bounds.min_determinant, lone_determinant(t));
        const auto refused_here = refused.find(t);
        TetUnion best{-1, -1, -1};
        double best_cosine = min_cosine;
        const auto consider = [&](const TetUnion& with) {
            const auto inside = [&](int32_t c) { return c >= 0 && std::find(with.begin(), with.end(), c) != with.end(); };
            size_t size = 1;
            Moment m;
            m.add(mesh, t);
            for (const int32_t c : with)
                if (c >= 0) size += members.of(c).size(), m.add(moment_of(c));
            if (static_cast<int32_t>(size) > bounds.max_cell_tets) return;
            if (refused_here != refused.end()) {
                const std::vector<TetUnion>& no = refused_here->second;
                if (std::find(no.begin(), no.end(), name(with)) != no.end()) return;
            }
            const Vec3 joint = m.centre();
            // The union's outer faces: star-shaped from `joint`, and their
            // worst cosine to the cells across.
            double worst = 1;
            bool star = true;
            CellDeterminant determinant; // over the outer faces to other cells (a prism's side quad as its two triangles)
            std::vector<int32_t> on_faces, all_points; // the union's points: each must stay on an outer face
            const auto outer = [&](int32_t u) {
                all_points.insert(all_points.end(), mesh.tets[u].begin(), mesh.tets[u].end());
                for (int j = 0; j < 4 && star; ++j) {
                    const int32_t a = adjacency.across[4 * u + j];
                    if (a >= 0 && (inside(cell[a]) || a == t)) continue;
                    const Triangle f = tet_face(mesh.tets[u], j);
                    on_faces.insert(on_faces.end(), f.begin(), f.end());
                    if (!faces_centre(mesh.points[f[0]], mesh.points[f[1]], mesh.points[f[2]], joint, min_sine))
                        star = false;
                    else if (a >= 0) {
                        determinant.add(face_area(u, j));
                        if (const double c = face_cosine(u, j, joint); !(c >= worst)) worst = c; // NaN sticks
                    }
                }
            };
            outer(t);
            for (const int32_t c : with)
                if (c >= 0)
                    for (const int32_t u : members.of(c)) outer(u);
            if (!star || !(worst > best_cosine) || !(determinant.determinant() >= min_determinant)) return;
            // A point all of whose tets the union holds would lie inside the
            // cell, on no face: OpenFOAM fails a mesh with an unused point.
            std::sort(on_faces.begin(), on_faces.end());
            for (const int32_t p : all_points)
                if (!std::binary_search(on_faces.begin(), on_faces.end(), p)) return;
            best = with, best_cosine = worst;
        };
        const size_t k = across_cells.size();
        for (size_t a = 0; a < k; ++a) {
            consider({across_cells[a], -1, -1});
            for (size_t b = a + 1; b < k; ++b) {
                consider({across_cells[a], across_cells[b], -1});
                for (size_t c = b + 1; c < k; ++c) consider({across_cells[a], across_cells[b], across_cells[c]});
            }
        }
        if (best[0] < 0) continue;
        if (chosen) {
            // A tet that joined one of these cells before keeps its union
            // unrefused: if the cell fails, this union is the one undone.
            for (const int32_t c : best)
                if (c >= 0)
                    for (const int32_t u : members.of(c)) chosen->erase(u);
            (*chosen)[t] = name(best);
        }
        const auto join = [&](int32_t u, int32_t into) {
            members.move(u, cell[u], into);
            cell[u] = into;
        };
        join(t, best[0]);
        for (size_t i = 1; i < best.size(); ++i)
            if (best[i] >= 0) {
                const std::span<const int32_t> of = members.of(best[i]);
                const std::vector<int32_t> other(of.begin(), of.end());
                for (const int32_t u : other) join(u, best[0]);
                grew[best[i]] = 1;
            }
        grew[best[0]] = 1;
        ++joined;
    }
    if (joined == 0) return 0;
    for (size_t c = 0; c < cell_count; ++c) cells.prisms -= was_prism[c] && grew[c];
    // Cells numbered in the order of their first tet again.
    std::vector<int32_t> number(cell_count, -1);
    cells.cells = 0;
    cells.prism_cell.clear();
    for (size_t t = 0; t < tets; ++t) {
        if (number[cell[t]] < 0) {
            number[cell[t]] = cells.cells++;
            cells.prism_cell.push_back(was_prism[cell[t]] && !grew[cell[t]]);
        }
        cell[t] = number[cell[t]];
    }
    cells.absorbed += joined;
    return joined;
}

int64_t layer_prism_groups(const TetMesh& mesh, const std::vector<int32_t>& point_generator,
                           const std::vector<int32_t>& point_layer, const std::vector<char>& point_filler)
{
    const size_t n = mesh.points.size();
    if (point_generator.size() != n || point_layer.size() != n || point_filler.size() != n)
        throw std::invalid_argument("layer_prism_groups: per-point arrays of the wrong size");
    return static_cast<int64_t>(three_tet_groups(mesh, point_generator, point_layer, point_filler).size());
}

LayerPrismCells checked_layer_prism_cells(const TetMesh& mesh, const TetFaceAdjacency& adjacency,
                                          const std::vector<int32_t>& point_generator,
                                          const std::vector<int32_t>& point_layer,
                                          const std::vector<char>& point_filler, double max_non_orthogonality_deg,
                                          const FailingCells& failing_cells, const PoorTetBounds* absorb)
{
    const size_t tets = mesh.tets.size();
    std::vector<char> apart(tets, 0);
    RefusedUnions refused;
    ChosenUnions chosen;
    for (;;) {
        LayerPrismCells cells = layer_prism_cells(mesh, adjacency, point_generator, point_layer, point_filler,
                                                  max_non_orthogonality_deg, &apart);
        if (absorb) absorb_poor_tets(mesh, adjacency, cells, *absorb, refused, &chosen);
        const std::vector<int32_t> failing = failing_cells(cells);
        std::vector<char> undo(static_cast<size_t>(cells.cells), 0);
        for (int32_t c : failing)
            if (c >= 0 && c < cells.cells) undo[c] = 1;
        // Each round refuses a union not refused before or marks tets not
        // marked before (a round that does neither ends it), so the rounds
        // end. Failing unions are undone first, and prisms are split only in
        // a round that undoes none: a prism named next to a failing union
        // may pass once the union is gone.
        bool refusing = false;
        for (const auto& [t, joined] : chosen)
            if (undo[cells.cell_of_tet[t]]) refused[t].push_back(joined), refusing = true;
        bool splitting = false;
        for (size_t t = 0; t < tets && !refusing; ++t)
            if (undo[cells.cell_of_tet[t]] && !apart[t]) apart[t] = 1, splitting = true;
        if (!refusing && !splitting) return cells;
    }
}

} // namespace scalemesh
