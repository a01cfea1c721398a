#include "importers/vdb_importer.h"

#include "core/atomic_file.h"
#include "core/errors.h"

#include <openvdb/io/DelayedLoadMetadata.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/ValueTransformer.h>

#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <string_view>
#include <vector>

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

// What the file check learns of one grid descriptor.
struct VdbGridEntry {
    std::string unique_name; // as stored: the name, with "\x1e" and an index when names repeat
    std::string type;        // without the "_HalfFloat" suffix
    std::string instance_parent;
    uint32_t compression = 0;
    bool half_float = false;            // the grid's is_saved_as_half_float metadata
    size_t topology = std::string::npos; // where the tree starts, npos when OpenVDB cannot read the transform
    std::string transform;               // the transform's map type
    size_t end = 0;                      // the grid's end offset
};

// OpenVDB 10 trusts the lengths, counts and offsets in a file: a string's
// length is allocated before it is read (2^31 for a grid name takes 2 GB and
// seconds to clear), each grid is read from the offset its descriptor gives,
// and each compressed buffer of a tree is allocated at the size it states
// (io::bloscFromStream, io::unzipFromStream). This walks what OpenVDB reads,
// as io/Archive.cc, io/File.cc, io/GridDescriptor.cc, MetaMap::readMeta,
// math/Maps.h, the tree's readTopology and readBuffers and
// io::readCompressedValues lay it out, and throws InputError at the first
// thing that does not fit the file.
class VdbFileCheck {
public:
    VdbFileCheck(std::string_view bytes, const std::filesystem::path& path) : bytes_(bytes), file_(path.string()) {}

    // The header, the file's metadata and every grid descriptor with the
    // grid's compression flags, metadata and transform.
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

    const std::vector<VdbGridEntry>& grids() const { return grids_; }

    // The descriptor io::File::findDescriptor returns for `name`: the first
    // with that grid name, or for "name[N]" the one of that unique name.
    const VdbGridEntry* find(const std::string& name) const
    {
        using openvdb::io::GridDescriptor;
        const std::string unique = GridDescriptor::stringAsUniqueName(name);
        std::vector<const VdbGridEntry*> range;
        for (const std::string& key : {name, GridDescriptor::stripSuffix(unique)}) {
            for (const VdbGridEntry& g : grids_)
                if (GridDescriptor::stripSuffix(g.unique_name) == key) range.push_back(&g);
            if (!range.empty()) break;
        }
        if (range.empty()) return nullptr;
        if (name == unique) return range.front();
        for (const VdbGridEntry* g : range)
            if (g->unique_name == unique || g->unique_name == name) return g;
        return nullptr;
    }

    // The tree of a scalar grid (float, double, int32, int64 or bool; the
    // standard 5-4-3 configuration), as Grid::readTopology and readBuffers
    // read it: every count within the file, every compressed buffer's size
    // within the grid's bytes, blosc headers that agree with it.
    void tree(const VdbGridEntry& grid)
    {
        const std::string name = openvdb::io::GridDescriptor::nameAsString(grid.unique_name);
        linear_transform(grid);
        tree_ = {};
        tree_.name = name;
        tree_.compression = grid.compression;
        tree_.is_bool = grid.type == openvdb::BoolGrid::gridType();
        const bool real = grid.type == openvdb::FloatGrid::gridType() || grid.type == openvdb::DoubleGrid::gridType();
        tree_.value_size = tree_.is_bool ? 1
                           : (grid.type == openvdb::DoubleGrid::gridType() ||
                              grid.type == openvdb::Int64Grid::gridType())
                               ? 8
                               : 4;
        tree_.half = real && grid.half_float;
        tree_.end = grid.end;
        pos_ = grid.topology;
        topology();
        buffers();
        // Archive::writeGrid ends a grid right after its buffers.
        if (pos_ != tree_.end)
            fail("the tree of grid '" + name + "' ends " + std::to_string(tree_.end - pos_) +
                 " bytes before the grid's end offset");
    }

    // A frustum map reads a second map type and map of any length; only
    // the linear maps are read.
    void linear_transform(const VdbGridEntry& grid) const
    {
        if (grid.topology == std::string::npos)
            fail("grid '" + openvdb::io::GridDescriptor::nameAsString(grid.unique_name) + "' has a " +
                     grid.transform + " transform, not a linear (affine) one",
                 "resample it onto a linear (affine) transform");
    }

private:
    [[noreturn]] void fail(const std::string& what,
                           const std::string& hint = "the file may be truncated or corrupt; re-export it") const
    {
        throw InputError(file_ + " is not a valid VDB file: " + what + " (at byte " + std::to_string(pos_) + " of " +
                             std::to_string(bytes_.size()) + ")",
                         hint);
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
        if (version_ < openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION || version_ > openvdb::OPENVDB_FILE_VERSION)
            fail("file format version " + std::to_string(version_) + ", where OpenVDB 10 writes " +
                 std::to_string(openvdb::OPENVDB_FILE_VERSION) + " and scalemesh reads " +
                 std::to_string(openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION) + " or later");
        value<uint32_t>("library major version");
        value<uint32_t>("library minor version");
        if (value<char>("grid offsets flag") == 0)
            fail("a stream without grid offsets, which is not read; write the file with openvdb::io::File");
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
    // the stored size says, so the two must agree. Sets half_float_ from the
    // item Grid::saveFloatAsHalf looks at.
    void meta_map(const std::string& what, size_t end, size_t grid_end)
    {
        half_float_ = false;
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
            if (name == openvdb::GridBase::META_SAVE_HALF_FLOAT) {
                if (type != openvdb::BoolMetadata::staticTypeName())
                    fail("metadata item '" + name + "' has type " + type + " instead of bool");
                half_float_ = bytes_[start] != 0;
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
            if (bytes > end - pos_) fail("a compressed array of " + std::to_string(bytes) + " bytes in " + what);
            blosc_header(bytes, std::nullopt, 16 * grid_bytes, "a compressed array in " + what);
            pos_ += bytes;
        }
    }

    // A blosc buffer of `bytes` bytes at pos_: a 16-byte header with the
    // uncompressed size at byte 4 and the compressed size at byte 12, which
    // must be the buffer's size (blosc reads as far as it says).
    void blosc_header(uint64_t bytes, std::optional<uint64_t> uncompressed_expected, uint64_t largest,
                      const std::string& what)
    {
        if (bytes < 16) fail(what + " of " + std::to_string(bytes) + " bytes, shorter than its header");
        uint32_t uncompressed = 0, compressed = 0;
        std::memcpy(&uncompressed, bytes_.data() + pos_ + 4, 4);
        std::memcpy(&compressed, bytes_.data() + pos_ + 12, 4);
        if (compressed != bytes || uncompressed > largest ||
            (uncompressed_expected && uncompressed != *uncompressed_expected))
            fail(what + " whose header says " + std::to_string(compressed) + " bytes, " +
                 std::to_string(uncompressed) + " uncompressed, for " + std::to_string(bytes) + " bytes" +
                 (uncompressed_expected ? ", " + std::to_string(*uncompressed_expected) + " uncompressed" : ""));
    }

    // The map a transform reads after its type name (math/Maps.h).
    static std::optional<size_t> map_size(const std::string& type)
    {
        namespace m = openvdb::math;
        if (type == m::AffineMap::mapType() || type == m::UnitaryMap::mapType()) return 16 * 8;
        if (type == m::ScaleMap::mapType() || type == m::UniformScaleMap::mapType()) return 5 * 24;
        if (type == m::ScaleTranslateMap::mapType() || type == m::UniformScaleTranslateMap::mapType()) return 6 * 24;
        if (type == m::TranslationMap::mapType()) return 24;
        return std::nullopt; // the frustum map (not linear) or a type OpenVDB refuses by name
    }

    // GridDescriptor::read, then what Archive::readGrid reads before the
    // tree: the compression flags, the grid's metadata and its transform.
    void descriptor(int64_t index)
    {
        VdbGridEntry entry;
        const std::string grid = "grid " + std::to_string(index + 1);
        entry.unique_name = string("name of " + grid, bytes_.size(), kLongestName);
        const std::string name = openvdb::io::GridDescriptor::nameAsString(entry.unique_name);
        entry.type = string("type of grid '" + name + "'", bytes_.size(), kLongestName);
        // GridDescriptor.cc marks grids saved at half precision so.
        constexpr std::string_view half_float = "_HalfFloat";
        if (entry.type.ends_with(half_float)) entry.type.resize(entry.type.size() - half_float.size());
        if (!openvdb::GridBase::isRegistered(entry.type))
            fail("grid '" + name + "' has the unknown type '" + entry.type + "'");
        entry.instance_parent = string("instance parent of grid '" + name + "'", bytes_.size(), kLongestName);
        const int64_t grid_pos = value<int64_t>("offsets of grid '" + name + "'");
        const int64_t block_pos = value<int64_t>("offsets of grid '" + name + "'");
        const int64_t end_pos = value<int64_t>("offsets of grid '" + name + "'");
        const std::string span = "grid '" + name + "' (bytes " + std::to_string(grid_pos) + ", " +
                                 std::to_string(block_pos) + " to " + std::to_string(end_pos) + ")";
        if (end_pos > static_cast<int64_t>(bytes_.size())) fail(span + " ends past the end of the file");
        if (!(static_cast<int64_t>(pos_) <= grid_pos && grid_pos <= block_pos && block_pos <= end_pos))
            fail(span + " has its offsets out of order or before its descriptor");

        pos_ = static_cast<size_t>(grid_pos);
        entry.end = static_cast<size_t>(end_pos);
        const auto block = static_cast<size_t>(block_pos);
        entry.compression = value<uint32_t>("compression flags of grid '" + name + "'", block);
        if (entry.compression >
            (openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK | openvdb::io::COMPRESS_BLOSC))
            fail("grid '" + name + "' has unknown compression flags " + std::to_string(entry.compression));
        meta_map("the metadata of grid '" + name + "'", block, entry.end);
        entry.half_float = half_float_;
        entry.transform = string("transform type of grid '" + name + "'", block, kLongestName);
        if (const auto size = map_size(entry.transform)) {
            skip(*size, "the transform of grid '" + name + "'", entry.end);
            entry.topology = pos_;
        }
        grids_.push_back(std::move(entry));
        // io::File::readGridDescriptors goes on at the grid's end.
        pos_ = static_cast<size_t>(end_pos);
    }

    // The tree being walked, and what it needs of its grid.
    struct Tree {
        std::string name;
        uint32_t compression = 0;
        bool is_bool = false;
        bool half = false;     // values stored as 16-bit floats
        size_t value_size = 4; // bytes of a value in memory (background, tiles, inactive values)
        size_t end = 0;
        // Root children in file order: their coordinates and the offsets of
        // their leaves' value masks in the topology.
        std::vector<std::array<int32_t, 3>> child_origins;
        std::vector<std::vector<size_t>> child_leaves;
    };

    static constexpr size_t mask_bytes(int log2dim) { return (size_t{1} << (3 * log2dim)) / 8; }

    size_t count_on(size_t mask_at, size_t bytes) const
    {
        size_t on = 0;
        for (size_t i = 0; i < bytes; ++i) on += std::popcount(static_cast<unsigned char>(bytes_[mask_at + i]));
        return on;
    }

    // Tree::readTopology: a buffer count, then RootNode::readTopology.
    void topology()
    {
        const std::string where = "the tree of grid '" + tree_.name + "'";
        value<int32_t>("buffer count of " + where, tree_.end);
        skip(tree_.value_size, "the background of " + where, tree_.end);
        const uint32_t tiles = value<uint32_t>("tile count of " + where, tree_.end);
        const uint32_t children = value<uint32_t>("child count of " + where, tree_.end);
        const size_t tile_bytes = 12 + tree_.value_size + 1;
        if (tiles > (tree_.end - pos_) / tile_bytes)
            fail(where + " counts " + std::to_string(tiles) + " tiles, more than its bytes hold");
        skip(uint64_t{tiles} * tile_bytes, "the tiles of " + where, tree_.end);
        // A child takes at least its origin, two masks and a compression byte.
        if (children > (tree_.end - pos_) / (12 + 2 * mask_bytes(5) + 1))
            fail(where + " counts " + std::to_string(children) + " children, more than its bytes hold");
        for (uint32_t c = 0; c < children; ++c) {
            std::array<int32_t, 3> origin{};
            for (int32_t& x : origin) x = value<int32_t>("origin of a node of " + where, tree_.end);
            tree_.child_origins.push_back(origin);
            tree_.child_leaves.emplace_back();
            internal_node(5, tree_.child_leaves.back());
        }
    }

    // InternalNode::readTopology: child mask, value mask, the node's values,
    // then each child in the order of the child mask.
    void internal_node(int log2dim, std::vector<size_t>& leaves)
    {
        const size_t bytes = mask_bytes(log2dim);
        const size_t child_mask = pos_;
        skip(bytes, "the child mask of a node in the tree of grid '" + tree_.name + "'", tree_.end);
        const size_t value_mask = pos_;
        skip(bytes, "the value mask of a node in the tree of grid '" + tree_.name + "'", tree_.end);
        compressed_values(size_t{1} << (3 * log2dim), value_mask, bytes, "the values of a node");
        for (size_t i = 0; i < bytes; ++i) {
            const auto byte = static_cast<unsigned char>(bytes_[child_mask + i]);
            for (int bit = 0; bit < 8; ++bit) {
                if (!(byte >> bit & 1)) continue;
                if (log2dim == 5) {
                    internal_node(4, leaves);
                } else {
                    leaves.push_back(pos_);
                    skip(mask_bytes(3), "the value mask of a leaf in the tree of grid '" + tree_.name + "'",
                         tree_.end);
                }
            }
        }
    }

    // RootNode::readBuffers goes through its table (a std::map of the
    // children by origin, a later child replacing one of the same origin),
    // then each leaf's LeafNode::readBuffers: its value mask again (skipped
    // by OpenVDB, so it must equal the topology's) and its values; a bool
    // leaf stores its value mask, origin and value bits.
    void buffers()
    {
        std::map<std::array<int32_t, 3>, size_t> table;
        for (size_t c = 0; c < tree_.child_origins.size(); ++c) table[tree_.child_origins[c]] = c;
        const std::string where = "a leaf of the tree of grid '" + tree_.name + "'";
        for (const auto& [origin, c] : table) {
            for (const size_t mask : tree_.child_leaves[c]) {
                const size_t here = pos_;
                skip(mask_bytes(3), "the value mask of " + where, tree_.end);
                if (tree_.is_bool) {
                    skip(12 + mask_bytes(3), "the values of " + where, tree_.end);
                    continue;
                }
                if (bytes_.compare(here, mask_bytes(3), bytes_.substr(mask, mask_bytes(3))) != 0)
                    fail("the value mask of " + where + " differs from the one in its topology");
                compressed_values(512, mask, mask_bytes(3), "the values of a leaf");
            }
        }
    }

    // io::readCompressedValues of `count` values under the value mask at
    // `mask_at`: a byte saying which inactive values and selection mask
    // follow, then the values (only the active ones under mask compression)
    // through io::readData.
    void compressed_values(size_t count, size_t mask_at, size_t mask_size, const std::string& what_values)
    {
        const std::string what = what_values + " in the tree of grid '" + tree_.name + "'";
        enum : int8_t { kOneInactive = 2, kMaskNoInactive = 3, kMaskOneInactive = 4, kMaskTwoInactive = 5, kAll = 6 };
        const auto metadata = value<int8_t>("compression byte of " + what, tree_.end);
        if (metadata == kOneInactive || metadata == kMaskOneInactive || metadata == kMaskTwoInactive)
            skip(tree_.value_size * (metadata == kMaskTwoInactive ? 2 : 1), "the inactive values of " + what,
                 tree_.end);
        if (metadata == kMaskNoInactive || metadata == kMaskOneInactive || metadata == kMaskTwoInactive)
            skip(mask_size, "the selection mask of " + what, tree_.end);
        if ((tree_.compression & openvdb::io::COMPRESS_ACTIVE_MASK) && metadata != kAll)
            count = count_on(mask_at, mask_size);
        // io::HalfReader reads nothing for no values; readData always reads.
        if (tree_.half && count == 0) return;
        const uint64_t bytes = count * (tree_.half ? 2 : tree_.value_size);
        if (!(tree_.compression & (openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ZIP))) {
            skip(bytes, what, tree_.end);
            return;
        }
        // bloscFromStream and unzipFromStream: a signed size, negative for
        // raw data of exactly the bytes expected, else the compressed bytes.
        const auto stored = value<int64_t>("size of " + what, tree_.end);
        if (stored <= 0) {
            if (uint64_t{0} - static_cast<uint64_t>(stored) != bytes)
                fail(what + " stored raw in " + std::to_string(uint64_t{0} - static_cast<uint64_t>(stored)) +
                     " bytes instead of " + std::to_string(bytes));
            skip(bytes, what, tree_.end);
            return;
        }
        if (static_cast<uint64_t>(stored) > tree_.end - pos_)
            fail(what + " compressed in " + std::to_string(stored) + " bytes, more than the grid's remaining " +
                 std::to_string(tree_.end - pos_));
        if (tree_.compression & openvdb::io::COMPRESS_BLOSC)
            blosc_header(static_cast<uint64_t>(stored), bytes, bytes, what);
        pos_ += static_cast<size_t>(stored);
    }

    static constexpr uint32_t kLongestName = 4096;
    std::string_view bytes_;
    size_t pos_ = 0;
    std::string file_;
    uint32_t version_ = 0;
    bool half_float_ = false;
    std::vector<VdbGridEntry> grids_;
    Tree tree_;
};

} // namespace

openvdb::FloatGrid::Ptr read_vdb(const std::filesystem::path& path, const VdbImportParams& params)
{
    initialize_openvdb();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw IoError(path.string(), "no such file; check the path");
    std::string read_name, all_names;
    {
        std::ifstream in(path, std::ios::binary);
        const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        if (!in.eof() && in.fail()) throw IoError(path.string(), "reading the file failed");
        // OpenVDB files start with the magic number 0x56444220 ("VDB " little-endian).
        if (bytes.size() < 4 || bytes.compare(0, 4, "\x20\x42\x44\x56") != 0)
            throw InputError(path.string() + " is not an OpenVDB file (wrong magic number)",
                             "give a .vdb file, or a supported image or surface format");
        VdbFileCheck check(bytes, path);
        check.run();
        // Only the chosen grid's tree is read (io::File::readGrid), so only
        // its tree is walked.
        using openvdb::io::GridDescriptor;
        std::string names;
        const VdbGridEntry* chosen = nullptr;
        for (const VdbGridEntry& g : check.grids()) {
            const std::string name = GridDescriptor::nameAsString(g.unique_name);
            names += (names.empty() ? "" : ", ") + ("'" + name + "' (" + g.type + ")");
            const bool wanted = params.grid_name.empty()
                                    ? is_scalar_type(g.type)
                                    : (name == params.grid_name ||
                                       GridDescriptor::stripSuffix(g.unique_name) == params.grid_name);
            if (wanted && !chosen) chosen = &g;
        }
        if (!chosen) {
            if (!params.grid_name.empty())
                throw InputError("grid '" + params.grid_name + "' is not in " + path.string(),
                                 "the file holds: " + (names.empty() ? std::string("no grids") : names));
            throw InputError(path.string() + " holds no float or integer grid",
                             "the file holds: " + (names.empty() ? std::string("no grids") : names));
        }
        read_name = GridDescriptor::nameAsString(chosen->unique_name);
        // The descriptor OpenVDB looks up by that name, and for an instance
        // the one whose tree it shares.
        const VdbGridEntry* read = check.find(read_name);
        if (read && !read->instance_parent.empty()) {
            check.linear_transform(*read);
            read = check.find(GridDescriptor::nameAsString(read->instance_parent));
        }
        if (read) check.linear_transform(*read);
        if (read && read->instance_parent.empty()) {
            if (!is_scalar_type(read->type))
                throw InputError("grid '" + GridDescriptor::nameAsString(read->unique_name) + "' has type " +
                                     read->type + ", not a scalar grid",
                                 "choose a float or integer grid with --grid; the file holds: " + names);
            check.tree(*read);
        }
        all_names = names;
    }

    openvdb::io::File file(path.string());
    openvdb::GridBase::Ptr chosen;
    try {
        file.open(false);
        chosen = file.readGrid(read_name);
        file.close();
    } catch (const std::exception& e) {
        throw InputError(path.string() + " could not be read as a VDB file: " + e.what(),
                         "the file may be truncated or corrupt; re-export it");
    }
    openvdb::FloatGrid::Ptr grid = as_float_grid(chosen);
    if (!grid)
        throw InputError("grid '" + chosen->getName() + "' has type " + chosen->type() + ", not a scalar grid",
                         "choose a float or integer grid with --grid; the file holds: " + all_names);
    if (!grid->transform().isLinear())
        throw InputError("grid '" + grid->getName() + "' has a non-linear transform",
                         "resample it onto a linear (affine) transform");
    // A NaN is neither inside nor outside at any iso value: marching cubes
    // would take it as outside, a one-voxel cavity nobody asked for.
    int64_t nonfinite = 0;
    openvdb::Coord first;
    if (!std::isfinite(grid->background()))
        throw InputError("grid '" + grid->getName() + "' in " + path.string() + " has a NaN or infinite background value",
                         "fix the grid: every value needs to be finite");
    for (auto it = grid->cbeginValueAll(); it; ++it)
        if (!std::isfinite(*it)) {
            if (nonfinite == 0) first = it.getCoord();
            nonfinite += static_cast<int64_t>(it.getVoxelCount());
        }
    if (nonfinite > 0)
        throw InputError("grid '" + grid->getName() + "' in " + path.string() + " has " + std::to_string(nonfinite) +
                             " NaN or infinite voxel values, the first at voxel (" + std::to_string(first.x()) + ", " +
                             std::to_string(first.y()) + ", " + std::to_string(first.z()) + ")",
                         "fix the grid: every voxel needs a finite value");
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
