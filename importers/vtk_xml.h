#pragma once
// The VTK XML file format as the .vtp and .vti readers share it: the XML
// through expat, and the DataArrays decoded from every encoding VTK writes
// (ascii; inline base64 "binary"; appended raw or base64; each binary one
// plain or zlib-compressed in blocks, with a UInt32 or UInt64 header; little-
// or big-endian). Internal to importers/.
//
// Every count, offset and size the file states is checked against the bytes
// that are there before anything is allocated for it; every failure is an
// InputError that starts with the reader's `prefix`.

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace scalemesh::vtk_xml {

enum class ScalarType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Int64, UInt64, Float32, Float64 };

// nullopt for a name VTK XML does not define.
std::optional<ScalarType> scalar_type(std::string_view name);
size_t scalar_size(ScalarType type);
bool is_integer(ScalarType type);

struct Element {
    std::string name;
    std::map<std::string, std::string> attributes;
    std::string text; // character data, kept for DataArray only
    std::vector<Element> children;

    // The attribute's value, empty when absent.
    std::string attribute(const std::string& key) const;
    // The first child of that name, or nullptr.
    const Element* child(std::string_view child_name) const;
};

// A DataArray's values in the machine's byte order, as the declared type.
struct Array {
    std::string name;
    ScalarType type = ScalarType::UInt8;
    int components = 1;
    uint64_t bytes = 0;
    std::unique_ptr<char[]> data; // aligned for any scalar type

    uint64_t size() const { return bytes / scalar_size(type); } // values, all components
    double value(uint64_t i) const;
    // The integer value i of an integer array; nullopt beyond int64.
    std::optional<int64_t> integer(uint64_t i) const;
};

class Document {
public:
    // Parses `bytes` as a VTKFile of type `type` ("PolyData", "ImageData").
    // `bytes` must outlive the Document: appended data are read in place.
    // `prefix` begins every error message ("<path> is not a VTK PolyData
    // surface scalemesh reads: ").
    Document(const std::string& bytes, const std::string& type, std::string prefix);

    // The <PolyData> or <ImageData> element.
    const Element& dataset() const { return *dataset_; }

    // Decodes a DataArray. `what` names it in errors ("piece 0 points");
    // `expected_values`, when known, is the number of values (all components)
    // it must hold, checked before its data are allocated.
    Array read(const Element& data_array, const std::string& what,
               std::optional<uint64_t> expected_values = std::nullopt) const;

    [[noreturn]] void fail(const std::string& what, const std::string& hint = "") const;

private:
    class Source;
    void read_plain(Source& source, Array& array, const std::string& what, std::optional<uint64_t> expected) const;
    void read_compressed(Source& source, Array& array, const std::string& what,
                         std::optional<uint64_t> expected) const;
    void read_ascii(const Element& e, Array& array, const std::string& what) const;
    uint64_t word(Source& source) const;

    std::string prefix_;
    Element root_;
    const Element* dataset_ = nullptr;
    std::string_view appended_; // the bytes after AppendedData's '_' (raw), or its text (base64)
    bool has_appended_ = false;
    bool appended_base64_ = false;
    bool big_endian_ = false;
    size_t header_bytes_ = 4;
    bool compressed_ = false;
    std::string xml_; // the XML part when the file has appended data
    uint64_t file_bytes_ = 0;
    mutable uint64_t inflated_ = 0; // bytes decompressed so far
};

} // namespace scalemesh::vtk_xml
