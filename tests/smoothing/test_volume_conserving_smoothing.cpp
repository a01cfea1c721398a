#include "smoothing/volume_conserving_smoothing.h"

#include "core/adjacency.h"
#include "core/errors.h"
#include "sizing/test_meshes.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>

namespace scalemesh {
namespace {

double relative_volume_change(const SurfaceMesh& before, const SurfaceMesh& after)
{
    const double v0 = signed_volume(before);
    return std::abs(signed_volume(after) - v0) / std::abs(v0);
}

double max_displacement(const SurfaceMesh& a, const SurfaceMesh& b)
{
    double m = 0;
    for (size_t i = 0; i < a.points.size(); ++i) m = std::max(m, distance(a.points[i], b.points[i]));
    return m;
}

double mean_sphere_distance(const SurfaceMesh& mesh, double R)
{
    double sum = 0;
    for (const Vec3& p : mesh.points) sum += std::abs(norm(p) - R);
    return sum / static_cast<double>(mesh.points.size());
}

double mean_torus_distance(const SurfaceMesh& mesh, double R, double r)
{
    double sum = 0;
    for (const Vec3& p : mesh.points) sum += test::torus_distance(p, R, r);
    return sum / static_cast<double>(mesh.points.size());
}

// Standard deviation over mean of the edge lengths.
double edge_length_variation(const SurfaceMesh& mesh)
{
    double sum = 0, sum2 = 0;
    const auto edges = unique_edges(mesh);
    for (const auto& e : edges) {
        const double l = distance(mesh.points[e[0]], mesh.points[e[1]]);
        sum += l;
        sum2 += l * l;
    }
    const double n = static_cast<double>(edges.size());
    const double mean = sum / n;
    return std::sqrt(std::max(0.0, sum2 / n - mean * mean)) / mean;
}

SurfaceMesh noisy_sphere()
{
    SurfaceMesh mesh = test::icosphere(10.0, 4);
    test::add_noise(mesh, 0.1); // about a quarter of the edge length (0.38)
    return mesh;
}

SurfaceMesh noisy_torus()
{
    SurfaceMesh mesh = test::uv_torus(10.0, 3.0, 96, 32);
    test::add_noise(mesh, 0.15);
    return mesh;
}

TEST(Smoothing, SphereVolumeConservedOmega1)
{
    const SurfaceMesh before = noisy_sphere();
    SurfaceMesh mesh = before;
    smooth_volume_conserving(mesh, {10, 1.0});
    EXPECT_LT(relative_volume_change(before, mesh), 1e-10);
    EXPECT_GT(max_displacement(before, mesh), 0.05); // it did move
}

TEST(Smoothing, TorusVolumeConservedOmega1)
{
    const SurfaceMesh before = noisy_torus();
    SurfaceMesh mesh = before;
    smooth_volume_conserving(mesh, {10, 1.0});
    EXPECT_LT(relative_volume_change(before, mesh), 1e-10);
    EXPECT_GT(max_displacement(before, mesh), 0.05);
}

TEST(Smoothing, VolumeConservedOmegaTenth)
{
    for (const SurfaceMesh& before : {noisy_sphere(), noisy_torus()}) {
        SurfaceMesh mesh = before;
        smooth_volume_conserving(mesh, {10, 0.1});
        EXPECT_LT(relative_volume_change(before, mesh), 1e-10);
        EXPECT_GT(max_displacement(before, mesh), 0.01);
    }
}

TEST(Smoothing, VolumeConservedFarFromOrigin)
{
    SurfaceMesh before = noisy_sphere();
    for (Vec3& p : before.points) p += Vec3{250, -180, 400}; // scanner coordinates, mm
    SurfaceMesh mesh = before;
    smooth_volume_conserving(mesh, {10, 1.0});
    EXPECT_LT(relative_volume_change(before, mesh), 1e-10);
}

// Every single move is orthogonal to N_i, the normal of the node's link, so
// the normal component of the Laplacian, which is what removes normal noise,
// is discarded; the noise decays only through the tilt of the neighbours'
// links. The analytic distance must still drop, if slowly.
TEST(Smoothing, ReducesNoiseOnSphere)
{
    const SurfaceMesh before = noisy_sphere();
    SurfaceMesh mesh = before;
    smooth_volume_conserving(mesh, {10, 1.0});
    const double error_before = mean_sphere_distance(before, 10.0);
    const double error_after = mean_sphere_distance(mesh, 10.0);
    RecordProperty("mean_distance_before", test::figure(error_before));
    RecordProperty("mean_distance_after", test::figure(error_after));
    EXPECT_LT(error_after, error_before);
}

TEST(Smoothing, ReducesNoiseOnTorus)
{
    const SurfaceMesh before = noisy_torus();
    SurfaceMesh mesh = before;
    smooth_volume_conserving(mesh, {10, 1.0});
    const double error_before = mean_torus_distance(before, 10.0, 3.0);
    const double error_after = mean_torus_distance(mesh, 10.0, 3.0);
    RecordProperty("mean_distance_before", test::figure(error_before));
    RecordProperty("mean_distance_after", test::figure(error_after));
    EXPECT_LT(error_after, error_before);
}

// What the tangential moves do fix: an irregular vertex distribution. The
// noise roughly doubles the spread of edge lengths of the icosphere; smoothing
// must remove most of the added spread.
TEST(Smoothing, EvensOutEdgeLengths)
{
    const double cv_clean = edge_length_variation(test::icosphere(10.0, 4));
    const SurfaceMesh before = noisy_sphere();
    SurfaceMesh mesh = before;
    smooth_volume_conserving(mesh, {10, 1.0});
    const double cv_before = edge_length_variation(before);
    const double cv_after = edge_length_variation(mesh);
    RecordProperty("edge_length_cv", test::figure(cv_clean) + " clean, " + test::figure(cv_before) +
                                         " noisy, " + test::figure(cv_after) + " smoothed");
    EXPECT_LT(cv_after - cv_clean, 0.5 * (cv_before - cv_clean)) << cv_clean << ", " << cv_before << " -> " << cv_after;
}

TEST(Smoothing, FixedNodesDoNotMove)
{
    const SurfaceMesh before = noisy_sphere();
    SurfaceMesh mesh = before;
    SmoothingConstraint constraint;
    constraint.fixed.assign(mesh.points.size(), 0);
    for (size_t i = 0; i < mesh.points.size(); i += 7) constraint.fixed[i] = 1;
    smooth_volume_conserving(mesh, {10, 1.0}, &constraint);
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        if (!constraint.fixed[i]) continue;
        EXPECT_EQ(mesh.points[i], before.points[i]) << "node " << i;
    }
    EXPECT_GT(max_displacement(before, mesh), 0.05);
    EXPECT_LT(relative_volume_change(before, mesh), 1e-10);
}

TEST(Smoothing, PlaneConstrainedNodesStayInPlane)
{
    // A tube whose cap nodes (rims and centres) may only slide in the cap
    // planes z = 0 and z = 20, with in-plane noise so that they have to move.
    const int around = 32, along = 20;
    const SurfaceMesh clean = test::capped_cylinder(3.0, 20.0, around, along);
    SurfaceMesh before = clean;
    test::add_noise(before, 0.1);
    SmoothingConstraint constraint;
    constraint.plane_normal.assign(before.points.size(), Vec3{});
    for (size_t i = 0; i < before.points.size(); ++i) {
        const double z = clean.points[i].z;
        if (z == 0.0 || z == 20.0) {
            constraint.plane_normal[i] = {0, 0, 2.5}; // length does not matter
            before.points[i].z = z;
        }
    }
    SurfaceMesh mesh = before;
    smooth_volume_conserving(mesh, {10, 1.0}, &constraint);

    double max_out_of_plane = 0, max_in_plane_move = 0;
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        if (norm2(constraint.plane_normal[i]) == 0) continue;
        max_out_of_plane = std::max(max_out_of_plane, std::abs(mesh.points[i].z - before.points[i].z));
        max_in_plane_move = std::max(max_in_plane_move, distance(mesh.points[i], before.points[i]));
    }
    EXPECT_LE(max_out_of_plane, 1e-12);
    EXPECT_GT(max_in_plane_move, 0.01);
    EXPECT_LT(relative_volume_change(before, mesh), 1e-10);
}

TEST(Smoothing, PlaneNormalOrthogonalToFanStillConservesVolume)
{
    // Planes through the axis (normal tangential to the tube): the allowed
    // line is the intersection of the plane with the tangent plane.
    const SurfaceMesh clean = test::capped_cylinder(3.0, 20.0, 32, 20);
    SurfaceMesh before = clean;
    test::add_noise(before, 0.1);
    SmoothingConstraint constraint;
    constraint.plane_normal.assign(before.points.size(), Vec3{});
    for (size_t i = 0; i < before.points.size(); i += 3) {
        const Vec3& p = before.points[i];
        constraint.plane_normal[i] = {-p.y, p.x, 0.3};
    }
    SurfaceMesh mesh = before;
    smooth_volume_conserving(mesh, {10, 1.0}, &constraint);
    for (size_t i = 0; i < mesh.points.size(); i += 3) {
        const Vec3 n = normalized(constraint.plane_normal[i]);
        EXPECT_LE(std::abs(dot(mesh.points[i] - before.points[i], n)), 1e-12) << "node " << i;
    }
    EXPECT_LT(relative_volume_change(before, mesh), 1e-10);
}

TEST(Smoothing, Deterministic)
{
    SurfaceMesh a = noisy_torus(), b = noisy_torus();
    smooth_volume_conserving(a, {10, 1.0});
    smooth_volume_conserving(b, {10, 1.0});
    ASSERT_EQ(a.points.size(), b.points.size());
    for (size_t i = 0; i < a.points.size(); ++i) ASSERT_EQ(a.points[i], b.points[i]) << "node " << i;
}

// The sweeps run cells of one colour in parallel; the nodes they touch are
// more than three edges apart, so the result is the one of a single thread,
// bit for bit. Several two-thread runs, since a race shows only sometimes.
TEST(Smoothing, TwoThreadsGiveTheOneThreadResultBitForBit)
{
    const SurfaceMesh input = [] {
        SurfaceMesh mesh = test::uv_torus(10.0, 3.0, 384, 128);
        test::add_noise(mesh, 0.04);
        return mesh;
    }();
    SurfaceMesh one = input;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        smooth_volume_conserving(one, {10, 1.0});
    }
    for (int run = 0; run < 4; ++run) {
        SurfaceMesh two = input;
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
        smooth_volume_conserving(two, {10, 1.0});
        for (size_t i = 0; i < one.points.size(); ++i)
            ASSERT_EQ(one.points[i], two.points[i]) << "node " << i << ", run " << run;
    }
    EXPECT_LT(relative_volume_change(input, one), 1e-10);
    EXPECT_GT(max_displacement(input, one), 0.01);
}

TEST(Smoothing, ZeroSweepsIsIdentity)
{
    const SurfaceMesh before = noisy_sphere();
    SurfaceMesh mesh = before;
    smooth_volume_conserving(mesh, {0, 1.0});
    for (size_t i = 0; i < mesh.points.size(); ++i) ASSERT_EQ(mesh.points[i], before.points[i]);
}

TEST(Smoothing, RejectsBadInput)
{
    SurfaceMesh mesh = test::icosphere(1.0, 1);
    EXPECT_THROW(smooth_volume_conserving(mesh, {10, 0.0}), InputError);
    EXPECT_THROW(smooth_volume_conserving(mesh, {10, 1.5}), InputError);
    EXPECT_THROW(smooth_volume_conserving(mesh, {10, std::nan("")}), InputError);
    EXPECT_THROW(smooth_volume_conserving(mesh, {-1, 1.0}), InputError);

    SmoothingConstraint wrong_size;
    wrong_size.fixed.assign(3, 1);
    EXPECT_THROW(smooth_volume_conserving(mesh, {10, 1.0}, &wrong_size), InputError);

    SurfaceMesh open = mesh;
    open.triangles.pop_back();
    const SurfaceMesh open_before = open;
    EXPECT_THROW(smooth_volume_conserving(open, {10, 1.0}), InputError);
    for (size_t i = 0; i < open.points.size(); ++i) EXPECT_EQ(open.points[i], open_before.points[i]);
}

} // namespace
} // namespace scalemesh
