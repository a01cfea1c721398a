#pragma once
// Reading a triangulated surface and its node data back from a Gmsh MSH file:
// the counterpart of write_surface for .msh, used by the round-trip tests.

#include "core/surface_mesh.h"
#include "core/tet_mesh.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace scalemesh {

struct MshSurface {
    // Points in increasing node tag order; the 3-node triangles (element type
    // 2) of every surface entity, entity by entity, with triangle_patch =
    // smallest physical surface tag of the entity - 1 (0 for an entity in no
    // physical group). Elements of other types are skipped.
    SurfaceMesh mesh;
    // One field per view holding scalar "NodeData" at step 0, named after the
    // view, values in point order; NaN where the view has no value for a node.
    std::vector<VertexField> fields;
    std::map<int32_t, std::string> patch_names; // patch id -> physical group name
};

// Reads an MSH 2.2 or 4.1 file (ASCII or binary). Throws IoError when the file
// does not exist or Gmsh cannot read it, and InputError when it does not begin
// with $MeshFormat, holds no triangles, or holds a view that is not scalar
// node data.
MshSurface read_msh_surface(const std::filesystem::path& path);

// Reads a volume mesh: the points as above, the tetrahedra (element type 4),
// and the triangles as boundary_faces with their patches and names. Throws as
// read_msh_surface does, and InputError when the file holds no tetrahedra.
TetMesh read_msh_volume(const std::filesystem::path& path);

} // namespace scalemesh
