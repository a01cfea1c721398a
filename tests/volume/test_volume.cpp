// The layered volume mesh (paper sections 2.3 to 2.5, Algorithms 4 and 5) on
// smoothed marching cubes surfaces of the phantoms: the facts every mesh must
// have, the layers on the tube, and the quality after improvement.
//
// The surfaces are not remeshed (the remeshing stage is separate): the voxel
// sizes are coarse so each case runs in about a second.

#include "core/adjacency.h"
#include "core/surface_mesh.h"
#include "core/tet_mesh.h"
#include "isosurface/marching_cubes.h"
#include "layers/offset_points.h"
#include "phantom/phantom.h"
#include "remeshing/remesh.h"
#include "sizing/feature_size.h"
#include "smoothing/volume_conserving_smoothing.h"
#include "volume/improve.h"
#include "volume/layer_prisms.h"
#include "volume/quality.h"
#include "volume/volume_mesh.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>

namespace scalemesh {
namespace {

struct Prepared {
    std::unique_ptr<Shape> shape;
    SurfaceMesh surface;
    FeatureSize size;
    SizingParams sizing;
};

Prepared prepare(const std::string& name, double h, double L_min, double L_max)
{
    Prepared p;
    p.shape = make_shape(name, h);
    p.surface = marching_cubes(*voxelize(*p.shape, {.voxel_size = h}));
    smooth_volume_conserving(p.surface, {10, 1.0, 0.5 * h});
    p.sizing.L_min = L_min;
    p.sizing.L_max = L_max;
    p.size = compute_feature_size(p.surface, p.sizing);
    return p;
}

VolumeParams volume_params(const Prepared& p)
{
    VolumeParams v;
    v.K = p.sizing.K;
    v.M = p.sizing.M;
    v.L_max = p.sizing.L_max;
    return v;
}

// The faces with one tet, oriented outwards, as a surface.
SurfaceMesh mesh_boundary(const TetMesh& mesh)
{
    std::map<std::array<int32_t, 3>, std::pair<Triangle, int>> faces;
    for (const Tet& t : mesh.tets) {
        // Faces of a positive tet, counter-clockwise seen from outside it.
        const Triangle f[4] = {{t[1], t[2], t[3]}, {t[0], t[3], t[2]}, {t[0], t[1], t[3]}, {t[0], t[2], t[1]}};
        for (const Triangle& tri : f) {
            std::array<int32_t, 3> key = tri;
            std::sort(key.begin(), key.end());
            auto [it, fresh] = faces.emplace(key, std::make_pair(tri, 0));
            ++it->second.second;
        }
    }
    SurfaceMesh boundary;
    boundary.points = mesh.points;
    for (const auto& [key, face] : faces)
        if (face.second == 1) boundary.triangles.push_back(face.first);
    return boundary;
}

struct PhantomCase {
    std::string name;
    double h, L_min, L_max;
};

std::ostream& operator<<(std::ostream& os, const PhantomCase& c) { return os << c.name; }

class VolumePhantom : public ::testing::TestWithParam<PhantomCase> {};

TEST_P(VolumePhantom, ConformingPositiveOfTheSurfacesTopologyAndAboveTheQualityFloor)
{
    const PhantomCase& c = GetParam();
    const Prepared p = prepare(c.name, c.h, c.L_min, c.L_max);
    const VolumeResult r = build_volume_mesh(p.surface, p.size, volume_params(p));
    const TetMesh& mesh = r.mesh;

    const TetMeshFacts facts = tet_mesh_facts(mesh);
    EXPECT_EQ(facts.nonpositive_tets, 0);
    EXPECT_EQ(facts.overshared_faces, 0);
    EXPECT_TRUE(facts.boundary_matches);
    // The boundary is the surface, except at the pairs of triangles the
    // stage flipped or peeled (volume_mesh.h), and the tets fill what it
    // encloses.
    ASSERT_EQ(mesh.boundary_faces.size(), p.surface.triangles.size());
    int64_t changed = 0;
    for (size_t t = 0; t < p.surface.triangles.size(); ++t) changed += mesh.boundary_faces[t] != p.surface.triangles[t];
    EXPECT_LE(changed, 2 * (r.quad_flips + r.facet_flips + r.caps_peeled + r.poor_tet_cap_flips + r.light_face_cap_flips));
    SurfaceMesh bounded = p.surface;
    bounded.triangles = mesh.boundary_faces;
    const double enclosed = signed_volume(bounded);
    EXPECT_NEAR(facts.volume, enclosed, 1e-9 * enclosed);
    EXPECT_NEAR(enclosed, signed_volume(p.surface), 1e-4 * enclosed);

    ASSERT_GE(mesh.points.size(), p.surface.points.size());
    for (size_t i = 0; i < p.surface.points.size(); ++i) ASSERT_EQ(mesh.points[i], p.surface.points[i]);
    EXPECT_TRUE(topology_check_failures(mesh, int32_t(p.surface.points.size())).empty());

    const SurfaceFacts boundary = surface_facts(mesh_boundary(mesh));
    const SurfaceFacts surface = surface_facts(p.surface);
    EXPECT_TRUE(boundary.closed_manifold());
    EXPECT_EQ(boundary.components, surface.components);
    EXPECT_EQ(boundary.euler_characteristic, surface.euler_characteristic);
    EXPECT_EQ(boundary.components, p.shape->components());
    EXPECT_EQ(boundary.euler_characteristic, p.shape->euler_characteristic());

    // Paper section 2.4: after improvement no tet has aspect ratio below 0.1
    // (the run's own floor, VolumeParams::aspect_ratio_floor).
    const QualityReport& q = r.after_slivers;
    EXPECT_GE(q.min_aspect_ratio, 0.1) << q.below_0_02 << " tets below 0.02";

    int64_t full = 0, eligible = 0;
    for (size_t i = 0; i < p.surface.points.size(); ++i) {
        if (p.size.D[i] < c.L_min) continue;
        ++eligible;
        full += r.layers.realised[i] >= 3;
    }
    const double realised = eligible ? double(full) / double(eligible) : 1.0;

    std::cout << "[ " << c.name << " ] h " << c.h << " surface " << p.surface.points.size() << " points, "
              << r.offset_points << " offset, " << r.filtered_points << " filtered, " << r.inserted_points
              << " inserted, rejected small/filler/surface/other " << r.rejected_small << "/" << r.rejected_filler
              << "/" << r.rejected_surface << "/" << r.rejected_other << ", unused " << r.unused_points << "; "
              << mesh.tets.size() << " tets; flips 3-2/2-3/4-4 " << r.flips_32 << "/" << r.flips_23 << "/"
              << r.flips_44 << ", sliver flips/moves " << r.sliver_flips << "/" << r.sliver_moves
              << "\n  all layers realised at " << realised * 100 << "% of nodes with D >= L_min"
              << "; median near-wall anisotropy " << r.first_layer_anisotropy_median
              << "\n  aspect < 0.1 before/after flips/after slivers " << r.before_flips.fraction_below_0_1 * 100
              << "% / " << r.after_flips.fraction_below_0_1 * 100 << "% / " << q.fraction_below_0_1 * 100
              << "%, min aspect " << r.before_flips.min_aspect_ratio << " / " << r.after_flips.min_aspect_ratio
              << " / " << q.min_aspect_ratio << ", min dihedral " << q.min_dihedral_deg << " deg"
              << "\n  seconds: points " << r.seconds_points << " insertion " << r.seconds_insertion << " classify "
              << r.seconds_classify << " flips " << r.seconds_flips << " slivers " << r.seconds_slivers << " total "
              << r.seconds_total << "\n";

    if (c.name == "shell") {
        // Cavities of radius 3 at x = +-4.5: no tet centroid deep inside.
        for (const Tet& t : mesh.tets) {
            const Vec3 centroid = 0.25 * (mesh.points[t[0]] + mesh.points[t[1]] + mesh.points[t[2]] + mesh.points[t[3]]);
            for (double cx : {-4.5, 4.5}) ASSERT_GT(distance(centroid, {cx, 0, 0}), 3.0 - c.h);
        }
    }
    if (c.name == "twin_tubes") {
        // The tubes lie on either side of x = 0: no tet has vertices in both.
        for (const Tet& t : mesh.tets) {
            int negative = 0;
            for (int32_t v : t) negative += mesh.points[v].x < 0;
            ASSERT_TRUE(negative == 0 || negative == 4);
        }
    }
}

// The tube of section 2.3 remeshed to edge length K/M d first, as Algorithm 6
// does before the volume points, then meshed with the given first layer.
struct TubeRun {
    Prepared p;
    VolumeResult r;
};
TubeRun mesh_remeshed_tube(FirstLayer first_layer)
{
    const double h = 1.0;
    Prepared p = prepare("tube", h, 2.0, 10.0);
    RemeshParams remesh;
    remesh.K = p.sizing.K;
    remesh.M = p.sizing.M;
    remesh.sizing = p.sizing;
    remesh.max_displacement = 0.5 * h;
    RemeshResult remeshed = remesh_to_feature_size(p.surface, p.size.d, remesh);
    p.surface = std::move(remeshed.surface);
    p.size = std::move(remeshed.sizing);
    VolumeParams params = volume_params(p);
    params.first_layer = first_layer;
    params.L_min = 2.0;
    VolumeResult r = build_volume_mesh(p.surface, p.size, params);
    return {std::move(p), std::move(r)};
}

// Paper section 2.3 with the paper's uniform spacing: on a tube of diameter
// in [L_min, L_max] with M = 7 the interior points of a thin cross-sectional
// slab lie on floor(M/2) = 3 rings per wall, at d/M, 2d/M and 3d/M from the
// wall (within 15% of the spacing), and every wall node keeps its 3 layers.
TEST(VolumeLayers, PaperSpacingPutsThreeRingsPerWallAtMultiplesOfDOverM)
{
    const TubeRun t = mesh_remeshed_tube(FirstLayer::paper);
    const Prepared& p = t.p;
    const VolumeResult& r = t.r;
    const TetMesh& mesh = r.mesh;
    const int32_t n = int32_t(p.surface.points.size());
    int64_t slab = 0, on_ring = 0;
    std::array<int64_t, 4> per_ring{};
    for (size_t i = n; i < mesh.points.size(); ++i) {
        const Vec3& x = mesh.points[i];
        if (std::abs(x.z) > 0.5 || r.point_filler[i]) continue;
        const int32_t g = r.point_generator[i];
        const Vec3& w = p.surface.points[g];
        const double depth = std::hypot(w.x, w.y) - std::hypot(x.x, x.y), spacing = p.size.d[g] / 7.0;
        const double k = std::round(depth / spacing);
        ++slab;
        const bool ring = k >= 1 && k <= 3 && std::abs(depth - k * spacing) <= 0.15 * spacing;
        on_ring += ring;
        if (ring) ++per_ring[static_cast<int>(k)];
    }
    ASSERT_GT(slab, 10);
    std::cout << "[ tube, paper spacing ] slab points on rings " << 100.0 * on_ring / slab << "% of " << slab
              << " (rings 1/2/3: " << per_ring[1] << "/" << per_ring[2] << "/" << per_ring[3]
              << "); layer coverage " << 100 * r.layers.coverage() << "% of " << r.layers.eligible_nodes << "\n";
    EXPECT_GE(double(on_ring) / double(slab), 0.95);
    for (int k = 1; k <= 3; ++k) EXPECT_GT(per_ring[k], 0) << "ring " << k;
    EXPECT_GE(r.layers.coverage(), 0.99);
}

// Section 2.5: the near-wall anisotropy is K. With the first layer at the
// node's mean surface edge length over K (the default), the median over the
// wall nodes is K within 10% and every wall node keeps its 3 layers; the
// innermost layermaking point is still at 3d/M, as with the paper's spacing.
TEST(VolumeLayers, EdgeFirstLayerRealisesTheAnisotropyKAndKeepsTheLayers)
{
    const TubeRun t = mesh_remeshed_tube(FirstLayer::edge);
    const VolumeResult& r = t.r;
    std::vector<double> a;
    for (double v : r.near_wall_anisotropy)
        if (std::isfinite(v)) a.push_back(v);
    ASSERT_GT(a.size(), 50u);
    std::sort(a.begin(), a.end());
    const double median = a[a.size() / 2];
    std::cout << "[ tube, edge first layer ] anisotropy median " << median << " over " << a.size()
              << " nodes (K = 4.2); layer coverage " << 100 * r.layers.coverage() << "% of "
              << r.layers.eligible_nodes << "\n";
    EXPECT_NEAR(median, 4.2, 0.42);
    EXPECT_NEAR(r.first_layer_anisotropy_median, median, 1e-12);
    EXPECT_GE(r.layers.coverage(), 0.99);
    EXPECT_GE(r.after_slivers.min_aspect_ratio, 0.1);
    // Layer 3 of each node ends where the paper's spacing puts it.
    const int32_t n = int32_t(t.p.surface.points.size());
    int64_t third = 0, at_paper_depth = 0;
    for (size_t i = n; i < r.mesh.points.size(); ++i) {
        if (r.point_filler[i] || r.point_layer[i] != 3) continue;
        const int32_t g = r.point_generator[i];
        const double depth = distance(r.mesh.points[i], t.p.surface.points[g]);
        ++third;
        // Within the layer tolerance, a quarter of layer 3's spacing (at most
        // the whole depth 3d/7).
        at_paper_depth += std::abs(depth - 3.0 * t.p.size.d[g] / 7.0) <= 0.25 * 3.0 * t.p.size.d[g] / 7.0;
    }
    ASSERT_GT(third, 10);
    EXPECT_EQ(at_paper_depth, third);
}

// The layers are inserted by parallel tasks in slabs (delaunay_insertion.h):
// the tasks insert most points themselves, and one thread and two give the
// same mesh, point for point and tet for tet. Of the improvement after it,
// the flips with sliver removal and the cell passes have their own tests on
// one and two threads below; the whole run's are
// Reproducible.OneThreadGivesByteIdenticalFilesAndTwoThreadsTheSame.
TEST(VolumeParallel, TheTasksInsertMostPointsAndOneOrTwoThreadsGiveTheSameMesh)
{
    const Prepared p = prepare("torus", 0.5, 0.25, 4);
    VolumeParams params = volume_params(p);
    params.improve = false;
    VolumeResult results[2];
    for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        results[threads - 1] = build_volume_mesh(p.surface, p.size, params);
    }
    const VolumeResult &one = results[0], &two = results[1];
    std::cout << "[ parallel insertion ] " << one.inserted_points << " points inserted, " << one.deferred_points
              << " deferred to the sequential pass; " << one.mesh.tets.size() << " tets\n";
    ASSERT_GT(one.inserted_points, 5000);
    EXPECT_LT(one.deferred_points, one.inserted_points / 4);
    EXPECT_EQ(one.deferred_points, two.deferred_points);
    EXPECT_EQ(one.mesh.points, two.mesh.points);
    EXPECT_EQ(one.mesh.tets, two.mesh.tets);
    EXPECT_EQ(one.after_slivers.min_aspect_ratio, two.after_slivers.min_aspect_ratio);
}

// Flips and sliver removal on a mesh of 248k tets run in two slabs at
// once, then on the tets near the cut: the mesh stays valid, the surface
// points stay put, and one or two threads give the same mesh.
TEST(VolumeParallel, ImprovementInSlabsKeepsTheMeshValidAndIsTheSameOnOneOrTwoThreads)
{
    const Prepared p = prepare("torus", 0.5, 0.25, 4);
    VolumeParams params = volume_params(p);
    params.improve = false;
    const VolumeResult raw = build_volume_mesh(p.surface, p.size, params);
    ASSERT_GE(raw.mesh.tets.size(), 200000u); // two slabs or more (slab_scheduler.cpp)
    const int32_t n = static_cast<int32_t>(p.surface.points.size());
    TetMesh improved[2];
    for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        TetMesh& mesh = improved[threads - 1];
        mesh = raw.mesh;
        const FlipCounts flips = flip_volume_criterion(mesh, params.flip_sweeps);
        const SliverCounts slivers = remove_slivers(mesh, n, params.sliver_aspect_ratio, params.sliver_sweeps);
        EXPECT_GT(flips.flips_32 + flips.flips_23 + flips.flips_44, 0);
        EXPECT_GT(slivers.moves, 0);
    }
    EXPECT_EQ(improved[0].tets, improved[1].tets);
    EXPECT_EQ(improved[0].points, improved[1].points);
    const TetMesh& mesh = improved[1];
    const TetMeshFacts facts = tet_mesh_facts(mesh);
    EXPECT_EQ(facts.nonpositive_tets, 0);
    EXPECT_EQ(facts.overshared_faces, 0);
    EXPECT_TRUE(facts.boundary_matches);
    EXPECT_NEAR(facts.volume, tet_mesh_facts(raw.mesh).volume, 1e-9 * facts.volume);
    for (int32_t v = 0; v < n; ++v) ASSERT_EQ(mesh.points[v], raw.mesh.points[v]) << "surface point " << v;
    const QualityReport before = quality_report(raw.mesh), after = quality_report(mesh);
    std::cout << "[ improvement in slabs ] below 0.1: " << 100 * before.fraction_below_0_1 << "% before, "
              << 100 * after.fraction_below_0_1 << "% after; worst " << after.min_aspect_ratio << "\n";
    EXPECT_LT(after.fraction_below_0_1, 0.01);
    // Below the floor only tets of four surface points (what sliver removal
    // cannot move; the volume stage splits or peels them afterwards).
    for (const Tet& t : mesh.tets) {
        if (tet_aspect_ratio(mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]], mesh.points[t[3]]) < kQualityFloor) {
            EXPECT_LT(*std::max_element(t.begin(), t.end()), n) << "a tet below the floor with an interior point";
        }
    }
}

// The cell passes in slabs (improve_cells), the slabs forced small: four
// slabs of the torus improved at once, then five cut at their middles,
// then what is left on the whole mesh. One thread and two give the same
// mesh, point for point and tet for tet, the mesh stays valid with its
// surface points in place, and the solver's floors (no tet below 10
// degrees, no face beyond 70) hold as they do in one slab.
TEST(VolumeParallel, CellPassesInSlabsAreTheSameOnOneOrTwoThreadsAndKeepTheFloors)
{
    const Prepared p = prepare("torus", 1.0, 0.5, 8);
    VolumeParams params = volume_params(p);
    params.improve = false;
    const VolumeResult raw = build_volume_mesh(p.surface, p.size, params);
    const int32_t n = static_cast<int32_t>(p.surface.points.size());
    TetMesh start = raw.mesh;
    flip_volume_criterion(start, params.flip_sweeps);
    remove_slivers(start, n, params.sliver_aspect_ratio, params.sliver_sweeps);
    ASSERT_TRUE(tets_missing_floors(start, 10, 70) != std::vector<char>(start.tets.size(), 0)) << "nothing to mend";

    CellPassParams slabs;
    slabs.tets_per_slab = static_cast<int64_t>(start.tets.size() / 4);
    TetMesh improved[2];
    for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        TetMesh& mesh = improved[threads - 1];
        mesh = start;
        const CellCounts made = improve_cells(mesh, n, slabs);
        EXPECT_GT(made.dihedral.flips + made.dihedral.moves, 0);
        EXPECT_GT(made.ortho.flips + made.ortho.moves, 0);
    }
    EXPECT_EQ(improved[0].points, improved[1].points);
    EXPECT_EQ(improved[0].tets, improved[1].tets);

    TetMesh whole = start;
    CellPassParams one_slab;
    one_slab.max_slabs = 1;
    improve_cells(whole, n, one_slab);
    EXPECT_NE(whole.tets, improved[0].tets) << "the slabs changed nothing: not cut";

    const TetMesh& mesh = improved[1];
    const TetMeshFacts facts = tet_mesh_facts(mesh);
    EXPECT_EQ(facts.nonpositive_tets, 0);
    EXPECT_EQ(facts.overshared_faces, 0);
    EXPECT_TRUE(facts.boundary_matches);
    EXPECT_NEAR(facts.volume, tet_mesh_facts(start).volume, 1e-9 * facts.volume);
    for (int32_t v = 0; v < n; ++v) ASSERT_EQ(mesh.points[v], start.points[v]) << "surface point " << v;
    for (const TetMesh* m : {&std::as_const(whole), &mesh}) {
        const QualityReport q = quality_report(*m);
        EXPECT_GE(q.min_dihedral_deg, 10.0);
        EXPECT_LT(max_non_orthogonality_deg(*m, tet_face_adjacency(*m)), 70.0);
    }
}

// layers = "prisms": the stack over the wall and Gmsh's core above it make
// one conforming mesh of the region, and every wall triangle carries all
// its layers as intact prisms (three tets each, which the export merges).
class PrismPhantom : public ::testing::TestWithParam<PhantomCase> {};

TEST_P(PrismPhantom, EveryWallTriangleCarriesAllItsLayersAsPrismsInAConformingMesh)
{
    const PhantomCase& c = GetParam();
    const Prepared p = prepare(c.name, c.h, c.L_min, c.L_max);
    VolumeParams params = volume_params(p);
    params.layers = LayerMode::prisms;
    const VolumeResult r = build_volume_mesh(p.surface, p.size, params);
    const TetMesh& mesh = r.mesh;
    const TetMeshFacts facts = tet_mesh_facts(mesh);
    EXPECT_EQ(facts.nonpositive_tets, 0);
    EXPECT_EQ(facts.overshared_faces, 0);
    EXPECT_TRUE(facts.boundary_matches);
    EXPECT_EQ(mesh.boundary_faces, p.surface.triangles);
    EXPECT_NEAR(facts.volume, signed_volume(p.surface), 1e-9 * signed_volume(p.surface));
    for (size_t i = 0; i < p.surface.points.size(); ++i) ASSERT_EQ(mesh.points[i], p.surface.points[i]);
    EXPECT_TRUE(topology_check_failures(mesh, int32_t(p.surface.points.size())).empty());
    const SurfaceFacts boundary = surface_facts(mesh_boundary(mesh));
    EXPECT_EQ(boundary.euler_characteristic, p.shape->euler_characteristic());

    // Every tet is used by some cell, every point by some tet.
    std::vector<char> used(mesh.points.size(), 0);
    for (const Tet& t : mesh.tets)
        for (int32_t v : t) used[v] = 1;
    EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0);

    const int64_t wanted = int64_t(p.surface.triangles.size()) * int64_t(std::floor(params.M / 2));
    EXPECT_EQ(r.prism_groups.after_cell_passes, wanted);
    EXPECT_EQ(layer_prism_groups(mesh, r.point_generator, r.point_layer, r.point_filler), wanted);
    const LayerPrismCells cells = layer_prism_cells(mesh, r.adjacency, r.point_generator, r.point_layer, r.point_filler);
    EXPECT_GE(double(cells.prisms), 0.95 * double(wanted)) << cells.refused << " refused";
}

INSTANTIATE_TEST_SUITE_P(Phantoms, PrismPhantom,
                         ::testing::Values(PhantomCase{"torus", 1.0, 0.5, 8}, PhantomCase{"shell", 0.75, 0.5, 8},
                                           PhantomCase{"twin_tubes", 0.75, 0.5, 8}),
                         [](const auto& info) { return info.param.name; });

INSTANTIATE_TEST_SUITE_P(Phantoms, VolumePhantom,
                         ::testing::Values(PhantomCase{"sphere", 1.0, 0.5, 10}, PhantomCase{"torus", 1.0, 0.5, 8},
                                           PhantomCase{"tube", 1.0, 2.0, 10}, PhantomCase{"stenosis", 0.75, 0.5, 8},
                                           PhantomCase{"bifurcation", 0.5, 0.5, 8},
                                           PhantomCase{"pretzel", 0.6, 0.5, 8}, PhantomCase{"shell", 0.75, 0.5, 8},
                                           PhantomCase{"twin_tubes", 0.75, 0.5, 8}),
                         [](const auto& info) { return info.param.name; });

} // namespace
} // namespace scalemesh
