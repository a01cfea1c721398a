// The processor meshes write_decomposed_polymesh writes, read back: every
// serial cell in one piece, every serial face in one piece as it is and,
// between two pieces, flipped on the other side at the same place of the
// two processor patches, as reconstructPar expects.

#include "exporters/polymesh_decompose.h"

#include "core/errors.h"
#include "polymesh_files.h"
#include "support/temp_dir.h"
#include "tet_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <numeric>
#include <random>
#include <sstream>

namespace scalemesh {
namespace {

struct Serial {
    TetMesh mesh = box_of_cubes(4, 3, 5);
    PolyMeshFaces faces;
    PolyMeshCounts counts;
    std::vector<std::string> names{"wall", "bottom", "top"}, types{"wall", "patch", "patch"};
};

Serial serial_box(const std::filesystem::path& dir)
{
    Serial s;
    s.counts = write_polymesh(s.mesh, dir, {.patch_types = s.types, .faces = &s.faces});
    return s;
}

TEST(DecomposedPolyMesh, PiecesHoldEveryCellOnceAndShareFacesFlippedInTheSameOrder)
{
    const TempDir dir;
    const Serial s = serial_box(dir.path);
    constexpr int32_t kPieces = 3;
    const DecomposeCounts counts = write_decomposed_polymesh(
        s.mesh.points, s.faces, s.counts.patch_faces, dir.path,
        {.processors = kPieces, .patch_names = s.names, .patch_types = s.types});
    ASSERT_EQ(counts.cells.size(), static_cast<size_t>(kPieces));

    const size_t n_faces = s.faces.owner.size(), internal = s.faces.neighbour.size();
    std::vector<int> cell_seen(static_cast<size_t>(s.counts.cells), 0), face_kept(n_faces, 0), face_flipped(n_faces, 0);
    // Per (piece, neighbour): the signed serial faces of its processor patch.
    std::map<std::pair<int, int>, std::vector<int64_t>> shared;
    for (int p = 0; p < kPieces; ++p) {
        const std::filesystem::path mesh = dir.path / ("processor" + std::to_string(p)) / "constant" / "polyMesh";
        const std::vector<int64_t> cells = read_label_list(mesh / "cellProcAddressing");
        const std::vector<int64_t> faces = read_label_list(mesh / "faceProcAddressing");
        const std::vector<int64_t> points = read_label_list(mesh / "pointProcAddressing");
        const std::vector<int64_t> owner = read_label_list(mesh / "owner"), neighbour = read_label_list(mesh / "neighbour");
        const std::vector<std::vector<int32_t>> local = read_face_list(mesh / "faces");
        const std::vector<BoundaryPatch> patches = read_boundary(mesh / "boundary");
        const std::vector<int64_t> patch_of = read_label_list(mesh / "boundaryProcAddressing");
        EXPECT_EQ(static_cast<int64_t>(cells.size()), counts.cells[p]);
        EXPECT_TRUE(std::is_sorted(cells.begin(), cells.end()));
        EXPECT_TRUE(std::is_sorted(points.begin(), points.end()));
        for (int64_t c : cells) ++cell_seen[c];
        ASSERT_EQ(faces.size(), local.size());
        ASSERT_EQ(owner.size(), local.size());

        // The internal faces first, in upper-triangular order.
        for (size_t f = 0; f < neighbour.size(); ++f) {
            EXPECT_LT(owner[f], neighbour[f]);
            EXPECT_LE(owner[f > 0 ? f - 1 : 0], owner[f]);
        }
        for (size_t f = 0; f < faces.size(); ++f) {
            const int64_t g = std::abs(faces[f]) - 1;
            const bool kept = faces[f] > 0;
            ++(kept ? face_kept : face_flipped)[g];
            // The face's points, through pointProcAddressing, are the serial
            // face's, or its reverse with the first point kept.
            std::vector<int32_t> expected(s.faces.points.begin() + s.faces.offsets[g],
                                          s.faces.points.begin() + s.faces.offsets[g + 1]);
            if (!kept) std::reverse(expected.begin() + 1, expected.end());
            std::vector<int32_t> got;
            for (int32_t q : local[f]) got.push_back(static_cast<int32_t>(points[q]));
            EXPECT_EQ(got, expected) << "processor " << p << " face " << f;
            EXPECT_EQ(cells[owner[f]], kept ? s.faces.owner[g] : s.faces.neighbour[g]);
            if (f < neighbour.size()) {
                EXPECT_EQ(cells[neighbour[f]], s.faces.neighbour[g]);
            }
        }
        // The serial patches in order, then the processor patches.
        ASSERT_EQ(patches.size(), patch_of.size());
        ASSERT_GE(patches.size(), s.names.size());
        int64_t start = static_cast<int64_t>(neighbour.size());
        for (size_t q = 0; q < patches.size(); ++q) {
            EXPECT_EQ(patches[q].start, start);
            const bool serial = q < s.names.size();
            EXPECT_EQ(patch_of[q], serial ? static_cast<int64_t>(q) : -1);
            if (serial) {
                EXPECT_EQ(patches[q].name, s.names[q]);
            } else {
                EXPECT_EQ(patches[q].name, "procBoundary" + std::to_string(p) + "to" + std::to_string(patches[q].neighbour));
                shared[{p, static_cast<int>(patches[q].neighbour)}] =
                    std::vector<int64_t>(faces.begin() + start, faces.begin() + start + patches[q].faces);
            }
            start += patches[q].faces;
        }
        EXPECT_EQ(start, static_cast<int64_t>(local.size()));
    }
    for (size_t c = 0; c < cell_seen.size(); ++c) EXPECT_EQ(cell_seen[c], 1) << "cell " << c;
    int64_t flipped = 0;
    for (size_t f = 0; f < n_faces; ++f) {
        EXPECT_EQ(face_kept[f], 1) << "face " << f;
        EXPECT_LE(face_flipped[f], f < internal ? 1 : 0) << "face " << f;
        flipped += face_flipped[f];
    }
    EXPECT_EQ(flipped, counts.processor_faces);
    EXPECT_GT(counts.processor_faces, 0);
    // Each processor patch face for face the negative of its neighbour's.
    for (const auto& [pair, list] : shared) {
        const auto back = shared.find({pair.second, pair.first});
        ASSERT_NE(back, shared.end());
        ASSERT_EQ(back->second.size(), list.size());
        for (size_t i = 0; i < list.size(); ++i) EXPECT_EQ(back->second[i], -list[i]);
    }
    EXPECT_EQ(counts.processor_patches, static_cast<int64_t>(shared.size() / 2));

    // The partition, for decomposePar's method manual.
    const std::vector<int64_t> part = read_label_list(dir.path / "constant" / "cellDecomposition");
    EXPECT_EQ(part.size(), cell_seen.size());
    std::ifstream dict(dir.path / "system" / "decomposeParDict");
    std::stringstream text;
    text << dict.rdbuf();
    EXPECT_NE(text.str().find("numberOfSubdomains 3;"), std::string::npos);
    EXPECT_NE(text.str().find("method          manual;"), std::string::npos);
}

TEST(DecomposedPolyMesh, RefusesFewerThanOneOrMorePiecesThanCellsAndWritesNothing)
{
    const TempDir dir;
    const Serial s = serial_box(dir.path);
    for (const int32_t pieces : {0, -1, static_cast<int32_t>(s.counts.cells) + 1})
        EXPECT_THROW(write_decomposed_polymesh(s.mesh.points, s.faces, s.counts.patch_faces, dir.path,
                                               {.processors = pieces, .patch_names = s.names, .patch_types = s.types}),
                     InputError)
            << pieces;
    EXPECT_FALSE(std::filesystem::exists(dir.path / "processor0"));
    EXPECT_FALSE(std::filesystem::exists(dir.path / "system" / "decomposeParDict"));
}

TEST(BisectCells, CutsAcrossTheLongestSideIntoPartsOfNearlyEqualSize)
{
    // Points along a 10 x 1 x 1 bar, in shuffled order.
    std::vector<Vec3> centres;
    std::mt19937 random(7);
    std::uniform_real_distribution<double> along(0, 10), across(0, 1);
    for (int i = 0; i < 1001; ++i) centres.push_back({along(random), across(random), across(random)});
    const std::vector<int32_t> halves = bisect_cells(centres, 2);
    double low_max = -1, high_min = 11;
    for (size_t i = 0; i < centres.size(); ++i)
        (halves[i] == 0 ? low_max : high_min) =
            halves[i] == 0 ? std::max(low_max, centres[i].x) : std::min(high_min, centres[i].x);
    EXPECT_LT(low_max, high_min);
    for (const int32_t parts : {1, 3, 7, 1001}) {
        const std::vector<int32_t> part = bisect_cells(centres, parts);
        std::vector<int64_t> size(static_cast<size_t>(parts), 0);
        for (int32_t p : part) {
            ASSERT_GE(p, 0);
            ASSERT_LT(p, parts);
            ++size[p];
        }
        const auto [least, most] = std::minmax_element(size.begin(), size.end());
        EXPECT_GE(*least, 1) << parts;
        EXPECT_LE(*most - *least, 2) << parts; // floor at each cut, one cut per level
        EXPECT_EQ(bisect_cells(centres, parts), part) << parts;
    }
    EXPECT_THROW(bisect_cells(centres, 1002), InputError);
    EXPECT_THROW(bisect_cells(centres, 0), InputError);
}

} // namespace
} // namespace scalemesh
