#include "gmsh_io/msh_reader.h"

#include "core/errors.h"
#include "gmsh_io/gmsh_session.h"

#include <gmsh.h>

#include <algorithm>
#include <fstream>
#include <limits>
#include <numeric>
#include <unordered_map>

namespace scalemesh {

namespace {

void read_points(MshSurface& result, std::unordered_map<size_t, int32_t>& index_of_tag)
{
    std::vector<size_t> tags;
    std::vector<double> coords, parametric;
    gmsh::model::mesh::getNodes(tags, coords, parametric, -1, -1, false, false);
    // Entity order is not tag order (and MSH 2.2 renumbers), so order by tag.
    std::vector<size_t> order(tags.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return tags[a] < tags[b]; });
    result.mesh.points.reserve(tags.size());
    for (size_t i : order) {
        if (!index_of_tag.emplace(tags[i], static_cast<int32_t>(result.mesh.points.size())).second) continue;
        result.mesh.points.push_back({coords[3 * i], coords[3 * i + 1], coords[3 * i + 2]});
    }
}

void read_triangles(MshSurface& result, const std::unordered_map<size_t, int32_t>& index_of_tag,
                    const std::filesystem::path& path)
{
    gmsh::vectorpair groups;
    gmsh::model::getPhysicalGroups(groups, 2);
    for (const auto& [dim, tag] : groups) {
        std::string name;
        gmsh::model::getPhysicalName(dim, tag, name);
        result.patch_names[tag - 1] = name;
    }

    gmsh::vectorpair entities;
    gmsh::model::getEntities(entities, 2);
    for (const auto& [dim, entity] : entities) {
        std::vector<size_t> element_tags, node_tags;
        gmsh::model::mesh::getElementsByType(2, element_tags, node_tags, entity);
        std::vector<int> physical;
        gmsh::model::getPhysicalGroupsForEntity(dim, entity, physical);
        const int32_t patch = physical.empty() ? 0 : *std::min_element(physical.begin(), physical.end()) - 1;
        for (size_t k = 0; k + 2 < node_tags.size(); k += 3) {
            Triangle t;
            for (int c = 0; c < 3; ++c) {
                const auto found = index_of_tag.find(node_tags[k + c]);
                if (found == index_of_tag.end())
                    throw InputError(path.string() + ": triangle " + std::to_string(element_tags[k / 3]) +
                                         " refers to the missing node " + std::to_string(node_tags[k + c]),
                                     "the file is damaged: write it again");
                t[c] = found->second;
            }
            result.mesh.triangles.push_back(t);
            result.mesh.triangle_patch.push_back(patch);
        }
    }
    if (result.mesh.triangles.empty())
        throw InputError(path.string() + " holds no triangles", "give a surface mesh of 3-node triangles");
}

void read_fields(MshSurface& result, const std::vector<int>& views,
                 const std::unordered_map<size_t, int32_t>& index_of_tag, const std::filesystem::path& path)
{
    for (int view : views) {
        VertexField field;
        gmsh::option::getString("View[" + std::to_string(gmsh::view::getIndex(view)) + "].Name", field.name);
        std::string type;
        std::vector<size_t> tags;
        std::vector<double> data;
        double time = 0;
        int components = 0;
        gmsh::view::getHomogeneousModelData(view, 0, type, tags, data, time, components);
        if (type != "NodeData" || components != 1)
            throw InputError(path.string() + ": view '" + field.name + "' holds " + std::to_string(components) +
                                 "-component " + type + ", not scalar NodeData",
                             "only per-node scalar fields can be read back as vertex fields");
        field.values.assign(result.mesh.points.size(), std::numeric_limits<double>::quiet_NaN());
        for (size_t i = 0; i < tags.size(); ++i) {
            const auto found = index_of_tag.find(tags[i]);
            if (found != index_of_tag.end()) field.values[found->second] = data[i];
        }
        result.fields.push_back(std::move(field));
    }
}

} // namespace

namespace {

// Checks that `path` is an MSH file, merges it into a scratch model, and
// runs `read` on it, the new views adopted by the model.
template <typename Read>
void with_msh_file(const std::filesystem::path& path, Read read)
{
    // gmsh::merge ignores a missing file without an error.
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) throw IoError(path.string(), "no such file");
    // Gmsh reads a file without an MSH header as a .geo script, which can run
    // commands: accept MSH files only.
    std::ifstream file(path, std::ios::binary);
    std::string first_word;
    file >> first_word;
    if (!file) throw IoError(path.string(), "cannot read the file");
    if (first_word != "$MeshFormat")
        throw InputError(path.string() + " is not a Gmsh MSH file (it does not begin with $MeshFormat)",
                         "give a mesh written in MSH 2.2 or 4.1 format");
    file.close();

    GmshSession session;
    try {
        // Merging into a fresh model keeps whatever model a caller has open.
        ScratchModel model("scalemesh_import");
        std::vector<int> views_before, views_after;
        gmsh::view::getTags(views_before);
        gmsh::merge(path.string());
        gmsh::view::getTags(views_after);
        std::vector<int> new_views;
        for (int view : views_after)
            if (std::find(views_before.begin(), views_before.end(), view) == views_before.end())
                new_views.push_back(view);
        model.adopt_views(new_views);
        read(new_views);
    } catch (const std::string& gmsh_error) { // how Gmsh 4.8 reports errors
        throw IoError(path.string(), "Gmsh cannot read the file: " + gmsh_error);
    }
}

} // namespace

MshSurface read_msh_surface(const std::filesystem::path& path)
{
    MshSurface result;
    with_msh_file(path, [&](const std::vector<int>& views) {
        std::unordered_map<size_t, int32_t> index_of_tag;
        read_points(result, index_of_tag);
        read_triangles(result, index_of_tag, path);
        read_fields(result, views, index_of_tag, path);
    });
    return result;
}

TetMesh read_msh_volume(const std::filesystem::path& path)
{
    TetMesh mesh;
    with_msh_file(path, [&](const std::vector<int>&) {
        MshSurface surface;
        std::unordered_map<size_t, int32_t> index_of_tag;
        read_points(surface, index_of_tag);
        read_triangles(surface, index_of_tag, path);
        std::vector<size_t> tags, nodes;
        gmsh::model::mesh::getElementsByType(4, tags, nodes);
        if (tags.empty())
            throw InputError(path.string() + " holds no tetrahedra", "give a volume mesh (scalemesh run writes mesh.msh)");
        mesh.tets.reserve(tags.size());
        for (size_t t = 0; t < tags.size(); ++t) {
            Tet tet;
            for (int k = 0; k < 4; ++k) {
                const auto it = index_of_tag.find(nodes[4 * t + k]);
                if (it == index_of_tag.end())
                    throw InputError(path.string() + ": tetrahedron " + std::to_string(tags[t]) + " uses a missing node",
                                     "the file is damaged; write it again");
                tet[k] = it->second;
            }
            mesh.tets.push_back(tet);
        }
        mesh.points = std::move(surface.mesh.points);
        mesh.boundary_faces = std::move(surface.mesh.triangles);
        mesh.boundary_patch = std::move(surface.mesh.triangle_patch);
        for (const auto& [patch, name] : surface.patch_names) {
            if (patch >= static_cast<int32_t>(mesh.patch_names.size())) mesh.patch_names.resize(patch + 1);
            mesh.patch_names[patch] = name;
        }
    });
    return mesh;
}

} // namespace scalemesh
