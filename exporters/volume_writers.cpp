#include "exporters/volume_writers.h"

#include "core/atomic_file.h"
#include "core/errors.h"
#include "gmsh_io/gmsh_session.h"

#include <gmsh.h>

#include <charconv>
#include <fstream>
#include <map>
#include <set>

namespace scalemesh {

namespace {

// The facts every exported volume mesh must have (the same as the polyMesh
// writer's), and fields of the right length.
void validate(const TetMesh& mesh, const char* format, const TetFaceAdjacency* adjacency = nullptr)
{
    const std::string stage = std::string(format) + " export";
    if (mesh.tets.empty()) throw StageError(stage, "the mesh has no cells");
    const TetMeshFacts facts = adjacency ? tet_mesh_facts(mesh, *adjacency) : tet_mesh_facts(mesh);
    if (facts.nonpositive_tets > 0)
        throw StageError(stage, std::to_string(facts.nonpositive_tets) + " tets have zero or negative volume");
    if (facts.overshared_faces > 0)
        throw StageError(stage, std::to_string(facts.overshared_faces) + " faces are shared by more than two tets");
    if (!facts.boundary_matches) throw StageError(stage, "the mesh's open faces are not exactly its boundary faces");
    if (!mesh.boundary_patch.empty() && mesh.boundary_patch.size() != mesh.boundary_faces.size())
        throw StageError(stage, "boundary_patch does not have one entry per boundary face");
    for (const VertexField& f : mesh.point_fields)
        if (f.values.size() > mesh.points.size())
            throw InputError("point field '" + f.name + "' has " + std::to_string(f.values.size()) + " values for " +
                                 std::to_string(mesh.points.size()) + " points",
                             "give one value per point, or per surface point (the first points)");
    for (const auto& [name, values] : mesh.tet_fields)
        if (values.size() != mesh.tets.size())
            throw InputError("tet field '" + name + "' has " + std::to_string(values.size()) + " values for " +
                                 std::to_string(mesh.tets.size()) + " tets",
                             "give one value per tet");
}

std::string patch_name(const TetMesh& mesh, int32_t patch)
{
    if (patch < static_cast<int32_t>(mesh.patch_names.size())) return mesh.patch_names[patch];
    return patch == 0 ? "wall" : "patch_" + std::to_string(patch);
}

void write_number(std::ostream& out, double v)
{
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof buf, v);
    out.write(buf, r.ptr - buf);
}

} // namespace

void write_volume_msh(const TetMesh& mesh, const std::filesystem::path& path, const VolumeMshOptions& options)
{
    if (options.msh_version != 4.1 && options.msh_version != 2.2)
        throw InputError("cannot write MSH version " + std::to_string(options.msh_version), "choose 4.1 or 2.2");
    validate(mesh, ".msh", options.adjacency);
    AtomicOutput out(path);

    GmshSession session;
    session.set_option("Mesh.SaveAll", 0);
    session.set_option("Mesh.MshFileVersion", options.msh_version);
    session.set_option("Mesh.Binary", options.binary ? 1 : 0);
    session.set_option("PostProcessing.SaveMesh", 0);
    try {
        ScratchModel model("scalemesh_volume");
        const int volume = gmsh::model::addDiscreteEntity(3);

        std::vector<size_t> node_tags(mesh.points.size());
        std::vector<double> coords;
        coords.reserve(3 * mesh.points.size());
        for (size_t i = 0; i < mesh.points.size(); ++i) {
            node_tags[i] = i + 1;
            coords.insert(coords.end(), {mesh.points[i].x, mesh.points[i].y, mesh.points[i].z});
        }
        gmsh::model::mesh::addNodes(3, volume, node_tags, coords);

        std::vector<size_t> tet_tags(mesh.tets.size()), tet_nodes;
        tet_nodes.reserve(4 * mesh.tets.size());
        for (size_t t = 0; t < mesh.tets.size(); ++t) {
            tet_tags[t] = t + 1;
            for (int32_t v : mesh.tets[t]) tet_nodes.push_back(static_cast<size_t>(v) + 1);
        }
        gmsh::model::mesh::addElementsByType(volume, 4, tet_tags, tet_nodes);
        gmsh::model::addPhysicalGroup(3, {volume}, 1);
        gmsh::model::setPhysicalName(3, 1, options.region);

        std::map<int32_t, std::pair<std::vector<size_t>, std::vector<size_t>>> by_patch; // tags, nodes
        size_t next_tag = mesh.tets.size() + 1;
        for (size_t f = 0; f < mesh.boundary_faces.size(); ++f) {
            auto& [tags, nodes] = by_patch[mesh.boundary_patch.empty() ? 0 : mesh.boundary_patch[f]];
            tags.push_back(next_tag++);
            for (int32_t v : mesh.boundary_faces[f]) nodes.push_back(static_cast<size_t>(v) + 1);
        }
        for (const auto& [patch, elements] : by_patch) {
            const int surface = gmsh::model::addDiscreteEntity(2);
            gmsh::model::mesh::addElementsByType(surface, 2, elements.first, elements.second);
            gmsh::model::addPhysicalGroup(2, {surface}, patch + 1);
            gmsh::model::setPhysicalName(2, patch + 1, patch_name(mesh, patch));
        }
        gmsh::write(out.temporary().string());

        for (const VertexField& field : mesh.point_fields) {
            const int view = model.add_view(field.name);
            const std::vector<size_t> tags(node_tags.begin(), node_tags.begin() + field.values.size());
            gmsh::view::addHomogeneousModelData(view, 0, model.name(), "NodeData", tags, field.values, 0.0, 1);
            gmsh::view::write(view, out.temporary().string(), /*append=*/true);
        }
        for (const auto& [name, values] : mesh.tet_fields) {
            const int view = model.add_view(name);
            gmsh::view::addHomogeneousModelData(view, 0, model.name(), "ElementData", tet_tags, values, 0.0, 1);
            gmsh::view::write(view, out.temporary().string(), /*append=*/true);
        }
    } catch (const std::string& gmsh_error) { // how Gmsh 4.8 reports errors
        throw IoError(path.string(), "Gmsh could not write the file: " + gmsh_error);
    }
    if (!options.comments.empty()) insert_msh_comments(out.temporary(), options.comments);
    out.commit();
}

void write_volume_vtk(const TetMesh& mesh, const std::filesystem::path& path)
{
    validate(mesh, ".vtk");
    AtomicOutput out(path);
    {
        std::ofstream f(out.temporary(), std::ios::binary);
        if (!f) throw IoError(path.string(), "cannot open for writing");
        f << "# vtk DataFile Version 3.0\nscalemesh volume mesh\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS "
          << mesh.points.size() << " double\n";
        for (const Vec3& p : mesh.points) {
            write_number(f, p.x);
            f << ' ';
            write_number(f, p.y);
            f << ' ';
            write_number(f, p.z);
            f << '\n';
        }
        f << "CELLS " << mesh.tets.size() << ' ' << 5 * mesh.tets.size() << '\n';
        for (const Tet& t : mesh.tets) f << "4 " << t[0] << ' ' << t[1] << ' ' << t[2] << ' ' << t[3] << '\n';
        f << "CELL_TYPES " << mesh.tets.size() << '\n';
        for (size_t t = 0; t < mesh.tets.size(); ++t) f << "10\n";
        if (!mesh.point_fields.empty()) f << "POINT_DATA " << mesh.points.size() << '\n';
        for (const VertexField& field : mesh.point_fields) {
            f << "SCALARS " << (field.name.empty() ? "field" : field.name) << " double 1\nLOOKUP_TABLE default\n";
            for (size_t i = 0; i < mesh.points.size(); ++i) {
                write_number(f, i < field.values.size() ? field.values[i] : -1.0);
                f << '\n';
            }
        }
        if (!mesh.tet_fields.empty()) f << "CELL_DATA " << mesh.tets.size() << '\n';
        for (const auto& [name, values] : mesh.tet_fields) {
            f << "SCALARS " << (name.empty() ? "field" : name) << " double 1\nLOOKUP_TABLE default\n";
            for (double v : values) {
                write_number(f, v);
                f << '\n';
            }
        }
        if (!f.flush()) throw IoError(path.string(), "cannot write the file");
    }
    out.commit();
}

} // namespace scalemesh
