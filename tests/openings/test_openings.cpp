// Inlets and outlets (paper section 3): cut and cap, the cap rules of the
// sizing stage, and caps rebuilt from the rim's layer points.

#include "core/adjacency.h"
#include "core/errors.h"
#include "core/surface_mesh.h"
#include "isosurface/marching_cubes.h"
#include "openings/openings.h"
#include "phantom/phantom.h"
#include "smoothing/volume_conserving_smoothing.h"

#include <gtest/gtest.h>

#include <openvdb/openvdb.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <numbers>

namespace scalemesh {
namespace {

constexpr double kPi = std::numbers::pi;

SurfaceMesh smoothed_phantom(const std::string& name, double h)
{
    const auto shape = make_shape(name, h);
    SurfaceMesh mesh = marching_cubes(*voxelize(*shape, {.voxel_size = h}));
    smooth_volume_conserving(mesh, {.sweeps = 10, .omega = 1.0, .max_displacement = 0.5 * h});
    return mesh;
}

OpeningSpec plane_opening(const std::string& name, OpeningType type, Vec3 point, Vec3 normal, double radius = 0)
{
    OpeningSpec spec;
    spec.name = name;
    spec.type = type;
    spec.plane = {point, normalized(normal)};
    spec.radius = radius;
    return spec;
}

double extent(const SurfaceMesh& mesh)
{
    Vec3 lo, hi;
    bounding_box(mesh, lo, hi);
    return distance(lo, hi);
}

// The tube phantom (radius 3 mm, z in [-15, 15]) opened at z = -12 and z = 12.
CappedSurface opened_tube(double h = 0.5)
{
    const SurfaceMesh tube = smoothed_phantom("tube", h);
    return cut_and_cap(tube,
                       {plane_opening("inlet", OpeningType::Inlet, {0, 0, -12}, {0, 0, -1}),
                        plane_opening("outlet", OpeningType::Outlet, {0, 0, 12}, {0, 0, 1})},
                       {});
}

TEST(CutAndCap, TubeGetsTwoFlatCapsAndStaysClosed)
{
    const CappedSurface capped = opened_tube();
    ASSERT_EQ(capped.caps.size(), 2u);
    const SurfaceFacts facts = surface_facts(capped.surface);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_EQ(facts.components, 1);
    EXPECT_EQ(facts.euler_characteristic, 2);
    ASSERT_EQ(capped.surface.triangle_patch.size(), capped.surface.triangles.size());
    const double scale = extent(capped.surface);
    std::vector<double> area(3, 0.0);
    double worst = 0;
    for (size_t f = 0; f < capped.surface.triangles.size(); ++f) {
        const int32_t patch = capped.surface.triangle_patch[f];
        if (patch == 0) continue;
        const Cap& cap = capped.caps[patch - 1];
        const Triangle& t = capped.surface.triangles[f];
        for (int32_t v : t) worst = std::max(worst, std::abs(cap.plane.signed_distance(capped.surface.points[v])));
        const Vec3& a = capped.surface.points[t[0]];
        // Counter-clockwise seen from outside: the area along the outward normal is positive.
        area[patch] += 0.5 * dot(cross(capped.surface.points[t[1]] - a, capped.surface.points[t[2]] - a), cap.plane.normal);
    }
    EXPECT_LT(worst, 1e-9 * scale);
    for (int p = 1; p <= 2; ++p) {
        EXPECT_NEAR(area[p], capped.caps[p - 1].area, 1e-9 * area[p]);
        // The smoothed voxel tube's cross-section is a circle of radius 3 mm to within a voxel's rounding.
        EXPECT_NEAR(area[p], kPi * 9, 0.05 * kPi * 9);
    }
    EXPECT_EQ(capped.caps[0].name, "inlet");
    EXPECT_EQ(capped.caps[1].name, "outlet");
    // The kept part is z in [-12, 12]: the volume of a 24 mm long, 3 mm radius cylinder.
    EXPECT_NEAR(facts.signed_volume, kPi * 9 * 24, 0.05 * kPi * 9 * 24);
    Vec3 lo, hi;
    bounding_box(capped.surface, lo, hi);
    EXPECT_NEAR(lo.z, -12, 1e-9 * scale);
    EXPECT_NEAR(hi.z, 12, 1e-9 * scale);
}

TEST(CutAndCap, BorderOpeningCutsInsideTheOutermostPoint)
{
    const SurfaceMesh tube = smoothed_phantom("tube", 0.5);
    Vec3 lo, hi;
    bounding_box(tube, lo, hi);
    OpeningSpec spec;
    spec.name = "inlet";
    spec.type = OpeningType::Inlet;
    spec.border = true;
    spec.side = "z-";
    spec.inset = 1.0;
    const CappedSurface capped = cut_and_cap(tube, {spec}, {});
    ASSERT_EQ(capped.caps.size(), 1u);
    EXPECT_NEAR(capped.caps[0].plane.point.z, lo.z + 1.0, 1e-6);
    EXPECT_NEAR(capped.caps[0].plane.normal.z, -1.0, 1e-12);
    EXPECT_TRUE(surface_facts(capped.surface).closed_manifold());
}

TEST(CutAndCap, BadOpeningsAreRefused)
{
    const SurfaceMesh tube = smoothed_phantom("tube", 0.5);
    // A plane that misses the lumen.
    EXPECT_THROW(cut_and_cap(tube, {plane_opening("inlet", OpeningType::Inlet, {0, 0, -40}, {0, 0, -1})}, {}),
                 InputError);
    // Two openings with one name.
    EXPECT_THROW(cut_and_cap(tube,
                             {plane_opening("a", OpeningType::Inlet, {0, 0, -12}, {0, 0, -1}),
                              plane_opening("a", OpeningType::Outlet, {0, 0, 12}, {0, 0, 1})},
                             {}),
                 InputError);
    // A plane crossing the same vessel twice: the torus (R 10, r 4 in z = 0)
    // cut by x = 0 meets the lumen at y = +-10.
    const SurfaceMesh torus = smoothed_phantom("torus", 0.5);
    try {
        cut_and_cap(torus, {plane_opening("outlet", OpeningType::Outlet, {0, 0, 0}, {1, 0, 0})}, {});
        FAIL() << "a plane crossing the lumen twice was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("2 places"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("radius"), std::string::npos) << e.what();
    }
    // A radius picks one crossing, but what lies beyond it reaches back
    // across the plane at the other.
    try {
        cut_and_cap(torus, {plane_opening("outlet", OpeningType::Outlet, {0, 10, 0}, {1, 0, 0}, 5.0)}, {});
        FAIL() << "a cut whose far part reaches back across the plane was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("reaches back"), std::string::npos) << e.what();
    }
    // A second plane cutting the first one's cap.
    EXPECT_THROW(cut_and_cap(tube,
                             {plane_opening("a", OpeningType::Inlet, {0, 0, -12}, {0, 0, -1}),
                              plane_opening("b", OpeningType::Outlet, {0, 0, -12}, {0, 1, -1})},
                             {}),
                 InputError);
}

TEST(CutAndCap, RadiusPicksOneBranchOfTheBifurcation)
{
    // The daughters end at (+-7.5, 0, 12.99) along 30 degrees from z; a plane
    // across the right daughter near its end, normal along it.
    const SurfaceMesh bif = smoothed_phantom("bifurcation", 0.25);
    const Vec3 axis = normalized(Vec3{std::sin(kPi / 6), 0, std::cos(kPi / 6)});
    const Vec3 point = 12.0 * axis;
    const CappedSurface capped =
        cut_and_cap(bif, {plane_opening("right", OpeningType::Outlet, point, axis, 3.0)}, {});
    ASSERT_EQ(capped.caps.size(), 1u);
    EXPECT_NEAR(capped.caps[0].area, kPi * 1.5 * 1.5, 0.1 * kPi * 1.5 * 1.5);
    EXPECT_LT(distance(capped.caps[0].centroid, point), 0.2);
    EXPECT_TRUE(surface_facts(capped.surface).closed_manifold());
}

TEST(CutAndCap, FlowExtensionAddsAStraightTubeOfTheCapsSection)
{
    const SurfaceMesh tube = smoothed_phantom("tube", 0.5);
    const CappedSurface plain =
        cut_and_cap(tube, {plane_opening("outlet", OpeningType::Outlet, {0, 0, 12}, {0, 0, 1})}, {});
    OpeningSpec spec = plane_opening("outlet", OpeningType::Outlet, {0, 0, 12}, {0, 0, 1});
    spec.extension = 2.0;
    const CappedSurface extended = cut_and_cap(tube, {spec}, {});
    ASSERT_EQ(extended.caps.size(), 1u);
    const Cap& cap = extended.caps[0];
    const double length = 2.0 * 2 * std::sqrt(cap.area / kPi);
    const SurfaceFacts facts = surface_facts(extended.surface);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_EQ(facts.euler_characteristic, 2);
    // A right prism of the cap polygon: its area times its length, exactly.
    EXPECT_NEAR(facts.signed_volume - signed_volume(plain.surface), cap.area * length, 1e-9 * facts.signed_volume);
    EXPECT_NEAR(cap.plane.point.z, 12 + length, 1e-9);
    Vec3 lo, hi;
    bounding_box(extended.surface, lo, hi);
    EXPECT_NEAR(hi.z, 12 + length, 1e-9);
    for (size_t f = 0; f < extended.surface.triangles.size(); ++f)
        if (extended.surface.triangle_patch[f] == cap.patch) {
            for (int32_t v : extended.surface.triangles[f])
                EXPECT_NEAR(extended.surface.points[v].z, 12 + length, 1e-9);
        }
}

// Item 5: the order of the openings does not matter, and planes may meet
// outside their crossings. On the bifurcation, "left" cuts the left
// daughter square to its axis 12 mm from the branch point; "right" is the
// horizontal plane z = 11 with a radius picking the right daughter. The
// horizontal plane also crosses the left daughter, through the left cap:
// their infinite planes meet inside the left daughter's lumen, along the
// line x = -4.94, z = 11 (1.2 mm from its axis, radius 1.5 mm).
TEST(CutAndCap, OrderOfOpeningsDoesNotMatterWhenCrossingsAreApart)
{
    const SurfaceMesh bif = smoothed_phantom("bifurcation", 0.25);
    const Vec3 left_axis = normalized(Vec3{-std::sin(kPi / 6), 0, std::cos(kPi / 6)});
    const OpeningSpec inlet = plane_opening("inlet", OpeningType::Inlet, {0, 0, -12}, {0, 0, -1});
    const OpeningSpec left = plane_opening("left", OpeningType::Outlet, 12.0 * left_axis, left_axis, 3.0);
    const OpeningSpec right =
        plane_opening("right", OpeningType::Outlet, {11 * std::tan(kPi / 6), 0, 11}, {0, 0, 1}, 3.0);
    // The line where the two planes meet passes through the left daughter's lumen.
    const Vec3 meet{-6 + std::cos(kPi / 6) * (11 - 12 * std::cos(kPi / 6)) / std::sin(kPi / 6), 0, 11};
    EXPECT_NEAR(left.plane.signed_distance(meet), 0, 1e-9);
    EXPECT_LT(norm(meet - dot(meet, left_axis) * left_axis), 1.5);
    EXPECT_LT(dot(meet, left_axis), 12.99);

    const std::vector<std::vector<OpeningSpec>> orders = {
        {inlet, left, right}, {right, left, inlet}, {left, inlet, right}};
    std::vector<CappedSurface> results;
    for (const auto& order : orders) results.push_back(cut_and_cap(bif, order, {}));
    const auto by_name = [](const CappedSurface& c) {
        std::map<std::string, Cap> caps;
        for (const Cap& cap : c.caps) caps[cap.name] = cap;
        return caps;
    };
    const std::map<std::string, Cap> first = by_name(results[0]);
    ASSERT_EQ(first.size(), 3u);
    const SurfaceFacts facts = surface_facts(results[0].surface);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_EQ(facts.components, 1);
    EXPECT_EQ(facts.euler_characteristic, 2);
    // Patches follow the order given.
    for (size_t o = 0; o < orders.size(); ++o)
        for (size_t i = 0; i < orders[o].size(); ++i) {
            EXPECT_EQ(results[o].caps[i].name, orders[o][i].name);
            EXPECT_EQ(results[o].caps[i].patch, static_cast<int32_t>(i) + 1);
        }
    for (size_t o = 1; o < results.size(); ++o) {
        const std::map<std::string, Cap> other = by_name(results[o]);
        ASSERT_EQ(other.size(), first.size());
        for (const auto& [name, cap] : first) {
            const Cap& c = other.at(name);
            EXPECT_NEAR(c.area, cap.area, 1e-9 * cap.area) << name;
            EXPECT_LT(distance(c.centroid, cap.centroid), 1e-9 * norm(cap.centroid)) << name;
        }
        const SurfaceFacts f = surface_facts(results[o].surface);
        EXPECT_TRUE(f.closed_manifold());
        EXPECT_EQ(f.vertices, facts.vertices);
        EXPECT_EQ(f.triangles, facts.triangles);
        EXPECT_EQ(f.components, facts.components);
        EXPECT_EQ(f.euler_characteristic, facts.euler_characteristic);
        EXPECT_NEAR(f.signed_volume, facts.signed_volume, 1e-9 * facts.signed_volume);
        EXPECT_NEAR(f.area, facts.area, 1e-9 * facts.area);
    }
    // The caps are the daughters' cross-sections: a circle of radius 1.5 mm
    // for the square cut, an ellipse 1.5 by 1.5 / cos 30 for the horizontal one.
    EXPECT_NEAR(first.at("left").area, kPi * 2.25, 0.1 * kPi * 2.25);
    EXPECT_NEAR(first.at("right").area, kPi * 2.25 / std::cos(kPi / 6), 0.1 * kPi * 2.25 / std::cos(kPi / 6));
    EXPECT_LT(distance(first.at("right").centroid, right.plane.point), 0.2);
}

TEST(CutAndCap, OverlappingCrossingsAreRefusedNamingBoth)
{
    // Two planes through the same crossing of the tube: their caps would cross.
    const SurfaceMesh tube = smoothed_phantom("tube", 0.5);
    const OpeningSpec a = plane_opening("first", OpeningType::Inlet, {0, 0, -12}, {0, 0, -1});
    const OpeningSpec b = plane_opening("second", OpeningType::Outlet, {0, 0, -12}, {0, 1, -1});
    for (const auto& order : {std::vector<OpeningSpec>{a, b}, std::vector<OpeningSpec>{b, a}}) {
        try {
            cut_and_cap(tube, order, {});
            FAIL() << "two openings whose crossings meet were accepted";
        } catch (const InputError& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find("'first'"), std::string::npos) << what;
            EXPECT_NE(what.find("'second'"), std::string::npos) << what;
            EXPECT_NE(what.find("meet"), std::string::npos) << what;
        }
    }
    // One opening inside the part another removes: an outlet at z = 8 and a
    // second one further out at z = 12 in the same vessel.
    const OpeningSpec near = plane_opening("near", OpeningType::Outlet, {0, 0, 8}, {0, 0, 1});
    const OpeningSpec far = plane_opening("far", OpeningType::Outlet, {0, 0, 12}, {0, 0, 1});
    for (const auto& order : {std::vector<OpeningSpec>{near, far}, std::vector<OpeningSpec>{far, near}}) {
        try {
            cut_and_cap(tube, order, {});
            FAIL() << "an opening inside the part another removes was accepted";
        } catch (const InputError& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find("opening 'far' lies in the part of the lumen that opening 'near' removes"),
                      std::string::npos)
                << what;
        }
    }
}

// Item 6: a mask that tapers over its last voxels before the image face.
// Index space 0 .. size - 1 per axis, voxel width h = 0.5 mm, centres at
// index * h. A bar along x (radius 5 voxels, y = 8, z = 8) runs from the x-
// face to x = 41 and three tubes (radius 5 voxels) rise from it at x = 8,
// 22 and 36. The first two reach the z+ face, narrowing over their last 3
// voxels (radius x 0.8, 0.6, 0.45); the third stops 4 voxels short.
constexpr double kComb_h = 0.5;
constexpr int kCombSize[3] = {48, 17, 40};
constexpr double kCombR = 5;       // voxels
constexpr int kShortTop = 40 - 1 - 4; // last layer of the third tube

openvdb::FloatGrid::Ptr comb_grid(bool taper)
{
    openvdb::initialize();
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(kComb_h));
    grid->setName("label");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    grid->insertMeta("image_size", openvdb::Vec3IMetadata(openvdb::Vec3i(kCombSize[0], kCombSize[1], kCombSize[2])));
    auto access = grid->getAccessor();
    const double yc = 8, zb = 8;
    const double xs[3] = {8, 22, 36};
    for (int i = 0; i < kCombSize[0]; ++i)
        for (int j = 0; j < kCombSize[1]; ++j)
            for (int k = 0; k < kCombSize[2]; ++k) {
                bool inside = i <= 41 && std::hypot(j - yc, k - zb) < kCombR;
                for (int n = 0; n < 3; ++n) {
                    const int top = n == 2 ? kShortTop : kCombSize[2] - 1;
                    const int from_face = kCombSize[2] - 1 - k;
                    const double scale = !taper || n == 2 || from_face > 2 ? 1.0 : (from_face == 2 ? 0.8 : from_face == 1 ? 0.6 : 0.45);
                    inside = inside || (k >= zb && k <= top && std::hypot(i - xs[n], j - yc) < kCombR * scale);
                }
                if (inside) access.setValue(openvdb::Coord(i, j, k), 1.0f);
            }
    return grid;
}

// The area of the mask's cross-section of one tube: its voxels in a layer, times h^2 (17.25 mm^2).
double comb_section()
{
    int count = 0;
    for (int i = -6; i <= 6; ++i)
        for (int j = -6; j <= 6; ++j) count += std::hypot(i, j) < kCombR;
    return count * kComb_h * kComb_h;
}

SurfaceMesh comb_surface(bool taper)
{
    SurfaceMesh mesh = marching_cubes(*comb_grid(taper));
    smooth_volume_conserving(mesh, {.sweeps = 10, .omega = 1.0, .max_displacement = 0.5 * kComb_h});
    return mesh;
}

ImageFrame comb_frame()
{
    ImageFrame frame;
    for (int k = 0; k < 3; ++k) {
        frame.axis[k] = Vec3{0, 0, 0};
        frame.axis[k][k] = kComb_h;
        frame.size[k] = kCombSize[k];
    }
    return frame;
}

OpeningSpec border_opening(const std::string& name, OpeningType type, const std::string& side)
{
    OpeningSpec spec;
    spec.name = name;
    spec.type = type;
    spec.border = true;
    spec.side = side;
    return spec;
}

TEST(BorderOpenings, TaperingPiecesEachGetAFullCapAndAShortPieceIsReported)
{
    const SurfaceMesh comb = comb_surface(true);
    const double full = comb_section();
    const CappedSurface capped = cut_and_cap(
        comb, {border_opening("inlet", OpeningType::Inlet, "x-"), border_opening("outlet", OpeningType::Outlet, "z+")},
        comb_frame());
    const SurfaceFacts facts = surface_facts(capped.surface);
    EXPECT_TRUE(facts.closed_manifold());
    EXPECT_EQ(facts.components, 1);
    ASSERT_EQ(capped.caps.size(), 3u);
    EXPECT_EQ(capped.caps[0].name, "inlet");
    EXPECT_EQ(capped.caps[1].name, "outlet_1");
    EXPECT_EQ(capped.caps[2].name, "outlet_2");
    for (const Cap& cap : capped.caps) EXPECT_NEAR(cap.area, full, 0.06 * full) << cap.name;
    // One outlet cap on each of the two tubes that reach the face, none on the third.
    std::vector<double> xs = {capped.caps[1].centroid.x, capped.caps[2].centroid.x};
    std::sort(xs.begin(), xs.end());
    EXPECT_NEAR(xs[0], 8 * kComb_h, 0.1);
    EXPECT_NEAR(xs[1], 22 * kComb_h, 0.1);

    ASSERT_EQ(capped.borders.size(), 2u);
    const BorderCut& outlet = capped.borders[1];
    EXPECT_EQ(outlet.opening, "outlet");
    EXPECT_TRUE(outlet.automatic && outlet.stable && outlet.face_known);
    // Past the 3 tapering voxels, and not far past them.
    EXPECT_GE(outlet.inset, 3 * kComb_h);
    EXPECT_LE(outlet.inset, 5 * kComb_h);
    ASSERT_EQ(outlet.short_pieces.size(), 1u);
    // Its tip: the top of the last layer, (kShortTop + 1/2) h, moved by smoothing by at most half a voxel;
    // the face is at (40 - 1/2) h.
    EXPECT_NEAR(outlet.short_pieces[0].distance, 4 * kComb_h, 0.5 * kComb_h);
    EXPECT_NEAR(outlet.short_pieces[0].tip.x, 36 * kComb_h, 5 * kComb_h);
    EXPECT_TRUE(capped.borders[0].short_pieces.empty());
    ASSERT_EQ(capped.warnings.size(), 1u);
    EXPECT_NE(capped.warnings[0].find("opening 'outlet'"), std::string::npos) << capped.warnings[0];
    EXPECT_NE(capped.warnings[0].find("short of the image face"), std::string::npos) << capped.warnings[0];
    // The third tube stays, a dead end: the capped lumen still rises to its tip.
    Vec3 lo, hi;
    bounding_box(capped.surface, lo, hi);
    EXPECT_GT(hi.z, (kShortTop + 0.5) * kComb_h - 0.5 * kComb_h);

    // The old default, 2 voxels inside the outermost point, cuts inside the
    // taper: the caps there are much smaller than the lumen.
    OpeningSpec fixed = border_opening("outlet", OpeningType::Outlet, "z+");
    fixed.inset = 2 * kComb_h;
    const CappedSurface old = cut_and_cap(comb, {fixed}, comb_frame());
    ASSERT_EQ(old.caps.size(), 2u);
    for (const Cap& cap : old.caps) EXPECT_LT(cap.area, 0.75 * full) << cap.name;
    EXPECT_FALSE(old.borders[0].automatic);
    EXPECT_NEAR(old.borders[0].inset, 2 * kComb_h, 1e-12);
}

// The smoothed marching-cubes surface of a label image of kComb_h voxels
// whose inside voxels `inside` picks, and the image's frame.
struct ImageSurface {
    SurfaceMesh surface;
    ImageFrame frame;
};

ImageSurface image_surface(const std::array<int, 3>& size, const std::function<bool(int, int, int)>& inside)
{
    openvdb::initialize();
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(kComb_h));
    grid->setName("label");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    auto access = grid->getAccessor();
    for (int i = 0; i < size[0]; ++i)
        for (int j = 0; j < size[1]; ++j)
            for (int k = 0; k < size[2]; ++k)
                if (inside(i, j, k)) access.setValue(openvdb::Coord(i, j, k), 1.0f);
    ImageSurface out{marching_cubes(*grid), {}};
    smooth_volume_conserving(out.surface, {.sweeps = 10, .omega = 1.0, .max_displacement = 0.5 * kComb_h});
    for (int k = 0; k < 3; ++k) {
        out.frame.axis[k] = Vec3{0, 0, 0};
        out.frame.axis[k][k] = kComb_h;
        out.frame.size[k] = size[k];
    }
    return out;
}

// A cone whose cross-section shrinks towards the image face all the way:
// the automatic inset never settles, and the warning says where it cut.
TEST(BorderOpenings, AConeShrinkingToTheFaceIsCutAtTheDeepestPlaneSearchedAndSaysSo)
{
    const ImageSurface cone = image_surface({26, 26, 30}, [](int i, int j, int k) {
        return k >= 15 && std::hypot(i - 13, j - 13) < 2 + 0.45 * (29 - k);
    });
    const CappedSurface capped =
        cut_and_cap(cone.surface, {border_opening("outlet", OpeningType::Outlet, "z+")}, cone.frame);
    ASSERT_EQ(capped.borders.size(), 1u);
    const BorderCut& outlet = capped.borders[0];
    EXPECT_TRUE(outlet.automatic);
    EXPECT_FALSE(outlet.stable);
    EXPECT_FALSE(outlet.joined);
    EXPECT_NEAR(outlet.inset, BorderRule::search_depth * kComb_h, 1e-9);
    ASSERT_EQ(capped.warnings.size(), 1u);
    // It said "over 10 voxels (or two of its pieces join before)" whatever the search met.
    EXPECT_NE(capped.warnings[0].find("opening 'outlet' (border z+): the cross-section kept shrinking towards the image "
                                      "face over the 10 voxels searched; cut at the deepest of them, 5 mm (10 voxels) "
                                      "inside. Give inset"),
              std::string::npos)
        << capped.warnings[0];
}

// Two cones that reach the face, each shrinking towards it, and join about
// 7 voxels inside it: the search stops at the last plane before they join,
// and the warning says so.
TEST(BorderOpenings, TwoConesJoiningNearTheFaceAreCutBeforeTheJoinAndSaySo)
{
    const ImageSurface joined = image_surface({26, 26, 30}, [](int i, int j, int k) {
        const double r = 2 + 0.45 * (29 - k); // they widen into each other, 7 voxels in
        return k >= 18 && (std::hypot(i - 8, j - 13) < r || std::hypot(i - 18, j - 13) < r);
    });
    const CappedSurface capped =
        cut_and_cap(joined.surface, {border_opening("outlet", OpeningType::Outlet, "z+")}, joined.frame);
    ASSERT_EQ(capped.borders.size(), 1u);
    const BorderCut& outlet = capped.borders[0];
    EXPECT_TRUE(outlet.automatic);
    EXPECT_TRUE(outlet.joined);
    EXPECT_LT(outlet.inset, BorderRule::search_depth * kComb_h);
    EXPECT_EQ(capped.caps.size(), 2u);
    std::string all;
    for (const std::string& w : capped.warnings) all += w + "\n";
    EXPECT_NE(all.find("opening 'outlet' (border z+): the cross-section kept shrinking towards the image face until two "
                       "of its pieces join, "),
              std::string::npos)
        << all;
    EXPECT_NE(all.find(" voxels inside; cut at the last plane before that, "), std::string::npos) << all;
}

TEST(BorderOpenings, WithoutTaperTheAutomaticInsetStaysNearTheFace)
{
    const SurfaceMesh comb = comb_surface(false);
    const double full = comb_section();
    const CappedSurface capped =
        cut_and_cap(comb, {border_opening("outlet", OpeningType::Outlet, "z+")}, comb_frame());
    ASSERT_EQ(capped.caps.size(), 2u);
    for (const Cap& cap : capped.caps) EXPECT_NEAR(cap.area, full, 0.06 * full) << cap.name;
    // The first plane the rule takes: the smoothed surface's rounding of
    // the face lies within it.
    EXPECT_NEAR(capped.borders[0].inset, BorderRule::first_plane * kComb_h, 1e-12);
    EXPECT_EQ(capped.borders[0].short_pieces.size(), 1u);
}

TEST(BorderOpenings, NoLumenAtTheSideIsRefused)
{
    const SurfaceMesh comb = comb_surface(true);
    // The y+ face is at (17 - 1/2) h; the lumen reaches y = (8 + 5) h: 3.5 voxels short.
    try {
        cut_and_cap(comb, {border_opening("outlet", OpeningType::Outlet, "y+")}, comb_frame());
        FAIL() << "a border opening on a side the lumen does not reach was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("no part of the lumen reaches the y+ side"), std::string::npos)
            << e.what();
    }
}

SizingParams tube_sizing()
{
    SizingParams p;
    p.L_min = 0.25;
    p.L_max = 20;
    return p;
}

TEST(CapSizing, RimNormalsLieInTheCapPlaneAndDSpansTheOpening)
{
    const CappedSurface capped = opened_tube();
    const FeatureSize sizing = cap_feature_size(capped.surface, capped.caps, tube_sizing());
    const CapNodes nodes = classify_cap_nodes(capped.surface, capped.caps);
    int64_t rims = 0, near = 0;
    for (size_t i = 0; i < capped.surface.points.size(); ++i) {
        if (nodes.rim[i] || nodes.next_to_rim[i]) {
            const int32_t c = nodes.rim[i] ? nodes.cap_of[i] : (capped.surface.points[i].z < 0 ? 0 : 1);
            EXPECT_LT(std::abs(dot(sizing.normals[i], capped.caps[c].plane.normal)), 1e-9) << "node " << i;
            EXPECT_NEAR(norm(sizing.normals[i]), 1.0, 1e-12);
        }
        if (nodes.rim[i]) {
            ++rims;
            // Across the opening: the diameter, 6 mm, to a voxel's rounding.
            EXPECT_NEAR(sizing.D[i], 6.0, 0.5) << "rim node " << i;
            EXPECT_EQ(sizing.inward_ok[i], 0);
        }
        near += nodes.next_to_rim[i];
        if (nodes.interior[i]) {
            EXPECT_EQ(sizing.inward_ok[i], 0);
        }
    }
    EXPECT_GT(rims, 40);
    EXPECT_GT(near, 40);
}

// A closed cylinder of radius R along z, z in [-L/2, L/2], `around` nodes per
// ring, its ends flat fans (patches 1 at z = -L/2 and 2 at z = L/2).
CappedSurface capped_cylinder(double R, double L, int around, int rings)
{
    CappedSurface c;
    SurfaceMesh& m = c.surface;
    for (int k = 0; k < rings; ++k)
        for (int j = 0; j < around; ++j) {
            const double a = 2 * kPi * j / around;
            m.points.push_back({R * std::cos(a), R * std::sin(a), -L / 2 + L * k / (rings - 1)});
        }
    const auto id = [&](int k, int j) { return static_cast<int32_t>(k * around + (j % around)); };
    for (int k = 0; k + 1 < rings; ++k)
        for (int j = 0; j < around; ++j) {
            m.triangles.push_back({id(k, j), id(k, j + 1), id(k + 1, j + 1)});
            m.triangles.push_back({id(k, j), id(k + 1, j + 1), id(k + 1, j)});
            m.triangle_patch.insert(m.triangle_patch.end(), {0, 0});
        }
    const auto bottom = static_cast<int32_t>(m.points.size());
    m.points.push_back({0, 0, -L / 2});
    const auto top = static_cast<int32_t>(m.points.size());
    m.points.push_back({0, 0, L / 2});
    for (int j = 0; j < around; ++j) {
        m.triangles.push_back({bottom, id(0, j + 1), id(0, j)});
        m.triangle_patch.push_back(1);
        m.triangles.push_back({top, id(rings - 1, j), id(rings - 1, j + 1)});
        m.triangle_patch.push_back(2);
    }
    Cap inlet, outlet;
    inlet.name = "inlet";
    inlet.type = OpeningType::Inlet;
    inlet.patch = 1;
    inlet.plane = {{0, 0, -L / 2}, {0, 0, -1}};
    outlet.name = "outlet";
    outlet.patch = 2;
    outlet.plane = {{0, 0, L / 2}, {0, 0, 1}};
    c.caps = {inlet, outlet};
    return c;
}

TEST(RingCaps, CylinderCapShowsThreeRingsForSevenLayers)
{
    constexpr double R = 3.0;
    constexpr int around = 24;
    const CappedSurface capped = capped_cylinder(R, 20, around, 26);
    ASSERT_TRUE(surface_facts(capped.surface).closed_manifold());
    FeatureSize sizing = cap_feature_size(capped.surface, capped.caps, tube_sizing());
    const SurfaceMesh ringed = ring_caps(capped.surface, capped.caps, sizing, {.M = 7, .growth = 1.0, .L_max = 20});
    const SurfaceFacts facts = surface_facts(ringed);
    ASSERT_TRUE(facts.closed_manifold());
    EXPECT_EQ(facts.euler_characteristic, 2);
    EXPECT_NEAR(facts.signed_volume, signed_volume(capped.surface), 1e-9 * facts.signed_volume);
    ASSERT_EQ(sizing.d.size(), ringed.points.size());
    const CapNodes nodes = classify_cap_nodes(ringed, capped.caps);
    for (const Cap& cap : capped.caps) {
        std::vector<int> ring_count(4, 0);
        int rim = 0;
        for (size_t i = 0; i < ringed.points.size(); ++i) {
            if (nodes.cap_of[i] != cap.patch - 1) continue;
            rim += nodes.rim[i];
            if (!nodes.interior[i]) continue;
            const Vec3& x = ringed.points[i];
            EXPECT_LT(std::abs(cap.plane.signed_distance(x)), 1e-12 * 20);
            EXPECT_EQ(sizing.inward_ok[i], 0);
            // Ring m lies m d/M inside the rim (d = D = 6 mm, the diameter).
            const double m = (R - std::hypot(x.x, x.y)) / (sizing.d[i] / 7);
            const int ring = static_cast<int>(std::lround(m));
            ASSERT_GE(ring, 1);
            ASSERT_LE(ring, 3) << "a cap point beyond the third ring at " << m << " d/M";
            EXPECT_NEAR(m, ring, 0.15 * ring) << "cap point off its ring";
            ++ring_count[ring];
        }
        EXPECT_EQ(rim, around);
        EXPECT_EQ(ring_count[1], around);
        // The inner rings are thinned where neighbouring points crowd.
        EXPECT_GE(ring_count[2], around / 2);
        EXPECT_GE(ring_count[3], 3);
    }
    for (size_t i = 0; i < ringed.points.size(); ++i) {
        if (nodes.rim[i]) {
            EXPECT_NEAR(sizing.D[i], 2 * R, 1e-9);
            EXPECT_EQ(sizing.inward_ok[i], 0);
        }
    }
}

TEST(RingCaps, PrismColumnsStopWhereTheLastRingIsAsWideAsItsTopLayerIsThick)
{
    // Seven layers in a 6 mm tube: three layers from each side would draw
    // the rim columns in to 0.4 mm of the axis, where the last ring's
    // segments are an eighth of the top layer's thickness and the fill
    // inside it needles. The columns are shortened until each segment of
    // the last ring is at least 0.8 of the thicker top layer of its two
    // columns.
    constexpr double R = 3.0;
    constexpr int around = 24;
    const CappedSurface capped = capped_cylinder(R, 20, around, 26);
    FeatureSize sizing = cap_feature_size(capped.surface, capped.caps, tube_sizing());
    std::vector<int32_t> columns;
    const SurfaceMesh ringed =
        ring_caps(capped.surface, capped.caps, sizing, {.M = 7, .growth = 1.0, .L_max = 20, .prism_columns = &columns});
    ASSERT_TRUE(surface_facts(ringed).closed_manifold());
    constexpr int L = 3;
    ASSERT_EQ(columns.size(), ringed.points.size() * L);
    const auto column = [&](int32_t v, int m) { return m == 0 ? v : columns[size_t(v) * L + m - 1]; };
    int segments = 0;
    double closest = 1e300; // the smallest segment over top layer
    for (const Triangle& t : ringed.triangles)
        for (int k = 0; k < 3; ++k) {
            const int32_t a = t[k], b = t[(k + 1) % 3];
            if (a > b || columns[size_t(a) * L] < 0 || columns[size_t(b) * L] < 0) continue; // a rim edge, once
            const auto& x = ringed.points;
            const double top = std::max(distance(x[column(a, L)], x[column(a, L - 1)]),
                                        distance(x[column(b, L)], x[column(b, L - 1)]));
            EXPECT_GE(distance(x[column(a, L)], x[column(b, L)]), 0.8 * top * (1 - 1e-9)) << a << "-" << b;
            closest = std::min(closest, distance(x[column(a, L)], x[column(b, L)]) / top);
            ++segments;
        }
    EXPECT_EQ(segments, 2 * around); // both caps' rims
    // Not cut much further than that asks: the closest segment is within
    // two rounds' worth (1.25 squared) of the bound.
    EXPECT_LT(closest, 0.8 * 1.25 * 1.25) << closest;
}

} // namespace
} // namespace scalemesh
