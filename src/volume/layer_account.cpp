#include "volume/layer_account.h"

#include <CGAL/Fuzzy_sphere.h>
#include <CGAL/Kd_tree.h>
#include <CGAL/Search_traits_3.h>
#include <CGAL/Simple_cartesian.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>

namespace scalemesh {

const char* layer_loss_name(LayerLoss loss)
{
    switch (loss) {
    case LayerLoss::none: return "none";
    case LayerLoss::normal: return "normal";
    case LayerLoss::short_ray: return "short_ray";
    case LayerLoss::filtered: return "filtered";
    case LayerLoss::tiny_tet: return "tiny_tet";
    case LayerLoss::hidden: return "hidden";
    case LayerLoss::outside: return "outside";
    case LayerLoss::unused: return "unused";
    case LayerLoss::moved: return "moved";
    }
    return "unknown";
}

LayerAccount account_layers(const SurfaceMesh& surface, const FeatureSize& sizing, double M, double L_min,
                            const std::vector<OffsetPoint>& raw, const std::vector<OffsetPoint>& kept,
                            const std::vector<InsertionFate>& fates, const std::vector<FinalPoint>& final_points,
                            double tolerance)
{
    const size_t n = surface.points.size();
    if (sizing.D.size() != n || (!sizing.inward_ok.empty() && sizing.inward_ok.size() != n))
        throw std::invalid_argument("layer account: the sizing does not match the surface");
    if (fates.size() != kept.size()) throw std::invalid_argument("layer account: one fate per kept point");
    LayerAccount account;
    account.layermaking = static_cast<int32_t>(std::floor(M / 2));
    account.tolerance = tolerance;
    const int32_t L = account.layermaking;
    const double limit = tolerance * (1 + 1e-9); // a move clamped to the tolerance counts, to round-off
    auto layermaking = [&](const OffsetPoint& p) {
        return !p.filler && p.layer >= 1 && p.layer <= L && p.generator >= 0 && size_t(p.generator) < n;
    };

    // Where each kept point ended (NaN when it is not in the mesh).
    const double nan = std::numeric_limits<double>::quiet_NaN();
    std::vector<Vec3> ended(kept.size(), Vec3{nan, nan, nan});
    for (const FinalPoint& f : final_points) {
        if (f.offset < 0 || size_t(f.offset) >= kept.size())
            throw std::invalid_argument("layer account: a final point names no kept offset point");
        ended[f.offset] = f.position;
    }

    // Per node and layermaking layer m (1..L), the state of its point:
    // never made, filtered, kept (then its fate decides), in the mesh within
    // the tolerance of its place, in the mesh beyond it. The kept points are
    // raw's survivors in order, so one walk pairs them.
    constexpr int8_t kNone = 0, kFiltered = 1, kKept = 2, kHere = 3, kMoved = 4;
    std::vector<int8_t> state(n * size_t(L), kNone);
    std::vector<int32_t> kept_at(n * size_t(L), -1); // the kept point's index
    std::vector<Vec3> place(n * size_t(L));
    std::vector<double> spacing(n * size_t(L), 0);
    auto slot = [&](const OffsetPoint& p) { return size_t(p.generator) * L + (p.layer - 1); };
    size_t k = 0;
    for (const OffsetPoint& p : raw) {
        const bool survived = k < kept.size() && kept[k].generator == p.generator && kept[k].layer == p.layer;
        if (layermaking(p)) {
            const size_t s = slot(p);
            place[s] = p.position, spacing[s] = p.spacing;
            if (!survived) state[s] = kFiltered;
            else if (std::isnan(ended[k].x)) state[s] = kKept;
            else {
                const double moved = distance(ended[k], p.position) / p.spacing;
                state[s] = moved <= limit ? kHere : kMoved;
                if (moved <= limit) account.max_displacement = std::max(account.max_displacement, moved);
            }
            if (survived) kept_at[s] = static_cast<int32_t>(k);
        }
        k += survived;
    }
    if (k != kept.size()) throw std::invalid_argument("layer account: the kept points are not a subsequence of raw");

    // Stand-ins: for a missing or moved point, another node's point of the
    // same layer in the mesh within the tolerance of its place. One k-d tree
    // per layer, built only when a point is missing.
    if (std::isfinite(tolerance) &&
        std::any_of(state.begin(), state.end(), [](int8_t v) { return v != kHere && v != kNone; })) {
        using Kernel = CGAL::Simple_cartesian<double>;
        using Tree = CGAL::Kd_tree<CGAL::Search_traits_3<Kernel>>;
        std::vector<std::vector<Kernel::Point_3>> by_layer(L);
        for (size_t j = 0; j < kept.size(); ++j)
            if (layermaking(kept[j]) && !std::isnan(ended[j].x))
                by_layer[kept[j].layer - 1].emplace_back(ended[j].x, ended[j].y, ended[j].z);
        std::vector<std::unique_ptr<Tree>> trees;
        for (auto& points : by_layer) trees.push_back(std::make_unique<Tree>(points.begin(), points.end()));
        for (size_t s = 0; s < state.size(); ++s) {
            if (state[s] == kHere || state[s] == kNone) continue;
            const Vec3& x = place[s];
            const CGAL::Fuzzy_sphere<CGAL::Search_traits_3<Kernel>> ball(Kernel::Point_3(x.x, x.y, x.z),
                                                                           limit * spacing[s]);
            if (const auto found = trees[s % L]->search_any_point(ball)) {
                state[s] = kHere, ++account.stand_ins;
                const Vec3 at{found->x(), found->y(), found->z()};
                account.max_displacement = std::max(account.max_displacement, distance(at, x) / spacing[s]);
            }
        }
    }

    // Wall nodes: every triangle at the node is in patch 0.
    account.wall.assign(n, 1);
    if (surface.triangle_patch.size() == surface.triangles.size())
        for (size_t t = 0; t < surface.triangles.size(); ++t)
            if (surface.triangle_patch[t] != 0)
                for (int32_t v : surface.triangles[t]) account.wall[v] = 0;

    account.realised.assign(n, 0);
    account.loss.assign(n, LayerLoss::none);
    account.eligible.assign(n, 0);
    double eligible_sum = 0;
    for (size_t i = 0; i < n; ++i) {
        int32_t r = 0;
        while (r < L && state[i * L + r] == kHere) ++r;
        account.realised[i] = r;
        if (r < L) {
            const size_t s = i * L + r;
            LayerLoss why = LayerLoss::none;
            if (state[s] == kNone)
                why = !sizing.inward_ok.empty() && !sizing.inward_ok[i] && r == 0 ? LayerLoss::normal : LayerLoss::short_ray;
            else if (state[s] == kFiltered) why = LayerLoss::filtered;
            else if (state[s] == kMoved) why = LayerLoss::moved;
            else switch (fates[kept_at[s]]) {
                case InsertionFate::inserted: why = LayerLoss::unused; break;
                case InsertionFate::tiny_tet: why = LayerLoss::tiny_tet; break;
                case InsertionFate::hidden: why = LayerLoss::hidden; break;
                case InsertionFate::filler: // a layermaking point is never a filler
                case InsertionFate::outside: why = LayerLoss::outside; break;
                }
            account.loss[i] = why;
        }
        if (!account.wall[i]) {
            ++account.opening_nodes;
            continue;
        }
        ++account.wall_nodes;
        account.wall_full += r == L;
        if (!(sizing.D[i] >= L_min) && !std::isnan(L_min)) continue;
        account.eligible[i] = 1;
        ++account.eligible_nodes;
        account.eligible_full += r == L;
        eligible_sum += r;
        ++account.eligible_losses[static_cast<int>(account.loss[i])];
    }
    if (account.eligible_nodes) account.eligible_mean = eligible_sum / double(account.eligible_nodes);
    return account;
}

} // namespace scalemesh
