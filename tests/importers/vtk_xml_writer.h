#pragma once
// VTK XML files written the way VTK's vtkXMLWriter lays them out, in every
// encoding the readers take, so that tests and fuzz seeds have .vtp and .vti
// inputs whose content is known independently of the readers:
//   ascii            values as text
//   binary           inline base64 of [header][data]
//   appended raw     the same bytes after <AppendedData encoding="raw">'s '_'
//   appended base64  as binary, appended
// each binary one plain ([byte count][data]) or zlib-compressed
// ([blocks, block size, last block size or 0, compressed sizes...][blocks];
// header and blocks base64-encoded apart), with a UInt32 or UInt64 header,
// little- or big-endian.

#include "core/surface_mesh.h"
#include "importers/surface_files.h"

#include <zlib.h>

#include <array>
#include <cstdint>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

namespace scalemesh::test::vtk {

enum class Encoding { Ascii, Binary, AppendedRaw, AppendedBase64 };

struct Options {
    Encoding encoding = Encoding::AppendedRaw;
    bool zlib = false;           // vtkZLibDataCompressor
    bool header64 = false;       // header_type UInt64 (else UInt32)
    bool big_endian = false;     // byte_order BigEndian
    size_t block_size = 32768;   // uncompressed bytes per compressed block (VTK's default)
    bool float32_points = false; // Float32 points (else Float64)
    bool int32_indices = false;  // Int32 connectivity and offsets (else Int64)
};

inline std::string name(const Options& o)
{
    const char* encodings[] = {"ascii", "binary", "appended_raw", "appended_base64"};
    std::string n = encodings[static_cast<int>(o.encoding)];
    if (o.encoding != Encoding::Ascii) {
        n += o.zlib ? "_zlib" : "";
        n += o.header64 ? "_h64" : "_h32";
        n += o.big_endian ? "_big" : "";
    }
    return n;
}

// Every combination of encoding, compression, header type and byte order.
inline std::vector<Options> all_options()
{
    std::vector<Options> out{{Encoding::Ascii}};
    for (Encoding e : {Encoding::Binary, Encoding::AppendedRaw, Encoding::AppendedBase64})
        for (bool zlib : {false, true})
            for (bool h64 : {false, true})
                for (bool big : {false, true}) out.push_back({e, zlib, h64, big});
    return out;
}

template <typename T>
const char* type_name()
{
    if constexpr (std::is_same_v<T, int8_t>) return "Int8";
    else if constexpr (std::is_same_v<T, uint8_t>) return "UInt8";
    else if constexpr (std::is_same_v<T, int16_t>) return "Int16";
    else if constexpr (std::is_same_v<T, uint16_t>) return "UInt16";
    else if constexpr (std::is_same_v<T, int32_t>) return "Int32";
    else if constexpr (std::is_same_v<T, uint32_t>) return "UInt32";
    else if constexpr (std::is_same_v<T, int64_t>) return "Int64";
    else if constexpr (std::is_same_v<T, uint64_t>) return "UInt64";
    else if constexpr (std::is_same_v<T, float>) return "Float32";
    else return "Float64";
}

inline std::string zlib_compress(const std::string& bytes)
{
    uLongf length = compressBound(static_cast<uLong>(bytes.size()));
    std::string out(length, '\0');
    compress(reinterpret_cast<Bytef*>(out.data()), &length, reinterpret_cast<const Bytef*>(bytes.data()),
             static_cast<uLong>(bytes.size()));
    out.resize(length);
    return out;
}

// Collects the DataArrays of one file and the appended section.
class Writer {
public:
    explicit Writer(Options o) : o_(o) {}

    template <typename T>
    std::string array(const std::string& array_name, const std::vector<T>& values, int components = 1)
    {
        std::ostringstream a;
        a.precision(17);
        a << "<DataArray type=\"" << type_name<T>() << "\" Name=\"" << array_name << "\"";
        if (components != 1) a << " NumberOfComponents=\"" << components << "\"";
        if (o_.encoding == Encoding::Ascii) {
            a << " format=\"ascii\">\n";
            for (T v : values) {
                if constexpr (sizeof(T) == 1) a << static_cast<int>(v) << ' ';
                else a << v << ' ';
            }
            a << "\n</DataArray>\n";
            return a.str();
        }
        std::string data;
        for (T v : values) put(data, v, o_.big_endian);
        const std::string encoded = encode(data);
        if (o_.encoding == Encoding::Binary) {
            a << " format=\"binary\">\n" << encoded << "\n</DataArray>\n";
        } else {
            a << " format=\"appended\" offset=\"" << appended_.size() << "\"/>\n";
            appended_ += encoded;
        }
        return a.str();
    }

    // The file: `type` PolyData or ImageData, `body` its element.
    std::string file(const std::string& type, const std::string& body) const
    {
        std::ostringstream f;
        f << "<?xml version=\"1.0\"?>\n<VTKFile type=\"" << type << "\" version=\"1.0\" byte_order=\""
          << (o_.big_endian ? "BigEndian" : "LittleEndian") << "\" header_type=\""
          << (o_.header64 ? "UInt64" : "UInt32") << "\"";
        if (o_.zlib && o_.encoding != Encoding::Ascii) f << " compressor=\"vtkZLibDataCompressor\"";
        f << ">\n" << body;
        if (o_.encoding == Encoding::AppendedRaw || o_.encoding == Encoding::AppendedBase64)
            f << "<AppendedData encoding=\"" << (o_.encoding == Encoding::AppendedRaw ? "raw" : "base64")
              << "\">\n   _" << appended_ << "\n</AppendedData>\n";
        f << "</VTKFile>\n";
        return f.str();
    }

private:
    void word(std::string& out, uint64_t v) const
    {
        if (o_.header64) put(out, v, o_.big_endian);
        else put(out, static_cast<uint32_t>(v), o_.big_endian);
    }

    std::string encode(const std::string& data) const
    {
        const bool text = o_.encoding != Encoding::AppendedRaw;
        if (!o_.zlib) {
            std::string bytes;
            word(bytes, data.size());
            bytes += data;
            return text ? base64(bytes) : bytes;
        }
        const size_t blocks = (data.size() + o_.block_size - 1) / o_.block_size;
        std::string header, packed;
        word(header, blocks);
        word(header, o_.block_size);
        word(header, data.size() % o_.block_size);
        for (size_t b = 0; b < blocks; ++b) {
            const std::string block = zlib_compress(data.substr(b * o_.block_size, o_.block_size));
            word(header, block.size());
            packed += block;
        }
        return text ? base64(header) + base64(packed) : header + packed;
    }

    Options o_;
    std::string appended_;
};

// A surface as .vtp: its polygons, with an Int32 cell array `label_name`
// of one value per face when `labels` is not empty.
inline std::string vtp(const PolyMesh& m, const Options& o, const std::vector<int32_t>& labels = {},
                       const std::string& label_name = "ModelFaceID")
{
    Writer w(o);
    std::string points;
    if (o.float32_points) {
        std::vector<float> xyz;
        for (const Vec3& p : m.points)
            xyz.insert(xyz.end(), {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)});
        points = w.array("Points", xyz, 3);
    } else {
        std::vector<double> xyz;
        for (const Vec3& p : m.points) xyz.insert(xyz.end(), {p.x, p.y, p.z});
        points = w.array("Points", xyz, 3);
    }
    std::vector<int64_t> connectivity, offsets{0};
    for (const auto& f : m.faces) {
        connectivity.insert(connectivity.end(), f.begin(), f.end());
        offsets.push_back(static_cast<int64_t>(connectivity.size()));
    }
    std::string polys;
    if (o.int32_indices) {
        polys = w.array("connectivity", std::vector<int32_t>(connectivity.begin(), connectivity.end())) +
                w.array("offsets", std::vector<int32_t>(offsets.begin(), offsets.end()));
    } else {
        polys = w.array("connectivity", connectivity) + w.array("offsets", offsets);
    }
    std::string cells;
    if (!labels.empty()) cells = w.array(label_name, labels);
    std::ostringstream b;
    b << "<PolyData>\n<Piece NumberOfPoints=\"" << m.points.size()
      << "\" NumberOfVerts=\"0\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"" << m.faces.size()
      << "\">\n<PointData>\n</PointData>\n<CellData" << (labels.empty() ? "" : " Scalars=\"" + label_name + "\"")
      << ">\n" << cells << "</CellData>\n<Points>\n" << points << "</Points>\n<Polys>\n" << polys
      << "</Polys>\n</Piece>\n</PolyData>\n";
    return w.file("PolyData", b.str());
}

inline std::string vtp(const SurfaceMesh& s, const Options& o, const std::vector<int32_t>& labels = {},
                       const std::string& label_name = "ModelFaceID")
{
    return vtp(from_surface(s), o, labels, label_name);
}

// A volume of `size` voxels, x fastest, and its frame: world position of
// voxel (i, j, k) = origin + direction * diag(spacing) * (i, j, k), with
// direction given row by row.
template <typename T>
struct Volume {
    std::array<int, 3> size{};
    std::array<double, 3> origin{0, 0, 0};
    std::array<double, 3> spacing{1, 1, 1};
    std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
    std::vector<T> values;
};

template <typename T>
std::string vti(const Volume<T>& v, const Options& o, const std::string& array_name = "labels")
{
    Writer w(o);
    const std::string scalars = w.array(array_name, v.values);
    std::ostringstream b;
    b.precision(17);
    const std::string extent = "0 " + std::to_string(v.size[0] - 1) + " 0 " + std::to_string(v.size[1] - 1) +
                               " 0 " + std::to_string(v.size[2] - 1);
    b << "<ImageData WholeExtent=\"" << extent << "\" Origin=\"" << v.origin[0] << ' ' << v.origin[1] << ' '
      << v.origin[2] << "\" Spacing=\"" << v.spacing[0] << ' ' << v.spacing[1] << ' ' << v.spacing[2]
      << "\" Direction=\"";
    for (int i = 0; i < 9; ++i) b << (i ? " " : "") << v.direction[i];
    b << "\">\n<Piece Extent=\"" << extent << "\">\n<PointData Scalars=\"" << array_name << "\">\n" << scalars
      << "</PointData>\n<CellData>\n</CellData>\n</Piece>\n</ImageData>\n";
    return w.file("ImageData", b.str());
}

} // namespace scalemesh::test::vtk
