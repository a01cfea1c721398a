// Facts the marching cubes surface must keep (DESIGN.md, "Isosurface"):
// closed, 2-manifold, consistently oriented outwards, with the topology of
// the voxel set, for every cube configuration and every phantom.

#include "core/errors.h"
#include "core/surface_mesh.h"
#include "isosurface/marching_cubes.h"
#include "phantom/phantom.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

namespace scalemesh {
namespace {

// Euler characteristic of the digital solid under inside 6-connectivity:
// the cubical complex on inside voxel centres (vertices, face-adjacent pairs,
// full 2x2 squares, full 2x2x2 cubes) is homotopy equivalent to it.
int64_t euler_characteristic_6(const std::vector<openvdb::Coord>& inside)
{
    std::set<openvdb::Coord> set(inside.begin(), inside.end());
    auto in = [&](int x, int y, int z) { return set.count(openvdb::Coord(x, y, z)) > 0; };
    int64_t v = 0, e = 0, f = 0, c = 0;
    for (const openvdb::Coord& p : set) {
        const int x = p.x(), y = p.y(), z = p.z();
        ++v;
        e += in(x + 1, y, z) + in(x, y + 1, z) + in(x, y, z + 1);
        f += (in(x + 1, y, z) && in(x, y + 1, z) && in(x + 1, y + 1, z));
        f += (in(x + 1, y, z) && in(x, y, z + 1) && in(x + 1, y, z + 1));
        f += (in(x, y + 1, z) && in(x, y, z + 1) && in(x, y + 1, z + 1));
        bool cube = true;
        for (int k = 1; k < 8 && cube; ++k) cube = in(x + (k & 1), y + ((k >> 1) & 1), z + ((k >> 2) & 1));
        c += cube;
    }
    return v - e + f - c;
}

// Under inside 26-connectivity the outside is 6-connected: inside a padded
// box B, the outside part Y = B minus the voxels is bounded by the surface S
// and the box, so chi(S) + 2 = 2 chi_6(Y).
int64_t surface_euler_characteristic_26(const std::vector<openvdb::Coord>& inside, int lo, int hi)
{
    std::set<openvdb::Coord> set(inside.begin(), inside.end());
    std::vector<openvdb::Coord> outside;
    for (int x = lo; x <= hi; ++x)
        for (int y = lo; y <= hi; ++y)
            for (int z = lo; z <= hi; ++z)
                if (!set.count(openvdb::Coord(x, y, z))) outside.emplace_back(x, y, z);
    return 2 * euler_characteristic_6(outside) - 2;
}

openvdb::FloatGrid::Ptr label_grid(const std::vector<openvdb::Coord>& inside)
{
    auto grid = openvdb::FloatGrid::create(0.0f);
    for (const auto& c : inside) grid->tree().setValueOn(c, 1.0f);
    return grid;
}

void expect_closed_oriented(const SurfaceMesh& mesh, const std::string& what)
{
    const SurfaceFacts facts = surface_facts(mesh);
    EXPECT_EQ(facts.boundary_edges, 0) << what;
    EXPECT_EQ(facts.nonmanifold_edges, 0) << what;
    EXPECT_EQ(facts.misoriented_edges, 0) << what;
    EXPECT_EQ(facts.nonmanifold_vertices, 0) << what;
    EXPECT_EQ(facts.degenerate_triangles, 0) << what;
    EXPECT_GT(facts.signed_volume, 0) << what;
}

TEST(MarchingCubes, EverySingleCubeConfigurationIsClosedOrientedWithTheVoxelTopology)
{
    for (InsideConnectivity connectivity : {InsideConnectivity::Six, InsideConnectivity::TwentySix}) {
        for (int mask = 1; mask < 256; ++mask) {
            std::vector<openvdb::Coord> inside;
            for (int c = 0; c < 8; ++c)
                if (mask & (1 << c)) inside.emplace_back(c & 1, (c >> 1) & 1, (c >> 2) & 1);
            const SurfaceMesh mesh = marching_cubes(*label_grid(inside), {.iso = 0.5, .connectivity = connectivity});
            const std::string what = "case " + std::to_string(mask);
            expect_closed_oriented(mesh, what);
            const int64_t expected = connectivity == InsideConnectivity::Six
                                         ? 2 * euler_characteristic_6(inside)
                                         : surface_euler_characteristic_26(inside, -1, 2);
            EXPECT_EQ(surface_facts(mesh).euler_characteristic, expected) << what;
        }
    }
}

TEST(MarchingCubes, RandomBlocksAreClosedOrientedWithTheVoxelTopology)
{
    std::mt19937 rng(12345);
    for (int trial = 0; trial < 3000; ++trial) {
        std::bernoulli_distribution coin(trial % 3 == 0 ? 0.3 : (trial % 3 == 1 ? 0.5 : 0.7));
        std::vector<openvdb::Coord> inside;
        for (int x = 0; x < 4; ++x)
            for (int y = 0; y < 4; ++y)
                for (int z = 0; z < 4; ++z)
                    if (coin(rng)) inside.emplace_back(x, y, z);
        if (inside.empty()) continue;
        const auto connectivity = trial % 2 ? InsideConnectivity::Six : InsideConnectivity::TwentySix;
        const SurfaceMesh mesh = marching_cubes(*label_grid(inside), {.iso = 0.5, .connectivity = connectivity});
        const std::string what = "trial " + std::to_string(trial);
        expect_closed_oriented(mesh, what);
        const int64_t expected = connectivity == InsideConnectivity::Six
                                     ? 2 * euler_characteristic_6(inside)
                                     : surface_euler_characteristic_26(inside, -1, 4);
        ASSERT_EQ(surface_facts(mesh).euler_characteristic, expected) << what;
        if (HasFailure()) return;
    }
}

TEST(MarchingCubes, FilledBoxHasTheExpectedFaces)
{
    // A 6^3 block of label voxels: a closed box whose flat faces lie half a
    // voxel outside the outer voxel centres, so its volume is 6^3 exactly
    // less the chamfers along edges and corners.
    std::vector<openvdb::Coord> inside;
    for (int x = 0; x < 6; ++x)
        for (int y = 0; y < 6; ++y)
            for (int z = 0; z < 6; ++z) inside.emplace_back(x, y, z);
    const SurfaceMesh mesh = marching_cubes(*label_grid(inside));
    expect_closed_oriented(mesh, "box");
    Vec3 lo, hi;
    bounding_box(mesh, lo, hi);
    for (int k = 0; k < 3; ++k) {
        EXPECT_DOUBLE_EQ(lo[k], -0.5);
        EXPECT_DOUBLE_EQ(hi[k], 5.5);
    }
    // Each of the 12 box edges loses a prism of cross-section 1/8 and length
    // 5; each of the 8 corner cells of volume 1/8 keeps only the tetrahedron
    // of volume 1/48 under the corner triangle.
    EXPECT_NEAR(signed_volume(mesh), 216.0 - 12 * 5 * 0.125 - 8 * (0.125 - 1.0 / 48.0), 1e-9);
}

TEST(MarchingCubes, LevelSetSphereIsClosedAndNearTheRadius)
{
    auto grid = openvdb::FloatGrid::create(3.0f);
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
    const double R = 6.0;
    for (int x = -16; x <= 16; ++x)
        for (int y = -16; y <= 16; ++y)
            for (int z = -16; z <= 16; ++z) {
                const double d = std::sqrt(0.25 * (x * x + y * y + z * z)) - R;
                if (std::abs(d) < 1.5) grid->tree().setValueOn({x, y, z}, static_cast<float>(d));
                else if (d < 0) grid->tree().setValueOff({x, y, z}, -3.0f);
            }
    const SurfaceMesh mesh = marching_cubes(*grid);
    expect_closed_oriented(mesh, "level set");
    EXPECT_EQ(surface_facts(mesh).euler_characteristic, 2);
    for (const Vec3& p : mesh.points) EXPECT_NEAR(norm(p), R, 0.05);
}

TEST(MarchingCubes, MirroringTransformsStillGiveOutwardNormals)
{
    // Many medical images map index to world with a reflection (x flipped).
    auto grid = voxelize(*make_shape("torus", 0.5), {.voxel_size = 0.5});
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    m.setToScale(openvdb::Vec3d(-0.5, 0.5, 0.5));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(m));
    const SurfaceMesh mesh = marching_cubes(*grid);
    expect_closed_oriented(mesh, "mirrored");
    EXPECT_NEAR(signed_volume(mesh), static_cast<double>(grid->activeVoxelCount()) * 0.125,
                0.03 * static_cast<double>(grid->activeVoxelCount()) * 0.125);
}

TEST(MarchingCubes, RefusesGridsWithoutABoundedSurface)
{
    auto empty = openvdb::FloatGrid::create(0.0f);
    EXPECT_THROW(marching_cubes(*empty), InputError);
    auto grid = label_grid({{0, 0, 0}});
    EXPECT_THROW(marching_cubes(*grid, {.iso = 2.0}), InputError);   // nothing inside
    EXPECT_THROW(marching_cubes(*grid, {.iso = -0.5}), InputError);  // background inside
    EXPECT_THROW(marching_cubes(*grid, {.iso = std::nan("")}), InputError);
}

// Every phantom: closed, oriented, with its analytic topology, its voxel
// volume, and every vertex within a voxel of its analytic surface.
class PhantomSurface : public ::testing::TestWithParam<std::string> {};

TEST_P(PhantomSurface, KeepsTheFactsOfTheAnalyticShape)
{
    const double h = 0.5;
    const auto shape = make_shape(GetParam(), h);
    const auto grid = voxelize(*shape, {.voxel_size = h});
    const SurfaceMesh mesh = marching_cubes(*grid);
    const SurfaceFacts facts = surface_facts(mesh);
    expect_closed_oriented(mesh, GetParam());
    EXPECT_EQ(facts.components, shape->components());
    EXPECT_EQ(facts.euler_characteristic, shape->euler_characteristic());

    const double voxel_volume = static_cast<double>(grid->tree().activeVoxelCount()) * h * h * h;
    EXPECT_NEAR(facts.signed_volume, voxel_volume, 0.03 * voxel_volume);

    // A vertex is within one voxel of the surface when the ball of radius h
    // around it holds points on both sides (sampled along 14 directions).
    int far = 0;
    for (const Vec3& p : mesh.points) {
        bool neg = shape->sdf(p) < 0, pos = !neg;
        for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
                for (int dz = -1; dz <= 1; ++dz) {
                    if (!dx && !dy && !dz) continue;
                    const Vec3 q = p + h * normalized(Vec3{double(dx), double(dy), double(dz)});
                    (shape->sdf(q) < 0 ? neg : pos) = true;
                }
        far += !(neg && pos);
    }
    EXPECT_EQ(far, 0) << "vertices farther than a voxel from the analytic surface";
}

INSTANTIATE_TEST_SUITE_P(AllShapes, PhantomSurface, ::testing::ValuesIn(phantom_names()),
                         [](const auto& info) { return info.param; });

TEST(MarchingCubes, ShellHasOneOuterAndTwoInnerSurfaces)
{
    const auto shape = make_shape("shell", 0.5);
    const SurfaceMesh mesh = marching_cubes(*voxelize(*shape, {.voxel_size = 0.5}));
    int32_t count = 0;
    const std::vector<int32_t> label = triangle_components(mesh, &count);
    ASSERT_EQ(count, 3);
    std::vector<double> volume(3, 0.0);
    for (size_t f = 0; f < mesh.triangles.size(); ++f) {
        const auto& t = mesh.triangles[f];
        volume[label[f]] += dot(mesh.points[t[0]], cross(mesh.points[t[1]], mesh.points[t[2]])) / 6.0;
    }
    std::sort(volume.begin(), volume.end());
    // Cavities bound outside space: their surfaces enclose negative volume.
    EXPECT_LT(volume[0], 0);
    EXPECT_LT(volume[1], 0);
    EXPECT_GT(volume[2], 0);
}

TEST(MarchingCubes, DoesNotDependOnTheThreadCountOrRun)
{
    const auto shape = make_shape("pretzel", 0.4);
    const auto grid = voxelize(*shape, {.voxel_size = 0.4});
    const SurfaceMesh a = marching_cubes(*grid);
    const SurfaceMesh b = marching_cubes(*grid);
    ASSERT_EQ(a.points.size(), b.points.size());
    ASSERT_EQ(a.triangles, b.triangles);
    for (size_t i = 0; i < a.points.size(); ++i) ASSERT_TRUE(a.points[i] == b.points[i]);
}

} // namespace
} // namespace scalemesh
