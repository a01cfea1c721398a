#include "sizing/feature_size.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "sizing/curvature.h"
#include "sizing/local_diameter.h"
#include "sizing/normals.h"

#include <boost/heap/d_ary_heap.hpp>

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

// Algorithm 1, gradient-limiting part. The directed edge i -> j is slot e of
// row i in the neighbour table; its excess d_i - (d_j + G |x_i - x_j|) is
// ranked in a mutable max-heap that holds exactly the edges of positive
// excess, each once.
class GradientLimiter {
public:
    GradientLimiter(const SurfaceMesh& mesh, double G, std::vector<double>& d)
        : neighbours_(vertex_neighbours(mesh)), d_(d)
    {
        const auto n = static_cast<int32_t>(mesh.points.size());
        const size_t edges = neighbours_.items.size();
        source_.resize(edges);
        slope_length_.resize(edges);
        for (int32_t i = 0; i < n; ++i)
            for (int32_t e = neighbours_.offsets[i]; e < neighbours_.offsets[i + 1]; ++e) {
                source_[e] = i;
                // |x_i - x_j| and |x_j - x_i| round identically, so both
                // directions of an edge use the same G l and a relaxed edge
                // has excess exactly 0, never a round-off residue that would
                // put it back in the queue.
                slope_length_[e] = G * distance(mesh.points[i], mesh.points[neighbours_.items[e]]);
            }
        handles_.resize(edges);
        queued_.assign(edges, 0);
    }

    void run()
    {
        for (int32_t e = 0; e < static_cast<int32_t>(source_.size()); ++e) rank(e);
        while (!queue_.empty()) {
            const int32_t e = queue_.top().edge;
            queue_.pop();
            queued_[e] = 0;
            const int32_t i = source_[e];
            d_[i] = d_[neighbours_.items[e]] + slope_length_[e];
            for (int32_t out = neighbours_.offsets[i]; out < neighbours_.offsets[i + 1]; ++out) {
                rank(out);
                rank(reverse(out));
            }
        }
    }

private:
    struct Entry {
        double excess;
        int32_t edge;
    };
    // Max-heap on excess; ties go to the lower edge id so that the order of
    // relaxations, and with it every rounding, is reproducible.
    struct Less {
        bool operator()(const Entry& a, const Entry& b) const
        {
            return a.excess < b.excess || (a.excess == b.excess && a.edge > b.edge);
        }
    };
    using Heap = boost::heap::d_ary_heap<Entry, boost::heap::arity<4>, boost::heap::mutable_<true>,
                                         boost::heap::compare<Less>>;

    double excess(int32_t e) const { return d_[source_[e]] - (d_[neighbours_.items[e]] + slope_length_[e]); }

    // Slot of j -> i for the slot of i -> j; rows are sorted.
    int32_t reverse(int32_t e) const
    {
        const int32_t j = neighbours_.items[e];
        return static_cast<int32_t>(std::lower_bound(neighbours_.begin(j), neighbours_.end(j), source_[e]) -
                                    neighbours_.items.data());
    }

    // Add, re-rank or delete edge e as its excess now requires.
    void rank(int32_t e)
    {
        const double x = excess(e);
        if (x > 0) {
            if (queued_[e]) queue_.update(handles_[e], Entry{x, e});
            else handles_[e] = queue_.push(Entry{x, e});
            queued_[e] = 1;
        } else if (queued_[e]) {
            queue_.erase(handles_[e]);
            queued_[e] = 0;
        }
    }

    VertexTable neighbours_;
    std::vector<double>& d_;
    std::vector<int32_t> source_;
    std::vector<double> slope_length_; // G |x_i - x_j| per directed edge
    std::vector<Heap::handle_type> handles_;
    std::vector<char> queued_;
    Heap queue_;
};

} // namespace

std::vector<double> limit_feature_size(const SurfaceMesh& mesh, const std::vector<double>& D,
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

    GradientLimiter(mesh, params.G, d).run();
    return d;
}

FeatureSize compute_feature_size(const SurfaceMesh& mesh, const SizingParams& params)
{
    validate_params(params);
    require_closed_manifold(mesh, "the surface to size");

    FeatureSize result;
    result.normals = synthetic_normals(mesh);
    result.inward_ok = inward_check(mesh, result.normals);
    RayResults rays = cast_local_diameter(mesh, result.normals, result.inward_ok, params.L_max, params.threads);
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
    result.d = limit_feature_size(mesh, result.D, result.D_out, params);
    result.seconds_limit = std::chrono::duration<double>(Clock::now() - start).count();
    return result;
}

} // namespace scalemesh
