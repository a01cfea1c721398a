#include "exporters/surface_writers.h"

#include "core/atomic_file.h"
#include "core/errors.h"
#include "gmsh_io/gmsh_session.h"

#include <gmsh.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>

namespace scalemesh {

namespace {

void check_surface(const SurfaceMesh& mesh, const std::vector<VertexField>& fields)
{
    const auto np = static_cast<int64_t>(mesh.points.size());
    for (size_t f = 0; f < mesh.triangles.size(); ++f)
        for (int32_t v : mesh.triangles[f])
            if (v < 0 || v >= np)
                throw InputError("cannot write the surface: triangle " + std::to_string(f) + " refers to vertex " +
                                     std::to_string(v) + " but there are " + std::to_string(np) + " points",
                                 "this is a bug in the stage that made the surface; please report it");
    if (!mesh.triangle_patch.empty() && mesh.triangle_patch.size() != mesh.triangles.size())
        throw InputError("cannot write the surface: " + std::to_string(mesh.triangle_patch.size()) +
                             " patch ids for " + std::to_string(mesh.triangles.size()) + " triangles",
                         "give one patch id per triangle, or none for an all-wall surface");
    for (size_t f = 0; f < mesh.triangle_patch.size(); ++f)
        if (mesh.triangle_patch[f] < 0)
            throw InputError("cannot write the surface: triangle " + std::to_string(f) + " has the negative patch id " +
                                 std::to_string(mesh.triangle_patch[f]),
                             "patch ids are 0 (wall) or positive");
    for (const VertexField& field : fields)
        if (field.values.size() != mesh.points.size())
            throw InputError("cannot write field '" + field.name + "': it has " + std::to_string(field.values.size()) +
                                 " values for " + std::to_string(np) + " points",
                             "a vertex field needs exactly one value per point of the surface");
}

std::ofstream open_for_writing(const AtomicOutput& out, std::ios::openmode mode)
{
    std::ofstream file(out.temporary(), mode | std::ios::trunc);
    if (!file) throw IoError(out.path().string(), std::string("cannot create the file: ") + std::strerror(errno));
    return file;
}

void close_checked(std::ofstream& file, const AtomicOutput& out)
{
    file.close();
    // A failed flush (disk full, quota) shows only here.
    if (!file) throw IoError(out.path().string(), "writing the file failed (is the disk full?)");
}

void write_stl(const SurfaceMesh& mesh, const AtomicOutput& out)
{
    static_assert(std::endian::native == std::endian::little, "binary STL is little-endian: add byte swapping");
    if (mesh.triangles.size() > std::numeric_limits<uint32_t>::max())
        throw InputError("cannot write " + std::to_string(mesh.triangles.size()) + " triangles to a binary STL",
                         "STL holds at most 2^32 - 1 triangles: write .vtk or .msh instead");

    // The header must not begin with "solid", which readers take as the mark
    // of an ASCII STL.
    std::string bytes(84 + 50 * mesh.triangles.size(), '\0');
    const std::string header = "binary STL written by scalemesh";
    std::fill(bytes.begin(), bytes.begin() + 80, ' ');
    std::memcpy(bytes.data(), header.data(), header.size());
    const auto count = static_cast<uint32_t>(mesh.triangles.size());
    std::memcpy(bytes.data() + 80, &count, 4);

    char* record = bytes.data() + 84;
    for (const Triangle& t : mesh.triangles) {
        const Vec3& a = mesh.points[t[0]];
        const Vec3& b = mesh.points[t[1]];
        const Vec3& c = mesh.points[t[2]];
        const Vec3 n = normalized(cross(b - a, c - a));
        const float values[12] = {float(n.x), float(n.y), float(n.z), float(a.x), float(a.y), float(a.z),
                                  float(b.x), float(b.y), float(b.z), float(c.x), float(c.y), float(c.z)};
        std::memcpy(record, values, sizeof values); // the 2 attribute bytes stay 0
        record += 50;
    }

    std::ofstream file = open_for_writing(out, std::ios::binary);
    file.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    close_checked(file, out);
}

// Shortest decimal text that reads back as the same double, independent of
// the locale (unlike iostreams).
void append(std::string& text, double value)
{
    char buffer[32];
    const auto end = std::to_chars(buffer, buffer + sizeof buffer, value).ptr;
    text.append(buffer, end);
}

void append(std::string& text, int64_t value)
{
    char buffer[24];
    const auto end = std::to_chars(buffer, buffer + sizeof buffer, value).ptr;
    text.append(buffer, end);
}

// Legacy VTK names are single tokens.
std::string vtk_name(const std::string& name, size_t index)
{
    if (name.empty()) return "field_" + std::to_string(index);
    std::string token = name;
    for (char& c : token)
        if (std::isspace(static_cast<unsigned char>(c))) c = '_';
    return token;
}

void write_vtk(const SurfaceMesh& mesh, const std::vector<VertexField>& fields, const AtomicOutput& out)
{
    const auto np = static_cast<int64_t>(mesh.points.size());
    const auto nt = static_cast<int64_t>(mesh.triangles.size());
    std::string text = "# vtk DataFile Version 3.0\nscalemesh surface\nASCII\nDATASET POLYDATA\nPOINTS ";
    append(text, np);
    text += " double\n";
    for (const Vec3& p : mesh.points) {
        append(text, p.x);
        text += ' ';
        append(text, p.y);
        text += ' ';
        append(text, p.z);
        text += '\n';
    }
    text += "POLYGONS ";
    append(text, nt);
    text += ' ';
    append(text, 4 * nt);
    text += '\n';
    for (const Triangle& t : mesh.triangles) {
        text += '3';
        for (int32_t v : t) {
            text += ' ';
            append(text, int64_t{v});
        }
        text += '\n';
    }
    if (!mesh.triangle_patch.empty()) {
        text += "CELL_DATA ";
        append(text, nt);
        text += "\nSCALARS patch int 1\nLOOKUP_TABLE default\n";
        for (int32_t patch : mesh.triangle_patch) {
            append(text, int64_t{patch});
            text += '\n';
        }
    }
    if (!fields.empty()) {
        text += "POINT_DATA ";
        append(text, np);
        text += '\n';
        for (size_t i = 0; i < fields.size(); ++i) {
            text += "SCALARS " + vtk_name(fields[i].name, i) + " double 1\nLOOKUP_TABLE default\n";
            for (double value : fields[i].values) {
                append(text, value);
                text += '\n';
            }
        }
    }

    std::ofstream file = open_for_writing(out, std::ios::binary);
    file.write(text.data(), static_cast<std::streamsize>(text.size()));
    close_checked(file, out);
}

std::string patch_name(int32_t patch, const SurfaceWriteOptions& options)
{
    const auto named = options.patch_names.find(patch);
    if (named != options.patch_names.end()) return named->second;
    return patch == 0 ? "wall" : "patch_" + std::to_string(patch);
}

void write_msh(const SurfaceMesh& mesh, const std::vector<VertexField>& fields, const AtomicOutput& out,
               const SurfaceWriteOptions& options)
{
    if (options.msh_version != 4.1 && options.msh_version != 2.2)
        throw InputError("cannot write MSH version " + std::to_string(options.msh_version),
                         "choose msh_version 4.1 or 2.2");

    const auto patch_of = [&](size_t f) { return mesh.triangle_patch.empty() ? 0 : mesh.triangle_patch[f]; };
    std::set<int32_t> patches;
    for (size_t f = 0; f < mesh.triangles.size(); ++f) patches.insert(patch_of(f));
    if (patches.empty()) patches.insert(0);

    GmshSession session;
    // SaveAll would write the elements without their physical tags in MSH 2.2.
    session.set_option("Mesh.SaveAll", 0);
    session.set_option("Mesh.MshFileVersion", options.msh_version);
    session.set_option("Mesh.Binary", options.msh_binary ? 1 : 0);
    session.set_option("PostProcessing.SaveMesh", 0); // views append without repeating the mesh
    try {
        ScratchModel model("scalemesh_export");

        std::map<int32_t, int> entity_of_patch;
        for (int32_t patch : patches) entity_of_patch[patch] = gmsh::model::addDiscreteEntity(2);

        // Each node is classified on the surface entity of the first triangle
        // that uses it; points used by no triangle are not written.
        const size_t np = mesh.points.size();
        std::vector<int> node_entity(np, 0);
        std::map<int, std::vector<size_t>> element_nodes;
        for (size_t f = 0; f < mesh.triangles.size(); ++f) {
            const int entity = entity_of_patch.at(patch_of(f));
            std::vector<size_t>& nodes = element_nodes[entity];
            for (int32_t v : mesh.triangles[f]) {
                if (node_entity[v] == 0) node_entity[v] = entity;
                nodes.push_back(static_cast<size_t>(v) + 1);
            }
        }
        std::map<int, std::pair<std::vector<size_t>, std::vector<double>>> entity_nodes;
        std::vector<size_t> used_tags;
        for (size_t i = 0; i < np; ++i) {
            if (node_entity[i] == 0) continue;
            auto& [tags, coords] = entity_nodes[node_entity[i]];
            tags.push_back(i + 1);
            coords.insert(coords.end(), {mesh.points[i].x, mesh.points[i].y, mesh.points[i].z});
            used_tags.push_back(i + 1);
        }
        for (const auto& [entity, nodes] : entity_nodes)
            gmsh::model::mesh::addNodes(2, entity, nodes.first, nodes.second);
        for (const auto& [entity, nodes] : element_nodes)
            gmsh::model::mesh::addElementsByType(entity, 2, {}, nodes);

        // Physical tags must be positive, hence patch id + 1.
        for (const auto& [patch, entity] : entity_of_patch) {
            gmsh::model::addPhysicalGroup(2, {entity}, patch + 1);
            gmsh::model::setPhysicalName(2, patch + 1, patch_name(patch, options));
        }
        gmsh::write(out.temporary().string());

        for (const VertexField& field : fields) {
            const int view = model.add_view(field.name);
            std::vector<double> values;
            values.reserve(used_tags.size());
            for (size_t tag : used_tags) values.push_back(field.values[tag - 1]);
            gmsh::view::addHomogeneousModelData(view, 0, model.name(), "NodeData", used_tags, values, 0.0, 1);
            gmsh::view::write(view, out.temporary().string(), /*append=*/true);
        }
    } catch (const std::string& gmsh_error) { // how Gmsh 4.8 reports errors
        throw IoError(out.path().string(), "Gmsh could not write the file: " + gmsh_error);
    }
    if (!options.msh_comments.empty()) insert_msh_comments(out.temporary(), options.msh_comments);
}

} // namespace

void write_surface(const SurfaceMesh& mesh, const std::vector<VertexField>& fields, const std::filesystem::path& path,
                   const SurfaceWriteOptions& options)
{
    const std::string extension = path.extension().string();
    if (extension != ".stl" && extension != ".vtk" && extension != ".msh")
        throw InputError("cannot write '" + path.string() + "': unknown surface format '" + extension + "'",
                         "use one of the extensions .stl, .vtk, .msh");
    check_surface(mesh, fields);

    AtomicOutput out(path);
    if (extension == ".stl") write_stl(mesh, out);
    else if (extension == ".vtk") write_vtk(mesh, fields, out);
    else write_msh(mesh, fields, out, options);
    out.commit();
}

} // namespace scalemesh
