#include "remeshing/halfedge_mesh.h"

#include <algorithm>

namespace scalemesh::remeshing {

HalfedgeMesh::HalfedgeMesh(const SurfaceMesh& surface) : points(surface.points)
{
    const auto nv = static_cast<int32_t>(surface.points.size());
    const auto nf = static_cast<int32_t>(surface.triangles.size());
    corner_.resize(3 * static_cast<size_t>(nf));
    for (int32_t f = 0; f < nf; ++f)
        for (int k = 0; k < 3; ++k) corner_[3 * f + k] = surface.triangles[f][k];
    patch_.assign(nf, 0);
    if (surface.triangle_patch.size() == static_cast<size_t>(nf)) {
        patch_ = surface.triangle_patch;
        has_patches_ = true;
    }
    live_faces_ = nf;

    // Outgoing half-edges per vertex in compressed rows; the twin of a -> b is
    // the half-edge b -> a in b's row.
    std::vector<int32_t> offsets(nv + 1, 0);
    for (int32_t h = 0; h < 3 * nf; ++h) ++offsets[corner_[h] + 1];
    for (int32_t v = 0; v < nv; ++v) offsets[v + 1] += offsets[v];
    std::vector<int32_t> rows(offsets[nv]);
    std::vector<int32_t> fill(offsets.begin(), offsets.end() - 1);
    for (int32_t h = 0; h < 3 * nf; ++h) rows[fill[corner_[h]]++] = h;

    twin_.assign(corner_.size(), -1);
    out_.assign(nv, -1);
    for (int32_t h = 0; h < 3 * nf; ++h) {
        const int32_t a = from(h), b = to(h);
        out_[a] = h;
        for (int32_t r = offsets[b]; r < offsets[b + 1]; ++r)
            if (to(rows[r]) == a) {
                twin_[h] = rows[r];
                break;
            }
    }
}

SurfaceMesh HalfedgeMesh::to_surface(std::vector<int32_t>* vertex_of_point) const
{
    SurfaceMesh surface;
    std::vector<int32_t> index(points.size(), -1);
    std::vector<int32_t> vertex;
    for (int32_t v = 0; v < vertex_capacity(); ++v)
        if (vertex_alive(v)) {
            index[v] = static_cast<int32_t>(vertex.size());
            vertex.push_back(v);
            surface.points.push_back(points[v]);
        }
    surface.triangles.reserve(live_faces_);
    for (int32_t f = 0; f < face_capacity(); ++f) {
        if (!face_alive(f)) continue;
        surface.triangles.push_back({index[corner_[3 * f]], index[corner_[3 * f + 1]], index[corner_[3 * f + 2]]});
        if (has_patches_) surface.triangle_patch.push_back(patch_[f]);
    }
    if (vertex_of_point) *vertex_of_point = std::move(vertex);
    return surface;
}

void HalfedgeMesh::set_positions(const std::vector<Vec3>& new_points, const std::vector<int32_t>& vertex_of_point)
{
    for (size_t p = 0; p < vertex_of_point.size(); ++p) points[vertex_of_point[p]] = new_points[p];
}

int32_t HalfedgeMesh::valence(int32_t v) const
{
    int32_t n = 0;
    find_outgoing(v, [&](int32_t) {
        ++n;
        return false; // the whole fan round
    });
    return n;
}

int32_t HalfedgeMesh::find_halfedge(int32_t a, int32_t b) const
{
    return find_outgoing(a, [&](int32_t h) { return to(h) == b; });
}

bool HalfedgeMesh::on_patch_boundary(int32_t v) const
{
    if (!has_patches_) return false;
    const int32_t p = patch_[face(out_[v])];
    return find_outgoing(v, [&](int32_t h) { return patch_[face(h)] != p; }) >= 0;
}

int32_t HalfedgeMesh::border_edges(int32_t v) const
{
    if (!has_patches_) return 0;
    int32_t n = 0;
    find_outgoing(v, [&](int32_t h) {
        n += border_edge(h);
        return false; // the whole fan round
    });
    return n;
}

int32_t HalfedgeMesh::new_face(int32_t patch)
{
    int32_t f;
    if (!free_faces_.empty()) {
        f = free_faces_.back();
        free_faces_.pop_back();
        patch_[f] = patch;
    } else {
        f = face_capacity();
        corner_.resize(corner_.size() + 3);
        twin_.resize(twin_.size() + 3);
        patch_.push_back(patch);
    }
    ++live_faces_;
    return f;
}

int32_t HalfedgeMesh::split(int32_t h, const Vec3& x)
{
    // Faces (a, b, c) on h and (b, a, e) on its twin g become (a, m, c),
    // (m, b, c) and (b, m, e), (m, a, e).
    const int32_t g = twin_[h];
    const int32_t a = from(h), b = to(h), c = opposite(h), e = opposite(g);
    const int32_t m = vertex_capacity();
    points.push_back(x);
    out_.push_back(-1);

    const int32_t f2 = new_face(patch_[face(h)]);
    const int32_t f3 = new_face(patch_[face(g)]);
    const int32_t p0 = 3 * f2, p1 = p0 + 1, p2 = p0 + 2; // m->b, b->c, c->m
    const int32_t q0 = 3 * f3, q1 = q0 + 1, q2 = q0 + 2; // m->a, a->e, e->m
    corner_[p0] = m, corner_[p1] = b, corner_[p2] = c;
    corner_[q0] = m, corner_[q1] = a, corner_[q2] = e;

    const int32_t hn = next(h), gn = next(g);
    const int32_t t_bc = twin_[hn], t_ae = twin_[gn];
    corner_[hn] = m; // h: a->m, hn: m->c
    corner_[gn] = m; // g: b->m, gn: m->e

    twin_[p1] = t_bc, twin_[t_bc] = p1;
    twin_[hn] = p2, twin_[p2] = hn;
    twin_[q1] = t_ae, twin_[t_ae] = q1;
    twin_[gn] = q2, twin_[q2] = gn;
    twin_[h] = q0, twin_[q0] = h;
    twin_[g] = p0, twin_[p0] = g;

    out_[a] = h;
    out_[b] = g;
    out_[m] = p0;
    return m;
}

void HalfedgeMesh::collapse(int32_t h)
{
    collapse(h, free_faces_);
    live_faces_ -= 2;
}

void HalfedgeMesh::release_faces(const std::vector<int32_t>& freed)
{
    free_faces_.insert(free_faces_.end(), freed.begin(), freed.end());
    live_faces_ -= static_cast<int64_t>(freed.size());
}

void HalfedgeMesh::collapse(int32_t h, std::vector<int32_t>& freed)
{
    const int32_t g = twin_[h];
    const int32_t i = from(h), j = to(h);
    int32_t k = h;
    do {
        corner_[k] = j;
        k = rotate(k);
    } while (k != h);

    // Face (j, c, i) of h and (i, j, e) of g disappear; glue the two pairs of
    // edges each leaves behind.
    const int32_t hn = next(h), hp = prev(h), gn = next(g), gp = prev(g);
    const int32_t A = twin_[hn]; // c -> j
    const int32_t B = twin_[hp]; // j -> c (was i -> c)
    const int32_t C = twin_[gn]; // e -> j (was e -> i)
    const int32_t D = twin_[gp]; // j -> e
    twin_[A] = B, twin_[B] = A;
    twin_[C] = D, twin_[D] = C;
    out_[j] = B;
    out_[from(A)] = A;
    out_[from(C)] = C;
    out_[i] = -1;

    for (int32_t f : {face(h), face(g)}) {
        corner_[3 * f] = corner_[3 * f + 1] = corner_[3 * f + 2] = -1;
        freed.push_back(f);
    }
}

void HalfedgeMesh::flip(int32_t h)
{
    // (a, b, c) and (b, a, e) become (c, a, e) and (e, b, c).
    const int32_t g = twin_[h];
    const int32_t hn = next(h), hp = prev(h), gn = next(g), gp = prev(g);
    const int32_t a = from(h), b = to(h), c = opposite(h), e = opposite(g);
    const int32_t t_bc = twin_[hn], t_ca = twin_[hp], t_ae = twin_[gn], t_eb = twin_[gp];

    corner_[h] = c, corner_[hn] = a, corner_[hp] = e; // h: c->a, hn: a->e, hp: e->c
    corner_[g] = e, corner_[gn] = b, corner_[gp] = c; // g: e->b, gn: b->c, gp: c->e
    twin_[h] = t_ca, twin_[t_ca] = h;
    twin_[hn] = t_ae, twin_[t_ae] = hn;
    twin_[g] = t_eb, twin_[t_eb] = g;
    twin_[gn] = t_bc, twin_[t_bc] = gn;
    twin_[hp] = gp, twin_[gp] = hp;

    out_[a] = hn;
    out_[b] = gn;
    out_[c] = h;
    out_[e] = g;
}

} // namespace scalemesh::remeshing
