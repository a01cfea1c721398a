// VTK XML PolyData (.vtp) reading: the XML through expat, the DataArrays
// decoded here. All of VTK would be needed for VTK's own reader; the subset
// below (ASCII and inline base64 binary, uncompressed) is what a surface needs.

#include "core/errors.h"
#include "importers/polygon_soup.h"
#include "importers/surface_importer.h"

#include <expat.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>
#include <optional>
#include <string_view>

namespace scalemesh {

namespace {

const char* const kSaveHint = "save it from ParaView with Data Mode 'Ascii' or 'Binary' and Compressor Type 'None' "
                              "(or as .stl or .ply)";

struct DataArray {
    std::string parent; // Points or Polys
    std::map<std::string, std::string> attributes;
    std::string text;
};

struct Piece {
    std::map<std::string, std::string> attributes;
    std::vector<DataArray> arrays; // of Points and Polys only
};

// What the expat callbacks collect. They cannot throw through expat's C
// frames: the first problem is stored and parsing stopped.
struct Document {
    XML_Parser parser = nullptr;
    std::vector<std::string> open; // element names from the root down
    std::map<std::string, std::string> file_attributes; // of VTKFile
    std::vector<Piece> pieces;
    DataArray* collecting = nullptr;
    std::string error, hint;

    void stop(std::string what, std::string advice = "")
    {
        if (error.empty()) {
            error = std::move(what);
            hint = std::move(advice);
        }
        XML_StopParser(parser, XML_FALSE);
    }
};

std::map<std::string, std::string> attribute_map(const XML_Char** attributes)
{
    std::map<std::string, std::string> out;
    for (int i = 0; attributes[i] && attributes[i + 1]; i += 2) out[attributes[i]] = attributes[i + 1];
    return out;
}

void XMLCALL on_start(void* data, const XML_Char* name_c, const XML_Char** attributes)
{
    Document& doc = *static_cast<Document*>(data);
    const std::string name = name_c;
    const std::string parent = doc.open.empty() ? "" : doc.open.back();
    doc.open.push_back(name);
    if (doc.open.size() == 1) {
        if (name != "VTKFile") return doc.stop("its root element is <" + name + ">, not <VTKFile>");
        doc.file_attributes = attribute_map(attributes);
    } else if (name == "AppendedData") {
        doc.stop("its data is appended (<AppendedData>), which scalemesh does not read", kSaveHint);
    } else if (name == "Piece" && parent == "PolyData") {
        doc.pieces.push_back({attribute_map(attributes), {}});
    } else if (name == "DataArray" && (parent == "Points" || parent == "Polys") && !doc.pieces.empty() &&
               doc.open.size() >= 4 && doc.open[doc.open.size() - 3] == "Piece") {
        doc.pieces.back().arrays.push_back({parent, attribute_map(attributes), {}});
        doc.collecting = &doc.pieces.back().arrays.back();
    }
}

void XMLCALL on_end(void* data, const XML_Char*)
{
    Document& doc = *static_cast<Document*>(data);
    doc.open.pop_back();
    doc.collecting = nullptr;
}

void XMLCALL on_text(void* data, const XML_Char* text, int length)
{
    Document& doc = *static_cast<Document*>(data);
    if (doc.collecting) doc.collecting->text.append(text, static_cast<size_t>(length));
}

class VtpReader {
public:
    explicit VtpReader(const std::filesystem::path& path) : path_(path) {}

    PolygonSoup read(const std::string& bytes)
    {
        Document doc;
        doc.parser = XML_ParserCreate(nullptr);
        if (!doc.parser) throw std::bad_alloc();
        XML_SetUserData(doc.parser, &doc);
        XML_SetElementHandler(doc.parser, on_start, on_end);
        XML_SetCharacterDataHandler(doc.parser, on_text);
        const XML_Status status =
            XML_Parse(doc.parser, bytes.data(), static_cast<int>(std::min<size_t>(bytes.size(), INT32_MAX)), XML_TRUE);
        const XML_LChar* message = XML_ErrorString(XML_GetErrorCode(doc.parser));
        const std::string xml_error = message ? message : "unknown error";
        const auto line = XML_GetCurrentLineNumber(doc.parser);
        XML_ParserFree(doc.parser);
        if (!doc.error.empty()) fail(doc.error, doc.hint);
        if (status != XML_STATUS_OK)
            fail("line " + std::to_string(line) + " is not well-formed XML (" + xml_error + ")",
                 "the file is truncated or damaged: export it again");

        const auto type = doc.file_attributes.find("type");
        if (type == doc.file_attributes.end() || type->second != "PolyData")
            fail("it is not VTK PolyData (VTKFile type=\"" +
                     (type == doc.file_attributes.end() ? std::string() : type->second) + "\")",
                 "give a .vtp surface; extract the surface of other VTK data first (ParaView: Extract Surface)");
        big_endian_ = attribute(doc.file_attributes, "byte_order") == "BigEndian";
        const std::string header_type = attribute(doc.file_attributes, "header_type");
        if (header_type == "UInt64") header_bytes_ = 8;
        else if (header_type.empty() || header_type == "UInt32") header_bytes_ = 4;
        else fail("its header_type '" + header_type + "' is unknown", "");
        compressed_ = !attribute(doc.file_attributes, "compressor").empty();
        if (doc.pieces.empty()) fail("it holds no <Piece>", "export a surface that has triangles");

        PolygonSoup soup;
        for (size_t p = 0; p < doc.pieces.size(); ++p) read_piece(doc.pieces[p], p, soup);
        return soup;
    }

private:
    void read_piece(const Piece& piece, size_t index, PolygonSoup& soup)
    {
        const std::string where = "piece " + std::to_string(index);
        for (const char* kind : {"NumberOfVerts", "NumberOfLines", "NumberOfStrips"})
            if (count(piece.attributes, kind, where) != 0)
                fail(where + " has " + kind + " = " + attribute(piece.attributes, kind) +
                         ": only polygons (<Polys>) make a surface",
                     "triangulate the surface and remove vertices and lines (ParaView: Extract Surface, Triangulate)");
        const uint64_t n_points = count(piece.attributes, "NumberOfPoints", where);
        const uint64_t n_polys = count(piece.attributes, "NumberOfPolys", where);
        const DataArray* points = nullptr;
        const DataArray* connectivity = nullptr;
        const DataArray* offsets = nullptr;
        for (const DataArray& array : piece.arrays) {
            if (array.parent == "Points" && !points) points = &array;
            const std::string name = attribute(array.attributes, "Name");
            if (array.parent == "Polys" && name == "connectivity") connectivity = &array;
            if (array.parent == "Polys" && name == "offsets") offsets = &array;
        }
        if (n_points > 0 && !points) fail(where + " has no <Points> DataArray", "");
        if (n_polys > 0 && (!connectivity || !offsets))
            fail(where + " has no <Polys> connectivity and offsets DataArrays", "");

        const size_t base = soup.points.size();
        if (points) {
            if (attribute(points->attributes, "NumberOfComponents") != "3")
                fail(where + ": its points do not have NumberOfComponents=\"3\"", "");
            const std::vector<double> xyz = values(*points, where + " points");
            if (xyz.size() != 3 * n_points)
                fail(where + " announces " + std::to_string(n_points) + " points but holds " +
                         std::to_string(xyz.size()) + " coordinates",
                     "");
            for (size_t i = 0; i < n_points; ++i) soup.points.push_back({xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]});
        }
        if (n_polys == 0) return;
        const std::vector<double> corners = values(*connectivity, where + " connectivity");
        std::vector<double> ends = values(*offsets, where + " offsets");
        // VTK 9 writes n + 1 offsets starting at 0; older files the n ends.
        if (ends.size() == n_polys + 1 && ends.front() == 0) ends.erase(ends.begin());
        if (ends.size() != n_polys)
            fail(where + " announces " + std::to_string(n_polys) + " polygons but holds " +
                     std::to_string(ends.size()) + " offsets",
                 "");
        double previous = 0;
        for (double end : ends) {
            if (!(end >= previous && end <= static_cast<double>(corners.size())))
                fail(where + ": its polygon offsets are not increasing within the " + std::to_string(corners.size()) +
                         " connectivity entries",
                     "");
            for (size_t c = static_cast<size_t>(previous); c < static_cast<size_t>(end); ++c)
                soup.corners.push_back(std::abs(corners[c]) < 4e9 ? static_cast<int64_t>(corners[c]) + static_cast<int64_t>(base)
                                                                 : -1);
            soup.offsets.push_back(static_cast<int64_t>(soup.corners.size()));
            previous = end;
        }
        // A piece's indices stay within its own points.
        for (size_t c = static_cast<size_t>(soup.offsets[soup.offsets.size() - 1 - n_polys]); c < soup.corners.size(); ++c)
            if (soup.corners[c] >= static_cast<int64_t>(soup.points.size()) || soup.corners[c] < static_cast<int64_t>(base))
                fail(where + " has a polygon corner outside its " + std::to_string(n_points) + " points",
                     "the file is damaged or its indices are off: export it again");
    }

    uint64_t count(const std::map<std::string, std::string>& attributes, const std::string& key, const std::string& where)
    {
        const std::string text = attribute(attributes, key);
        if (text.empty()) return 0;
        uint64_t value = 0;
        const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
        if (error != std::errc() || end != text.data() + text.size())
            fail(where + ": " + key + "=\"" + text + "\" is not a count", "");
        return value;
    }

    static std::string attribute(const std::map<std::string, std::string>& attributes, const std::string& key)
    {
        const auto it = attributes.find(key);
        return it == attributes.end() ? std::string() : it->second;
    }

    std::vector<double> values(const DataArray& array, const std::string& what)
    {
        const std::string type = attribute(array.attributes, "type");
        const size_t size = type_size(type);
        if (size == 0) fail(what + " have the unknown type '" + type + "'", "");
        const std::string format = attribute(array.attributes, "format");
        if (format == "ascii") return ascii_values(array.text, type, what);
        if (format == "appended")
            fail(what + " are appended data, which scalemesh does not read", kSaveHint);
        if (format != "binary") fail(what + " have the unknown format '" + format + "'", "");
        if (compressed_) fail(what + " are compressed, which scalemesh does not read", kSaveHint);

        const std::string bytes = base64(array.text, what);
        if (bytes.size() < header_bytes_) fail(what + " are shorter than their header", "");
        uint64_t length = header_bytes_ == 8 ? load<uint64_t>(bytes.data()) : load<uint32_t>(bytes.data());
        if (length > bytes.size() - header_bytes_ || length % size != 0)
            fail(what + " announce " + std::to_string(length) + " bytes but hold " +
                     std::to_string(bytes.size() - header_bytes_),
                 "the file is truncated or damaged: export it again");
        std::vector<double> out(length / size);
        const char* data = bytes.data() + header_bytes_;
        for (size_t i = 0; i < out.size(); ++i) out[i] = binary_value(type, data + i * size);
        return out;
    }

    static size_t type_size(const std::string& type)
    {
        if (type == "Int8" || type == "UInt8") return 1;
        if (type == "Int16" || type == "UInt16") return 2;
        if (type == "Int32" || type == "UInt32" || type == "Float32") return 4;
        if (type == "Int64" || type == "UInt64" || type == "Float64") return 8;
        return 0;
    }

    template <typename T>
    T load(const char* raw) const
    {
        char buffer[sizeof(T)];
        std::memcpy(buffer, raw, sizeof(T));
        if (big_endian_ != (std::endian::native == std::endian::big)) std::reverse(buffer, buffer + sizeof(T));
        T value;
        std::memcpy(&value, buffer, sizeof(T));
        return value;
    }

    double binary_value(const std::string& type, const char* raw) const
    {
        if (type == "Int8") return load<int8_t>(raw);
        if (type == "UInt8") return load<uint8_t>(raw);
        if (type == "Int16") return load<int16_t>(raw);
        if (type == "UInt16") return load<uint16_t>(raw);
        if (type == "Int32") return load<int32_t>(raw);
        if (type == "UInt32") return load<uint32_t>(raw);
        if (type == "Int64") return static_cast<double>(load<int64_t>(raw));
        if (type == "UInt64") return static_cast<double>(load<uint64_t>(raw));
        if (type == "Float32") return load<float>(raw);
        return load<double>(raw);
    }

    std::vector<double> ascii_values(const std::string& text, const std::string& type, const std::string& what)
    {
        std::vector<double> out;
        const bool integer = type.find("Int") != std::string::npos;
        size_t at = 0;
        for (;;) {
            const size_t start = text.find_first_not_of(" \t\r\n", at);
            if (start == std::string::npos) break;
            size_t end = text.find_first_of(" \t\r\n", start);
            if (end == std::string::npos) end = text.size();
            at = end;
            std::string_view token(text.data() + start, end - start);
            if (token.front() == '+') token.remove_prefix(1);
            double value = 0;
            std::from_chars_result result{};
            if (integer) {
                int64_t v = 0;
                result = std::from_chars(token.data(), token.data() + token.size(), v);
                value = static_cast<double>(v);
            } else {
                result = std::from_chars(token.data(), token.data() + token.size(), value);
            }
            if (token.empty() || result.ec != std::errc() || result.ptr != token.data() + token.size())
                fail(what + " hold '" + std::string(token.substr(0, 40)) + "', which is not " +
                         (integer ? "an integer" : "a number"),
                     "");
            out.push_back(value);
        }
        return out;
    }

    // Decodes base64, padding included; streams encoded one after another
    // (VTK encodes a compressed array's header apart from its data) are
    // decoded one after another.
    std::string base64(const std::string& text, const std::string& what)
    {
        std::string out;
        out.reserve(text.size() / 4 * 3);
        uint32_t group = 0;
        int filled = 0, padding = 0;
        for (char c : text) {
            int value;
            if (c >= 'A' && c <= 'Z') value = c - 'A';
            else if (c >= 'a' && c <= 'z') value = c - 'a' + 26;
            else if (c >= '0' && c <= '9') value = c - '0' + 52;
            else if (c == '+') value = 62;
            else if (c == '/') value = 63;
            else if (c == '=') value = -1;
            else if (c == ' ' || c == '\n' || c == '\r' || c == '\t') continue;
            else fail(what + " hold the character '" + std::string(1, c) + "', which is not base64", "");
            if (value < 0) {
                if (filled < 2) fail(what + " have misplaced base64 padding", "");
                ++padding;
                value = 0;
            } else if (padding > 0) {
                fail(what + " have misplaced base64 padding", "");
            }
            group = (group << 6) | static_cast<uint32_t>(value);
            if (++filled == 4) {
                const char decoded[3] = {static_cast<char>(group >> 16), static_cast<char>(group >> 8),
                                         static_cast<char>(group)};
                out.append(decoded, 3 - padding);
                group = 0;
                filled = 0;
                padding = 0;
            }
        }
        if (filled != 0) fail(what + " end in the middle of a base64 group (the file is truncated)", "");
        return out;
    }

    [[noreturn]] void fail(const std::string& what, const std::string& hint) const
    {
        throw InputError(path_.string() + " is not a VTK PolyData surface scalemesh reads: " + what,
                         hint.empty() ? "the file is damaged: export it again" : hint);
    }

    const std::filesystem::path& path_;
    bool big_endian_ = false;
    size_t header_bytes_ = 4;
    bool compressed_ = false;
};

} // namespace

SurfaceMesh read_vtp(const std::filesystem::path& path, double scale)
{
    require_scale(scale);
    const std::string bytes = read_file_bytes(path);
    const PolygonSoup soup = VtpReader(path).read(bytes);
    return weld_polygons(soup, scale, path);
}

} // namespace scalemesh
