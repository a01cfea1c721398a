#pragma once
// OpenFOAM constant/polyMesh from a TetMesh, by our own writer: points, faces,
// owner, neighbour and boundary, with OpenFOAM's ordering rules.

#include "core/tet_mesh.h"

#include <filesystem>
#include <string>
#include <vector>

#include "core/atomic_file.h"

namespace scalemesh {

// The faces of a polyMesh in its order: face f is points[offsets[f] ..
// offsets[f + 1]), owned by owner[f]; the first neighbour.size() faces are
// the internal ones.
struct PolyMeshFaces {
    std::vector<int32_t> offsets{0}, points, owner, neighbour;
};

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
    // With cell_of_tet, when given (one entry per cell): the cells of three
    // tets whose faces to each other may be joined into quads, the layer
    // prisms (LayerPrismCells::prism_cell); by default every cell of three.
    const std::vector<char>* quad_cells = nullptr;
    // When given, the written files are handed over here, still under their
    // temporary names, for the caller to commit with its other outputs;
    // otherwise they are moved into place before returning.
    StagedOutputs* staged = nullptr;
    // When given, filled with the faces as written (for the decomposition,
    // write_decomposed_polymesh).
    PolyMeshFaces* faces = nullptr;
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

// Bounds below checkMesh's own limits (70 degrees of non-orthogonality,
// skewness 4, a positive pyramid on every face of every cell; -allGeometry: an
// interpolation weight of 0.05), with a
// margin for the round-off between this measure and OpenFOAM's.
struct OpenFoamCellBounds {
    double non_orthogonality_deg = 69.9;
    double skewness = 3.8;
    // The cell centre's height above each of its faces, as a fraction of
    // the square root of the face's area: a face pyramid flatter than this
    // counts as wrongly oriented (checkMesh fails only a negative one).
    double pyramid_height = 1e-2;
    // A face's interpolation weight, the nearer cell centre's distance from
    // the face's plane over the sum of both (OpenFOAM's faceWeights;
    // checkMesh -allGeometry fails a face below 0.05).
    double weight = 0.06;
};

struct OpenFoamCellChecks {
    double max_non_orthogonality_deg = 0; // the worst internal face
    double max_skewness = 0;              // the worst face, internal or boundary
    double min_pyramid_height = 0;        // the flattest face pyramid, as OpenFoamCellBounds::pyramid_height measures
    double min_weight = 0;                // the smallest interpolation weight of an internal face
    int64_t faces_beyond_orthogonality = 0, skew_faces = 0, flat_pyramids = 0, light_faces = 0; // beyond the bounds
    std::vector<int32_t> grouped_cells_failing; // cells of more than one tet on a face beyond a bound, ascending
    // Faces checkMesh itself would fail ("Failed N mesh checks"): skewness
    // above 4, or a face pyramid that is not positive. (A face beyond 70
    // degrees of non-orthogonality it reports as severe, but passes.)
    int64_t checkmesh_failures = 0;
};

// OpenFOAM's own cell checks on the polyMesh write_polymesh would write for
// `cell_of_tet` (the same faces: quads between layer prisms as it joins
// them), measured as checkMesh measures them:
// - face centres and area vectors of the polygons by their triangle fans
//   (primitiveMeshFaceCentresAndAreas);
// - cell centres by pyramids on the faces from the mean of the face centres
//   (primitiveMeshCellCentresAndVols);
// - non-orthogonality, the angle between a face's area vector and the join
//   of its two cells' centres (faceOrthogonality);
// - skewness, the face centre's distance from where that join crosses the
//   face, over the face's extent that way (faceSkewness, boundary faces
//   against their normal);
// - face pyramids, the volume of each face with each of its cells' centres
//   as apex, which must be positive (facePyramidVolume: "faces are
//   incorrectly oriented" when not);
// - interpolation weights, min(d_own, d_nei) / (d_own + d_nei) with d a
//   cell centre's distance from the face's plane (faceWeights, which
//   checkMesh -allGeometry judges).
// A cell of several tets has a centre off its tets' centroid where its
// faces are warped, so a face of it or next to it can pass a check on the
// tets and fail it here. The cells of more than one tet on a face beyond a
// bound are returned for the caller to split back into tets.
// `quad_cells` as PolyMeshOptions::quad_cells.
OpenFoamCellChecks openfoam_cell_checks(const TetMesh& mesh, const TetFaceAdjacency& adjacency,
                                        const std::vector<int32_t>& cell_of_tet, int32_t cells,
                                        const OpenFoamCellBounds& bounds = {},
                                        const std::vector<char>* quad_cells = nullptr);

} // namespace scalemesh
