#pragma once
// Private to src/remeshing: a half-edge view of a closed, oriented 2-manifold
// triangle mesh that supports the three local operations of paper section 2.2
// (edge bisection, edge collapse for node merging, edge swap) in O(valence)
// time each, without rebuilding any global adjacency.
//
// Half-edge h = 3 f + k is the k-th edge of face f, running from corner k to
// corner k + 1 (mod 3); next and prev stay inside the face. Every half-edge
// has a twin on the neighbouring face (the surface is closed). Each live
// vertex keeps one outgoing half-edge. Dead faces are reused by later splits;
// vertex ids are never reused, so per-vertex data kept by the caller stays
// valid (splits append one id).

#include "core/surface_mesh.h"

#include <cstdint>
#include <vector>

namespace scalemesh::remeshing {

class HalfedgeMesh {
public:
    // Builds the structure. The caller guarantees a closed, oriented
    // 2-manifold (require_closed_manifold); points used by no triangle become
    // dead vertices and are dropped by to_surface.
    explicit HalfedgeMesh(const SurfaceMesh& surface);

    // Live faces as index arrays, live vertices renumbered in increasing id
    // order. `vertex_of_point`, when given, receives the vertex id of each
    // output point. triangle_patch is empty when the input's was.
    SurfaceMesh to_surface(std::vector<int32_t>* vertex_of_point = nullptr) const;

    // Replaces the positions of the live vertices, in the order to_surface
    // numbers them (used after smoothing a to_surface copy).
    void set_positions(const std::vector<Vec3>& points, const std::vector<int32_t>& vertex_of_point);

    static int32_t face(int32_t h) { return h / 3; }
    static int32_t next(int32_t h) { return h % 3 == 2 ? h - 2 : h + 1; }
    static int32_t prev(int32_t h) { return h % 3 == 0 ? h + 2 : h - 1; }
    int32_t twin(int32_t h) const { return twin_[h]; }
    int32_t from(int32_t h) const { return corner_[h]; }
    int32_t to(int32_t h) const { return corner_[next(h)]; }
    // The vertex of h's face that is not on h.
    int32_t opposite(int32_t h) const { return corner_[prev(h)]; }
    // One outgoing half-edge of a live vertex; -1 for a dead one.
    int32_t outgoing(int32_t v) const { return out_[v]; }
    // The next outgoing half-edge around from(h), counter-clockwise seen from
    // outside: from the edge to b of face (v, b, c) to the edge to c.
    int32_t rotate(int32_t h) const { return twin_[prev(h)]; }
    int32_t halfedge_capacity() const { return static_cast<int32_t>(corner_.size()); }
    bool face_alive(int32_t f) const { return corner_[3 * f] >= 0; }
    int32_t face_capacity() const { return static_cast<int32_t>(patch_.size()); }
    int32_t patch(int32_t f) const { return patch_[f]; }
    bool has_patches() const { return has_patches_; }

    int32_t vertex_capacity() const { return static_cast<int32_t>(points.size()); }
    bool vertex_alive(int32_t v) const { return out_[v] >= 0; }
    int64_t live_faces() const { return live_faces_; }
    int32_t valence(int32_t v) const;
    // The first half-edge leaving v, turning from outgoing(v) by rotate,
    // for which found(h) holds, or -1.
    template <class Predicate>
    int32_t find_outgoing(int32_t v, Predicate&& found) const
    {
        const int32_t start = out_[v];
        int32_t h = start;
        do {
            if (found(h)) return h;
            h = rotate(h);
        } while (h != start);
        return -1;
    }
    // The half-edge a -> b, or -1 when a and b are not joined.
    int32_t find_halfedge(int32_t a, int32_t b) const;
    // True when the faces around v do not all carry the same patch.
    bool on_patch_boundary(int32_t v) const;
    // True when the two faces of h's edge carry different patches.
    bool border_edge(int32_t h) const { return patch_[face(h)] != patch_[face(twin_[h])]; }
    // The number of v's edges that are border edges: 0 inside a patch, 2 on
    // a rim between two patches, 3 or more at a corner (or where a patch
    // touches itself).
    int32_t border_edges(int32_t v) const;

    // Algorithm 2's bisection: inserts a vertex at x on the edge of h and
    // splits both faces of the edge in two. Returns the new vertex id
    // (vertex_capacity() - 1 afterwards). Both halves of each face keep its patch.
    int32_t split(int32_t h, const Vec3& x);
    // Algorithm 3's merge from(h) -> to(h): from(h) dies, its corners become
    // to(h), the two faces of the edge die. The caller checks the link
    // condition first; to(h) keeps its position.
    void collapse(int32_t h);
    // As collapse, but the two faces that die go to `freed` instead of the
    // mesh's free list, and live_faces() is not updated: collapses in
    // disjoint regions may run at once (each touches only faces with all
    // their corners within two edges of from(h)), and hand their faces back
    // afterwards, in an order of the caller's, with release_faces.
    void collapse(int32_t h, std::vector<int32_t>& freed);
    // Puts faces collapse(h, freed) took onto the free list, in order.
    void release_faces(const std::vector<int32_t>& freed);
    // Swaps the edge of h to join the two vertices opposite it (Fig. 9).
    // The caller checks that the new edge does not exist yet.
    void flip(int32_t h);

    std::vector<Vec3> points; // mm, by vertex id; dead vertices keep stale values

private:
    int32_t new_face(int32_t patch);

    std::vector<int32_t> corner_; // vertex at each corner, -1 on dead faces
    std::vector<int32_t> twin_;
    std::vector<int32_t> out_;
    std::vector<int32_t> patch_;
    std::vector<int32_t> free_faces_;
    int64_t live_faces_ = 0;
    bool has_patches_ = false;
};

} // namespace scalemesh::remeshing
