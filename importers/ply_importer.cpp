// PLY (Stanford polygon file) reading. Written here rather than taken from a
// library: Debian packages no PLY reader, and CGAL's trusts the header's
// counts (a corrupt list length resizes a buffer to billions of entries),
// where this one checks every count against the bytes the file has left.

#include "core/errors.h"
#include "importers/polygon_soup.h"
#include "importers/surface_importer.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <optional>
#include <sstream>
#include <string_view>

namespace scalemesh {

namespace {

enum class Format { Ascii, BinaryLittle, BinaryBig };

enum class Type { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

std::optional<Type> parse_type(std::string_view name)
{
    if (name == "char" || name == "int8") return Type::Int8;
    if (name == "uchar" || name == "uint8") return Type::UInt8;
    if (name == "short" || name == "int16") return Type::Int16;
    if (name == "ushort" || name == "uint16") return Type::UInt16;
    if (name == "int" || name == "int32") return Type::Int32;
    if (name == "uint" || name == "uint32") return Type::UInt32;
    if (name == "float" || name == "float32") return Type::Float32;
    if (name == "double" || name == "float64") return Type::Float64;
    return std::nullopt;
}

size_t type_size(Type t)
{
    switch (t) {
    case Type::Int8: case Type::UInt8: return 1;
    case Type::Int16: case Type::UInt16: return 2;
    case Type::Int32: case Type::UInt32: case Type::Float32: return 4;
    case Type::Float64: return 8;
    }
    return 1;
}

bool is_integer(Type t) { return t != Type::Float32 && t != Type::Float64; }

struct Property {
    std::string name;
    Type type = Type::Float32;
    bool list = false;
    Type count_type = Type::UInt8; // lists only
};

struct Element {
    std::string name;
    uint64_t count = 0;
    std::vector<Property> properties;
};

class PlyReader {
public:
    PlyReader(const std::string& bytes, const std::filesystem::path& path) : bytes_(bytes), path_(path) {}

    PolygonSoup read()
    {
        parse_header();
        PolygonSoup soup;
        for (const Element& element : elements_) {
            if (element.name == "vertex") read_vertices(element, soup);
            else if (element.name == "face") read_faces(element, soup);
            else skip(element);
        }
        return soup;
    }

private:
    // The header: "ply", a format line, then element and property lines up to
    // "end_header".
    void parse_header()
    {
        const std::string_view text(bytes_);
        if (text.substr(0, 4) != "ply\n" && text.substr(0, 5) != "ply\r\n")
            fail_header("it does not begin with the line 'ply'", "give a PLY file (or a surface in another format)");
        bool have_format = false;
        for (;;) {
            const size_t end = text.find('\n', at_);
            if (end == std::string_view::npos) fail_header("the header has no 'end_header' line", "");
            std::string line(text.substr(at_, end - at_));
            at_ = end + 1;
            if (!line.empty() && line.back() == '\r') line.pop_back();
            std::istringstream words(line);
            std::string keyword;
            words >> keyword;
            if (keyword == "ply" || keyword.empty() || keyword == "comment" || keyword == "obj_info") continue;
            if (keyword == "end_header") break;
            if (keyword == "format") {
                std::string name, version;
                words >> name >> version;
                if (name == "ascii") format_ = Format::Ascii;
                else if (name == "binary_little_endian") format_ = Format::BinaryLittle;
                else if (name == "binary_big_endian") format_ = Format::BinaryBig;
                else fail_header("the format '" + name + "' is unknown", "");
                have_format = true;
            } else if (keyword == "element") {
                Element element;
                std::string count;
                words >> element.name >> count;
                const auto [ptr, error] = std::from_chars(count.data(), count.data() + count.size(), element.count);
                if (element.name.empty() || error != std::errc() || ptr != count.data() + count.size())
                    fail_header("the line '" + line + "' does not give an element name and count", "");
                elements_.push_back(std::move(element));
            } else if (keyword == "property") {
                if (elements_.empty()) fail_header("a property comes before any element", "");
                Property property;
                std::string type;
                words >> type;
                if (type == "list") {
                    std::string count_type, item_type;
                    words >> count_type >> item_type;
                    const auto c = parse_type(count_type), i = parse_type(item_type);
                    if (!c || !i || !is_integer(*c)) fail_header("the list property '" + line + "' has a bad type", "");
                    property.list = true;
                    property.count_type = *c;
                    property.type = *i;
                } else {
                    const auto t = parse_type(type);
                    if (!t) fail_header("the property type '" + type + "' is unknown", "");
                    property.type = *t;
                }
                words >> property.name;
                if (property.name.empty()) fail_header("the line '" + line + "' names no property", "");
                elements_.back().properties.push_back(std::move(property));
            } else {
                fail_header("the header line '" + line + "' is not PLY", "");
            }
        }
        if (!have_format) fail_header("the header has no 'format' line", "");
    }

    void read_vertices(const Element& element, PolygonSoup& soup)
    {
        int xyz[3] = {-1, -1, -1};
        for (size_t p = 0; p < element.properties.size(); ++p) {
            const Property& property = element.properties[p];
            for (int k = 0; k < 3; ++k)
                if (property.name == std::string(1, static_cast<char>('x' + k)) && !property.list) xyz[k] = static_cast<int>(p);
        }
        if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0)
            fail("its vertex element has no x, y and z properties", "export the surface with vertex positions");
        if (!soup.points.empty()) fail("it has two vertex elements", "export the surface as one mesh");
        require_room(element);
        soup.points.resize(element.count);
        for (uint64_t i = 0; i < element.count; ++i)
            for (size_t p = 0; p < element.properties.size(); ++p) {
                const Property& property = element.properties[p];
                if (property.list) {
                    skip_list(property);
                    continue;
                }
                const double value = number(property.type);
                for (int k = 0; k < 3; ++k)
                    if (xyz[k] == static_cast<int>(p)) soup.points[i][k] = value;
            }
    }

    void read_faces(const Element& element, PolygonSoup& soup)
    {
        int indices = -1;
        for (size_t p = 0; p < element.properties.size(); ++p) {
            const Property& property = element.properties[p];
            if (property.list && (property.name == "vertex_indices" || property.name == "vertex_index"))
                indices = static_cast<int>(p);
        }
        if (indices < 0)
            fail("its face element has no vertex_indices list", "export the surface with its faces");
        if (!is_integer(element.properties[indices].type))
            fail("its face vertex_indices are not integers", "export the faces with integer indices");
        if (soup.offsets.size() > 1) fail("it has two face elements", "export the surface as one mesh");
        require_room(element);
        for (uint64_t f = 0; f < element.count; ++f)
            for (size_t p = 0; p < element.properties.size(); ++p) {
                const Property& property = element.properties[p];
                if (static_cast<int>(p) != indices) {
                    if (property.list) skip_list(property);
                    else number(property.type);
                    continue;
                }
                const uint64_t n = list_count(property);
                for (uint64_t c = 0; c < n; ++c) {
                    // Any value beyond int32 is out of range; -1 says so without
                    // a float-to-integer overflow.
                    const double index = number(property.type);
                    soup.corners.push_back(std::abs(index) < 4e9 ? static_cast<int64_t>(index) : -1);
                }
                soup.offsets.push_back(static_cast<int64_t>(soup.corners.size()));
            }
    }

    void skip(const Element& element)
    {
        if (element.properties.empty()) return;
        require_room(element);
        for (uint64_t i = 0; i < element.count; ++i)
            for (const Property& property : element.properties) {
                if (property.list) skip_list(property);
                else number(property.type);
            }
    }

    void skip_list(const Property& property)
    {
        const uint64_t n = list_count(property);
        for (uint64_t c = 0; c < n; ++c) number(property.type);
    }

    uint64_t list_count(const Property& property)
    {
        const double n = number(property.count_type);
        if (n < 0) fail("a list has the negative length " + std::to_string(static_cast<int64_t>(n)), "");
        // Each item takes at least one byte (binary) or two (ASCII: a digit
        // and a separator): a longer list cannot be in the file.
        const uint64_t count = static_cast<uint64_t>(n);
        if (count > bytes_.size() - at_) fail("a list of " + std::to_string(count) + " items runs past the end", "");
        return count;
    }

    // Refuses an element count that the rest of the file cannot hold, before
    // anything is allocated for it.
    void require_room(const Element& element)
    {
        uint64_t least = 0; // bytes per instance, at least
        for (const Property& property : element.properties)
            least += format_ == Format::Ascii ? 2 : (property.list ? type_size(property.count_type) : type_size(property.type));
        const uint64_t left = bytes_.size() - at_;
        if (least > 0 && element.count > left / least)
            fail("its header announces " + std::to_string(element.count) + " " + element.name + " elements, which the " +
                     std::to_string(left) + " bytes after the header cannot hold",
                 "the file is truncated or damaged: copy or export it again");
    }

    double number(Type type)
    {
        if (format_ == Format::Ascii) return ascii_number(type);
        const size_t size = type_size(type);
        if (bytes_.size() - at_ < size) fail("the data ends early (the file is truncated)", "copy or export it again");
        unsigned char raw[8];
        std::memcpy(raw, bytes_.data() + at_, size);
        at_ += size;
        if ((format_ == Format::BinaryBig) != (std::endian::native == std::endian::big)) std::reverse(raw, raw + size);
        switch (type) {
        case Type::Int8: return static_cast<int8_t>(raw[0]);
        case Type::UInt8: return raw[0];
        case Type::Int16: return load<int16_t>(raw);
        case Type::UInt16: return load<uint16_t>(raw);
        case Type::Int32: return load<int32_t>(raw);
        case Type::UInt32: return load<uint32_t>(raw);
        case Type::Float32: return load<float>(raw);
        case Type::Float64: return load<double>(raw);
        }
        return 0;
    }

    template <typename T>
    static double load(const unsigned char* raw)
    {
        T value;
        std::memcpy(&value, raw, sizeof value);
        return static_cast<double>(value);
    }

    double ascii_number(Type type)
    {
        const size_t start = bytes_.find_first_not_of(" \t\r\n", at_);
        if (start == std::string::npos) fail("the data ends early (the file is truncated)", "copy or export it again");
        size_t end = bytes_.find_first_of(" \t\r\n", start);
        if (end == std::string::npos) end = bytes_.size();
        at_ = end;
        std::string_view token(bytes_.data() + start, end - start);
        if (!token.empty() && token.front() == '+') token.remove_prefix(1);
        double value = 0;
        std::from_chars_result result{};
        if (is_integer(type)) {
            int64_t integer = 0;
            result = std::from_chars(token.data(), token.data() + token.size(), integer);
            value = static_cast<double>(integer);
        } else {
            result = std::from_chars(token.data(), token.data() + token.size(), value);
        }
        if (token.empty() || result.ec != std::errc() || result.ptr != token.data() + token.size())
            fail("'" + std::string(token.substr(0, 40)) + "' is not " + (is_integer(type) ? "an integer" : "a number"),
                 "the file is damaged: export it again");
        return value;
    }

    [[noreturn]] void fail_header(const std::string& what, const std::string& hint) const
    {
        throw InputError(path_.string() + " is not a valid PLY file: " + what,
                         hint.empty() ? "the header is damaged: export the surface again" : hint);
    }

    [[noreturn]] void fail(const std::string& what, const std::string& hint) const
    {
        throw InputError(path_.string() + ": " + what, hint.empty() ? "the file is damaged: export it again" : hint);
    }

    const std::string& bytes_;
    const std::filesystem::path& path_;
    size_t at_ = 0;
    Format format_ = Format::Ascii;
    std::vector<Element> elements_;
};

} // namespace

SurfaceMesh read_ply(const std::filesystem::path& path, double scale)
{
    require_scale(scale);
    const std::string bytes = read_file_bytes(path);
    const PolygonSoup soup = PlyReader(bytes, path).read();
    if (soup.points.empty() && soup.offsets.size() == 1)
        throw InputError(path.string() + " holds no vertices and no faces", "export a surface that has triangles");
    return weld_polygons(soup, scale, path);
}

} // namespace scalemesh
