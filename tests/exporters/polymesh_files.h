#pragma once
// The ASCII polyMesh files the exporters write, read back: the lists after
// the FoamFile header, and the patches of a boundary file. A malformed file
// fails the calling test (EXPECT_*) and reads as what could be read.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace scalemesh {

// The numbers of an ASCII OpenFOAM list file after its header, up to the
// closing comment, brackets read as spaces: the count first, then the
// entries.
std::vector<int64_t> read_numbers(const std::filesystem::path& file);

// The entries of a labelList (owner, neighbour, cellDecomposition, the
// *ProcAddressing files); the count is checked against them.
std::vector<int64_t> read_label_list(const std::filesystem::path& file);

// The faces of a faceList, each its point labels; the count is checked.
std::vector<std::vector<int32_t>> read_face_list(const std::filesystem::path& file);

// One patch of a polyBoundaryMesh.
struct BoundaryPatch {
    std::string name;
    int64_t faces = 0, start = 0; // nFaces, startFace
    int64_t neighbour = -1;       // neighbProcNo of a processor patch; -1 for the others
};
std::vector<BoundaryPatch> read_boundary(const std::filesystem::path& file);

} // namespace scalemesh
