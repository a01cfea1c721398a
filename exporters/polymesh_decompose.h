#pragma once
// A polyMesh cut into processor meshes for a parallel OpenFOAM run, written
// as OpenFOAM's decomposePar writes them: processor<i>/constant/polyMesh with
// procBoundary patches and the addressing files reconstructPar reads.

#include "core/atomic_file.h"
#include "core/vec3.h"
#include "exporters/polymesh_writer.h"

#include <filesystem>
#include <string>
#include <vector>

namespace scalemesh {

struct DecomposeOptions {
    int32_t processors = 2; // at least 1, at most the cell count
    double scale = 1.0;     // as PolyMeshOptions::scale
    // Per patch of the serial mesh, in the order of its boundary file:
    // its name and type ("wall" or "patch").
    std::vector<std::string> patch_names, patch_types;
    StagedOutputs* staged = nullptr; // as PolyMeshOptions::staged
};

struct DecomposeCounts {
    std::vector<int64_t> cells; // per processor
    int64_t processor_faces = 0; // faces between two processors, each counted once
    int64_t processor_patches = 0; // pairs of processors sharing a face, each pair once
};

// The part (0 .. parts - 1) of each cell, by recursive coordinate bisection
// of the cell centres: the set is cut across the longest side of its
// centres' bounding box into two sets of cells in proportion to the parts
// each gets (parts / 2 and the rest), and so on down to one part each.
// Deterministic (ties broken by the cell index); every part gets at least
// one cell when parts <= centres.size().
std::vector<int32_t> bisect_cells(const std::vector<Vec3>& centres, int32_t parts);

// Writes case_dir/processor<i>/constant/polyMesh/{points,faces,owner,
// neighbour,boundary} for the serial polyMesh of `points` (unscaled) and
// `faces` (as write_polymesh wrote them, with `patch_faces` per patch), its
// cells cut by bisect_cells of the mean of their face centres, with
// cellProcAddressing, faceProcAddressing, pointProcAddressing and
// boundaryProcAddressing as decomposePar writes them:
// - each piece's cells in serial order, its internal faces in serial order,
//   then its faces of each serial patch (every patch listed, empty or not),
//   then one procBoundary<i>to<j> patch per neighbouring processor j in
//   ascending j, its faces in serial order on both sides;
// - a face between two processors is kept on its serial owner's side and
//   flipped on the other (first point kept, the rest reversed, as OpenFOAM's
//   face::reverseFace), faceProcAddressing being face + 1 where kept and
//   -(face + 1) where flipped;
// - the points of each piece in serial order; boundaryProcAddressing the
//   serial patch, -1 for a processor patch.
// Also constant/cellDecomposition (the part per cell) and
// system/decomposeParDict (method manual on that file), so that decomposePar
// gives the same pieces. Files are ASCII.
//
// The pieces are checked before anything is written: every cell in one
// piece, every piece with cells, the faces of each processor patch matched
// one for one by its neighbour's, every serial face accounted for once (twice
// between processors). A failure is a StageError and nothing is written.
// Throws InputError for processors < 1 or above the cell count, IoError when
// a file cannot be written.
DecomposeCounts write_decomposed_polymesh(const std::vector<Vec3>& points, const PolyMeshFaces& faces,
                                          const std::vector<int64_t>& patch_faces,
                                          const std::filesystem::path& case_dir, const DecomposeOptions& options);

} // namespace scalemesh
