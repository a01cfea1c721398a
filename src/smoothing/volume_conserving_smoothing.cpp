#include "smoothing/volume_conserving_smoothing.h"

#include "core/adjacency.h"
#include "core/errors.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

namespace scalemesh {

namespace {

bool finite(const Vec3& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

void validate(const SurfaceMesh& mesh, const SmoothingParams& params, const SmoothingConstraint* constraint)
{
    if (params.sweeps < 0)
        throw InputError("smoothing sweeps is " + std::to_string(params.sweeps), "use a count >= 0 (the paper uses 10)");
    if (!(params.omega > 0 && params.omega <= 1))
        throw InputError("smoothing under-relaxation omega is " + std::to_string(params.omega),
                         "use a value in (0, 1] (the paper uses 1 after marching cubes, 0.1 after remeshing)");
    if (!(params.max_displacement >= 0) || !std::isfinite(params.max_displacement))
        throw InputError("smoothing max_displacement is " + std::to_string(params.max_displacement),
                         "use a distance >= 0 in mm (0: unbounded)");
    require_closed_manifold(mesh, "the surface to smooth");
    for (size_t i = 0; i < mesh.points.size(); ++i)
        if (!finite(mesh.points[i]))
            throw InputError("point " + std::to_string(i) + " of the surface to smooth is not finite",
                             "give finite coordinates");
    if (!constraint) return;
    const size_t n = mesh.points.size();
    if (!constraint->fixed.empty() && constraint->fixed.size() != n)
        throw InputError("smoothing constraint has " + std::to_string(constraint->fixed.size()) +
                             " fixed flags for " + std::to_string(n) + " points",
                         "give one flag per point, or none");
    if (!constraint->plane_normal.empty() && constraint->plane_normal.size() != n)
        throw InputError("smoothing constraint has " + std::to_string(constraint->plane_normal.size()) +
                             " plane normals for " + std::to_string(n) + " points",
                         "give one normal per point (zero for a free point), or none");
    for (size_t i = 0; i < constraint->plane_normal.size(); ++i)
        if (!finite(constraint->plane_normal[i]))
            throw InputError("smoothing constraint plane normal of point " + std::to_string(i) + " is not finite",
                             "give a finite normal, or zero for a free point");
}

class VolumeConservingSmoother {
public:
    VolumeConservingSmoother(SurfaceMesh& mesh, const SmoothingConstraint* constraint, double max_displacement)
        : mesh_(mesh), fans_(vertex_triangles(mesh)), neighbours_(vertex_neighbours(mesh)), constraint_(constraint),
          start_(max_displacement > 0 ? mesh.points : std::vector<Vec3>{}), reach2_(max_displacement * max_displacement)
    {
        plan_sweep();
    }

    // One sweep: the colours in turn; within a colour the cells in parallel,
    // each cell's nodes in index order (see plan_sweep).
    void sweep(double omega)
    {
        for (size_t colour = 0; colour + 1 < colour_begin_.size(); ++colour)
            tbb::parallel_for(tbb::blocked_range<size_t>(colour_begin_[colour], colour_begin_[colour + 1], 1),
                              [&](const tbb::blocked_range<size_t>& cells) {
                                  for (size_t c = cells.begin(); c != cells.end(); ++c)
                                      for (size_t k = cell_begin_[c]; k != cell_begin_[c + 1]; ++k)
                                          relax(order_[k], omega);
                              });
    }

    // The order of a sweep. Relaxing node i reads the points within two
    // edges of i (its neighbours' means and fans) and writes i and one
    // neighbour, so two nodes more than three edges apart can be relaxed at
    // the same time, and in either order with the same result. A path of
    // three edges is at most 3 l long, l the longest edge now (connectivity
    // never changes, so this holds for the whole smoothing), so the nodes are
    // put in cubic cells of side h > 3 l and the cells get one of eight
    // colours by the parity of their three grid indices: two cells of one
    // colour have a whole cell between them along some axis, so their nodes
    // are more than 3 l, hence more than three edges, apart. A sweep then
    // takes the colours in turn and the cells of a colour in parallel, each
    // cell's nodes in index order: the same as a sequential Gauss-Seidel
    // sweep in that order, bit for bit, whatever the number of threads.
    void plan_sweep()
    {
        const auto n = static_cast<int32_t>(mesh_.points.size());
        double longest2 = 0;
        for (const Triangle& t : mesh_.triangles)
            for (int e = 0; e < 3; ++e)
                longest2 = std::max(longest2, norm2(mesh_.points[t[e]] - mesh_.points[t[(e + 1) % 3]]));
        Vec3 lo, hi;
        bounding_box(mesh_, lo, hi);
        const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
        // 0.1% over 3 l absorbs the rounding of the cell indices; at most
        // 2^20 cells per axis keeps a cell's key in 64 bits.
        double h = std::max(3.003 * std::sqrt(longest2), extent / double(kMaxCells - 2));
        if (!(h > 0) || !std::isfinite(h)) h = std::numeric_limits<double>::max(); // one cell
        auto index = [&](double x, double x0) {
            return static_cast<uint64_t>(std::min(double(kMaxCells - 1), std::max(0.0, std::floor((x - x0) / h))));
        };
        std::vector<std::pair<uint64_t, int32_t>> keyed(n);
        tbb::parallel_for(tbb::blocked_range<int32_t>(0, n, 4096), [&](const tbb::blocked_range<int32_t>& range) {
            for (int32_t i = range.begin(); i != range.end(); ++i) {
                const Vec3& p = mesh_.points[i];
                const uint64_t cx = index(p.x, lo.x), cy = index(p.y, lo.y), cz = index(p.z, lo.z);
                const uint64_t colour = (cx & 1) | (cy & 1) << 1 | (cz & 1) << 2;
                keyed[i] = {colour << 60 | cx << 40 | cy << 20 | cz, i};
            }
        });
        tbb::parallel_sort(keyed.begin(), keyed.end());
        order_.resize(n);
        cell_begin_.clear();
        colour_begin_.assign(9, 0);
        for (int32_t k = 0; k < n; ++k) {
            order_[k] = keyed[k].second;
            if (k == 0 || keyed[k].first != keyed[k - 1].first) cell_begin_.push_back(k);
        }
        cell_begin_.push_back(n);
        // colour_begin_[c]: the first cell of colour c or above.
        size_t cell = 0;
        for (uint64_t colour = 0; colour < 8; ++colour) {
            while (cell + 1 < cell_begin_.size() && (keyed[cell_begin_[cell]].first >> 60) < colour) ++cell;
            colour_begin_[colour] = cell;
        }
        colour_begin_[8] = cell_begin_.size() - 1;
    }

    void relax(int32_t i, double omega)
    {
        if (neighbours_.size(i) == 0 || is_fixed(i)) return;
        const Vec3 move = omega * (neighbour_mean(i) - mesh_.points[i]);
        const Vec3 N = volume_gradient(i);
        if (is_free(i) && relax_pair(i, move, N, omega)) return;
        mesh_.points[i] += within_reach(i, conserving_part(move, N, plane_normal(i)));
    }

private:
    bool is_free(int32_t i) const { return !is_fixed(i) && norm2(plane_normal(i)) == 0; }

    // Two-node relaxation of [13]: nodes i and j make their Laplacian moves
    // d_i and d_j in full, normal parts included, and then one shared move
    // h n that puts the volume back. Moving only i and j changes the volume
    // by (d_i . N_i + d_j . N_j) / 3 + d_i . (d_j x v) / 6, v = x_p - x_q the
    // vertices opposite the edge (p in the triangle running i -> j), and a
    // shared move h n adds h n . A with A = (N_i + N_j) / 3 + v x (d_i - d_j) / 6
    // (no h^2 term: n . (n x v) = 0), so h = -change / |A| along n = A / |A|
    // restores it exactly. Unlike a single node, a pair can trade volume
    // between its nodes, which is what lets a spike come down. The partner
    // is the free neighbour whose own Laplacian move changes the volume most
    // in the opposite sense; without one, i falls back to the single-node move.
    bool relax_pair(int32_t i, const Vec3& d_i, const Vec3& N_i, double omega)
    {
        const double change_i = dot(d_i, N_i);
        int32_t j = -1;
        Vec3 d_j, N_j;
        double best = 0;
        for (const int32_t* k = neighbours_.begin(i); k != neighbours_.end(i); ++k) {
            if (!is_free(*k)) continue;
            const Vec3 d_k = omega * (neighbour_mean(*k) - mesh_.points[*k]);
            const Vec3 N_k = volume_gradient(*k);
            const double opposition = -change_i * dot(d_k, N_k);
            if (opposition > best) best = opposition, j = *k, d_j = d_k, N_j = N_k;
        }
        if (j < 0) return false;

        int32_t p = -1, q = -1;
        for (const int32_t* f = fans_.begin(i); f != fans_.end(i); ++f) {
            const Triangle& t = mesh_.triangles[*f];
            const int k = t[0] == i ? 0 : (t[1] == i ? 1 : 2);
            if (t[(k + 1) % 3] == j) p = t[(k + 2) % 3];
            if (t[(k + 2) % 3] == j) q = t[(k + 1) % 3];
        }
        if (p < 0 || q < 0) return false;
        const Vec3 v = mesh_.points[p] - mesh_.points[q];

        const double change = (change_i + dot(d_j, N_j)) / 3.0 + dot(d_i, cross(d_j, v)) / 6.0;
        const Vec3 A = (N_i + N_j) / 3.0 + cross(v, d_i - d_j) / 6.0;
        const double length = norm(A);
        // A vanishes only for a degenerate pair; leave it to the single-node move.
        if (!(length > kTinyGradient * (norm(N_i) + norm(N_j)))) return false;
        const Vec3 shared = (-change / length) * (A / length);
        const Vec3 xi = mesh_.points[i] + d_i + shared, xj = mesh_.points[j] + d_j + shared;
        if (!reachable(i, xi) || !reachable(j, xj)) return false;
        mesh_.points[i] = xi;
        mesh_.points[j] = xj;
        return true;
    }

    bool reachable(int32_t i, const Vec3& x) const { return start_.empty() || norm2(x - start_[i]) <= reach2_; }

    // The longest part t * move, t in [0, 1], that keeps node i within reach
    // of its start (the node is within reach before the move).
    Vec3 within_reach(int32_t i, const Vec3& move) const
    {
        if (reachable(i, mesh_.points[i] + move)) return move;
        // |o + t m|^2 = reach^2 with o the current offset from the start.
        const Vec3 o = mesh_.points[i] - start_[i];
        const double a = norm2(move), b = dot(o, move), c = norm2(o) - reach2_;
        const double t = (-b + std::sqrt(std::max(0.0, b * b - a * c))) / a;
        return std::clamp(t, 0.0, 1.0) * move;
    }

    static constexpr double kTinyGradient = 1e-12;

    bool is_fixed(int32_t i) const { return constraint_ && !constraint_->fixed.empty() && constraint_->fixed[i]; }

    Vec3 plane_normal(int32_t i) const
    {
        return constraint_ && !constraint_->plane_normal.empty() ? constraint_->plane_normal[i] : Vec3{};
    }

    Vec3 neighbour_mean(int32_t i) const
    {
        Vec3 sum;
        for (const int32_t* j = neighbours_.begin(i); j != neighbours_.end(i); ++j) sum += mesh_.points[*j];
        return sum / neighbours_.size(i);
    }

    // N_i = (1/2) sum (x_j x x_k) over the fan of i. Around a closed fan the
    // sum is unchanged by a translation, so it is taken relative to x_i: far
    // from the origin the absolute cross products would cancel and lose digits.
    Vec3 volume_gradient(int32_t i) const
    {
        const Vec3& xi = mesh_.points[i];
        Vec3 n;
        for (const int32_t* f = fans_.begin(i); f != fans_.end(i); ++f) {
            const Triangle& t = mesh_.triangles[*f];
            const int k = t[0] == i ? 0 : (t[1] == i ? 1 : 2);
            n += cross(mesh_.points[t[(k + 1) % 3]] - xi, mesh_.points[t[(k + 2) % 3]] - xi);
        }
        return 0.5 * n;
    }

    // The part of `move` that keeps the volume (orthogonal to n) and, when a
    // plane is given, stays in the plane. The plane component is removed
    // first, exactly; then the component along the in-plane part of n. That
    // equals projecting onto the line orthogonal to both, and stays stable as
    // n approaches the plane normal: the residual along n is round-off of n
    // whatever the angle. When n is parallel to the plane normal the fan lies
    // in the plane, and every in-plane move already keeps the volume.
    static Vec3 conserving_part(Vec3 move, const Vec3& n, const Vec3& plane)
    {
        if (norm2(plane) > 0) {
            const Vec3 p = normalized(plane);
            move -= dot(move, p) * p;
            const Vec3 n_in_plane = n - dot(n, p) * p;
            if (norm2(n_in_plane) > kParallel2 * norm2(n))
                move -= dot(move, n_in_plane) / norm2(n_in_plane) * n_in_plane;
            return move;
        }
        if (norm2(n) > 0) move -= dot(move, n) / norm2(n) * n;
        return move;
    }

    // sin^2 of the angle below which n and the plane normal count as parallel.
    static constexpr double kParallel2 = 1e-24;

    SurfaceMesh& mesh_;
    VertexTable fans_;
    VertexTable neighbours_;
    const SmoothingConstraint* constraint_;
    std::vector<Vec3> start_; // starting positions, kept only when the reach is bounded
    double reach2_;
    static constexpr uint64_t kMaxCells = uint64_t(1) << 20; // per axis
    std::vector<int32_t> order_;      // the nodes, cell by cell
    std::vector<size_t> cell_begin_;  // cell c holds order_[cell_begin_[c], cell_begin_[c + 1])
    std::vector<size_t> colour_begin_; // colour c holds cells [colour_begin_[c], colour_begin_[c + 1])
};

} // namespace

void smooth_volume_conserving(SurfaceMesh& mesh, const SmoothingParams& params, const SmoothingConstraint* constraint)
{
    validate(mesh, params, constraint);
    VolumeConservingSmoother smoother(mesh, constraint, params.max_displacement);
    for (int s = 0; s < params.sweeps; ++s) smoother.sweep(params.omega);
}

} // namespace scalemesh
