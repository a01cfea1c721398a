#pragma once
// Surfaces built in code and written by hand in every format read_surface
// reads, so that the readers are tested against files whose content is known
// independently of them.

#include "core/surface_mesh.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace scalemesh::test {

// A closed polygon mesh: faces of three or more corners, counter-clockwise
// seen from outside.
struct PolyMesh {
    std::vector<Vec3> points;
    std::vector<std::vector<int32_t>> faces;
};

// The cube [-1, 1]^3 as six quads (12 triangles once fanned, volume 8).
inline PolyMesh quad_cube()
{
    PolyMesh m;
    for (int i = 0; i < 8; ++i) m.points.push_back({i & 1 ? 1.0 : -1.0, i & 2 ? 1.0 : -1.0, i & 4 ? 1.0 : -1.0});
    m.faces = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    return m;
}

// An icosphere of radius `r`: 20 * 4^level triangles, 10 * 4^level + 2 points.
inline PolyMesh icosphere(int level, double r = 1.0)
{
    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    PolyMesh m;
    m.points = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    m.faces = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
               {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
               {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    for (Vec3& p : m.points) p = p / norm(p);
    for (int l = 0; l < level; ++l) {
        std::map<std::pair<int32_t, int32_t>, int32_t> middle;
        const auto mid = [&](int32_t a, int32_t b) {
            const auto key = std::minmax(a, b);
            const auto it = middle.find(key);
            if (it != middle.end()) return it->second;
            const Vec3 p = m.points[a] + m.points[b];
            m.points.push_back(p / norm(p));
            return middle[key] = static_cast<int32_t>(m.points.size() - 1);
        };
        std::vector<std::vector<int32_t>> faces;
        for (const auto& f : m.faces) {
            const int32_t a = mid(f[0], f[1]), b = mid(f[1], f[2]), c = mid(f[2], f[0]);
            faces.push_back({f[0], a, c});
            faces.push_back({f[1], b, a});
            faces.push_back({f[2], c, b});
            faces.push_back({a, b, c});
        }
        m.faces = std::move(faces);
    }
    for (Vec3& p : m.points) p *= r;
    return m;
}

inline PolyMesh from_surface(const SurfaceMesh& s)
{
    PolyMesh m;
    m.points = s.points;
    for (const Triangle& t : s.triangles) m.faces.push_back({t[0], t[1], t[2]});
    return m;
}

inline void write_text(const std::filesystem::path& path, const std::string& text)
{
    std::ofstream(path, std::ios::binary) << text;
}

inline std::string read_text(const std::filesystem::path& path)
{
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

template <typename T>
void put(std::string& out, T value, bool big_endian)
{
    char raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    if (big_endian != (std::endian::native == std::endian::big)) std::reverse(raw, raw + sizeof(T));
    out.append(raw, sizeof(T));
}

enum class PlyFormat { Ascii, BinaryLittle, BinaryBig };

// PLY with an extra per-vertex property and an extra element, to be skipped.
inline std::string ply_text(const PolyMesh& m, PlyFormat format)
{
    std::ostringstream h;
    h << "ply\nformat "
      << (format == PlyFormat::Ascii ? "ascii" : format == PlyFormat::BinaryLittle ? "binary_little_endian"
                                                                                   : "binary_big_endian")
      << " 1.0\ncomment written by the scalemesh tests\nelement vertex " << m.points.size()
      << "\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nelement face "
      << m.faces.size() << "\nproperty list uchar int vertex_indices\nelement edge 1\nproperty int vertex1\n"
      << "property int vertex2\nend_header\n";
    std::string out = h.str();
    if (format == PlyFormat::Ascii) {
        std::ostringstream b;
        b.precision(17);
        for (const Vec3& p : m.points) b << p.x << ' ' << p.y << ' ' << p.z << " 255\n";
        for (const auto& f : m.faces) {
            b << f.size();
            for (int32_t v : f) b << ' ' << v;
            b << '\n';
        }
        b << "0 1\n";
        return out + b.str();
    }
    const bool big = format == PlyFormat::BinaryBig;
    for (const Vec3& p : m.points) {
        put(out, p.x, big), put(out, p.y, big), put(out, p.z, big);
        put(out, uint8_t{255}, big);
    }
    for (const auto& f : m.faces) {
        put(out, static_cast<uint8_t>(f.size()), big);
        for (int32_t v : f) put(out, v, big);
    }
    put(out, int32_t{0}, big), put(out, int32_t{1}, big);
    return out;
}

inline std::string obj_text(const PolyMesh& m)
{
    std::ostringstream o;
    o.precision(17);
    o << "# written by the scalemesh tests\nmtllib missing.mtl\no shape\n";
    for (const Vec3& p : m.points) o << "v " << p.x << ' ' << p.y << ' ' << p.z << '\n';
    o << "vn 0 0 1\n";
    for (const auto& f : m.faces) {
        o << 'f';
        for (int32_t v : f) o << ' ' << v + 1 << "//1";
        o << '\n';
    }
    return o.str();
}

inline std::string base64(const std::string& bytes)
{
    static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (size_t i = 0; i < bytes.size(); i += 3) {
        uint32_t group = 0;
        const size_t n = std::min<size_t>(3, bytes.size() - i);
        for (size_t k = 0; k < 3; ++k) group = (group << 8) | (k < n ? static_cast<uint8_t>(bytes[i + k]) : 0u);
        for (size_t k = 0; k < 4; ++k) out += k <= n ? table[(group >> (18 - 6 * k)) & 63] : '=';
    }
    return out;
}

enum class VtpFormat { Ascii, Binary32, Binary64Separate };

// VTK XML PolyData. Binary32: one base64 stream of a UInt32 byte count and
// the data (as VTK writes uncompressed arrays); Binary64Separate: a UInt64
// header encoded apart from the data, and VTK 9's offsets with a leading 0.
inline std::string vtp_text(const PolyMesh& m, VtpFormat format)
{
    std::vector<double> xyz;
    for (const Vec3& p : m.points) xyz.insert(xyz.end(), {p.x, p.y, p.z});
    std::vector<int64_t> connectivity, offsets;
    if (format == VtpFormat::Binary64Separate) offsets.push_back(0);
    for (const auto& f : m.faces) {
        connectivity.insert(connectivity.end(), f.begin(), f.end());
        offsets.push_back(static_cast<int64_t>(connectivity.size()));
    }
    const auto array = [&](const std::string& type, const std::string& name, const auto& values, int components) {
        std::ostringstream a;
        a.precision(17);
        a << "        <DataArray type=\"" << type << "\" Name=\"" << name << "\"";
        if (components) a << " NumberOfComponents=\"" << components << "\"";
        a << " format=\"" << (format == VtpFormat::Ascii ? "ascii" : "binary") << "\">\n          ";
        if (format == VtpFormat::Ascii) {
            for (auto v : values) a << v << ' ';
        } else {
            std::string data;
            for (auto v : values) put(data, v, false);
            std::string header;
            if (format == VtpFormat::Binary32) {
                put(header, static_cast<uint32_t>(data.size()), false);
                a << base64(header + data);
            } else {
                put(header, static_cast<uint64_t>(data.size()), false);
                a << base64(header) << base64(data);
            }
        }
        a << "\n        </DataArray>\n";
        return a.str();
    };
    std::ostringstream v;
    v << "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"" << (format == VtpFormat::Binary64Separate ? "2.2" : "0.1")
      << "\" byte_order=\"LittleEndian\" header_type=\"" << (format == VtpFormat::Binary64Separate ? "UInt64" : "UInt32")
      << "\">\n  <PolyData>\n    <Piece NumberOfPoints=\"" << m.points.size()
      << "\" NumberOfVerts=\"0\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"" << m.faces.size()
      << "\">\n      <PointData>\n" << array("Float64", "ignored", std::vector<double>(m.points.size(), 1.0), 0)
      << "      </PointData>\n      <Points>\n" << array("Float64", "Points", xyz, 3)
      << "      </Points>\n      <Polys>\n" << array("Int64", "connectivity", connectivity, 0)
      << array("Int64", "offsets", offsets, 0) << "      </Polys>\n    </Piece>\n  </PolyData>\n</VTKFile>\n";
    return v.str();
}

// Gmsh MSH 2.2, ASCII: points and 3-node triangles.
inline std::string msh_text(const PolyMesh& m)
{
    std::ostringstream o;
    o.precision(17);
    o << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n" << m.points.size() << '\n';
    for (size_t i = 0; i < m.points.size(); ++i)
        o << i + 1 << ' ' << m.points[i].x << ' ' << m.points[i].y << ' ' << m.points[i].z << '\n';
    size_t triangles = 0;
    for (const auto& f : m.faces) triangles += f.size() - 2;
    o << "$EndNodes\n$Elements\n" << triangles << '\n';
    size_t tag = 1;
    for (const auto& f : m.faces)
        for (size_t c = 1; c + 1 < f.size(); ++c)
            o << tag++ << " 2 2 1 1 " << f[0] + 1 << ' ' << f[c] + 1 << ' ' << f[c + 1] + 1 << '\n';
    o << "$EndElements\n";
    return o.str();
}

} // namespace scalemesh::test
