// Open-ended surfaces and labelled caps (openings/open_ends.h): the loops
// found, closed, measured and cut flat; broken surfaces refused with where.

#include "core/errors.h"
#include "openings/open_ends.h"
#include "openings/openings.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace scalemesh {
namespace {

// A tube along z from z = 0 (radius r0) to z = length (radius r1), open at
// both ends: `rings` rings of `segments` points, triangles wound outwards.
SurfaceMesh open_tube(int segments, int rings, double r0, double r1, double length)
{
    SurfaceMesh mesh;
    for (int j = 0; j < rings; ++j) {
        const double t = static_cast<double>(j) / (rings - 1);
        const double r = r0 + t * (r1 - r0);
        for (int i = 0; i < segments; ++i) {
            const double a = 2 * std::numbers::pi * (i + 0.5 * (j % 2)) / segments;
            mesh.points.push_back({r * std::cos(a), r * std::sin(a), t * length});
        }
    }
    const auto id = [&](int i, int j) { return j * segments + (i % segments); };
    for (int j = 0; j + 1 < rings; ++j)
        for (int i = 0; i < segments; ++i) {
            mesh.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
            mesh.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
        }
    return mesh;
}

// The open tube with both ends closed by flat fans, labelled: wall 1, the
// z = 0 cap 2, the z = length cap 3.
SurfaceMesh capped_tube(int segments, int rings, double r, double length, std::vector<int32_t>& labels)
{
    SurfaceMesh mesh = open_tube(segments, rings, r, r, length);
    labels.assign(mesh.triangles.size(), 1);
    const auto bottom = static_cast<int32_t>(mesh.points.size());
    mesh.points.push_back({0, 0, 0});
    const auto top = static_cast<int32_t>(mesh.points.size());
    mesh.points.push_back({0, 0, length});
    const int32_t last = (rings - 1) * segments;
    for (int i = 0; i < segments; ++i) {
        mesh.triangles.push_back({(i + 1) % segments, i, bottom});
        labels.push_back(2);
    }
    for (int i = 0; i < segments; ++i) {
        mesh.triangles.push_back({last + i, last + (i + 1) % segments, top});
        labels.push_back(3);
    }
    return mesh;
}

TEST(OpenEnds, AnOpenTubeHasTwoLoopsOfItsRingSize)
{
    const SurfaceMesh tube = open_tube(24, 10, 2, 2, 20);
    const auto loops = boundary_loops(tube, "tube");
    ASSERT_EQ(loops.size(), 2u);
    EXPECT_EQ(loops[0].size(), 24u);
    EXPECT_EQ(loops[1].size(), 24u);
}

TEST(OpenEnds, ClosingGivesAClosedSurfaceAndMeasuresEachEnd)
{
    const int n = 32;
    const ClosedEnds closed = close_open_ends(open_tube(n, 12, 2.0, 1.5, 20), "tube");
    EXPECT_TRUE(surface_facts(closed.surface).closed_manifold());
    EXPECT_GT(signed_volume(closed.surface), 0);
    EXPECT_FALSE(closed.flipped);
    ASSERT_EQ(closed.ends.size(), 2u);
    // Largest first: the z = 0 end, radius 2, normal -z; then z = 20, +z.
    const double polygon = 0.5 * n * std::sin(2 * std::numbers::pi / n);
    EXPECT_NEAR(closed.ends[0].area, polygon * 4.0, 1e-9);
    EXPECT_NEAR(closed.ends[1].area, polygon * 2.25, 1e-9);
    EXPECT_NEAR(closed.ends[0].normal.z, -1.0, 1e-12);
    EXPECT_NEAR(closed.ends[1].normal.z, 1.0, 1e-12);
    EXPECT_NEAR(closed.ends[0].centre.z, 0.0, 1e-12);
    EXPECT_NEAR(closed.ends[1].centre.z, 20.0, 1e-12);
    EXPECT_NEAR(closed.ends[0].radius, 2.0, 1e-12);
    EXPECT_LT(closed.ends[0].deviation, 1e-12);
    EXPECT_EQ(closed.ends[0].label, -1);
}

TEST(OpenEnds, ASurfaceWoundInwardsIsReversedAndItsEndsStillPointOut)
{
    SurfaceMesh tube = open_tube(16, 6, 2, 2, 10);
    for (Triangle& t : tube.triangles) std::swap(t[1], t[2]);
    const ClosedEnds closed = close_open_ends(tube, "tube");
    EXPECT_TRUE(closed.flipped);
    EXPECT_GT(signed_volume(closed.surface), 0);
    for (const OpenEnd& end : closed.ends) EXPECT_NEAR(std::abs(end.normal.z), 1.0, 1e-12);
    const OpenEnd& bottom = closed.ends[0].centre.z < 5 ? closed.ends[0] : closed.ends[1];
    EXPECT_LT(bottom.normal.z, 0);
}

TEST(OpenEnds, LoopsThatTouchAreRefusedWithHowManyAndWhere)
{
    // Two tubes side by side whose rim rings share one point.
    SurfaceMesh a = open_tube(12, 4, 1, 1, 5);
    SurfaceMesh b = open_tube(12, 4, 1, 1, 5);
    const auto offset = static_cast<int32_t>(a.points.size());
    for (Vec3& p : b.points) p.x += 2.0;
    // Point 6 of b's first ring is at (-1 + 2, 0, 0) = a's point 0.
    for (Triangle t : b.triangles) {
        for (int32_t& v : t) v = v == 6 ? 0 : v + offset;
        a.triangles.push_back(t);
    }
    a.points.insert(a.points.end(), b.points.begin(), b.points.end());
    try {
        boundary_loops(a, "pair.stl");
        FAIL() << "touching loops accepted";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("pair.stl is not a surface with clean open ends"), std::string::npos) << what;
        EXPECT_NE(what.find("1 vertices where open loops touch"), std::string::npos) << what;
        EXPECT_NE(what.find("first problem at (1, 0, 0)"), std::string::npos) << what;
        EXPECT_NE(what.find("Hint: an open-ended surface needs clean boundary loops"), std::string::npos) << what;
    }
}

TEST(OpenEnds, ANonManifoldEdgeIsRefused)
{
    SurfaceMesh tube = open_tube(12, 4, 1, 1, 5);
    const auto extra = static_cast<int32_t>(tube.points.size());
    tube.points.push_back({0, 0, 2});
    // A third triangle on the interior edge of the first two.
    tube.triangles.push_back({tube.triangles[0][0], tube.triangles[0][2], extra});
    try {
        boundary_loops(tube, "fin.stl");
        FAIL() << "non-manifold edge accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("1 non-manifold edges"), std::string::npos) << e.what();
    }
}

TEST(OpenEnds, AMissingTriangleIsAHoleNotAnEnd)
{
    SurfaceMesh tube = open_tube(16, 6, 2, 2, 10);
    tube.triangles.erase(tube.triangles.begin() + 40);
    try {
        close_open_ends(tube, "holed.stl");
        FAIL() << "a three-edge hole became an open end";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("holed.stl has 1 hole of fewer than 6 edges, too small to be open ends"),
                  std::string::npos)
            << e.what();
    }
}

TEST(OpenEnds, FlatLabelledCapsComeOutAndTheirLoopsKeepTheLabel)
{
    std::vector<int32_t> labels;
    const SurfaceMesh tube = capped_tube(20, 8, 2, 15, labels);
    ASSERT_TRUE(surface_facts(tube).closed_manifold());
    const LabelCaps caps = remove_label_caps(tube, labels);
    ASSERT_EQ(caps.parts.size(), 3u);
    EXPECT_FALSE(caps.parts[0].cap); // the wall, the largest
    EXPECT_TRUE(caps.parts[1].cap);
    EXPECT_TRUE(caps.parts[2].cap);
    EXPECT_EQ(surface_facts(caps.surface).boundary_edges, 40);
    ASSERT_EQ(caps.loop_label.size(), 2u);
    std::vector<int32_t> got = caps.loop_label;
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, (std::vector<int32_t>{2, 3}));

    // Loops and labels line up through close_open_ends.
    const ClosedEnds closed = close_open_ends(caps.surface, "tube", caps.loop_label);
    for (const OpenEnd& end : closed.ends) EXPECT_EQ(end.label, end.normal.z < 0 ? 2 : 3);
}

TEST(OpenEnds, ACurvedLabelStaysWall)
{
    std::vector<int32_t> labels;
    const SurfaceMesh tube = capped_tube(20, 8, 2, 15, labels);
    // Half of the wall (x > 0) gets its own label: not flat, so not a cap.
    for (size_t t = 0; t < tube.triangles.size(); ++t)
        if (labels[t] == 1 && tube.points[tube.triangles[t][0]].x > 0) labels[t] = 4;
    const LabelCaps caps = remove_label_caps(tube, labels);
    for (const LabelPart& part : caps.parts) EXPECT_EQ(part.cap, part.label == 2 || part.label == 3) << part.label;
}

// A cap read from a float32 file far from the origin (a model in cm, placed
// at 100 cm) is flat only to the coordinates' single-precision rounding:
// still a cap. A cap bent by more than that is not, and says by how much.
TEST(OpenEnds, ACapFlatToSinglePrecisionIsACapAndABentOneSaysByHowMuch)
{
    std::vector<int32_t> labels;
    SurfaceMesh tube = capped_tube(20, 8, 0.2, 1.5, labels);
    const double a = 0.5, b = 0.3; // tilted, so that rounding moves the cap points off its plane
    for (Vec3& p : tube.points) {
        const Vec3 q{p.x, std::cos(a) * p.y - std::sin(a) * p.z, std::sin(a) * p.y + std::cos(a) * p.z};
        p = Vec3{std::cos(b) * q.x + std::sin(b) * q.z, q.y, -std::sin(b) * q.x + std::cos(b) * q.z} +
            Vec3{100, 100, 100};
        for (int k = 0; k < 3; ++k) p[k] = static_cast<double>(static_cast<float>(p[k]));
    }
    LabelCaps caps = remove_label_caps(tube, labels);
    ASSERT_EQ(caps.parts.size(), 3u);
    for (const LabelPart& part : {caps.parts[1], caps.parts[2]}) {
        EXPECT_GT(part.flatness, 1e-6) << "the rounding alone bends the cap beyond the default tolerance";
        EXPECT_TRUE(part.cap) << part.label << ": " << why_not_a_cap(part);
        EXPECT_EQ(why_not_a_cap(part), "");
    }
    EXPECT_EQ(why_not_a_cap(caps.parts[0]), "it is the wall (the label of the largest area)");

    // One point of cap 3 pushed 1% of the radius off its plane.
    for (size_t t = 0; t < tube.triangles.size(); ++t)
        if (labels[t] == 3) {
            tube.points[tube.triangles[t][0]].z += 0.002;
            break;
        }
    caps = remove_label_caps(tube, labels);
    EXPECT_TRUE(caps.parts[1].cap);
    EXPECT_FALSE(caps.parts[2].cap);
    const std::string why = why_not_a_cap(caps.parts[2]);
    EXPECT_EQ(why.rfind("not flat: its points leave its plane by up to ", 0), 0u) << why;
    EXPECT_NE(why.find(" of sqrt(area), beyond "), std::string::npos) << why;
}

TEST(OpenEnds, EndOpeningsCutTheEndsFlatAndCapThem)
{
    const ClosedEnds closed = close_open_ends(open_tube(24, 16, 2.0, 2.0, 20), "tube");
    std::vector<OpeningSpec> specs;
    for (size_t i = 0; i < closed.ends.size(); ++i)
        specs.push_back(end_opening(closed.ends[i], "end_" + std::to_string(i), OpeningType::Outlet,
                                    0.25 * closed.ends[i].mean_edge));
    const CappedSurface capped = cut_and_cap(closed.surface, specs, ImageFrame{});
    EXPECT_TRUE(surface_facts(capped.surface).closed_manifold());
    ASSERT_EQ(capped.caps.size(), 2u);
    for (size_t t = 0; t < capped.surface.triangles.size(); ++t) {
        const int32_t patch = capped.surface.triangle_patch[t];
        if (patch == 0) continue;
        const Plane& plane = capped.caps[patch - 1].plane;
        for (int32_t p : capped.surface.triangles[t])
            EXPECT_LE(std::abs(plane.signed_distance(capped.surface.points[p])), 1e-9 * 2.0);
    }
    // Cut just inside the loops: a quarter of an edge each end.
    const double edge = closed.ends[0].mean_edge;
    for (const Cap& cap : capped.caps) {
        EXPECT_NEAR(std::abs(cap.centroid.z - (cap.plane.normal.z > 0 ? 20.0 : 0.0)), 0.25 * edge, 1e-9);
        EXPECT_GT(cap.area, 0.9 * std::numbers::pi * 4.0);
    }
}

} // namespace
} // namespace scalemesh
