#pragma once
// Private to src/remeshing (tests include it): the acceptance tests of a node
// merge (Algorithm 3 with Appendix A) and of an edge swap (Fig. 9 with
// Appendix B), on the half-edge mesh, without changing it.

#include "remeshing/halfedge_mesh.h"
#include "remeshing/remesh.h"

#include <cstdint>
#include <limits>
#include <vector>

namespace scalemesh::remeshing {

enum class Verdict {
    accepted,
    too_long,         // merge: |x_i - x_j| >= K/(2M) d(x_i)
    patch_border,     // merge of a node on a patch border, swap of an edge between patches
    topology,         // link condition, valence or existing edge
    degenerate,       // a new triangle of (near) zero area
    damage,           // eq. (A.1) at or above K/(30M) d
    fold,             // eq. (A.3) fails
    inscribed_radius, // Algorithm 3's inscribed radius test fails
    no_gain,          // swap: the smallest of the six angles does not grow
};

struct Check {
    Verdict verdict = Verdict::accepted;
    double damage = 0;    // mm, eq. (A.1) (for a swap: of its midpoint merge)
    double toldamage = 0; // mm, K/(30M) d
    double volume_change = 0; // mm^3, enclosed volume after minus before
    Vec3 shift;               // mm, merge: the move of the surviving node that keeps the volume
};

// Evaluates the tests in a fixed order, cheapest first, and stops at the
// first that fails. Holds scratch space, so one instance per thread.
class Criteria {
public:
    explicit Criteria(const RemeshParams& params) : K_(params.K), M_(params.M), patch_normals_(params.patch_normals) {}

    // Vertex ids below n are input points (splits append ids above): the
    // only survivors a rim merge may have.
    void set_input_points(int32_t n) { input_points_ = n; }

    // Target edge length K/M d (mm).
    double target(double d) const { return K_ / M_ * d; }
    // True when the patch is flat (a cap): params.patch_normals holds a
    // non-zero normal for it.
    bool planar(int32_t patch) const
    {
        return patch >= 0 && static_cast<size_t>(patch) < patch_normals_.size() && !(patch_normals_[patch] == Vec3{});
    }
    // True when v may not move off where it is: on a patch border, or inside
    // a flat patch (where it may move only within the plane).
    bool held(const HalfedgeMesh& mesh, int32_t v) const
    {
        return mesh.on_patch_boundary(v) || planar(mesh.patch(HalfedgeMesh::face(mesh.outgoing(v))));
    }

    // Algorithm 3's tests for merging from(h) into to(h), with d per vertex
    // id. from(h) inside a patch may merge into any neighbour; on a rim
    // between a flat patch and another (two border edges) only along one of
    // its two border edges, into an input point, with the rim's sagitta
    // counted as damage; elsewhere on a border (corners, borders between
    // two curved patches) never. With `drift` (per vertex id, the sum of the
    // moves a node has made so far) the surviving node moves along its fan's
    // area normal so that the merge keeps the enclosed volume exactly,
    // unless it is held (on a border or a flat patch); its damage then
    // includes the height of its total move, so that repeated merges into
    // one node cannot walk it off the surface. Without `drift` it stays put,
    // as in the paper. The fold check (A.3) compares each new triangle with
    // the area normal of the part of from(h)'s fan in its own patch.
    Check merge(const HalfedgeMesh& mesh, const std::vector<double>& d, const std::vector<Vec3>* drift, int32_t h);
    // The swap tests for the edge of h.
    Check swap(const HalfedgeMesh& mesh, const std::vector<double>& d, int32_t h) const;

private:
    bool link_condition(const HalfedgeMesh& mesh, int32_t h);

    double K_, M_;
    std::vector<Vec3> patch_normals_;
    int32_t input_points_ = std::numeric_limits<int32_t>::max();
    std::vector<uint32_t> stamp_; // per vertex id, for the link condition
    uint32_t current_stamp_ = 0;
    struct Tri {
        Vec3 b, c;   // the two vertices other than the merged node, counter-clockwise
        bool from_i; // in i's fan (else in j's untouched fan)
        bool across; // in i's fan, in another patch than the face of h (a rim node's other side)
    };
    std::vector<Tri> changed_;
};

// The merge test on a plain surface, for tests: builds the half-edge mesh of
// `surface` (a closed, oriented 2-manifold) and checks merging point i into
// its neighbour j. Throws InputError when i and j are not joined by an edge.
Check check_merge(const SurfaceMesh& surface, const std::vector<double>& d, int32_t i, int32_t j,
                  const RemeshParams& params);

// The swap test on a plain surface, for tests: swapping the edge from point
// a to point b (an edge of `surface`, a closed, oriented 2-manifold).
// Throws InputError when a and b are not joined by an edge.
Check check_swap(const SurfaceMesh& surface, const std::vector<double>& d, int32_t a, int32_t b,
                 const RemeshParams& params);

} // namespace scalemesh::remeshing
