#include "importers/vtk_xml.h"

#include "core/errors.h"

#include <expat.h>
#include <zlib.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cstring>
#include <limits>

namespace scalemesh::vtk_xml {

namespace {

const char* const kDamaged = "the file is truncated or damaged: export it again";

// Deepest element nesting accepted; VTK files nest five levels. The element
// tree is freed recursively, so a hostile depth must not reach the stack.
constexpr size_t kMaxDepth = 64;

// zlib's deflate packs at most 1032 bytes into one; a block claiming more
// is refused before its buffer is allocated.
constexpr uint64_t kMaxCompressionRatio = 1032;
constexpr uint64_t kBlockSlack = 64; // zlib's header and an empty stream's bytes

struct Parse {
    XML_Parser parser = nullptr;
    std::vector<Element*> open; // the path from the root down
    Element root;
    bool have_root = false;
    std::string error;

    void stop(std::string what)
    {
        if (error.empty()) error = std::move(what);
        XML_StopParser(parser, XML_FALSE);
    }
};

// expat's callbacks must not throw through its C frames: the first problem
// is stored and parsing stopped.
void XMLCALL on_start(void* data, const XML_Char* name, const XML_Char** attributes)
{
    Parse& p = *static_cast<Parse*>(data);
    if (p.open.size() >= kMaxDepth) return p.stop("its elements nest deeper than " + std::to_string(kMaxDepth));
    Element* e = nullptr;
    if (p.open.empty()) {
        e = &p.root;
        p.have_root = true;
    } else {
        p.open.back()->children.emplace_back();
        e = &p.open.back()->children.back();
    }
    e->name = name;
    for (int i = 0; attributes[i] && attributes[i + 1]; i += 2) e->attributes[attributes[i]] = attributes[i + 1];
    p.open.push_back(e);
}

void XMLCALL on_end(void* data, const XML_Char*)
{
    // expat may still call this for the empty element whose start was refused.
    Parse& p = *static_cast<Parse*>(data);
    if (!p.open.empty()) p.open.pop_back();
}

void XMLCALL on_text(void* data, const XML_Char* text, int length)
{
    Parse& p = *static_cast<Parse*>(data);
    if (!p.open.empty() && p.open.back()->name == "DataArray")
        p.open.back()->text.append(text, static_cast<size_t>(length));
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

int base64_value(char c)
{
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    if (c == '=') return -1;
    return -2;
}

void swap_bytes(char* data, uint64_t bytes, size_t size)
{
    if (size == 1) return;
    for (uint64_t i = 0; i + size <= bytes; i += size) std::reverse(data + i, data + i + size);
}

std::unique_ptr<char[]> allocate(uint64_t bytes)
{
    // new[] aligns for every scalar type; one byte more keeps an empty array
    // a valid pointer.
    return std::unique_ptr<char[]>(new char[bytes + 1]);
}

template <typename T>
T load(const char* data, uint64_t i)
{
    T v;
    std::memcpy(&v, data + i * sizeof(T), sizeof(T));
    return v;
}

} // namespace

std::optional<ScalarType> scalar_type(std::string_view name)
{
    static const std::pair<std::string_view, ScalarType> kNames[] = {
        {"Int8", ScalarType::Int8},       {"UInt8", ScalarType::UInt8},     {"Int16", ScalarType::Int16},
        {"UInt16", ScalarType::UInt16},   {"Int32", ScalarType::Int32},     {"UInt32", ScalarType::UInt32},
        {"Int64", ScalarType::Int64},     {"UInt64", ScalarType::UInt64},   {"Float32", ScalarType::Float32},
        {"Float64", ScalarType::Float64}, {"Char", ScalarType::Int8},       {"UChar", ScalarType::UInt8}};
    for (const auto& [n, t] : kNames)
        if (n == name) return t;
    return std::nullopt;
}

size_t scalar_size(ScalarType type)
{
    switch (type) {
    case ScalarType::Int8: case ScalarType::UInt8: return 1;
    case ScalarType::Int16: case ScalarType::UInt16: return 2;
    case ScalarType::Int32: case ScalarType::UInt32: case ScalarType::Float32: return 4;
    case ScalarType::Int64: case ScalarType::UInt64: case ScalarType::Float64: return 8;
    }
    return 1;
}

bool is_integer(ScalarType type) { return type != ScalarType::Float32 && type != ScalarType::Float64; }

std::string Element::attribute(const std::string& key) const
{
    const auto it = attributes.find(key);
    return it == attributes.end() ? std::string() : it->second;
}

const Element* Element::child(std::string_view child_name) const
{
    for (const Element& c : children)
        if (c.name == child_name) return &c;
    return nullptr;
}

double Array::value(uint64_t i) const
{
    const char* d = data.get();
    switch (type) {
    case ScalarType::Int8: return load<int8_t>(d, i);
    case ScalarType::UInt8: return load<uint8_t>(d, i);
    case ScalarType::Int16: return load<int16_t>(d, i);
    case ScalarType::UInt16: return load<uint16_t>(d, i);
    case ScalarType::Int32: return load<int32_t>(d, i);
    case ScalarType::UInt32: return load<uint32_t>(d, i);
    case ScalarType::Int64: return static_cast<double>(load<int64_t>(d, i));
    case ScalarType::UInt64: return static_cast<double>(load<uint64_t>(d, i));
    case ScalarType::Float32: return load<float>(d, i);
    case ScalarType::Float64: return load<double>(d, i);
    }
    return 0;
}

std::optional<int64_t> Array::integer(uint64_t i) const
{
    const char* d = data.get();
    switch (type) {
    case ScalarType::Int8: return load<int8_t>(d, i);
    case ScalarType::UInt8: return load<uint8_t>(d, i);
    case ScalarType::Int16: return load<int16_t>(d, i);
    case ScalarType::UInt16: return load<uint16_t>(d, i);
    case ScalarType::Int32: return load<int32_t>(d, i);
    case ScalarType::UInt32: return load<uint32_t>(d, i);
    case ScalarType::Int64: return load<int64_t>(d, i);
    case ScalarType::UInt64: {
        const uint64_t v = load<uint64_t>(d, i);
        if (v > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) return std::nullopt;
        return static_cast<int64_t>(v);
    }
    default: return std::nullopt;
    }
}

// The bytes of one binary DataArray: raw appended bytes from its offset, or
// base64 text (inline, or appended from its offset) decoded as it is read.
// VTK encodes a compressed array's header apart from its data, each padded:
// base64 streams one after another are decoded one after another.
class Document::Source {
public:
    Source(std::string_view bytes, bool base64, const Document& doc, const std::string& what)
        : bytes_(bytes), base64_(base64), doc_(doc), what_(what)
    {
    }

    // At least the bytes left (exactly, for raw bytes).
    uint64_t at_most() const
    {
        const uint64_t left = bytes_.size() - at_;
        return base64_ ? pending_.size() + left / 4 * 3 + 3 : left;
    }

    void read(char* out, uint64_t n)
    {
        if (n > at_most()) short_of(n);
        if (!base64_) {
            std::memcpy(out, bytes_.data() + at_, n);
            at_ += n;
            return;
        }
        uint64_t done = 0;
        while (done < n) {
            if (pending_.empty()) decode_group(n);
            const uint64_t take = std::min<uint64_t>(n - done, pending_.size());
            std::memcpy(out + done, pending_.data(), take);
            pending_.erase(0, take);
            done += take;
        }
    }

private:
    [[noreturn]] void short_of(uint64_t n) const
    {
        doc_.fail(what_ + " need " + std::to_string(n) + " bytes more, beyond the end of the file", kDamaged);
    }

    void decode_group(uint64_t n)
    {
        uint32_t group = 0;
        int filled = 0, padding = 0;
        while (filled < 4) {
            if (at_ >= bytes_.size()) {
                if (filled == 0) short_of(n);
                doc_.fail(what_ + " end in the middle of a base64 group (the file is truncated)", kDamaged);
            }
            const char c = bytes_[at_++];
            if (is_space(c)) continue;
            int value = base64_value(c);
            if (value == -2)
                doc_.fail(what_ + " hold the character '" + std::string(1, c) + "', which is not base64", kDamaged);
            if (value < 0) {
                if (filled < 2) doc_.fail(what_ + " have misplaced base64 padding", kDamaged);
                ++padding;
                value = 0;
            } else if (padding > 0) {
                doc_.fail(what_ + " have misplaced base64 padding", kDamaged);
            }
            group = (group << 6) | static_cast<uint32_t>(value);
            ++filled;
        }
        const char decoded[3] = {static_cast<char>(group >> 16), static_cast<char>(group >> 8),
                                 static_cast<char>(group)};
        pending_.append(decoded, static_cast<size_t>(3 - padding));
    }

    std::string_view bytes_;
    bool base64_;
    const Document& doc_;
    const std::string& what_;
    uint64_t at_ = 0;
    std::string pending_; // decoded, not yet read
};

Document::Document(const std::string& bytes, const std::string& type, std::string prefix)
    : prefix_(std::move(prefix)), file_bytes_(bytes.size())
{
    // Raw appended data are not XML: the document is parsed up to the '_'
    // that begins them, and closed there.
    std::string_view xml = bytes;
    if (const size_t tag = bytes.find("<AppendedData"); tag != std::string::npos) {
        const size_t close = bytes.find('>', tag);
        if (close == std::string::npos) fail("it ends inside its <AppendedData> tag", kDamaged);
        if (bytes[close - 1] != '/') {
            const size_t marker = bytes.find_first_not_of(" \t\r\n", close + 1);
            if (marker == std::string::npos || bytes[marker] != '_')
                fail("its <AppendedData> does not begin with the '_' marker", kDamaged);
            xml_ = bytes.substr(0, marker) + "</AppendedData></VTKFile>";
            xml = xml_;
            appended_ = std::string_view(bytes).substr(marker + 1);
            has_appended_ = true;
        }
    }

    Parse p;
    p.parser = XML_ParserCreate(nullptr);
    if (!p.parser) throw std::bad_alloc();
    XML_SetUserData(p.parser, &p);
    XML_SetElementHandler(p.parser, on_start, on_end);
    XML_SetCharacterDataHandler(p.parser, on_text);
    if (xml.size() > static_cast<size_t>(std::numeric_limits<int>::max())) {
        XML_ParserFree(p.parser);
        fail("its XML is larger than 2 GB", "save the data as appended binary (ParaView: Data Mode 'Appended')");
    }
    const XML_Status status = XML_Parse(p.parser, xml.data(), static_cast<int>(xml.size()), XML_TRUE);
    const XML_LChar* message = XML_ErrorString(XML_GetErrorCode(p.parser));
    const std::string xml_error = message ? message : "unknown error";
    const auto line = XML_GetCurrentLineNumber(p.parser);
    XML_ParserFree(p.parser);
    if (!p.error.empty()) fail(p.error, kDamaged);
    if (status != XML_STATUS_OK || !p.have_root)
        fail("line " + std::to_string(line) + " is not well-formed XML (" + xml_error + ")", kDamaged);
    root_ = std::move(p.root);

    if (root_.name != "VTKFile") fail("its root element is <" + root_.name + ">, not <VTKFile>", kDamaged);
    const std::string file_type = root_.attribute("type");
    if (file_type != type)
        fail("it is not VTK " + type + " (VTKFile type=\"" + file_type + "\")",
             type == "PolyData"
                 ? "give a .vtp surface; extract the surface of other VTK data first (ParaView: Extract Surface)"
                 : "give a .vti image (VTK ImageData); resample other VTK data to an image first (ParaView: "
                   "Resample To Image)");
    dataset_ = root_.child(type);
    if (!dataset_) fail("it has no <" + type + "> element", kDamaged);

    const std::string order = root_.attribute("byte_order");
    if (order == "BigEndian") big_endian_ = true;
    else if (!order.empty() && order != "LittleEndian")
        fail("its byte_order '" + order + "' is neither LittleEndian nor BigEndian", kDamaged);
    const std::string header_type = root_.attribute("header_type");
    if (header_type == "UInt64") header_bytes_ = 8;
    else if (header_type.empty() || header_type == "UInt32") header_bytes_ = 4;
    else fail("its header_type '" + header_type + "' is neither UInt32 nor UInt64", kDamaged);
    const std::string compressor = root_.attribute("compressor");
    if (compressor == "vtkZLibDataCompressor") compressed_ = true;
    else if (!compressor.empty())
        fail("its data are compressed with " + compressor + ", which scalemesh does not read",
             "save it with Compressor Type 'ZLib' or 'None' (ParaView's writer options, or vtkXMLWriter::"
             "SetCompressorTypeToZLib)");

    if (const Element* appended = root_.child("AppendedData"); appended && has_appended_) {
        const std::string encoding = appended->attribute("encoding");
        if (encoding == "base64") {
            appended_base64_ = true;
            // Base64 text ends at the closing tag; raw bytes may hold any byte.
            appended_ = appended_.substr(0, appended_.find('<'));
        } else if (encoding != "raw") {
            fail("its <AppendedData> has the encoding '" + encoding + "', neither raw nor base64", kDamaged);
        }
    }
}

void Document::fail(const std::string& what, const std::string& hint) const
{
    throw InputError(prefix_ + what, hint.empty() ? kDamaged : hint);
}

uint64_t Document::word(Source& source) const
{
    char raw[8];
    source.read(raw, header_bytes_);
    if (big_endian_ != (std::endian::native == std::endian::big)) std::reverse(raw, raw + header_bytes_);
    if (header_bytes_ == 4) return load<uint32_t>(raw, 0);
    return load<uint64_t>(raw, 0);
}

Array Document::read(const Element& e, const std::string& what, std::optional<uint64_t> expected) const
{
    Array array;
    array.name = e.attribute("Name");
    const std::string type_name = e.attribute("type");
    const std::optional<ScalarType> type = scalar_type(type_name);
    if (!type) fail(what + " have the unknown type '" + type_name + "'", kDamaged);
    array.type = *type;
    const std::string components = e.attribute("NumberOfComponents");
    if (!components.empty()) {
        int n = 0;
        const auto [end, error] = std::from_chars(components.data(), components.data() + components.size(), n);
        if (error != std::errc() || end != components.data() + components.size() || n < 1 || n > 64)
            fail(what + " have NumberOfComponents=\"" + components.substr(0, 40) + "\", not a count from 1 to 64",
                 kDamaged);
        array.components = n;
    }
    const size_t size = scalar_size(array.type);
    // Every count the readers pass is below 2^60: no product overflows.
    if (expected && *expected > (uint64_t{1} << 60) / size)
        fail(what + " would hold " + std::to_string(*expected) + " values, more than any file holds", kDamaged);

    const std::string format = e.attribute("format");
    if (format == "ascii") {
        read_ascii(e, array, what);
    } else if (format == "binary") {
        Source source(e.text, true, *this, what);
        compressed_ ? read_compressed(source, array, what, expected) : read_plain(source, array, what, expected);
    } else if (format == "appended") {
        if (!has_appended_) fail(what + " are appended, but the file has no <AppendedData>", kDamaged);
        const std::string text = e.attribute("offset");
        uint64_t offset = 0;
        const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), offset);
        if (text.empty() || error != std::errc() || end != text.data() + text.size())
            fail(what + " have the offset \"" + text.substr(0, 40) + "\", which is not a count", kDamaged);
        if (offset > appended_.size())
            fail(what + " begin at offset " + text + ", past the end of the " + std::to_string(appended_.size()) +
                     " bytes of appended data",
                 kDamaged);
        Source source(appended_.substr(offset), appended_base64_, *this, what);
        compressed_ ? read_compressed(source, array, what, expected) : read_plain(source, array, what, expected);
    } else {
        fail(what + " have the unknown format '" + format + "' (ascii, binary or appended)", kDamaged);
    }

    if (array.bytes % (size * static_cast<uint64_t>(array.components)) != 0)
        fail(what + " hold " + std::to_string(array.bytes) + " bytes, not a whole number of " +
                 std::to_string(array.components) + "-component " + type_name + " tuples",
             kDamaged);
    if (expected && array.size() != *expected)
        fail(what + " hold " + std::to_string(array.size()) + " values where " + std::to_string(*expected) +
                 " are announced",
             kDamaged);
    if (format != "ascii" && big_endian_ != (std::endian::native == std::endian::big))
        swap_bytes(array.data.get(), array.bytes, size);
    return array;
}

void Document::read_plain(Source& source, Array& array, const std::string& what,
                          std::optional<uint64_t> expected) const
{
    const uint64_t length = word(source);
    if (length > source.at_most())
        fail(what + " announce " + std::to_string(length) + " bytes, but at most " +
                 std::to_string(source.at_most()) + " follow",
             kDamaged);
    const uint64_t size = scalar_size(array.type);
    if (expected && length != *expected * size)
        fail(what + " announce " + std::to_string(length) + " bytes where " + std::to_string(*expected) +
                 " values take " + std::to_string(*expected * size),
             kDamaged);
    array.data = allocate(length);
    array.bytes = length;
    source.read(array.data.get(), length);
}

// VTK's compressed layout: a header [number of blocks, uncompressed block
// size, uncompressed size of the last block (0: a whole block), compressed
// size of each block], then the blocks, each one zlib stream.
void Document::read_compressed(Source& source, Array& array, const std::string& what,
                               std::optional<uint64_t> expected) const
{
    const uint64_t blocks = word(source);
    const uint64_t block_size = word(source);
    const uint64_t last_size = word(source);
    if (blocks > source.at_most() / header_bytes_)
        fail(what + " announce " + std::to_string(blocks) + " compressed blocks, more than the file can hold",
             kDamaged);
    std::vector<uint64_t> packed(blocks);
    uint64_t packed_total = 0;
    for (uint64_t& p : packed) {
        p = word(source);
        if (p > source.at_most() - std::min(source.at_most(), packed_total))
            fail(what + " announce compressed blocks longer than the " + std::to_string(source.at_most()) +
                     " bytes that follow",
                 kDamaged);
        packed_total += p;
    }
    if (blocks > 0 && block_size == 0) fail(what + " announce compressed blocks of 0 bytes", kDamaged);
    if (last_size > block_size)
        fail(what + " announce a last block of " + std::to_string(last_size) + " bytes, larger than the blocks' " +
                 std::to_string(block_size),
             kDamaged);
    uint64_t total = 0;
    std::vector<uint64_t> unpacked(blocks);
    for (uint64_t b = 0; b < blocks; ++b) {
        unpacked[b] = b + 1 == blocks && last_size != 0 ? last_size : block_size;
        if (unpacked[b] > packed[b] * kMaxCompressionRatio + kBlockSlack)
            fail(what + ": block " + std::to_string(b) + " claims " + std::to_string(unpacked[b]) + " bytes from " +
                     std::to_string(packed[b]) + " compressed bytes, more than zlib can pack into them",
                 kDamaged);
        total += unpacked[b];
    }
    // Pieces may all point at one compressed array: the whole file may
    // inflate to no more than zlib could have packed into it.
    inflated_ += total;
    if (inflated_ > file_bytes_ * kMaxCompressionRatio + (uint64_t{1} << 20))
        fail(what + " bring the data decompressed from this file to " + std::to_string(inflated_) +
                 " bytes, more than zlib can pack into its " + std::to_string(file_bytes_),
             kDamaged);
    const uint64_t size = scalar_size(array.type);
    if (expected && total != *expected * size)
        fail(what + " decompress to " + std::to_string(total) + " bytes where " + std::to_string(*expected) +
                 " values take " + std::to_string(*expected * size),
             kDamaged);
    array.data = allocate(total);
    array.bytes = total;
    std::string block;
    uint64_t at = 0;
    for (uint64_t b = 0; b < blocks; ++b) {
        block.resize(packed[b]);
        source.read(block.data(), packed[b]);
        uLongf length = static_cast<uLongf>(unpacked[b]);
        const int status = uncompress(reinterpret_cast<Bytef*>(array.data.get() + at), &length,
                                      reinterpret_cast<const Bytef*>(block.data()), static_cast<uLong>(packed[b]));
        if (status != Z_OK || length != unpacked[b])
            fail(what + ": compressed block " + std::to_string(b) + " does not decompress to its announced " +
                     std::to_string(unpacked[b]) + " bytes (" +
                     (status == Z_OK ? std::to_string(length) + " bytes"
                      : status == Z_BUF_ERROR ? std::string("more, or cut short")
                                              : std::string("zlib: ") + zError(status)) +
                     ")",
                 kDamaged);
        at += unpacked[b];
    }
}

void Document::read_ascii(const Element& e, Array& array, const std::string& what) const
{
    // Parsed straight into the declared type, so that a Float32 written
    // with nine digits reads back to the same bits.
    std::vector<char> out;
    const size_t size = scalar_size(array.type);
    const std::string& text = e.text;
    size_t at = 0;
    for (;;) {
        const size_t start = text.find_first_not_of(" \t\r\n", at);
        if (start == std::string::npos) break;
        size_t end = text.find_first_of(" \t\r\n", start);
        if (end == std::string::npos) end = text.size();
        at = end;
        std::string_view token(text.data() + start, end - start);
        if (token.front() == '+') token.remove_prefix(1);
        char raw[8];
        bool ok = false;
        const auto whole = [&](const std::from_chars_result& r) {
            return !token.empty() && r.ec == std::errc() && r.ptr == token.data() + token.size();
        };
        const auto integer = [&]<typename T>(T) {
            T v{};
            if (std::is_signed_v<T>) {
                int64_t w = 0;
                if (whole(std::from_chars(token.data(), token.data() + token.size(), w)) &&
                    w >= std::numeric_limits<T>::min() && w <= std::numeric_limits<T>::max()) {
                    v = static_cast<T>(w);
                    ok = true;
                }
            } else {
                uint64_t w = 0;
                if (whole(std::from_chars(token.data(), token.data() + token.size(), w)) &&
                    w <= std::numeric_limits<T>::max()) {
                    v = static_cast<T>(w);
                    ok = true;
                }
            }
            std::memcpy(raw, &v, sizeof(T));
        };
        switch (array.type) {
        case ScalarType::Int8: integer(int8_t{}); break;
        case ScalarType::UInt8: integer(uint8_t{}); break;
        case ScalarType::Int16: integer(int16_t{}); break;
        case ScalarType::UInt16: integer(uint16_t{}); break;
        case ScalarType::Int32: integer(int32_t{}); break;
        case ScalarType::UInt32: integer(uint32_t{}); break;
        case ScalarType::Int64: integer(int64_t{}); break;
        case ScalarType::UInt64: integer(uint64_t{}); break;
        case ScalarType::Float32: {
            float v = 0;
            ok = whole(std::from_chars(token.data(), token.data() + token.size(), v));
            std::memcpy(raw, &v, 4);
            break;
        }
        case ScalarType::Float64: {
            double v = 0;
            ok = whole(std::from_chars(token.data(), token.data() + token.size(), v));
            std::memcpy(raw, &v, 8);
            break;
        }
        }
        if (!ok)
            fail(what + " hold '" + std::string(token.substr(0, 40)) + "', which is not " +
                     (is_integer(array.type) ? "an integer in the range of " : "a number of type ") +
                     e.attribute("type"),
                 kDamaged);
        out.insert(out.end(), raw, raw + size);
    }
    array.bytes = out.size();
    array.data = allocate(array.bytes);
    if (!out.empty()) std::memcpy(array.data.get(), out.data(), out.size());
}

} // namespace scalemesh::vtk_xml
