#include "importers/vdb_importer.h"

#include "core/atomic_file.h"
#include "core/errors.h"

#include <openvdb/io/DelayedLoadMetadata.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/ValueTransformer.h>

#include <cctype>
#include <cstring>
#include <fstream>
#include <limits>
#include <mutex>
#include <string_view>

namespace scalemesh {

namespace {

std::once_flag g_openvdb_init;

void initialize_openvdb() { std::call_once(g_openvdb_init, [] { openvdb::initialize(); }); }

// A float copy of any scalar grid, keeping name, class, transform and metadata.
template <typename GridT>
openvdb::FloatGrid::Ptr to_float(const GridT& in)
{
    auto out = openvdb::FloatGrid::create(static_cast<float>(in.background()));
    out->setTransform(in.transform().copy());
    out->setName(in.getName());
    out->setGridClass(in.getGridClass());
    out->tree().topologyUnion(in.tree());
    // Copy voxel and tile values.
    openvdb::tools::foreach(out->beginValueAll(), [&in](const openvdb::FloatGrid::ValueAllIter& it) {
        it.setValue(static_cast<float>(in.tree().getValue(it.getCoord())));
    });
    return out;
}

openvdb::FloatGrid::Ptr as_float_grid(const openvdb::GridBase::Ptr& base)
{
    if (auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(base)) return g;
    if (auto g = openvdb::gridPtrCast<openvdb::DoubleGrid>(base)) return to_float(*g);
    if (auto g = openvdb::gridPtrCast<openvdb::Int32Grid>(base)) return to_float(*g);
    if (auto g = openvdb::gridPtrCast<openvdb::Int64Grid>(base)) return to_float(*g);
    if (auto g = openvdb::gridPtrCast<openvdb::BoolGrid>(base)) return to_float(*g);
    return nullptr;
}

bool is_scalar_type(const std::string& type)
{
    return type == openvdb::FloatGrid::gridType() || type == openvdb::DoubleGrid::gridType() ||
           type == openvdb::Int32Grid::gridType() || type == openvdb::Int64Grid::gridType() ||
           type == openvdb::BoolGrid::gridType();
}

// OpenVDB 10 trusts the lengths and offsets in a file: a string's length is
// allocated before it is read (2^31 for a grid name takes 2 GB and seconds to
// clear), and each grid is read from the offset its descriptor gives. This
// walks what io::File::open and getGrids read before the trees, as
// io/Archive.cc, io/File.cc, io/GridDescriptor.cc and MetaMap::readMeta lay
// it out, and throws InputError at the first thing that does not fit the
// file. The trees themselves (node masks, values, compressed buffers) are
// not checked here.
class VdbHeaderCheck {
public:
    VdbHeaderCheck(std::string_view bytes, const std::filesystem::path& path) : bytes_(bytes), file_(path.string()) {}

    void run()
    {
        header();
        meta_map("the file's metadata", bytes_.size(), bytes_.size());
        const int64_t grids = value<int32_t>("grid count");
        // A descriptor takes at least three string lengths and three offsets.
        if (grids < 0 || grids > static_cast<int64_t>((bytes_.size() - pos_) / 36))
            fail("a grid count of " + std::to_string(grids) + ", more than the rest of the file can describe");
        for (int64_t g = 0; g < grids; ++g) descriptor(g);
    }

private:
    [[noreturn]] void fail(const std::string& what) const
    {
        throw InputError(file_ + " is not a valid VDB file: " + what + " (at byte " + std::to_string(pos_) + " of " +
                             std::to_string(bytes_.size()) + ")",
                         "the file may be truncated or corrupt; re-export it");
    }

    template <typename T>
    T value(const std::string& what, size_t end = std::string::npos)
    {
        end = std::min(end, bytes_.size());
        if (pos_ > end || end - pos_ < sizeof(T)) fail("it ends inside the " + what);
        T v;
        std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
        pos_ += sizeof(T);
        return v;
    }

    void skip(uint64_t count, const std::string& what, size_t end)
    {
        if (pos_ > end || count > end - pos_)
            fail(what + " of " + std::to_string(count) + " bytes runs past " +
                 (end == bytes_.size() ? std::string("the end of the file") : "its grid's data"));
        pos_ += count;
    }

    // io::readString: a uint32 length, then the characters.
    std::string string(const std::string& what, size_t end, uint32_t longest)
    {
        const uint32_t length = value<uint32_t>("length of the " + what, end);
        if (length > longest) fail("the " + what + " is " + std::to_string(length) + " characters long");
        const size_t start = pos_;
        skip(length, "the " + what, end);
        return std::string(bytes_.substr(start, length));
    }

    void header()
    {
        if (value<int64_t>("magic number") != openvdb::OPENVDB_MAGIC) fail("wrong magic number");
        version_ = value<uint32_t>("file format version");
        if (version_ < openvdb::OPENVDB_FILE_VERSION_SELECTIVE_COMPRESSION || version_ > openvdb::OPENVDB_FILE_VERSION)
            fail("file format version " + std::to_string(version_) + ", where OpenVDB 10 writes " +
                 std::to_string(openvdb::OPENVDB_FILE_VERSION) + " and scalemesh reads " +
                 std::to_string(openvdb::OPENVDB_FILE_VERSION_SELECTIVE_COMPRESSION) + " or later");
        value<uint32_t>("library major version");
        value<uint32_t>("library minor version");
        if (value<char>("grid offsets flag") == 0)
            fail("a stream without grid offsets, which is not read; write the file with openvdb::io::File");
        if (version_ < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) value<char>("compression flag");
        // The UUID as text: 36 characters, hyphens after 8, 12, 16 and 20 hex digits.
        const size_t start = pos_;
        skip(36, "the UUID", bytes_.size());
        for (size_t i = 0; i < 36; ++i) {
            const char c = bytes_[start + i];
            const bool hyphen = i == 8 || i == 13 || i == 18 || i == 23;
            if (hyphen ? c != '-' : !std::isxdigit(static_cast<unsigned char>(c))) fail("a malformed UUID");
        }
    }

    // MetaMap::readMeta: a count, then name, type name and value of each
    // item. A registered type of fixed size reads that many bytes whatever
    // the stored size says, so the two must agree.
    void meta_map(const std::string& what, size_t end, size_t grid_end)
    {
        const uint32_t count = value<uint32_t>("number of items in " + what, end);
        if (count > (end - pos_) / 12) fail(what + " with " + std::to_string(count) + " items");
        for (uint32_t i = 0; i < count; ++i) {
            const std::string name = string("name of a metadata item in " + what, end, kLongestName);
            const std::string type = string("type of metadata item '" + name + "'", end, kLongestName);
            const uint32_t size = value<uint32_t>("size of metadata item '" + name + "'", end);
            const size_t start = pos_;
            skip(size, "metadata item '" + name + "'", end);
            if (type == openvdb::io::DelayedLoadMetadata::staticTypeName()) {
                pos_ = start;
                delayed_load(start + size, grid_end, "metadata item '" + name + "'");
            } else if (openvdb::Metadata::isRegisteredType(type) &&
                       type != openvdb::StringMetadata::staticTypeName()) {
                const uint32_t expected = openvdb::Metadata::createMetadata(type)->size();
                if (size != expected)
                    fail("metadata item '" + name + "' of type " + type + " stores " + std::to_string(size) +
                         " bytes instead of " + std::to_string(expected));
            }
            pos_ = start + size;
        }
    }

    // DelayedLoadMetadata::readValue (io/DelayedLoadMetadata.cc) reads by its
    // own count, the number of leaf buffers: a mask byte for each, then (unless
    // marked absent) compressed sizes of 8 bytes, each array stored raw or
    // blosc-compressed; for a blosc array it reserves the uncompressed size
    // the array's header gives. All must lie within the item (up to `end`);
    // the count and the reserved sizes are held to the grid's bytes (up to
    // `grid_end`) and sixteen times that.
    void delayed_load(size_t end, size_t grid_end, const std::string& what)
    {
        if (end == pos_) return;
        const uint64_t grid_bytes = grid_end - pos_;
        const uint32_t count = value<uint32_t>("leaf count of " + what, end);
        if (count > grid_bytes) fail(what + " counts " + std::to_string(count) + " leaf buffers");
        for (const uint32_t width : {1, 8}) {
            const uint32_t bytes = value<uint32_t>("array size in " + what, end);
            if (width == 8 && bytes == std::numeric_limits<uint32_t>::max()) return; // no sizes stored
            if (bytes == 0) {
                skip(uint64_t{count} * width, "an array in " + what, end);
                continue;
            }
            // A blosc buffer: a 16-byte header with the uncompressed size at
            // byte 4 and the compressed size at byte 12.
            if (bytes < 16 || bytes > end - pos_)
                fail("a compressed array of " + std::to_string(bytes) + " bytes in " + what);
            uint32_t uncompressed = 0, compressed = 0;
            std::memcpy(&uncompressed, bytes_.data() + pos_ + 4, 4);
            std::memcpy(&compressed, bytes_.data() + pos_ + 12, 4);
            if (compressed != bytes || uncompressed > 16 * grid_bytes)
                fail("a compressed array in " + what + " whose header says " + std::to_string(compressed) + " bytes, " +
                     std::to_string(uncompressed) + " uncompressed");
            pos_ += bytes;
        }
    }

    // GridDescriptor::read, then what Archive::readGrid reads before the
    // topology: the compression flags, the grid's metadata and the name of
    // its transform's map.
    void descriptor(int64_t index)
    {
        const std::string grid = "grid " + std::to_string(index + 1);
        const std::string name = string("name of " + grid, bytes_.size(), kLongestName);
        std::string type = string("type of grid '" + name + "'", bytes_.size(), kLongestName);
        // GridDescriptor.cc marks grids saved at half precision so.
        constexpr std::string_view half_float = "_HalfFloat";
        if (type.ends_with(half_float)) type.resize(type.size() - half_float.size());
        if (!openvdb::GridBase::isRegistered(type)) fail("grid '" + name + "' has the unknown type '" + type + "'");
        string("instance parent of grid '" + name + "'", bytes_.size(), kLongestName);
        const int64_t grid_pos = value<int64_t>("offsets of grid '" + name + "'");
        const int64_t block_pos = value<int64_t>("offsets of grid '" + name + "'");
        const int64_t end_pos = value<int64_t>("offsets of grid '" + name + "'");
        const std::string span = "grid '" + name + "' (bytes " + std::to_string(grid_pos) + ", " +
                                 std::to_string(block_pos) + " to " + std::to_string(end_pos) + ")";
        if (end_pos > static_cast<int64_t>(bytes_.size())) fail(span + " ends past the end of the file");
        if (!(static_cast<int64_t>(pos_) <= grid_pos && grid_pos <= block_pos && block_pos <= end_pos))
            fail(span + " has its offsets out of order or before its descriptor");

        pos_ = static_cast<size_t>(grid_pos);
        const auto block = static_cast<size_t>(block_pos);
        if (version_ >= openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) {
            const uint32_t compression = value<uint32_t>("compression flags of grid '" + name + "'", block);
            if (compression > (openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK |
                               openvdb::io::COMPRESS_BLOSC))
                fail("grid '" + name + "' has unknown compression flags " + std::to_string(compression));
        }
        meta_map("the metadata of grid '" + name + "'", block, static_cast<size_t>(end_pos));
        string("transform type of grid '" + name + "'", block, kLongestName);
        // io::File::readGridDescriptors goes on at the grid's end.
        pos_ = static_cast<size_t>(end_pos);
    }

    static constexpr uint32_t kLongestName = 4096;
    std::string_view bytes_;
    size_t pos_ = 0;
    std::string file_;
    uint32_t version_ = 0;
};

} // namespace

openvdb::FloatGrid::Ptr read_vdb(const std::filesystem::path& path, const VdbImportParams& params)
{
    initialize_openvdb();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw IoError(path.string(), "no such file; check the path");
    {
        std::ifstream in(path, std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        if (!in.eof() && in.fail()) throw IoError(path.string(), "reading the file failed");
        // OpenVDB files start with the magic number 0x56444220 ("VDB " little-endian).
        if (bytes.size() < 4 || bytes.compare(0, 4, "\x20\x42\x44\x56") != 0)
            throw InputError(path.string() + " is not an OpenVDB file (wrong magic number)",
                             "give a .vdb file, or a supported image or surface format");
        VdbHeaderCheck(bytes, path).run();
    }

    openvdb::io::File file(path.string());
    openvdb::GridPtrVecPtr grids;
    try {
        file.open(false);
        grids = file.getGrids();
        file.close();
    } catch (const std::exception& e) {
        throw InputError(path.string() + " could not be read as a VDB file: " + e.what(),
                         "the file may be truncated or corrupt; re-export it");
    }

    std::string names;
    openvdb::GridBase::Ptr chosen;
    for (const auto& g : *grids) {
        names += (names.empty() ? "" : ", ") + ("'" + g->getName() + "' (" + g->type() + ")");
        if (params.grid_name.empty() ? (!chosen && is_scalar_type(g->type())) : g->getName() == params.grid_name)
            if (!chosen) chosen = g;
    }
    if (!chosen) {
        if (!params.grid_name.empty())
            throw InputError("grid '" + params.grid_name + "' is not in " + path.string(),
                             "the file holds: " + (names.empty() ? std::string("no grids") : names));
        throw InputError(path.string() + " holds no float or integer grid",
                         "the file holds: " + (names.empty() ? std::string("no grids") : names));
    }
    openvdb::FloatGrid::Ptr grid = as_float_grid(chosen);
    if (!grid)
        throw InputError("grid '" + chosen->getName() + "' has type " + chosen->type() + ", not a scalar grid",
                         "choose a float or integer grid with --grid; the file holds: " + names);
    if (!grid->transform().isLinear())
        throw InputError("grid '" + grid->getName() + "' has a non-linear transform",
                         "resample it onto a linear (affine) transform");
    if (grid->tree().activeVoxelCount() == 0 && grid->tree().activeTileCount() == 0 &&
        grid->getGridClass() != openvdb::GRID_LEVEL_SET)
        throw InputError("grid '" + grid->getName() + "' in " + path.string() + " is empty (no active voxels)",
                         "check that the segmentation was exported with its label");
    return grid;
}

void write_vdb(const openvdb::GridBase& grid, const std::filesystem::path& path)
{
    initialize_openvdb();
    AtomicOutput out(path);
    try {
        openvdb::io::File file(out.temporary().string());
        // copyGrid shares the tree: no voxel data is duplicated.
        openvdb::GridCPtrVec grids{grid.copyGrid()};
        file.write(grids);
        file.close();
    } catch (const std::exception& e) {
        throw IoError(path.string(), std::string("cannot write the VDB file: ") + e.what());
    }
    out.commit();
}

} // namespace scalemesh
