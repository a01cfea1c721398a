#pragma once
// Writing a TetMesh as a Gmsh .msh (physical groups and inspection views) and
// as a legacy VTK unstructured grid for ParaView.

#include "core/tet_mesh.h"

#include <filesystem>
#include <string>
#include <vector>

namespace scalemesh {

struct VolumeMshOptions {
    double msh_version = 4.1;       // 4.1 or 2.2 (gmshToFoam and older tools read 2.2)
    bool binary = false;
    std::string region = "fluid";   // name of the volume physical group
    std::vector<std::string> comments = {}; // lines of a $Comments section after $MeshFormat (provenance)
    const TetFaceAdjacency* adjacency = nullptr; // as in PolyMeshOptions
};

// .msh through the Gmsh SDK: tets (element type 4, tags 1..T in mesh order)
// in one discrete volume with the physical group `region` (tag 1); boundary
// triangles (type 2) in one discrete surface per patch, each a physical group
// (tag patch id + 1) named from mesh.patch_names ("wall" for patch 0 when
// absent), so patches can be picked in the Gmsh GUI. Node i has tag i + 1.
// point_fields are appended as "NodeData" views (a field with fewer values
// than points covers the first points only, e.g. the surface nodes), tet_fields
// as "ElementData" views on the tets, all in the same file (Gmsh lists them under
// Post-processing). The mesh is validated first as write_polymesh does (a
// StageError and nothing written when it fails); the file appears whole or
// not at all. Throws InputError for a bad version or field size, IoError when
// the file cannot be written.
void write_volume_msh(const TetMesh& mesh, const std::filesystem::path& path, const VolumeMshOptions& options = {});

// Legacy VTK UNSTRUCTURED_GRID, ASCII: points, tets (cell type 10), the
// point fields as POINT_DATA (-1 at points a partial field does not cover)
// and the tet fields as CELL_DATA. Same validation
// and atomicity as write_volume_msh.
void write_volume_vtk(const TetMesh& mesh, const std::filesystem::path& path);

} // namespace scalemesh
