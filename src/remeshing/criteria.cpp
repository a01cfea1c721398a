#include "remeshing/criteria.h"

#include "core/errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace scalemesh::remeshing {

namespace {

// Twice the area vector of a triangle with this cross product is `cr`; its
// inscribed radius is 2 A / perimeter = |cr| / perimeter.
double inscribed_radius(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& cr)
{
    const double perimeter = distance(a, b) + distance(b, c) + distance(c, a);
    return perimeter > 0 ? norm(cr) / perimeter : 0.0;
}

double angle(const Vec3& u, const Vec3& v) { return std::atan2(norm(cross(u, v)), dot(u, v)); }

double min_angle(const Vec3& p, const Vec3& q, const Vec3& r)
{
    return std::min({angle(q - p, r - p), angle(r - q, p - q), angle(p - r, q - r)});
}

// A cross product this small relative to the edges is no triangle: its
// normal would be round-off.
bool degenerate(const Vec3& cr, const Vec3& u, const Vec3& v) { return norm(cr) <= 1e-12 * (norm2(u) + norm2(v)); }

// InputError naming `what` unless a and b are point indices of `surface`
// and d holds one value per point.
void check_indices(const SurfaceMesh& surface, const std::vector<double>& d, int32_t a, int32_t b, const char* what)
{
    const auto n = static_cast<int32_t>(surface.points.size());
    if (a < 0 || b < 0 || a >= n || b >= n || d.size() != surface.points.size())
        throw InputError(std::string(what) + " needs two point indices and one d per point", "");
}

// The half-edge from point a to point b of `mesh` (indices checked by
// check_indices), for the check functions: InputError with `hint` when the
// points are not joined by an edge.
int32_t checked_edge(const HalfedgeMesh& mesh, int32_t a, int32_t b, const char* hint)
{
    const int32_t h = mesh.vertex_alive(a) ? mesh.find_halfedge(a, b) : -1;
    if (h < 0)
        throw InputError("points " + std::to_string(a) + " and " + std::to_string(b) + " are not joined by an edge",
                         hint);
    return h;
}

} // namespace

bool Criteria::link_condition(const HalfedgeMesh& mesh, int32_t h)
{
    const int32_t i = mesh.from(h), j = mesh.to(h);
    const int32_t c = mesh.opposite(h), e = mesh.opposite(mesh.twin(h));
    // c and e lose the edge to i; with three neighbours left they keep a
    // proper fan (with two they would hold two copies of one triangle).
    if (mesh.valence(c) < 4 || mesh.valence(e) < 4) return false;

    if (stamp_.size() < static_cast<size_t>(mesh.vertex_capacity())) stamp_.resize(mesh.vertex_capacity(), 0);
    if (++current_stamp_ == 0) {
        std::fill(stamp_.begin(), stamp_.end(), 0);
        current_stamp_ = 1;
    }
    int32_t valence_i = 0, valence_j = 0;
    const int32_t start_i = mesh.outgoing(i);
    int32_t k = start_i;
    do {
        stamp_[mesh.to(k)] = current_stamp_;
        ++valence_i;
        k = mesh.rotate(k);
    } while (k != start_i);
    // A common neighbour other than c and e would give the merged node two
    // copies of an edge: a pinched, non-manifold surface (or a lost handle).
    const int32_t start_j = mesh.outgoing(j);
    k = start_j;
    do {
        const int32_t w = mesh.to(k);
        if (stamp_[w] == current_stamp_ && w != c && w != e) return false;
        ++valence_j;
        k = mesh.rotate(k);
    } while (k != start_j);
    return valence_i + valence_j - 4 >= 3;
}

Check Criteria::merge(const HalfedgeMesh& mesh, const std::vector<double>& d, const std::vector<Vec3>* drift,
                      int32_t h)
{
    Check check;
    const int32_t g = mesh.twin(h);
    const int32_t i = mesh.from(h), j = mesh.to(h);
    const Vec3 xi = mesh.points[i], xj = mesh.points[j];
    const double t = target(d[i]);
    check.toldamage = t / 30;
    auto reject = [&check](Verdict v) {
        check.verdict = v;
        return check;
    };
    if (distance(xi, xj) >= 0.5 * t) return reject(Verdict::too_long);
    // A rim node slides along the rim into a neighbour that stays put, so
    // the rim keeps to its plane. The survivor must be an input point: a
    // bisection midpoint lies inside a convex rim, and rims merged into
    // such points would creep inwards cycle after cycle.
    const int32_t patch_h = mesh.patch(HalfedgeMesh::face(h));
    if (const int32_t border = mesh.border_edges(i); border > 0) {
        if (border != 2 || !mesh.border_edge(h)) return reject(Verdict::patch_border);
        if (!planar(patch_h) && !planar(mesh.patch(HalfedgeMesh::face(g)))) return reject(Verdict::patch_border);
        if (j >= input_points_) return reject(Verdict::patch_border);
        // The rim is a curve: its damage is how far the chord that replaces
        // its two rim edges lies from the arc through x_i and its two rim
        // neighbours (the sagitta), at least x_i's own distance from it.
        // Repeated merges each move only a little, so x_i's distance alone
        // would let chords grow without bound; and the wall triangles beside
        // the rim can tilt far enough to hide either from eq. (A.1).
        int32_t k = mesh.rotate(h);
        while (!mesh.border_edge(k)) k = mesh.rotate(k);
        const Vec3 xp = mesh.points[mesh.to(k)];
        const Vec3 chord = xj - xp;
        const double along = norm2(chord) > 0 ? std::clamp(dot(xi - xp, chord) / norm2(chord), 0.0, 1.0) : 0.0;
        const double twice_area = norm(cross(xi - xp, xj - xp));
        double sagitta = 0;
        if (twice_area > 0) {
            const double radius = distance(xi, xp) * distance(xi, xj) * norm(chord) / (2 * twice_area);
            const double half = 0.5 * norm(chord);
            sagitta = radius - std::sqrt(std::max(0.0, radius * radius - half * half));
        }
        check.damage = std::max(distance(xi, xp + along * chord), sagitta);
        if (!(check.damage < check.toldamage)) return reject(Verdict::damage);
    }
    if (!link_condition(mesh, h)) return reject(Verdict::topology);

    // The old fans of i and of j, and the triangles the merge changes: i's
    // fan less the two triangles on the edge, with i replaced by j (Fig.
    // A.1), and j's other triangles (changed only when j moves).
    changed_.clear();
    const double inf = std::numeric_limits<double>::infinity();
    Vec3 fan_i{}, fan_i_across{}, fan_j{};
    double old_min_i = inf, old_min_j = inf;
    int32_t k = h;
    do {
        const Vec3& b = mesh.points[mesh.to(k)];
        const Vec3& c = mesh.points[mesh.opposite(k)];
        const Vec3 cr = cross(b - xi, c - xi);
        const bool across = mesh.patch(HalfedgeMesh::face(k)) != patch_h;
        (across ? fan_i_across : fan_i) += cr;
        old_min_i = std::min(old_min_i, inscribed_radius(xi, b, c, cr));
        if (k != h && k != HalfedgeMesh::next(g)) changed_.push_back({b, c, true, across});
        k = mesh.rotate(k);
    } while (k != h);
    k = g;
    do {
        const Vec3& b = mesh.points[mesh.to(k)];
        const Vec3& c = mesh.points[mesh.opposite(k)];
        const Vec3 cr = cross(b - xj, c - xj);
        fan_j += cr;
        if (k != g && k != HalfedgeMesh::next(h)) {
            old_min_j = std::min(old_min_j, inscribed_radius(xj, b, c, cr));
            changed_.push_back({b, c, false, false});
        }
        k = mesh.rotate(k);
    } while (k != g);

    // The volume change of the merge with j in place: with the origin at x_i
    // the old fan adds nothing and each new triangle (j, b, c) adds
    // (x_j - x_i) . ((b - x_i) x (c - x_i)) / 6. The volume is linear in x_j
    // with gradient N_j / 3, N_j the area vector of j's new fan, so moving j
    // by -3 dV N_j / |N_j|^2 puts it back exactly.
    double six_dV = 0;
    Vec3 two_N{};
    for (const Tri& tri : changed_) {
        if (tri.from_i) six_dV += dot(xj - xi, cross(tri.b - xi, tri.c - xi));
        two_N += cross(tri.b - xj, tri.c - xj);
    }
    Vec3 shift{};
    if (drift && !held(mesh, j) && norm2(two_N) > 0)
        shift = (-six_dV / norm2(two_N)) * two_N; // -3 dV N / |N|^2, dV = six_dV / 6, N = two_N / 2
    const bool moves = !(shift == Vec3{});
    const Vec3 xn = xj + shift;
    const Vec3 total_shift = moves ? (*drift)[j] + shift : Vec3{};
    check.shift = shift;
    check.volume_change = moves ? 0.0 : six_dV / 6;

    // Damage (A.1): the height of x_i over each new triangle; a moving j adds
    // its height (all its moves so far included) over each triangle it spans.
    // Fold check (A.3): each new normal against the area-weighted patch
    // normal (A.2) of the fan the triangle came from.
    const Vec3 patch_i = normalized(fan_i), patch_i_across = normalized(fan_i_across), patch_j = normalized(fan_j);
    double damage = 0, new_min = inf;
    bool folded = false;
    for (const Tri& tri : changed_) {
        if (!tri.from_i && !moves) continue;
        const Vec3 u = tri.b - xn, v = tri.c - xn;
        const Vec3 cr = cross(u, v);
        if (degenerate(cr, u, v)) return reject(Verdict::degenerate);
        const Vec3 n = cr / norm(cr);
        double height = std::abs(dot(total_shift, n));
        if (tri.from_i) height = std::max(height, std::abs(dot(xi - xn, n)));
        damage = std::max(damage, height);
        folded |= dot(n, !tri.from_i ? patch_j : tri.across ? patch_i_across : patch_i) <= 0;
        new_min = std::min(new_min, inscribed_radius(xn, tri.b, tri.c, cr));
    }
    check.damage = damage = std::max(damage, check.damage);
    if (!(damage < check.toldamage)) return reject(Verdict::damage);
    if (folded) return reject(Verdict::fold);

    // Algorithm 3: at least half the old smallest inscribed radius; where the
    // old one is already below a tenth of merge_length, no smaller at all.
    const double old_min = moves ? std::min(old_min_i, old_min_j) : old_min_i;
    const double required = old_min < 0.05 * t ? old_min : 0.5 * old_min;
    if (new_min < required) return reject(Verdict::inscribed_radius);
    return check;
}

Check Criteria::swap(const HalfedgeMesh& mesh, const std::vector<double>& d, int32_t h) const
{
    Check check;
    const int32_t g = mesh.twin(h);
    const int32_t a = mesh.from(h), b = mesh.to(h), c = mesh.opposite(h), e = mesh.opposite(g);
    check.toldamage = target(0.5 * (d[a] + d[b])) / 30;
    auto reject = [&check](Verdict v) {
        check.verdict = v;
        return check;
    };
    if (mesh.patch(HalfedgeMesh::face(h)) != mesh.patch(HalfedgeMesh::face(g))) return reject(Verdict::patch_border);
    // With c and e already joined the swap would duplicate an edge (this also
    // refuses a or b of valence three, which would be left with two).
    if (c == e || mesh.find_halfedge(c, e) >= 0) return reject(Verdict::topology);

    const Vec3 &xa = mesh.points[a], &xb = mesh.points[b], &xc = mesh.points[c], &xe = mesh.points[e];
    const double before = std::min(min_angle(xa, xb, xc), min_angle(xb, xa, xe));
    const double after = std::min(min_angle(xc, xa, xe), min_angle(xe, xb, xc));
    // The margin keeps round-off from swapping an edge back and forth.
    if (!(after > before + 1e-9)) return reject(Verdict::no_gain);

    const Vec3 u1 = xa - xc, v1 = xe - xc, u2 = xb - xe, v2 = xc - xe;
    const Vec3 cr1 = cross(u1, v1), cr2 = cross(u2, v2);
    if (degenerate(cr1, u1, v1) || degenerate(cr2, u2, v2)) return reject(Verdict::degenerate);
    const Vec3 n1 = cr1 / norm(cr1), n2 = cr2 / norm(cr2);

    // Appendix B: the swap is the merge of the old edge's midpoint into c
    // (or e: both new triangles hold both), damage (A.1) its height over them.
    const Vec3 m = 0.5 * (xa + xb);
    check.damage = std::max(std::abs(dot(m - xc, n1)), std::abs(dot(m - xc, n2)));
    if (!(check.damage < check.toldamage)) return reject(Verdict::damage);

    const Vec3 old1 = cross(xb - xa, xc - xa), old2 = cross(xa - xb, xe - xb);
    const Vec3 patch = old1 + old2;
    if (dot(n1, patch) <= 0 || dot(n2, patch) <= 0) return reject(Verdict::fold);
    // Each new normal within a right angle of each old one too: where the
    // two old triangles meet at a sharp crease (as where a branch leaves its
    // parent) their sum says little, and the swap can lay a new triangle
    // over the fan beside it. An old triangle too flat to have a normal
    // (a needle the swap would remove) is left out.
    const bool has_normal1 = !degenerate(old1, xb - xa, xc - xa), has_normal2 = !degenerate(old2, xa - xb, xe - xb);
    if ((has_normal1 && (dot(n1, old1) <= 0 || dot(n2, old1) <= 0)) ||
        (has_normal2 && (dot(n1, old2) <= 0 || dot(n2, old2) <= 0)))
        return reject(Verdict::fold);
    // With the origin at x_c only the old triangle (b, a, e) adds volume.
    check.volume_change = -dot(xb - xc, cross(xa - xc, xe - xc)) / 6;
    return check;
}

Check check_merge(const SurfaceMesh& surface, const std::vector<double>& d, int32_t i, int32_t j,
                  const RemeshParams& params)
{
    check_indices(surface, d, i, j, "check_merge");
    const HalfedgeMesh mesh(surface);
    const int32_t h = checked_edge(mesh, i, j, "merge a point into one of its neighbours");
    Criteria criteria(params);
    return criteria.merge(mesh, d, nullptr, h);
}

Check check_swap(const SurfaceMesh& surface, const std::vector<double>& d, int32_t a, int32_t b,
                 const RemeshParams& params)
{
    check_indices(surface, d, a, b, "check_swap");
    const HalfedgeMesh mesh(surface);
    const int32_t h = checked_edge(mesh, a, b, "swap an edge of the surface");
    return Criteria(params).swap(mesh, d, h);
}

} // namespace scalemesh::remeshing
