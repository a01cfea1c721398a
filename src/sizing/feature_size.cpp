#include "sizing/feature_size.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "sizing/curvature.h"
#include "sizing/local_diameter.h"
#include "sizing/normals.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <string>

namespace scalemesh {

namespace {

using Clock = std::chrono::steady_clock;

void validate_params(const SizingParams& p)
{
    auto bad = [](const std::string& what, double value, const std::string& range) {
        std::ostringstream msg;
        msg << "sizing parameter " << what << " is " << value;
        throw InputError(msg.str(), "the valid range is " + range);
    };
    if (!(p.K > 0) || !std::isfinite(p.K)) bad("K (anisotropy)", p.K, "K > 0, finite (the paper uses 4.2)");
    if (!(p.M >= 1) || !std::isfinite(p.M)) bad("M (layers across)", p.M, "M >= 1, finite (the paper uses 7)");
    if (!(p.G > 0) || !std::isfinite(p.G)) bad("G (gradient limit)", p.G, "G > 0, finite (the paper uses 0.85)");
    if (!(p.L_min > 0) || !std::isfinite(p.L_min))
        bad("L_min (mm)", p.L_min, "0 < L_min <= L_max, finite (usually a fraction of a voxel)");
    if (!(p.L_max >= p.L_min) || !std::isfinite(p.L_max))
        bad("L_max (mm)", p.L_max, "L_min <= L_max, finite (at most the largest dimension of the geometry)");
    if (p.threads < 0) bad("threads", p.threads, "threads >= 0 (0 = default)");
}

void validate_field(const std::vector<double>& field, const char* name, size_t points)
{
    if (field.size() != points)
        throw InputError(std::string("Algorithm 1 got ") + std::to_string(field.size()) + " values of " + name +
                             " for " + std::to_string(points) + " points",
                         "give one value per point");
    for (size_t i = 0; i < field.size(); ++i)
        if (std::isnan(field[i]) || field[i] < 0)
            throw InputError(std::string(name) + " of point " + std::to_string(i) + " is " + std::to_string(field[i]),
                             "local diameters are >= 0 (+infinity allowed)");
}

// Algorithm 1, gradient-limiting part. The relaxation is the paper's: a
// directed edge k -> i with positive excess d_k - (d_i + G |x_k - x_i|) sets
// d_k = d_i + G |x_k - x_i|, until no edge has positive excess. Every order of
// relaxations ends at the same field, the largest one below the clamped d
// that meets the limit: d_k = min over i of (d_i + G * path length from k to
// i), each sum rounded step by step along the path; rounding is monotone and
// G |x_k - x_i| > 0, so this holds bit for bit, not only in exact arithmetic.
// The paper pops the edge of largest excess, which relaxes a node several
// times (five on average on a 763k-vertex torus); here, as in Dijkstra's
// algorithm, nodes are finalised in order of their d, so each edge is
// relaxed once. Most nodes are never lowered (about three in four on the
// pretzel phantom, all of them where d is uniform), so every node first
// takes, in parallel, the limit from its neighbours' clamped values; only
// the nodes that this lowers enter the queue (a binary heap), and the ones
// lowered later from a finalised node join them. A node never lowered keeps
// its clamped value, which the first round has passed on to its
// neighbours; a lowered one passes on its final value when it leaves the
// queue.
class GradientLimiter {
public:
    GradientLimiter(const SurfaceMesh& mesh, const VertexTable& fans, double G, std::vector<double>& d)
        : mesh_(mesh), neighbours_(vertex_neighbours(mesh, fans)), G_(G), d_(d)
    {
    }

    void run()
    {
        const auto n = static_cast<int32_t>(d_.size());
        const std::vector<double> clamped = d_;
        tbb::enumerable_thread_specific<std::vector<Entry>> found;
        tbb::parallel_for(tbb::blocked_range<int32_t>(0, n, 4096), [&](const tbb::blocked_range<int32_t>& range) {
            auto& local = found.local();
            for (int32_t k = range.begin(); k != range.end(); ++k) {
                double best = clamped[k];
                for (const int32_t* i = neighbours_.begin(k); i != neighbours_.end(k); ++i)
                    best = std::min(best, limit(clamped[*i], *i, k));
                if (best < clamped[k]) {
                    d_[k] = best;
                    local.push_back(Entry{best, k});
                }
            }
        });
        std::vector<Entry> lowered; // a heap, smallest on top
        for (const auto& local : found) lowered.insert(lowered.end(), local.begin(), local.end());
        std::make_heap(lowered.begin(), lowered.end(), Greater{});
        std::vector<char> done(n, 0);
        while (!lowered.empty()) {
            std::pop_heap(lowered.begin(), lowered.end(), Greater{});
            const Entry top = lowered.back();
            lowered.pop_back();
            const int32_t i = top.node;
            if (done[i] || top.d != d_[i]) continue; // lowered since
            done[i] = 1;
            for (const int32_t* k = neighbours_.begin(i); k != neighbours_.end(i); ++k) {
                if (done[*k]) continue;
                const double limited = limit(d_[i], i, *k);
                if (d_[*k] > limited) {
                    d_[*k] = limited;
                    lowered.push_back(Entry{limited, *k});
                    std::push_heap(lowered.begin(), lowered.end(), Greater{});
                }
            }
        }
    }

private:
    // The bound node i with size d_i puts on its neighbour k. Both rounds
    // use this one expression, so that the field is the same to the last
    // bit; |x_k - x_i| and |x_i - x_k| round identically, so a relaxed edge
    // has excess 0 both ways.
    double limit(double d_i, int32_t i, int32_t k) const
    {
        return d_i + G_ * distance(mesh_.points[k], mesh_.points[i]);
    }

    struct Entry {
        double d;
        int32_t node;
    };
    // Smallest d first; ties go to the lower node id so that the order of
    // relaxations, and with it every rounding, is reproducible.
    struct Less {
        bool operator()(const Entry& a, const Entry& b) const
        {
            return a.d < b.d || (a.d == b.d && a.node < b.node);
        }
    };
    struct Greater {
        bool operator()(const Entry& a, const Entry& b) const { return Less{}(b, a); }
    };

    const SurfaceMesh& mesh_;
    VertexTable neighbours_;
    double G_;
    std::vector<double>& d_;
};

std::vector<double> limit_with_fans(const SurfaceMesh& mesh, const VertexTable& fans, const std::vector<double>& D,
                                    const std::vector<double>& D_out, const SizingParams& params)
{
    validate_params(params);
    validate_field(D, "D", mesh.points.size());
    validate_field(D_out, "D_out", mesh.points.size());

    std::vector<double> d = D;
    for (double& di : d) {
        di = std::min(params.L_max, di);
        di = std::max(params.L_min, di);
    }
    // Section 2.3: in tight concave areas the outward gap bounds d, after
    // and below the L_min clamp.
    const double out_factor = 2 * params.M / params.K;
    for (size_t i = 0; i < d.size(); ++i) d[i] = std::min(d[i], out_factor * D_out[i]);

    GradientLimiter(mesh, fans, params.G, d).run();
    return d;
}

} // namespace

std::vector<double> limit_feature_size(const SurfaceMesh& mesh, const std::vector<double>& D,
                                       const std::vector<double>& D_out, const SizingParams& params)
{
    return limit_with_fans(mesh, vertex_triangles(mesh), D, D_out, params);
}

FeatureSize compute_feature_size(const SurfaceMesh& mesh, const SizingParams& params)
{
    validate_params(params);
    // One table of vertex fans serves the check, the normals and the rays.
    const VertexTable fans = vertex_triangles(mesh);
    require_closed_manifold(mesh, fans, "the surface to size");

    FeatureSize result;
    result.normals = synthetic_normals(mesh, fans, &result.inward_ok);
    RayResults rays = cast_local_diameter(mesh, fans, result.normals, result.inward_ok, params.L_max, params.threads);
    result.D = std::move(rays.D);
    result.D_out = std::move(rays.D_out);
    result.escaped_inward_rays = rays.escaped_inward;
    result.seconds_bvh = rays.bvh_seconds;
    result.seconds_rays = rays.ray_seconds;

    if (params.curvature_term) {
        const std::vector<double> radius = curvature_radius(mesh, result.normals);
        for (size_t i = 0; i < result.D.size(); ++i)
            if (result.inward_ok[i]) result.D[i] = std::min(result.D[i], 2 * radius[i]);
    }

    const auto start = Clock::now();
    result.d = limit_with_fans(mesh, fans, result.D, result.D_out, params);
    result.seconds_limit = std::chrono::duration<double>(Clock::now() - start).count();
    return result;
}

} // namespace scalemesh
