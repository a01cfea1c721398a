#include "volume/layer_prisms.h"

#include "core/vec3.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

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

// The volume-weighted centroid of tets `group`, or nothing if their volume
// is not positive.
std::optional<Vec3> group_centroid(const TetMesh& mesh, const std::array<int32_t, 3>& group)
{
    Vec3 centroid;
    double volume = 0;
    for (int32_t t : group) {
        const Tet& tet = mesh.tets[t];
        const Vec3 &a = mesh.points[tet[0]], &b = mesh.points[tet[1]], &c = mesh.points[tet[2]], &d = mesh.points[tet[3]];
        const double v = tet_volume6(a, b, c, d);
        centroid += v * (a + b + c + d) / 4;
        volume += v;
    }
    if (!(volume > 0)) return std::nullopt;
    return centroid / volume;
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
        if (out.cell_of_tet[lead] < 0) out.cell_of_tet[lead] = out.cells++;
        out.cell_of_tet[t] = out.cell_of_tet[lead];
    }
    return out;
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
                                          const FailingCells& failing_cells)
{
    std::vector<char> apart(mesh.tets.size(), 0);
    for (;;) {
        LayerPrismCells cells = layer_prism_cells(mesh, adjacency, point_generator, point_layer, point_filler,
                                                  max_non_orthogonality_deg, &apart);
        const std::vector<int32_t> failing = failing_cells(cells);
        std::vector<char> split(static_cast<size_t>(cells.cells), 0);
        for (int32_t c : failing)
            if (c >= 0 && c < cells.cells) split[c] = 1;
        // Each round marks tets not marked before (a round that marks none
        // ends it), so the rounds end.
        bool more = false;
        for (size_t t = 0; t < mesh.tets.size(); ++t)
            if (split[cells.cell_of_tet[t]] && !apart[t]) apart[t] = 1, more = true;
        if (!more) return cells;
    }
}

} // namespace scalemesh
