// Layer prisms as cells: layer_prism_cells finds the three tets that fill a
// layer prism, and the polyMesh writer makes each such group one cell, with
// the quad between two prisms one face; checkMesh accepts the result.

#include "core/tet_mesh.h"
#include "exporters/polymesh_writer.h"
#include "openfoam_support.h"
#include "volume/layer_prisms.h"
#include "volume/quality.h"

#include "support/temp_dir.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <map>

namespace scalemesh {
namespace {

// Two layer prisms on the wall triangles (0, 1, 2) and (0, 2, 3) of the unit
// square at z = 0, their top points 4 .. 7 at z = 0.25 made from 0 .. 3.
// Each prism is three tets, its quads split on the diagonal from the lower
// of their wall points (so the shared quad is split the same way from both
// sides). The boundary is every face of one tet, outward.
struct TwoPrisms {
    TetMesh mesh;
    std::vector<int32_t> generator, layer;
    std::vector<char> filler;
};

void set_boundary(TetMesh& mesh);

// Appends tet `t` to `mesh`, its first two points swapped if it is negative.
void push_oriented(TetMesh& mesh, Tet t)
{
    const auto& p = mesh.points;
    if (tet_volume6(p[t[0]], p[t[1]], p[t[2]], p[t[3]]) < 0) std::swap(t[0], t[1]);
    mesh.tets.push_back(t);
}

// The cells written as a polyMesh, which checkMesh must pass (where
// OpenFOAM is installed) with as many cells: the writer's counts.
PolyMeshCounts write_and_check(const TetMesh& mesh, const LayerPrismCells& cells)
{
    const TempDir dir;
    const PolyMeshCounts counts = write_polymesh(
        mesh, dir.path,
        {.patch_types = {}, .cell_of_tet = &cells.cell_of_tet, .cells = cells.cells, .quad_cells = &cells.prism_cell});
    if (openfoam_available()) {
        const CheckMeshFigures check = check_mesh(dir.path);
        EXPECT_TRUE(check.ok) << check.log;
        EXPECT_EQ(check.cells, cells.cells);
    }
    return counts;
}

// `points` in place of the square's, if given: the tets are oriented on them.
TwoPrisms two_prisms(const std::vector<Vec3>& points = {})
{
    TwoPrisms s;
    const double z = 0.25;
    s.mesh.points = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, z}, {1, 0, z}, {1, 1, z}, {0, 1, z}};
    if (!points.empty()) s.mesh.points = points;
    s.generator = {0, 1, 2, 3, 0, 1, 2, 3};
    s.layer = {0, 0, 0, 0, 1, 1, 1, 1};
    s.filler.assign(8, 0);
    for (std::array<int32_t, 3> wall : {std::array<int32_t, 3>{0, 1, 2}, {0, 2, 3}}) {
        std::sort(wall.begin(), wall.end());
        const int32_t a = wall[0], b = wall[1], c = wall[2];
        for (const Tet& t : {Tet{a, b, c, c + 4}, Tet{a, b, b + 4, c + 4}, Tet{a, a + 4, b + 4, c + 4}})
            push_oriented(s.mesh, t);
    }
    set_boundary(s.mesh);
    return s;
}

// `mesh.boundary_faces`: every tet face no other tet shares, outward.
void set_boundary(TetMesh& mesh)
{
    std::map<std::array<int32_t, 3>, std::pair<int, Triangle>> faces;
    for (const Tet& t : mesh.tets)
        for (int k = 0; k < 4; ++k) {
            const Triangle f = tet_face(t, k);
            std::array<int32_t, 3> key = f;
            std::sort(key.begin(), key.end());
            auto& [count, face] = faces[key];
            ++count;
            face = f;
        }
    mesh.boundary_faces.clear();
    for (const auto& [key, entry] : faces)
        if (entry.first == 1) mesh.boundary_faces.push_back(entry.second);
}

// Every tet a cell of its own.
LayerPrismCells single_tets(const TetMesh& mesh)
{
    LayerPrismCells cells;
    for (size_t t = 0; t < mesh.tets.size(); ++t) cells.cell_of_tet.push_back(static_cast<int32_t>(t));
    cells.cells = static_cast<int32_t>(mesh.tets.size());
    return cells;
}

TEST(LayerPrisms, ThreeTetsFillingALayerPrismBecomeOneCell)
{
    const TwoPrisms s = two_prisms();
    ASSERT_EQ(s.mesh.tets.size(), 6u);
    ASSERT_EQ(s.mesh.boundary_faces.size(), 12u); // 2 + 2 caps, 4 sides of 2 triangles
    const TetFaceAdjacency adjacency = tet_face_adjacency(s.mesh);
    const LayerPrismCells cells = layer_prism_cells(s.mesh, adjacency, s.generator, s.layer, s.filler);
    EXPECT_EQ(cells.prisms, 2);
    EXPECT_EQ(cells.refused, 0);
    ASSERT_EQ(cells.cells, 2);
    EXPECT_EQ(cells.cell_of_tet, (std::vector<int32_t>{0, 0, 0, 1, 1, 1}));

    // A filler among a prism's points: its tets stay cells of their own.
    TwoPrisms with_filler = s;
    with_filler.filler[7] = 1; // a top point of the second prism only
    const LayerPrismCells partly =
        layer_prism_cells(s.mesh, adjacency, with_filler.generator, with_filler.layer, with_filler.filler);
    EXPECT_EQ(partly.prisms, 1);
    EXPECT_EQ(partly.cells, 4);

    // No face may end up beyond the bound: at 0 degrees every prism with a
    // neighbouring cell is refused, and both tets' groups stay tets.
    const LayerPrismCells strict = layer_prism_cells(s.mesh, adjacency, s.generator, s.layer, s.filler, 0.0);
    EXPECT_EQ(strict.prisms, 0);
    EXPECT_EQ(strict.refused, 2);
    EXPECT_EQ(strict.cells, 6);
}

// Prisms of an inner layer stand on the triangles of that layer, which need
// not be boundary triangles: the same two prisms as layers 1 and 2 of
// columns whose generators (10 .. 13) are nodes of no face of this mesh.
TEST(LayerPrisms, InnerLayerPrismsNeedNoBoundaryTriangleBelow)
{
    TwoPrisms s = two_prisms();
    for (int32_t& g : s.generator) g += 10;
    for (int32_t& l : s.layer) l += 1;
    const TetFaceAdjacency adjacency = tet_face_adjacency(s.mesh);
    const LayerPrismCells cells = layer_prism_cells(s.mesh, adjacency, s.generator, s.layer, s.filler);
    EXPECT_EQ(cells.prisms, 2);
    EXPECT_EQ(cells.cells, 2);

    // Points of three layers (0, 1 and 2 in one prism) are no prism.
    TwoPrisms tall = two_prisms();
    tall.layer[7] = 2;
    const LayerPrismCells mixed = layer_prism_cells(tall.mesh, adjacency, tall.generator, tall.layer, tall.filler);
    EXPECT_EQ(mixed.prisms, 1);
    EXPECT_EQ(mixed.cells, 4);
}

TEST(LayerPrisms, PolyMeshWritesEachPrismAsOneCellAndTheirSharedQuadAsOneFace)
{
    const TwoPrisms s = two_prisms();
    const TetFaceAdjacency adjacency = tet_face_adjacency(s.mesh);
    const LayerPrismCells cells = layer_prism_cells(s.mesh, adjacency, s.generator, s.layer, s.filler);
    for (bool binary : {false, true}) {
        const TempDir dir;
        const PolyMeshCounts counts = write_polymesh(
            s.mesh, dir.path, {.binary = binary, .cell_of_tet = &cells.cell_of_tet, .cells = cells.cells});
        EXPECT_EQ(counts.cells, 2);
        EXPECT_EQ(counts.internal_faces, 1);
        EXPECT_EQ(counts.quad_faces, 1);
        EXPECT_EQ(counts.faces, 13);
        if (!openfoam_available()) continue;
        const CheckMeshFigures check = check_mesh(dir.path);
        EXPECT_TRUE(check.ok) << (binary ? "binary" : "ascii") << "\n" << check.log;
        EXPECT_EQ(check.cells, 2);
        EXPECT_NEAR(check.volume, 0.25, 1e-12);
        // Each prism's four outer side triangles keep it from matching
        // OpenFOAM's prism shape: two polyhedra of seven faces.
        EXPECT_NE(check.log.find("polyhedra:     2"), std::string::npos) << check.log;
    }
    // A cell of three tets that is not named a prism joins no quad.
    const std::vector<char> one_prism{1, 0};
    const TempDir apart;
    const PolyMeshCounts triangles = write_polymesh(
        s.mesh, apart.path,
        {.patch_types = {}, .cell_of_tet = &cells.cell_of_tet, .cells = cells.cells, .quad_cells = &one_prism});
    EXPECT_EQ(triangles.cells, 2);
    EXPECT_EQ(triangles.internal_faces, 2);
    EXPECT_EQ(triangles.quad_faces, 0);
    // The same mesh as tets: six cells, the quad as two triangles each way.
    const TempDir dir;
    const PolyMeshCounts tets = write_polymesh(s.mesh, dir.path);
    EXPECT_EQ(tets.cells, 6);
    EXPECT_EQ(tets.quad_faces, 0);
}

// openfoam_cell_checks measures as checkMesh does, also where the quad
// between two prisms is warped (its centre and area from OpenFOAM's fan,
// the prisms' centres from pyramids on their faces, not their tets'
// centroid): the largest angle agrees with checkMesh's, for the prisms and
// for the same mesh as tets.
TEST(LayerPrisms, OpenFoamOrthogonalityMatchesCheckMesh)
{
    TwoPrisms s = two_prisms();
    s.mesh.points[6] += Vec3{-0.15, 0.1, 0.12}; // the shared quad (0, 2, 6, 4) no longer planar
    s.mesh.points[4] += Vec3{0.05, 0.1, -0.05};
    for (const Tet& t : s.mesh.tets)
        ASSERT_GT(tet_volume6(s.mesh.points[t[0]], s.mesh.points[t[1]], s.mesh.points[t[2]], s.mesh.points[t[3]]), 0);
    const TetFaceAdjacency adjacency = tet_face_adjacency(s.mesh);
    const LayerPrismCells prisms = layer_prism_cells(s.mesh, adjacency, s.generator, s.layer, s.filler);
    ASSERT_EQ(prisms.prisms, 2);
    const LayerPrismCells tets = single_tets(s.mesh);
    for (const LayerPrismCells* cells : std::array<const LayerPrismCells*, 2>{&prisms, &tets}) {
        const OpenFoamCellChecks measured =
            openfoam_cell_checks(s.mesh, adjacency, cells->cell_of_tet, cells->cells, {.non_orthogonality_deg = 90.0});
        EXPECT_GT(measured.max_non_orthogonality_deg, 1.0); // warped: not a trivially orthogonal face
        EXPECT_TRUE(measured.grouped_cells_failing.empty());
        EXPECT_EQ(measured.flat_pyramids, 0);
        // A bound below the worst face names the prisms on it (never a single tet).
        const OpenFoamCellChecks strict =
            openfoam_cell_checks(s.mesh, adjacency, cells->cell_of_tet, cells->cells,
                                 {.non_orthogonality_deg = measured.max_non_orthogonality_deg - 1e-9});
        const std::vector<int32_t> named = cells == &prisms ? std::vector<int32_t>{0, 1} : std::vector<int32_t>{};
        EXPECT_EQ(strict.grouped_cells_failing, named);
        EXPECT_EQ(strict.faces_beyond_orthogonality, 1);
        EXPECT_EQ(strict.checkmesh_failures, 0);
        const TempDir dir;
        write_polymesh(s.mesh, dir.path, {.adjacency = &adjacency, .cell_of_tet = &cells->cell_of_tet, .cells = cells->cells});
        const CheckMeshFigures check = check_mesh(dir.path);
        ASSERT_TRUE(check.ok) << check.log;
        EXPECT_NEAR(check.max_non_orthogonality, measured.max_non_orthogonality_deg, 1e-5) << check.log; // 8 digits
        EXPECT_NEAR(check.max_skewness, measured.max_skewness, 1e-5) << check.log;
    }
}

// Cells of the tets of `cells`, with the cells in `split` split back into
// their tets: numbered in the order of their first tet.
LayerPrismCells split_back(const LayerPrismCells& cells, const std::vector<int32_t>& split)
{
    LayerPrismCells out;
    std::map<int32_t, int32_t> kept;
    for (int32_t c : cells.cell_of_tet) {
        if (std::find(split.begin(), split.end(), c) != split.end()) {
            out.cell_of_tet.push_back(out.cells++);
            continue;
        }
        const auto [it, fresh] = kept.try_emplace(c, out.cells);
        if (fresh) ++out.cells;
        out.cell_of_tet.push_back(it->second);
    }
    return out;
}

// The face-pyramid failure checkMesh reported on a vessel tree ("faces are
// incorrectly oriented" between a merged layer cell and its neighbour): two
// warped layer prisms, every tet positive and every face between two tets
// within 60 degrees of the join of their centroids, whose union
// OpenFOAM centres (from pyramids on its faces, the warped quad between the
// prisms taken whole) outside one of its faces. checkMesh fails the merged
// cells; openfoam_cell_checks names the prism, and with it split back into
// its tets checkMesh passes.
TEST(LayerPrisms, PrismWhoseOpenFoamCentreLiesOutsideAFaceIsFoundAndSplitBack)
{
    const TwoPrisms s = two_prisms({{0.11621999, 0.14607048, -0.07746752}, {0.91712014, 0.15770182, 0.04029919},
                                    {0.95263921, 0.90624627, -0.17436766}, {0.26316818, 1.14905971, -0.01775142},
                                    {0.086855, 0.04232155, 0.4349236}, {0.89937456, -0.15999199, 0.1852305},
                                    {1.03839946, 1.00394423, 0.24128058}, {-0.05165965, 0.88360688, 0.11714804}});
    for (const Tet& t : s.mesh.tets)
        ASSERT_GT(tet_volume6(s.mesh.points[t[0]], s.mesh.points[t[1]], s.mesh.points[t[2]], s.mesh.points[t[3]]), 0);
    const TetFaceAdjacency adjacency = tet_face_adjacency(s.mesh);
    LayerPrismCells merged;
    merged.cell_of_tet = {0, 0, 0, 1, 1, 1};
    merged.cells = 2;
    const OpenFoamCellChecks found = openfoam_cell_checks(s.mesh, adjacency, merged.cell_of_tet, merged.cells);
    EXPECT_LT(found.min_pyramid_height, 0);
    EXPECT_GE(found.flat_pyramids, 1);
    EXPECT_GE(found.checkmesh_failures, 1);
    ASSERT_FALSE(found.grouped_cells_failing.empty());
    EXPECT_LT(found.grouped_cells_failing.size(), 2u); // one prism is enough
    // The face pyramids find it: non-orthogonality alone (all the check was
    // before) passes these cells.
    const OpenFoamCellChecks orthogonality_only =
        openfoam_cell_checks(s.mesh, adjacency, merged.cell_of_tet, merged.cells,
                             {.skewness = 1e300, .pyramid_height = -1e300});
    EXPECT_TRUE(orthogonality_only.grouped_cells_failing.empty());
    {
        const TempDir dir;
        write_polymesh(s.mesh, dir.path, {.adjacency = &adjacency, .cell_of_tet = &merged.cell_of_tet, .cells = 2});
        const CheckMeshFigures check = check_mesh(dir.path);
        EXPECT_FALSE(check.ok) << check.log;
        EXPECT_NE(check.log.find("incorrectly oriented"), std::string::npos) << check.log;
    }
    // Split back as run_case does (checked_layer_prism_cells), round by
    // round: the other prism's faces change with the first one's split.
    LayerPrismCells split = merged;
    OpenFoamCellChecks after = found;
    for (int round = 0; round < 3 && !after.grouped_cells_failing.empty(); ++round) {
        split = split_back(split, after.grouped_cells_failing);
        after = openfoam_cell_checks(s.mesh, adjacency, split.cell_of_tet, split.cells);
    }
    EXPECT_TRUE(after.grouped_cells_failing.empty());
    EXPECT_EQ(after.checkmesh_failures, 0);
    EXPECT_GT(after.min_pyramid_height, 0);
    const TempDir dir;
    write_polymesh(s.mesh, dir.path, {.adjacency = &adjacency, .cell_of_tet = &split.cell_of_tet, .cells = split.cells});
    const CheckMeshFigures check = check_mesh(dir.path);
    EXPECT_TRUE(check.ok) << check.log;
    EXPECT_NEAR(check.max_skewness, after.max_skewness, 1e-5) << check.log;
}

// checked_layer_prism_cells splits exactly the prisms named, and ends when a
// round names none (or names only single tets).
TEST(LayerPrisms, CheckedCellsSplitOnlyThePrismsNamed)
{
    const TwoPrisms s = two_prisms();
    const TetFaceAdjacency adjacency = tet_face_adjacency(s.mesh);
    int rounds = 0;
    const LayerPrismCells one = checked_layer_prism_cells(
        s.mesh, adjacency, s.generator, s.layer, s.filler, 68.0, [&](const LayerPrismCells& cells) {
            ++rounds;
            // The first round names the second prism (cell 1), the next its tets.
            return rounds == 1 ? std::vector<int32_t>{1} : std::vector<int32_t>{cells.cells - 1};
        });
    EXPECT_EQ(rounds, 2);
    EXPECT_EQ(one.prisms, 1);
    EXPECT_EQ(one.cells, 4);
    EXPECT_EQ(one.cell_of_tet, (std::vector<int32_t>{0, 0, 0, 1, 2, 3}));
}

// The two prisms and a sliver on the first one's top (4, 5, 6): a core
// point (a filler) 0.002 above that triangle's centre, tet 6.
TwoPrisms prisms_and_sliver()
{
    TwoPrisms s = two_prisms();
    const auto& p = s.mesh.points;
    s.mesh.points.push_back((p[4] + p[5] + p[6]) / 3 + Vec3{0, 0, 0.002});
    s.generator.push_back(0), s.layer.push_back(2), s.filler.push_back(1);
    push_oriented(s.mesh, {4, 5, 6, 8});
    set_boundary(s.mesh);
    return s;
}

TEST(LayerPrisms, ASliverOnAPrismJoinsItAsOnePolyhedron)
{
    const TwoPrisms s = prisms_and_sliver();
    const auto& p = s.mesh.points;
    ASSERT_LT(tet_min_dihedral_deg(p[4], p[5], p[6], p[8]), 10.0);
    const TetFaceAdjacency adjacency = tet_face_adjacency(s.mesh);
    const LayerPrismCells found = layer_prism_cells(s.mesh, adjacency, s.generator, s.layer, s.filler);
    ASSERT_EQ(found.prisms, 2);
    ASSERT_EQ(found.cells, 3);

    LayerPrismCells cells = found;
    ChosenUnions chosen;
    EXPECT_EQ(absorb_poor_tets(s.mesh, adjacency, cells, PoorTetBounds{}, {}, &chosen), 1);
    EXPECT_EQ(cells.cells, 2);
    EXPECT_EQ(cells.absorbed, 1);
    EXPECT_EQ(cells.prisms, 1); // the prism that took the sliver is a polyhedron now
    EXPECT_EQ(cells.cell_of_tet, (std::vector<int32_t>{0, 0, 0, 1, 1, 1, 0}));
    EXPECT_EQ(cells.prism_cell, (std::vector<char>{0, 1}));
    EXPECT_EQ(chosen, (ChosenUnions{{6, TetUnion{0, -1, -1}}})); // the sliver's union, and no other

    const PolyMeshCounts counts = write_and_check(s.mesh, cells);
    EXPECT_EQ(counts.cells, 2);
    EXPECT_EQ(counts.quad_faces, 0); // no quad from a prism to a polyhedron

    // A union refused before is not made again, and none grows beyond
    // max_cell_tets: the sliver stays a cell of its own.
    LayerPrismCells again = found;
    const RefusedUnions refused{{6, {TetUnion{0, -1, -1}}}};
    EXPECT_EQ(absorb_poor_tets(s.mesh, adjacency, again, PoorTetBounds{}, refused), 0);
    EXPECT_EQ(again.cells, 3);
    EXPECT_EQ(again.prisms, 2);
    LayerPrismCells small = found;
    EXPECT_EQ(absorb_poor_tets(s.mesh, adjacency, small, PoorTetBounds{.max_cell_tets = 3}), 0);
    EXPECT_EQ(small.cells, 3);

    // A sound tet is no candidate: with floors of 0 and 90 degrees and no
    // least interpolation weight or determinant nothing joins (the sliver,
    // with one internal face, has no determinant).
    LayerPrismCells sound = found;
    EXPECT_EQ(absorb_poor_tets(s.mesh, adjacency, sound,
                               PoorTetBounds{.min_aspect_ratio = 0, .min_dihedral_deg = 0,
                                             .max_non_orthogonality_deg = 90, .min_weight = 0,
                                             .min_determinant = 0}),
              0);
}

// A sliver in the crease of the two prisms' top: points 5 and 7 raised by
// 0.002 make the top a shallow valley along the diagonal 4-6, which tet
// (4, 5, 6, 7) fills; its two lower faces lie on the two prisms.
TEST(LayerPrisms, ASliverOnTwoPrismsJoinsBothWhereNeitherAloneSeesIt)
{
    const double z = 0.25, e = 0.002;
    TwoPrisms s = two_prisms({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, z}, {1, 0, z + e}, {1, 1, z},
                              {0, 1, z + e}});
    const auto& p = s.mesh.points;
    push_oriented(s.mesh, {4, 5, 6, 7});
    set_boundary(s.mesh);
    ASSERT_LT(tet_min_dihedral_deg(p[4], p[5], p[6], p[7]), 10.0);
    const TetFaceAdjacency adjacency = tet_face_adjacency(s.mesh);
    const LayerPrismCells found = layer_prism_cells(s.mesh, adjacency, s.generator, s.layer, s.filler);
    ASSERT_EQ(found.prisms, 2);
    ASSERT_EQ(found.cells, 3);

    // Within six tets neither prism may take it (its face on the other
    // prism would face away from the union's centre), nor both.
    LayerPrismCells six = found;
    EXPECT_EQ(absorb_poor_tets(s.mesh, adjacency, six, PoorTetBounds{.max_cell_tets = 6}), 0);
    EXPECT_EQ(six.cells, 3);

    // Within seven (the default), both together.
    LayerPrismCells seven = found;
    ChosenUnions chosen;
    EXPECT_EQ(absorb_poor_tets(s.mesh, adjacency, seven, PoorTetBounds{}, {}, &chosen), 1);
    EXPECT_EQ(seven.cells, 1);
    EXPECT_EQ(seven.prisms, 0);
    EXPECT_EQ(seven.absorbed, 1);
    EXPECT_EQ(seven.cell_of_tet, std::vector<int32_t>(7, 0));
    EXPECT_EQ(chosen, (ChosenUnions{{6, TetUnion{0, 3, -1}}})); // the lowest tet of each prism, ascending
}

// A tet split at a point P just inside its face (1, 2, 3): tet (P, 1, 2, 3)
// is a sliver, and the three others are its neighbours. Joined with all
// three it would hold every tet at P, which would lie inside the cell on
// no face; at most two of them may take it.
TEST(LayerPrisms, NoUnionSwallowsAPoint)
{
    TetMesh mesh;
    mesh.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0.32, 0.32, 0.32}};
    for (const Tet& t : {Tet{4, 1, 2, 3}, Tet{0, 4, 2, 3}, Tet{0, 1, 4, 3}, Tet{0, 1, 2, 4}}) push_oriented(mesh, t);
    set_boundary(mesh);
    const auto& p = mesh.points;
    ASSERT_LT(tet_min_dihedral_deg(p[4], p[1], p[2], p[3]), 10.0);
    const TetFaceAdjacency adjacency = tet_face_adjacency(mesh);
    LayerPrismCells cells = single_tets(mesh);
    cells.prism_cell.assign(4, 0);
    absorb_poor_tets(mesh, adjacency, cells, PoorTetBounds{.max_non_orthogonality_deg = 90});
    EXPECT_GE(cells.cells, 2);
    EXPECT_EQ(write_and_check(mesh, cells).cells, cells.cells);
}

TEST(LayerPrisms, CheckedCellsGiveAnAbsorbedTetBackWhereTheUnionFails)
{
    const TwoPrisms s = prisms_and_sliver();
    const TetFaceAdjacency adjacency = tet_face_adjacency(s.mesh);
    const PoorTetBounds poor;
    int rounds = 0;
    const LayerPrismCells cells = checked_layer_prism_cells(
        s.mesh, adjacency, s.generator, s.layer, s.filler, 68.0,
        [&](const LayerPrismCells& c) {
            // The first round names the cell that took the sliver.
            return ++rounds == 1 ? std::vector<int32_t>{c.cell_of_tet[6]} : std::vector<int32_t>{};
        },
        &poor);
    EXPECT_EQ(rounds, 2);
    EXPECT_EQ(cells.prisms, 2); // given back, not split
    EXPECT_EQ(cells.absorbed, 0);
    EXPECT_EQ(cells.cells, 3);
    EXPECT_EQ(cells.cell_of_tet, (std::vector<int32_t>{0, 0, 0, 1, 1, 1, 2}));
}

} // namespace
} // namespace scalemesh
