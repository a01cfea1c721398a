// Wavefront OBJ reading through tinyobjloader (Debian's libtinyobjloader-dev,
// the double-precision build). Its own triangulation is off: it reads corner
// positions before anyone has checked the indices, so the polygons are fanned
// in weld_polygons after the checks.

#include "core/errors.h"
#include "importers/polygon_soup.h"
#include "importers/surface_importer.h"

#include <tiny_obj_loader.h>

#include <charconv>
#include <cmath>
#include <string_view>

namespace scalemesh {

namespace {

// tinyobjloader reads a coordinate it cannot parse ("nan", "1,5", a missing
// one) as 0 without a word: check every "v" line holds three to seven finite
// numbers (x y z, optionally w or r g b) first.
void check_vertex_lines(const std::string& text, const std::filesystem::path& path)
{
    size_t begin = 0;
    int64_t line = 0;
    while (begin < text.size()) {
        size_t end = text.find('\n', begin);
        if (end == std::string::npos) end = text.size();
        ++line;
        std::string_view rest(text.data() + begin, end - begin);
        begin = end + 1;
        const size_t start = rest.find_first_not_of(" \t");
        if (start == std::string_view::npos || (rest.substr(start, 2) != "v " && rest.substr(start, 2) != "v\t")) continue;
        rest.remove_prefix(start + 2);
        int numbers = 0;
        for (;;) {
            const size_t from = rest.find_first_not_of(" \t\r");
            if (from == std::string_view::npos) break;
            rest.remove_prefix(from);
            std::string_view token = rest.substr(0, std::min(rest.find_first_of(" \t\r"), rest.size()));
            rest.remove_prefix(token.size());
            if (token.front() == '+') token.remove_prefix(1);
            double value = 0;
            const auto [ptr, error] = std::from_chars(token.data(), token.data() + token.size(), value);
            if (token.empty() || error != std::errc() || ptr != token.data() + token.size() || !std::isfinite(value))
                throw InputError(path.string() + ": line " + std::to_string(line) + " has the coordinate '" +
                                     std::string(token.substr(0, 40)) + "', which is not a finite number",
                                 "repair or re-export the surface; scalemesh needs finite coordinates");
            ++numbers;
        }
        if (numbers < 3 || numbers > 7)
            throw InputError(path.string() + ": line " + std::to_string(line) + " is a vertex with " +
                                 std::to_string(numbers) + " numbers",
                             "a vertex line is 'v x y z': repair or re-export the surface");
    }
}

} // namespace

SurfaceMesh read_obj(const std::filesystem::path& path, double scale)
{
    require_scale(scale);
    const std::string text = read_file_bytes(path);
    check_vertex_lines(text, path);
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;
    config.vertex_color = false;
    tinyobj::ObjReader reader;
    // Parsing from a string with no material text: a "mtllib" line opens no file.
    if (!reader.ParseFromString(text, "", config)) {
        std::string error = reader.Error();
        while (!error.empty() && (error.back() == '\n' || error.back() == '\r')) error.pop_back();
        throw InputError(path.string() + " is not a valid OBJ file: " + (error.empty() ? "parse error" : error),
                         "the file is damaged: export the surface again");
    }

    PolygonSoup soup;
    const std::vector<tinyobj::real_t>& v = reader.GetAttrib().vertices;
    soup.points.resize(v.size() / 3);
    for (size_t i = 0; i < soup.points.size(); ++i) soup.points[i] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        const tinyobj::mesh_t& mesh = shape.mesh;
        size_t at = 0;
        for (unsigned char n : mesh.num_face_vertices) {
            // tinyobjloader stores a face's corner count in one byte.
            if (at + n > mesh.indices.size())
                throw InputError(path.string() + ": a face has more than 255 corners",
                                 "triangulate the surface before exporting it");
            for (size_t c = 0; c < n; ++c) soup.corners.push_back(mesh.indices[at + c].vertex_index);
            soup.offsets.push_back(static_cast<int64_t>(soup.corners.size()));
            at += n;
        }
        if (at != mesh.indices.size())
            throw InputError(path.string() + ": a face has more than 255 corners",
                             "triangulate the surface before exporting it");
    }
    if (soup.offsets.size() == 1)
        throw InputError(path.string() + " holds no faces ('f' lines)", "export a surface that has triangles");
    return weld_polygons(soup, scale, path);
}

} // namespace scalemesh
