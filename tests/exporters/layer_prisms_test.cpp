// Layer prisms as cells: layer_prism_cells finds the three tets that fill a
// layer prism, and the polyMesh writer makes each such group one cell, with
// the quad between two prisms one face; checkMesh accepts the result.

#include "core/tet_mesh.h"
#include "exporters/polymesh_writer.h"
#include "openfoam_support.h"
#include "volume/layer_prisms.h"

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

TwoPrisms two_prisms()
{
    TwoPrisms s;
    const double z = 0.25;
    s.mesh.points = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, z}, {1, 0, z}, {1, 1, z}, {0, 1, z}};
    s.generator = {0, 1, 2, 3, 0, 1, 2, 3};
    s.layer = {0, 0, 0, 0, 1, 1, 1, 1};
    s.filler.assign(8, 0);
    for (std::array<int32_t, 3> wall : {std::array<int32_t, 3>{0, 1, 2}, {0, 2, 3}}) {
        std::sort(wall.begin(), wall.end());
        const int32_t a = wall[0], b = wall[1], c = wall[2];
        for (Tet t : {Tet{a, b, c, c + 4}, Tet{a, b, b + 4, c + 4}, Tet{a, a + 4, b + 4, c + 4}}) {
            const auto& p = s.mesh.points;
            if (tet_volume6(p[t[0]], p[t[1]], p[t[2]], p[t[3]]) < 0) std::swap(t[0], t[1]);
            s.mesh.tets.push_back(t);
        }
    }
    std::map<std::array<int32_t, 3>, std::pair<int, Triangle>> faces;
    for (const Tet& t : s.mesh.tets)
        for (int k = 0; k < 4; ++k) {
            const Triangle f = tet_face(t, k);
            std::array<int32_t, 3> key = f;
            std::sort(key.begin(), key.end());
            auto& [count, face] = faces[key];
            ++count;
            face = f;
        }
    for (const auto& [key, entry] : faces)
        if (entry.first == 1) s.mesh.boundary_faces.push_back(entry.second);
    return s;
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
    // The same mesh as tets: six cells, the quad as two triangles each way.
    const TempDir dir;
    const PolyMeshCounts tets = write_polymesh(s.mesh, dir.path);
    EXPECT_EQ(tets.cells, 6);
    EXPECT_EQ(tets.quad_faces, 0);
}

// openfoam_orthogonality measures as checkMesh does, also where the quad
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
    LayerPrismCells tets;
    for (size_t t = 0; t < s.mesh.tets.size(); ++t) tets.cell_of_tet.push_back(static_cast<int32_t>(t));
    tets.cells = static_cast<int32_t>(s.mesh.tets.size());
    for (const LayerPrismCells* cells : std::array<const LayerPrismCells*, 2>{&prisms, &tets}) {
        const OpenFoamOrthogonality measured =
            openfoam_orthogonality(s.mesh, adjacency, cells->cell_of_tet, cells->cells, 90.0);
        EXPECT_GT(measured.max_deg, 1.0); // warped: not a trivially orthogonal face
        EXPECT_TRUE(measured.grouped_cells_beyond.empty());
        // A bound below the worst face names the prisms on it (never a single tet).
        const OpenFoamOrthogonality strict = openfoam_orthogonality(s.mesh, adjacency, cells->cell_of_tet, cells->cells,
                                                                    measured.max_deg - 1e-9);
        const std::vector<int32_t> named = cells == &prisms ? std::vector<int32_t>{0, 1} : std::vector<int32_t>{};
        EXPECT_EQ(strict.grouped_cells_beyond, named);
        if (!openfoam_available()) continue;
        const TempDir dir;
        write_polymesh(s.mesh, dir.path, {.adjacency = &adjacency, .cell_of_tet = &cells->cell_of_tet, .cells = cells->cells});
        const CheckMeshFigures check = check_mesh(dir.path);
        ASSERT_TRUE(check.ok) << check.log;
        EXPECT_NEAR(check.max_non_orthogonality, measured.max_deg, 1e-5) << check.log; // checkMesh prints 8 digits
    }
}

} // namespace
} // namespace scalemesh
