#pragma once
// Reading closed surfaces that users already have: STL, PLY, OBJ, VTK XML
// PolyData (.vtp) and Gmsh .msh, into the SurfaceMesh the pipeline starts from
// instead of marching cubes (DESIGN.md, the import stage).

#include "core/surface_mesh.h"
#include "core/tet_mesh.h"

#include <filesystem>
#include <string>

namespace scalemesh {

// Whether `path` has the extension of a surface format read_surface reads
// (.stl, .ply, .obj, .vtp, .msh, in any letter case).
bool is_surface_file(const std::filesystem::path& path);

// The factor from a length unit to mm: "mm" 1, "cm" 10, "m" 1000, "um" 0.001.
// Throws InputError naming the valid units for anything else.
double unit_to_mm(const std::string& unit);

// Reads the triangles of a surface file, chosen by its extension:
//   .stl  binary or ASCII (importers/stl_importer.h)
//   .ply  ASCII, binary little- and big-endian; the vertex element's x, y, z
//         and the face element's vertex_indices (or vertex_index) list; other
//         elements and properties are skipped
//   .obj  "v" and "f" lines (tinyobjloader); every object and group merged
//   .vtp  VTK XML PolyData, ASCII or inline base64 binary DataArrays,
//         uncompressed; every Piece's Polys merged (Verts, Lines, Strips are
//         refused)
//   .msh  Gmsh MSH 2.2 or 4.1: every 3-node triangle (exporters/msh_reader.h);
//         physical groups are not kept
// Polygons with more than three corners are split into a fan of triangles
// from their first corner.
//
// Guarantees, as read_stl gives them: points with exactly equal coordinates
// are welded; triangles that weld to fewer than three distinct points are
// removed; every point is used by a triangle and points are numbered by first
// use; coordinates are multiplied by `scale` (the file's unit to mm, see
// unit_to_mm). Triangles keep the file's vertex order. Closedness is not
// checked: callers use require_closed_manifold.
//
// Throws IoError when the file is missing or unreadable; InputError for an
// unknown extension, a wrong magic number or header, a truncated file, a count
// the file cannot hold, a NaN or infinite coordinate, an index out of range,
// a face of fewer than three corners, no triangles at all, compressed or
// appended VTP data, or a `scale` that is not a positive finite number.
SurfaceMesh read_surface(const std::filesystem::path& path, double scale = 1.0);

// The readers behind read_surface, for one format each; same guarantees.
SurfaceMesh read_ply(const std::filesystem::path& path, double scale = 1.0);
SurfaceMesh read_obj(const std::filesystem::path& path, double scale = 1.0);
SurfaceMesh read_vtp(const std::filesystem::path& path, double scale = 1.0);
SurfaceMesh read_msh_surface_mesh(const std::filesystem::path& path, double scale = 1.0);

// A volume .msh (the mesh.msh scalemesh run writes, for `scalemesh check`),
// checked as read_surface checks a .msh before Gmsh reads it. Throws
// IoError when the file is missing or unreadable, InputError when it is
// damaged or holds no tetrahedra.
TetMesh read_msh_tet_mesh(const std::filesystem::path& path);

} // namespace scalemesh
