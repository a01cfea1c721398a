// Issue 10, item 3: hostile but valid input. Each case either meshes with
// every mesh fact holding (hostile_support.h) or is refused with exit 2 and
// one line saying what is wrong and what to do; never a crash, a hang (the
// run is killed after two minutes) or an invalid mesh. docs/reliability.md
// lists the cases and their outcomes.

#include "hostile_support.h"

#include <nlohmann/json.hpp>

#include <cmath>

namespace scalemesh {
namespace {

constexpr int kTimeLimit = 120; // seconds; each case takes a few

nlohmann::json report(const TempDir& dir) { return nlohmann::json::parse(std::ifstream(dir.path / "report.json")); }

// An image case: image.mha with [input] file and any further case text.
CommandResult run_image(const TempDir& dir, std::array<int, 3> size, double spacing, const VoxelTest& inside,
                        const std::string& more = "")
{
    write_label_mha(dir.path / "image.mha", size, spacing, inside);
    write_case(dir.path, "[input]\nfile = \"image.mha\"\n" + more);
    return run_case_limited(dir.path, kTimeLimit);
}

void expect_meshed(const CommandResult& r, const TempDir& dir)
{
    ASSERT_EQ(r.exit_code, 0) << r.err;
    expect_mesh_facts(dir.path);
}

TEST(HostileInput, OneVoxelBridgeBetweenTwoBalls)
{
    const TempDir dir;
    const auto a = ball({5, 7, 7}, 4), b = ball({19, 7, 7}, 4);
    expect_meshed(run_image(dir, {25, 15, 15}, 0.5,
                            [&](int i, int j, int k) { return a(i, j, k) || b(i, j, k) || (j == 7 && k == 7 && i > 5 && i < 19); }),
                  dir);
    EXPECT_EQ(report(dir)["remeshed_surface"]["components"], 1) << "the bridge joins the balls";
}

TEST(HostileInput, OneVoxelHoleInsideABall)
{
    const TempDir dir;
    const auto a = ball({7, 7, 7}, 5);
    expect_meshed(run_image(dir, {15, 15, 15}, 0.5, [&](int i, int j, int k) { return a(i, j, k) && !(i == 7 && j == 7 && k == 7); }),
                  dir);
    // The hole stays a cavity: an outer wall and the cavity's, Euler
    // characteristic 2 each.
    EXPECT_EQ(report(dir)["remeshed_surface"]["components"], 2);
    EXPECT_EQ(report(dir)["remeshed_surface"]["euler_characteristic"], 4);
}

TEST(HostileInput, SingleIsolatedVoxel)
{
    const TempDir dir;
    expect_meshed(run_image(dir, {5, 5, 5}, 0.5, [](int i, int j, int k) { return i == 2 && j == 2 && k == 2; }), dir);
}

TEST(HostileInput, StrayVoxelBesideABall)
{
    const TempDir dir;
    const auto a = ball({7, 7, 7}, 5);
    expect_meshed(run_image(dir, {20, 15, 15}, 0.5, [&](int i, int j, int k) { return a(i, j, k) || (i == 17 && j == 7 && k == 7); }),
                  dir);
    EXPECT_EQ(report(dir)["remeshed_surface"]["components"], 2);
}

TEST(HostileInput, LabelFillingTheWholeImage)
{
    const TempDir dir;
    expect_meshed(run_image(dir, {10, 10, 10}, 0.5, [](int, int, int) { return true; }), dir);
}

TEST(HostileInput, BallCutByEveryImageFace)
{
    const TempDir dir;
    expect_meshed(run_image(dir, {12, 12, 12}, 0.5, ball({6, 6, 6}, 8)), dir);
}

TEST(HostileInput, LabelFillingTheImageWithBorderOpenings)
{
    const TempDir dir;
    expect_meshed(run_image(dir, {10, 10, 10}, 0.5, [](int, int, int) { return true; },
                            "[[openings]]\nname = \"in\"\ntype = \"inlet\"\nborder = \"z-\"\n"
                            "[[openings]]\nname = \"out\"\ntype = \"outlet\"\nborder = \"z+\"\n"),
                  dir);
}

TEST(HostileInput, OneByNByNSlabImage)
{
    const TempDir dir;
    expect_meshed(run_image(dir, {1, 12, 12}, 0.5, [](int, int, int) { return true; }), dir);
    // The plate is one voxel thick, yet the layers fit across it.
    const nlohmann::json q = report(dir)["volume"]["quality_after_sliver_removal"];
    EXPECT_GT(q["min_aspect_ratio"].get<double>(), 0.05);
}

TEST(HostileInput, VoxelsOfAMillionthOfAMillimetreAreRefused)
{
    // OpenVDB cannot invert a transform this small; the importer says so.
    const TempDir dir;
    const CommandResult r = run_image(dir, {15, 15, 15}, 1e-6, ball({7, 7, 7}, 5));
    expect_refused(r, dir.path, {"image.mha"});
    EXPECT_NE(r.err.find("spacing 1e-06"), std::string::npos) << r.err;
}

TEST(HostileInput, VoxelsOfAMetre)
{
    const TempDir dir;
    expect_meshed(run_image(dir, {15, 15, 15}, 1e3, ball({7, 7, 7}, 5)), dir);
    // Scale invariance: with 1024 mm voxels (a power of two, so that every
    // product scales exactly; 1e3 rounds differently and may break a tie
    // elsewhere) the very mesh of 1 mm voxels, scaled.
    const TempDir large, unit;
    expect_meshed(run_image(large, {15, 15, 15}, 1024, ball({7, 7, 7}, 5)), large);
    expect_meshed(run_image(unit, {15, 15, 15}, 1, ball({7, 7, 7}, 5)), unit);
    EXPECT_EQ(report(large)["volume"]["tets"], report(unit)["volume"]["tets"]);
    EXPECT_DOUBLE_EQ(report(large)["volume"]["volume_mm3"].get<double>(),
                     std::pow(1024.0, 3) * report(unit)["volume"]["volume_mm3"].get<double>());
}

TEST(HostileInput, HundredSeparateComponents)
{
    const TempDir dir;
    std::vector<VoxelTest> balls;
    for (int a = 0; a < 5; ++a)
        for (int b = 0; b < 5; ++b)
            for (int c = 0; c < 4; ++c) balls.push_back(ball({3 + 6 * a, 3 + 6 * b, 3 + 6 * c}, 2));
    expect_meshed(run_image(dir, {30, 30, 24}, 0.5,
                            [&](int i, int j, int k) {
                                return std::any_of(balls.begin(), balls.end(), [&](const VoxelTest& f) { return f(i, j, k); });
                            }),
                  dir);
    EXPECT_EQ(report(dir)["remeshed_surface"]["components"], 100);
}

// A 10 mm cube whose top face is fanned from a point 0.01 degrees off one
// of its edges: triangle (a, b, p) has angles of 0.01 degrees at a and b.
std::vector<std::array<Vec3, 3>> cube_with_sliver(double scale)
{
    const double L = 10 * scale, eps = L / 2 * std::tan(0.01 * M_PI / 180);
    const Vec3 a{0, 0, L}, b{L, 0, L}, c{L, L, L}, d{0, L, L}, p{L / 2, eps, L};
    const Vec3 e{0, 0, 0}, f{L, 0, 0}, g{L, L, 0}, h{0, L, 0};
    return {{a, b, p}, {b, c, p}, {c, d, p}, {d, a, p}, {e, g, f}, {e, h, g}, {e, f, b},
            {e, b, a}, {f, g, c}, {f, c, b}, {g, h, d}, {g, d, c}, {h, e, a}, {h, a, d}};
}

TEST(HostileInput, SurfaceWithASliverTriangle)
{
    for (const double scale : {1.0, 1e-6, 1e3}) {
        SCOPED_TRACE(scale);
        const TempDir dir;
        write_stl(dir.path / "cube.stl", cube_with_sliver(scale));
        write_case(dir.path, "[input]\nfile = \"cube.stl\"\n");
        expect_meshed(run_case_limited(dir.path, kTimeLimit), dir);
        // STL stores single-precision coordinates: the cube is exact only to that.
        const double volume = 1000 * std::pow(scale, 3);
        EXPECT_NEAR(report(dir)["volume"]["volume_mm3"].get<double>(), volume, 1e-6 * volume);
    }
}

TEST(HostileInput, SharedAortaSurfaceWithSliverTriangles)
{
    const std::filesystem::path aorta = std::filesystem::absolute("../shared/data/vmtk_aorta_capped.stl");
    if (!std::filesystem::exists(aorta)) GTEST_SKIP() << aorta << " is not there";
    const TempDir dir;
    write_case(dir.path, "[input]\nfile = " + quote(aorta.string()) + "\n");
    expect_meshed(run_case_limited(dir.path, kTimeLimit), dir);
}

} // namespace
} // namespace scalemesh
