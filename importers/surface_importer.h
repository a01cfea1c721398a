#pragma once
// Reading closed surfaces that users already have: STL, PLY, OBJ, VTK XML
// PolyData (.vtp) and Gmsh .msh, into the SurfaceMesh the pipeline starts from
// instead of marching cubes (DESIGN.md, the import stage).

#include "core/surface_mesh.h"
#include "core/tet_mesh.h"

#include <filesystem>
#include <map>
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
//   .vtp  VTK XML PolyData as VTK, VMTK, SimVascular and ParaView write it:
//         ASCII, inline base64 binary or appended (raw or base64) DataArrays,
//         zlib-compressed or not, UInt32 or UInt64 headers, little- or
//         big-endian; every Piece's Polys merged (Verts, Lines, Strips are
//         refused)
//   .msh  Gmsh MSH 2.2 or 4.1: every 3-node triangle (gmsh_io/msh_reader.h);
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
// a face of fewer than three corners, no triangles at all, VTP data whose
// stated sizes, offsets or compressed blocks do not match the file's bytes
// or that use a compressor other than zlib, or a `scale` that is not a
// positive finite number.
SurfaceMesh read_surface(const std::filesystem::path& path, double scale = 1.0);

// Per-triangle labels a surface file carries: a VTP cell array such as
// SimVascular's ModelFaceID or CapID, or VMTK's CellEntityIds; the physical
// surfaces of a .msh. Labels are never dropped silently: a caller that does
// not use them says so.
struct SurfaceLabels {
    std::string source;                    // where they came from: "cell array ModelFaceID", "physical surfaces"; empty: none
    std::vector<int32_t> per_triangle;     // one label per triangle of the mesh, in its order; empty: none
    std::map<int32_t, std::string> names;  // names of label values where the file gives them
    bool empty() const { return per_triangle.empty(); }
};

struct LabelledSurface {
    SurfaceMesh mesh;      // as read_surface returns it; triangle_patch left empty
    SurfaceLabels labels;  // aligned with mesh.triangles (welding and dropped triangles accounted for)
};

// read_surface with the file's face labels. A .vtp takes the first of its
// integer cell arrays named ModelFaceID, CapID, CellEntityIds, FaceID,
// GroupIds (or the only integer cell array when there is exactly one); a
// .msh its physical surfaces (names from $PhysicalNames). Other formats
// have none.
LabelledSurface read_labelled_surface(const std::filesystem::path& path, double scale = 1.0);
LabelledSurface read_vtp_labelled(const std::filesystem::path& path, double scale = 1.0);
LabelledSurface read_msh_labelled(const std::filesystem::path& path, double scale = 1.0);

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
