#pragma once
// Writing a SurfaceMesh and its per-vertex fields to STL, legacy VTK or Gmsh MSH.

#include "core/surface_mesh.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace scalemesh {

struct SurfaceWriteOptions {
    double msh_version = 4.1; // .msh only: 4.1 or 2.2 (2.2 renumbers nodes and elements)
    bool msh_binary = false;  // .msh only: Gmsh's binary variant (Mesh.Binary)
    // .msh only: physical group name per patch id; ids not listed are named
    // "wall" (patch 0) and "patch_<id>" (any other id).
    std::map<int32_t, std::string> patch_names;
    std::vector<std::string> msh_comments = {}; // .msh only: lines of a $Comments section (provenance)
};

// Writes `mesh` to `path`, the format chosen by the extension (case sensitive):
//   .stl  binary STL, float32 coordinates, facet normals from the vertex order;
//         fields and patches are not stored.
//   .vtk  legacy VTK POLYDATA, ASCII, coordinates and values with enough digits
//         to read back the same doubles; every field as POINT_DATA SCALARS
//         double (whitespace in names becomes '_', an empty name "field_<i>"),
//         and CELL_DATA SCALARS "patch" int when triangle_patch is non-empty.
//   .msh  Gmsh MSH through the Gmsh SDK: one discrete surface and one physical
//         surface group per patch id (physical tag = patch id + 1), node tag
//         i + 1 for point i, and every field as a "NodeData" view (step 0)
//         appended to the same file. Only points used by a triangle are written,
//         because MSH 2.2 drops unused nodes.
// Coordinates are written as given (mm). The file appears complete or not at
// all: it is written under a temporary name and renamed at the end, and on any
// exception no file is left behind.
// Throws InputError for an unknown extension, a field whose size differs from
// the number of points, a triangle_patch whose size differs from the number of
// triangles, a negative patch id, a vertex index out of range, or an MSH version
// other than 4.1 and 2.2; IoError (naming `path`) when the file cannot be
// written.
void write_surface(const SurfaceMesh& mesh, const std::vector<VertexField>& fields,
                   const std::filesystem::path& path, const SurfaceWriteOptions& options = {});

} // namespace scalemesh
