#include "importers/msh_check.h"

#include "core/errors.h"

#include <algorithm>
#include <array>
#include <charconv>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

namespace scalemesh {

namespace {

// Gmsh 4.8 keeps node and element tags as int where it looks them up.
constexpr int64_t kMaxTag = std::numeric_limits<int32_t>::max();
// The lines Gmsh reads whole go through fgets into buffers of 256 bytes; a
// longer line would be read in pieces, each taken for a line. Lines of items
// (fscanf, or an MSH4 element's fgets into 10000 bytes) are kept below 4096.
constexpr size_t kMaxLine = 254;
constexpr size_t kMaxItemLine = 4095;
// A data section indexes an array by tag, sized by the largest tag: tags far
// beyond the count of nodes or elements would make Gmsh allocate for them.
// Gmsh itself calls a numbering dense up to ten times the count.
constexpr int64_t kDataTagSlack = 10;
constexpr int64_t kMaxTimeStep = 1000;

struct ElementType {
    int nodes;
    int dim;
};
// Gmsh's element types 1 to 31 (the MSH format's list): node count, dimension.
constexpr std::array<ElementType, 32> kElementTypes{{{0, -1}, {2, 1},  {3, 2},  {4, 2},  {4, 3},  {8, 3},  {6, 3},
                                                     {5, 3},  {3, 1},  {6, 2},  {9, 2},  {10, 3}, {27, 3}, {18, 3},
                                                     {14, 3}, {1, 0},  {8, 2},  {20, 3}, {15, 3}, {13, 3}, {9, 2},
                                                     {10, 2}, {12, 2}, {15, 2}, {15, 2}, {21, 2}, {4, 1},  {5, 1},
                                                     {6, 1},  {20, 3}, {35, 3}, {56, 3}}};

// What fscanf skips.
bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f'; }

bool is_blank(std::string_view text)
{
    for (const char c : text)
        if (!is_space(c)) return false;
    return true;
}

std::string without_cr(std::string_view line)
{
    return std::string(line.ends_with('\r') ? line.substr(0, line.size() - 1) : line);
}

std::vector<std::string_view> words(std::string_view line)
{
    std::vector<std::string_view> out;
    size_t at = 0;
    while (at < line.size()) {
        while (at < line.size() && is_space(line[at])) ++at;
        const size_t start = at;
        while (at < line.size() && !is_space(line[at])) ++at;
        if (at > start) out.push_back(line.substr(start, at - start));
    }
    return out;
}

class MshCheck {
public:
    MshCheck(std::string_view bytes, const std::filesystem::path& path) : bytes_(bytes), file_(path.string()) {}

    void run()
    {
        mesh_format();
        if (!binary_) {
            size_t longest = 0;
            for (size_t at = 0; at < bytes_.size();) {
                const size_t end = std::min(bytes_.find('\n', at), bytes_.size());
                longest = std::max(longest, end - at);
                at = end + 1;
            }
            if (longest > kMaxItemLine) fail("a line of more than " + std::to_string(kMaxItemLine) + " characters");
        }
        for (skip_blank_lines(); pos_ < bytes_.size(); skip_blank_lines()) {
            header_ = line();
            if (!header_.starts_with('$'))
                fail("text outside any section: '" + std::string(header_.substr(0, 40)) + "'");
            const std::string name = without_cr(header_.substr(1));
            section_ = "$" + name;
            if (name == "PhysicalNames") physical_names();
            else if (name == "Entities" && v4_) entities();
            else if (name == "Nodes" && !seen_nodes_) nodes();
            else if (name == "Elements" && seen_nodes_ && !seen_elements_) elements();
            else if (name == "NodeData" || name == "ElementData" || name == "ElementNodeData") data(name);
            else if (name == "InterpolationScheme") interpolation_scheme();
            else other_section(name);
        }
    }

private:
    [[noreturn]] void fail(const std::string& what) const
    {
        std::string where;
        if (!section_.empty()) where = " (in " + section_;
        if (!binary_ && !where.empty()) {
            const auto newlines = std::count(bytes_.begin(), bytes_.begin() + std::min(pos_, bytes_.size()), '\n');
            where += ", line " + std::to_string(newlines + 1);
        }
        if (!where.empty()) where += ")";
        throw InputError(file_ + " is not a valid MSH file: " + what + where,
                         "the file is damaged or was cut short: write the mesh again in MSH 2.2 or 4.1");
    }

    // -- Reading, the way Gmsh does: fgets for whole lines, fscanf (any
    // whitespace between items) or fread for the items.

    std::string_view line()
    {
        if (pos_ >= bytes_.size()) fail("the file ends early");
        const size_t end = std::min(bytes_.find('\n', pos_), bytes_.size());
        const std::string_view text = bytes_.substr(pos_, end - pos_);
        pos_ = std::min(end + 1, bytes_.size());
        if (text.size() > kMaxLine) fail("a line of more than " + std::to_string(kMaxLine) + " characters");
        if (text.find('\0') != std::string_view::npos) fail("a NUL byte in a text line");
        return text;
    }

    void skip_blank_lines()
    {
        while (pos_ < bytes_.size()) {
            const size_t end = std::min(bytes_.find('\n', pos_), bytes_.size());
            if (!is_blank(bytes_.substr(pos_, end - pos_))) return;
            pos_ = std::min(end + 1, bytes_.size());
        }
    }

    // The rest of the current line (after the last item of a section) must
    // be blank.
    void finish_line()
    {
        if (pos_ == 0 || bytes_[pos_ - 1] == '\n') return;
        const size_t end = std::min(bytes_.find('\n', pos_), bytes_.size());
        if (!is_blank(bytes_.substr(pos_, end - pos_))) fail("unexpected text after the last item");
        pos_ = std::min(end + 1, bytes_.size());
    }

    void end_of_section()
    {
        finish_line();
        skip_blank_lines();
        if (pos_ >= bytes_.size()) fail("the file ends before $End" + section_.substr(1));
        const std::string_view end = line();
        if (end != "$End" + std::string(header_.substr(1)))
            fail("'" + std::string(end.substr(0, 40)) + "' where $End" + section_.substr(1) + " should be");
    }

    // One item of ASCII text; with `same_line`, on the current line (Gmsh
    // reads an MSH4 element's node tags from the line of its tag).
    std::string_view token(const char* what, bool same_line = false)
    {
        while (pos_ < bytes_.size() && is_space(bytes_[pos_])) {
            if (same_line && bytes_[pos_] == '\n') fail(std::string("the line ends before the ") + what);
            ++pos_;
        }
        const size_t start = pos_;
        while (pos_ < bytes_.size() && !is_space(bytes_[pos_])) ++pos_;
        if (pos_ == start) fail(std::string("the file ends before the ") + what);
        return bytes_.substr(start, pos_ - start);
    }

    // A plain decimal integer, or nullopt.
    static std::optional<int64_t> parse_integer(std::string_view text)
    {
        int64_t value = 0;
        const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
        if (error != std::errc() || end != text.data() + text.size()) return std::nullopt;
        return value;
    }

    int64_t check_range(const std::optional<int64_t>& value, std::string_view text, int64_t lo, int64_t hi,
                        const std::string& what) const
    {
        const int64_t v = value.value_or(lo - 1);
        if (v < lo || v > hi)
            fail(what + " '" + std::string(text.substr(0, 30)) + "' is not an integer from " + std::to_string(lo) +
                 " to " + std::to_string(hi));
        return v;
    }

    template <typename T>
    T binary_value(const std::string& what)
    {
        if (bytes_.size() - pos_ < sizeof(T)) fail("the file ends before the " + what);
        T value;
        std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
        pos_ += sizeof(T);
        return value;
    }

    // An int of the format: 4 bytes in binary.
    int64_t int_item(int64_t lo, int64_t hi, const std::string& what, bool same_line = false)
    {
        if (binary_) {
            const int64_t value = binary_value<int32_t>(what);
            return check_range(value, std::to_string(value), lo, hi, what);
        }
        const std::string_view text = token(what.c_str(), same_line);
        return check_range(parse_integer(text), text, lo, hi, what);
    }

    // A size_t of the format: 8 bytes in binary.
    int64_t size_item(int64_t lo, int64_t hi, const std::string& what, bool same_line = false)
    {
        if (binary_) {
            const uint64_t value = binary_value<uint64_t>(what);
            const auto fits = static_cast<int64_t>(std::min<uint64_t>(value, static_cast<uint64_t>(hi) + 1));
            return check_range(fits, std::to_string(value), lo, hi, what);
        }
        const std::string_view text = token(what.c_str(), same_line);
        return check_range(parse_integer(text), text, lo, hi, what);
    }

    void reals(int64_t count, const std::string& what)
    {
        if (binary_) {
            if (static_cast<uint64_t>(count) > (bytes_.size() - pos_) / 8) fail("the file ends inside the " + what);
            pos_ += static_cast<size_t>(count) * 8;
            return;
        }
        for (int64_t i = 0; i < count; ++i) {
            const std::string text(token(what.c_str()));
            char* end = nullptr;
            std::strtod(text.c_str(), &end);
            if (end != text.c_str() + text.size()) fail(what + " '" + text.substr(0, 30) + "' is not a number");
        }
    }

    // A count on a line of its own, as MSH 2.2 and data sections give them.
    int64_t count_line(int64_t lo, int64_t hi, const std::string& what)
    {
        const std::string_view text = line();
        const auto items = words(text);
        return check_range(items.size() == 1 ? parse_integer(items[0]) : std::nullopt, text, lo, hi, what);
    }

    // A count is refused before anything is read for it when the rest of
    // the file cannot hold that many items of at least `bytes_each` bytes
    // (Gmsh allocates for the count first).
    void room(int64_t count, int64_t bytes_each, const std::string& what) const
    {
        const auto left = static_cast<int64_t>(bytes_.size() - pos_);
        if (count > left / bytes_each)
            fail("it promises " + std::to_string(count) + " " + what + ", more than the " + std::to_string(left) +
                 " bytes left in the file can hold");
    }

    // ASCII numbers take at least two bytes: a digit and a separator.
    int64_t bytes(int64_t binary_bytes, int64_t numbers) const { return binary_ ? binary_bytes : 2 * numbers; }

    // -- Sections

    void mesh_format()
    {
        skip_blank_lines();
        if (pos_ >= bytes_.size()) fail("it is blank");
        header_ = line();
        if (without_cr(header_) != "$MeshFormat") fail("it does not begin with $MeshFormat");
        section_ = "$MeshFormat";
        const std::string_view format = line();
        const auto items = words(format);
        if (items.size() != 3 || (items[0] != "2.2" && items[0] != "4.1") || (items[1] != "0" && items[1] != "1") ||
            items[2] != "8")
            fail("'" + std::string(format.substr(0, 40)) + "' is not MSH 2.2 or 4.1 (version, 0 or 1 for ASCII or "
                                                            "binary, 8)");
        v4_ = items[0] == "4.1";
        binary_ = items[1] == "1";
        if (binary_ && binary_value<int32_t>("byte order mark") != 1)
            fail("its binary data are not little-endian (the byte order mark is not 1)");
        end_of_section();
    }

    void physical_names()
    {
        const int64_t count = count_line(0, kMaxTag, "the number of physical names");
        room(count, 8, "physical names");
        for (int64_t i = 0; i < count; ++i) {
            // Gmsh indexes an array of four by the dimension.
            const bool was_binary = std::exchange(binary_, false);
            int_item(0, 3, "dimension of physical name " + std::to_string(i + 1));
            int_item(-kMaxTag, kMaxTag, "tag of physical name " + std::to_string(i + 1));
            binary_ = was_binary;
            line(); // the quoted name, read whole
        }
        end_of_section();
    }

    void entities()
    {
        std::array<int64_t, 4> counts{};
        for (int dim = 0; dim < 4; ++dim)
            counts[dim] = size_item(0, kMaxTag, "number of " + std::to_string(dim) + "D entities");
        for (int dim = 0; dim < 4; ++dim) {
            const int box = dim == 0 ? 3 : 6;
            room(counts[dim], bytes(4 + 8 * box + 8 + (dim > 0 ? 8 : 0), 2 + box + (dim > 0 ? 1 : 0)),
                 std::to_string(dim) + "D entities");
            for (int64_t i = 0; i < counts[dim]; ++i) {
                const std::string entity = std::to_string(dim) + "D entity " + std::to_string(i + 1);
                int_item(1, kMaxTag, "tag of " + entity);
                reals(box, "bounding box of " + entity);
                tag_list(entity + "'s physical groups");
                if (dim > 0) tag_list(entity + "'s bounding entities");
            }
        }
        end_of_section();
    }

    void tag_list(const std::string& what)
    {
        const int64_t count = size_item(0, kMaxTag, "number of " + what);
        room(count, bytes(4, 1), what);
        for (int64_t i = 0; i < count; ++i) int_item(-kMaxTag, kMaxTag, what);
    }

    void define_node(int64_t tag)
    {
        if (!nodes_.insert(tag).second) fail("node " + std::to_string(tag) + " is defined twice");
    }

    void node_of_element(int64_t element, bool same_line)
    {
        const std::string what = "node tag of element " + std::to_string(element);
        const int64_t tag = v4_ ? size_item(1, kMaxTag, what, same_line) : int_item(1, kMaxTag, what, same_line);
        if (!nodes_.contains(tag))
            fail("element " + std::to_string(element) + " refers to node " + std::to_string(tag) +
                 ", which the $Nodes section does not define");
    }

    void define_element(int64_t tag, int type)
    {
        if (!element_nodes_.emplace(tag, kElementTypes[type].nodes).second)
            fail("element " + std::to_string(tag) + " is defined twice");
    }

    int element_type(int64_t element_count_so_far)
    {
        return static_cast<int>(int_item(1, kElementTypes.size() - 1,
                                         "type of element " + std::to_string(element_count_so_far + 1)));
    }

    // MSH4's $Nodes and $Elements begin alike: the numbers of blocks and of
    // items, the smallest and the largest tag. Returns the two numbers.
    std::pair<int64_t, int64_t> v4_section_header(const std::string& item, int64_t bytes_each)
    {
        const int64_t blocks = size_item(0, kMaxTag, "number of " + item + " blocks");
        const int64_t total = size_item(0, kMaxTag, "number of " + item + "s");
        size_item(0, std::numeric_limits<int64_t>::max(), "smallest " + item + " tag");
        size_item(0, std::numeric_limits<int64_t>::max(), "largest " + item + " tag");
        room(total, bytes_each, item + "s");
        room(blocks, bytes(20, 4), item + " blocks");
        return {blocks, total};
    }

    // A block's entity: its dimension (returned) and tag.
    int64_t v4_block_entity(const std::string& block)
    {
        const int64_t dim = int_item(0, 3, "dimension of " + block);
        int_item(1, kMaxTag, "entity tag of " + block);
        return dim;
    }

    void nodes()
    {
        seen_nodes_ = true;
        if (!v4_) {
            const int64_t count = count_line(0, kMaxTag, "the number of nodes");
            room(count, bytes(28, 4), "nodes");
            for (int64_t i = 0; i < count; ++i) {
                define_node(int_item(1, kMaxTag, "tag of node " + std::to_string(i + 1)));
                reals(3, "coordinates of node " + std::to_string(i + 1));
            }
            end_of_section();
            return;
        }
        const auto [blocks, total] = v4_section_header("node", bytes(32, 4));
        int64_t read = 0;
        for (int64_t b = 0; b < blocks; ++b) {
            const std::string block = "node block " + std::to_string(b + 1);
            const int64_t dim = v4_block_entity(block);
            const int64_t parametric = int_item(0, 1, "parametric flag of " + block);
            const int64_t count = size_item(0, total - read, "number of nodes in " + block + " (of " +
                                                                 std::to_string(total) + " in all)");
            const int64_t coordinates = 3 + parametric * dim;
            room(count, bytes(8 + 8 * coordinates, 1 + coordinates), "nodes in " + block);
            for (int64_t i = 0; i < count; ++i) define_node(size_item(1, kMaxTag, "node tag in " + block));
            reals(count * coordinates, "coordinates in " + block);
            read += count;
        }
        if (read != total)
            fail("its header promises " + std::to_string(total) + " nodes, its blocks hold " + std::to_string(read));
        end_of_section();
    }

    void elements()
    {
        seen_elements_ = true;
        if (!v4_) return elements_2();
        const auto [blocks, total] = v4_section_header("element", bytes(16, 2));
        int64_t read = 0;
        for (int64_t b = 0; b < blocks; ++b) {
            const std::string block = "element block " + std::to_string(b + 1);
            const int64_t dim = v4_block_entity(block);
            const int type = element_type(read);
            const int64_t count = size_item(0, total - read, "number of elements in " + block + " (of " +
                                                                 std::to_string(total) + " in all)");
            if (kElementTypes[type].dim != dim)
                fail(block + " puts elements of type " + std::to_string(type) + " (" +
                     std::to_string(kElementTypes[type].dim) + "D) in a " + std::to_string(dim) + "D entity");
            const int nodes = kElementTypes[type].nodes;
            room(count, bytes(8 + 8 * nodes, 1 + nodes), "elements in " + block);
            for (int64_t i = 0; i < count; ++i) {
                const int64_t tag = size_item(1, kMaxTag, "element tag in " + block);
                define_element(tag, type);
                for (int k = 0; k < nodes; ++k) node_of_element(tag, !binary_);
                if (!binary_) finish_line();
            }
            read += count;
        }
        if (read != total)
            fail("its header promises " + std::to_string(total) + " elements, its blocks hold " +
                 std::to_string(read));
        end_of_section();
    }

    // MSH 2.2: each element with its type and tags (ASCII), or blocks of
    // elements of one type, each block with a header (binary).
    void elements_2()
    {
        const int64_t total = count_line(0, kMaxTag, "the number of elements");
        room(total, bytes(16, 4), "elements");
        int64_t read = 0;
        while (read < total) {
            int type = 0;
            int64_t count = 1, tags = 0;
            if (binary_) {
                type = element_type(read);
                count = int_item(1, total - read, "number of elements after element " + std::to_string(read));
                tags = int_item(0, 2, "number of tags after element " + std::to_string(read));
                room(count, 4 * (1 + tags + kElementTypes[type].nodes), "elements");
            }
            for (int64_t i = 0; i < count; ++i) {
                const int64_t tag = int_item(1, kMaxTag, "tag of element " + std::to_string(read + 1));
                if (!binary_) {
                    type = element_type(read);
                    tags = int_item(0, 2, "number of tags of element " + std::to_string(tag) +
                                              " (more are partitions, which are not read)");
                }
                for (int64_t k = 0; k < tags; ++k)
                    int_item(0, kMaxTag, "tag " + std::to_string(k + 1) + " of element " + std::to_string(tag));
                define_element(tag, type);
                for (int k = 0; k < kElementTypes[type].nodes; ++k) node_of_element(tag, false);
                ++read;
            }
        }
        end_of_section();
    }

    // $NodeData, $ElementData, $ElementNodeData: string, real and integer
    // tags, one a line, then one record per node or element.
    void data(const std::string& name)
    {
        const bool on_nodes = name == "NodeData";
        for (const char* kind : {"string", "real"}) {
            const int64_t count = count_line(0, 64, std::string("the number of ") + kind + " tags");
            for (int64_t i = 0; i < count; ++i) line();
        }
        // Gmsh makes a view for every time step up to this one.
        const int64_t ints = count_line(3, 64, "the number of integer tags");
        count_line(0, kMaxTimeStep, "the time step");
        const int64_t components = count_line(1, 9, "the number of components");
        if (components != 1 && components != 3 && components != 9) fail("a field of 1, 3 or 9 components is needed");
        const int64_t count = count_line(0, kMaxTag, "the number of entries");
        for (int64_t i = 3; i < ints; ++i) count_line(-kMaxTag, kMaxTag, "an integer tag");

        const auto defined = static_cast<int64_t>(on_nodes ? nodes_.size() : element_nodes_.size());
        const int64_t largest = kDataTagSlack * defined + 100;
        room(count, bytes(4 + 8 * components, 1 + components), "entries");
        for (int64_t i = 0; i < count; ++i) {
            const int64_t tag = int_item(1, largest, "tag of entry " + std::to_string(i + 1));
            int64_t values = components;
            if (on_nodes) {
                if (!nodes_.contains(tag)) fail("data on node " + std::to_string(tag) + ", which is not defined");
            } else {
                const auto element = element_nodes_.find(tag);
                if (element == element_nodes_.end())
                    fail("data on element " + std::to_string(tag) + ", which is not defined");
                if (name == "ElementNodeData") {
                    const int nodes = element->second;
                    int_item(nodes, nodes, "number of nodes with data on element " + std::to_string(tag));
                    values *= nodes;
                }
            }
            reals(values, "values of entry " + std::to_string(i + 1));
        }
        end_of_section();
    }

    // A name, then matrices per element type, all ASCII (Gmsh allocates each
    // matrix from its two sizes).
    void interpolation_scheme()
    {
        line(); // the quoted name
        const bool was_binary = std::exchange(binary_, false);
        const int64_t types = int_item(0, 64, "number of element types");
        for (int64_t t = 0; t < types; ++t) {
            int_item(-kMaxTag, kMaxTag, "element type");
            const int64_t matrices = int_item(0, 64, "number of matrices");
            for (int64_t m = 0; m < matrices; ++m) {
                const int64_t rows = int_item(0, kMaxTag, "number of rows");
                const int64_t columns = int_item(0, kMaxTag, "number of columns");
                room(rows, 1, "rows");
                room(columns, 1, "columns");
                room(rows * columns, 2, "matrix entries");
                reals(rows * columns, "matrix entry");
            }
        }
        binary_ = was_binary;
        end_of_section();
    }

    // Sections Gmsh stores as text or skips, up to their end line; those it
    // would parse but scalemesh does not take are refused, as is a line
    // beginning with '$' inside (Gmsh's MSH 2.2 reader takes it for a section).
    void other_section(const std::string& name)
    {
        for (const char* read_by_gmsh :
             {"MeshFormat", "PhysicalNames", "Entities", "PartitionedEntities", "Nodes", "Elements", "Periodic",
              "GhostElements", "Parametrizations", "InterpolationScheme", "NodeData", "ElementData",
              "ElementNodeData", "NO", "ELM", "ParametricNodes"})
            if (name.starts_with(read_by_gmsh))
                fail("a section $" + name + " that scalemesh does not read " +
                     "(it takes one $Nodes and one $Elements section after them, and no partitions, periodic links, "
                     "ghost elements or parametrizations)");
        if (name.empty()) fail("a section without a name");
        const std::string end = "$End" + std::string(header_.substr(1));
        for (;;) {
            const std::string_view text = line();
            if (text == end) return;
            if (text.starts_with('$') || text.substr(std::min<size_t>(1, text.size())) == end.substr(1))
                fail("'" + std::string(text.substr(0, 40)) + "' before $End" + name);
        }
    }

    std::string_view bytes_;
    size_t pos_ = 0;
    std::string file_;
    bool binary_ = false;
    bool v4_ = false;
    std::string header_;  // the current section's first line, as written
    std::string section_;     // its name, for messages
    bool seen_nodes_ = false;
    bool seen_elements_ = false;
    std::unordered_set<int64_t> nodes_;
    std::unordered_map<int64_t, int> element_nodes_; // element tag -> its node count
};

} // namespace

void check_msh_file(std::string_view bytes, const std::filesystem::path& path) { MshCheck(bytes, path).run(); }

} // namespace scalemesh
