// Light faces (mend_light_faces, improve.h): an interior face between two
// tets whose interpolation weight is below a
// target (0.06 in the volume stage, a margin over checkMesh's 0.05), mended
// by the flip of a flat cap's quad under it or by moves of the free points
// of its tets, each judged on every tet and face it changes.

#include "volume/improve.h"

#include "core/adjacency.h"
#include "core/face_measures.h"
#include "volume/tet_editor.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>
#include <optional>
#include <vector>

namespace scalemesh {
namespace {

using improvement::face_links;
using improvement::FaceLink;
using improvement::Few;
using improvement::OrthoFloors;
using improvement::point_gradient;
using improvement::Shape;
using improvement::shape_of;
using improvement::TetEditor;
using improvement::within_layer;

// The interpolation weight of the face tets t and `other` share, from their
// cells' centres (the editor's: a layer prism's, else the tet's centroid).
double shared_face_weight(const TetEditor& ed, const Tet& t, const Tet& other)
{
    const auto at = [&](int32_t v) -> const Vec3& { return ed.point(v); };
    const int k = improvement::corner_off(t, other);
    const Vec3 &a = ed.point(t[(k + 1) % 4]), &b = ed.point(t[(k + 2) % 4]), &c = ed.point(t[(k + 3) % 4]);
    return face_interpolation_weight(cross(b - a, c - a), (a + b + c) / 3, improvement::cell_centre(at, t, ed.centres),
                                     improvement::cell_centre(at, other, ed.centres));
}

// Point v's star: its tets and their interior faces, as a move of v sees them.
struct Star {
    std::vector<int32_t> ids;
    std::vector<Tet> tets;
    std::vector<FaceLink> links;
    double mean_length = 0;
};

// The lightest of the interior faces `links` of `tets`.
double lightest(const TetEditor& ed, const std::vector<Tet>& tets, const std::vector<FaceLink>& links)
{
    double w = 1;
    for (const FaceLink& link : links)
        w = std::min(w, shared_face_weight(ed, tets[link.i], link.inside >= 0 ? tets[link.inside] : ed.tet(link.outside)));
    return w;
}

// The lightest face of the star (its smallest interpolation weight).
double lightest(const TetEditor& ed, const Star& star) { return lightest(ed, star.tets, star.links); }

// What a move must keep: every tet positive, the aspect ratio floor and
// the targets of the cell passes (CellPassParams: their margins over the
// solver's floors), or the star's own worst where it already misses one.
bool keeps_floors(const Shape& before, const Shape& after, const OrthoFloors& floors, const CellPassParams& targets)
{
    const double target_cosine = std::cos(targets.ortho_bound_deg * M_PI / 180);
    return after.aspect > 0 && after.aspect >= std::min(floors.aspect, before.aspect) &&
           after.dihedral >= std::min(targets.dihedral_target_deg, before.dihedral) &&
           after.cosine >= std::min(target_cosine, before.cosine);
}

// Moves free point v to raise the lightest face of its star: line searches
// along the gradient of that weight and along the normal of the light face
// (both ways), by steps of 0.2 down to 0.003 of the star's mean edge
// length, up to four rounds while they gain. A star with a locked tet is
// left alone, and one with a face to a locked tet unless the editor has the
// prisms' centres to measure that face from. True when v moved.
bool lighten_point(TetEditor& ed, int32_t v, const LayerBound& layer, const Vec3& face_normal,
                   const OrthoFloors& floors)
{
    Star star;
    star.ids = ed.at(v);
    for (int32_t t : star.ids) {
        if (ed.locked(t)) return false;
        star.tets.push_back(ed.tet(t));
    }
    star.links = face_links(ed, star.tets, star.ids);
    for (const FaceLink& link : star.links)
        if (link.inside < 0 && ed.locked(link.outside) && !ed.centres) return false;
    const Vec3 origin = ed.point(v);
    int corners = 0;
    for (const Tet& t : star.tets)
        for (int32_t w : t)
            if (w != v) star.mean_length += distance(origin, ed.point(w)), ++corners;
    if (corners == 0) return false;
    star.mean_length /= corners;

    const CellPassParams targets;
    const auto shape = [&] { return shape_of(ed, star.tets, star.links); };
    const Shape start = shape();
    if (!(start.aspect > 0)) return false;
    double best = lightest(ed, star);
    Vec3 position = origin;
    for (int round = 0; round < 4; ++round) {
        ed.point(v) = position;
        const Vec3 gradient =
            normalized(point_gradient(ed, v, 1e-4 * star.mean_length, [&] { return lightest(ed, star); }));
        bool gained = false;
        Vec3 next = position;
        for (const Vec3& d : {gradient, face_normal, -face_normal}) {
            if (!(norm2(d) > 0)) continue;
            for (double step : {0.2, 0.1, 0.05, 0.025, 0.0125, 0.006, 0.003}) {
                ed.point(v) = within_layer(layer, position + step * star.mean_length * d);
                const double w = lightest(ed, star);
                if (!(w > best + 1e-9) || !keeps_floors(start, shape(), floors, targets)) continue;
                best = w, next = ed.point(v), gained = true;
            }
        }
        position = next;
        if (!gained) break;
    }
    ed.point(v) = position;
    return !(position == origin);
}

struct Face {
    int32_t t, u;
};

// The faces lighter than `target` between two tets beyond the first
// `locked` (t < u), from the mesh's adjacency as the editor was made; the
// tets' weights read in parallel. A face to a locked tet (a layer prism's)
// is not taken: counting those, the moves for them near the stack cost the
// stepped tube of the multi-scale study its prism layers (a tet cell of
// 7.1 degrees, a face of 70.05, in the writer's checks).
std::vector<Face> light_faces(const TetEditor& ed, const TetFaceAdjacency& adjacency, int32_t locked, double target)
{
    const auto light = [&](int32_t t, int k) {
        const int32_t u = adjacency.across[4 * size_t(t) + k];
        return u > t && shared_face_weight(ed, ed.tet(t), ed.tet(u)) < target;
    };
    const std::vector<char> marks = improvement::parallel_marks(size_t(locked), ed.size(), [&](size_t i) {
        for (int k = 0; k < 4; ++k)
            if (light(int32_t(i), k)) return true;
        return false;
    });
    std::vector<Face> found;
    for (size_t m = 0; m < marks.size(); ++m)
        if (marks[m])
            for (int k = 0; k < 4; ++k) {
                const auto t = static_cast<int32_t>(locked + m);
                if (light(t, k)) found.push_back({t, adjacency.across[4 * size_t(t) + k]});
            }
    return found;
}

// The unit normal of triangle f.
Vec3 unit_normal(const TetEditor& ed, const Triangle& f)
{
    return normalized(cross(ed.point(f[1]) - ed.point(f[0]), ed.point(f[2]) - ed.point(f[0])));
}

// The boundary faces' indices by their sorted corners.
using FaceIndex = std::map<std::array<int32_t, 3>, size_t>;

std::array<int32_t, 3> sorted_key(int32_t x, int32_t y, int32_t z)
{
    std::array<int32_t, 3> key{x, y, z};
    std::sort(key.begin(), key.end());
    return key;
}

// The flip of a flat cap's quad under tets t and u, which no move of a
// point mends (a thin triangle at a cap's rim, or a cap triangle with an
// angle near 180 degrees: see improve.h). `boundary` is the mesh's
// boundary faces, `patch` their patches, `at` a face's index by its sorted
// corners (kept up to date). The face t and u share has an edge (e0, e1)
// on which each tet has a boundary face, (e0, e1, a) and (e0, e1, b), both
// of one opening's patch (not the wall's, 0) and in one plane; the tets are
// then a pyramid over the quad (e0, a, e1, b) from the face's third corner
// p. Its other diagonal splits it into (a, b, e0, p) and (a, b, e1, p), the
// cap's plane unchanged, where both are clearly positive and fill the
// pyramid (the quad is convex), (a, b) is no edge yet, and
// better(old tets, their links, new tets, their links) holds. Each edge of
// the face is tried. True when flipped.
template <class Better>
bool flip_flat_cap(TetEditor& ed, std::vector<Triangle>& boundary, const std::vector<int32_t>& patch, FaceIndex& at,
                   int32_t t, int32_t u, const Better& better)
{
    if (ed.locked(t) || ed.locked(u)) return false;
    const Tet first = ed.tet(t), second = ed.tet(u);
    int32_t a = -1, b = -1;
    Few<int32_t, 3> face;
    for (int32_t v : first)
        if (TetEditor::contains(second, v)) face.push_back(v);
        else a = v;
    for (int32_t v : second)
        if (!TetEditor::contains(first, v)) b = v;
    if (face.size() != 3) return false;
    const auto boundary_face = [&](int32_t x, int32_t y, int32_t z) -> std::optional<size_t> {
        const auto it = at.find(sorted_key(x, y, z));
        return it == at.end() ? std::nullopt : std::optional<size_t>(it->second);
    };
    if (!ed.around_edge(a, b).empty()) return false;
    const std::vector<Tet> old{first, second};
    const std::vector<int32_t> ids{t, u};
    const std::vector<FaceLink> old_links = face_links(ed, old, ids);
    const double whole = ed.volume6(first) + ed.volume6(second);
    for (int e = 0; e < 3; ++e) {
        const int32_t e0 = face[e], e1 = face[(e + 1) % 3], p = face[(e + 2) % 3];
        const std::optional<size_t> i = boundary_face(e0, e1, a), j = boundary_face(e0, e1, b);
        if (!i || !j || patch[*i] != patch[*j] || patch[*i] == 0) continue;
        const Vec3 normal = unit_normal(ed, boundary[*i]);
        if (!(dot(normal, unit_normal(ed, boundary[*j])) > 1 - 1e-9)) continue;
        double v0 = 0, v1 = 0;
        const std::vector<Tet> fresh{improvement::oriented(ed, a, b, e0, p, v0),
                                     improvement::oriented(ed, a, b, e1, p, v1)};
        if (!(v0 > 1e-3 * whole && v1 > 1e-3 * whole && std::abs(v0 + v1 - whole) <= 1e-9 * whole)) continue;
        if (!better(old, old_links, fresh, face_links(ed, fresh, ids))) continue;
        ed.replace(ids, fresh);
        // The cap's two triangles, each facing out as before.
        const auto outward = [&](Triangle x) {
            if (dot(unit_normal(ed, x), normal) < 0) std::swap(x[0], x[1]);
            return x;
        };
        at.erase(sorted_key(e0, e1, a));
        at.erase(sorted_key(e0, e1, b));
        boundary[*i] = outward({a, b, e0});
        boundary[*j] = outward({a, b, e1});
        at.emplace(sorted_key(a, b, e0), *i);
        at.emplace(sorted_key(a, b, e1), *j);
        return true;
    }
    return false;
}

// Per tet beyond the first `locked`: whether it is below the solver's
// floors (OrthoFloors: the smallest dihedral angle, the aspect ratio).
// Measured in parallel (reading only).
std::vector<char> poor_tets(const TetEditor& ed, int32_t locked, const OrthoFloors& floors)
{
    return improvement::parallel_marks(size_t(locked), ed.size(), [&](size_t i) {
        const Tet& x = ed.tet(int32_t(i));
        const TetMeasures m = tet_measures(ed.point(x[0]), ed.point(x[1]), ed.point(x[2]), ed.point(x[3]));
        return ed.alive(int32_t(i)) && (m.min_dihedral_deg < floors.dihedral || m.aspect_ratio < floors.aspect);
    });
}

// The tets marked `poor` (poor_tets) with an opening's face in `at`, each
// with every tet that may share a flat cap's quad with it: for a boundary
// face (e0, e1, a) of the tet and its fourth corner p, the tet across the
// face (e0, e1, p), and so for each edge of the boundary face. In id order.
std::vector<std::pair<int32_t, int32_t>> cap_pairs(TetEditor& ed, int32_t locked, const std::vector<char>& poor,
                                                   const FaceIndex& at)
{
    std::vector<std::pair<int32_t, int32_t>> found;
    for (size_t i = size_t(locked); i < ed.size(); ++i) {
        if (!poor[i - size_t(locked)]) continue;
        const auto t = static_cast<int32_t>(i);
        const Tet& x = ed.tet(t);
        for (int k = 0; k < 4; ++k) {
            const int32_t p = x[k], f[3] = {x[(k + 1) % 4], x[(k + 2) % 4], x[(k + 3) % 4]};
            if (!at.count(sorted_key(f[0], f[1], f[2]))) continue;
            for (int e = 0; e < 3; ++e) {
                Few<int32_t, 2> two;
                if (!ed.tets_at(two, f[e], f[(e + 1) % 3], p) || two.size() != 2) continue;
                found.push_back({t, two[0] == t ? two[1] : two[0]});
            }
        }
    }
    return found;
}

} // namespace

LightFaceCounts mend_light_faces(TetMesh& mesh, int32_t surface_points, double target_weight,
                                 const std::vector<LayerBound>& layers, int32_t locked_tets, const PrismCells* prisms,
                                 const std::vector<int32_t>& boundary_patch)
{
    LightFaceCounts counts;
    // The layer prisms' centres over the whole mesh, as an editor's one
    // part: its points are the mesh's.
    improvement::CellCentres centres;
    std::vector<int32_t> identity;
    if (prisms && !prisms->points.empty()) {
        identity.resize(mesh.points.size());
        std::iota(identity.begin(), identity.end(), 0);
        centres.prisms = prisms;
        centres.global = &identity;
        centres.stacked.assign(mesh.points.size(), 0);
        for (size_t v = 0; v < mesh.points.size() && v < prisms->generator.size(); ++v)
            if (prisms->generator[v] >= 0) centres.stacked[v] = 1, centres.local.emplace(int32_t(v), int32_t(v));
    }
    const auto attach_centres = [&](TetEditor& ed) {
        if (centres.prisms) ed.centres = &centres;
    };

    const OrthoFloors floors;
    // The openings' boundary faces (patch 0 is the wall's), indexed.
    const bool caps = boundary_patch.size() == mesh.boundary_faces.size() &&
                      std::any_of(boundary_patch.begin(), boundary_patch.end(), [](int32_t p) { return p != 0; });
    const auto boundary_index = [&] {
        FaceIndex at;
        for (size_t i = 0; i < mesh.boundary_faces.size(); ++i) {
            const Triangle& f = mesh.boundary_faces[i];
            if (boundary_patch[i] != 0) at.emplace(sorted_key(f[0], f[1], f[2]), i);
        }
        return at;
    };

    // First the light faces over a flat cap: their boundary quads flipped,
    // where the new tets keep what a move keeps and have a heavier lightest
    // face.
    {
        TetEditor ed(mesh, locked_tets);
        attach_centres(ed);
        const std::vector<Face> light = light_faces(ed, tet_face_adjacency(mesh), locked_tets, target_weight);
        counts.faces_before = static_cast<int64_t>(light.size());
        if (caps && !light.empty()) {
            FaceIndex at = boundary_index();
            const auto lightens = [&](const std::vector<Tet>& old, const std::vector<FaceLink>& old_links,
                                      const std::vector<Tet>& fresh, const std::vector<FaceLink>& links) {
                return keeps_floors(shape_of(ed, old, old_links), shape_of(ed, fresh, links), floors, CellPassParams{}) &&
                       lightest(ed, fresh, links) > lightest(ed, old, old_links) + 1e-9;
            };
            for (const Face& f : light)
                if (ed.alive(f.t) && ed.alive(f.u) &&
                    flip_flat_cap(ed, mesh.boundary_faces, boundary_patch, at, f.t, f.u, lightens))
                    ++counts.cap_flips;
            if (counts.cap_flips > 0) ed.commit();
        }
    }

    // Then the flat caps under a tet still below the solver's floors. A tet
    // on a cap triangle with an angle near 180 degrees is as flat as that
    // triangle wherever its apex is (its angles at the edges to the apex
    // tend to the triangle's small angles), so no move mends it. The flip
    // must raise the two tets' smallest dihedral angle, keep the aspect
    // ratio floor and non-orthogonality within 70 degrees, or the old tets'
    // worst (dihedral_better), and leave no face lighter than the target,
    // or the old tets' lightest: the new interior face stands on the cap
    // as the light faces above do, where no move mends it either.
    if (caps) {
        TetEditor ed(mesh, locked_tets);
        attach_centres(ed);
        const std::vector<char> poor = poor_tets(ed, locked_tets, floors);
        const bool any = std::find(poor.begin(), poor.end(), 1) != poor.end();
        FaceIndex at = any ? boundary_index() : FaceIndex{};
        const auto raises_dihedral = [&](const std::vector<Tet>& old, const std::vector<FaceLink>& old_links,
                                         const std::vector<Tet>& fresh, const std::vector<FaceLink>& links) {
            return improvement::dihedral_better(shape_of(ed, old, old_links), shape_of(ed, fresh, links), floors) &&
                   lightest(ed, fresh, links) >= std::min(target_weight, lightest(ed, old, old_links));
        };
        for (const auto& [t, u] : cap_pairs(ed, locked_tets, poor, at))
            if (ed.alive(t) && ed.alive(u) &&
                flip_flat_cap(ed, mesh.boundary_faces, boundary_patch, at, t, u, raises_dihedral))
                ++counts.poor_tet_cap_flips;
        if (counts.poor_tet_cap_flips > 0) ed.commit();
    }
    if (counts.faces_before == 0 && counts.poor_tet_cap_flips == 0) return counts;

    // Then moves of the free points of the rest, a face's tets' points in
    // turn until it is mended.
    const TetFaceAdjacency adjacency = tet_face_adjacency(mesh);
    TetEditor ed(mesh, locked_tets);
    attach_centres(ed);
    for (const Face& f : light_faces(ed, adjacency, locked_tets, target_weight)) {
        const Tet t = ed.tet(f.t), u = ed.tet(f.u);
        Triangle face{};
        int corners = 0;
        for (int32_t v : t)
            if (TetEditor::contains(u, v)) face[corners++] = v;
        const Vec3 normal = unit_normal(ed, face);
        const auto mended = [&] { return shared_face_weight(ed, ed.tet(f.t), ed.tet(f.u)) >= target_weight; };
        for (const Tet& tet : {t, u})
            for (int32_t v : tet) {
                if (mended()) break;
                const bool fixed = v < surface_points || (size_t(v) < layers.size() && layers[v].fixed);
                const LayerBound layer = size_t(v) < layers.size() ? layers[v] : LayerBound{};
                if (!fixed && lighten_point(ed, v, layer, normal, floors)) ++counts.moves;
            }
    }
    // A move raises its star's lightest face, so no face of the star ends
    // below where that one was; but one may end below the target, so the
    // faces left are counted afresh (no tet was replaced: the same adjacency).
    counts.faces_after = static_cast<int64_t>(light_faces(ed, adjacency, locked_tets, target_weight).size());
    return counts;
}

} // namespace scalemesh
