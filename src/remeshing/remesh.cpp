#include "remeshing/remesh.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "remeshing/criteria.h"
#include "remeshing/halfedge_mesh.h"
#include "remeshing/volume_give_back.h"
#include "smoothing/volume_conserving_smoothing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <tuple>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

namespace scalemesh {

namespace {

// Bounds on the fixed-point loops of merging and swapping.
constexpr int kMaxRounds = 100;
constexpr int kMaxPasses = 200;
constexpr int kMaxBisectionPasses = 60;


using remeshing::Check;
using remeshing::Criteria;
using remeshing::HalfedgeMesh;
using remeshing::Verdict;

// Every point of a flat patch's triangles must lie on one plane with the
// patch's normal, to round-off of the surface's size.
void validate_patch_planes(const SurfaceMesh& surface, const std::vector<Vec3>& normals)
{
    for (size_t p = 0; p < normals.size(); ++p)
        if (!std::isfinite(normals[p].x) || !std::isfinite(normals[p].y) || !std::isfinite(normals[p].z))
            throw InputError("remeshing: patch_normals[" + std::to_string(p) + "] is not finite",
                             "give a plane normal for a flat patch, the zero vector for a curved one");
    if (surface.triangle_patch.size() != surface.triangles.size() || normals.empty()) return;
    Vec3 lo, hi;
    bounding_box(surface, lo, hi);
    const double tolerance = 1e-6 * norm(hi - lo);
    std::vector<double> low(normals.size(), std::numeric_limits<double>::infinity());
    std::vector<double> high(normals.size(), -std::numeric_limits<double>::infinity());
    for (size_t f = 0; f < surface.triangles.size(); ++f) {
        const int32_t p = surface.triangle_patch[f];
        if (p < 0 || static_cast<size_t>(p) >= normals.size() || normals[p] == Vec3{}) continue;
        for (int32_t v : surface.triangles[f]) {
            const double height = dot(surface.points[v], normalized(normals[p]));
            low[p] = std::min(low[p], height);
            high[p] = std::max(high[p], height);
        }
    }
    for (size_t p = 0; p < normals.size(); ++p)
        if (high[p] - low[p] > tolerance)
            throw InputError("remeshing: patch " + std::to_string(p) + " is given as flat, but its points lie " +
                                 std::to_string(high[p] - low[p]) + " mm apart along its normal",
                             "project the cap's points onto its plane, or give the zero normal for a curved patch");
}

void validate(const SurfaceMesh& surface, const std::vector<double>& d, const RemeshParams& params)
{
    auto bad = [](const std::string& what, const std::string& hint) { throw InputError("remeshing: " + what, hint); };
    if (!(params.K > 0) || !std::isfinite(params.K)) bad("K is " + std::to_string(params.K), "use K > 0 (the paper uses 4.2)");
    if (!(params.M >= 1) || !std::isfinite(params.M)) bad("M is " + std::to_string(params.M), "use M >= 1 (the paper uses 7)");
    if (params.cycles < 0) bad("cycles is " + std::to_string(params.cycles), "use a count >= 0 (the paper uses 3)");
    if (params.smoothing_sweeps < 0)
        bad("smoothing sweeps is " + std::to_string(params.smoothing_sweeps), "use a count >= 0 (the paper uses 10)");
    if (!(params.smoothing_omega > 0 && params.smoothing_omega <= 1))
        bad("smoothing omega is " + std::to_string(params.smoothing_omega), "use a value in (0, 1] (the paper uses 0.1)");
    if (!(params.parallel_merge_cube > 0) || !std::isfinite(params.parallel_merge_cube))
        bad("parallel_merge_cube is " + std::to_string(params.parallel_merge_cube),
            "use a side > 0 in target edge lengths (12 by default)");
    if (!(params.max_displacement >= 0) || !std::isfinite(params.max_displacement))
        bad("max_displacement is " + std::to_string(params.max_displacement), "use a distance >= 0 in mm (0: unbounded)");
    const SizingParams& s = params.sizing;
    if (!(s.L_min > 0 && s.L_min <= s.L_max) || !std::isfinite(s.L_max))
        bad("sizing L_min and L_max are " + std::to_string(s.L_min) + " and " + std::to_string(s.L_max),
            "give finite lengths in mm with 0 < L_min <= L_max, as for the sizing stage");
    require_closed_manifold(surface, "the surface to remesh");
    validate_patch_planes(surface, params.patch_normals);
    if (d.size() != surface.points.size())
        bad("d has " + std::to_string(d.size()) + " values for " + std::to_string(surface.points.size()) + " points",
            "pass compute_feature_size(surface, ...).d of this same surface");
    for (size_t i = 0; i < d.size(); ++i)
        if (!(d[i] >= 0) || !std::isfinite(d[i]))
            bad("d of point " + std::to_string(i) + " is " + std::to_string(d[i]), "d must be finite and >= 0 (mm)");
}

double seconds_since(std::chrono::steady_clock::time_point start)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The working state of Algorithm 6's surface loop. Merges and swaps are
// driven by worklists: a node or face is looked at again only after an
// operation nearby could have changed its verdict, which reaches the same
// "until nothing changes" state as full sweeps at a fraction of the cost.
class Remesher {
public:
    Remesher(const SurfaceMesh& surface, const std::vector<double>& d, const RemeshParams& params)
        : params_(params), mesh_(surface), d_(d), drift_(d.size()), lost_(d.size(), 0.0), criteria_(params),
          volume_(signed_volume(surface))
    {
        // A surface that touches itself has d = 0 there (sizing: D_out = 0);
        // bisection would never end. A tenth of L_min is finer than any
        // feature the method resolves.
        for (double& v : d_) v = std::max(v, 0.1 * params.sizing.L_min);
        criteria_.set_input_points(mesh_.vertex_capacity());
        if (params.relax_rims) find_rims();
    }

    RemeshResult run()
    {
        RemeshResult result;
        for (int cycle = 0; cycle < params_.cycles; ++cycle) {
            const auto start = std::chrono::steady_clock::now();
            RemeshCycle counts;
            // RemeshParams::relax_rims: the last cycle's merges and swaps
            // work on evened rims, and its bisections' rim edges are evened
            // again below. In an earlier cycle, evened rims would keep the
            // merges from coarsening the rim as far as the chord's damage
            // allows.
            const bool last = !rims_.empty() && cycle + 1 == params_.cycles;
            if (last) relax_rims();
            const int64_t cube_merges_before = cube_merges_;
            in_cubes_ = params_.parallel_merge_vertices > 0 && mesh_.live_faces() / 2 >= params_.parallel_merge_vertices;
            mark_everything();
            int64_t merged = 0, swapped = 0;
            // "Until nothing changes", bounded: on surfaces with degenerate
            // triangles (angles of 0.01 degrees in some STL files) rounding
            // can make a swap undo the one before it.
            int rounds = 0;
            do {
                merged = merge_nodes();
                swapped = swap_edges();
                counts.merges += merged;
                counts.swaps += swapped;
            } while ((merged > 0 || swapped > 0) && ++rounds < kMaxRounds);
            if (params_.conserve_volume) counts.max_volume_offset = restore_volume();
            counts.bisections = bisect_long_edges();
            // The Rivara chains of the bisections halve rim edges shorter
            // than the target; the moves' volume is given back as the
            // swaps' is.
            if (last) {
                relax_rims();
                if (params_.conserve_volume)
                    counts.max_volume_offset = std::max(counts.max_volume_offset, restore_volume());
            }
            smooth();
            counts.cube_merges = cube_merges_ - cube_merges_before;
            counts.triangles = mesh_.live_faces();
            counts.seconds = seconds_since(start);
            result.merges += counts.merges;
            result.cube_merges += counts.cube_merges;
            result.swaps += counts.swaps;
            result.bisections += counts.bisections;
            result.cycles.push_back(counts);
        }
        std::vector<int32_t> vertex_of_point;
        result.surface = mesh_.to_surface(&vertex_of_point);
        result.target_d.reserve(vertex_of_point.size());
        for (int32_t v : vertex_of_point) result.target_d.push_back(d_[v]);
        result.max_damage = max_damage_;
        const auto start = std::chrono::steady_clock::now();
        result.sizing = compute_feature_size(result.surface, params_.sizing);
        result.seconds_sizing = seconds_since(start);
        return result;
    }

private:
    // Algorithm 3, to a fixed point: each node i tries its neighbours j by
    // increasing distance and merges into the first one that passes.
    int64_t merge_nodes()
    {
        int64_t merges = merge_in_cubes();
        std::vector<std::pair<double, int32_t>> candidates;
        for (int pass = 0; !dirty_vertices_.empty() && pass < kMaxPasses; ++pass) {
            std::vector<int32_t> work;
            work.swap(dirty_vertices_);
            std::sort(work.begin(), work.end());
            for (int32_t v : work) vertex_dirty_[v] = 0;
            for (int32_t i : work) {
                if (!mesh_.vertex_alive(i)) continue;
                merge_candidates(i, criteria_, candidates);
                const int32_t j = merge_first(candidates, criteria_, max_damage_, nullptr);
                if (j < 0) continue;
                mark_two_ring(j);
                ++merges;
            }
        }
        return merges;
    }

    // The edges out of node i shorter than the merge length (half of K/M d
    // at i), shortest first, into `out`.
    void merge_candidates(int32_t i, const Criteria& criteria, std::vector<std::pair<double, int32_t>>& out) const
    {
        const double merge_length = 0.5 * criteria.target(d_[i]);
        out.clear();
        mesh_.find_outgoing(i, [&](int32_t h) {
            const double length = distance(mesh_.points[i], mesh_.points[mesh_.to(h)]);
            if (length < merge_length) out.emplace_back(length, h);
            return false; // the whole fan round
        });
        std::sort(out.begin(), out.end());
    }

    // Merges along the first of `candidates` that `criteria` accepts: its
    // node collapsed into the edge's other end j, which moves by the merge's
    // shift (its drift and the volume lost kept per node); `damage` rises to
    // the merge's. The two dead faces go to `freed` when given
    // (HalfedgeMesh::collapse(h, freed)), else to the free list. Returns j,
    // or -1 when no candidate passes.
    int32_t merge_first(const std::vector<std::pair<double, int32_t>>& candidates, Criteria& criteria, double& damage,
                        std::vector<int32_t>* freed)
    {
        for (const auto& [length, edge] : candidates) {
            const Check check = criteria.merge(mesh_, d_, params_.conserve_volume ? &drift_ : nullptr, edge);
            if (check.verdict != Verdict::accepted) continue;
            const int32_t j = mesh_.to(edge);
            if (freed) mesh_.collapse(edge, *freed);
            else mesh_.collapse(edge);
            mesh_.points[j] += check.shift;
            drift_[j] += check.shift;
            lost_[j] -= check.volume_change;
            damage = std::max(damage, check.damage);
            return j;
        }
        return -1;
    }

    // RemeshParams::parallel_merge_vertices: merge_nodes in the cubes of a
    // grid at once, on the dirty nodes when there are many, twice (the
    // second time on the grid shifted by half a cube along each axis, so
    // that the first grid's faces lie inside cubes). A node i merges there
    // only while neither it nor a neighbour is on its cube's rim (below),
    // so every node within two edges of it is its cube's. A cube then reads
    // only faces with a corner among its nodes and the points of its nodes
    // and their neighbours, and writes only faces whose corners are all its
    // nodes (i's fan; the faces beside the edge's two faces, through twins)
    // and the points, drift and lost volume of its survivors, never a rim
    // node: what one cube writes, no other reads. What a cube cannot do is
    // left dirty for the serial merges: its nodes that would merge but lie
    // on or beside its rim, and the nodes of other cubes a merge marks (as
    // mark_two_ring). The dead faces are handed back in the cubes' order,
    // which keeps every later face id, and so the result, independent of
    // how the cubes were scheduled. Returns the merges.
    int64_t merge_in_cubes()
    {
        constexpr size_t kFewDirty = 2048; // fewer dirty nodes than this: serial merges only
        if (!in_cubes_ || dirty_vertices_.size() < kFewDirty) return 0;
        std::vector<int32_t> live;
        for (int32_t v = 0; v < mesh_.vertex_capacity(); ++v)
            if (mesh_.vertex_alive(v)) live.push_back(v);
        // The cube's side: at most parallel_merge_cube target edge lengths t
        // at the median d, so that a cube holds many merged nodes across and
        // its band along the faces, where nodes wait for the next grid, is
        // thin; but no more than a quarter of the surface's longest side
        // (a vessel a few t across would otherwise fall into one or two
        // cubes, one thread's work), and no less than 4 t.
        std::vector<double> t;
        t.reserve(live.size());
        for (int32_t v : live) t.push_back(criteria_.target(d_[v]));
        std::nth_element(t.begin(), t.begin() + t.size() / 2, t.end());
        const double median_t = t[t.size() / 2];
        Vec3 lo = mesh_.points[live.front()], hi = lo;
        for (int32_t v : live)
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], mesh_.points[v][a]);
                hi[a] = std::max(hi[a], mesh_.points[v][a]);
            }
        const double longest = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
        const double side = std::max(4 * median_t, std::min(params_.parallel_merge_cube * median_t, longest / 4));

        std::vector<int32_t> work;
        work.swap(dirty_vertices_);
        for (int32_t v : work) vertex_dirty_[v] = 0;
        // Scratch space per thread (a verdict never depends on it).
        tbb::enumerable_thread_specific<Criteria> criteria_of_thread(criteria_);
        int64_t merges = 0;
        for (int shift = 0; shift < 2; ++shift) {
            std::erase_if(live, [&](int32_t v) { return !mesh_.vertex_alive(v); });
            // Each live node's cube, (ix, iy, iz) packed; cubes numbered in
            // the order of their keys.
            std::vector<std::pair<int64_t, int32_t>> keyed;
            keyed.reserve(live.size());
            for (int32_t v : live) {
                int64_t key = 0;
                for (int a = 0; a < 3; ++a)
                    key = (key << 21) + std::max<int64_t>(0, static_cast<int64_t>(std::floor(
                                                               (mesh_.points[v][a] - lo[a]) / side + 0.5 * shift)));
                keyed.emplace_back(key, v);
            }
            std::sort(keyed.begin(), keyed.end());
            std::vector<int32_t> cube_of(mesh_.vertex_capacity(), -1);
            int32_t cubes = 0;
            for (size_t k = 0; k < keyed.size(); ++k) {
                if (k > 0 && keyed[k].first != keyed[k - 1].first) ++cubes;
                cube_of[keyed[k].second] = cubes;
            }
            ++cubes;
            if (cubes < 2) break; // one cube: the serial merges do the same
            // The dirty nodes by cube, by id within each.
            std::sort(work.begin(), work.end());
            std::vector<std::vector<int32_t>> nodes(cubes);
            for (int32_t v : work)
                if (mesh_.vertex_alive(v)) nodes[cube_of[v]].push_back(v);
            // The rim: the nodes with a neighbour in another cube. It stays
            // the same while the cubes merge: a rim node never merges away,
            // nor is merged into (the survivor is a neighbour of a node off
            // the rim, so not on it), and keeps its edges (only the edges at
            // the merged node change, and no rim node is next to one); a
            // node off the rim gains only the survivor, or the merged node's
            // neighbours, all of its own cube. So every node within two
            // edges of i is i's cube's exactly when neither i nor a
            // neighbour of i is on the rim.
            std::vector<char> rim(mesh_.vertex_capacity(), 0);
            for (int32_t h = 0; h < mesh_.halfedge_capacity(); ++h)
                if (mesh_.face_alive(HalfedgeMesh::face(h)) && cube_of[mesh_.from(h)] != cube_of[mesh_.to(h)])
                    rim[mesh_.from(h)] = 1;
            std::vector<CubeMerges> done(cubes);
            std::vector<char> queued(mesh_.vertex_capacity(), 0);
            tbb::parallel_for(tbb::blocked_range<int32_t>(0, cubes, 1), [&](const tbb::blocked_range<int32_t>& range) {
                Criteria& criteria = criteria_of_thread.local();
                for (int32_t cube = range.begin(); cube != range.end(); ++cube)
                    if (!nodes[cube].empty())
                        done[cube] = merge_in_cube(cube, std::move(nodes[cube]), cube_of, rim, queued, criteria);
            });
            work.clear();
            for (const CubeMerges& cube : done) {
                mesh_.release_faces(cube.freed);
                merges += cube.merges;
                max_damage_ = std::max(max_damage_, cube.max_damage);
                work.insert(work.end(), cube.left.begin(), cube.left.end());
                for (int32_t f : cube.faces)
                    if (mesh_.face_alive(f)) mark_face(f);
            }
            std::sort(work.begin(), work.end());
            work.erase(std::unique(work.begin(), work.end()), work.end());
        }
        for (int32_t v : work)
            if (mesh_.vertex_alive(v)) mark_vertex(v);
        cube_merges_ += merges;
        return merges;
    }

    struct CubeMerges {
        int64_t merges = 0;
        double max_damage = 0;
        std::vector<int32_t> freed; // faces the merges killed, in order
        std::vector<int32_t> left;  // nodes left dirty: too near the cube's faces to merge, or another cube's marked
        std::vector<int32_t> faces; // faces of the survivors' fans, for the swaps
    };

    // merge_nodes within one cube from its dirty nodes `work`: passes over
    // them (by id) until none merges, the cube's nodes within two edges of
    // a merge looked at again. `queued` is shared by all cubes, each writing
    // only its own nodes' entries.
    CubeMerges merge_in_cube(int32_t cube, std::vector<int32_t> work, const std::vector<int32_t>& cube_of,
                             const std::vector<char>& rim, std::vector<char>& queued, Criteria& criteria)
    {
        CubeMerges out;
        const auto mine = [&](int32_t v) { return cube_of[v] == cube; };
        // Every node within two edges of i in the cube (see `rim`). i's fan
        // is the cube's, so no other cube's merge changes it meanwhile.
        const auto inside = [&](int32_t i) {
            return !rim[i] && mesh_.find_outgoing(i, [&](int32_t h) { return rim[mesh_.to(h)] != 0; }) < 0;
        };
        std::vector<int32_t> next;
        const auto queue = [&](int32_t v) {
            if (!mine(v)) {
                out.left.push_back(v);
            } else if (!queued[v]) {
                queued[v] = 1;
                next.push_back(v);
            }
        };
        std::vector<std::pair<double, int32_t>> candidates;
        for (int pass = 0; !work.empty() && pass < kMaxPasses; ++pass) {
            for (int32_t v : work) queued[v] = 0;
            for (int32_t i : work) {
                if (!mesh_.vertex_alive(i)) continue;
                merge_candidates(i, criteria, candidates);
                if (candidates.empty()) continue;
                if (!inside(i)) {
                    out.left.push_back(i);
                    continue;
                }
                const int32_t j = merge_first(candidates, criteria, out.max_damage, &out.freed);
                if (j < 0) continue;
                // As mark_two_ring: the nodes within two edges of j, and the
                // faces of j's fan.
                mesh_.find_outgoing(j, [&](int32_t h) {
                    const int32_t k = mesh_.to(h);
                    out.faces.push_back(HalfedgeMesh::face(h));
                    queue(k);
                    mesh_.find_outgoing(k, [&](int32_t g) {
                        queue(mesh_.to(g));
                        return false;
                    });
                    return false;
                });
                ++out.merges;
            }
            work.swap(next);
            next.clear();
            std::sort(work.begin(), work.end());
        }
        // A pass bound reached: what is still queued is left for the serial merges.
        out.left.insert(out.left.end(), work.begin(), work.end());
        return out;
    }

    // Fig. 9 with Appendix B, to a fixed point over the dirty faces' edges.
    int64_t swap_edges()
    {
        int64_t swaps = 0;
        for (int pass = 0; !dirty_faces_.empty() && pass < kMaxPasses; ++pass) {
            std::vector<int32_t> work;
            work.swap(dirty_faces_);
            std::sort(work.begin(), work.end());
            for (int32_t f : work) face_dirty_[f] = 0;
            for (int32_t f : work) {
                if (!mesh_.face_alive(f)) continue;
                for (int32_t h = 3 * f; h < 3 * f + 3; ++h) {
                    const Check check = criteria_.swap(mesh_, d_, h);
                    if (check.verdict != Verdict::accepted) continue;
                    const int32_t g = mesh_.twin(h);
                    const int32_t corners[4] = {mesh_.from(h), mesh_.to(h), mesh_.opposite(h), mesh_.opposite(g)};
                    mesh_.flip(h);
                    for (int32_t v : corners) lost_[v] -= 0.25 * check.volume_change;
                    max_damage_ = std::max(max_damage_, check.damage);
                    mark_face(HalfedgeMesh::face(h));
                    mark_face(HalfedgeMesh::face(g));
                    for (int32_t v : corners) mark_one_ring(v);
                    ++swaps;
                    break; // f is another face now, and queued again
                }
            }
        }
        return swaps;
    }

    // Swaps (and merges into nodes that may not move) cut a sliver off a
    // convex region or add one to a concave one; each node has kept count of
    // the volume removed at it, and the free nodes give it back. Nodes on a
    // patch border or a flat patch are not free: a move along their normal
    // would take a rim or a cap off its plane.
    double restore_volume()
    {
        std::vector<char> held(mesh_.vertex_capacity(), 0);
        for (int32_t v = 0; v < mesh_.vertex_capacity(); ++v)
            held[v] = mesh_.vertex_alive(v) && criteria_.held(mesh_, v);
        return remeshing::give_back_volume(mesh_, lost_, held, volume_);
    }

    // Algorithm 2: E = edges longer than the smaller bisection length K/M d
    // of their ends, longest first; each refines the terminal edge of its
    // Rivara chain; E is recomputed until it is empty.
    int64_t bisect_long_edges()
    {
        int64_t bisections = 0;
        std::vector<std::tuple<double, int32_t, int32_t>> E;
        for (int pass = 0;; ++pass) {
            // Every pass halves the edges it finds too long, so a legitimate
            // input is done in far fewer passes; past that, stop with an
            // error rather than run on.
            if (pass == kMaxBisectionPasses)
                throw StageError("remeshing", "edge bisection (Algorithm 2) did not finish after " +
                                                  std::to_string(kMaxBisectionPasses) + " passes and " +
                                                  std::to_string(bisections) + " bisections; the surface may have "
                                                  "degenerate triangles or the feature size a tiny value");
            E.clear();
            for (int32_t h = 0; h < mesh_.halfedge_capacity(); ++h) {
                if (!mesh_.face_alive(HalfedgeMesh::face(h)) || h > mesh_.twin(h)) continue;
                const int32_t a = mesh_.from(h), b = mesh_.to(h);
                const double length = distance(mesh_.points[a], mesh_.points[b]);
                if (length > criteria_.target(std::min(d_[a], d_[b]))) E.emplace_back(length, a, b);
            }
            if (E.empty()) break;
            std::sort(E.begin(), E.end(), [](const auto& p, const auto& q) { return p > q; });
            for (const auto& [length, a, b] : E) {
                const int32_t h = mesh_.find_halfedge(a, b);
                if (h < 0) continue; // bisected by an earlier chain this pass
                const int32_t terminal = rivara_terminal(h);
                const int32_t p = mesh_.from(terminal), q = mesh_.to(terminal);
                mesh_.split(terminal, 0.5 * (mesh_.points[p] + mesh_.points[q]));
                d_.push_back(0.5 * (d_[p] + d_[q]));
                lost_.push_back(0.0);
                drift_.push_back(0.5 * (drift_[p] + drift_[q]));
                ++bisections;
            }
        }
        return bisections;
    }

    // Edges ordered by length, ties broken by their end ids, so that every
    // chain strictly climbs and ends.
    std::tuple<double, int32_t, int32_t> edge_key(int32_t h) const
    {
        const int32_t a = mesh_.from(h), b = mesh_.to(h);
        return {norm2(mesh_.points[a] - mesh_.points[b]), std::min(a, b), std::max(a, b)};
    }

    int32_t longest_in_face(int32_t h) const
    {
        const int32_t first = 3 * HalfedgeMesh::face(h);
        int32_t best = first;
        for (int32_t k = first + 1; k < first + 3; ++k)
            if (edge_key(k) > edge_key(best)) best = k;
        return best;
    }

    // The Rivara chain of h: while h is not the longest edge of both its
    // triangles, move to the longest edge of the triangle where it is not.
    int32_t rivara_terminal(int32_t h) const
    {
        for (;;) {
            const int32_t here = longest_in_face(h);
            if (here != h) {
                h = here;
                continue;
            }
            const int32_t there = longest_in_face(mesh_.twin(h));
            if (there == mesh_.twin(h)) return h;
            h = there;
        }
    }

    // Algorithm 6's smoothing after each cycle. Patch borders stay put, so
    // that caps keep their rims, and nodes inside a flat patch move only in
    // its plane.
    void smooth()
    {
        std::vector<int32_t> vertex_of_point;
        SurfaceMesh surface = mesh_.to_surface(&vertex_of_point);
        SmoothingConstraint constraint;
        if (mesh_.has_patches()) {
            constraint.fixed.resize(vertex_of_point.size());
            for (size_t p = 0; p < vertex_of_point.size(); ++p)
                constraint.fixed[p] = mesh_.on_patch_boundary(vertex_of_point[p]);
            if (!params_.patch_normals.empty()) {
                constraint.plane_normal.resize(vertex_of_point.size());
                for (size_t p = 0; p < vertex_of_point.size(); ++p) {
                    const int32_t patch = mesh_.patch(HalfedgeMesh::face(mesh_.outgoing(vertex_of_point[p])));
                    if (!constraint.fixed[p] && criteria_.planar(patch)) constraint.plane_normal[p] = params_.patch_normals[patch];
                }
            }
        }
        smooth_volume_conserving(surface, {params_.smoothing_sweeps, params_.smoothing_omega, params_.max_displacement},
                                 mesh_.has_patches() ? &constraint : nullptr);
        mesh_.set_positions(surface.points, vertex_of_point);
    }

    // A rim as the input has it: a closed polyline and the arc length at
    // each of its points.
    struct Rim {
        std::vector<Vec3> points;
        std::vector<double> arc; // arc[k]: along the rim from points[0] to points[k]; arc.back(): the whole loop
    };

    // The rim halfedge leaving v along the flat patch's side (that patch's
    // face to its left), or -1; its source and target are consecutive rim
    // nodes in the rim's direction.
    int32_t rim_out(int32_t v) const
    {
        return mesh_.find_outgoing(v, [&](int32_t h) { return flat_rim(h); });
    }

    // The rim halfedge arriving at v along the flat patch's side, or -1.
    int32_t rim_in(int32_t v) const
    {
        const int32_t h = mesh_.find_outgoing(v, [&](int32_t out) { return flat_rim(HalfedgeMesh::prev(out)); });
        return h < 0 ? -1 : HalfedgeMesh::prev(h);
    }

    // Whether h lies on a rim with a flat patch's face to its left.
    bool flat_rim(int32_t h) const
    {
        return mesh_.border_edge(h) && criteria_.planar(mesh_.patch(HalfedgeMesh::face(h)));
    }

    // The input's rims between a flat patch and another patch, each node
    // on exactly two border edges (a node where rims meet is not a rim's:
    // such rims are left as they are).
    void find_rims()
    {
        if (!mesh_.has_patches()) return;
        const int32_t n = mesh_.vertex_capacity();
        rim_of_.assign(n, -1);
        arc_of_.assign(n, 0.0);
        std::vector<char> seen(n, 0);
        for (int32_t v = 0; v < n; ++v) {
            if (seen[v] || !mesh_.vertex_alive(v) || rim_out(v) < 0) continue;
            Rim rim;
            std::vector<int32_t> nodes;
            bool simple = true;
            int32_t u = v;
            do {
                seen[u] = 1;
                simple = simple && mesh_.border_edges(u) == 2;
                nodes.push_back(u);
                const int32_t h = rim_out(u);
                if (h < 0) {
                    simple = false;
                    break;
                }
                u = mesh_.to(h);
            } while (u != v && !seen[u]);
            if (!simple || u != v || nodes.size() < 3) continue;
            double arc = 0;
            for (size_t k = 0; k < nodes.size(); ++k) {
                if (k > 0) arc += distance(mesh_.points[nodes[k - 1]], mesh_.points[nodes[k]]);
                rim.points.push_back(mesh_.points[nodes[k]]);
                rim.arc.push_back(arc);
                rim_of_[nodes[k]] = static_cast<int32_t>(rims_.size());
                arc_of_[nodes[k]] = arc;
            }
            rim.arc.push_back(arc + distance(mesh_.points[nodes.back()], mesh_.points[nodes.front()]));
            rims_.push_back(std::move(rim));
        }
    }

    // The point of `rim` at arc length s (taken around the loop).
    Vec3 rim_point(const Rim& rim, double s) const
    {
        const double length = rim.arc.back();
        s = std::fmod(s, length);
        if (s < 0) s += length;
        if (!(s < length)) s = 0; // -1e-16 + length rounds to length
        const size_t k = static_cast<size_t>(std::upper_bound(rim.arc.begin(), rim.arc.end(), s) - rim.arc.begin()) - 1;
        const size_t next = k + 1 == rim.points.size() ? 0 : k + 1;
        const double span = rim.arc[k + 1] - rim.arc[k];
        const double t = span > 0 ? (s - rim.arc[k]) / span : 0.0;
        return (1 - t) * rim.points[k] + t * rim.points[next];
    }

    // The arc length of the point of `rim` nearest x.
    double rim_arc(const Rim& rim, const Vec3& x) const
    {
        double best = std::numeric_limits<double>::infinity(), arc = 0;
        for (size_t k = 0; k < rim.points.size(); ++k) {
            const Vec3& a = rim.points[k];
            const Vec3& b = rim.points[k + 1 == rim.points.size() ? 0 : k + 1];
            const Vec3 e = b - a;
            const double t = norm2(e) > 0 ? std::clamp(dot(x - a, e) / norm2(e), 0.0, 1.0) : 0.0;
            const double gap = distance(x, a + t * e);
            if (gap < best) {
                best = gap;
                arc = rim.arc[k] + t * (rim.arc[k + 1] - rim.arc[k]);
            }
        }
        return arc;
    }

    // RemeshParams::relax_rims, twice in the last cycle: sweeps of moves of
    // each rim node along its input rim, halfway (kOmega) toward the middle
    // (by arc length) of its two rim neighbours; 64 sweeps spread a run of
    // short rim edges along a rim of a few dozen nodes. A move is not made
    // where a triangle of the node's fan would turn more than 30 degrees or
    // keep less than a fifth of its area (a sliver along the rim; the last
    // cycle's swaps do not follow the second call). The bounds are per move,
    // and a move may lengthen an edge of the node beyond t: bounding the
    // edges, or the turn against the fan before the sweeps, gave up the
    // prism layers on the stepped tube of validation/multiscale_validation.py
    // (a tet cell of 9.43 degrees). The volume a move adds goes into lost_,
    // which restore_volume gives back.
    void relax_rims()
    {
        constexpr int kSweeps = 64;
        constexpr double kOmega = 0.5;
        const double cos_turn = std::cos(30.0 * std::numbers::pi / 180);
        constexpr double kMinArea = 0.2;
        rim_of_.resize(mesh_.vertex_capacity(), -1);
        arc_of_.resize(mesh_.vertex_capacity(), 0.0);
        // A node a bisection put on the rim: where its rim is nearest.
        const auto arc_at = [&](int32_t v, int32_t rim) {
            if (rim_of_[v] != rim) {
                rim_of_[v] = rim;
                arc_of_[v] = rim_arc(rims_[rim], mesh_.points[v]);
            }
            return arc_of_[v];
        };
        std::vector<int32_t> nodes;
        for (int32_t v = 0; v < mesh_.vertex_capacity(); ++v)
            if (mesh_.vertex_alive(v) && mesh_.border_edges(v) == 2 && rim_out(v) >= 0) nodes.push_back(v);
        for (int sweep = 0; sweep < kSweeps; ++sweep)
            for (const int32_t v : nodes) {
                if (rim_of_[v] < 0) continue;
                const int32_t out = rim_out(v), in = rim_in(v);
                if (out < 0 || in < 0) continue;
                const int32_t rim = rim_of_[v], next = mesh_.to(out), prev = mesh_.from(in);
                if (next == prev) continue;
                if (rim_of_[next] < 0 && mesh_.border_edges(next) != 2) continue;
                if (rim_of_[prev] < 0 && mesh_.border_edges(prev) != 2) continue;
                const double length = rims_[rim].arc.back();
                const double here = arc_at(v, rim);
                const auto ahead = [&](double from, double to) {
                    const double s = std::fmod(to - from, length);
                    return s < 0 ? s + length : s;
                };
                const double to_next = ahead(here, arc_at(next, rim)), from_prev = ahead(arc_at(prev, rim), here);
                if (!(to_next + from_prev < 0.5 * length)) continue; // not a neighbourhood of the rim
                const double shift = kOmega * 0.5 * (to_next - from_prev);
                const Vec3 x = rim_point(rims_[rim], here + shift);
                const auto unsound = [&](int32_t h) {
                    const Vec3& b = mesh_.points[mesh_.to(h)];
                    const Vec3& c = mesh_.points[mesh_.opposite(h)];
                    const Vec3 before = cross(b - mesh_.points[v], c - mesh_.points[v]);
                    const Vec3 after = cross(b - x, c - x);
                    const double nb = norm(before), na = norm(after);
                    return !(na >= kMinArea * nb && dot(before, after) >= cos_turn * nb * na);
                };
                if (mesh_.find_outgoing(v, unsound) >= 0) continue;
                // The volume the move adds, given back with the swaps' (lost_).
                Vec3 fan{};
                mesh_.find_outgoing(v, [&](int32_t h) {
                    fan += cross(mesh_.points[mesh_.to(h)], mesh_.points[mesh_.opposite(h)]);
                    return false; // the whole fan round
                });
                lost_[v] -= dot(x - mesh_.points[v], fan) / 6;
                mesh_.points[v] = x;
                arc_of_[v] = std::fmod(here + shift + length, length);
            }
    }

    void mark_everything()
    {
        vertex_dirty_.assign(mesh_.vertex_capacity(), 0);
        face_dirty_.assign(mesh_.face_capacity(), 0);
        dirty_vertices_.clear();
        dirty_faces_.clear();
        for (int32_t v = 0; v < mesh_.vertex_capacity(); ++v)
            if (mesh_.vertex_alive(v)) mark_vertex(v);
        for (int32_t f = 0; f < mesh_.face_capacity(); ++f)
            if (mesh_.face_alive(f)) mark_face(f);
    }

    void mark_vertex(int32_t v)
    {
        if (vertex_dirty_[v]) return;
        vertex_dirty_[v] = 1;
        dirty_vertices_.push_back(v);
    }

    void mark_face(int32_t f)
    {
        if (face_dirty_[f]) return;
        face_dirty_[f] = 1;
        dirty_faces_.push_back(f);
    }

    // A swap at v changes the merge tests of v and its neighbours (their
    // fans, link conditions and valences).
    void mark_one_ring(int32_t v)
    {
        mark_vertex(v);
        const int32_t start = mesh_.outgoing(v);
        int32_t h = start;
        do {
            mark_vertex(mesh_.to(h));
            h = mesh_.rotate(h);
        } while (h != start);
    }

    // A merge into j moves j and changes the fans of j and its neighbours:
    // every node within two edges may judge its merges differently, and
    // every edge of j's fan its swap.
    void mark_two_ring(int32_t j)
    {
        const int32_t start = mesh_.outgoing(j);
        int32_t h = start;
        do {
            mark_one_ring(mesh_.to(h));
            mark_face(HalfedgeMesh::face(h));
            h = mesh_.rotate(h);
        } while (h != start);
    }

    const RemeshParams& params_;
    HalfedgeMesh mesh_;
    std::vector<double> d_;
    std::vector<Vec3> drift_;  // mm per vertex id: the sum of its volume keeping moves
    std::vector<double> lost_; // mm^3 per vertex id: volume the merges and swaps there removed since the last restore
    Criteria criteria_;
    double volume_; // mm^3 enclosed by the input
    double max_damage_ = 0;
    int64_t cube_merges_ = 0; // merges made by merge_in_cubes
    bool in_cubes_ = false;   // this cycle started with parallel_merge_vertices nodes or more
    std::vector<char> vertex_dirty_, face_dirty_;
    std::vector<int32_t> dirty_vertices_, dirty_faces_;
    std::vector<Rim> rims_;         // RemeshParams::relax_rims
    std::vector<int32_t> rim_of_;   // per vertex id: its rim in rims_, -1 for none (yet)
    std::vector<double> arc_of_;    // per vertex id on a rim: its arc length along it
};

} // namespace

RemeshResult remesh_to_feature_size(const SurfaceMesh& surface, const std::vector<double>& d,
                                    const RemeshParams& params)
{
    validate(surface, d, params);
    Remesher remesher(surface, d, params);
    return remesher.run();
}

std::vector<double> edge_length_ratio(const SurfaceMesh& surface, const std::vector<double>& d, double K, double M)
{
    if (d.size() != surface.points.size())
        throw InputError("edge_length_ratio: d has " + std::to_string(d.size()) + " values for " +
                             std::to_string(surface.points.size()) + " points",
                         "pass one d per point");
    std::vector<double> sum(surface.points.size(), 0.0);
    std::vector<int32_t> count(surface.points.size(), 0);
    for (const auto& [a, b] : unique_edges(surface)) {
        const double ratio = distance(surface.points[a], surface.points[b]) / (K / M * 0.5 * (d[a] + d[b]));
        sum[a] += ratio, sum[b] += ratio;
        ++count[a], ++count[b];
    }
    for (size_t i = 0; i < sum.size(); ++i) sum[i] = count[i] > 0 ? sum[i] / count[i] : 0.0;
    return sum;
}

} // namespace scalemesh
