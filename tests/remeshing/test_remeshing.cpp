// Surface remeshing to the feature size (paper section 2.2, Algorithms 2, 3
// and 6, Appendices A and B) on smoothed marching cubes surfaces of every
// phantom and on a real aorta surface.

#include "core/adjacency.h"
#include "core/errors.h"
#include "core/surface_mesh.h"
#include "importers/stl_importer.h"
#include "isosurface/marching_cubes.h"
#include "phantom/phantom.h"
#include "remeshing/criteria.h"
#include "remeshing/remesh.h"
#include "remeshing/volume_give_back.h"
#include "sizing/feature_size.h"
#include "smoothing/volume_conserving_smoothing.h"
#include "support/triangle_angles.h"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <tuple>

namespace scalemesh {
namespace {

constexpr double kK = 4.2, kM = 7;

// Distance from points to a triangle surface through CGAL's AABB tree.
class DistanceTo {
public:
    explicit DistanceTo(const SurfaceMesh& mesh)
    {
        for (const Triangle& t : mesh.triangles)
            triangles_.emplace_back(point(mesh.points[t[0]]), point(mesh.points[t[1]]), point(mesh.points[t[2]]));
        tree_.insert(triangles_.begin(), triangles_.end());
        tree_.accelerate_distance_queries();
    }
    double operator()(const Vec3& p) const { return std::sqrt(tree_.squared_distance(point(p))); }

private:
    using Kernel = CGAL::Simple_cartesian<double>;
    using Iterator = std::vector<Kernel::Triangle_3>::const_iterator;
    using Tree = CGAL::AABB_tree<CGAL::AABB_traits<Kernel, CGAL::AABB_triangle_primitive<Kernel, Iterator>>>;
    static Kernel::Point_3 point(const Vec3& p) { return {p.x, p.y, p.z}; }
    std::vector<Kernel::Triangle_3> triangles_;
    Tree tree_;
};

// Largest distance from the vertices, edge midpoints and centroids of `from`
// to the surface `to`.
double one_sided_distance(const SurfaceMesh& from, const SurfaceMesh& to)
{
    const DistanceTo distance_to(to);
    double largest = 0;
    for (const Vec3& p : from.points) largest = std::max(largest, distance_to(p));
    for (const Triangle& t : from.triangles) {
        const Vec3 &a = from.points[t[0]], &b = from.points[t[1]], &c = from.points[t[2]];
        for (const Vec3& p : {(a + b + c) / 3.0, 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)})
            largest = std::max(largest, distance_to(p));
    }
    return largest;
}

double hausdorff(const SurfaceMesh& a, const SurfaceMesh& b)
{
    return std::max(one_sided_distance(a, b), one_sided_distance(b, a));
}

struct Figures {
    double ratio_in_band = 0;   // fraction of edges with length / (K/M d) in [0.45, 1.1], stable d
    double ratio_in_band_target = 0; // the same with the input d carried along
    double ratio_at_most = 0;   // fraction of edges with length / (K/M d) <= 1.1, stable d
    double angle_above_15 = 0;  // fraction of triangles with min angle > 15 degrees
    double hausdorff = 0;       // mm
    double bound = 0;           // mm, K/(30M) d_max + one voxel
    double volume_change = 0;   // relative
};

// Fractions of edges whose length / (K/M d) is in [0.45, 1.1] and <= 1.1,
// d the mean of the edge's two ends.
std::pair<double, double> edge_ratio_fractions(const SurfaceMesh& mesh, const std::vector<double>& d)
{
    const auto edges = unique_edges(mesh);
    size_t in = 0, below = 0;
    for (const auto& [a, b] : edges) {
        const double ratio = distance(mesh.points[a], mesh.points[b]) / (kK / kM * 0.5 * (d[a] + d[b]));
        in += ratio >= 0.45 && ratio <= 1.1;
        below += ratio <= 1.1;
    }
    return {double(in) / double(edges.size()), double(below) / double(edges.size())};
}

struct Case {
    SurfaceMesh input;
    FeatureSize sizing;
    RemeshParams params;
    double voxel = 0; // mm
};

// The Algorithm 6 surface front end on a phantom: marching cubes, 10 sweeps
// of smoothing with omega 1 (half a voxel of reach), feature size. The
// remeshing's own smoothing may move a node a third of a voxel per cycle.
Case phantom_case(const std::string& name, double h, double L_min = 0.25, double L_max = 20)
{
    const auto shape = make_shape(name, h);
    Case c;
    c.voxel = h;
    c.input = marching_cubes(*voxelize(*shape, {.voxel_size = h}));
    smooth_volume_conserving(c.input, {10, 1.0, 0.5 * h});
    c.params.sizing.L_min = L_min;
    c.params.sizing.L_max = L_max;
    c.params.max_displacement = h / 3;
    c.sizing = compute_feature_size(c.input, c.params.sizing);
    return c;
}

// Topology always; the figures are returned for the caller to bound.
Figures measure(const Case& c, const RemeshResult& r, const std::string& label)
{
    const SurfaceFacts before = surface_facts(c.input);
    const SurfaceFacts after = surface_facts(r.surface);
    EXPECT_TRUE(after.closed_manifold()) << label;
    EXPECT_EQ(after.euler_characteristic, before.euler_characteristic) << label;
    EXPECT_EQ(after.components, before.components) << label;
    EXPECT_GT(after.signed_volume, 0) << label;

    Figures f;
    std::tie(f.ratio_in_band, f.ratio_at_most) = edge_ratio_fractions(r.surface, r.sizing.d);
    f.ratio_in_band_target = edge_ratio_fractions(r.surface, r.target_d).first;
    size_t good = 0;
    for (const Triangle& t : r.surface.triangles) good += min_angle_degrees(r.surface, t) > 15;
    f.angle_above_15 = double(good) / double(r.surface.triangles.size());
    f.hausdorff = hausdorff(c.input, r.surface);
    f.volume_change = after.signed_volume / before.signed_volume - 1;
    const double d_max = *std::max_element(c.sizing.d.begin(), c.sizing.d.end());
    f.bound = kK / (30 * kM) * d_max + c.voxel;
    double seconds = 0;
    for (const RemeshCycle& cycle : r.cycles) seconds += cycle.seconds;
    std::printf("%-12s triangles %6lld -> %5lld  edges in [0.45, 1.1]: %.3f (carried d %.3f), <= 1.1: %.3f  "
                "angles > 15: %.4f  Hausdorff %.3f mm (bound %.3f)  volume %+.1e  max damage %.3f mm  %.2f s\n",
                label.c_str(), (long long)before.triangles, (long long)after.triangles, f.ratio_in_band,
                f.ratio_in_band_target, f.ratio_at_most, f.angle_above_15, f.hausdorff, f.bound, f.volume_change,
                r.max_damage, seconds);
    return f;
}

void expect_shape_kept(const Figures& f, const std::string& label)
{
    EXPECT_GE(f.angle_above_15, 0.99) << label;
    EXPECT_LT(f.hausdorff, f.bound) << label;
    EXPECT_LT(std::abs(f.volume_change), 0.005) << label;
    // Bisection (Algorithm 2) leaves no edge above K/M d but for the motion
    // of the last smoothing and the change from carried to stable d.
    EXPECT_GE(f.ratio_at_most, 0.99) << label;
}

// The paper's sizes (L_max = 20 mm, d = the diameter): the damage limit of
// K/(30M) d, not the merge length, stops coarsening where the surface bends
// with a radius near d/2, so the length band is printed but not bounded here
// (see PaperRegime below for it).
class RemeshPhantom : public ::testing::TestWithParam<std::string> {};

TEST_P(RemeshPhantom, KeepsTopologyShapeAndVolume)
{
    const Case c = phantom_case(GetParam(), 0.5);
    const RemeshResult r = remesh_to_feature_size(c.input, c.sizing.d, c.params);
    expect_shape_kept(measure(c, r, GetParam()), GetParam());
    EXPECT_LE(r.max_damage, kK / (30 * kM) * *std::max_element(c.sizing.d.begin(), c.sizing.d.end()));
}

INSTANTIATE_TEST_SUITE_P(AllShapes, RemeshPhantom, ::testing::ValuesIn(phantom_names()),
                         [](const auto& info) { return info.param; });

// Where d is held well below the radius of curvature (L_max = 2.5 mm, 5
// voxels, on shapes that bend with radii of 4 mm and more), merges are
// limited by merge_length and the edge length lands in the paper's band.
class PaperRegime : public ::testing::TestWithParam<std::string> {};

TEST_P(PaperRegime, EdgesReachTheTargetLength)
{
    const Case c = phantom_case(GetParam(), 0.5, 0.25, 2.5);
    const RemeshResult r = remesh_to_feature_size(c.input, c.sizing.d, c.params);
    const Figures f = measure(c, r, GetParam() + "/2.5");
    expect_shape_kept(f, GetParam());
    EXPECT_GE(f.ratio_in_band, 0.90) << GetParam();
}

INSTANTIATE_TEST_SUITE_P(LargeShapes, PaperRegime, ::testing::Values("sphere", "torus"),
                         [](const auto& info) { return info.param; });

// RemeshParams::parallel_merge_vertices: the merges in the cubes of a
// grid, all cubes at once, then the serial fixed point. The torus of
// PaperRegime (9,168 vertices, 28 mm across, t = 1.5 mm where d = L_max)
// in cubes of a quarter of its width, 7 mm. The surface is the same on one
// thread and on two, the merges in cubes are most of them (6,702 of 8,655
// when this was written), and the result keeps what PaperRegime asks of
// the serial merges.
TEST(RemeshParallel, MergesInCubesGiveOneSurfaceOnAnyThreadCountAndKeepItsShape)
{
    Case c = phantom_case("torus", 0.5, 0.25, 2.5);
    c.params.parallel_merge_vertices = 1000;
    const auto remesh_on = [&](int threads) {
        tbb::task_arena arena(threads);
        return arena.execute([&] { return remesh_to_feature_size(c.input, c.sizing.d, c.params); });
    };
    const RemeshResult one = remesh_on(1);
    const RemeshResult two = remesh_on(2);
    ASSERT_EQ(one.surface.triangles, two.surface.triangles);
    ASSERT_EQ(one.surface.points.size(), two.surface.points.size());
    for (size_t i = 0; i < one.surface.points.size(); ++i)
        ASSERT_TRUE(one.surface.points[i] == two.surface.points[i]) << "point " << i;
    EXPECT_EQ(one.merges, two.merges);
    EXPECT_GT(one.cube_merges, 0.5 * double(one.merges)) << one.cube_merges << " of " << one.merges;
    const Figures f = measure(c, two, "torus/cubes");
    expect_shape_kept(f, "torus/cubes");
    EXPECT_GE(f.ratio_in_band, 0.90);

    // Below the threshold the merges are the serial ones alone.
    c.params.parallel_merge_vertices = 0;
    const RemeshResult serial = remesh_to_feature_size(c.input, c.sizing.d, c.params);
    EXPECT_EQ(serial.cube_merges, 0);
    EXPECT_GT(serial.merges, 0);
}

TEST(RemeshSurface, RealAorta)
{
    Case c;
    c.input = read_stl("../shared/data/vmtk_aorta_capped.stl");
    orient_outward(c.input);
    c.voxel = 0.879; // in-plane spacing of the segmentation the surface came from
    c.params.sizing.L_min = 0.5;
    c.params.sizing.L_max = 30;
    c.params.max_displacement = c.voxel / 3;
    c.sizing = compute_feature_size(c.input, c.params.sizing);
    const RemeshResult r = remesh_to_feature_size(c.input, c.sizing.d, c.params);
    expect_shape_kept(measure(c, r, "aorta"), "aorta");
}

// Edges cut by the plane z = 0: the number around the tube's circumference.
int64_t edges_around(const SurfaceMesh& mesh)
{
    int64_t n = 0;
    for (const auto& [a, b] : unique_edges(mesh)) n += (mesh.points[a].z < 0) != (mesh.points[b].z < 0);
    return n;
}

// The aorta STL as `scalemesh run` meshes it (L_min 0.5 mm, L_max 20 mm),
// first with its d, then with d reduced by the volume stage's factor 0.7
// around a stretch of the wall, as its first refinement retry does: the
// retry that hung. Every cycle's volume give-back moves nodes by less than
// the damage limit, and the result is no finer than the input.
TEST(RemeshSurface, RealAortaRefinedLocallyKeepsItsShape)
{
    Case c;
    c.input = read_stl("../shared/data/vmtk_aorta_capped.stl");
    orient_outward(c.input);
    // The pipeline's front end for an STL: its voxel is the mean edge length,
    // smoothing and remeshing may move a node half of one.
    double sum = 0;
    for (const Triangle& t : c.input.triangles)
        for (int k = 0; k < 3; ++k) sum += distance(c.input.points[t[k]], c.input.points[t[(k + 1) % 3]]);
    c.voxel = sum / (3.0 * double(c.input.triangles.size()));
    smooth_volume_conserving(c.input, {10, 1.0, 0.5 * c.voxel});
    c.params.sizing.L_min = 0.5;
    c.params.sizing.L_max = 20;
    c.params.max_displacement = 0.5 * c.voxel;
    c.sizing = compute_feature_size(c.input, c.params.sizing);
    std::vector<double> d = c.sizing.d;
    for (int retry = 0; retry <= 3; ++retry) {
        const RemeshResult r = remesh_to_feature_size(c.input, d, c.params);
        const std::string label = "aorta, retry " + std::to_string(retry);
        const double d_max = *std::max_element(d.begin(), d.end());
        for (const RemeshCycle& cycle : r.cycles)
            EXPECT_LT(cycle.max_volume_offset, kK / (30 * kM) * d_max) << label;
        EXPECT_LT(r.surface.triangles.size(), c.input.triangles.size()) << label;
        expect_shape_kept(measure(c, r, label), label);
        // Refine around a few remeshed nodes, as the pipeline does around
        // the nodes the volume stage could not conform to.
        for (size_t i = 0; i < d.size(); ++i)
            for (int32_t node = 0; node < 8; ++node)
                if (distance(c.input.points[i], r.surface.points[node * 37 % r.surface.points.size()]) <= kK / kM * d[i]) {
                    d[i] *= 0.7;
                    break;
                }
    }
}

TEST(RemeshScaleInvariance, TubeOfSixAndTwentyFourVoxelsGetsTheSameRing)
{
    // The tube phantom is 6 mm across: 6 voxels at 1 mm, 24 at 0.25 mm; its
    // d (about 6 mm) is inside [L_min, L_max] for both.
    const Case coarse = phantom_case("tube", 1.0);
    const Case fine = phantom_case("tube", 0.25);
    const RemeshResult rc = remesh_to_feature_size(coarse.input, coarse.sizing.d, coarse.params);
    const RemeshResult rf = remesh_to_feature_size(fine.input, fine.sizing.d, fine.params);
    const int64_t n_coarse = edges_around(rc.surface), n_fine = edges_around(rf.surface);
    std::printf("edges around the tube: %lld at 6 voxels across, %lld at 24 (before remeshing %lld and %lld)\n",
                (long long)n_coarse, (long long)n_fine, (long long)edges_around(coarse.input),
                (long long)edges_around(fine.input));
    ASSERT_GT(n_coarse, 0);
    // The input rings differ four times over; the remeshed ones must not.
    EXPECT_LT(std::abs(double(n_coarse - n_fine)) / double(std::max(n_coarse, n_fine)), 0.20);
}

// Fig. A.2: node i on a crease between two planes meeting along the x axis
// at slope s, its six neighbours two on the crease and two on each side,
// closed below by an apex so the surface is a closed manifold.
SurfaceMesh crease(double s)
{
    SurfaceMesh mesh;
    mesh.points = {{0, 0, 0},                                  // 0: i
                   {1, 0, 0},     {0.5, 1, -s},  {-0.5, 1, -s}, // 1: j on the crease, 2, 3 on one side
                   {-1, 0, 0},    {-0.5, -1, -s}, {0.5, -1, -s}, // 4: on the crease, 5, 6 on the other side
                   {0, 0, -3}};                                 // 7: apex below
    for (int32_t k = 0; k < 6; ++k) {
        const int32_t a = 1 + k, b = 1 + (k + 1) % 6;
        mesh.triangles.push_back({0, a, b});
        mesh.triangles.push_back({7, b, a});
    }
    return mesh;
}

TEST(RemeshDamage, MergeAlongACreaseIsAcceptedAndAcrossItRejected)
{
    const SurfaceMesh mesh = crease(0.5);
    ASSERT_TRUE(surface_facts(mesh).closed_manifold());
    ASSERT_GT(signed_volume(mesh), 0);
    RemeshParams params;
    const std::vector<double> d(mesh.points.size(), 5.0); // merge_length 1.5, toldamage 0.1 (mm)

    const remeshing::Check along = remeshing::check_merge(mesh, d, 0, 1, params);
    EXPECT_EQ(along.verdict, remeshing::Verdict::accepted);
    EXPECT_LT(along.damage, 1e-12);

    const remeshing::Check across = remeshing::check_merge(mesh, d, 0, 2, params);
    EXPECT_EQ(across.verdict, remeshing::Verdict::damage);
    EXPECT_GT(across.damage, across.toldamage);

    // On a flat fan the same merge across is harmless: the crease is what the
    // damage sees.
    const remeshing::Check flat = remeshing::check_merge(crease(0.0), d, 0, 2, params);
    EXPECT_EQ(flat.verdict, remeshing::Verdict::accepted);
    EXPECT_LT(flat.damage, 1e-12);
}

// Where two triangles meet at a crease sharper than a right angle (found
// where a branch of a bifurcating tree leaves its parent), swapping their
// edge passed every old test: the smallest angle grew (0.17 to 0.43 rad),
// the damage stayed below K/(30M) d and each new normal lay within a right
// angle of the sum of the old ones; yet each new triangle faced away from
// one of the old ones and lay over the fan beside it, and the remeshed
// surface crossed itself. The swap is refused as a fold.
TEST(RemeshFold, SwapAcrossACreaseSharperThanARightAngleIsRefused)
{
    SurfaceMesh mesh;
    // Old triangles (a, b, c) and (b, a, e) on edge a - b; apex z closes the
    // surface below, with no edge c - e.
    const Vec3 a{0, 0, 0}, b{0.0254, -0.18854, -0.4354}, c{0.59729, 0.19425, -0.7517}, e{0.0193, 1.18832, 0.6351};
    const Vec3 patch = cross(b - a, c - a) + cross(a - b, e - b);
    const Vec3 z = (a + b + c + e) / 4 - normalized(patch);
    mesh.points = {a, b, c, e, z};
    mesh.triangles = {{0, 1, 2}, {1, 0, 3}, {2, 1, 4}, {0, 2, 4}, {3, 0, 4}, {1, 3, 4}};
    ASSERT_TRUE(surface_facts(mesh).closed_manifold());
    RemeshParams params;
    params.K = 4.2;
    params.M = 5;
    const std::vector<double> d(mesh.points.size(), 3.6); // target 3.02 mm, toldamage 0.1 mm
    // What the old tests saw: both new normals within a right angle of the
    // old ones' sum.
    const Vec3 n1 = cross(a - c, e - c), n2 = cross(b - e, c - e);
    ASSERT_GT(dot(n1, patch), 0);
    ASSERT_GT(dot(n2, patch), 0);
    // Each new triangle faces away from one of the old ones.
    EXPECT_LT(dot(n1, cross(b - a, c - a)), 0);
    EXPECT_EQ(remeshing::check_swap(mesh, d, 0, 1, params).verdict, remeshing::Verdict::fold);

    // A flat quad of the same shape of connections swaps: its long edge
    // a - b gives way to the short c - e.
    SurfaceMesh flat = mesh;
    flat.points = {{0, -1, 0}, {0, 1, 0}, {-0.4, 0, 0}, {0.4, 0, 0}, {0, 0, -1}};
    ASSERT_TRUE(surface_facts(flat).closed_manifold());
    ASSERT_GT(signed_volume(flat), 0);
    EXPECT_EQ(remeshing::check_swap(flat, d, 0, 1, params).verdict, remeshing::Verdict::accepted);
}

TEST(RemeshTopology, MergesRefuseToCollapseATetrahedronOrPinchAHandle)
{
    SurfaceMesh tet;
    tet.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    tet.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    const std::vector<double> d(4, 100.0);
    EXPECT_EQ(remeshing::check_merge(tet, d, 0, 1, RemeshParams{}).verdict, remeshing::Verdict::topology);

    // A coarse torus whose tube is three vertices round: every merge along
    // the tube would pinch it.
    SurfaceMesh torus;
    const int ring = 3, around = 3;
    for (int u = 0; u < around; ++u)
        for (int v = 0; v < ring; ++v) {
            const double a = 2 * std::numbers::pi * u / around, b = 2 * std::numbers::pi * v / ring;
            torus.points.push_back({(3 + std::cos(b)) * std::cos(a), (3 + std::cos(b)) * std::sin(a), std::sin(b)});
        }
    auto id = [&](int u, int v) { return int32_t(((u + around) % around) * ring + (v + ring) % ring); };
    for (int u = 0; u < around; ++u)
        for (int v = 0; v < ring; ++v) {
            torus.triangles.push_back({id(u, v), id(u + 1, v), id(u + 1, v + 1)});
            torus.triangles.push_back({id(u, v), id(u + 1, v + 1), id(u, v + 1)});
        }
    orient_outward(torus);
    ASSERT_TRUE(surface_facts(torus).closed_manifold());
    ASSERT_EQ(surface_facts(torus).euler_characteristic, 0);
    const std::vector<double> big(torus.points.size(), 1000.0);
    for (const auto& [a, b] : unique_edges(torus)) {
        EXPECT_NE(remeshing::check_merge(torus, big, a, b, RemeshParams{}).verdict, remeshing::Verdict::accepted);
        EXPECT_NE(remeshing::check_merge(torus, big, b, a, RemeshParams{}).verdict, remeshing::Verdict::accepted);
    }
    // And the whole loop leaves it a torus.
    RemeshParams params;
    params.sizing.L_min = 0.5;
    params.sizing.L_max = 1000;
    const RemeshResult r = remesh_to_feature_size(torus, big, params);
    EXPECT_TRUE(surface_facts(r.surface).closed_manifold());
    EXPECT_EQ(surface_facts(r.surface).euler_characteristic, 0);
}

TEST(RemeshPatches, PatchBordersStayWhereTheyAre)
{
    Case c = phantom_case("tube", 0.5);
    // The two end caps (and a little of the rim) become patch 1.
    c.input.triangle_patch.resize(c.input.triangles.size());
    for (size_t f = 0; f < c.input.triangles.size(); ++f) {
        const Triangle& t = c.input.triangles[f];
        const double z = (c.input.points[t[0]].z + c.input.points[t[1]].z + c.input.points[t[2]].z) / 3;
        c.input.triangle_patch[f] = std::abs(z) > 14.5 ? 1 : 0;
    }
    auto border_points = [](const SurfaceMesh& mesh) {
        const VertexTable fans = vertex_triangles(mesh);
        std::vector<Vec3> border;
        for (int32_t v = 0; v < static_cast<int32_t>(mesh.points.size()); ++v) {
            bool zero = false, one = false;
            for (const int32_t* f = fans.begin(v); f != fans.end(v); ++f) (mesh.triangle_patch[*f] ? one : zero) = true;
            if (zero && one) border.push_back(mesh.points[v]);
        }
        return border;
    };
    const std::vector<Vec3> before = border_points(c.input);
    ASSERT_GT(before.size(), 20u);
    const RemeshResult r = remesh_to_feature_size(c.input, c.sizing.d, c.params);
    ASSERT_EQ(r.surface.triangle_patch.size(), r.surface.triangles.size());
    EXPECT_TRUE(surface_facts(r.surface).closed_manifold());
    // Every border node survives at its exact place (bisection may add more).
    const std::vector<Vec3> after = border_points(r.surface);
    for (const Vec3& p : before)
        EXPECT_NE(std::find(after.begin(), after.end(), p), after.end()) << p.x << " " << p.y << " " << p.z;
    // Both patches are still there and the rest of the surface was coarsened.
    const auto caps = std::count(r.surface.triangle_patch.begin(), r.surface.triangle_patch.end(), 1);
    EXPECT_GT(caps, 0);
    EXPECT_LT(r.surface.triangles.size(), c.input.triangles.size() / 2);
}

// A sphere of radius r: the octahedron with every face split into n^2
// triangles, pushed out to the sphere. Its six original corners have four
// neighbours, the rest six (the corners on the octahedron's edges).
SurfaceMesh octahedron_sphere(int n, double r)
{
    SurfaceMesh mesh;
    const Vec3 corners[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    const int faces[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    std::vector<std::pair<Vec3, int32_t>> seen; // the shared points, by position before projection
    auto id = [&](const Vec3& p) {
        for (const auto& [q, i] : seen)
            if (distance(p, q) < 1e-9) return i;
        const auto i = static_cast<int32_t>(mesh.points.size());
        seen.emplace_back(p, i);
        mesh.points.push_back(r * normalized(p));
        return i;
    };
    for (const auto& f : faces) {
        const Vec3 &a = corners[f[0]], &b = corners[f[1]], &c = corners[f[2]];
        auto at = [&](int i, int j) { return id(a + (double(i) / n) * (b - a) + (double(j) / n) * (c - a)); };
        for (int i = 0; i < n; ++i)
            for (int j = 0; i + j < n; ++j) {
                mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i, j + 1)});
                if (i + j + 2 <= n) mesh.triangles.push_back({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
            }
    }
    return mesh;
}

// The hang on the real aorta STL (scalemesh run, first refinement retry):
// the volume the swaps removed was given back by per-node moves scaled with
// one common factor, solved for by Newton's method. Where gains and losses
// nearly balance (some nodes with lost volume, some with gained), that
// factor's slope nearly vanishes, the factor became ~1e8, nodes were thrown
// millions of mm away, and bisection then split the giant edges without end.
// Here one node lost volume and another gained it, in every ratio between
// them, on nodes of different valence (so that some ratio made the old
// slope vanish): the moves must stay of the size of the lost volume over the
// fan area, and the volume must come back exactly.
TEST(RemeshVolume, GivingBackBalancedGainsAndLossesMovesNodesALittle)
{
    const SurfaceMesh sphere = octahedron_sphere(8, 10.0);
    ASSERT_TRUE(surface_facts(sphere).closed_manifold());
    const double volume = signed_volume(sphere);
    const int32_t corner = 0;                                         // four neighbours
    const auto regular = static_cast<int32_t>(sphere.points.size() - 1); // six
    ASSERT_LT(distance(sphere.points[corner], Vec3{10, 0, 0}), 1e-12);
    const double lost = 0.05; // mm^3; a fan here is about 3 * 1.7 mm^2, so a move of about 0.03 mm
    const std::vector<char> held(sphere.points.size(), 0);
    for (int step = 0; step <= 2000; ++step) {
        const double gained = lost * (0.2 + 1.6 * step / 2000.0);
        remeshing::HalfedgeMesh mesh(sphere);
        std::vector<double> lost_at(sphere.points.size(), 0.0);
        lost_at[corner] = lost;
        lost_at[regular] = -gained;
        // The surface as the merges and swaps left it: the input's volume
        // less what was removed.
        const double target = volume + lost - gained;
        const double largest = remeshing::give_back_volume(mesh, lost_at, held, target);
        ASSERT_LT(largest, 0.1) << "gained " << gained;
        ASSERT_NEAR(remeshing::enclosed_volume(mesh), target, 1e-12 * volume) << "gained " << gained;
        for (double v : lost_at) ASSERT_EQ(v, 0.0);
    }
}

// A closed cylinder along z from 0 to `length`: the wall (patch 0) and two
// flat discs, the bottom cap at z = 0 (patch 1) and the top cap at z =
// length (patch 2), all with edges of about h. Each cap is a fan around its
// centre and rings of growing point counts joined by zippers.
SurfaceMesh capped_cylinder(double radius, double length, double h)
{
    SurfaceMesh mesh;
    const double two_pi = 2 * std::numbers::pi;
    const int around = static_cast<int>(std::lround(two_pi * radius / h));
    const int along = static_cast<int>(std::lround(length / h));
    auto ring_point = [&](double r, int k, int n, double z) {
        return Vec3{r * std::cos(two_pi * k / n), r * std::sin(two_pi * k / n), z};
    };
    for (int j = 0; j <= along; ++j)
        for (int i = 0; i < around; ++i) mesh.points.push_back(ring_point(radius, i, around, length * j / along));
    auto wall = [&](int i, int j) { return int32_t(j * around + (i % around)); };
    for (int j = 0; j < along; ++j)
        for (int i = 0; i < around; ++i) {
            mesh.triangles.push_back({wall(i, j), wall(i + 1, j), wall(i + 1, j + 1)});
            mesh.triangles.push_back({wall(i, j), wall(i + 1, j + 1), wall(i, j + 1)});
        }
    mesh.triangle_patch.assign(mesh.triangles.size(), 0);

    const int rings = static_cast<int>(std::lround(radius / h));
    for (int cap = 1; cap <= 2; ++cap) {
        const double z = cap == 1 ? 0.0 : length;
        const int end = cap == 1 ? 0 : along;
        auto add = [&](int32_t a, int32_t b, int32_t c) {
            // Counter-clockwise seen from +z; the bottom cap faces -z.
            mesh.triangles.push_back(cap == 2 ? Triangle{a, b, c} : Triangle{a, c, b});
            mesh.triangle_patch.push_back(cap);
        };
        const auto centre = static_cast<int32_t>(mesh.points.size());
        mesh.points.push_back({0, 0, z});
        std::vector<int32_t> inner = {centre};
        for (int k = 1; k <= rings; ++k) {
            std::vector<int32_t> outer;
            if (k == rings) {
                for (int i = 0; i < around; ++i) outer.push_back(wall(i, end));
            } else {
                const int n = std::max(3, static_cast<int>(std::lround(two_pi * radius * k / rings / h)));
                for (int i = 0; i < n; ++i) {
                    outer.push_back(static_cast<int32_t>(mesh.points.size()));
                    mesh.points.push_back(ring_point(radius * k / rings, i, n, z));
                }
            }
            const auto m_in = static_cast<int>(inner.size()), m_out = static_cast<int>(outer.size());
            if (m_in == 1) {
                for (int i = 0; i < m_out; ++i) add(centre, outer[i], outer[(i + 1) % m_out]);
            } else {
                // Advance along whichever loop has the nearer next point.
                int i = 0, o = 0;
                while (i < m_in || o < m_out) {
                    const bool step_outer = i == m_in || (o < m_out && double(o + 1) / m_out < double(i + 1) / m_in);
                    if (step_outer) {
                        add(outer[o % m_out], outer[(o + 1) % m_out], inner[i % m_in]);
                        ++o;
                    } else {
                        add(inner[i % m_in], outer[o % m_out], inner[(i + 1) % m_in]);
                        ++i;
                    }
                }
            }
            inner = std::move(outer);
        }
    }
    return mesh;
}

// Per undirected edge (smaller node first), the patches of the triangles on it.
std::map<std::pair<int32_t, int32_t>, std::vector<int32_t>> edge_patches(const SurfaceMesh& mesh)
{
    std::map<std::pair<int32_t, int32_t>, std::vector<int32_t>> patches;
    for (size_t f = 0; f < mesh.triangles.size(); ++f)
        for (int k = 0; k < 3; ++k) {
            const int32_t u = mesh.triangles[f][k], v = mesh.triangles[f][(k + 1) % 3];
            patches[{std::min(u, v), std::max(u, v)}].push_back(mesh.triangle_patch[f]);
        }
    return patches;
}

// Edges between patch a and patch b.
int64_t border_edge_count(const SurfaceMesh& mesh, int32_t a, int32_t b)
{
    int64_t n = 0;
    for (const auto& [edge, p] : edge_patches(mesh))
        n += p.size() == 2 && ((p[0] == a && p[1] == b) || (p[0] == b && p[1] == a));
    return n;
}

// Remeshes a capped cylinder with d = 6 mm everywhere (edges of 0.5 mm in)
// and checks what must hold whatever the rim's final count: topology and
// volume kept, caps flat and unfolded. Returns per cap the rim edges before
// and after, the cap area before and after and the shortest and longest rim
// edge after; the furthest a rim node lies from the input's rim; and the
// wall's edges around the middle.
struct CapFigures {
    int64_t rim_before[3] = {}, rim[3] = {};
    double area_before[3] = {}, area[3] = {};
    double shortest_rim_edge[3] = {}, longest_rim_edge[3] = {}; // mm, after
    double rim_off_input = 0; // mm, the furthest a rim node lies from the input's rim polygon
    int64_t wall_around = 0;
};

CapFigures remesh_capped_cylinder(double radius, bool relax_rims = true)
{
    const double length = 20, h = 0.5, d = 6;
    const SurfaceMesh input = capped_cylinder(radius, length, h);
    const SurfaceFacts before = surface_facts(input);
    EXPECT_TRUE(before.closed_manifold());
    EXPECT_EQ(before.euler_characteristic, 2);
    EXPECT_GT(before.signed_volume, 0);

    RemeshParams params;
    params.sizing.L_min = 0.25;
    params.sizing.L_max = 20;
    params.max_displacement = h / 3;
    params.patch_normals = {Vec3{}, Vec3{0, 0, -1}, Vec3{0, 0, 1}};
    params.relax_rims = relax_rims;
    const RemeshResult r = remesh_to_feature_size(input, std::vector<double>(input.points.size(), d), params);
    const SurfaceFacts after = surface_facts(r.surface);
    EXPECT_TRUE(after.closed_manifold());
    EXPECT_EQ(after.euler_characteristic, before.euler_characteristic);
    EXPECT_EQ(after.components, 1);
    EXPECT_NEAR(after.signed_volume, before.signed_volume, 1e-9 * before.signed_volume);
    EXPECT_EQ(r.surface.triangle_patch.size(), r.surface.triangles.size());
    // Every point has at least three neighbours.
    const VertexTable fans = vertex_triangles(r.surface);
    for (int32_t v = 0; v < static_cast<int32_t>(r.surface.points.size()); ++v) EXPECT_GE(fans.size(v), 3) << v;

    // Every point of a cap face on its plane, every cap face facing along
    // the plane normal (no fold inside a cap).
    CapFigures figures;
    const double size = std::hypot(2 * radius, 2 * radius, length);
    auto cap_area = [&](const SurfaceMesh& mesh, int32_t cap, bool check) {
        const double z = cap == 1 ? 0.0 : length;
        double area = 0;
        for (size_t f = 0; f < mesh.triangles.size(); ++f) {
            if (mesh.triangle_patch[f] != cap) continue;
            const Triangle& t = mesh.triangles[f];
            const Vec3& a = mesh.points[t[0]];
            const double projected = 0.5 * dot(cross(mesh.points[t[1]] - a, mesh.points[t[2]] - a), params.patch_normals[cap]);
            area += projected;
            if (!check) continue;
            for (int32_t v : t) EXPECT_LE(std::abs(mesh.points[v].z - z), 1e-9 * size) << "cap " << cap;
            EXPECT_GT(projected, 0) << "cap " << cap;
        }
        return area;
    };
    for (int32_t cap = 1; cap <= 2; ++cap) {
        figures.area_before[cap] = cap_area(input, cap, false);
        figures.area[cap] = cap_area(r.surface, cap, true);
        figures.rim_before[cap] = border_edge_count(input, 0, cap);
        figures.rim[cap] = border_edge_count(r.surface, 0, cap);
        figures.shortest_rim_edge[cap] = std::numeric_limits<double>::infinity();
    }
    {
        for (const auto& [edge, p] : edge_patches(r.surface)) {
            if (p.size() != 2 || (p[0] == 0) == (p[1] == 0)) continue;
            const int32_t cap = std::max(p[0], p[1]);
            const double length = distance(r.surface.points[edge.first], r.surface.points[edge.second]);
            figures.shortest_rim_edge[cap] = std::min(figures.shortest_rim_edge[cap], length);
            figures.longest_rim_edge[cap] = std::max(figures.longest_rim_edge[cap], length);
            // The input's rim: the regular polygon of its rim_before corners
            // on the circle (capped_cylinder's first corner on the x axis).
            const double step = 2 * std::numbers::pi / double(figures.rim_before[cap]);
            for (int32_t v : {edge.first, edge.second}) {
                const Vec3& x = r.surface.points[v];
                const double angle = std::atan2(x.y, x.x);
                const double k = std::floor((angle < 0 ? angle + 2 * std::numbers::pi : angle) / step);
                const Vec3 a{radius * std::cos(k * step), radius * std::sin(k * step), x.z};
                const Vec3 b{radius * std::cos((k + 1) * step), radius * std::sin((k + 1) * step), x.z};
                const double t = std::clamp(dot(x - a, b - a) / norm2(b - a), 0.0, 1.0);
                figures.rim_off_input = std::max(figures.rim_off_input, distance(x, a + t * (b - a)));
            }
        }
    }
    for (const auto& [a, b] : unique_edges(r.surface))
        figures.wall_around += (r.surface.points[a].z < 0.5 * length) != (r.surface.points[b].z < 0.5 * length);
    std::printf("cylinder r = %g mm: wall edges around %lld, perimeter / (K/M d) = %.2f\n", radius,
                (long long)figures.wall_around, 2 * std::numbers::pi * radius / (kK / kM * d));
    for (int32_t cap = 1; cap <= 2; ++cap)
        std::printf("  cap %d: rim edges %lld -> %lld, area %.4f -> %.4f mm^2\n", cap, (long long)figures.rim_before[cap],
                    (long long)figures.rim[cap], figures.area_before[cap], figures.area[cap]);
    for (int32_t cap = 1; cap <= 2; ++cap)
        std::printf("  cap %d (relax_rims %d): rim edges %.3f to %.3f mm, rim nodes up to %.2g mm off the input rim\n",
                    cap, int(relax_rims), figures.shortest_rim_edge[cap], figures.longest_rim_edge[cap],
                    figures.rim_off_input);
    return figures;
}

// Where d (6 mm) is small against the radius of curvature (20 mm), the rim
// is coarsened like the wall beside it, into the paper's band of edge
// lengths [K/(2M) d, K/M d], and the cap loses only the thin segments its
// chords cut off the disc. (The wall edges crossing a ring count each
// column about twice: a vertical and a diagonal.)
TEST(RemeshPatches, FlatCapsOfAWideCylinderGetTheTargetRim)
{
    const double radius = 20, target = kK / kM * 6;
    const CapFigures f = remesh_capped_cylinder(radius);
    const double perimeter = 2 * std::numbers::pi * radius;
    for (int cap = 1; cap <= 2; ++cap) {
        EXPECT_GE(double(f.rim[cap]), perimeter / target) << "cap " << cap;
        EXPECT_LE(double(f.rim[cap]), 2 * perimeter / target) << "cap " << cap;
        EXPECT_GT(double(f.rim[cap]), 0.5 * double(f.wall_around) / 1.5) << "cap " << cap;
        EXPECT_LT(double(f.rim[cap]), 0.5 * double(f.wall_around) * 1.5) << "cap " << cap;
        EXPECT_NEAR(f.area[cap], f.area_before[cap], 0.02 * f.area_before[cap]) << "cap " << cap;
    }
}

// On a 6 mm tube with d = 6 mm the damage limit (K/(30M) d = 0.12 mm of
// chord height) stops coarsening around the circumference at about fifteen
// edges, for the wall and for the rim alike, not at perimeter / (K/M d) =
// 5.2: the rim follows the wall, at well under half its input count. The
// cap loses the segments of those chords, a few percent of the disc.
TEST(RemeshPatches, FlatCapsOfANarrowTubeFollowTheWall)
{
    const CapFigures f = remesh_capped_cylinder(3);
    ASSERT_GT(f.wall_around, 0);
    for (int cap = 1; cap <= 2; ++cap) {
        EXPECT_LT(f.rim[cap], f.rim_before[cap] / 2) << "cap " << cap;
        EXPECT_GT(double(f.rim[cap]), 0.5 * double(f.wall_around) / 1.5) << "cap " << cap;
        EXPECT_LT(double(f.rim[cap]), 0.5 * double(f.wall_around) * 1.5) << "cap " << cap;
        // A regular 10-gon keeps 93.5% of its circle's area.
        EXPECT_GT(f.area[cap], 0.935 * f.area_before[cap]) << "cap " << cap;
        EXPECT_LE(f.area[cap], f.area_before[cap] * (1 + 1e-12)) << "cap " << cap;
    }
}

TEST(RemeshPatches, RimsAreEvenedAlongTheInputRim)
{
    for (const double radius : {3.0, 20.0}) {
        const CapFigures relaxed = remesh_capped_cylinder(radius, true);
        const CapFigures fixed = remesh_capped_cylinder(radius, false);
        for (int cap = 1; cap <= 2; ++cap) {
            EXPECT_GT(relaxed.shortest_rim_edge[cap], 0.5 * relaxed.longest_rim_edge[cap]) << radius << " cap " << cap;
            // Without: the merges, which must end on an input point, leave
            // rim edges of the input's 0.5 mm beside ones three times longer.
            EXPECT_LT(fixed.shortest_rim_edge[cap], 0.5 * fixed.longest_rim_edge[cap]) << radius << " cap " << cap;
        }
        // Every rim node on the input's rim polygon. Without, the wide
        // cylinder's rim is bisected where merges left it long, and the
        // midpoints lie on chords inside the polygon.
        EXPECT_LE(relaxed.rim_off_input, 1e-9 * radius) << radius;
        if (radius == 20.0) EXPECT_GT(fixed.rim_off_input, 1e-3 * radius);
    }
}

TEST(RemeshInput, AFlatPatchOffItsPlaneIsRefused)
{
    const SurfaceMesh cylinder = capped_cylinder(3, 20, 1.0);
    RemeshParams params;
    params.sizing.L_min = 0.25;
    params.sizing.L_max = 20;
    const std::vector<double> d(cylinder.points.size(), 6.0);
    params.patch_normals = {Vec3{}, Vec3{1, 0, 0}, Vec3{0, 0, 1}}; // cap 1 is not in a plane x = const
    EXPECT_THROW(remesh_to_feature_size(cylinder, d, params), InputError);
    params.patch_normals = {Vec3{}, Vec3{0, 0, std::nan("")}};
    EXPECT_THROW(remesh_to_feature_size(cylinder, d, params), InputError);
    params.patch_normals = {Vec3{}, Vec3{0, 0, -2}}; // any length; patch 2 past the end is curved
    EXPECT_NO_THROW(remesh_to_feature_size(cylinder, d, params));
}

TEST(RemeshInput, BadInputIsRefusedWithAHint)
{
    const SurfaceMesh mesh = crease(0.5);
    RemeshParams params;
    EXPECT_THROW(remesh_to_feature_size(mesh, std::vector<double>(mesh.points.size(), 1.0), params), InputError)
        << "L_min and L_max are required";
    params.sizing.L_min = 0.25;
    params.sizing.L_max = 20;
    EXPECT_THROW(remesh_to_feature_size(mesh, std::vector<double>(3, 1.0), params), InputError);
    EXPECT_THROW(remesh_to_feature_size(mesh, std::vector<double>(mesh.points.size(), -1.0), params), InputError);
    SurfaceMesh open = mesh;
    open.triangles.pop_back();
    EXPECT_THROW(remesh_to_feature_size(open, std::vector<double>(open.points.size(), 1.0), params), InputError);
    params.parallel_merge_cube = 0;
    EXPECT_THROW(remesh_to_feature_size(mesh, std::vector<double>(mesh.points.size(), 1.0), params), InputError);
    params.parallel_merge_cube = 12;
    params.cycles = 0;
    const RemeshResult r = remesh_to_feature_size(mesh, std::vector<double>(mesh.points.size(), 1.0), params);
    EXPECT_EQ(r.surface.triangles.size(), mesh.triangles.size());
}

} // namespace
} // namespace scalemesh
