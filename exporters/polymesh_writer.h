#pragma once
// OpenFOAM constant/polyMesh from a TetMesh, by our own writer: points, faces,
// owner, neighbour and boundary, with OpenFOAM's ordering rules.

#include "core/tet_mesh.h"

#include <filesystem>
#include <string>
#include <vector>

#include "core/atomic_file.h"

namespace scalemesh {

struct PolyMeshOptions {
    bool binary = false; // "format binary" (32-bit labels, 64-bit scalars, little-endian)
    double scale = 1.0;  // coordinates are multiplied by this: 1e-3 writes a mesh in mm as metres
    // Patch type per patch id ("wall" or "patch"); ids not listed are "wall".
    std::vector<std::string> patch_types;
    // tet_face_adjacency(mesh) when the caller has it (the volume stage
    // keeps it); computed here otherwise. Either way the mesh is checked.
    const TetFaceAdjacency* adjacency = nullptr;
    // When given (one entry per tet, values 0 .. cells - 1, each cell named
    // by some tet), cell c is the union of the tets with cell_of_tet = c:
    // the faces between two tets of one cell are left out, and two triangles
    // between the same two cells of three tets each (two layer prisms) that
    // share an edge and face the same way (normals within about 45 degrees)
    // are written as one quad. Otherwise cell i is tet i. The caller vouches
    // for the union's shape (layer_prism_cells keeps only star-shaped ones).
    const std::vector<int32_t>* cell_of_tet = nullptr;
    int32_t cells = 0;
    // When given, the written files are handed over here, still under their
    // temporary names, for the caller to commit with its other outputs;
    // otherwise they are moved into place before returning.
    StagedOutputs* staged = nullptr;
};

struct PolyMeshCounts {
    int64_t points = 0, cells = 0, faces = 0, internal_faces = 0;
    int64_t quad_faces = 0; // internal faces written as quads (between layer prisms)
    std::vector<int64_t> patch_faces; // per patch, in the order of `boundary`
};

// Writes case_dir/constant/polyMesh/{points,faces,owner,neighbour,boundary}.
//
// Ordering, as checkMesh requires: internal faces first, sorted by owner cell
// and then by neighbour cell (upper-triangular order), owner < neighbour,
// each face's points ordered so its normal points from owner to neighbour;
// then the boundary faces grouped by patch in the order of `boundary`, their
// normals pointing out of the mesh. Cell i is tet i (or the cells of
// options.cell_of_tet); point i is point i.
//
// The mesh is validated before anything is written: every tet positively
// oriented, no face shared by more than two tets, the one-tet faces exactly
// mesh.boundary_faces, every patch id named. A mesh that fails is refused with
// a StageError naming what failed, and no file is written. The five files are
// written under temporary names and moved into place together at the end.
// Throws IoError when a file cannot be written.
//
// The faces are generated from the cells, never held as a list, and the files
// are formatted in parallel (TBB) in blocks fixed by the mesh and written in
// order: the bytes are the same on any number of threads.
PolyMeshCounts write_polymesh(const TetMesh& mesh, const std::filesystem::path& case_dir,
                              const PolyMeshOptions& options = {});

struct OpenFoamOrthogonality {
    double max_deg = 0;                         // the worst internal face
    std::vector<int32_t> grouped_cells_beyond; // cells of more than one tet on a face beyond the bound, ascending
};

// Face non-orthogonality of the polyMesh write_polymesh would write for
// `cell_of_tet` (the same faces: quads between layer prisms as it joins
// them), measured as OpenFOAM measures it: face centres and area vectors of
// the polygons by their triangle fans (primitiveMeshFaceCentresAndAreas),
// cell centres by pyramids on the faces from the mean of the face centres
// (primitiveMeshCellCentresAndVols), the angle between a face's area vector
// and the join of its two cells' centres (checkMesh's faceOrthogonality).
// A cell of several tets has a centre off its tets' centroid where its
// faces are warped, so a face next to it can pass a bound on the tets and
// fail it here. The cells of more than one tet on a face beyond `bound_deg`
// are returned for the caller to split.
OpenFoamOrthogonality openfoam_orthogonality(const TetMesh& mesh, const TetFaceAdjacency& adjacency,
                                             const std::vector<int32_t>& cell_of_tet, int32_t cells,
                                             double bound_deg);

} // namespace scalemesh
