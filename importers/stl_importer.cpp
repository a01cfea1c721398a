#include "importers/stl_importer.h"

#include "core/errors.h"
#include "importers/polygon_soup.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <string_view>
#include <unordered_map>

namespace scalemesh {

namespace {

using Corner = std::array<float, 3>; // one triangle corner as stored in STL

constexpr uint64_t kHeaderBytes = 84;
constexpr uint64_t kFacetBytes = 50;

uint32_t header_count(const std::string& bytes)
{
    static_assert(std::endian::native == std::endian::little, "binary STL is little-endian: add byte swapping");
    uint32_t count = 0;
    std::memcpy(&count, bytes.data() + 80, 4);
    return count;
}

bool is_binary(const std::string& bytes)
{
    return bytes.size() >= kHeaderBytes && bytes.size() == kHeaderBytes + kFacetBytes * header_count(bytes);
}

bool equal_nocase(std::string_view a, std::string_view b)
{
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
               return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
           });
}

bool looks_ascii(const std::string& bytes)
{
    const size_t start = bytes.find_first_not_of(" \t\r\n");
    if (start == std::string::npos || !equal_nocase(std::string_view(bytes).substr(start, 5), "solid")) return false;
    const std::string_view keyword = "facet";
    return std::search(bytes.begin(), bytes.end(), keyword.begin(), keyword.end(), [](char x, char y) {
               return std::tolower(static_cast<unsigned char>(x)) == y;
           }) != bytes.end();
}

std::vector<Corner> binary_corners(const std::string& bytes)
{
    const uint64_t count = header_count(bytes);
    std::vector<Corner> corners(3 * count);
    for (uint64_t f = 0; f < count; ++f) {
        // Skip the stored normal (12 bytes); the corners follow it.
        const char* record = bytes.data() + kHeaderBytes + kFacetBytes * f + 12;
        std::memcpy(corners[3 * f].data(), record, 36);
    }
    return corners;
}

class AsciiParser {
public:
    AsciiParser(const std::string& bytes, const std::filesystem::path& path) : text_(bytes), path_(path) {}

    std::vector<Corner> corners()
    {
        std::vector<Corner> corners;
        bool in_facet = false;
        int facet_vertices = 0;
        size_t begin = 0;
        while (begin < text_.size()) {
            size_t end = text_.find('\n', begin);
            if (end == std::string_view::npos) end = text_.size();
            line_ = text_.substr(begin, end - begin);
            ++line_number_;
            begin = end + 1;

            const std::string_view keyword = next_token();
            if (keyword.empty() || equal_nocase(keyword, "outer") || equal_nocase(keyword, "endloop")) continue;
            if (equal_nocase(keyword, "solid") || equal_nocase(keyword, "endsolid")) {
                // The rest of the line is the solid's name, which may be any text.
                if (in_facet) fail("'" + std::string(keyword) + "' inside a facet");
            } else if (equal_nocase(keyword, "facet")) {
                if (in_facet) fail("a facet begins before the previous one ended");
                in_facet = true;
                facet_vertices = 0;
            } else if (equal_nocase(keyword, "vertex")) {
                if (!in_facet) fail("a vertex outside a facet");
                if (++facet_vertices > 3) fail("a facet with more than three vertices (only triangles are STL)");
                Corner corner;
                for (float& value : corner) value = next_number();
                if (!next_token().empty()) fail("more than three numbers after 'vertex'");
                corners.push_back(corner);
            } else if (equal_nocase(keyword, "endfacet")) {
                if (!in_facet) fail("'endfacet' without 'facet'");
                if (facet_vertices != 3)
                    fail("a facet with " + std::to_string(facet_vertices) + " vertices instead of three");
                in_facet = false;
            } else {
                fail("unexpected '" + std::string(keyword) + "'");
            }
        }
        if (in_facet) fail("the file ends inside a facet (it is truncated)");
        return corners;
    }

private:
    std::string_view next_token()
    {
        const size_t start = line_.find_first_not_of(" \t\r\f\v");
        if (start == std::string_view::npos) {
            line_ = {};
            return {};
        }
        line_.remove_prefix(start);
        const size_t length = std::min(line_.find_first_of(" \t\r\f\v"), line_.size());
        const std::string_view token = line_.substr(0, length);
        line_.remove_prefix(length);
        return token;
    }

    float next_number()
    {
        std::string_view token = next_token();
        // from_chars rejects the leading '+' that some writers emit.
        if (!token.empty() && token.front() == '+') token.remove_prefix(1);
        float value = 0;
        const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
        if (token.empty() || error != std::errc() || end != token.data() + token.size())
            fail("'" + std::string(token) + "' is not a single-precision number");
        return value;
    }

    [[noreturn]] void fail(const std::string& what) const
    {
        throw InputError(path_.string() + ": line " + std::to_string(line_number_) + " of the ASCII STL has " + what,
                         "the file is damaged or not an STL: export it again from the software that made it");
    }

    std::string_view text_;
    const std::filesystem::path& path_;
    std::string_view line_;
    int64_t line_number_ = 0;
};

struct CornerHash {
    size_t operator()(const Corner& c) const
    {
        size_t h = 0;
        for (float value : c)
            h = h * 0x9E3779B97F4A7C15ull + std::bit_cast<uint32_t>(value);
        return h;
    }
};

// Welds equal corners, drops degenerate triangles and numbers the points by
// first use in the kept triangles.
SurfaceMesh weld(std::vector<Corner>& corners, double scale, int64_t* degenerate_removed,
                 const std::filesystem::path& path)
{
    const size_t nt = corners.size() / 3;
    for (size_t i = 0; i < corners.size(); ++i)
        for (float& value : corners[i]) {
            if (!std::isfinite(value))
                throw InputError(path.string() + ": facet " + std::to_string(i / 3 + 1) + " of " + std::to_string(nt) +
                                     " (counting from 1) has a NaN or infinite coordinate",
                                 "repair or re-export the surface; scalemesh needs finite coordinates");
            // -0 and +0 compare equal; give them one bit pattern for the hash.
            value += 0.0f;
        }

    std::unordered_map<Corner, int32_t, CornerHash> index_of;
    index_of.reserve(corners.size() / 2);
    std::vector<const Corner*> unique;
    std::vector<Triangle> triangles;
    triangles.reserve(nt);
    int64_t degenerate = 0;
    for (size_t f = 0; f < nt; ++f) {
        Triangle t;
        for (int k = 0; k < 3; ++k) {
            const Corner& corner = corners[3 * f + k];
            const auto [it, inserted] = index_of.try_emplace(corner, static_cast<int32_t>(unique.size()));
            if (inserted) unique.push_back(&corner);
            t[k] = it->second;
        }
        if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) ++degenerate;
        else triangles.push_back(t);
    }
    if (degenerate_removed) *degenerate_removed = degenerate;
    if (triangles.empty())
        throw InputError(path.string() + ": all " + std::to_string(nt) + " triangles are degenerate",
                         "the surface has no area: check the file and its units");

    // Dropping degenerate triangles can leave points unused; renumber so that
    // every point is used, keeping first-use order.
    SurfaceMesh mesh;
    std::vector<int32_t> renumbered(unique.size(), -1);
    for (Triangle& t : triangles)
        for (int32_t& v : t) {
            if (renumbered[v] < 0) {
                renumbered[v] = static_cast<int32_t>(mesh.points.size());
                const Corner& c = *unique[v];
                mesh.points.push_back({c[0] * scale, c[1] * scale, c[2] * scale});
            }
            v = renumbered[v];
        }
    mesh.triangles = std::move(triangles);
    return mesh;
}

struct PointHash {
    size_t operator()(const Vec3& p) const
    {
        size_t h = 0;
        for (int k = 0; k < 3; ++k) h = h * 0x9E3779B97F4A7C15ull + std::bit_cast<uint64_t>(p[k]);
        return h;
    }
};

} // namespace

SurfaceMesh weld_polygons(const PolygonSoup& soup, double scale, const std::filesystem::path& path,
                          const std::vector<int32_t>& polygon_labels, std::vector<int32_t>& triangle_labels)
{
    const std::string file = path.string();
    const size_t n_polygons = soup.offsets.size() - 1;
    if (polygon_labels.size() != n_polygons)
        throw InputError(file + " has " + std::to_string(polygon_labels.size()) + " face labels for " +
                             std::to_string(n_polygons) + " faces",
                         "the labels must have one value per face: export the surface again");
    const int64_t n_points = static_cast<int64_t>(soup.points.size());
    for (int64_t i = 0; i < n_points; ++i)
        for (int k = 0; k < 3; ++k)
            if (!std::isfinite(soup.points[i][k]))
                throw InputError(file + ": point " + std::to_string(i) + " (counting from 0) has a NaN or infinite "
                                     "coordinate",
                                 "repair or re-export the surface; scalemesh needs finite coordinates");

    int64_t n_triangles = 0;
    for (size_t f = 0; f < n_polygons; ++f) {
        const int64_t size = soup.offsets[f + 1] - soup.offsets[f];
        if (size < 3)
            throw InputError(file + ": face " + std::to_string(f) + " (counting from 0) has " + std::to_string(size) +
                                 " corner" + (size == 1 ? "" : "s"),
                             "every face needs three or more corners: repair or re-export the surface");
        for (int64_t c = soup.offsets[f]; c < soup.offsets[f + 1]; ++c)
            if (soup.corners[c] < 0 || soup.corners[c] >= n_points)
                throw InputError(file + ": face " + std::to_string(f) + " (counting from 0) refers to point " +
                                     std::to_string(soup.corners[c]) + ", but the file has " +
                                     std::to_string(n_points) + " points",
                                 "the file is damaged or its indices are off: export it again");
        n_triangles += size - 2;
        if (n_triangles > std::numeric_limits<int32_t>::max() / 3)
            throw InputError(file + " has more than 715,827,882 triangles", "decimate the surface first");
    }
    if (n_triangles == 0) throw InputError(file + " holds no faces", "export a surface that has triangles");

    // Weld exactly equal points; -0 and +0 get one bit pattern for the hash.
    std::vector<int32_t> welded(soup.points.size());
    std::vector<Vec3> unique;
    {
        std::unordered_map<Vec3, int32_t, PointHash> index_of;
        index_of.reserve(soup.points.size());
        for (size_t i = 0; i < soup.points.size(); ++i) {
            Vec3 p = soup.points[i];
            for (int k = 0; k < 3; ++k) p[k] += 0.0;
            const auto [it, inserted] = index_of.try_emplace(p, static_cast<int32_t>(unique.size()));
            if (inserted) unique.push_back(p);
            welded[i] = it->second;
        }
    }

    std::vector<Triangle> triangles;
    triangles.reserve(static_cast<size_t>(n_triangles));
    triangle_labels.clear();
    triangle_labels.reserve(static_cast<size_t>(n_triangles));
    for (size_t f = 0; f < n_polygons; ++f) {
        const int64_t first = soup.offsets[f];
        for (int64_t c = first + 1; c + 1 < soup.offsets[f + 1]; ++c) {
            const Triangle t{welded[soup.corners[first]], welded[soup.corners[c]], welded[soup.corners[c + 1]]};
            if (t[0] != t[1] && t[1] != t[2] && t[2] != t[0]) {
                triangles.push_back(t);
                triangle_labels.push_back(polygon_labels[f]);
            }
        }
    }
    if (triangles.empty())
        throw InputError(file + ": all " + std::to_string(n_triangles) + " triangles are degenerate",
                         "the surface has no area: check the file and its units");

    SurfaceMesh mesh;
    std::vector<int32_t> renumbered(unique.size(), -1);
    for (Triangle& t : triangles)
        for (int32_t& v : t) {
            if (renumbered[v] < 0) {
                renumbered[v] = static_cast<int32_t>(mesh.points.size());
                mesh.points.push_back(unique[v] * scale);
            }
            v = renumbered[v];
        }
    mesh.triangles = std::move(triangles);
    return mesh;
}

std::string read_file_bytes(const std::filesystem::path& path)
{
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw IoError(path.string(), "no such file; check the path");
    if (std::filesystem::is_directory(path, ec)) throw IoError(path.string(), "is a directory, not a surface file");
    std::ifstream file(path, std::ios::binary);
    if (!file) throw IoError(path.string(), std::string("cannot open the file: ") + std::strerror(errno));
    std::string bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
    if (file.bad()) throw IoError(path.string(), "reading the file failed");
    if (bytes.empty()) throw InputError(path.string() + " is empty", "export the surface again");
    return bytes;
}

SurfaceMesh read_stl(const std::filesystem::path& path, double scale, int64_t* degenerate_removed)
{
    if (!(std::isfinite(scale) && scale > 0))
        throw InputError("STL scale factor " + std::to_string(scale) + " is not a positive number",
                         "give the factor from the file's units to mm, e.g. 1000 for metres");
    const std::string bytes = read_file_bytes(path);

    std::vector<Corner> corners;
    if (is_binary(bytes)) {
        // Indices are int32: at most 3 corners per triangle must fit.
        if (header_count(bytes) > std::numeric_limits<int32_t>::max() / 3)
            throw InputError(path.string() + " has " + std::to_string(header_count(bytes)) + " triangles",
                             "scalemesh reads at most 715,827,882 triangles: decimate the surface first");
        corners = binary_corners(bytes);
    } else if (looks_ascii(bytes)) {
        corners = AsciiParser(bytes, path).corners();
    } else if (bytes.size() < kHeaderBytes) {
        throw InputError(path.string() + " is not an STL: " + std::to_string(bytes.size()) +
                             " bytes is too short for a binary STL (84 bytes or more) and it is not ASCII STL",
                         "check that the path names an STL file and that it was copied completely");
    } else {
        const uint64_t count = header_count(bytes);
        throw InputError(path.string() + " is not a valid STL: as binary STL its header announces " +
                             std::to_string(count) + " triangles, which take " +
                             std::to_string(kHeaderBytes + kFacetBytes * count) + " bytes, but the file has " +
                             std::to_string(bytes.size()) + ", and it is not ASCII STL",
                         "the file is truncated or damaged: copy or export it again");
    }
    if (corners.empty())
        throw InputError(path.string() + " holds no triangles", "export a surface that has triangles");
    return weld(corners, scale, degenerate_removed, path);
}

} // namespace scalemesh
