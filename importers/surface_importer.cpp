#include "importers/surface_importer.h"

#include "core/errors.h"
#include "gmsh_io/msh_reader.h"
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


} // namespace

void require_scale(double scale)
{
    if (!(std::isfinite(scale) && scale > 0))
        throw InputError("surface scale factor " + std::to_string(scale) + " is not a positive number",
                         "give the factor from the file's units to mm, e.g. 1000 for metres");
}

SurfaceMesh weld_polygons(const PolygonSoup& soup, double scale, const std::filesystem::path& path)
{
    const std::vector<int32_t> none(soup.offsets.empty() ? 0 : soup.offsets.size() - 1, 0);
    std::vector<int32_t> unused;
    return weld_polygons(soup, scale, path, none, unused);
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
    return read_msh_labelled(path, scale).mesh;
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

LabelledSurface read_msh_labelled(const std::filesystem::path& path, double scale)
{
    require_scale(scale);
    check_msh_file(read_file_bytes(path), path);
    MshSurface msh;
    try {
        msh = read_msh_surface(path);
    } catch (const IoError& e) {
        throw InputError(std::string(e.what()), "the file is damaged or not a mesh: write it again");
    }
    PolygonSoup soup;
    soup.points = msh.mesh.points;
    std::vector<int32_t> labels;
    for (size_t t = 0; t < msh.mesh.triangles.size(); ++t) {
        const Triangle& tri = msh.mesh.triangles[t];
        soup.corners.insert(soup.corners.end(), tri.begin(), tri.end());
        soup.offsets.push_back(static_cast<int64_t>(soup.corners.size()));
        labels.push_back(msh.mesh.triangle_patch.empty() ? 1 : msh.mesh.triangle_patch[t] + 1);
    }
    LabelledSurface result;
    std::vector<int32_t> triangle_labels;
    result.mesh = weld_polygons(soup, scale, path, labels, triangle_labels);
    if (!msh.patch_names.empty()) {
        result.labels.source = "physical surfaces";
        result.labels.per_triangle = std::move(triangle_labels);
        for (const auto& [patch, name] : msh.patch_names) result.labels.names[patch + 1] = name;
    }
    return result;
}

LabelledSurface read_labelled_surface(const std::filesystem::path& path, double scale)
{
    const std::string ext = lower_extension(path);
    if (ext == ".vtp") return read_vtp_labelled(path, scale);
    if (ext == ".msh") return read_msh_labelled(path, scale);
    return {read_surface(path, scale), {}};
}

} // namespace scalemesh
