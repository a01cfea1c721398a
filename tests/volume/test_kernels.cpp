// The volume kernels on hand-built shapes whose answer is known: the flips
// of section 2.4 with the volume criterion, and the conditions of
// Algorithm 5 (the volume floor, the filler rule) in the insertion.

#include "core/face_measures.h"
#include "core/surface_mesh.h"
#include "core/tet_mesh.h"
#include "layers/offset_points.h"
#include "volume/delaunay_insertion.h"
#include "volume/improve.h"
#include "volume/layer_account.h"
#include "volume/quality.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>
#include <vector>

namespace scalemesh {
namespace {

// ---- Flips --------------------------------------------------------------

Tet positive(const std::vector<Vec3>& p, Tet t)
{
    if (tet_volume6(p[t[0]], p[t[1]], p[t[2]], p[t[3]]) < 0) std::swap(t[1], t[2]);
    return t;
}

// A mesh of `tets` (any orientation) whose boundary_faces are its one-tet faces.
TetMesh tet_mesh(std::vector<Vec3> points, const std::vector<Tet>& tets)
{
    TetMesh mesh;
    mesh.points = std::move(points);
    for (const Tet& t : tets) mesh.tets.push_back(positive(mesh.points, t));
    const TetFaceAdjacency adjacency = tet_face_adjacency(mesh);
    for (size_t t = 0; t < mesh.tets.size(); ++t)
        for (int k = 0; k < 4; ++k)
            if (adjacency.across[4 * t + k] == TetFaceAdjacency::kBoundary)
                mesh.boundary_faces.push_back(tet_face(mesh.tets[t], k));
    return mesh;
}

double smallest_aspect_ratio(const TetMesh& mesh)
{
    double q = 1e300;
    for (const Tet& t : mesh.tets)
        q = std::min(q, tet_aspect_ratio(mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]], mesh.points[t[3]]));
    return q;
}

double smallest_volume(const TetMesh& mesh)
{
    double v = 1e300;
    for (const Tet& t : mesh.tets)
        v = std::min(v, tet_volume6(mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]], mesh.points[t[3]]) / 6);
    return v;
}

bool holds(const Tet& t, int32_t v) { return std::find(t.begin(), t.end(), v) != t.end(); }

// What any flip keeps: the points, the boundary faces (same orientation),
// the total volume; every tet positive, no face with three tets.
void expect_flip_invariants(const TetMesh& before, const TetMesh& after)
{
    EXPECT_EQ(after.points.size(), before.points.size());
    for (size_t v = 0; v < before.points.size() && v < after.points.size(); ++v)
        EXPECT_EQ(after.points[v], before.points[v]) << "point " << v << " moved";
    const TetMeshFacts was = tet_mesh_facts(before), is = tet_mesh_facts(after);
    ASSERT_TRUE(was.boundary_matches);
    EXPECT_EQ(is.nonpositive_tets, 0);
    EXPECT_EQ(is.overshared_faces, 0);
    EXPECT_EQ(is.boundary_faces, was.boundary_faces);
    EXPECT_TRUE(is.boundary_matches) << "a surface face changed";
    EXPECT_NEAR(is.volume, was.volume, 1e-12 * was.volume);
}

// An interior edge (a, b) = (3, 4) with three tets: the triangle c0 c1 c2 in
// z = 0, a and b at +-1 over the point with barycentric coordinate `lambda`
// on c2 (the rest shared by c0, c1). The tet (a, b, c0, c1) has volume
// 2 lambda A / 3, the two tets of the 3-2 flip A / 3 each (A the triangle's
// area): the criterion's ratio is 1 / (2 lambda).
TetMesh three_tets_around_an_edge(double lambda)
{
    const Vec3 c0{0, 0, 0}, c1{1, 0, 0}, c2{0.5, std::sqrt(3.0) / 2, 0};
    const Vec3 foot = lambda * c2 + 0.5 * (1 - lambda) * (c0 + c1);
    return tet_mesh({c0, c1, c2, foot + Vec3{0, 0, 1}, foot - Vec3{0, 0, 1}}, {{3, 4, 0, 1}, {3, 4, 1, 2}, {3, 4, 2, 0}});
}

TEST(KernelFlips, ThreeToTwoWhenTheNewTetsAreMoreThanThreeTimesTheSmallest)
{
    const TetMesh before = three_tets_around_an_edge(0.15); // ratio 1 / 0.3 = 3.33
    ASSERT_LT(smallest_aspect_ratio(before), 0.3) << "no tet is a flip candidate";
    ASSERT_GT((1.0 / 3) * std::sqrt(3.0) / 4 / smallest_volume(before), 3.0);
    TetMesh mesh = before;
    const FlipCounts counts = flip_volume_criterion(mesh, 3);
    EXPECT_EQ(counts.flips_32, 1);
    EXPECT_EQ(counts.flips_23, 0);
    EXPECT_EQ(counts.flips_44, 0);
    ASSERT_EQ(mesh.tets.size(), 2u);
    for (const Tet& t : mesh.tets) {
        EXPECT_FALSE(holds(t, 3) && holds(t, 4)) << "the edge (a, b) is still there";
        EXPECT_TRUE(holds(t, 0) && holds(t, 1) && holds(t, 2)) << "a new tet is not on the triangle c0 c1 c2";
    }
    expect_flip_invariants(before, mesh);
    // Each new tet is a cone of height 1 over the triangle.
    EXPECT_NEAR(smallest_volume(mesh), std::sqrt(3.0) / 12, 1e-12);
}

TEST(KernelFlips, NoThreeToTwoWhenTheRatioIsJustBelowThree)
{
    const TetMesh before = three_tets_around_an_edge(0.17); // ratio 1 / 0.34 = 2.94
    ASSERT_LT(smallest_aspect_ratio(before), 0.3) << "no tet is a flip candidate: the test would prove nothing";
    const double ratio = (1.0 / 3) * std::sqrt(3.0) / 4 / smallest_volume(before);
    ASSERT_LT(ratio, 3.0);
    ASSERT_GT(ratio, 2.9);
    TetMesh mesh = before;
    const FlipCounts counts = flip_volume_criterion(mesh, 3);
    EXPECT_EQ(counts.flips_32 + counts.flips_23 + counts.flips_44, 0);
    ASSERT_EQ(mesh.tets.size(), 3u);
    for (const Tet& t : mesh.tets) EXPECT_TRUE(holds(t, 3) && holds(t, 4));
    expect_flip_invariants(before, mesh);
}

// Two tets on the triangle c0 c1 c2 (area A, z = 0): d = 3 at `above` over
// its centroid, e = 4 at `below` under it. The 2-3 flip makes three tets
// around (d, e), each (above + below) A / 9: the criterion's ratio is
// (above + below) / (3 min(above, below)).
TetMesh two_tets_on_a_face(double above, double below)
{
    const Vec3 c0{0, 0, 0}, c1{1, 0, 0}, c2{0.5, std::sqrt(3.0) / 2, 0};
    const Vec3 g = (c0 + c1 + c2) / 3.0;
    return tet_mesh({c0, c1, c2, g + Vec3{0, 0, above}, g - Vec3{0, 0, below}}, {{0, 1, 2, 3}, {0, 1, 2, 4}});
}

TEST(KernelFlips, TwoToThreeWhenTheNewTetsAreMoreThanThreeTimesTheSmallest)
{
    const TetMesh before = two_tets_on_a_face(0.05, 0.5); // ratio 0.55 / 0.15 = 3.67
    ASSERT_LT(smallest_aspect_ratio(before), 0.3);
    TetMesh mesh = before;
    const FlipCounts counts = flip_volume_criterion(mesh, 3);
    EXPECT_EQ(counts.flips_23, 1);
    EXPECT_EQ(counts.flips_32, 0);
    EXPECT_EQ(counts.flips_44, 0);
    ASSERT_EQ(mesh.tets.size(), 3u);
    for (const Tet& t : mesh.tets) EXPECT_TRUE(holds(t, 3) && holds(t, 4)) << "a new tet is not at the edge (d, e)";
    expect_flip_invariants(before, mesh);
    const double area = std::sqrt(3.0) / 4;
    EXPECT_NEAR(smallest_volume(mesh), 0.55 * area / 9, 1e-12);
    EXPECT_GT(smallest_volume(mesh), 3 * smallest_volume(before));
}

TEST(KernelFlips, NoTwoToThreeWhenTheRatioIsJustBelowThree)
{
    const TetMesh before = two_tets_on_a_face(0.065, 0.5); // ratio 0.565 / 0.195 = 2.90
    ASSERT_LT(smallest_aspect_ratio(before), 0.3);
    TetMesh mesh = before;
    const FlipCounts counts = flip_volume_criterion(mesh, 3);
    EXPECT_EQ(counts.flips_32 + counts.flips_23 + counts.flips_44, 0);
    EXPECT_EQ(mesh.tets.size(), 2u);
    expect_flip_invariants(before, mesh);
}

// An interior edge (a, b) = (4, 5) with four tets around the kite
// q0 = (-1, 0), q1 = (0, -1), q2 = (3, 0), q3 = (0, 1) in z = 0, a and b at
// +-2 over (-0.25, -0.25). The smallest old tet, (a, b, q0, q1), has
// 6V = 2 (the kite's four tets: 2, 10, 16, 4). The diagonal (q0, q2) halves
// the kite into two triangles of area 2: four new tets of 6V = 8, ratio 4.
// The diagonal (q1, q3) makes triangles of area 1 and 3: tets of 6V = 4 and
// 12, ratio 2. Only the first meets the criterion.
TEST(KernelFlips, FourToFourTakesTheDiagonalThatMeetsTheCriterion)
{
    const Vec3 foot{-0.25, -0.25, 0};
    const TetMesh before = tet_mesh({{-1, 0, 0}, {0, -1, 0}, {3, 0, 0}, {0, 1, 0}, foot + Vec3{0, 0, 2}, foot - Vec3{0, 0, 2}},
                                    {{4, 5, 0, 1}, {4, 5, 1, 2}, {4, 5, 2, 3}, {4, 5, 3, 0}});
    ASSERT_LT(smallest_aspect_ratio(before), 0.3);
    ASSERT_NEAR(smallest_volume(before), 2.0 / 6, 1e-12);
    TetMesh mesh = before;
    const FlipCounts counts = flip_volume_criterion(mesh, 3);
    EXPECT_EQ(counts.flips_44, 1);
    EXPECT_EQ(counts.flips_32, 0);
    EXPECT_EQ(counts.flips_23, 0);
    ASSERT_EQ(mesh.tets.size(), 4u);
    for (const Tet& t : mesh.tets) {
        EXPECT_FALSE(holds(t, 4) && holds(t, 5)) << "the edge (a, b) is still there";
        EXPECT_TRUE(holds(t, 0) && holds(t, 2)) << "a new tet is not at the diagonal (q0, q2)";
        EXPECT_FALSE(holds(t, 1) && holds(t, 3)) << "the diagonal (q1, q3) was taken";
    }
    expect_flip_invariants(before, mesh);
    EXPECT_NEAR(smallest_volume(mesh), 8.0 / 6, 1e-12);
}

// ---- Edge removal (the quality passes) -----------------------------------

double smallest_dihedral(const TetMesh& mesh)
{
    double d = 1e300;
    for (const Tet& t : mesh.tets)
        d = std::min(d, tet_min_dihedral_deg(mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]], mesh.points[t[3]]));
    return d;
}

// An interior edge (a, b) from (0, 0, 1) to (0, 0, -1) with m tets around it:
// the ring c_0 .. c_{m-1} in z = 0 at angles spread evenly over 185 degrees,
// so that the gap from c_{m-1} back to c_0 is 175 degrees and the tet
// (a, b, c_{m-1}, c_0) is nearly flat at (a, b), at uneven distances from
// the edge (0.75 to 1.25), so that the ring's triangulations differ. No 2-3
// flip of a face (a, b, c_i) raises its two tets' smallest angle, and with
// five or more tets around (a, b) neither a 3-2 nor a 4-4 flip applies.
TetMesh edge_with_a_flat_tet(int m)
{
    constexpr double kRadius[] = {0.75, 0.9166666666666666, 1.0833333333333333, 1.25, 0.8333333333333334, 1.0,
                                  1.1666666666666667};
    std::vector<Vec3> points;
    std::vector<Tet> tets;
    const double step = 185.0 / (m - 1);
    for (int k = 0; k < m; ++k) {
        const double angle = (90 + 87.5 + k * step) * M_PI / 180;
        points.push_back({kRadius[k] * std::cos(angle), kRadius[k] * std::sin(angle), 0});
    }
    points.push_back({0, 0, 1});
    points.push_back({0, 0, -1});
    for (int k = 0; k < m; ++k) tets.push_back({m, m + 1, k, (k + 1) % m});
    return tet_mesh(points, tets);
}

// The figures below come from enumerating the ring's triangulations apart
// from scalemesh (each triangle joined to a and to b, the ones with an
// inverted tet left out): the smallest dihedral angle before, the best
// triangulation's and the second best's.
void expect_edge_removed(int m, double before_deg, double target_deg, double best_deg, double second_deg)
{
    const TetMesh before = edge_with_a_flat_tet(m);
    ASSERT_NEAR(smallest_dihedral(before), before_deg, 1e-3);
    TetMesh mesh = before;
    // Every point a surface point: no moves, and no split is needed once the
    // edge is gone (the best triangulation is above the target).
    const DihedralCounts counts = raise_dihedral_angles(mesh, static_cast<int32_t>(mesh.points.size()), target_deg, 4);
    EXPECT_EQ(counts.tets_before, 1);
    EXPECT_EQ(counts.moves, 0);
    EXPECT_EQ(counts.splits, 0);
    EXPECT_EQ(counts.flips, 1) << "one edge removal";
    ASSERT_EQ(mesh.tets.size(), size_t(2 * (m - 2)));
    for (const Tet& t : mesh.tets) EXPECT_FALSE(holds(t, m) && holds(t, m + 1)) << "the edge (a, b) is still there";
    expect_flip_invariants(before, mesh);
    // The best of the ring's triangulations was taken, not merely a better one.
    ASSERT_GT(best_deg - second_deg, 1.0);
    EXPECT_NEAR(smallest_dihedral(mesh), best_deg, 0.01);
}

TEST(KernelEdgeRemoval, AnEdgeWithFiveTetsIsReplacedByTheBestTriangulationOfItsRing)
{
    expect_edge_removed(5, 3.082, 15.0, 30.409, 20.573); // 5 triangulations
}

TEST(KernelEdgeRemoval, AnEdgeWithSevenTetsIsReplacedByTheBestOfItsTriangulations)
{
    expect_edge_removed(7, 3.004, 10.0, 17.504, 13.619); // 42 triangulations, 23 without an inverted tet
}

// Locked tets (the layer prisms of layers = "prisms") are never replaced:
// with one tet around the edge (a, b) locked, the edge removal that mends
// the flat tet is refused, and no other edit applies (every other edge is a
// surface edge), so the mesh stays as it was.
TEST(KernelLockedTets, AnEdgeRemovalThatWouldReplaceALockedTetIsNotMade)
{
    const TetMesh before = edge_with_a_flat_tet(5);
    TetMesh mesh = before;
    const DihedralCounts counts =
        raise_dihedral_angles(mesh, static_cast<int32_t>(mesh.points.size()), 15.0, 4, {}, /*locked_tets=*/1);
    EXPECT_EQ(counts.tets_before, 1);
    EXPECT_EQ(counts.flips + counts.moves + counts.splits, 0);
    EXPECT_EQ(mesh.tets, before.tets);
    // Unlocked, the same pass removes the edge (expect_edge_removed).
    mesh = before;
    EXPECT_EQ(raise_dihedral_angles(mesh, static_cast<int32_t>(mesh.points.size()), 15.0, 4).flips, 1);
}

// A locked tet is not improved for its own sake: the flat tet locked (moved
// to the front) is not counted below the target, and nothing changes.
TEST(KernelLockedTets, ALockedTetIsNotATarget)
{
    TetMesh mesh = edge_with_a_flat_tet(5);
    std::rotate(mesh.tets.begin(), mesh.tets.end() - 1, mesh.tets.end()); // the flat tet (a, b, c_4, c_0) first
    const std::vector<Tet> tets = mesh.tets;
    const DihedralCounts counts =
        raise_dihedral_angles(mesh, static_cast<int32_t>(mesh.points.size()), 15.0, 4, {}, /*locked_tets=*/1);
    EXPECT_EQ(counts.tets_before, 0);
    EXPECT_EQ(mesh.tets, tets);
}

// A point held on its normal (LayerBound::on_normal: the top of a layer
// column) moves only along that line, within its slack: the centre of an
// octahedron, off its middle, is moved by the dihedral pass along z alone.
TEST(KernelLockedTets, APointHeldOnItsNormalMovesAlongItOnly)
{
    std::vector<Vec3> points = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, {0.1, 0.05, 0.6}};
    std::vector<Tet> tets;
    for (int32_t x : {0, 1})
        for (int32_t y : {2, 3})
            for (int32_t z : {4, 5}) tets.push_back({x, y, z, 6});
    TetMesh mesh = tet_mesh(points, tets);
    std::vector<LayerBound> bounds(points.size());
    bounds[6] = {.home = points[6], .normal = {0, 0, 1}, .slack = 0.4, .on_normal = true};
    const double before = smallest_dihedral(mesh);
    const DihedralCounts counts = raise_dihedral_angles(mesh, 6, 30.0, 8, bounds);
    EXPECT_GT(counts.moves, 0);
    EXPECT_GT(smallest_dihedral(mesh), before);
    const Vec3& centre = mesh.points[6];
    EXPECT_EQ(centre.x, 0.1);
    EXPECT_EQ(centre.y, 0.05);
    EXPECT_LT(centre.z, 0.6);
    EXPECT_GE(centre.z, 0.6 - 0.4 - 1e-12);
    // A fixed point does not move at all (the pass may split edges instead).
    mesh = tet_mesh(points, tets);
    bounds[6] = {.home = {}, .normal = {}, .fixed = true};
    raise_dihedral_angles(mesh, 6, 30.0, 8, bounds);
    EXPECT_EQ(mesh.points[6], points[6]);
}

// ---- Face non-orthogonality ---------------------------------------------

// Two tets on the triangle (0,0,0), (1,0,0), (0,1,0), their apexes (0,0,1)
// and (x,0,-1): the centroids' join is ((x/4), 0, -1/2) against the face's
// normal (0, 0, -1), so the face's non-orthogonality is atan(x/2).
TetMesh two_tets_over_a_triangle(double x)
{
    return tet_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {x, 0, -1}}, {{0, 1, 2, 3}, {0, 1, 2, 4}});
}

TEST(KernelNonOrthogonality, TheLargestAngleIsTheSharedFacesAsCheckMeshMeasuresIt)
{
    for (double x : {0.0, 2.0, 6.0}) {
        const TetMesh mesh = two_tets_over_a_triangle(x);
        EXPECT_NEAR(max_non_orthogonality_deg(mesh, tet_face_adjacency(mesh)), std::atan(x / 2) * 180 / M_PI, 1e-9)
            << "apex at x = " << x;
    }
    // One tet has no interior face.
    const TetMesh one = tet_mesh({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {{0, 1, 2, 3}});
    EXPECT_EQ(max_non_orthogonality_deg(one, tet_face_adjacency(one)), 0);
}

// The release's finder marks both tets of a face beyond the bound (71.6
// degrees at x = 6) and neither below it (45 degrees at x = 2); the dihedral
// floor alone marks the flat tet.
TEST(KernelNonOrthogonality, PointsMissingFloorsAreThePointsOfTheCellsBeyondTheBounds)
{
    const TetMesh within = two_tets_over_a_triangle(2);
    EXPECT_TRUE(points_missing_floors(within, 0, 0.0, 70.0).empty());
    const TetMesh beyond = two_tets_over_a_triangle(6);
    EXPECT_EQ(points_missing_floors(beyond, 0, 0.0, 70.0), (std::vector<int32_t>{0, 1, 2, 3, 4}));
    EXPECT_EQ(points_missing_floors(beyond, 3, 0.0, 70.0), (std::vector<int32_t>{3, 4})) << "surface points listed";
    // With the angle bound out of reach, only a tet below the dihedral floor
    // is marked: the second tet, stretched to x = 6, has the smaller angle.
    const auto [first, second] = std::pair{tet_min_dihedral_deg({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}),
                                           tet_min_dihedral_deg({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {6, 0, -1})};
    ASSERT_LT(second, first);
    EXPECT_EQ(points_missing_floors(beyond, 0, 0.5 * (first + second), 180.0), (std::vector<int32_t>{0, 1, 2, 4}));
}

// ---- Light faces -----------------------------------------------------------

// OpenFOAM's interpolation weight of every interior face, both centres the
// tets' centroids: the smallest.
double lightest_face(const TetMesh& mesh)
{
    const TetFaceAdjacency adjacency = tet_face_adjacency(mesh);
    const auto centroid = [&](size_t t) {
        const Tet& x = mesh.tets[t];
        return (mesh.points[x[0]] + mesh.points[x[1]] + mesh.points[x[2]] + mesh.points[x[3]]) / 4;
    };
    double lightest = 1;
    for (size_t t = 0; t < mesh.tets.size(); ++t)
        for (int k = 0; k < 4; ++k) {
            const int32_t u = adjacency.across[4 * t + k];
            if (u == TetFaceAdjacency::kBoundary) continue;
            const Triangle f = tet_face(mesh.tets[t], k);
            const Vec3 &a = mesh.points[f[0]], &b = mesh.points[f[1]], &c = mesh.points[f[2]];
            lightest = std::min(lightest, face_interpolation_weight(cross(b - a, c - a), (a + b + c) / 3, centroid(t),
                                                                    centroid(size_t(u))));
        }
    return lightest;
}

// The regular octahedron (surface points 0-5) coned from an interior point
// 6 at `inner`: eight tets.
TetMesh coned_octahedron(const Vec3& inner)
{
    std::vector<Vec3> points{{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, inner};
    std::vector<Tet> tets;
    for (int32_t x : {0, 1})
        for (int32_t y : {2, 3})
            for (int32_t z : {4, 5}) tets.push_back({x, y, z, 6});
    return tet_mesh(points, tets);
}

// The inner point near the face (1, 0, 0), (0, 1, 0), (0, 0, 1): the tet on
// that face is flat, and its faces to its three neighbours have weights
// below 0.05. Moving the free point raises them past the target; the
// surface points stay, every tet stays positive.
TEST(KernelLightFaces, AFreePointNearAFaceOfItsStarMovesUntilNoFaceIsLight)
{
    TetMesh mesh = coned_octahedron({0.326, 0.326, 0.326});
    const double before = lightest_face(mesh);
    ASSERT_LT(before, 0.05);
    const auto worst = [](const TetMesh& m) {
        std::pair<double, double> aspect_dihedral{1e300, 1e300};
        for (const Tet& t : m.tets) {
            const Vec3 &a = m.points[t[0]], &b = m.points[t[1]], &c = m.points[t[2]], &d = m.points[t[3]];
            aspect_dihedral.first = std::min(aspect_dihedral.first, tet_aspect_ratio(a, b, c, d));
            aspect_dihedral.second = std::min(aspect_dihedral.second, tet_min_dihedral_deg(a, b, c, d));
        }
        return aspect_dihedral;
    };
    const auto [aspect_before, dihedral_before] = worst(mesh);
    const double ortho_before = max_non_orthogonality_deg(mesh, tet_face_adjacency(mesh));
    const std::vector<Vec3> surface(mesh.points.begin(), mesh.points.begin() + 6);
    const LightFaceCounts made = mend_light_faces(mesh, 6, 0.06);
    EXPECT_EQ(made.faces_before, 3);
    EXPECT_GE(made.moves, 1);
    EXPECT_EQ(made.faces_after, 0);
    EXPECT_GE(lightest_face(mesh), 0.06) << "from " << before;
    EXPECT_EQ(std::vector<Vec3>(mesh.points.begin(), mesh.points.begin() + 6), surface);
    for (const Tet& t : mesh.tets)
        EXPECT_GT(tet_volume6(mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]], mesh.points[t[3]]), 0);
    // What a move keeps: the aspect ratio floor and the passes' targets
    // (12 and 65 degrees), or the mesh's own worst where it missed them.
    const auto [aspect_after, dihedral_after] = worst(mesh);
    EXPECT_GE(aspect_after, std::min(0.1, aspect_before));
    EXPECT_GE(dihedral_after, std::min(12.0, dihedral_before));
    EXPECT_LE(max_non_orthogonality_deg(mesh, tet_face_adjacency(mesh)), std::max(65.0, ortho_before) + 1e-9);
}

// The tets (0, 1, 2, 4) and (0, 1, 3, 4) of `points`, joined at the face
// (0, 1, 4) and standing on the triangles (0, 1, 2) and (0, 1, 3) in z = 0,
// and the patches of the mesh's boundary faces: 1 for those two (an
// opening's cap), 0 for the others.
std::pair<TetMesh, std::vector<int32_t>> two_tets_on_a_cap(const std::vector<Vec3>& points)
{
    TetMesh mesh = tet_mesh(points, {{0, 1, 2, 4}, {0, 1, 3, 4}});
    std::vector<int32_t> cap(mesh.boundary_faces.size());
    for (size_t i = 0; i < cap.size(); ++i) {
        const Triangle& f = mesh.boundary_faces[i];
        cap[i] = points[f[0]].z == 0 && points[f[1]].z == 0 && points[f[2]].z == 0;
    }
    return {std::move(mesh), std::move(cap)};
}

// The two tets of two_tets_on_a_cap after the flip of the cap's quad: the
// points where they were, every tet positive, the boundary closed, the
// volume kept; the cap's two triangles on the other diagonal (2, 3), facing
// out (-z), the rest as before.
void expect_cap_quad_flipped(const TetMesh& start, const TetMesh& flipped, const std::vector<int32_t>& cap)
{
    EXPECT_EQ(flipped.points, start.points);
    const TetMeshFacts facts = tet_mesh_facts(flipped);
    EXPECT_EQ(facts.nonpositive_tets, 0);
    EXPECT_TRUE(facts.boundary_matches);
    EXPECT_NEAR(facts.volume, tet_mesh_facts(start).volume, 1e-12);
    const std::vector<Vec3>& p = start.points;
    for (size_t i = 0; i < cap.size(); ++i) {
        const Triangle& f = flipped.boundary_faces[i];
        const bool has_diagonal = std::count(f.begin(), f.end(), 2) + std::count(f.begin(), f.end(), 3) == 2;
        EXPECT_EQ(has_diagonal, cap[i] == 1) << "boundary face " << i;
        if (cap[i]) {
            EXPECT_LT(cross(p[f[1]] - p[f[0]], p[f[2]] - p[f[0]]).z, 0) << "faces out";
        } else {
            EXPECT_EQ(f, start.boundary_faces[i]) << "boundary face " << i;
        }
    }
}

// A light face whose two apexes lie in one plane with its surface edge (two
// triangles of a flat cap, 2 far nearer the edge (0, 1) than 3; the free
// point 4 above the edge): a move of 4 turns the face about that edge, and
// both apexes' distances from it change by the same factor, so no move
// changes the weight. Where the two triangles are an opening's (patch 1),
// the quad's other diagonal (2, 3) takes the edge's place, in the tets and
// the boundary faces, the cap's plane and the volume unchanged; on the wall
// (patch 0), or without patches, the face is reported left, nothing moved.
TEST(KernelLightFaces, ALightFaceOverAFlatCapIsFlippedToTheQuadsOtherDiagonal)
{
    const std::vector<Vec3> points{{0, 0, 0}, {1, 0, 0}, {0.5, 0.03, 0}, {0.5, -1, 0}, {0.5, 0, 1}};
    const auto [start, cap] = two_tets_on_a_cap(points);
    ASSERT_LT(lightest_face(start), 0.05);
    ASSERT_EQ(std::count(cap.begin(), cap.end(), 1), 2);

    TetMesh flipped = start;
    const LightFaceCounts made = mend_light_faces(flipped, 4, 0.06, {}, 0, nullptr, cap);
    EXPECT_EQ(made.faces_before, 1);
    EXPECT_EQ(made.cap_flips, 1);
    EXPECT_EQ(made.faces_after, 0);
    EXPECT_GE(lightest_face(flipped), 0.06);
    expect_cap_quad_flipped(start, flipped, cap);

    for (const std::vector<int32_t>& patches : {std::vector<int32_t>(cap.size(), 0), std::vector<int32_t>{}}) {
        TetMesh left = start;
        const LightFaceCounts none = mend_light_faces(left, 4, 0.06, {}, 0, nullptr, patches);
        EXPECT_EQ(none.faces_before, 1);
        EXPECT_EQ(none.cap_flips + none.moves, 0);
        EXPECT_EQ(none.faces_after, 1);
        EXPECT_EQ(left.points, points);
        EXPECT_EQ(left.tets, start.tets);
    }
}

// A light face over two cap triangles whose quad is not convex (2 beyond
// the edge (0, 1)'s end, so the diagonal (2, 3) misses the edge): the flip
// would not fill the pyramid, and is not made; no move changes the weight.
TEST(KernelLightFaces, ALightFaceOverANonConvexCapQuadIsNotFlipped)
{
    const std::vector<Vec3> points{{0, 0, 0}, {1, 0, 0}, {1.5, 0.001, 0}, {0.5, -1, 0}, {0.5, 0, 1}};
    const auto [start, cap] = two_tets_on_a_cap(points);
    ASSERT_LT(lightest_face(start), 0.05);
    TetMesh left = start;
    const LightFaceCounts none = mend_light_faces(left, 4, 0.06, {}, 0, nullptr, cap);
    EXPECT_EQ(none.faces_before, 1);
    EXPECT_EQ(none.cap_flips + none.moves, 0);
    EXPECT_EQ(none.faces_after, 1);
    EXPECT_EQ(left.tets, start.tets);
    EXPECT_EQ(left.boundary_faces, start.boundary_faces);
}

// A tet below the dihedral floor (8.9 degrees) on a cap triangle whose angle
// at 2 is 164 degrees, its face to the other tet not light (0.065): its
// angles at the edges to the apex 4 tend to the triangle's small angles
// wherever 4 is, so only the quad's other diagonal (2, 3) mends it. On an
// opening's patch it takes the edge's place (both new tets at 35 degrees),
// the cap's plane and the volume unchanged; on the wall, or without
// patches, nothing changes.
TEST(KernelLightFaces, ATetBelowTheFloorsOverAFlatCapIsFlippedToTheQuadsOtherDiagonal)
{
    const std::vector<Vec3> points{{0, 0, 0}, {1, 0, 0}, {0.5, 0.07, 0}, {0.5, -1, 0}, {0.5, 0, 1}};
    const auto [start, cap] = two_tets_on_a_cap(points);
    ASSERT_LT(smallest_dihedral(start), 10);
    ASSERT_GE(lightest_face(start), 0.06);

    TetMesh flipped = start;
    const LightFaceCounts made = mend_light_faces(flipped, 4, 0.06, {}, 0, nullptr, cap);
    EXPECT_EQ(made.faces_before, 0);
    EXPECT_EQ(made.cap_flips, 0);
    EXPECT_EQ(made.poor_tet_cap_flips, 1);
    EXPECT_EQ(made.faces_after, 0);
    EXPECT_GE(smallest_dihedral(flipped), 30);
    expect_cap_quad_flipped(start, flipped, cap);

    for (const std::vector<int32_t>& patches : {std::vector<int32_t>(cap.size(), 0), std::vector<int32_t>{}}) {
        TetMesh left = start;
        const LightFaceCounts none = mend_light_faces(left, 4, 0.06, {}, 0, nullptr, patches);
        EXPECT_EQ(none.poor_tet_cap_flips + none.cap_flips + none.moves, 0);
        EXPECT_EQ(left.tets, start.tets);
        EXPECT_EQ(left.boundary_faces, start.boundary_faces);
    }
}

// A free point held (a fixed layer point) is not moved.
TEST(KernelLightFaces, AFixedLayerPointIsNotMoved)
{
    TetMesh held = coned_octahedron({0.326, 0.326, 0.326});
    const std::vector<Vec3> start = held.points;
    std::vector<LayerBound> layers(7);
    layers[6].fixed = true;
    const LightFaceCounts none = mend_light_faces(held, 6, 0.06, layers);
    EXPECT_EQ(none.faces_before, 3);
    EXPECT_EQ(none.moves, 0);
    EXPECT_EQ(none.faces_after, 3);
    EXPECT_EQ(held.points, start);
}

// ---- Conditional insertion (Algorithm 5) ---------------------------------

// A closed tetrahedron surface: the equilateral triangle c0 c1 c2 in z = 0
// (edge 1) and the apex over its centroid at the regular height.
SurfaceMesh tetrahedron_surface()
{
    SurfaceMesh s;
    s.points = {{0, 0, 0}, {1, 0, 0}, {0.5, std::sqrt(3.0) / 2, 0}, {0.5, std::sqrt(3.0) / 6, std::sqrt(2.0 / 3)}};
    const Tet t = positive(s.points, {0, 1, 2, 3});
    for (int k = 0; k < 4; ++k) s.triangles.push_back(tet_face(t, k));
    return s;
}

// A layermaking point of layer 1 cast from `node` at `position`.
OffsetPoint layer_point(const SurfaceMesh& s, int32_t node, const Vec3& position, double spacing)
{
    return {position, node, 1, false, distance(position, s.points[node]), spacing};
}

InsertionParams floor_params(double min_volume_fraction, double layer_shift)
{
    InsertionParams params;
    params.min_volume_fraction = min_volume_fraction;
    params.layer_shift = layer_shift;
    return params;
}

double smallest_volume(const InsertionResult& r)
{
    double v = 1e300;
    for (const Tet& t : r.tets) v = std::min(v, tet_volume6(r.points[t[0]], r.points[t[1]], r.points[t[2]], r.points[t[3]]) / 6);
    return v;
}

TEST(KernelInsertion, AWellPlacedLayerPointIsInserted)
{
    const SurfaceMesh s = tetrahedron_surface();
    const Vec3 centroid = (s.points[0] + s.points[1] + s.points[2] + s.points[3]) / 4.0;
    const InsertionResult r = insert_and_classify(s, {layer_point(s, 3, centroid, 0.3)}, floor_params(1e-3, 0));
    ASSERT_TRUE(r.missing_triangles.empty());
    ASSERT_EQ(r.fates.size(), 1u);
    EXPECT_EQ(r.fates[0], InsertionFate::inserted);
    EXPECT_EQ(r.inserted, 1);
    ASSERT_EQ(r.points.size(), 5u);
    EXPECT_EQ(r.points[4], centroid);
    EXPECT_EQ(r.tets.size(), 4u); // the centroid joined to the four faces
    EXPECT_NEAR(smallest_volume(r), std::sqrt(2.0) / 12 / 4, 1e-12);
}

// A point 1e-5 over the base triangle (area sqrt(3)/4): joined to it, a tet
// of 1.4e-6 mm^3, below the floor 1e-3 * 0.3^3 = 2.7e-5. The cell holding the
// point is the one that would go, so the point is refused, not given a
// smaller cavity.
TEST(KernelInsertion, ALayerPointThatWouldMakeATetBelowTheFloorIsRefused)
{
    const SurfaceMesh s = tetrahedron_surface();
    const Vec3 near_base{0.5, std::sqrt(3.0) / 6, 1e-5};
    ASSERT_LT(std::sqrt(3.0) / 4 * 1e-5 / 3, 1e-3 * 0.3 * 0.3 * 0.3);
    const std::vector<OffsetPoint> points = {layer_point(s, 3, near_base, 0.3)};

    const InsertionResult refused = insert_and_classify(s, points, floor_params(1e-3, 0));
    ASSERT_EQ(refused.fates.size(), 1u);
    EXPECT_NE(refused.fates[0], InsertionFate::inserted);
    EXPECT_EQ(refused.inserted, 0);
    EXPECT_EQ(refused.points.size(), 4u);
    EXPECT_EQ(refused.tets.size(), 1u);
    // Refused for the tiny tet (Algorithm 5 (i)), not as hidden, outside or
    // a filler.
    EXPECT_EQ(refused.fates[0], InsertionFate::tiny_tet);
    EXPECT_EQ(refused.rejected_small, 1);
    EXPECT_EQ(refused.rejected_surface + refused.rejected_filler + refused.rejected_other, 0);

    // Without the floor the same point goes in: the floor refused it.
    const InsertionResult no_floor = insert_and_classify(s, points, floor_params(0, 0));
    ASSERT_EQ(no_floor.fates.size(), 1u);
    EXPECT_EQ(no_floor.fates[0], InsertionFate::inserted);
    EXPECT_EQ(no_floor.tets.size(), 4u);
    EXPECT_GT(smallest_volume(no_floor), 0);
}

// With a layer shift, the refused point is tried again along its normal
// (from its node, the apex, towards the base) within layer_shift of its
// spacing, and goes in there, its tets all above the floor.
TEST(KernelInsertion, ARefusedLayerPointIsRetriedAlongItsNormal)
{
    const SurfaceMesh s = tetrahedron_surface();
    const Vec3 near_base{0.5, std::sqrt(3.0) / 6, 1e-5};
    const double spacing = 0.3, shift = 0.15;
    const InsertionResult r = insert_and_classify(s, {layer_point(s, 3, near_base, spacing)}, floor_params(1e-3, shift));
    ASSERT_EQ(r.fates.size(), 1u);
    EXPECT_EQ(r.fates[0], InsertionFate::inserted);
    ASSERT_EQ(r.points.size(), 5u);
    const Vec3 placed = r.points[4];
    EXPECT_LE(distance(placed, near_base), shift * spacing + 1e-12);
    EXPECT_GT(distance(placed, near_base), 0) << "inserted where it was refused";
    // On the line from the node through the point.
    const Vec3 along = normalized(near_base - s.points[3]);
    EXPECT_LT(norm(cross(placed - near_base, along)), 1e-12);
    EXPECT_GE(smallest_volume(r), 1e-3 * spacing * spacing * spacing);
}

OffsetPoint filler_point(const SurfaceMesh& s, int32_t node, const Vec3& position, int32_t layer, double spacing)
{
    return {position, node, layer, true, distance(position, s.points[node]), spacing};
}

// Inside the bare tetrahedron every cavity is bounded by surface points, so
// a filler point there would join one: refused (section 2.3), while a
// layermaking point at the same place is inserted.
TEST(KernelInsertion, AFillerPointThatWouldJoinASurfacePointIsRefused)
{
    const SurfaceMesh s = tetrahedron_surface();
    const Vec3 centroid = (s.points[0] + s.points[1] + s.points[2] + s.points[3]) / 4.0;

    const InsertionResult filler = insert_and_classify(s, {filler_point(s, 3, centroid, 2, 0.3)}, floor_params(1e-3, 0.15));
    ASSERT_EQ(filler.fates.size(), 1u);
    EXPECT_EQ(filler.fates[0], InsertionFate::filler);
    EXPECT_EQ(filler.rejected_filler, 1);
    EXPECT_EQ(filler.inserted, 0);
    EXPECT_EQ(filler.points.size(), 4u);

    const InsertionResult layer = insert_and_classify(s, {layer_point(s, 3, centroid, 0.3)}, floor_params(1e-3, 0.15));
    ASSERT_EQ(layer.fates.size(), 1u);
    EXPECT_EQ(layer.fates[0], InsertionFate::inserted);
}

// Four layermaking points on a small copy of the tetrahedron (scale 0.2,
// about the centroid) make a cell of interior points around the centroid.
// A filler point there has a cavity of that cell alone: it joins no
// surface point and is inserted.
TEST(KernelInsertion, AFillerPointAwayFromTheSurfaceIsInserted)
{
    const SurfaceMesh s = tetrahedron_surface();
    const Vec3 centroid = (s.points[0] + s.points[1] + s.points[2] + s.points[3]) / 4.0;
    std::vector<OffsetPoint> points;
    for (int32_t k = 0; k < 4; ++k) points.push_back(layer_point(s, k, centroid + 0.2 * (s.points[k] - centroid), 0.05));
    points.push_back(filler_point(s, 3, centroid, 2, 0.05));
    const InsertionResult r = insert_and_classify(s, points, floor_params(1e-3, 0.15));
    ASSERT_EQ(r.fates.size(), 5u);
    for (int k = 0; k < 4; ++k) EXPECT_EQ(r.fates[k], InsertionFate::inserted) << "layer point " << k;
    EXPECT_EQ(r.fates[4], InsertionFate::inserted);
    EXPECT_EQ(r.inserted, 5);
    // The filler's tets are the inner cell's four faces joined to it.
    const int32_t filler = static_cast<int32_t>(r.points.size()) - 1;
    ASSERT_EQ(r.points[filler], centroid);
    int around = 0;
    for (const Tet& t : r.tets)
        if (holds(t, filler)) {
            ++around;
            for (int32_t v : t) EXPECT_GE(v, 4) << "the filler point is joined to surface point " << v;
        }
    EXPECT_EQ(around, 4);
}

// Eleven layermaking points about the tetrahedron's middle and a point p
// among them (a configuration found by a search over random ones, on a
// 0.001 grid). Inserting p, one cell of its Delaunay cavity, not the one
// holding p, has a boundary facet that would make a tet below the floor
// (min_volume_fraction 0.02 of spacing^3). A layermaking point at p goes in
// with that cell taken out of its cavity (kept, though p is in its
// circumsphere); a filler at p is refused instead, as the paper's rule (i)
// says: fillers only fill, and on the torus of a 1152 box the cells such
// shrinks kept made each next layer's cavities larger and less often
// star-shaped, until a quarter of the tets were below aspect ratio 0.1.
TEST(KernelInsertion, AFillerIsRefusedWhereALayerPointWouldHaveItsCavityShrunk)
{
    const SurfaceMesh s = tetrahedron_surface();
    std::vector<OffsetPoint> points;
    for (const Vec3& x : std::vector<Vec3>{{0.482, 0.399, 0.286}, {0.604, 0.243, 0.247}, {0.526, 0.218, 0.124},
                                           {0.452, 0.298, 0.166}, {0.496, 0.377, 0.276}, {0.511, 0.212, 0.252},
                                           {0.568, 0.274, 0.282}, {0.474, 0.392, 0.096}, {0.498, 0.378, 0.289},
                                           {0.571, 0.290, 0.281}, {0.497, 0.372, 0.264}})
        points.push_back(layer_point(s, 3, x, 0.05));
    const Vec3 p{0.494, 0.259, 0.202};
    const InsertionParams params = floor_params(0.02, 0); // no retry along the normal
    auto with = [&](const OffsetPoint& last, const InsertionParams& with_params) {
        std::vector<OffsetPoint> all = points;
        all.push_back(last);
        const InsertionResult r = insert_and_classify(s, all, with_params);
        EXPECT_EQ(r.fates.size(), all.size());
        for (size_t k = 0; k + 1 < all.size(); ++k) EXPECT_EQ(r.fates[k], InsertionFate::inserted) << "layer point " << k;
        return r;
    };

    const InsertionResult layer = with(layer_point(s, 3, p, 0.05), params);
    ASSERT_EQ(layer.fates.size(), 12u);
    EXPECT_EQ(layer.fates[11], InsertionFate::inserted);
    EXPECT_EQ(std::count(layer.points.begin(), layer.points.end(), p), 1) << "not inserted at its place";
    EXPECT_GE(smallest_volume(layer), 0.02 * 0.05 * 0.05 * 0.05) << "a tet below the floor was made";

    const InsertionResult filler = with(filler_point(s, 3, p, 2, 0.05), params);
    ASSERT_EQ(filler.fates.size(), 12u);
    EXPECT_EQ(filler.fates[11], InsertionFate::tiny_tet);
    EXPECT_EQ(filler.rejected_small, 1);
    EXPECT_EQ(filler.inserted, 11);
    EXPECT_EQ(std::count(filler.points.begin(), filler.points.end(), p), 0);

    // Without the floor the filler goes in: the tiny tet refused it, not a
    // surface point (rule (ii)) or the cell holding it.
    InsertionParams no_floor = params;
    no_floor.min_volume_fraction = 0;
    const InsertionResult free = with(filler_point(s, 3, p, 2, 0.05), no_floor);
    ASSERT_EQ(free.fates.size(), 12u);
    EXPECT_EQ(free.fates[11], InsertionFate::inserted);
}

} // namespace
} // namespace scalemesh
