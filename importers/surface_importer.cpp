#include "importers/surface_importer.h"

#include "core/errors.h"
#include "exporters/msh_reader.h"
#include "importers/msh_check.h"
#include "importers/polygon_soup.h"
#include "importers/stl_importer.h"

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace scalemesh {

namespace {

std::string lower_extension(const std::filesystem::path& path)
{
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    return ext;
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

void require_scale(double scale)
{
    if (!(std::isfinite(scale) && scale > 0))
        throw InputError("surface scale factor " + std::to_string(scale) + " is not a positive number",
                         "give the factor from the file's units to mm, e.g. 1000 for metres");
}

SurfaceMesh weld_polygons(const PolygonSoup& soup, double scale, const std::filesystem::path& path)
{
    const std::string file = path.string();
    const int64_t n_points = static_cast<int64_t>(soup.points.size());
    for (int64_t i = 0; i < n_points; ++i)
        for (int k = 0; k < 3; ++k)
            if (!std::isfinite(soup.points[i][k]))
                throw InputError(file + ": point " + std::to_string(i) + " (counting from 0) has a NaN or infinite "
                                     "coordinate",
                                 "repair or re-export the surface; scalemesh needs finite coordinates");

    const size_t n_polygons = soup.offsets.size() - 1;
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
    for (size_t f = 0; f < n_polygons; ++f) {
        const int64_t first = soup.offsets[f];
        for (int64_t c = first + 1; c + 1 < soup.offsets[f + 1]; ++c) {
            const Triangle t{welded[soup.corners[first]], welded[soup.corners[c]], welded[soup.corners[c + 1]]};
            if (t[0] != t[1] && t[1] != t[2] && t[2] != t[0]) triangles.push_back(t);
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

bool is_surface_file(const std::filesystem::path& path)
{
    const std::string ext = lower_extension(path);
    return ext == ".stl" || ext == ".ply" || ext == ".obj" || ext == ".vtp" || ext == ".msh";
}

double unit_to_mm(const std::string& unit)
{
    if (unit == "mm") return 1.0;
    if (unit == "cm") return 10.0;
    if (unit == "m") return 1000.0;
    if (unit == "um") return 1e-3;
    throw InputError("'" + unit + "' is not a length unit", "choose \"mm\", \"cm\", \"m\" or \"um\"");
}

SurfaceMesh read_msh_surface_mesh(const std::filesystem::path& path, double scale)
{
    require_scale(scale);
    // Gmsh reports a missing file in its own words, and trusts what a file
    // says (importers/msh_check.h): both are checked here first.
    check_msh_file(read_file_bytes(path), path);
    SurfaceMesh msh;
    try {
        msh = read_msh_surface(path).mesh;
    } catch (const IoError& e) {
        // The file was readable: what Gmsh refuses is its content.
        throw InputError(std::string(e.what()), "the file is damaged or not a mesh: write it again");
    }
    PolygonSoup soup;
    soup.points = msh.points;
    for (const Triangle& t : msh.triangles) {
        soup.corners.insert(soup.corners.end(), t.begin(), t.end());
        soup.offsets.push_back(static_cast<int64_t>(soup.corners.size()));
    }
    return weld_polygons(soup, scale, path);
}

TetMesh read_msh_tet_mesh(const std::filesystem::path& path)
{
    check_msh_file(read_file_bytes(path), path);
    try {
        return read_msh_volume(path);
    } catch (const IoError& e) {
        throw InputError(std::string(e.what()), "the file is damaged or not a mesh: write it again");
    }
}

SurfaceMesh read_surface(const std::filesystem::path& path, double scale)
{
    require_scale(scale);
    const std::string ext = lower_extension(path);
    if (ext == ".stl") return read_stl(path, scale);
    if (ext == ".ply") return read_ply(path, scale);
    if (ext == ".obj") return read_obj(path, scale);
    if (ext == ".vtp") return read_vtp(path, scale);
    if (ext == ".msh") return read_msh_surface_mesh(path, scale);
    throw InputError("cannot read '" + path.string() + "' as a surface: unknown extension '" + ext + "'",
                     "give a .stl, .ply, .obj, .vtp or .msh file");
}

} // namespace scalemesh
