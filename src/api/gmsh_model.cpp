// mesh_gmsh_model (include/scalemesh/gmsh_model.h): the current Gmsh model's
// triangles read through the Gmsh API, meshed by mesh_surface, and the mesh
// added back to the model. The host owns the Gmsh session, so nothing here
// goes through gmsh_io/gmsh_session.h (which would initialise and finalise
// Gmsh around the call), and mesh_surface's pipeline reads its scratch
// surface as PLY, never through Gmsh.
//
// Like api.cpp, this file does not include scalemesh/scalemesh.h: the
// exceptions are those of core/errors.h.

#include "scalemesh/gmsh_model.h"

#include "api/run_state.h"
#include "core/errors.h"
#include "gmsh_io/gmsh_session.h"

#include <gmsh.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>
#include <utility>

namespace scalemesh {

void detail::require_gmsh_session(const std::string& hint)
{
    std::vector<std::string> models;
    bool refused = false;
    try {
        gmsh::model::list(models);
    } catch (const std::string&) {
        refused = true;
    }
    if (refused || models.empty())
        throw InputError("Gmsh has no model: it was not initialised, or was finalised", hint);
}

namespace {

// Gmsh 4.8 reports API errors by throwing the message as a std::string.
template <class F> auto gmsh_call(const std::string& what, F&& f)
{
    try {
        return f();
    } catch (const std::string& message) {
        throw StageError("gmsh model", what + ": Gmsh: " + message);
    }
}

std::string entity_name(int tag) { return "surface entity " + std::to_string(tag); }

// The surface entities to mesh, and the patch of each: 0 ("wall") or the
// index of its non-wall physical surface's name in `names`.
struct Selection {
    std::vector<int> entities;
    std::vector<int32_t> entity_patch;
    std::vector<std::string> names{"wall"};
};

Selection select_surfaces(const GmshModelOptions& options)
{
    gmsh::vectorpair groups;
    gmsh::model::getPhysicalGroups(groups, 2);
    std::map<int, std::string> group_name;
    std::vector<std::string> all_names;
    for (const auto& [dim, tag] : groups) {
        std::string name;
        gmsh::model::getPhysicalName(dim, tag, name);
        group_name[tag] = name;
        all_names.push_back(name.empty() ? "(unnamed " + std::to_string(tag) + ")" : name);
    }
    Selection selection;
    int selecting_group = -1;
    if (options.physical_group.empty()) {
        gmsh::vectorpair entities;
        gmsh::model::getEntities(entities, 2);
        for (const auto& [dim, tag] : entities) selection.entities.push_back(tag);
    } else {
        for (const auto& [tag, name] : group_name)
            if (name == options.physical_group) selecting_group = tag;
        if (selecting_group < 0) {
            std::string have;
            for (const std::string& name : all_names) have += (have.empty() ? "" : ", ") + name;
            throw InputError("the Gmsh model has no physical surface named '" + options.physical_group + "'",
                             have.empty() ? "the model has no physical surfaces: leave physical_group empty to mesh "
                                            "every surface entity"
                                          : "choose one of: " + have);
        }
        gmsh::model::getEntitiesForPhysicalGroup(2, selecting_group, selection.entities);
    }
    if (selection.entities.empty())
        throw InputError("the Gmsh model has no surface entities" +
                             (options.physical_group.empty() ? std::string()
                                                             : " in physical surface '" + options.physical_group + "'"),
                         "build or merge a closed surface and mesh it in 2D (gmsh::model::mesh::generate(2))");

    // A surface that bounds a volume already holding tets (the result of an
    // earlier call, or the host's own 3D mesh) is refused: meshed again, that
    // mesh's boundary would lie on top of the input surface, a surface that
    // overlaps itself.
    for (int entity : selection.entities) {
        std::vector<int> up, down;
        gmsh::model::getAdjacencies(2, entity, up, down);
        for (int volume : up) {
            std::vector<int> types;
            gmsh::model::mesh::getElementTypes(types, 3, volume);
            if (!types.empty())
                throw InputError(entity_name(entity) + " bounds volume entity " + std::to_string(volume) +
                                     ", which already holds a volume mesh (an earlier mesh_gmsh_model result, or "
                                     "the model's own 3D mesh): meshing its boundary again would overlap the input "
                                     "surface",
                                 "select the input surface with physical_group, or remove the volume first "
                                 "(gmsh::model::removeEntities({{3, " + std::to_string(volume) +
                                     "}}, true)) or start from a new model");
        }
    }
    for (int entity : selection.entities) {
        std::vector<int> physical;
        gmsh::model::getPhysicalGroupsForEntity(2, entity, physical);
        std::string patch;
        for (int group : physical) {
            const std::string& name = group_name[group];
            if (group == selecting_group || name == "wall" || name.empty()) continue;
            if (!patch.empty() && patch != name)
                throw InputError(entity_name(entity) + " belongs to the physical surfaces '" + patch + "' and '" +
                                     name + "'",
                                 "put each surface entity in one patch group (or in 'wall')");
            patch = name;
        }
        int32_t id = 0;
        if (!patch.empty()) {
            const auto found = std::find(selection.names.begin(), selection.names.end(), patch);
            id = static_cast<int32_t>(found - selection.names.begin());
            if (found == selection.names.end()) selection.names.push_back(patch);
        }
        selection.entity_patch.push_back(id);
    }
    return selection;
}

// The selected entities' 3-node triangles as a SurfaceInput: points numbered
// by first use, one label per triangle.
SurfaceInput read_surface(const Selection& selection)
{
    std::vector<size_t> node_tags;
    std::vector<double> coords, parametric;
    gmsh::model::mesh::getNodes(node_tags, coords, parametric, -1, -1, false, false);
    std::unordered_map<size_t, size_t> node_position;
    node_position.reserve(node_tags.size());
    for (size_t i = 0; i < node_tags.size(); ++i) node_position.emplace(node_tags[i], i);

    SurfaceInput surface;
    std::unordered_map<size_t, size_t> point_of_node;
    for (size_t e = 0; e < selection.entities.size(); ++e) {
        const int entity = selection.entities[e];
        std::vector<int> types;
        gmsh::model::mesh::getElementTypes(types, 2, entity);
        for (int type : types)
            if (type != 2) {
                std::string name;
                int dim = 0, order = 0, nodes = 0, primary = 0;
                std::vector<double> local;
                gmsh::model::mesh::getElementProperties(type, name, dim, order, nodes, local, primary);
                throw InputError(entity_name(entity) + " has elements of type '" + name +
                                     "'; scalemesh meshes 3-node triangles only",
                                 "mesh the surfaces with first-order triangles (Mesh.ElementOrder = 1, "
                                 "Mesh.RecombineAll = 0)");
            }
        std::vector<size_t> element_tags, element_nodes;
        gmsh::model::mesh::getElementsByType(2, element_tags, element_nodes, entity);
        if (element_tags.empty())
            throw InputError(entity_name(entity) + " has no triangles",
                             "mesh the model in 2D first (gmsh::model::mesh::generate(2))");
        for (size_t node : element_nodes) {
            const auto [it, added] = point_of_node.emplace(node, surface.points.size() / 3);
            if (added) {
                const auto position = node_position.find(node);
                if (position == node_position.end())
                    throw StageError("gmsh model", entity_name(entity) + " has a triangle on node " +
                                                       std::to_string(node) + ", which the model does not list");
                const double* xyz = &coords[3 * position->second];
                surface.points.insert(surface.points.end(), xyz, xyz + 3);
            }
            surface.triangles.push_back(it->second);
        }
        surface.labels.insert(surface.labels.end(), element_tags.size(), selection.entity_patch[e]);
    }
    surface.label_names = selection.names;
    return surface;
}

size_t largest_node_tag()
{
    std::vector<size_t> tags;
    std::vector<double> coords, parametric;
    gmsh::model::mesh::getNodes(tags, coords, parametric, -1, -1, false, false);
    return tags.empty() ? 0 : *std::max_element(tags.begin(), tags.end());
}

size_t largest_element_tag()
{
    std::vector<int> types;
    std::vector<std::vector<size_t>> tags, nodes;
    gmsh::model::mesh::getElements(types, tags, nodes, -1, -1);
    size_t largest = 0;
    for (const std::vector<size_t>& of_type : tags)
        if (!of_type.empty()) largest = std::max(largest, *std::max_element(of_type.begin(), of_type.end()));
    return largest;
}

// A physical group of `entity` named `name`. Gmsh keeps physical names
// unique per dimension (a second group of a name stays unnamed), so a group
// of that dimension and name the model has is replaced, keeping its tag.
int named_group(int dim, int entity, const std::string& name)
{
    gmsh::vectorpair groups;
    gmsh::model::getPhysicalGroups(groups, dim);
    int tag = -1;
    for (const auto& [group_dim, group_tag] : groups) {
        std::string group_name;
        gmsh::model::getPhysicalName(group_dim, group_tag, group_name);
        if (group_name == name) tag = group_tag;
    }
    if (tag >= 0) gmsh::model::removePhysicalGroups({{dim, tag}});
    tag = gmsh::model::addPhysicalGroup(dim, {entity}, tag);
    gmsh::model::setPhysicalName(dim, tag, name);
    return tag;
}

void add_to_model(GmshModelResult& out, const GmshModelOptions& options)
{
    const MeshResult& mesh = out.mesh;
    const size_t patches = mesh.patch_names.size();
    std::vector<std::vector<size_t>> patch_nodes(patches);
    for (size_t f = 0; f < mesh.boundary_count(); ++f)
        for (int c = 0; c < 3; ++c) patch_nodes[mesh.boundary_patch[f]].push_back(mesh.boundary_triangles[3 * f + c]);

    out.first_node_tag = largest_node_tag() + 1;
    out.first_tet_tag = largest_element_tag() + 1;

    out.patch_surfaces.assign(patches, -1);
    std::vector<int> boundary;
    for (size_t p = 0; p < patches; ++p)
        if (!patch_nodes[p].empty()) {
            out.patch_surfaces[p] = gmsh::model::addDiscreteEntity(2);
            boundary.push_back(out.patch_surfaces[p]);
        }
    out.volume = gmsh::model::addDiscreteEntity(3, -1, boundary);

    const size_t n = mesh.point_count();
    std::vector<size_t> node_tags(n);
    for (size_t i = 0; i < n; ++i) node_tags[i] = out.first_node_tag + i;
    gmsh::model::mesh::addNodes(3, out.volume, node_tags, mesh.points);

    const size_t t_count = mesh.tet_count();
    std::vector<size_t> tet_tags(t_count), tet_nodes(mesh.tets.size());
    for (size_t t = 0; t < t_count; ++t) tet_tags[t] = out.first_tet_tag + t;
    for (size_t k = 0; k < mesh.tets.size(); ++k) tet_nodes[k] = out.first_node_tag + mesh.tets[k];
    gmsh::model::mesh::addElementsByType(out.volume, 4, tet_tags, tet_nodes);

    size_t next_tag = out.first_tet_tag + t_count;
    for (size_t p = 0; p < patches; ++p) {
        if (out.patch_surfaces[p] < 0) continue;
        std::vector<size_t> tags(patch_nodes[p].size() / 3);
        for (size_t& tag : tags) tag = next_tag++;
        for (size_t& node : patch_nodes[p]) node += out.first_node_tag;
        gmsh::model::mesh::addElementsByType(out.patch_surfaces[p], 2, tags, patch_nodes[p]);
    }

    out.volume_group = named_group(3, out.volume, options.volume_name);
    out.patch_groups.assign(patches, -1);
    for (size_t p = 0; p < patches; ++p)
        if (out.patch_surfaces[p] >= 0) out.patch_groups[p] = named_group(2, out.patch_surfaces[p], mesh.patch_names[p]);

    if (!options.views) return;
    std::string model_name;
    gmsh::model::getCurrent(model_name);
    // The node fields are defined on the boundary nodes, the first points.
    const std::vector<size_t> surface_tags(node_tags.begin(), node_tags.begin() + mesh.surface_points);
    const std::pair<const char*, const std::vector<double>*> node_fields[] = {
        {"D", &mesh.D}, {"D_out", &mesh.D_out}, {"d", &mesh.d}, {"layers", &mesh.layers}};
    for (const auto& [name, values] : node_fields) {
        const int view = gmsh::view::add(name);
        out.views.push_back(view);
        const std::vector<double> data(values->begin(), values->begin() + mesh.surface_points);
        gmsh::view::addHomogeneousModelData(view, 0, model_name, "NodeData", surface_tags, data, 0.0, 1);
    }
    const int view = gmsh::view::add("aspect_ratio");
    out.views.push_back(view);
    gmsh::view::addHomogeneousModelData(view, 0, model_name, "ElementData", tet_tags, mesh.aspect_ratio, 0.0, 1);
}

// The volume entities the selected surfaces bound that scalemesh's volume
// takes the place of (such as the OCC solid the host meshed in 2D): each
// volume all of whose boundary surfaces were selected, that holds no mesh of
// its own and is in no physical volume group, and that shares none of its
// surfaces with another such volume (two volumes on one selected surface,
// as a vessel inside a tissue block, are not both the input: neither is
// taken). Left in the model, a later gmsh::model::mesh::generate(3) would
// fill it with Gmsh's own tets on top of scalemesh's. Read-only.
std::vector<int> input_volumes(const Selection& selection)
{
    std::vector<int> selected = selection.entities;
    std::sort(selected.begin(), selected.end());
    std::map<int, int> volumes_on; // selected surface -> the volumes it bounds
    std::vector<int> candidates;
    for (int entity : selection.entities) {
        std::vector<int> up, down;
        gmsh::model::getAdjacencies(2, entity, up, down);
        volumes_on[entity] = static_cast<int>(up.size());
        candidates.insert(candidates.end(), up.begin(), up.end());
    }
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    std::vector<int> input;
    for (int volume : candidates) {
        std::vector<int> up, bounding, types, groups;
        gmsh::model::getAdjacencies(3, volume, up, bounding);
        gmsh::model::mesh::getElementTypes(types, 3, volume);
        gmsh::model::getPhysicalGroupsForEntity(3, volume, groups);
        const bool alone = std::all_of(bounding.begin(), bounding.end(), [&](int surface) {
            return std::binary_search(selected.begin(), selected.end(), surface) && volumes_on[surface] == 1;
        });
        if (!bounding.empty() && types.empty() && groups.empty() && alone) input.push_back(volume);
    }
    return input;
}

// Removes `volumes` from the model only, not recursively: their surfaces
// stay, and a later occ::synchronize brings them back from the CAD.
void remove_volumes(const std::vector<int>& volumes)
{
    gmsh::vectorpair entities;
    for (int volume : volumes) entities.emplace_back(3, volume);
    if (!entities.empty()) gmsh::model::removeEntities(entities, false);
}

} // namespace

GmshModelResult mesh_gmsh_model(const GmshModelOptions& model, const MeshOptions& options)
{
    if (model.volume_name.empty())
        throw InputError("the volume's physical group has no name", "give volume_name, e.g. \"fluid\"");
    if (!options.openings.empty())
        throw InputError("mesh_gmsh_model takes no openings: the model's surface is closed, and its patches are "
                         "its physical surfaces",
                         "leave MeshOptions::openings empty; for inlets and outlets mesh the surface with "
                         "mesh_surface and openings");
    detail::require_gmsh_session("call gmsh::initialize (gmsh.initialize() in Python) and build or merge a model "
                                 "with a 2D mesh before meshing it with scalemesh");
    // The host's session, adopted: the stages that reach Gmsh (the core of
    // layers = "prisms") work beside the host's model in it.
    const GmshSession host(GmshSession::Host{});
    const Selection selection = gmsh_call("reading the surface entities", [&] { return select_surfaces(model); });
    const SurfaceInput surface = gmsh_call("reading the triangles", [&] { return read_surface(selection); });
    const std::vector<int> input = gmsh_call("finding the input volume", [&] { return input_volumes(selection); });
    GmshModelResult out;
    out.mesh = mesh_surface(surface, options);
    gmsh_call("adding the volume mesh", [&] { add_to_model(out, model); });
    gmsh_call("removing the input volume", [&] { remove_volumes(input); });
    out.removed_volumes = input;
    return out;
}

} // namespace scalemesh
