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

#include <cmath>
#include <cstring>
#include <limits>
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

// Writes `bytes` to `file` and expects read_vdb to refuse it with a message
// that mentions `mentions`.
void expect_refused_as(const std::filesystem::path& file, const std::string& bytes, const std::string& mentions)
{
    std::ofstream(file, std::ios::binary) << bytes;
    try {
        read_vdb(file);
        ADD_FAILURE() << "read: " << mentions;
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(mentions), std::string::npos) << e.what();
    }
}

// OpenVDB 10 trusts the lengths and offsets in a file: a grid name of length
// 2^31 made it allocate and clear 2 GB (found by fuzzing). read_vdb walks the
// header, the descriptors and each grid's metadata first.
// A NaN voxel would be outside at any iso value: a cavity of one voxel that
// nobody segmented. It is refused, named by its voxel, active or not.
TEST(VdbImporter, RefusesNaNAndInfiniteValues)
{
    const TempDir s;
    for (const bool active : {true, false}) {
        const auto grid = voxelize(*make_shape("sphere", 0.5), {.voxel_size = 0.5});
        const openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
        const openvdb::Coord centre = (box.min() + box.max()) >> 1;
        if (active)
            grid->tree().setValueOn(centre, std::nanf(""));
        else
            grid->tree().setValueOff(centre, std::numeric_limits<float>::infinity());
        write_vdb(*grid, s.path / "nan.vdb");
        try {
            read_vdb(s.path / "nan.vdb");
            ADD_FAILURE() << "a grid with a NaN or infinite value was read";
        } catch (const InputError& e) {
            const std::string expected = "has 1 NaN or infinite voxel values, the first at voxel (" +
                                         std::to_string(centre.x()) + ", " + std::to_string(centre.y()) + ", " +
                                         std::to_string(centre.z()) + ")";
            EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
        }
    }
}

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
        expect_refused_as(s.path / "bad.vdb", bytes, mentions);
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

// read_vdb walks the tree of the grid it reads as OpenVDB does and needs it
// to end exactly at the grid's end offset; a walk that misplaced one field
// would refuse these files.
TEST(VdbImporter, ReadsTreesOfEveryScalarTypeAndCompression)
{
    const TempDir s;
    openvdb::initialize();
    // Two whole leaves partly active with two inactive values each (of both
    // signs for the level set), which mask compression stores with a
    // selection mask and, where neither is the background, both values; a
    // third leaf partly filled; a tile in a lower node and one at the root.
    const auto fill = [](auto& tree, auto inside, auto outside, auto active) {
        for (int x = -8; x < 10; ++x)
            for (int y = 0; y < 8; ++y)
                for (int z = 0; z < 8; ++z) {
                    if ((x + y + z) % 3 == 0) tree.setValueOn({x, y, z}, active);
                    else tree.setValueOff({x, y, z}, (x < 0) != (y == 4) ? inside : outside);
                }
        tree.addTile(1, {256, 0, 0}, active, true);
        tree.addTile(3, {8192, 0, 0}, active, true);
    };
    auto level_set = openvdb::FloatGrid::create(3.0f);
    level_set->setGridClass(openvdb::GRID_LEVEL_SET);
    fill(level_set->tree(), -3.0f, 3.0f, 0.5f);
    auto doubles = openvdb::DoubleGrid::create(0.0);
    fill(doubles->tree(), -1.0, 0.0, 2.0);
    auto int32 = openvdb::Int32Grid::create(0);
    fill(int32->tree(), 5, 7, 4); // two inactive values, neither the background
    auto int64 = openvdb::Int64Grid::create(0);
    fill(int64->tree(), 5, 0, int64_t{1} << 40);
    auto bools = openvdb::BoolGrid::create(false);
    fill(bools->tree(), true, false, true);
    const std::vector<openvdb::GridBase::Ptr> grids{level_set, doubles, int32, int64, bools};

    using namespace openvdb::io;
    for (const uint32_t compression :
         std::initializer_list<uint32_t>{COMPRESS_NONE, COMPRESS_ZIP, COMPRESS_ACTIVE_MASK,
                                         COMPRESS_ZIP | COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC,
                                         COMPRESS_BLOSC | COMPRESS_ACTIVE_MASK}) {
        for (const bool half : {false, true}) {
            for (const auto& grid : grids) {
                grid->setName("g");
                grid->setSaveFloatAsHalf(half);
                const auto file_name = s.path / ("c" + std::to_string(compression) + grid->type() + ".vdb");
                File file(file_name.string());
                file.setCompression(compression);
                file.write({grid});
                file.close();
                const std::string what = grid->type() + ", compression " + compressionToString(compression) +
                                         (half ? ", half" : "");
                openvdb::FloatGrid::Ptr back;
                ASSERT_NO_THROW(back = read_vdb(file_name)) << what;
                EXPECT_EQ(back->tree().activeVoxelCount(), grid->baseTree().activeVoxelCount()) << what;
                EXPECT_EQ(back->tree().leafCount(), grid->baseTree().leafCount()) << what;
            }
        }
    }
}

// A buffer's stated size, a node count or a blosc header that does not fit
// the file is refused before OpenVDB allocates it (found by fuzzing: a
// leaf's blosc size made OpenVDB allocate whatever it said).
TEST(VdbImporter, RefusesTreeCountsAndBufferSizesBeyondTheFile)
{
    const TempDir s;
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("label");
    grid->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
    for (int x = 0; x < 8; ++x)
        for (int y = 0; y < 8; ++y)
            for (int z = 0; z < 8; ++z) grid->tree().setValueOn({x, y, z}, float(x + y * z));
    write_vdb(*grid, s.path / "good.vdb"); // blosc with mask compression, as OpenVDB writes by default
    std::ifstream in(s.path / "good.vdb", std::ios::binary);
    const std::string good((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_NO_THROW(read_vdb(s.path / "good.vdb"));

    const auto expect_refused = [&](const std::string& bytes, const std::string& mentions) {
        expect_refused_as(s.path / "bad.vdb", bytes, mentions);
    };

    // The tree follows the transform: its map type, then 5 vectors of 3
    // doubles; then a buffer count, the background, the tile and child counts.
    const std::string map = "UniformScaleMap";
    const size_t map_at = good.find(map);
    ASSERT_NE(map_at, std::string::npos);
    const size_t tree_at = map_at + map.size() + 5 * 24;
    ASSERT_EQ(u32_at(good, tree_at + 8), 0u) << "no tiles";
    ASSERT_EQ(u32_at(good, tree_at + 12), 1u) << "one child";
    expect_refused(with_value_at(good, tree_at + 8, uint32_t{1} << 30), "counts 1073741824 tiles");
    expect_refused(with_value_at(good, tree_at + 12, uint32_t{70000}), "counts 70000 children");

    // The one leaf's values come last: a signed size, then that many bytes.
    size_t size_at = 0;
    for (size_t n = 16; n + 8 < good.size() && !size_at; ++n) {
        int64_t stated = 0;
        std::memcpy(&stated, good.data() + good.size() - n - 8, 8);
        if (stated == static_cast<int64_t>(n)) size_at = good.size() - n - 8;
    }
    ASSERT_NE(size_at, 0u) << "the leaf's blosc buffer";
    expect_refused(with_value_at(good, size_at, int64_t{1} << 40), "compressed in 1099511627776 bytes");
    expect_refused(with_value_at(good, size_at, int64_t{-4096}), "stored raw in 4096 bytes instead of 2048");
    // Its blosc header: the uncompressed size at byte 4, the compressed at 12.
    expect_refused(with_value_at(good, size_at + 8 + 4, uint32_t{1} << 30), "1073741824 uncompressed");
    expect_refused(with_value_at(good, size_at + 8 + 12, uint32_t{1} << 20), "says 1048576 bytes");
    // Bytes after the tree that the grid's end offset includes: the third
    // offset after the descriptor's name, type and instance parent.
    size_t offsets_at = 65;
    for (int string = 0; string < 3; ++string) offsets_at += 4 + u32_at(good, offsets_at);
    expect_refused(with_value_at(good + "more", offsets_at + 16, static_cast<int64_t>(good.size() + 4)),
                   "ends 4 bytes before the grid's end offset");
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
