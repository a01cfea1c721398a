// Issue 10, item 3: hostile but valid input. Each case either meshes with
// every mesh fact holding (hostile_support.h) or is refused with exit 2 and
// one line saying what is wrong and what to do; never a crash, a hang (the
// run is killed after two minutes) or an invalid mesh. Each test records its
// input and what the runs did (RecordedOutcome); reliability_table.py writes
// them into docs/reliability.md.

#include "hostile_support.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <sstream>

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

// The run meshed with every fact holding; its outcome goes to `outcome`
// under `label` whether it did or not.
void expect_meshed(const CommandResult& r, const TempDir& dir, RecordedOutcome& outcome, const std::string& label = "")
{
    if (r.exit_code != 0) outcome.add(describe_unmeshed(r), label);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    outcome.add(describe(expect_mesh_facts(dir.path)), label);
}

TEST(HostileInput, OneVoxelBridgeBetweenTwoBalls)
{
    RecordedOutcome outcome("two balls of radius 4 voxels joined by a line of single voxels (25 x 15 x 15 image, 0.5 mm voxels)");
    const TempDir dir;
    const auto a = ball({5, 7, 7}, 4), b = ball({19, 7, 7}, 4);
    expect_meshed(run_image(dir, {25, 15, 15}, 0.5,
                            [&](int i, int j, int k) { return a(i, j, k) || b(i, j, k) || (j == 7 && k == 7 && i > 5 && i < 19); }),
                  dir, outcome);
    EXPECT_EQ(report(dir)["remeshed_surface"]["components"], 1) << "the bridge joins the balls";
}

TEST(HostileInput, OneVoxelHoleInsideABall)
{
    RecordedOutcome outcome("a ball of radius 5 voxels missing its centre voxel (15^3 image, 0.5 mm voxels)");
    const TempDir dir;
    const auto a = ball({7, 7, 7}, 5);
    expect_meshed(run_image(dir, {15, 15, 15}, 0.5, [&](int i, int j, int k) { return a(i, j, k) && !(i == 7 && j == 7 && k == 7); }),
                  dir, outcome);
    // The hole stays a cavity: an outer wall and the cavity's, Euler
    // characteristic 2 each.
    EXPECT_EQ(report(dir)["remeshed_surface"]["components"], 2);
    EXPECT_EQ(report(dir)["remeshed_surface"]["euler_characteristic"], 4);
}

TEST(HostileInput, SingleIsolatedVoxel)
{
    RecordedOutcome outcome("one inside voxel in a 5^3 image of 0.5 mm voxels");
    const TempDir dir;
    expect_meshed(run_image(dir, {5, 5, 5}, 0.5, [](int i, int j, int k) { return i == 2 && j == 2 && k == 2; }), dir, outcome);
}

TEST(HostileInput, StrayVoxelBesideABall)
{
    RecordedOutcome outcome("a ball of radius 5 voxels and a separate single voxel (20 x 15 x 15 image, 0.5 mm voxels)");
    const TempDir dir;
    const auto a = ball({7, 7, 7}, 5);
    expect_meshed(run_image(dir, {20, 15, 15}, 0.5, [&](int i, int j, int k) { return a(i, j, k) || (i == 17 && j == 7 && k == 7); }),
                  dir, outcome);
    EXPECT_EQ(report(dir)["remeshed_surface"]["components"], 2);

    // keep = "largest" drops the stray voxel on purpose, and says so.
    const TempDir largest;
    expect_meshed(run_image(largest, {20, 15, 15}, 0.5,
                            [&](int i, int j, int k) { return a(i, j, k) || (i == 17 && j == 7 && k == 7); },
                            "keep = \"largest\"\n"),
                  largest, outcome, "keep = \"largest\"");
    EXPECT_EQ(report(largest)["remeshed_surface"]["components"], 1);
    EXPECT_EQ(report(largest)["input"]["dropped_regions"]["regions"], 1);
    EXPECT_EQ(report(largest)["input"]["dropped_regions"]["voxels"], 1);
    EXPECT_EQ(report(largest)["input"]["inside_voxels"].get<int64_t>() + 1,
              report(dir)["input"]["inside_voxels"].get<int64_t>());
}

TEST(HostileInput, LabelFillingTheWholeImage)
{
    RecordedOutcome outcome("every voxel of a 10^3 image of 0.5 mm voxels inside");
    const TempDir dir;
    expect_meshed(run_image(dir, {10, 10, 10}, 0.5, [](int, int, int) { return true; }), dir, outcome);
}

TEST(HostileInput, BallCutByEveryImageFace)
{
    RecordedOutcome outcome("a ball of radius 8 voxels in a 12^3 image (0.5 mm voxels), cut by all six faces");
    const TempDir dir;
    expect_meshed(run_image(dir, {12, 12, 12}, 0.5, ball({6, 6, 6}, 8)), dir, outcome);
    // Meshed closed at each face, and each face warned of with the area the
    // ball touches there: 6 voxels from its centre at the low sides, a disc
    // of radius sqrt(8^2 - 6^2) = 5.3 voxels (89 voxels of 0.25 mm^2), 5 at
    // the high sides (radius 6.2, 115 voxels).
    const nlohmann::json warnings = report(dir)["warnings"];
    ASSERT_EQ(warnings.size(), 6u) << warnings;
    for (const char* side : {"x-", "x+", "y-", "y+", "z-", "z+"}) {
        const bool low = side[1] == '-';
        const std::string expected = std::string("the segmentation touches the image's ") + side + " side over " +
                                     (low ? "22.25 mm^2 (89" : "28.75 mm^2 (115") +
                                     " voxels) and is meshed closed there; if the vessel runs on beyond the image, "
                                     "add an opening with border = \"" + side + "\"";
        EXPECT_NE(std::find(warnings.begin(), warnings.end(), expected), warnings.end()) << expected << "\n" << warnings;
    }
    // With border openings on z- and z+, only the other four are warned of.
    const TempDir opened;
    expect_meshed(run_image(opened, {12, 12, 12}, 0.5, ball({6, 6, 6}, 8),
                            "[[openings]]\nname = \"in\"\ntype = \"inlet\"\nborder = \"z-\"\n"
                            "[[openings]]\nname = \"out\"\ntype = \"outlet\"\nborder = \"z+\"\n"),
                  opened, outcome, "z- and z+ opened");
    int touching = 0;
    const nlohmann::json opened_warnings = report(opened)["warnings"];
    for (const auto& w : opened_warnings) {
        const std::string text = w.get<std::string>();
        touching += text.find("the segmentation touches") != std::string::npos;
        EXPECT_EQ(text.find("side z"), std::string::npos) << text;
    }
    EXPECT_EQ(touching, 4) << opened_warnings;
}

TEST(HostileInput, LabelFillingTheImageWithBorderOpenings)
{
    RecordedOutcome outcome("every voxel of a 10^3 image inside, border openings z- (inlet) and z+ (outlet)");
    const TempDir dir;
    expect_meshed(run_image(dir, {10, 10, 10}, 0.5, [](int, int, int) { return true; },
                            "[[openings]]\nname = \"in\"\ntype = \"inlet\"\nborder = \"z-\"\n"
                            "[[openings]]\nname = \"out\"\ntype = \"outlet\"\nborder = \"z+\"\n"),
                  dir, outcome);
}

TEST(HostileInput, OneByNByNSlabImage)
{
    RecordedOutcome outcome("a 1 x 12 x 12 image of 0.5 mm voxels, all inside");
    const auto inside = [](int, int, int) { return true; };
    // The paper's layers fit across the plate, one voxel thick: no flat tet.
    const TempDir delaunay;
    expect_meshed(run_image(delaunay, {1, 12, 12}, 0.5, inside, "[volume]\nlayers = \"delaunay\"\n"), delaunay,
                  outcome, "layers = \"delaunay\"");
    EXPECT_GT(report(delaunay)["volume"]["quality_after_sliver_removal"]["min_aspect_ratio"].get<double>(), 0.05);
    // The default prism layers' cells there miss the floors (their columns,
    // shortened to a tenth, still leave flat tets between the two walls'
    // stacks: aspect ratio 0.044): the run gives them up for the paper's
    // layers and says so.
    const TempDir prisms;
    expect_meshed(run_image(prisms, {1, 12, 12}, 0.5, inside), prisms, outcome, "default layers");
    const nlohmann::json r = report(prisms);
    EXPECT_EQ(r["volume"]["layers_built"], "delaunay");
    EXPECT_NE(r["warnings"].dump().find("the prism layers were given up"), std::string::npos) << r["warnings"];
    EXPECT_GT(r["volume"]["quality_after_sliver_removal"]["min_aspect_ratio"].get<double>(), 0.05);
}

TEST(HostileInput, VoxelsOfAMillionthOfAMillimetreAreRefused)
{
    RecordedOutcome outcome("a ball of radius 5 voxels in a 15^3 image of 1e-6 mm voxels");
    // OpenVDB cannot invert a transform this small; the importer says so.
    const TempDir dir;
    const CommandResult r = run_image(dir, {15, 15, 15}, 1e-6, ball({7, 7, 7}, 5));
    outcome.add(describe_unmeshed(r));
    expect_refused(r, dir.path, {"image.mha"});
    EXPECT_NE(r.err.find("spacing 1e-06"), std::string::npos) << r.err;
}

TEST(HostileInput, VoxelsOfAMetre)
{
    RecordedOutcome outcome("a ball of radius 5 voxels in a 15^3 image of 1e3 mm voxels, of 1024 mm and of 1 mm");
    const TempDir dir;
    expect_meshed(run_image(dir, {15, 15, 15}, 1e3, ball({7, 7, 7}, 5)), dir, outcome, "1e3 mm");
    // Scale invariance: with 1024 mm voxels (a power of two, so that every
    // product scales exactly; 1e3 rounds differently and may break a tie
    // elsewhere) the very mesh of 1 mm voxels, scaled.
    const TempDir large, unit;
    expect_meshed(run_image(large, {15, 15, 15}, 1024, ball({7, 7, 7}, 5)), large, outcome, "1024 mm");
    expect_meshed(run_image(unit, {15, 15, 15}, 1, ball({7, 7, 7}, 5)), unit, outcome, "1 mm");
    EXPECT_EQ(report(large)["volume"]["tets"], report(unit)["volume"]["tets"]);
    EXPECT_DOUBLE_EQ(report(large)["volume"]["volume_mm3"].get<double>(),
                     std::pow(1024.0, 3) * report(unit)["volume"]["volume_mm3"].get<double>());
}

TEST(HostileInput, LMinBeyondTheWholeSurfaceIsRefused)
{
    RecordedOutcome outcome("the tube phantom (6 mm across, 30 mm long) with its two openings and L_min = L_max = 1e6 mm; "
                            "and, as a control, L_min = L_max = 30 mm");
    const std::string openings = "[[openings]]\nname = \"inlet\"\ntype = \"inlet\"\npoint = [0, 0, -12]\nnormal = [0, 0, -1]\n"
                                 "[[openings]]\nname = \"outlet\"\ntype = \"outlet\"\npoint = [0, 0, 12]\nnormal = [0, 0, 1]\n";
    const TempDir dir, control;
    write_case(dir.path, "[input]\nphantom = \"tube\"\nvoxel_size = 0.5\n[sizing]\nL_min = 1e6\nL_max = 1e6\n" +
                             openings);
    const CommandResult r = run_case_limited(dir.path, kTimeLimit);
    outcome.add(describe_unmeshed(r), "1e6 mm");
    // It said "cap 'inlet' has no faces left", after remeshing had collapsed the surface.
    expect_refused(r, dir.path, {});
    EXPECT_NE(r.err.find("L_min = 1e+06 mm asks for surface edges of at least K/M L_min = 600000 mm, longer than the "
                         "whole surface is across"),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("below the narrowest vessel diameter"), std::string::npos) << r.err;
    // An L_min below the surface's size runs, and warns of the layers it misses.
    write_case(control.path, "[input]\nphantom = \"tube\"\nvoxel_size = 0.5\n[sizing]\nL_min = 30\nL_max = 30\n" +
                                 openings);
    const CommandResult c = run_case_limited(control.path, kTimeLimit);
    expect_meshed(c, control, outcome, "30 mm");
    EXPECT_NE(report(control)["warnings"].dump().find("layers"), std::string::npos) << report(control)["warnings"].dump();
}

TEST(HostileInput, HundredSeparateComponents)
{
    RecordedOutcome outcome("100 balls of radius 2 voxels in a 30 x 30 x 24 image of 0.5 mm voxels");
    const TempDir dir;
    std::vector<VoxelTest> balls;
    for (int a = 0; a < 5; ++a)
        for (int b = 0; b < 5; ++b)
            for (int c = 0; c < 4; ++c) balls.push_back(ball({3 + 6 * a, 3 + 6 * b, 3 + 6 * c}, 2));
    expect_meshed(run_image(dir, {30, 30, 24}, 0.5,
                            [&](int i, int j, int k) {
                                return std::any_of(balls.begin(), balls.end(), [&](const VoxelTest& f) { return f(i, j, k); });
                            }),
                  dir, outcome);
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
    RecordedOutcome outcome("a 10 mm cube STL whose top face has a triangle with two angles of 0.01 degrees, also scaled by 1e-6 and 1e3");
    for (const double scale : {1.0, 1e-6, 1e3}) {
        SCOPED_TRACE(scale);
        const TempDir dir;
        write_stl(dir.path / "cube.stl", cube_with_sliver(scale));
        write_case(dir.path, "[input]\nfile = \"cube.stl\"\n");
        std::ostringstream label;
        label << "scale " << scale;
        expect_meshed(run_case_limited(dir.path, kTimeLimit), dir, outcome, label.str());
        // STL stores single-precision coordinates: the cube is exact only to that.
        const double volume = 1000 * std::pow(scale, 3);
        EXPECT_NEAR(report(dir)["volume"]["volume_mm3"].get<double>(), volume, 1e-6 * volume);
    }
}

TEST(HostileInput, SharedAortaSurfaceWithSliverTriangles)
{
    RecordedOutcome outcome("../shared/data/vmtk_aorta_capped.stl, a capped aorta surface with sliver triangles");
    const std::filesystem::path aorta = std::filesystem::absolute("../shared/data/vmtk_aorta_capped.stl");
    if (!std::filesystem::exists(aorta)) {
        outcome.add("not run: " + aorta.string() + " is not there");
        GTEST_SKIP() << aorta << " is not there";
    }
    const TempDir dir;
    write_case(dir.path, "[input]\nfile = " + quote(aorta.string()) + "\n");
    expect_meshed(run_case_limited(dir.path, kTimeLimit), dir, outcome);
}

} // namespace
} // namespace scalemesh

namespace scalemesh {
namespace {

// A closed cube of side `side` from corner `lo`, counter-clockwise from outside.
std::vector<std::array<Vec3, 3>> cube(const Vec3& lo, double side)
{
    const double L = side;
    const Vec3 e = lo, f = lo + Vec3{L, 0, 0}, g = lo + Vec3{L, L, 0}, h = lo + Vec3{0, L, 0};
    const Vec3 a = lo + Vec3{0, 0, L}, b = lo + Vec3{L, 0, L}, c = lo + Vec3{L, L, L}, d = lo + Vec3{0, L, L};
    return {{a, b, c}, {a, c, d}, {e, g, f}, {e, h, g}, {e, f, b}, {e, b, a},
            {f, g, c}, {f, c, b}, {g, h, d}, {g, d, c}, {h, e, a}, {h, a, d}};
}

TEST(HostileInput, OverlappingCubesAreRefusedAsSelfIntersecting)
{
    RecordedOutcome outcome("two closed 10 mm cubes in one STL, the second shifted by (3, 3, 3) mm into the first; and, "
                            "as a control, shifted by (15, 0, 0) mm clear of it");
    const TempDir overlapping, apart;
    std::vector<std::array<Vec3, 3>> two = cube({0, 0, 0}, 10);
    for (const auto& t : cube({3, 3, 3}, 10)) two.push_back(t);
    write_stl(overlapping.path / "cubes.stl", two);
    write_case(overlapping.path, "[input]\nfile = \"cubes.stl\"\n");
    const CommandResult r = run_case_limited(overlapping.path, kTimeLimit);
    outcome.add(describe_unmeshed(r), "overlapping");
    expect_refused(r, overlapping.path, {"cubes.stl"});
    EXPECT_NE(r.err.find("cubes.stl intersects itself"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("pairs of triangles cross, the first near ("), std::string::npos) << r.err;

    two = cube({0, 0, 0}, 10);
    for (const auto& t : cube({15, 0, 0}, 10)) two.push_back(t);
    write_stl(apart.path / "cubes.stl", two);
    write_case(apart.path, "[input]\nfile = \"cubes.stl\"\n");
    expect_meshed(run_case_limited(apart.path, kTimeLimit), apart, outcome, "apart");
    EXPECT_EQ(report(apart)["remeshed_surface"]["components"], 2);
}

} // namespace
} // namespace scalemesh
