// Reading .vdb files: grids round-trip with their transform and class,
// integer grids convert, and every bad file is refused with an InputError or
// IoError, never a crash.

#include "core/errors.h"
#include "importers/vdb_importer.h"
#include "isosurface/marching_cubes.h"
#include "phantom/phantom.h"

#include "support/temp_dir.h"

#include <gtest/gtest.h>
#include <openvdb/io/File.h>

#include <cstring>
#include <fstream>
#include <random>

namespace scalemesh {
namespace {

TEST(VdbImporter, RoundTripsAPhantomWithItsTransform)
{
    const TempDir s;
    const auto grid = voxelize(*make_shape("torus", 0.4), {.voxel_size = 0.4});
    write_vdb(*grid, s.path / "torus.vdb");
    const auto back = read_vdb(s.path / "torus.vdb");
    EXPECT_EQ(back->getName(), "label");
    EXPECT_EQ(back->getGridClass(), openvdb::GRID_FOG_VOLUME);
    EXPECT_DOUBLE_EQ(back->voxelSize().x(), 0.4);
    EXPECT_EQ(back->transform(), grid->transform());
    EXPECT_EQ(back->activeVoxelCount(), grid->activeVoxelCount());
    for (auto it = grid->cbeginValueOn(); it; ++it) {
        if (it.isVoxelValue()) {
            ASSERT_EQ(back->tree().getValue(it.getCoord()), *it);
        }
    }
    // The surface of the re-read grid is the same surface.
    EXPECT_EQ(marching_cubes(*back).triangles.size(), marching_cubes(*grid).triangles.size());
}

TEST(VdbImporter, PicksTheNamedGridAndConvertsIntegerLabels)
{
    const TempDir s;
    openvdb::initialize();
    auto vector_grid = openvdb::Vec3SGrid::create();
    vector_grid->setName("velocity");
    auto labels = openvdb::Int32Grid::create(0);
    labels->setName("labels");
    labels->setTransform(openvdb::math::Transform::createLinearTransform(2.0));
    for (int x = 0; x < 3; ++x) labels->tree().setValueOn({x, 0, 0}, 4);
    auto other = openvdb::FloatGrid::create(0.0f);
    other->setName("other");
    other->tree().setValueOn({5, 5, 5}, 1.0f);
    openvdb::io::File file((s.path / "multi.vdb").string());
    file.write({vector_grid, labels, other});
    file.close();

    const auto first = read_vdb(s.path / "multi.vdb"); // the first scalar grid, skipping the vector grid
    EXPECT_EQ(first->getName(), "labels");
    EXPECT_EQ(first->tree().getValue({1, 0, 0}), 4.0f);
    EXPECT_DOUBLE_EQ(first->voxelSize().x(), 2.0);
    EXPECT_EQ(read_vdb(s.path / "multi.vdb", {"other"})->getName(), "other");
    EXPECT_THROW(read_vdb(s.path / "multi.vdb", {"velocity"}), InputError);
    try {
        read_vdb(s.path / "multi.vdb", {"density"});
        FAIL() << "a missing grid must be refused";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("'labels'"), std::string::npos) << "lists the grids: " << e.what();
    }
}

TEST(VdbImporter, ReadsLevelSetsAsLevelSets)
{
    const TempDir s;
    auto ls = openvdb::FloatGrid::create(3.0f);
    ls->setGridClass(openvdb::GRID_LEVEL_SET);
    ls->setName("surface");
    for (int x = -6; x <= 6; ++x)
        for (int y = -6; y <= 6; ++y)
            for (int z = -6; z <= 6; ++z) {
                const float d = std::sqrt(float(x * x + y * y + z * z)) - 4.0f;
                if (std::abs(d) < 3.0f) ls->tree().setValueOn({x, y, z}, d);
                else if (d < 0) ls->tree().setValueOff({x, y, z}, -3.0f);
            }
    write_vdb(*ls, s.path / "ls.vdb");
    const auto back = read_vdb(s.path / "ls.vdb");
    EXPECT_TRUE(is_level_set(*back));
    const SurfaceMesh mesh = marching_cubes(*back);
    EXPECT_TRUE(surface_facts(mesh).closed_manifold());
    for (const Vec3& p : mesh.points) EXPECT_NEAR(norm(p), 4.0, 0.1);
}

TEST(VdbImporter, RefusesMissingCorruptAndEmptyFiles)
{
    const TempDir s;
    EXPECT_THROW(read_vdb(s.path / "missing.vdb"), IoError);
    std::ofstream(s.path / "text.vdb") << "hello";
    EXPECT_THROW(read_vdb(s.path / "text.vdb"), InputError);
    std::ofstream(s.path / "zero.vdb");
    EXPECT_THROW(read_vdb(s.path / "zero.vdb"), InputError);

    const auto grid = voxelize(*make_shape("sphere", 0.5), {.voxel_size = 0.5});
    write_vdb(*grid, s.path / "good.vdb");
    std::ifstream in(s.path / "good.vdb", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // A file cut short anywhere is refused, never read as a smaller grid.
    std::mt19937 rng(3);
    for (int trial = 0; trial < 60; ++trial) {
        const size_t length = trial < 8 ? static_cast<size_t>(trial) : rng() % bytes.size();
        std::ofstream(s.path / "broken.vdb", std::ios::binary) << bytes.substr(0, length);
        EXPECT_THROW(read_vdb(s.path / "broken.vdb"), InputError) << "cut at " << length << " of " << bytes.size();
    }

    auto empty = openvdb::FloatGrid::create(0.0f);
    write_vdb(*empty, s.path / "empty.vdb");
    EXPECT_THROW(read_vdb(s.path / "empty.vdb"), InputError);
}

uint32_t u32_at(const std::string& bytes, size_t at)
{
    uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4);
    return v;
}

template <typename T>
std::string with_value_at(std::string bytes, size_t at, T value)
{
    std::memcpy(bytes.data() + at, &value, sizeof(T));
    return bytes;
}

// OpenVDB 10 trusts the lengths and offsets in a file: a grid name of length
// 2^31 made it allocate and clear 2 GB (found by fuzzing). read_vdb walks the
// header, the descriptors and each grid's metadata first.
TEST(VdbImporter, RefusesLengthsAndOffsetsBeyondTheFile)
{
    const TempDir s;
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("label");
    for (int x = 0; x < 3; ++x) grid->tree().setValueOn({x, 0, 0}, 1.0f);
    write_vdb(*grid, s.path / "good.vdb");
    std::ifstream in(s.path / "good.vdb", std::ios::binary);
    const std::string good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_NO_THROW(read_vdb(s.path / "good.vdb"));

    // Magic, versions, offsets flag and UUID take 57 bytes; then the file's
    // metadata (no items), the grid count, and the first descriptor: name,
    // type and instance parent as length and characters, then three offsets.
    ASSERT_EQ(u32_at(good, 57), 0u);
    const size_t name_at = 65;
    size_t at = name_at;
    for (int string = 0; string < 3; ++string) at += 4 + u32_at(good, at);
    const size_t offsets_at = at;
    int64_t grid_pos = 0;
    std::memcpy(&grid_pos, good.data() + offsets_at, 8);

    const auto expect_refused = [&](const std::string& bytes, const std::string& mentions) {
        std::ofstream(s.path / "bad.vdb", std::ios::binary) << bytes;
        try {
            read_vdb(s.path / "bad.vdb");
            ADD_FAILURE() << "read: " << mentions;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(mentions), std::string::npos) << e.what();
        }
    };
    expect_refused(with_value_at(good, name_at, uint32_t{1} << 31), "name of grid 1 is 2147483648 characters long");
    expect_refused(with_value_at(good, 61, int32_t{1000000}), "a grid count of 1000000");
    expect_refused(with_value_at(good, offsets_at + 16, static_cast<int64_t>(good.size()) + 1),
                   "ends past the end of the file");
    expect_refused(with_value_at(good, offsets_at + 8, grid_pos - 1), "out of order");
    // The grid's metadata: compression flags, then the item count.
    expect_refused(with_value_at(good, static_cast<size_t>(grid_pos) + 4, uint32_t{0xffffffff}),
                   "with 4294967295 items");
    expect_refused(with_value_at(good, static_cast<size_t>(grid_pos), uint32_t{64}), "unknown compression flags 64");
}

TEST(VdbImporter, WriteLeavesNoFileWhenTheDirectoryIsMissing)
{
    const TempDir s;
    const auto grid = voxelize(*make_shape("sphere", 1.0), {.voxel_size = 1.0});
    EXPECT_THROW(write_vdb(*grid, s.path / "no" / "such.vdb"), IoError);
    EXPECT_TRUE(std::filesystem::is_empty(s.path));
}

} // namespace
} // namespace scalemesh
